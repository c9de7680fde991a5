// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <Eigen/Dense>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "spidarcad/modeling/tet_mesh.h"

namespace spidarcad::modeling {

namespace {

Eigen::Vector3d Node(const TetMesh& mesh, Eigen::Index t, int k) { return mesh.nodes.col(mesh.tets(k, t)); }

// Closes the file on scope exit; Close() reports write errors.
class File {
 public:
  explicit File(const std::string& path) : path_(path), f_(std::fopen(path.c_str(), "w")) {
    if (!f_) throw std::runtime_error(path + ": cannot open for writing: " + std::strerror(errno));
  }
  ~File() {
    if (f_) std::fclose(f_);
  }
  std::FILE* get() { return f_; }
  void Close() {
    const bool bad = std::ferror(f_) != 0;
    const int rc = std::fclose(f_);
    f_ = nullptr;
    if (bad || rc != 0) throw std::runtime_error(path_ + ": write failed");
  }

 private:
  std::string path_;
  std::FILE* f_;
};

void WriteArray(std::FILE* f, const std::string& name, const Eigen::MatrixXd& values) {
  std::fprintf(f, "        <DataArray type=\"Float64\" Name=\"%s\" NumberOfComponents=\"%ld\" format=\"ascii\">\n",
               name.c_str(), static_cast<long>(values.rows()));
  for (Eigen::Index j = 0; j < values.cols(); ++j) {
    std::fprintf(f, "         ");
    for (Eigen::Index i = 0; i < values.rows(); ++i) std::fprintf(f, " %.17g", values(i, j));
    std::fprintf(f, "\n");
  }
  std::fprintf(f, "        </DataArray>\n");
}

void CheckArrays(const VtuArrays& arrays, Eigen::Index cols, const char* kind) {
  for (const auto& [name, values] : arrays) {
    if (name.empty() || name.find_first_of("\"<>&") != std::string::npos) {
      throw std::invalid_argument(std::string("WriteVtu: bad ") + kind + " array name '" + name + "'");
    }
    if (values.cols() != cols || values.rows() < 1) {
      throw std::invalid_argument(std::string("WriteVtu: ") + kind + " array '" + name + "' is " +
                                  std::to_string(values.rows()) + " by " + std::to_string(values.cols()) +
                                  ", expected k by " + std::to_string(cols));
    }
    if (!values.allFinite()) throw std::invalid_argument(std::string("WriteVtu: ") + kind + " array '" + name + "' is not finite");
  }
}

}  // namespace

double TetVolume(const TetMesh& mesh, Eigen::Index t) {
  const Eigen::Vector3d p0 = Node(mesh, t, 0);
  return (Node(mesh, t, 1) - p0).dot((Node(mesh, t, 2) - p0).cross(Node(mesh, t, 3) - p0)) / 6.0;
}

double TotalVolume(const TetMesh& mesh) {
  double sum = 0.0;
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) sum += TetVolume(mesh, t);
  return sum;
}

Eigen::Matrix<double, 6, 1> DihedralAngles(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1,
                                           const Eigen::Vector3d& p2, const Eigen::Vector3d& p3) {
  const Eigen::Vector3d p[4] = {p0, p1, p2, p3};
  static constexpr int kEdges[6][4] = {{0, 1, 2, 3}, {0, 2, 1, 3}, {0, 3, 1, 2}, {1, 2, 0, 3}, {1, 3, 0, 2}, {2, 3, 0, 1}};
  Eigen::Matrix<double, 6, 1> angles;
  for (int e = 0; e < 6; ++e) {
    const auto& [i, j, k, l] = kEdges[e];
    const Eigen::Vector3d axis = (p[j] - p[i]).normalized();
    // The angle between the two faces at edge ij is the angle between the other two vertices'
    // offsets with their components along the edge removed.
    Eigen::Vector3d u = p[k] - p[i], v = p[l] - p[i];
    u -= u.dot(axis) * axis;
    v -= v.dot(axis) * axis;
    const double c = u.dot(v) / (u.norm() * v.norm());
    angles[e] = std::acos(std::clamp(c, -1.0, 1.0));
  }
  return angles;
}

double RadiusEdgeRatio(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                       const Eigen::Vector3d& p3) {
  // Circumcentre c (relative to p0): 2 (p_i - p0) · c = |p_i - p0|², i = 1..3.
  Eigen::Matrix3d a;
  a.row(0) = 2 * (p1 - p0);
  a.row(1) = 2 * (p2 - p0);
  a.row(2) = 2 * (p3 - p0);
  const Eigen::Vector3d b((p1 - p0).squaredNorm(), (p2 - p0).squaredNorm(), (p3 - p0).squaredNorm());
  const double radius = a.partialPivLu().solve(b).norm();
  const double shortest = std::sqrt(std::min({(p1 - p0).squaredNorm(), (p2 - p0).squaredNorm(), (p3 - p0).squaredNorm(),
                                              (p2 - p1).squaredNorm(), (p3 - p1).squaredNorm(), (p3 - p2).squaredNorm()}));
  return radius / shortest;
}

TetQuality MeasureTetQuality(const TetMesh& mesh) {
  TetQuality q;
  if (mesh.tets.cols() == 0) return q;
  q.min_dihedral_deg = std::numeric_limits<double>::infinity();
  q.min_volume = std::numeric_limits<double>::infinity();
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    const Eigen::Vector3d p0 = Node(mesh, t, 0), p1 = Node(mesh, t, 1), p2 = Node(mesh, t, 2), p3 = Node(mesh, t, 3);
    const Eigen::Matrix<double, 6, 1> angles = DihedralAngles(p0, p1, p2, p3) * (180.0 / M_PI);
    q.min_dihedral_deg = std::min(q.min_dihedral_deg, angles.minCoeff());
    q.max_dihedral_deg = std::max(q.max_dihedral_deg, angles.maxCoeff());
    q.max_radius_edge = std::max(q.max_radius_edge, RadiusEdgeRatio(p0, p1, p2, p3));
    const double v = TetVolume(mesh, t);
    q.min_volume = std::min(q.min_volume, v);
    q.total_volume += v;
  }
  return q;
}

void ValidateTetMesh(const TetMesh& mesh) {
  const Eigen::Index nv = mesh.nodes.cols(), nt = mesh.tets.cols();
  if (mesh.regions.size() != 0 && mesh.regions.size() != nt) {
    throw std::invalid_argument("TetMesh: " + std::to_string(mesh.regions.size()) + " regions for " + std::to_string(nt) + " tets");
  }
  if (!mesh.nodes.allFinite()) throw std::invalid_argument("TetMesh: a node coordinate is not finite");
  for (Eigen::Index t = 0; t < nt; ++t) {
    for (int k = 0; k < 4; ++k) {
      const int i = mesh.tets(k, t);
      if (i < 0 || i >= nv) {
        throw std::invalid_argument("TetMesh: tet " + std::to_string(t) + " has node index " + std::to_string(i) +
                                    " outside [0, " + std::to_string(nv) + ")");
      }
      for (int m = 0; m < k; ++m) {
        if (mesh.tets(m, t) == i) throw std::invalid_argument("TetMesh: tet " + std::to_string(t) + " repeats node " + std::to_string(i));
      }
    }
  }
}

void WriteVtu(const TetMesh& mesh, const std::string& path, const VtuArrays& point_data, const VtuArrays& cell_data) {
  ValidateTetMesh(mesh);
  const Eigen::Index nv = mesh.nodes.cols(), nt = mesh.tets.cols();
  CheckArrays(point_data, nv, "point");
  CheckArrays(cell_data, nt, "cell");
  for (const char* builtin : {"region", "volume", "min_dihedral_deg"}) {
    if (cell_data.count(builtin)) throw std::invalid_argument(std::string("WriteVtu: cell array name '") + builtin + "' is reserved");
  }
  File file(path);
  std::FILE* f = file.get();
  std::fprintf(f, "<?xml version=\"1.0\"?>\n");
  std::fprintf(f, "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n");
  std::fprintf(f, "  <UnstructuredGrid>\n");
  std::fprintf(f, "    <Piece NumberOfPoints=\"%ld\" NumberOfCells=\"%ld\">\n", static_cast<long>(nv), static_cast<long>(nt));
  std::fprintf(f, "      <PointData>\n");
  for (const auto& [name, values] : point_data) WriteArray(f, name, values);
  std::fprintf(f, "      </PointData>\n      <CellData>\n");
  std::fprintf(f, "        <DataArray type=\"Int32\" Name=\"region\" format=\"ascii\">\n");
  for (Eigen::Index t = 0; t < nt; ++t) std::fprintf(f, "%s%d", t % 16 ? " " : "\n          ", mesh.regions.size() ? mesh.regions[t] : 0);
  std::fprintf(f, "\n        </DataArray>\n");
  Eigen::MatrixXd volume(1, nt), dihedral(1, nt);
  for (Eigen::Index t = 0; t < nt; ++t) {
    volume(0, t) = TetVolume(mesh, t);
    dihedral(0, t) = DihedralAngles(Node(mesh, t, 0), Node(mesh, t, 1), Node(mesh, t, 2), Node(mesh, t, 3)).minCoeff() * (180.0 / M_PI);
  }
  WriteArray(f, "volume", volume);
  WriteArray(f, "min_dihedral_deg", dihedral);
  for (const auto& [name, values] : cell_data) WriteArray(f, name, values);
  std::fprintf(f, "      </CellData>\n      <Points>\n");
  WriteArray(f, "Points", mesh.nodes);
  std::fprintf(f, "      </Points>\n      <Cells>\n");
  std::fprintf(f, "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
  for (Eigen::Index t = 0; t < nt; ++t) {
    std::fprintf(f, "          %d %d %d %d\n", mesh.tets(0, t), mesh.tets(1, t), mesh.tets(2, t), mesh.tets(3, t));
  }
  std::fprintf(f, "        </DataArray>\n        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
  for (Eigen::Index t = 0; t < nt; ++t) std::fprintf(f, "%s%ld", t % 16 ? " " : "\n          ", 4 * static_cast<long>(t + 1));
  std::fprintf(f, "\n        </DataArray>\n        <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
  // 10 = VTK_TETRA.
  for (Eigen::Index t = 0; t < nt; ++t) std::fprintf(f, "%s10", t % 32 ? " " : "\n          ");
  std::fprintf(f, "\n        </DataArray>\n      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n");
  file.Close();
}

void WriteTetgenFiles(const TetMesh& mesh, const std::string& base) {
  ValidateTetMesh(mesh);
  {
    File file(base + ".node");
    std::FILE* f = file.get();
    std::fprintf(f, "# spidarcad tetrahedral mesh nodes, metres, 0-based\n%ld 3 0 0\n", static_cast<long>(mesh.nodes.cols()));
    for (Eigen::Index i = 0; i < mesh.nodes.cols(); ++i) {
      std::fprintf(f, "%ld %.17g %.17g %.17g\n", static_cast<long>(i), mesh.nodes(0, i), mesh.nodes(1, i), mesh.nodes(2, i));
    }
    file.Close();
  }
  File file(base + ".ele");
  std::FILE* f = file.get();
  std::fprintf(f, "# spidarcad tetrahedra, 0-based node indices, last column the region\n%ld 4 1\n", static_cast<long>(mesh.tets.cols()));
  for (Eigen::Index t = 0; t < mesh.tets.cols(); ++t) {
    std::fprintf(f, "%ld %d %d %d %d %d\n", static_cast<long>(t), mesh.tets(0, t), mesh.tets(1, t), mesh.tets(2, t),
                 mesh.tets(3, t), mesh.regions.size() ? mesh.regions[t] : 0);
  }
  file.Close();
}

}  // namespace spidarcad::modeling
