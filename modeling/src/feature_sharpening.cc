// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/feature_sharpening.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

#include "point_field.h"
#include "spidarcad/modeling/triangle_closest_point.h"
#include "triangle_predicates.h"

namespace spidarcad::modeling {

namespace {

// The box of mesh's vertices grown by margin on every side (m): where the sharpening evaluates.
Eigen::AlignedBox3d Around(const TriangleMesh& mesh, double margin) {
  Eigen::AlignedBox3d box;
  for (Eigen::Index i = 0; i < mesh.vertices.cols(); ++i)
    box.extend(Eigen::Vector3d(mesh.vertices.col(i)));
  if (!box.isEmpty() && std::isfinite(margin)) {
    box.min().array() -= margin;
    box.max().array() += margin;
  }
  return box;
}

using internal::TrianglesMeet;

// A plane of the true surface: a point on it and the unit outward normal there.
struct Plane {
  Eigen::Vector3d point;
  Eigen::Vector3d normal;
};

// Barycentric sample points of a triangle for the sampled distance: the centroid, the three edge
// midpoints and three inner points.
constexpr std::array<std::array<double, 3>, 7> kSamples = {{
    {1.0 / 3, 1.0 / 3, 1.0 / 3},
    {0.5, 0.5, 0.0},
    {0.0, 0.5, 0.5},
    {0.5, 0.0, 0.5},
    {2.0 / 3, 1.0 / 6, 1.0 / 6},
    {1.0 / 6, 2.0 / 3, 1.0 / 6},
    {1.0 / 6, 1.0 / 6, 2.0 / 3},
}};

// Sampled distance of one or more triangles to the surface: sum of squares and max of |value|.
struct Deviation {
  double sum2 = 0.0;
  double max = 0.0;
  void Add(const Deviation& d) {
    sum2 += d.sum2;
    max = std::max(max, d.max);
  }
};

double MinAngle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  auto angle = [](const Eigen::Vector3d& u, const Eigen::Vector3d& w) {
    return std::atan2(u.cross(w).norm(), u.dot(w));
  };
  return std::min({angle(b - a, c - a), angle(a - b, c - b), angle(a - c, b - c)});
}

class Sharpener {
 public:
  Sharpener(const CompiledSolid& solid, const TriangleMesh& mesh, const FeatureSettings& s)
      : solid_(solid, Around(mesh, 2.0 * s.cell_size), s.cell_size), s_(s) {
    h_ = s.cell_size;
    const Eigen::Index nv = mesh.vertices.cols(), nt = mesh.triangles.cols();
    pos_.resize(nv);
    for (Eigen::Index i = 0; i < nv; ++i) {
      pos_[i] = mesh.vertices.col(i);
      if (!pos_[i].allFinite()) {
        throw std::invalid_argument("SharpenFeatures: mesh vertex " + std::to_string(i) +
                                    " is not finite");
      }
    }
    tris_.resize(nt);
    vertex_tris_.resize(nv);
    std::map<std::pair<int, int>, int> directed;
    for (Eigen::Index t = 0; t < nt; ++t) {
      for (int k = 0; k < 3; ++k) {
        const int v = mesh.triangles(k, t);
        if (v < 0 || v >= nv) {
          throw std::invalid_argument("SharpenFeatures: triangle " + std::to_string(t) +
                                      " corner " + std::to_string(k) + ": vertex index " +
                                      std::to_string(v) + " out of range [0, " +
                                      std::to_string(nv) + ")");
        }
        tris_[t][k] = v;
      }
      for (int k = 0; k < 3; ++k) {
        const int a = tris_[t][k], b = tris_[t][(k + 1) % 3];
        if (a == b)
          throw std::invalid_argument("SharpenFeatures: triangle " + std::to_string(t) +
                                      " repeats vertex " + std::to_string(a));
        if (++directed[{a, b}] > 1) {
          throw std::invalid_argument("SharpenFeatures: directed edge " + std::to_string(a) + "-" +
                                      std::to_string(b) + " occurs twice (triangle " +
                                      std::to_string(t) + "): mesh not manifold or not oriented");
        }
        vertex_tris_[a].push_back(static_cast<int>(t));
      }
    }
    for (const auto& [edge, count] : directed) {
      if (directed.find({edge.second, edge.first}) == directed.end()) {
        throw std::invalid_argument("SharpenFeatures: edge " + std::to_string(edge.first) + "-" +
                                    std::to_string(edge.second) +
                                    " has one triangle: the mesh is not closed");
      }
    }
    for (int v = 0; v < static_cast<int>(nv); ++v) HashInsert(v);
  }

  TriangleMesh Run(FeatureStats* stats) {
    const double cos_crease = std::cos(s_.crease_angle_deg * M_PI / 180.0);
    const double cos_half_crease = std::cos(0.5 * s_.crease_angle_deg * M_PI / 180.0);
    long feature = 0, corners = 0;
    for (int round = 0; round < s_.iterations; ++round) {
      Poll();
      // 1. Planes at the vertices (Jacobi: from this round's mesh); planes at projected triangle
      // centroids are made on demand (TrianglePlane), only around vertices whose own planes
      // already spread past the crease angle.
      ++round_stamp_;
      vertex_normal_.assign(pos_.size(), Eigen::Vector3d::Zero());
      for (size_t v = 0; v < pos_.size(); ++v) vertex_normal_[v] = UnitGradient(pos_[v]);
      tri_plane_.resize(tris_.size());
      tri_stamp_.resize(tris_.size(), 0);
      // 2. Targets of feature vertices.
      struct Candidate {
        int rank;
        double distance;
        int vertex;
        Eigen::Vector3d target;
      };
      std::vector<Candidate> candidates;
      is_feature_.assign(pos_.size(), false);
      rank_.assign(pos_.size(), 0);
      target_.resize(pos_.size());
      feature = corners = 0;
      std::vector<Plane> planes;
      for (int v = 0; v < static_cast<int>(pos_.size()); ++v) {
        if (!VertexNormalsSpread(v, cos_crease, cos_half_crease)) continue;
        GatherPlanes(v, &planes);
        int rank = 0;
        Eigen::Vector3d target;
        if (!Solve(v, planes, cos_crease, &rank, &target)) continue;
        is_feature_[v] = true;
        rank_[v] = rank;
        target_[v] = target;
        ++feature;
        corners += rank == 3;
        const double d = (target - pos_[v]).norm();
        if (d > 1e-9 * h_) candidates.push_back({rank, d, v, target});
      }
      // 3. Moves, nearest target first.
      std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
        return a.distance < b.distance || (a.distance == b.distance && a.vertex < b.vertex);
      });
      long moved = 0;
      for (const Candidate& c : candidates) {
        if (TryMove(c.vertex, c.target)) {
          ++moved;
        } else if (c.rank == 3 && s_.insert_corners && InsertCorner(c.vertex, c.target)) {
          ++moved;  // 3b. a new vertex on the corner (counted as a change of this round)
        } else {
          ++rejected_;
        }
      }
      moved_ += moved;
      // 4. Flips next to feature vertices.
      long flipped = 0;
      dirty_.assign(tris_.size(), 1);
      for (int pass = 0; pass < 8; ++pass) {
        Poll();
        const long f = FlipPass();
        flipped += f;
        if (f == 0) break;
      }
      flipped_ += flipped;
      if (moved == 0 && flipped == 0) break;
    }
    // 5. Triangles still sharper than relax_angle_deg: their corners off the features relax and
    // their long edge flips where that raises their smallest angle (Relax, FlipForAngle).
    const double relax_angle = s_.relax_angle_deg * M_PI / 180.0;
    if (is_feature_.size() != pos_.size()) is_feature_.assign(pos_.size(), false);
    // 4b. Triangles sharper than sliver_angle_deg: collapses, flips, snaps onto creases and
    // relaxation moves (RepairSlivers); the mesh is then renumbered (Compact).
    if (s_.sliver_angle_deg > 0.0) {
      RepairSlivers();
      Compact();
      feature = corners = 0;
      for (size_t v = 0; v < pos_.size(); ++v) {
        feature += is_feature_[v];
        corners += is_feature_[v] && rank_[v] == 3;
      }
    }
    for (int sweep = 0; sweep < 4 && relax_angle > 0.0; ++sweep) {
      Poll();
      long changed = 0;
      for (int t = 0; t < static_cast<int>(tris_.size()); ++t) {
        const auto tri = tris_[t];
        if (!(MinAngle(pos_[tri[0]], pos_[tri[1]], pos_[tri[2]]) < relax_angle)) continue;
        for (int v : tri) {
          if (!is_feature_[v] && Relax(v)) ++changed;
        }
        changed += FlipForAngle(t);
      }
      relaxed_ += changed;
      if (changed == 0) break;
    }
    if (stats) {
      stats->feature_vertices = feature;
      stats->corner_vertices = corners;
      stats->vertices_moved = moved_;
      stats->edges_flipped = flipped_;
      stats->rejected_moves = rejected_;
      stats->corners_inserted = inserted_;
      stats->relaxed = relaxed_;
      stats->sliver_collapses = collapses_;
      stats->sliver_snaps = snaps_;
      stats->sliver_flips = sliver_flips_;
      stats->sliver_moves = sliver_moves_;
    }
    TriangleMesh out;
    out.vertices.resize(3, static_cast<Eigen::Index>(pos_.size()));
    for (size_t i = 0; i < pos_.size(); ++i)
      out.vertices.col(static_cast<Eigen::Index>(i)) = pos_[i];
    out.triangles.resize(3, static_cast<Eigen::Index>(tris_.size()));
    for (size_t t = 0; t < tris_.size(); ++t) {
      for (int k = 0; k < 3; ++k) out.triangles(k, static_cast<Eigen::Index>(t)) = tris_[t][k];
    }
    return out;
  }

 private:
  void Poll() const {
    if (s_.cancel && s_.cancel->load(std::memory_order_relaxed)) throw MeshingCancelled();
  }

  // Unit gradient at p (zero where the gradient vanishes).
  Eigen::Vector3d UnitGradient(const Eigen::Vector3d& p) const {
    Eigen::Vector3d g;
    solid_.ValueAndGradient(p, &g);
    const double n = g.norm();
    return n > 1e-12 ? Eigen::Vector3d(g / n) : Eigen::Vector3d::Zero();
  }

  // Newton steps p -= f ∇f / |∇f|² towards the zero set; stops when |f| <= 1e-9 cells.
  Eigen::Vector3d Project(Eigen::Vector3d p, int steps) const {
    for (int i = 0; i < steps; ++i) {
      Eigen::Vector3d g;
      const double f = solid_.ValueAndGradient(p, &g);
      const double g2 = g.squaredNorm();
      if (std::abs(f) <= 1e-9 * h_ || g2 < 1e-12) break;
      p -= (f / g2) * g;
    }
    return p;
  }

  Deviation TriangleDeviation(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                              const Eigen::Vector3d& c) const {
    Deviation d;
    for (const auto& w : kSamples) {
      const double f = std::abs(solid_.Value(w[0] * a + w[1] * b + w[2] * c));
      d.sum2 += f * f;
      d.max = std::max(d.max, f);
    }
    return d;
  }

  // Plane at the centroid of triangle t projected onto the surface, made once per round.
  const Plane& TrianglePlane(int t) {
    if (tri_stamp_[t] != round_stamp_) {
      const Eigen::Vector3d c = (pos_[tris_[t][0]] + pos_[tris_[t][1]] + pos_[tris_[t][2]]) / 3.0;
      const Eigen::Vector3d p = Project(c, 4);
      tri_plane_[t] = {p, UnitGradient(p)};
      tri_stamp_[t] = round_stamp_;
    }
    return tri_plane_[t];
  }

  // Whether the normals at v and its one-ring neighbours spread past the crease angle, or an
  // adjacent triangle turns by more than half of it from the normal at v (a cheap test before the
  // triangle planes are made; the second part catches a vertex on a crease, whose gradient is
  // that of one face only, among neighbours on that face).
  bool VertexNormalsSpread(int v, double cos_crease, double cos_half_crease) {
    for (int t : vertex_tris_[v]) {
      const auto& tri = tris_[t];
      const Eigen::Vector3d n = (pos_[tri[1]] - pos_[tri[0]]).cross(pos_[tri[2]] - pos_[tri[0]]);
      if (n.dot(vertex_normal_[v]) < cos_half_crease * n.norm()) return true;
    }
    ring_.clear();
    for (int t : vertex_tris_[v]) {
      for (int w : tris_[t]) ring_.push_back(w);
    }
    std::sort(ring_.begin(), ring_.end());
    ring_.erase(std::unique(ring_.begin(), ring_.end()), ring_.end());
    for (size_t i = 0; i < ring_.size(); ++i) {
      for (size_t j = i + 1; j < ring_.size(); ++j) {
        if (vertex_normal_[ring_[i]].dot(vertex_normal_[ring_[j]]) < cos_crease) return true;
      }
    }
    return false;
  }

  void GatherPlanes(int v, std::vector<Plane>* planes) {
    planes->clear();
    auto add = [&](const Eigen::Vector3d& p, const Eigen::Vector3d& n) {
      if (n.squaredNorm() > 0.5) planes->push_back({p, n});
    };
    add(pos_[v], vertex_normal_[v]);
    for (int t : vertex_tris_[v]) {
      const Plane& tp = TrianglePlane(t);
      add(tp.point, tp.normal);
      for (int w : tris_[t]) {
        // Each neighbour appears in two triangles of the fan: take it from the one where it
        // follows v, so it is added once.
        if (w == v) continue;
        const auto& tri = tris_[t];
        const int at = tri[0] == v ? 0 : tri[1] == v ? 1 : 2;
        if (tri[(at + 1) % 3] == w) add(pos_[w], vertex_normal_[w]);
      }
    }
  }

  // Classifies vertex v by its planes; for a feature vertex writes the rank (2 crease, 3 corner)
  // and the target (QEF minimiser nearest to the vertex, projected onto the surface). Returns
  // whether v is a feature vertex with a usable target.
  bool Solve(int v, const std::vector<Plane>& planes, double cos_crease, int* rank,
             Eigen::Vector3d* target) const {
    return SolveAt(pos_[v], planes, cos_crease, rank, target);
  }

  // Solve around the point x0 (m) instead of a vertex.
  bool SolveAt(const Eigen::Vector3d& x0, const std::vector<Plane>& planes, double cos_crease,
               int* rank, Eigen::Vector3d* target) const {
    if (planes.size() < 2) return false;
    double min_dot = 1.0;
    for (size_t i = 0; i < planes.size(); ++i) {
      for (size_t j = i + 1; j < planes.size(); ++j)
        min_dot = std::min(min_dot, planes[i].normal.dot(planes[j].normal));
    }
    if (min_dot >= cos_crease) return false;
    // Normal equations around x0: M = Σ n nᵀ, r = Σ n (n·(p_i - x0)).
    Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
    Eigen::Vector3d r = Eigen::Vector3d::Zero();
    for (const Plane& p : planes) {
      m += p.normal * p.normal.transpose();
      r += p.normal * p.normal.dot(p.point - x0);
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(m);  // ascending eigenvalues
    const Eigen::Vector3d lambda = eig.eigenvalues();
    const double sigma1 = std::sqrt(std::max(lambda[2], 0.0));
    if (!(sigma1 > 0.0)) return false;
    int k = 1;
    if (std::sqrt(std::max(lambda[1], 0.0)) > s_.singular_threshold * sigma1) ++k;
    if (k == 2 && std::sqrt(std::max(lambda[0], 0.0)) > s_.singular_threshold * sigma1) ++k;
    if (k == 1) k = 2;  // the normals spread past the crease angle: at least a crease
    Eigen::Vector3d x = x0;
    for (int i = 0; i < k; ++i) {
      const Eigen::Vector3d e = eig.eigenvectors().col(2 - i);
      const double l = lambda[2 - i];
      if (l <= 1e-12 * lambda[2]) continue;
      x += e * (e.dot(r) / l);
    }
    x = Project(x, 6);
    if (!x.allFinite() || std::abs(solid_.Value(x)) > 1e-4 * h_) return false;
    *rank = k;
    *target = x;
    return true;
  }

  // Whether a triangle (a, b, c) with normal n faces the way the surface does: positive dot
  // product with the unit gradient at its centroid projected onto the surface. (The gradients at
  // its corners are no help: on a crease or corner the gradient is that of one face only.)
  bool FacesOutward(const Eigen::Vector3d& n, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                    const Eigen::Vector3d& c) const {
    return n.dot(UnitGradient(Project((a + b + c) / 3.0, 3))) > 0.0;
  }

  // Whether one of the triangles `changed` (as they stand now) meets, other than along what they
  // share, a triangle incident to one of its vertices or a triangle whose box its box overlaps
  // (TrianglesMeet). The first keeps a move or a flip from folding a triangle onto its neighbour
  // (a sliver turned over against its neighbours, near a concave corner) or a fan over itself;
  // the second from cutting through a triangle that shares no vertex with it: where a part is
  // about a cell thick (the platform's 10 mm bracket at 9 mm cells) a move onto a crease on one
  // face could put a triangle through the opposite face.
  bool ChangedTrianglesMeetOthers(const std::vector<int>& changed) {
    if (near_mark_.size() < tris_.size()) near_mark_.resize(tris_.size(), 0);
    ++near_stamp_;
    nearby_.clear();
    auto add = [this](int u) {
      if (near_mark_[u] == near_stamp_) return;
      near_mark_[u] = near_stamp_;
      nearby_.push_back(u);
    };
    for (int t : changed) {
      for (int w : tris_[t]) {
        for (int u : vertex_tris_[w]) add(u);
      }
    }
    if (!tri_cells_built_) {
      tri_cells_.clear();
      for (int t = 0; t < static_cast<int>(tris_.size()); ++t) {
        if (dead_tri_.empty() || !dead_tri_[t]) {
          ForTriangleCells(t, [t](std::vector<int>& list) { list.push_back(t); });
        }
      }
      tri_cells_built_ = true;
    }
    for (int t : changed) {
      // Listed in its cells as it stands now (an entry left where it was before is only a
      // candidate more: every candidate is tested as it stands).
      ForTriangleCells(t, [t, &add](std::vector<int>& list) {
        if (list.empty() || list.back() != t) list.push_back(t);
        for (int u : list) add(u);
      });
    }
    for (int t : changed) {
      const std::array<Eigen::Vector3d, 3> pt{pos_[tris_[t][0]], pos_[tris_[t][1]],
                                              pos_[tris_[t][2]]};
      const Eigen::AlignedBox3d bt = Box(pt);
      for (int u : nearby_) {
        if (u == t) continue;
        if (!dead_tri_.empty() && dead_tri_[u]) continue;  // removed by the operation tried
        // Each changed pair once.
        if (u < t && std::find(changed.begin(), changed.end(), u) != changed.end()) continue;
        const std::array<Eigen::Vector3d, 3> pu{pos_[tris_[u][0]], pos_[tris_[u][1]],
                                                pos_[tris_[u][2]]};
        if (!bt.intersects(Box(pu))) continue;
        if (TrianglesMeet(tris_[t], pt, tris_[u], pu)) return true;
        if (FoldedAcrossEdge(tris_[t], pt, tris_[u], pu)) return true;
      }
    }
    return false;
  }

  // Whether triangles a and b share an edge and their normals are within kFoldAngleDeg of
  // opposite: a fin of two triangles nearly folded onto each other, which no solid the
  // sharpener meets has (TrianglesMeet finds only those folded exactly into one plane).
  static bool FoldedAcrossEdge(const std::array<int, 3>& ia,
                               const std::array<Eigen::Vector3d, 3>& pa,
                               const std::array<int, 3>& ib,
                               const std::array<Eigen::Vector3d, 3>& pb) {
    constexpr double kFoldAngleDeg = 5.0;
    int shared = 0;
    for (int v : ia) shared += v == ib[0] || v == ib[1] || v == ib[2];
    if (shared != 2) return false;
    const Eigen::Vector3d na = Normal(pa), nb = Normal(pb);
    const double scale = na.norm() * nb.norm();
    if (!(scale > 0.0)) return false;  // a degenerate triangle: TrianglesMeet's to judge
    return na.dot(nb) < -std::cos(kFoldAngleDeg * M_PI / 180.0) * scale;
  }

  // Calls f(list) for the list of each cell of tri_cells_ that triangle t's box overlaps (the
  // cells of Key; made when missing). A box more than kMaxBoxCells cells across on an axis
  // (none on a mesh from MeshSurface, whose edges are a few cells at most) is left out.
  template <class F>
  void ForTriangleCells(int t, const F& f) {
    constexpr long long kMaxBoxCells = 16;
    const Eigen::AlignedBox3d b = Box({pos_[tris_[t][0]], pos_[tris_[t][1]], pos_[tris_[t][2]]});
    const Eigen::Vector3d lo = (b.min() / h_).array().floor(), hi = (b.max() / h_).array().floor();
    if (!lo.allFinite() || !hi.allFinite() || ((hi - lo).array() >= kMaxBoxCells).any()) return;
    for (long long i = static_cast<long long>(lo.x()); i <= static_cast<long long>(hi.x()); ++i)
      for (long long j = static_cast<long long>(lo.y()); j <= static_cast<long long>(hi.y()); ++j)
        for (long long k = static_cast<long long>(lo.z()); k <= static_cast<long long>(hi.z()); ++k)
          f(tri_cells_[KeyOf(i, j, k)]);
  }
  static Eigen::AlignedBox3d Box(const std::array<Eigen::Vector3d, 3>& p) {
    Eigen::AlignedBox3d b(p[0]);
    b.extend(p[1]);
    b.extend(p[2]);
    return b;
  }

  // Moves v to x if every safety test passes (see the header). Returns whether it moved.
  bool TryMove(int v, const Eigen::Vector3d& x) {
    const Eigen::Vector3d old = pos_[v];
    if ((x - old).norm() > s_.max_move_cells * h_) return false;
    if (TooClose(v, x)) return false;
    const double min_angle = s_.min_angle_deg * M_PI / 180.0;
    Deviation before, after;
    for (int t : vertex_tris_[v]) {
      const auto& tri = tris_[t];
      std::array<Eigen::Vector3d, 3> p{pos_[tri[0]], pos_[tri[1]], pos_[tri[2]]};
      const Eigen::Vector3d n_old = (p[1] - p[0]).cross(p[2] - p[0]);
      const double angle_old = MinAngle(p[0], p[1], p[2]);
      before.Add(TriangleDeviation(p[0], p[1], p[2]));
      for (int k = 0; k < 3; ++k) {
        if (tri[k] == v) p[k] = x;
      }
      const Eigen::Vector3d n_new = (p[1] - p[0]).cross(p[2] - p[0]);
      if (!(n_new.dot(n_old) > 0.0)) return false;
      const double angle_new = MinAngle(p[0], p[1], p[2]);
      if (angle_new < std::min(angle_old, min_angle)) return false;
      if (!FacesOutward(n_new, p[0], p[1], p[2])) return false;
      after.Add(TriangleDeviation(p[0], p[1], p[2]));
    }
    if (!(after.sum2 < before.sum2) || after.max > before.max + 1e-9 * h_) return false;
    // Last (the costliest): with v at x, no adjacent triangle may fold onto a neighbour or cut
    // through a nearby triangle.
    return MoveUnlessItFolds(v, x);
  }

  // Step 3b: puts a new vertex on the corner x (found from v's planes; no vertex could move
  // there), splitting a triangle (a, b, c) near v into (a, b, x), (b, c, x) and (c, a, x), or an
  // edge (p, q) between triangles (p, q, c) and (q, p, d) into (p, x, c), (x, q, c), (q, x, d) and
  // (x, p, d). Of the splits of the triangles around v and its neighbours and of their edges, the
  // one kept is the one whose new triangles face as the ones they replace did and as the surface
  // does, make no angle under min_angle_deg and lower the sampled distance to the surface most
  // (sum of squares lower, max not higher), unless they fold onto a triangle around them.
  // Nothing happens when a vertex lies within half a cell of x. Returns whether a vertex was
  // inserted.
  bool InsertCorner(int v, const Eigen::Vector3d& x) {
    if (WithinOf(x, 0.5 * h_)) return false;
    const double min_angle = s_.min_angle_deg * M_PI / 180.0;
    std::vector<int> near;
    for (int t : vertex_tris_[v]) {
      for (int w : tris_[t])
        near.insert(near.end(), vertex_tris_[w].begin(), vertex_tris_[w].end());
    }
    std::sort(near.begin(), near.end());
    near.erase(std::unique(near.begin(), near.end()), near.end());
    // The sampled sum of squares of the fan's new triangles (a, b, x), or infinity when the
    // split fails a test.
    auto score = [&](const std::vector<FanEdge>& fan) -> double {
      Deviation before, after;
      int last = -1;
      for (const FanEdge& e : fan) {
        const auto p = Corners(tris_[e.from]);
        if (e.from != last) before.Add(TriangleDeviation(p[0], p[1], p[2]));
        last = e.from;
        const Eigen::Vector3d &a = pos_[e.a], &b = pos_[e.b];
        const Eigen::Vector3d n = (b - a).cross(x - a);
        if (!(n.dot(Normal(p)) > 0.0) || MinAngle(a, b, x) < min_angle || !FacesOutward(n, a, b, x))
          return INFINITY;
        after.Add(TriangleDeviation(a, b, x));
      }
      if (!(after.sum2 < before.sum2) || after.max > before.max + 1e-9 * h_) return INFINITY;
      return after.sum2;
    };
    std::vector<FanEdge> best;
    double best_sum2 = INFINITY;
    auto consider = [&](std::vector<FanEdge> fan) {
      const double sum2 = score(fan);
      if (sum2 < best_sum2) best_sum2 = sum2, best = std::move(fan);
    };
    for (int t : near) {
      consider(SplitFan(t, -1));
      for (int k = 0; k < 3; ++k) {
        // Each edge once, from the triangle where it runs p -> q with p < q.
        if (tris_[t][k] < tris_[t][(k + 1) % 3] &&
            TriangleWithEdge(tris_[t][(k + 1) % 3], tris_[t][k]) >= 0)
          consider(SplitFan(t, k));
      }
    }
    if (best.empty()) return false;
    // The replaced triangles' slots take the first new triangles; the others are appended.
    std::vector<int> parts;
    for (const FanEdge& e : best)
      if (std::find(parts.begin(), parts.end(), e.from) == parts.end()) parts.push_back(e.from);
    const int nv = static_cast<int>(pos_.size());
    const int first_new = static_cast<int>(tris_.size());
    std::vector<std::array<int, 3>> saved;
    for (int t : parts) saved.push_back(tris_[t]);
    auto detach = [&](int t) {
      for (int w : tris_[t]) {
        auto& fan = vertex_tris_[w];
        fan.erase(std::remove(fan.begin(), fan.end(), t), fan.end());
      }
    };
    auto attach = [&](int t) {
      for (int w : tris_[t]) vertex_tris_[w].push_back(t);
    };
    for (int t : parts) detach(t);
    pos_.push_back(x);
    vertex_tris_.push_back({});
    std::vector<int> changed;
    for (size_t i = 0; i < best.size(); ++i) {
      const std::array<int, 3> corners{best[i].a, best[i].b, nv};
      const int t = i < parts.size() ? parts[i] : static_cast<int>(tris_.size());
      if (i < parts.size()) {
        tris_[t] = corners;
      } else {
        tris_.push_back(corners);
      }
      attach(t);
      changed.push_back(t);
    }
    if (ChangedTrianglesMeetOthers(changed)) {
      for (int t : changed) detach(t);
      tris_.resize(first_new);
      for (size_t i = 0; i < parts.size(); ++i) {
        tris_[parts[i]] = saved[i];
        attach(parts[i]);
      }
      vertex_tris_.pop_back();
      pos_.pop_back();
      return false;
    }
    HashInsert(nv);
    vertex_normal_.push_back(UnitGradient(x));
    is_feature_.push_back(true);
    rank_.push_back(3);
    target_.push_back(x);
    tri_plane_.resize(tris_.size());
    tri_stamp_.resize(tris_.size(), 0);
    for (int t : changed) tri_stamp_[t] = 0;  // new corners: this round's cached plane is stale
    ++inserted_;
    return true;
  }

  // One new triangle (a, b, x) of a split, and the triangle `from` whose part it replaces.
  struct FanEdge {
    int a, b, from;
  };
  // The new triangles of splitting triangle t (k < 0) or its edge from corner k to k + 1 with
  // the triangle across it, grouped by the triangle they replace (InsertCorner gives the first
  // new triangle the slot of the first replaced one, the second that of the second).
  std::vector<FanEdge> SplitFan(int t, int k) const {
    const auto& tri = tris_[t];
    if (k < 0) return {{tri[0], tri[1], t}, {tri[1], tri[2], t}, {tri[2], tri[0], t}};
    const int p = tri[k], q = tri[(k + 1) % 3], c = tri[(k + 2) % 3];
    const int t2 = TriangleWithEdge(q, p), d = Third(tris_[t2], p, q);
    return {{q, c, t}, {c, p, t}, {p, d, t2}, {d, q, t2}};
  }

  // Whether a vertex lies closer than r (at most h) to x.
  bool WithinOf(const Eigen::Vector3d& x, double r) const {
    return AnyVertexWithin(x, r, [](int) { return false; });
  }

  // Moves v to x unless one of its triangles would then fold onto a neighbour or cut through a
  // nearby triangle (ChangedTrianglesMeetOthers). Returns whether it moved.
  bool MoveUnlessItFolds(int v, const Eigen::Vector3d& x) {
    const Eigen::Vector3d old = pos_[v];
    pos_[v] = x;
    if (ChangedTrianglesMeetOthers(vertex_tris_[v])) {
      pos_[v] = old;
      return false;
    }
    pos_[v] = old;
    HashErase(v);
    pos_[v] = x;
    HashInsert(v);
    return true;
  }

  // Moves v (not a feature vertex) towards the centroid of its neighbours within its tangent
  // plane and back onto the surface (Newton steps) if that raises the smallest angle of its
  // triangles and passes the safety tests of TryMove but the one on deviation, which here only
  // asks that the sampled distance of the triangles to the surface does not grow (the move is
  // along the surface, not onto a feature).
  // The centroid of v's one-ring moved into v's tangent plane, then onto the surface by `steps`
  // Newton steps: where relaxation moves v.
  Eigen::Vector3d RelaxTarget(int v, int steps) const {
    const auto& fan = vertex_tris_[v];
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int t : fan) {
      const auto& tri = tris_[t];
      const int at = tri[0] == v ? 0 : tri[1] == v ? 1 : 2;
      centre += pos_[tri[(at + 1) % 3]];
    }
    centre /= static_cast<double>(fan.size());
    const Eigen::Vector3d n = UnitGradient(pos_[v]);
    return Project(centre - n * n.dot(centre - pos_[v]), steps);
  }

  bool Relax(int v) {
    const auto& fan = vertex_tris_[v];
    if (fan.size() < 3) return false;
    const Eigen::Vector3d old = pos_[v];
    double old_min = M_PI;
    for (int t : fan) {
      const auto& tri = tris_[t];
      old_min = std::min(old_min, MinAngle(pos_[tri[0]], pos_[tri[1]], pos_[tri[2]]));
    }
    const Eigen::Vector3d x = RelaxTarget(v, 3);
    if (!x.allFinite() || (x - old).norm() > 0.5 * h_ || TooClose(v, x)) return false;
    Deviation before, after;
    double new_min = M_PI;
    for (int t : fan) {
      const auto& tri = tris_[t];
      std::array<Eigen::Vector3d, 3> p{pos_[tri[0]], pos_[tri[1]], pos_[tri[2]]};
      const Eigen::Vector3d n_old = (p[1] - p[0]).cross(p[2] - p[0]);
      before.Add(TriangleDeviation(p[0], p[1], p[2]));
      for (int k = 0; k < 3; ++k) {
        if (tri[k] == v) p[k] = x;
      }
      const Eigen::Vector3d n_new = (p[1] - p[0]).cross(p[2] - p[0]);
      if (!(n_new.dot(n_old) > 0.5 * n_new.norm() * n_old.norm())) return false;
      new_min = std::min(new_min, MinAngle(p[0], p[1], p[2]));
      if (!FacesOutward(n_new, p[0], p[1], p[2])) return false;
      after.Add(TriangleDeviation(p[0], p[1], p[2]));
    }
    if (!(new_min > old_min) || after.max > before.max) return false;
    return MoveUnlessItFolds(v, x);
  }

  // Flips the longest edge of triangle t if it joins no two feature vertices (a crease), the
  // two triangles lie within 20° of one plane, the flip raises their smallest angle, and the
  // flipped pair passes TryFlip's tests without its demand on deviation (which must not grow).
  bool FlipForAngle(int t) {
    const auto tri = tris_[t];
    int k = 0;
    double longest = -1.0;
    for (int i = 0; i < 3; ++i) {
      const double l = (pos_[tri[(i + 1) % 3]] - pos_[tri[i]]).squaredNorm();
      if (l > longest) longest = l, k = i;
    }
    const int p = tri[k], q = tri[(k + 1) % 3];
    if (is_feature_[p] && is_feature_[q]) return false;
    return TryFlip(t, p, q, 0.0, /*for_angle=*/true);
  }

  // Flips edges of triangles around feature vertices that lower the sampled deviation by half.
  // Only triangles marked dirty (all at the start of a round, then those near a flip) are tried.
  long FlipPass() {
    long flips = 0;
    const double min_angle = s_.min_angle_deg * M_PI / 180.0;
    for (int t = 0; t < static_cast<int>(tris_.size()); ++t) {
      if (!dirty_[t]) continue;  // nothing near it changed since it was last tried
      dirty_[t] = 0;
      for (int k = 0; k < 3; ++k) {
        const int p = tris_[t][k], q = tris_[t][(k + 1) % 3];
        if (p > q) continue;  // each edge once, from the triangle where it runs p -> q with p < q
        if (!is_feature_[p] && !is_feature_[q]) continue;
        if (TryFlip(t, p, q, min_angle)) {
          ++flips;
          break;  // triangle t changed
        }
      }
    }
    return flips;
  }

  // Triangle t = (p, q, c) and its neighbour (q, p, d) become (c, p, d) and (d, q, c).
  // for_angle (FlipForAngle): the pair must lie within 20° of one plane and the flip must raise
  // its smallest angle and not raise its sampled deviation; otherwise the flip must halve the
  // deviation and make no angle below min(min_angle, the pair's smallest before).
  bool TryFlip(int t, int p, int q, double min_angle, bool for_angle = false) {
    const int t2 = TriangleWithEdge(q, p);
    if (t2 < 0) return false;
    const int c = Third(tris_[t], p, q), d = Third(tris_[t2], p, q);
    if (c == d) return false;
    if (vertex_tris_[p].size() <= 3 || vertex_tris_[q].size() <= 3) return false;
    for (int u : vertex_tris_[c]) {
      for (int w : tris_[u]) {
        if (w == d) return false;  // c-d is already an edge
      }
    }
    const Eigen::Vector3d &P = pos_[p], &Q = pos_[q], &C = pos_[c], &D = pos_[d];
    const Eigen::Vector3d n1 = (Q - P).cross(C - P), n2 = (P - Q).cross(D - Q);
    const Eigen::Vector3d m1 = (P - C).cross(D - C), m2 = (Q - D).cross(C - D);
    const Eigen::Vector3d ref = n1 + n2;
    if (!(m1.dot(ref) > 0.0) || !(m2.dot(ref) > 0.0)) return false;
    const double old_angle = std::min(MinAngle(P, Q, C), MinAngle(Q, P, D));
    const double new_angle = std::min(MinAngle(C, P, D), MinAngle(D, Q, C));
    if (for_angle) {
      if (!(n1.dot(n2) > std::cos(M_PI / 9) * n1.norm() * n2.norm())) return false;
      if (!(new_angle > old_angle)) return false;
    } else if (new_angle < std::min(old_angle, min_angle)) {
      return false;
    }
    if (!FacesOutward(m1, C, P, D) || !FacesOutward(m2, D, Q, C)) return false;
    Deviation before = TriangleDeviation(P, Q, C), after = TriangleDeviation(C, P, D);
    before.Add(TriangleDeviation(Q, P, D));
    after.Add(TriangleDeviation(D, Q, C));
    if (for_angle ? after.max > before.max
                  : !(after.sum2 < 0.5 * before.sum2) || after.max > before.max)
      return false;
    const std::array<int, 3> old_t = tris_[t], old_t2 = tris_[t2];
    tris_[t] = {c, p, d};
    tris_[t2] = {d, q, c};
    // The new pair may not fold onto each other or onto a neighbour (a non-convex quad).
    if (ChangedTrianglesMeetOthers({t, t2})) {
      tris_[t] = old_t;
      tris_[t2] = old_t2;
      return false;
    }
    // t lost q and gained d; t2 lost p and gained c.
    auto erase = [&](int v, int u) {
      auto& list = vertex_tris_[v];
      list.erase(std::remove(list.begin(), list.end(), u), list.end());
    };
    erase(q, t);
    vertex_tris_[d].push_back(t);
    erase(p, t2);
    vertex_tris_[c].push_back(t2);
    for (int v : {p, q, c, d}) {
      for (int u : vertex_tris_[v]) dirty_[u] = 1;
    }
    return true;
  }

  // ---- 4b. Sliver repair (RepairSlivers) ----

  // One local change of the mesh: triangles removed, triangles given new corners (or only
  // reshaped by a moved vertex: then listed with their corners unchanged), vertices moved, at
  // most one vertex removed (a collapse) and vertices that become crease vertices (a snap).
  struct Op {
    std::vector<int> removed;
    std::vector<std::pair<int, std::array<int, 3>>> changed;
    std::vector<std::pair<int, Eigen::Vector3d>> moves;
    int removed_vertex = -1;
    std::vector<Eigen::Vector3d> keep_covered;  // crease points the new triangles must cover
    int cover_vertex = -1;  // whose triangles count for keep_covered (with the changed ones)
    int new_crease_vertex = -1;
    enum Kind { kNone, kCollapse, kSnap, kFlip, kMove, kSlide } kind = kNone;
  };

  static double TriangleMinAngle(const std::array<Eigen::Vector3d, 3>& p) {
    return MinAngle(p[0], p[1], p[2]);
  }
  std::array<Eigen::Vector3d, 3> Corners(const std::array<int, 3>& t) const {
    return {pos_[t[0]], pos_[t[1]], pos_[t[2]]};
  }
  static Eigen::Vector3d Normal(const std::array<Eigen::Vector3d, 3>& p) {
    return (p[1] - p[0]).cross(p[2] - p[0]);
  }

  // Adds every triangle around v not yet in op.changed, with its corners as they are.
  void AddFan(int v, Op* op) const {
    for (int t : vertex_tris_[v]) {
      bool listed = std::find(op->removed.begin(), op->removed.end(), t) != op->removed.end();
      for (const auto& c : op->changed) listed = listed || c.first == t;
      if (!listed) op->changed.push_back({t, tris_[t]});
    }
  }

  // Tries op against the safety tests: every changed triangle keeps facing the way it did (or,
  // if its corners changed, the way the triangles it replaces did on the whole) and the way the
  // surface does, their angles improve (AngleAfter), their sampled distance to the surface
  // stays within the largest of the old one, tolerance and the neighbours'
  // (NeighbourhoodDeviation), the crease points in op.keep_covered stay as close, moved vertices
  // keep their separation, and no changed triangle meets a triangle around it. AngleAfter(op)
  // must have passed on the mesh as it is. Commits the change and returns true when every test
  // passes; otherwise leaves the mesh as it was and returns false.
  bool TryOp(const Op& op) {
    const double tolerance = tolerance_cells_ * h_;
    Deviation before;
    Eigen::Vector3d ref = Eigen::Vector3d::Zero();
    auto old_tri = [&](int t) {
      const auto p = Corners(tris_[t]);
      before.Add(TriangleDeviation(p[0], p[1], p[2]));
      ref += Normal(p);
    };
    for (int t : op.removed) old_tri(t);
    std::vector<Eigen::Vector3d> old_normals;
    old_normals.reserve(op.changed.size());
    for (const auto& [t, corners] : op.changed) {
      old_tri(t);
      old_normals.push_back(Normal(Corners(tris_[t])));
    }
    for (const auto& [v, x] : op.moves) {
      if (!x.allFinite() || TooClose(v, x, op.removed_vertex)) return false;
    }
    // Apply.
    std::vector<std::array<int, 3>> saved_tris;
    for (const auto& [t, corners] : op.changed) saved_tris.push_back(tris_[t]);
    std::vector<Eigen::Vector3d> saved_pos;
    for (const auto& [v, x] : op.moves) saved_pos.push_back(pos_[v]);
    for (const auto& [t, corners] : op.changed) tris_[t] = corners;
    for (const auto& [v, x] : op.moves) pos_[v] = x;
    for (int t : op.removed) dead_tri_[t] = 1;
    auto revert = [&]() {
      for (size_t i = 0; i < op.changed.size(); ++i) tris_[op.changed[i].first] = saved_tris[i];
      for (size_t i = 0; i < op.moves.size(); ++i) pos_[op.moves[i].first] = saved_pos[i];
      for (int t : op.removed) dead_tri_[t] = 0;
    };
    Deviation after;
    double neighbourhood = -1.0;  // NeighbourhoodDeviation, when needed
    bool ok = true;
    for (size_t i = 0; ok && i < op.changed.size(); ++i) {
      const auto& [t, corners] = op.changed[i];
      const auto p = Corners(corners);
      const Eigen::Vector3d n = Normal(p);
      // A collapse rewrites a triangle in place (one corner renamed): against its own normal.
      const bool same_slot = op.kind == Op::kCollapse || corners == saved_tris[i];
      const Eigen::Vector3d& against = same_slot ? old_normals[i] : ref;
      if (!(n.dot(against) > 0.0)) ok = false;
      if (ok) after.Add(TriangleDeviation(p[0], p[1], p[2]));
      if (ok && after.max > std::max(before.max, tolerance) && neighbourhood < 0.0)
        neighbourhood = NeighbourhoodDeviation(op, saved_tris, saved_pos);
      if (ok && after.max > std::max({before.max, tolerance, neighbourhood})) {
        ok = false;
      }
    }
    for (size_t i = 0; ok && i < op.changed.size(); ++i) {
      const auto p = Corners(op.changed[i].second);
      if (!FacesOutward(Normal(p), p[0], p[1], p[2])) ok = false;
    }
    // Crease points the op must keep covered (a crease vertex merged into its neighbour or slid
    // along its crease) stay within the same distance of the new triangles (those changed and
    // those around op.cover_vertex).
    for (const Eigen::Vector3d& x : op.keep_covered) {
      if (!ok) break;
      double nearest = INFINITY;
      auto to = [&](const std::array<int, 3>& corners) {
        const auto p = Corners(corners);
        nearest = std::min(nearest, (x - ClosestPointOnTriangle(x, p[0], p[1], p[2])).norm());
      };
      for (const auto& [t, corners] : op.changed) to(corners);
      for (int t : vertex_tris_[op.cover_vertex]) {
        if (!dead_tri_[t]) to(tris_[t]);
      }
      if (nearest > std::max(tolerance, before.max) && neighbourhood < 0.0)
        neighbourhood = NeighbourhoodDeviation(op, saved_tris, saved_pos);
      if (!(nearest <= std::max({tolerance, before.max, neighbourhood}))) ok = false;
    }
    if (ok) {
      std::vector<int> changed;
      for (const auto& c : op.changed) changed.push_back(c.first);
      // The removed vertex's fan is gone from the mesh: its triangles are rewritten (listed in
      // changed) or removed (dead).
      if (ChangedTrianglesMeetOthers(changed)) ok = false;
    }
    if (!ok) {
      revert();
      return false;
    }
    // Commit: positions and corners are in place; now the lists, the hash and the flags.
    for (size_t i = 0; i < op.moves.size(); ++i) {
      const int v = op.moves[i].first;
      const Eigen::Vector3d x = pos_[v];
      pos_[v] = saved_pos[i];
      HashErase(v);
      pos_[v] = x;
      HashInsert(v);
    }
    auto erase = [&](int v, int t) {
      auto& list = vertex_tris_[v];
      list.erase(std::remove(list.begin(), list.end(), t), list.end());
    };
    for (int t : op.removed) {
      for (int v : tris_[t]) erase(v, t);
    }
    for (size_t i = 0; i < op.changed.size(); ++i) {
      const int t = op.changed[i].first;
      for (int v : saved_tris[i]) erase(v, t);
      for (int v : tris_[t]) vertex_tris_[v].push_back(t);
      touched_.push_back(t);
    }
    if (op.removed_vertex >= 0) {
      const int u = op.removed_vertex;
      HashErase(u);
      dead_vertex_[u] = 1;
      vertex_tris_[u].clear();
    }
    // A released feature vertex that moved is off its crease or corner now (the point it
    // marked stays covered by the triangles around it).
    for (const auto& [v, x] : op.moves) {
      if (Released(v)) {
        released_[v] = 0;
        is_feature_[v] = false;
        rank_[v] = 0;
      }
    }
    if (op.new_crease_vertex >= 0) {
      is_feature_[op.new_crease_vertex] = true;
      pinned_[op.new_crease_vertex] = 1;
      rank_[op.new_crease_vertex] = 2;
    }
    return true;
  }

  // Largest sampled distance to the surface (m) of the triangles around the corners of the
  // triangles op changes or removes, as they were before op (op applied now; saved_tris: the
  // changed triangles' corners before; saved_pos: the moved vertices' positions before).
  double NeighbourhoodDeviation(const Op& op, const std::vector<std::array<int, 3>>& saved_tris,
                                const std::vector<Eigen::Vector3d>& saved_pos) {
    if (tri_mark_.size() < tris_.size()) tri_mark_.resize(tris_.size(), 0);
    std::vector<int> corners;
    for (int t : op.removed) corners.insert(corners.end(), tris_[t].begin(), tris_[t].end());
    for (const auto& tri : saved_tris) corners.insert(corners.end(), tri.begin(), tri.end());
    double worst = 0.0;
    ++tri_stamp2_;
    auto corner_pos = [&](int v) -> Eigen::Vector3d {
      for (size_t i = 0; i < op.moves.size(); ++i) {
        if (op.moves[i].first == v) return saved_pos[i];
      }
      return pos_[v];
    };
    for (int v : corners) {
      for (int t : vertex_tris_[v]) {
        if (tri_mark_[t] == tri_stamp2_) continue;
        tri_mark_[t] = tri_stamp2_;
        // Triangles op changes: as they were (saved_tris), the rest as they are.
        std::array<int, 3> tri = tris_[t];
        for (size_t i = 0; i < op.changed.size(); ++i) {
          if (op.changed[i].first == t) tri = saved_tris[i];
        }
        worst = std::max(
            worst,
            TriangleDeviation(corner_pos(tri[0]), corner_pos(tri[1]), corner_pos(tri[2])).max);
      }
    }
    return worst;
  }

  // The geometric part of TryOp (no field evaluations): the smallest angle after op if the
  // changed triangles keep facing as TryOp asks and that angle exceeds the smallest of the
  // triangles op changes or removes, or equals it (within 1e-6 relative) with fewer of them
  // under sliver_angle_deg; else -1.
  double AngleAfter(const Op& op) {
    const double limit = s_.sliver_angle_deg * M_PI / 180.0;
    double before_min = M_PI;
    int before_count = 0, after_count = 0;
    Eigen::Vector3d ref = Eigen::Vector3d::Zero();
    for (int t : op.removed) {
      const auto p = Corners(tris_[t]);
      const double a = TriangleMinAngle(p);
      before_min = std::min(before_min, a);
      before_count += a < limit;
      ref += Normal(p);
    }
    scratch_normals_.clear();
    for (const auto& [t, corners] : op.changed) {
      const auto p = Corners(tris_[t]);
      const double a = TriangleMinAngle(p);
      before_min = std::min(before_min, a);
      before_count += a < limit;
      ref += Normal(p);
      scratch_normals_.push_back(Normal(p));
    }
    for (const auto& [v, x] : op.moves) {
      if (!x.allFinite()) return -1.0;
    }
    auto at = [&](int v) -> const Eigen::Vector3d& {
      for (const auto& [w, x] : op.moves) {
        if (w == v) return x;
      }
      return pos_[v];
    };
    double after_min = M_PI;
    for (size_t i = 0; i < op.changed.size(); ++i) {
      const auto& [t, corners] = op.changed[i];
      const std::array<Eigen::Vector3d, 3> p{at(corners[0]), at(corners[1]), at(corners[2])};
      const bool same_slot = op.kind == Op::kCollapse || corners == tris_[t];
      if (!(Normal(p).dot(same_slot ? scratch_normals_[i] : ref) > 0.0)) return -1.0;
      const double a = TriangleMinAngle(p);
      after_min = std::min(after_min, a);
      after_count += a < limit;
      if (!(after_min >= before_min * (1.0 - 1e-6))) return -1.0;
    }
    // Better: a larger smallest angle, or the same one (within rounding) on fewer triangles
    // under the limit.
    if (!(after_min > before_min) && !(after_count < before_count)) return -1.0;
    return after_min;
  }

  // The triangle (u, v, w) listed for edge u->v, or -1.
  int TriangleWithEdge(int u, int v) const {
    for (int t : vertex_tris_[u]) {
      const auto& tri = tris_[t];
      for (int k = 0; k < 3; ++k) {
        if (tri[k] == u && tri[(k + 1) % 3] == v) return t;
      }
    }
    return -1;
  }
  static int Third(const std::array<int, 3>& tri, int a, int b) {
    for (int v : tri) {
      if (v != a && v != b) return v;
    }
    return -1;
  }

  // Collapse of edge u-v removing u, v moving to x (a copy of pos_[v] when it stays). False
  // when the link condition fails: u and v must share exactly the two vertices opposite the
  // edge, each of which keeps three or more triangles.
  bool MakeCollapse(int u, int v, const Eigen::Vector3d& x, Op* op) {
    const int t1 = TriangleWithEdge(u, v), t2 = TriangleWithEdge(v, u);
    if (t1 < 0 || t2 < 0) return false;
    const int a = Third(tris_[t1], u, v), b = Third(tris_[t2], u, v);
    if (a == b || vertex_tris_[a].size() <= 3 || vertex_tris_[b].size() <= 3) return false;
    if (vertex_tris_[u].size() + vertex_tris_[v].size() < 7) return false;
    ++mark_stamp_;
    if (mark_.size() < pos_.size()) mark_.resize(pos_.size(), 0);
    for (int t : vertex_tris_[u]) {
      for (int w : tris_[t]) mark_[w] = mark_stamp_;
    }
    int common = 0;
    for (int t : vertex_tris_[v]) {
      for (int w : tris_[t]) {
        if (w != u && w != v && mark_[w] == mark_stamp_) {
          mark_[w] = mark_stamp_ - 1;  // count once
          ++common;
        }
      }
    }
    if (common != 2) return false;
    *op = Op{};
    op->kind = Op::kCollapse;
    op->removed = {t1, t2};
    op->removed_vertex = u;
    op->cover_vertex = v;
    if (pinned_[u] || Released(u)) op->keep_covered.push_back(pos_[u]);
    for (int t : vertex_tris_[u]) {
      if (t == t1 || t == t2) continue;
      auto tri = tris_[t];
      for (int& w : tri) {
        if (w == u) w = v;
      }
      op->changed.push_back({t, tri});
    }
    if ((x - pos_[v]).squaredNorm() > 0.0) {
      KeepCoveredIfReleased(v, op);
      op->moves.push_back({v, x});
      AddFan(v, op);
    }
    return true;
  }

  // Flip of edge p-q (triangles (p, q, c) and (q, p, d) become (c, p, d) and (d, q, c)), with
  // optionally vertex c moved to x. False when c-d is already an edge or p or q would keep
  // fewer than three triangles.
  bool MakeFlip(int p, int q, Op* op, const Eigen::Vector3d* x = nullptr) {
    const int t = TriangleWithEdge(p, q), t2 = TriangleWithEdge(q, p);
    if (t < 0 || t2 < 0) return false;
    const int c = Third(tris_[t], p, q), d = Third(tris_[t2], p, q);
    if (c == d || vertex_tris_[p].size() <= 3 || vertex_tris_[q].size() <= 3) return false;
    for (int u : vertex_tris_[c]) {
      for (int w : tris_[u]) {
        if (w == d) return false;
      }
    }
    *op = Op{};
    op->kind = Op::kFlip;
    op->changed.push_back({t, {c, p, d}});
    op->changed.push_back({t2, {d, q, c}});
    if (x) {
      op->kind = Op::kSnap;
      op->moves.push_back({c, *x});
      AddFan(c, op);
    }
    return true;
  }

  // The point of the crease through (or near) x0 (m), from the planes of the surface around
  // vertices p and q (their one-rings and their triangles' projected centroids); false unless
  // the planes make a crease (rank 2) whose point is within `reach` of x0.
  bool CreasePoint(const Eigen::Vector3d& x0, int p, int q, double reach, Eigen::Vector3d* out) {
    std::vector<Plane> planes;
    auto add = [&](const Eigen::Vector3d& at) {
      const Eigen::Vector3d n = UnitGradient(at);
      if (n.squaredNorm() > 0.5) planes.push_back({at, n});
    };
    for (int v : {p, q}) {
      for (int t : vertex_tris_[v]) {
        const auto& tri = tris_[t];
        add(Project((pos_[tri[0]] + pos_[tri[1]] + pos_[tri[2]]) / 3.0, 4));
        for (int w : tri) add(pos_[w]);
      }
    }
    const double cos_crease = std::cos(s_.crease_angle_deg * M_PI / 180.0);
    int rank = 0;
    Eigen::Vector3d x;
    if (!SolveAt(x0, planes, cos_crease, &rank, &x) || rank != 2) return false;
    if ((x - x0).norm() > reach) return false;
    *out = x;
    return true;
  }

  // Where vertex v is best placed for the smallest angle of its fan: a pattern search in the
  // tangent plane at v (eight directions, steps from 0.2 cells halved down to 0.0125 cells,
  // within 0.5 cells of v; no triangle of the fan may turn over), projected onto the surface.
  // False when no step improves on v where it is.
  bool FanAngleTarget(int v, Eigen::Vector3d* out) {
    const auto& fan = vertex_tris_[v];
    const Eigen::Vector3d x0 = pos_[v];
    const Eigen::Vector3d n = UnitGradient(x0);
    if (fan.size() < 3 || n.squaredNorm() < 0.5) return false;
    const Eigen::Vector3d t1 = n.unitOrthogonal(), t2 = n.cross(t1);
    scratch_normals_.clear();
    for (int t : fan) scratch_normals_.push_back(Normal(Corners(tris_[t])));
    auto fan_min = [&](const Eigen::Vector3d& x) {
      double m = M_PI;
      for (size_t i = 0; i < fan.size(); ++i) {
        std::array<Eigen::Vector3d, 3> p = Corners(tris_[fan[i]]);
        for (int k = 0; k < 3; ++k) {
          if (tris_[fan[i]][k] == v) p[k] = x;
        }
        if (!(Normal(p).dot(scratch_normals_[i]) > 0.0)) return -1.0;
        m = std::min(m, TriangleMinAngle(p));
      }
      return m;
    };
    double best = fan_min(x0);
    if (!(best > 0.0)) return false;  // a degenerate triangle in the fan
    Eigen::Vector3d at = x0;
    for (double step = 0.2 * h_; step >= 0.0125 * h_ * 0.999; step *= 0.5) {
      for (int climb = 0; climb < 16; ++climb) {
        Eigen::Vector3d next = at;
        for (int k = 0; k < 8; ++k) {
          const double a = k * M_PI / 4;
          const Eigen::Vector3d x = at + step * (std::cos(a) * t1 + std::sin(a) * t2);
          if ((x - x0).norm() > 0.5 * h_) continue;
          const double m = fan_min(x);
          if (m > best * (1.0 + 1e-9)) best = m, next = x;
        }
        if (next == at) break;
        at = next;
      }
    }
    if (at == x0) return false;
    *out = Project(at, 4);
    return out->allFinite() && (*out - x0).norm() <= 0.5 * h_;
  }

  // Candidate operations for triangle t (sharper than the repair angle): collapses of its
  // edges, a snap of its widest corner onto the opposite edge (flip that edge, move the
  // corner onto it: onto the crease when the edge joins two crease vertices), flips of its
  // edges, slides of its crease corners along their crease, and relaxation moves of its corners
  // off the features. Keeps the candidate with the
  // largest smallest angle; returns whether one was done. (The candidates are ranked by their
  // angle alone, AngleAfter, and tried with every test in that order: the first to pass is the
  // one with the largest angle among those that pass.)
  bool RepairTriangle(int t) {
    const auto tri = tris_[t];
    Op op;
    std::vector<std::pair<double, Op>> ranked;
    auto consider = [&](const Op& candidate) {
      const double a = AngleAfter(candidate);
      if (a >= 0.0) ranked.push_back({a, candidate});
    };
    // Collapses.
    for (int k = 0; k < 3; ++k) {
      const int a = tri[k], b = tri[(k + 1) % 3];
      for (int dir = 0; dir < 2; ++dir) {
        const int u = dir ? b : a, v = dir ? a : b;  // u goes, v stays
        if (pinned_[u] && !(pinned_[v] && rank_[u] != 3)) continue;
        if (MakeCollapse(u, v, pos_[v], &op)) consider(op);
        if (!pinned_[u] && !pinned_[v] && dir == 0) {
          const Eigen::Vector3d mid = Project(0.5 * (pos_[u] + pos_[v]), 4);
          if (MakeCollapse(u, v, mid, &op)) consider(op);
        }
      }
    }
    // The widest corner c onto the opposite edge p-q.
    int kc = 0;
    double widest = -1.0;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d e1 = pos_[tri[(k + 1) % 3]] - pos_[tri[k]],
                            e2 = pos_[tri[(k + 2) % 3]] - pos_[tri[k]];
      const double angle = std::atan2(e1.cross(e2).norm(), e1.dot(e2));
      if (angle > widest) widest = angle, kc = k;
    }
    {
      const int c = tri[kc], p = tri[(kc + 1) % 3], q = tri[(kc + 2) % 3];
      const Eigen::Vector3d pq = pos_[q] - pos_[p];
      const double s = pq.dot(pos_[c] - pos_[p]) / pq.squaredNorm();
      if (!pinned_[c] && widest > M_PI / 2 && s > 0.05 && s < 0.95) {
        const Eigen::Vector3d foot = pos_[p] + s * pq;
        Eigen::Vector3d x;
        bool have = false;
        if (pinned_[p] && pinned_[q]) {
          have = CreasePoint(foot, p, q, 0.25 * pq.norm(), &x);
        } else {
          x = Project(foot, 4);
          have = x.allFinite();
        }
        // t runs c -> p -> q, so it is the triangle of the directed edge p -> q.
        if (have && MakeFlip(p, q, &op, &x)) {
          if (pinned_[p] && pinned_[q]) op.new_crease_vertex = c;
          KeepCoveredIfReleased(c, &op);
          consider(op);
        }
      }
    }
    // Flips of the edges (not between two crease vertices).
    for (int k = 0; k < 3; ++k) {
      const int p = tri[k], q = tri[(k + 1) % 3];
      if (pinned_[p] && pinned_[q]) continue;
      if (MakeFlip(p, q, &op)) consider(op);
    }
    // Slides of its crease corners (not corners of the solid) along the crease, half way to a
    // crease neighbour: where two creases run less than a cell apart, vertices facing each
    // other across the narrow face make needles that a shift by half a spacing removes.
    for (int c : tri) {
      if (!pinned_[c] || rank_[c] == 3) continue;
      for (int u : vertex_tris_[c]) {
        const auto& f = tris_[u];
        const int at = f[0] == c ? 0 : f[1] == c ? 1 : 2;
        const int w = f[(at + 1) % 3];  // each neighbour once
        if (!pinned_[w]) continue;
        const Eigen::Vector3d mid = 0.5 * (pos_[c] + pos_[w]);
        Eigen::Vector3d x;
        if (!CreasePoint(mid, c, w, 0.1 * (pos_[w] - pos_[c]).norm(), &x)) continue;
        op = Op{};
        op.kind = Op::kSlide;
        op.moves.push_back({c, x});
        AddFan(c, &op);
        op.keep_covered.push_back(pos_[c]);
        op.cover_vertex = c;
        consider(op);
      }
    }
    // Relaxation of the corners off the features: towards the centroid of the one-ring in the
    // tangent plane, back onto the surface.
    auto move = [&](int v, const Eigen::Vector3d& x) {
      op = Op{};
      op.kind = Op::kMove;
      op.moves.push_back({v, x});
      AddFan(v, &op);
      KeepCoveredIfReleased(v, &op);
      consider(op);
    };
    for (int v : tri) {
      if (pinned_[v]) continue;
      const Eigen::Vector3d x = RelaxTarget(v, 4);
      if ((x - pos_[v]).norm() <= 0.5 * h_) move(v, x);
    }
    auto try_ranked = [&]() -> const Op* {
      std::stable_sort(ranked.begin(), ranked.end(),
                       [](const auto& a, const auto& b) { return a.first > b.first; });
      for (const auto& [angle, candidate] : ranked) {
        if (TryOp(candidate)) return &candidate;
      }
      return nullptr;
    };
    const Op* done = try_ranked();
    // Where none passes, the corners off the features moved to where the smallest angle of
    // their fan is largest (FanAngleTarget): where the centroid overshoots or falls short,
    // every step above can leave some triangle of the fan sharper than t, and the best point of
    // the fan often does not.
    if (!done && s_.sliver_fan_moves) {
      ranked.clear();
      for (int v : tri) {
        Eigen::Vector3d x;
        if (!pinned_[v] && FanAngleTarget(v, &x)) move(v, x);
      }
      done = try_ranked();
    }
    if (!done) return false;
    const Op& best = *done;
    collapses_ += best.kind == Op::kCollapse;
    snaps_ += best.kind == Op::kSnap;
    sliver_flips_ += best.kind == Op::kFlip;
    sliver_moves_ += best.kind == Op::kMove || best.kind == Op::kSlide;
    return true;
  }

  // Step 4b: sweeps over the triangles sharper than sliver_angle_deg, worst first, each
  // repaired by RepairTriangle, until a sweep changes nothing (at most 10 sweeps), with the
  // deviation tolerance sliver_deviation_cells. Then, for those that remain, the fallback:
  // the same sweeps over them (and what they change) with the tolerance tripled at each stage up
  // to sliver_fallback_deviation_cells, and a last stage at that tolerance with their feature
  // vertices released, in up to sliver_release_rounds rounds.
  void RepairSlivers() {
    pinned_.assign(pos_.size(), 0);
    rank_.resize(pos_.size(), 0);
    target_.resize(pos_.size());
    for (size_t v = 0; v < pos_.size(); ++v) {
      pinned_[v] = is_feature_[v] && (pos_[v] - target_[v]).norm() <= 1e-6 * h_;
      if (!pinned_[v]) rank_[v] = 0;
    }
    dead_vertex_.assign(pos_.size(), 0);
    dead_tri_.assign(tris_.size(), 0);
    released_.assign(pos_.size(), 0);
    std::vector<int> look(tris_.size());
    for (int t = 0; t < static_cast<int>(tris_.size()); ++t) look[t] = t;
    tolerance_cells_ = s_.sliver_deviation_cells;
    look = RepairSweeps(std::move(look));
    const double fallback = s_.sliver_fallback_deviation_cells;
    if (look.empty() || !(fallback > s_.sliver_deviation_cells)) return;
    while (!look.empty() && tolerance_cells_ < fallback) {
      tolerance_cells_ = std::min(3.0 * std::max(tolerance_cells_, 1e-3), fallback);
      look = RepairSweeps(std::move(look));
    }
    // A feature vertex of a triangle that no operation could mend is released: it may move or
    // go, as long as the crease or corner point it marked stays as close to the new triangles as
    // the bound allows (keep_covered). On the platform those lie on blends smaller than a cell,
    // whose planes make false corners, or where a crease runs a fraction of a cell from a row of
    // vertices; keeping the corners pinned left the default cell at 5.8° and 8.2°. A round's
    // collapses and flips can make a new sharp triangle around a vertex still pinned, so the
    // next round releases the feature vertices of what is left (sliver_release_rounds).
    for (int round = 0; round < s_.sliver_release_rounds && !look.empty(); ++round) {
      bool any = false;
      for (int t : look) {
        for (int v : tris_[t]) {
          if (pinned_[v]) {
            pinned_[v] = 0;
            released_[v] = 1;
            any = true;
          }
        }
      }
      if (!any && round > 0) break;
      look = RepairSweeps(std::move(look));
    }
  }

  // Whether the fallback released v from its crease or corner (RepairSlivers).
  bool Released(int v) const {
    return static_cast<std::size_t>(v) < released_.size() && released_[v] != 0;
  }

  // When v is released and `op` moves it or its triangles: the point v marks must stay covered
  // by the triangles around v after `op`.
  void KeepCoveredIfReleased(int v, Op* op) const {
    if (!Released(v)) return;
    op->keep_covered.push_back(pos_[v]);
    op->cover_vertex = v;
  }

  // Up to 10 sweeps of RepairTriangle over the triangles of `look` sharper than
  // sliver_angle_deg, worst first; returns the triangles still sharper (sorted).
  std::vector<int> RepairSweeps(std::vector<int> look) {
    const double limit = s_.sliver_angle_deg * M_PI / 180.0;
    std::vector<std::pair<double, int>> bad;
    // Triangles to look at: those given at first, then those of the last sweep's list and those
    // its operations changed (every other triangle kept its angles, so this finds the same list
    // as a scan of the whole mesh).
    for (int sweep = 0; sweep < 10; ++sweep) {
      Poll();
      std::sort(look.begin(), look.end());
      look.erase(std::unique(look.begin(), look.end()), look.end());
      bad.clear();
      for (int t : look) {
        if (dead_tri_[t]) continue;
        const double a = TriangleMinAngle(Corners(tris_[t]));
        if (a < limit) bad.push_back({a, t});
      }
      std::sort(bad.begin(), bad.end());
      touched_.clear();
      long changed = 0;
      for (const auto& [angle, t] : bad) {
        if (dead_tri_[t] || !(TriangleMinAngle(Corners(tris_[t])) < limit)) continue;
        changed += RepairTriangle(t);
      }
      look = touched_;
      for (const auto& entry : bad) look.push_back(entry.second);
      if (changed == 0) break;
    }
    std::vector<int> left;
    for (int t : look) {
      if (!dead_tri_[t] && TriangleMinAngle(Corners(tris_[t])) < limit) left.push_back(t);
    }
    std::sort(left.begin(), left.end());
    left.erase(std::unique(left.begin(), left.end()), left.end());
    return left;
  }

  // Drops the vertices and triangles the repair removed and renumbers the rest.
  void Compact() {
    std::vector<int> index(pos_.size(), -1);
    int n = 0;
    for (size_t v = 0; v < pos_.size(); ++v) {
      if (dead_vertex_[v]) continue;
      index[v] = n;
      pos_[n] = pos_[v];
      is_feature_[n] = is_feature_[v];
      rank_[n] = rank_[v];
      ++n;
    }
    pos_.resize(n);
    is_feature_.resize(n);
    rank_.resize(n);
    int m = 0;
    for (size_t t = 0; t < tris_.size(); ++t) {
      if (dead_tri_[t]) continue;
      for (int k = 0; k < 3; ++k) tris_[m][k] = index[tris_[t][k]];
      ++m;
    }
    tris_.resize(m);
    vertex_tris_.assign(n, {});
    for (int t = 0; t < m; ++t) {
      for (int v : tris_[t]) vertex_tris_[v].push_back(t);
    }
    hash_.clear();
    for (int v = 0; v < n; ++v) HashInsert(v);
    tri_cells_built_ = false;  // triangles renumbered
    dead_vertex_.clear();
    dead_tri_.clear();
    pinned_.clear();
  }

  // Spatial hash of vertex positions on cells of edge h, for the separation test.
  long long Key(const Eigen::Vector3d& p) const {
    return KeyOf(static_cast<long long>(std::floor(p.x() / h_)),
                 static_cast<long long>(std::floor(p.y() / h_)),
                 static_cast<long long>(std::floor(p.z() / h_)));
  }
  static long long KeyOf(long long i, long long j, long long k) {
    return ((i & 0x1fffff) << 42) | ((j & 0x1fffff) << 21) | (k & 0x1fffff);
  }
  void HashInsert(int v) { hash_[Key(pos_[v])].push_back(v); }
  void HashErase(int v) {
    auto& list = hash_[Key(pos_[v])];
    list.erase(std::remove(list.begin(), list.end(), v), list.end());
  }
  bool TooClose(int v, const Eigen::Vector3d& x, int ignore = -1) const {
    return AnyVertexWithin(x, s_.min_separation_cells * h_,
                           [&](int w) { return w == v || w == ignore; });
  }
  // Whether a vertex w for which skip(w) is false lies closer than r to x (searched in the hash
  // cells around x: found for r up to h).
  template <class Skip>
  bool AnyVertexWithin(const Eigen::Vector3d& x, double r, const Skip& skip) const {
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const auto it = hash_.find(Key(x + h_ * Eigen::Vector3d(dx, dy, dz)));
          if (it == hash_.end()) continue;
          for (int w : it->second) {
            if (!skip(w) && (pos_[w] - x).squaredNorm() < r * r) return true;
          }
        }
      }
    }
    return false;
  }

  internal::PointField solid_;  // point values (pruned tapes, bit-identical to the solid's)
  const FeatureSettings& s_;
  double h_ = 0.0;
  std::vector<Eigen::Vector3d> pos_;
  std::vector<std::array<int, 3>> tris_;
  std::vector<std::vector<int>> vertex_tris_;
  std::vector<Eigen::Vector3d> vertex_normal_;
  std::vector<Plane> tri_plane_;
  std::vector<int> tri_stamp_;
  std::vector<int> ring_;    // scratch of VertexNormalsSpread
  std::vector<int> nearby_;  // scratch of ChangedTrianglesMeetOthers
  // Triangles by the cells (Key) their boxes overlap, for ChangedTrianglesMeetOthers (made at
  // its first call, again after Compact; a triangle is added wherever it is checked).
  std::unordered_map<long long, std::vector<int>> tri_cells_;
  bool tri_cells_built_ = false;
  std::vector<int> near_mark_;  // per triangle: near_stamp_ when in nearby_
  int near_stamp_ = 0;
  std::vector<char> dirty_;  // per triangle: to be tried by the next FlipPass
  int round_stamp_ = 0;
  std::vector<int> mark_;         // scratch of MakeCollapse (link condition)
  std::vector<int> tri_mark_;     // scratch of NeighbourhoodDeviation
  double tolerance_cells_ = 0.0;  // RepairSlivers: this stage's deviation tolerance (cells)
  std::vector<int> touched_;      // RepairSlivers: triangles changed in this sweep
  std::vector<Eigen::Vector3d> scratch_normals_;  // AngleAfter
  int tri_stamp2_ = 0;
  int mark_stamp_ = 0;
  std::vector<bool> is_feature_;
  std::vector<int> rank_;                // per vertex: 2 crease, 3 corner (last round), else 0
  std::vector<Eigen::Vector3d> target_;  // per feature vertex: its target (last round)
  std::vector<char> released_;  // per vertex: unpinned by the fallback's last stage (RepairSlivers)
  std::vector<char> pinned_;    // per vertex: on its crease or corner (RepairSlivers)
  std::vector<char> dead_vertex_, dead_tri_;  // removed by collapses, until Compact
  long collapses_ = 0, snaps_ = 0, sliver_flips_ = 0, sliver_moves_ = 0;
  std::unordered_map<long long, std::vector<int>> hash_;
  long moved_ = 0, flipped_ = 0, rejected_ = 0, relaxed_ = 0, inserted_ = 0;
};

void Validate(const FeatureSettings& s) {
  auto bad = [](const std::string& field, double value, const std::string& rule) {
    throw std::invalid_argument("SharpenFeatures: settings." + field + " = " +
                                std::to_string(value) + ": " + rule);
  };
  if (!(s.cell_size > 0.0) || !std::isfinite(s.cell_size))
    bad("cell_size", s.cell_size, "must be a finite length > 0 m");
  if (!(s.crease_angle_deg > 0.0 && s.crease_angle_deg < 180.0))
    bad("crease_angle_deg", s.crease_angle_deg, "must be in (0, 180)");
  if (s.iterations < 0) bad("iterations", s.iterations, "must be >= 0");
  if (!(s.singular_threshold > 0.0 && s.singular_threshold < 1.0))
    bad("singular_threshold", s.singular_threshold, "must be in (0, 1)");
  if (!(s.max_move_cells > 0.0) || !std::isfinite(s.max_move_cells))
    bad("max_move_cells", s.max_move_cells, "must be > 0");
  if (!(s.min_separation_cells >= 0.0) || !std::isfinite(s.min_separation_cells)) {
    bad("min_separation_cells", s.min_separation_cells, "must be >= 0");
  }
  if (!(s.min_angle_deg >= 0.0 && s.min_angle_deg < 60.0))
    bad("min_angle_deg", s.min_angle_deg, "must be in [0, 60)");
  if (!(s.relax_angle_deg >= 0.0 && s.relax_angle_deg < 60.0))
    bad("relax_angle_deg", s.relax_angle_deg, "must be in [0, 60)");
  if (!(s.sliver_angle_deg >= 0.0 && s.sliver_angle_deg < 60.0))
    bad("sliver_angle_deg", s.sliver_angle_deg, "must be in [0, 60)");
  if (!(s.sliver_deviation_cells >= 0.0) || !std::isfinite(s.sliver_deviation_cells))
    bad("sliver_deviation_cells", s.sliver_deviation_cells, "must be >= 0");
  if (!(s.sliver_fallback_deviation_cells >= 0.0) ||
      !std::isfinite(s.sliver_fallback_deviation_cells))
    bad("sliver_fallback_deviation_cells", s.sliver_fallback_deviation_cells, "must be >= 0");
  if (s.sliver_release_rounds < 1 || s.sliver_release_rounds > 10)
    bad("sliver_release_rounds", s.sliver_release_rounds, "must be in [1, 10]");
}

}  // namespace

TriangleMesh SharpenFeatures(const CompiledSolid& solid, TriangleMesh mesh,
                             const FeatureSettings& settings, FeatureStats* stats) {
  const auto start = std::chrono::steady_clock::now();
  Validate(settings);
  Sharpener sharpener(solid, mesh, settings);
  TriangleMesh out = sharpener.Run(stats);
  if (stats)
    stats->seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace spidarcad::modeling
