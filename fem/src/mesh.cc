// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/mesh.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "spidarcad/base/faces_seen_once.h"

namespace spidarcad::fem {
namespace {

std::string Fmt(const Eigen::Vector3d& v) {
  std::ostringstream s;
  s << "(" << v.x() << ", " << v.y() << ", " << v.z() << ")";
  return s.str();
}

// Key of an undirected edge between nodes a and b.
std::uint64_t EdgeKey(int a, int b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b);
}

}  // namespace

int TetEdgeNode(int a, int b) {
  for (int k = 0; k < 6; ++k) {
    if ((kTetEdges[k][0] == a && kTetEdges[k][1] == b) ||
        (kTetEdges[k][0] == b && kTetEdges[k][1] == a)) {
      return 4 + k;
    }
  }
  throw std::invalid_argument("TetEdgeNode: corners " + std::to_string(a) + ", " +
                              std::to_string(b) + " do not form an edge");
}

double TetMesh::CornerVolume(int e) const {
  const Eigen::Vector3d x0 = nodes.row(elements(e, 0)).transpose();
  Eigen::Matrix3d m;
  for (int k = 0; k < 3; ++k) m.col(k) = nodes.row(elements(e, k + 1)).transpose() - x0;
  return m.determinant() / 6.0;
}

void TetMesh::Validate() const {
  const int npe = NodesPerElement();
  if (npe != 4 && npe != 10) {
    throw std::invalid_argument("TetMesh: elements must have 4 or 10 columns, got " +
                                std::to_string(npe));
  }
  if (regions.size() != elements.rows()) {
    throw std::invalid_argument("TetMesh: regions has " + std::to_string(regions.size()) +
                                " entries for " + std::to_string(elements.rows()) + " elements");
  }
  if (!nodes.allFinite()) throw std::invalid_argument("TetMesh: a node position is not finite");
  for (int e = 0; e < num_elements(); ++e) {
    for (int k = 0; k < npe; ++k) {
      const int v = elements(e, k);
      if (v < 0 || v >= num_nodes()) {
        throw std::invalid_argument("TetMesh: element " + std::to_string(e) + " node " +
                                    std::to_string(k) + " index " + std::to_string(v) +
                                    " is out of range [0, " + std::to_string(num_nodes()) + ")");
      }
    }
    const double vol = CornerVolume(e);
    if (!(vol > 0.0)) {
      std::ostringstream s;
      s << "TetMesh: element " << e << " has non-positive volume " << vol << " m^3";
      throw std::invalid_argument(s.str());
    }
  }
}

TetMesh MakeBoxMesh(const BoxMeshSettings& st) {
  if (st.nx < 1 || st.ny < 1 || st.nz < 1) {
    throw std::invalid_argument(
        "MakeBoxMesh: cell counts must be >= 1, got nx=" + std::to_string(st.nx) +
        " ny=" + std::to_string(st.ny) + " nz=" + std::to_string(st.nz));
  }
  if (!((st.upper - st.lower).array() > 0.0).all()) {
    throw std::invalid_argument("MakeBoxMesh: upper " + Fmt(st.upper) + " must exceed lower " +
                                Fmt(st.lower));
  }
  if (st.order != 1 && st.order != 2) {
    throw std::invalid_argument("MakeBoxMesh: order must be 1 or 2, got " +
                                std::to_string(st.order));
  }
  const int nx = st.nx, ny = st.ny, nz = st.nz;
  auto node_id = [&](int i, int j, int k) { return i + (nx + 1) * (j + (ny + 1) * k); };
  TetMesh mesh;
  mesh.nodes.resize((nx + 1) * (ny + 1) * (nz + 1), 3);
  const Eigen::Vector3d h = (st.upper - st.lower).cwiseQuotient(Eigen::Vector3d(nx, ny, nz));
  for (int k = 0; k <= nz; ++k)
    for (int j = 0; j <= ny; ++j)
      for (int i = 0; i <= nx; ++i)
        mesh.nodes.row(node_id(i, j, k)) =
            (st.lower + Eigen::Vector3d(i * h.x(), j * h.y(), k * h.z())).transpose();
  const int per_cell = st.split == HexSplit::kSix ? 6 : 5;
  mesh.elements.resize(static_cast<Eigen::Index>(nx) * ny * nz * per_cell, 4);
  int e = 0;
  // Corner of a cell by bits (bx, by, bz) = bit 0, 1, 2 of c.
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        auto corner = [&](int c) {
          return node_id(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
        };
        if (st.split == HexSplit::kSix) {
          // Kuhn split: paths 0 -> 7 along the three axes in every order.
          static constexpr int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                              {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
          for (const auto& p : kPerm) {
            const int c1 = 1 << p[0];
            const int c2 = c1 | (1 << p[1]);
            mesh.elements.row(e++) << corner(0), corner(c1), corner(c2), corner(7);
          }
        } else {
          // Five-tet split; the central tetrahedron uses the corners of one parity, which
          // alternates between neighbouring cells so that face diagonals match.
          const int parity = (i + j + k) & 1;
          std::array<int, 4> centre{}, others{};
          int nc = 0, no = 0;
          for (int c = 0; c < 8; ++c) {
            const int bits = (c & 1) + ((c >> 1) & 1) + ((c >> 2) & 1);
            if (((bits + parity) & 1) == 0)
              centre[nc++] = c;
            else
              others[no++] = c;
          }
          mesh.elements.row(e++) << corner(centre[0]), corner(centre[1]), corner(centre[2]),
              corner(centre[3]);
          for (int c : others) {
            // The three neighbours of corner c differ by one bit.
            mesh.elements.row(e++) << corner(c), corner(c ^ 1), corner(c ^ 2), corner(c ^ 4);
          }
        }
      }
    }
  }
  mesh.regions = Eigen::VectorXi::Zero(mesh.elements.rows());
  // Orient every element positively.
  for (int t = 0; t < mesh.num_elements(); ++t) {
    if (mesh.CornerVolume(t) < 0.0) std::swap(mesh.elements(t, 1), mesh.elements(t, 2));
  }
  if (st.order == 2) return MakeQuadratic(mesh);
  return mesh;
}

TetMesh MakeQuadratic(const TetMesh& linear) {
  if (linear.NodesPerElement() != 4) {
    throw std::invalid_argument("MakeQuadratic: input must have 4-node elements, got " +
                                std::to_string(linear.NodesPerElement()));
  }
  std::unordered_map<std::uint64_t, int> edge_node;
  edge_node.reserve(linear.num_elements() * 2);
  std::vector<Eigen::Vector3d> extra;
  TetMesh out;
  out.regions = linear.regions;
  out.elements.resize(linear.num_elements(), 10);
  const int n0 = linear.num_nodes();
  for (int e = 0; e < linear.num_elements(); ++e) {
    for (int c = 0; c < 4; ++c) out.elements(e, c) = linear.elements(e, c);
    for (int k = 0; k < 6; ++k) {
      const int a = linear.elements(e, kTetEdges[k][0]);
      const int b = linear.elements(e, kTetEdges[k][1]);
      auto [it, inserted] =
          edge_node.try_emplace(EdgeKey(a, b), n0 + static_cast<int>(extra.size()));
      if (inserted) {
        extra.push_back(0.5 * (linear.nodes.row(a) + linear.nodes.row(b)).transpose());
      }
      out.elements(e, 4 + k) = it->second;
    }
  }
  out.nodes.resize(n0 + static_cast<Eigen::Index>(extra.size()), 3);
  out.nodes.topRows(n0) = linear.nodes;
  for (size_t i = 0; i < extra.size(); ++i) out.nodes.row(n0 + i) = extra[i].transpose();
  return out;
}

void LabelRegionInBox(const Eigen::Vector3d& lower, const Eigen::Vector3d& upper, int label,
                      TetMesh* mesh) {
  for (int e = 0; e < mesh->num_elements(); ++e) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int k = 0; k < 4; ++k) c += mesh->nodes.row(mesh->elements(e, k)).transpose();
    c /= 4.0;
    if ((c.array() >= lower.array()).all() && (c.array() <= upper.array()).all()) {
      mesh->regions(e) = label;
    }
  }
}

Surface ExtractSurface(const TetMesh& mesh) {
  // Faces by their sorted corner triple; a triple seen once is on the boundary (face i of the
  // list: face i % 4 of element i / 4). Faces come out in triple order.
  std::vector<std::array<int, 3>> keys;
  keys.reserve(4 * static_cast<std::size_t>(mesh.num_elements()));
  for (int e = 0; e < mesh.num_elements(); ++e) {
    for (int f = 0; f < 4; ++f) {
      std::array<int, 3> key{mesh.elements(e, kTetFaces[f][0]), mesh.elements(e, kTetFaces[f][1]),
                             mesh.elements(e, kTetFaces[f][2])};
      std::sort(key.begin(), key.end());
      keys.push_back(key);
    }
  }
  const bool quadratic = mesh.NodesPerElement() == 10;
  struct FaceRef {
    int element;
    int local_face;
  };
  std::vector<FaceRef> boundary;
  for (const std::size_t i : base::FacesSeenOnce(keys))
    boundary.push_back(FaceRef{static_cast<int>(i / 4), static_cast<int>(i % 4)});
  Surface s;
  s.faces.resize(static_cast<Eigen::Index>(boundary.size()), 3);
  if (quadratic) s.faces6.resize(static_cast<Eigen::Index>(boundary.size()), 6);
  s.face_element.resize(static_cast<Eigen::Index>(boundary.size()));
  std::vector<char> on_surface(mesh.num_nodes(), 0);
  for (size_t i = 0; i < boundary.size(); ++i) {
    const auto& ref = boundary[i];
    const auto& lf = kTetFaces[ref.local_face];
    s.face_element(i) = ref.element;
    for (int k = 0; k < 3; ++k) {
      s.faces(i, k) = mesh.elements(ref.element, lf[k]);
      on_surface[s.faces(i, k)] = 1;
    }
    if (quadratic) {
      for (int k = 0; k < 3; ++k) {
        s.faces6(i, k) = s.faces(i, k);
        const int m = mesh.elements(ref.element, TetEdgeNode(lf[k], lf[(k + 1) % 3]));
        s.faces6(i, 3 + k) = m;
        on_surface[m] = 1;
      }
    }
  }
  for (int v = 0; v < mesh.num_nodes(); ++v)
    if (on_surface[v]) s.nodes.push_back(v);
  return s;
}

}  // namespace spidarcad::fem
