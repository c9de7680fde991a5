// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/surface_mesher.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <iterator>
#include <limits>
#include <memory>
#include <queue>
#include <stdexcept>
#include <string>
#include <vector>

#include "lattice_mesher.h"
#include "point_field.h"
#include "triangle_predicates.h"

namespace spidarcad::modeling {

namespace {

using internal::PointField;
using internal::TrianglesMeet;

// The six tetrahedra of the Kuhn (Freudenthal) subdivision of a cube, as corner codes
// (bit 0: +x, bit 1: +y, bit 2: +z). Every cube of the grid is split along the same
// diagonal 0-7, so the tetrahedra of neighbouring cubes share whole faces.
constexpr std::array<std::array<int, 4>, 6> kKuhnTets = {{
    {0, 1, 3, 7},
    {0, 1, 5, 7},
    {0, 2, 3, 7},
    {0, 2, 6, 7},
    {0, 4, 5, 7},
    {0, 4, 6, 7},
}};

// Grid vertex values within kZeroBand cells of zero always count as exactly zero (see
// VertexValue): far above rounding noise (1e-17 m) on faces that lie in a grid plane, and a
// blend's tail (-1e-12 m), far below any error that matters. SurfaceMeshSettings::snap_cells
// widens the band.
constexpr double kZeroBand = 1e-6;
// Mesh vertices at a zero grid vertex that the clean-up could not merge move the first of these
// fractions of their grid edge towards its inside end that keeps the triangles around them
// unfolded (see Cleaner::SeparateCoincident); the last is taken regardless.
constexpr std::array<double, 3> kZeroOffsets = {0.05, 1e-3, 1e-5};
// With snapping, the clean-up ends by mending the triangles still sharper than
// SurfaceMeshSettings::mend_angle_deg (Cleaner::Mend). A pinch among their corners opens wider
// first: its vertices move, along the same grid edges, the one of these fractions that gives
// their triangles the largest smallest angle (Cleaner::WidenPinch).
constexpr std::array<double, 4> kWideZeroOffsets = {0.1, 0.15, 0.2, 0.25};
// The clean-up merges vertices closer than kCoincident cells without geometric checks.
constexpr double kCoincident = 1e-4;

// Hash map from non-negative long keys to values of type V: open addressing with linear
// probing in a power-of-two table that doubles at half load: one probe into a flat array
// instead of std::unordered_map's allocated node per entry. BrickMap's index of bricks, and the
// unsnapped grid vertices.
template <class V>
class FlatMap {
 public:
  FlatMap() : keys_(kInitial, kEmpty), values_(kInitial) {}
  // The value of key, or null.
  const V* Find(long key) const {
    for (size_t i = Slot(key);; i = (i + 1) & (keys_.size() - 1)) {
      if (keys_[i] == key) return &values_[i];
      if (keys_[i] == kEmpty) return nullptr;
    }
  }
  // Number of keys.
  size_t size() const { return size_; }
  // Adds key (not present) with value.
  void Insert(long key, V value) {
    if (2 * (size_ + 1) > keys_.size()) Grow();
    Place(key, value);
    ++size_;
  }

 private:
  static constexpr long kEmpty = -1;
  static constexpr size_t kInitial = 1024;
  size_t Slot(long key) const {
    // Fibonacci hashing of the key's bits (grid ids are dense along x).
    return static_cast<size_t>((static_cast<unsigned long long>(key) * 0x9E3779B97F4A7C15ull) >>
                               (64 - bits_));
  }
  void Place(long key, V value) {
    size_t i = Slot(key);
    while (keys_[i] != kEmpty) i = (i + 1) & (keys_.size() - 1);
    keys_[i] = key;
    values_[i] = value;
  }
  void Grow() {
    std::vector<long> keys(2 * keys_.size(), kEmpty);
    std::vector<V> values(2 * keys_.size());
    keys.swap(keys_);
    values.swap(values_);
    ++bits_;
    for (size_t i = 0; i < keys.size(); ++i) {
      if (keys[i] != kEmpty) Place(keys[i], values[i]);
    }
  }
  std::vector<long> keys_;
  std::vector<V> values_;
  size_t size_ = 0;
  int bits_ = 10;  // log2 of the table size
};

// Map from grid vertices to up to kSlots values each, in bricks of 4 x 4 x 4 vertices: one
// probe of a small FlatMap per brick (none while the lookups stay in the last brick), then the
// brick's own arrays. The mesher's grid-value and edge-vertex caches, read by neighbouring cells
// in turn: a brick stays in cache across them, where a table keyed by single vertices spreads
// neighbours over the whole table (a cache miss per lookup).
template <class V, int kSlots>
class BrickMap {
 public:
  using Index3 = std::array<long, 3>;
  BrickMap() = default;
  // vertices: grid vertices per axis.
  explicit BrickMap(const Index3& vertices)
      : bricks_x_((vertices[0] + 3) / 4), bricks_y_((vertices[1] + 3) / 4) {}
  // Slot `slot` of grid vertex v, or null when it was not inserted.
  const V* Find(const Index3& v, int slot) const {
    const Brick* b = FindBrick(Key(v));
    const int local = Local(v);
    if (b == nullptr || !((b->set[slot] >> local) & 1u)) return nullptr;
    return &b->values[slot * 64 + local];
  }
  // Sets slot `slot` of grid vertex v (not present) to value.
  void Insert(const Index3& v, int slot, V value) {
    const long key = Key(v);
    Brick* b = const_cast<Brick*>(FindBrick(key));
    if (b == nullptr) {
      index_.Insert(key, static_cast<int>(bricks_.size()));
      b = &bricks_.emplace_back();
      last_key_ = key;
      last_ = b;
    }
    const int local = Local(v);
    b->set[slot] |= std::uint64_t{1} << local;
    b->values[slot * 64 + local] = value;
  }

 private:
  struct Brick {
    std::array<std::uint64_t, kSlots> set{};  // bit (x & 3) + 4 (y & 3) + 16 (z & 3) per slot
    std::array<V, 64 * kSlots> values{};
  };
  long Key(const Index3& v) const {
    return (v[0] >> 2) + bricks_x_ * ((v[1] >> 2) + bricks_y_ * (v[2] >> 2));
  }
  static int Local(const Index3& v) {
    return static_cast<int>((v[0] & 3) | ((v[1] & 3) << 2) | ((v[2] & 3) << 4));
  }
  const Brick* FindBrick(long key) const {
    if (key == last_key_) return last_;
    const int* at = index_.Find(key);
    if (at == nullptr) return nullptr;
    last_key_ = key;
    last_ = &bricks_[static_cast<size_t>(*at)];
    return last_;
  }
  long bricks_x_ = 1, bricks_y_ = 1;
  FlatMap<int> index_;        // brick key -> its index in bricks_
  std::deque<Brick> bricks_;  // a deque: bricks stay where they are as it grows
  mutable long last_key_ = -1;
  mutable const Brick* last_ = nullptr;
};

// A fan whose triangles' normals lie within this angle of one another counts as flat (planar but
// for rounding on the planar faces of CSG solids; no fan of a sphere meshed at r/50 is).
constexpr double kFlatFanDegrees = 0.01;

// A triangle's edges k = 0, 1, 2 ordered by `len` (lengths or squared lengths), shortest first,
// ties by k.
std::array<int, 3> EdgesShortestFirst(const double (&len)[3]) {
  std::array<int, 3> order = {0, 1, 2};
  std::sort(order.begin(), order.end(),
            [&](int i, int j) { return len[i] < len[j] || (len[i] == len[j] && i < j); });
  return order;
}

// Post-pass of MeshSurface: edge collapses (with the link condition, so a closed manifold
// stays a closed manifold of the same genus) and edge flips that remove the zero-area, needle
// and cap triangles marching tetrahedra produces where the surface passes at or near grid
// vertices.
class Cleaner {
 public:
  // solid: the field whose gradient says which way is out (FacesOut). cancel (may be null) is
  // polled before every gradient evaluation; when raised, MeshingCancelled.
  Cleaner(const PointField& solid, std::vector<Eigen::Vector3d>* positions,
          std::vector<std::array<int, 3>>* triangles, const std::atomic<bool>* cancel = nullptr)
      : solid_(solid),
        cancel_(cancel),
        pos_(*positions),
        tris_(*triangles),
        alive_(triangles->size(), true),
        vertex_tris_(positions->size()),
        gradient_(positions->size()),
        has_gradient_(positions->size(), false),
        pinch_of_(positions->size(), -1) {
    std::vector<int> degree(pos_.size(), 0);
    for (const auto& tri : tris_) {
      for (int v : tri) ++degree[v];
    }
    for (size_t v = 0; v < pos_.size(); ++v) vertex_tris_[v].reserve(degree[v]);
    for (size_t t = 0; t < tris_.size(); ++t) {
      for (int k = 0; k < 3; ++k) vertex_tris_[tris_[t][k]].push_back(static_cast<int>(t));
    }
  }

  // Runs the passes: collapse edges shorter than short_edge and the short edge of needles,
  // flip the long edge of caps (angles below small_angle_rad). Returns collapses and flips.
  // Vertices closer than `coincident` are merged without geometric checks.
  // With angle_guard, no collapse leaves a triangle sharper than both small_angle_rad and the
  // sharpest triangle it replaces.
  void Run(double short_edge, double small_angle_rad, double max_edge, double coincident,
           bool angle_guard, long* collapses, long* flips) {
    angle_guard_ = angle_guard;
    max_edge2_ = max_edge * max_edge;
    coincident2_ = coincident * coincident;
    small_angle_ = small_angle_rad;
    sin_small_angle_ = std::sin(small_angle_rad);
    cell_ = max_edge / 1.5;
    for (int pass = 0; pass < 4; ++pass) {
      long changed = 0;
      for (size_t t = 0; t < tris_.size(); ++t) {
        if (!alive_[t]) continue;
        changed += Improve(static_cast<int>(t), short_edge, small_angle_rad, collapses, flips);
      }
      if (changed == 0) break;
    }
  }

  // Moves each live vertex made at a snapped grid vertex (inward[v] non-zero) and not moved by
  // SeparateCoincident onto the surface by Newton steps, where that turns none of its triangles
  // over and folds none (Unfolded). Returns the number moved.
  long ProjectSnapped(const std::vector<Eigen::Vector3d>& inward) {
    long moved = 0;
    for (size_t i = 0; i < pos_.size(); ++i) {
      const int v = static_cast<int>(i);
      if (vertex_tris_[v].empty() || inward[v].squaredNorm() == 0.0 || pinch_of_[v] >= 0) continue;
      const Eigen::Vector3d p = pos_[v];
      Eigen::Vector3d x = p;
      for (int step = 0; step < 3; ++step) {
        Eigen::Vector3d g;
        const double f = solid_.ValueAndGradient(x, &g);
        const double g2 = g.squaredNorm();
        if (std::abs(f) <= 1e-9 * cell_ || !(g2 > 1e-12)) break;
        x -= (f / g2) * g;
      }
      if (x == p || !x.allFinite() || (x - p).squaredNorm() > 0.25 * cell_ * cell_) continue;
      pos_[v] = x;
      if (Unfolded(v, p)) {
        has_gradient_[v] = false;
        ++moved;
      } else {
        pos_[v] = p;
      }
    }
    return moved;
  }

  // After Run, SeparateCoincident and ProjectSnapped: the corners of the triangles still sharper
  // than Run's small angle relax (Relax), and what that leaves gets one more round of flips and
  // collapses.
  void Polish(double short_edge, long* collapses, long* flips) {
    for (int sweep = 0; sweep < 3; ++sweep) {
      long moved = 0;
      for (size_t t = 0; t < tris_.size(); ++t) {
        if (!alive_[t]) continue;
        const auto tri = tris_[t];
        if (!Sharp(tri, 0.0, sin_small_angle_)) continue;
        for (int v : tri) moved += Relax(v);
      }
      relaxed_ += moved;
      if (moved == 0) break;
    }
    for (size_t t = 0; t < tris_.size(); ++t) {
      if (alive_[t]) Improve(static_cast<int>(t), short_edge, small_angle_, collapses, flips);
    }
  }

  // After Polish (and CoarsenFlat): each triangle still sharper than `angle_rad` gets, in turn
  // until one is done, its pinch opened wider (WidenPinch), Improve's collapses and flips with
  // edges up to `max_edge` (Run's bound is 1.5 cells; a grid cube's diagonal is 1.73), its cap
  // flattened into the neighbour across its long edge (FlattenCap), a flip of one of its other
  // edges, or a relaxation of a corner (Relax). The steps that move vertices (the pinch, the cap,
  // the relaxation) keep what they change within the larger of its old sampled distance to the
  // surface and the mesh's largest one before the pass (MendDeviationBound, sampled once, before
  // the first step), so they never raise the latter; Improve's steps keep their own guards. A
  // mesh with no triangle under `angle_rad` is left as it is, and not sampled.
  void Mend(double angle_rad, double max_edge, long* collapses, long* flips) {
    const double run_max_edge2 = max_edge2_;
    max_edge2_ = max_edge * max_edge;
    const double sine = std::sin(angle_rad);
    mesh_deviation_ = -1.0;
    for (int pass = 0; pass < 4; ++pass) {
      long changed = 0;
      for (size_t i = 0; i < tris_.size(); ++i) {
        if (!alive_[i] || !Sharp(tris_[i], 0.0, sine)) continue;
        MendDeviationBound();  // sampled before the first step changes anything
        changed += MendTriangle(static_cast<int>(i), collapses, flips);
      }
      if (changed == 0) break;
    }
    max_edge2_ = run_max_edge2;
  }

  // Collapses the edges shorter than `edge` (shortest first in each triangle) where the vertex
  // that goes has a flat fan: every triangle around it within kFlatFanDegrees of one plane, so
  // the surface keeps its shape. Collapse's other guards hold as in Run (facing, folds, the 1.5
  // cell edge bound), with the angle guard on: no fan's worst triangle gets sharper than it was
  // or than Run's small angle. Returns collapses.
  long CoarsenFlat(double edge) {
    const bool angle_guard = angle_guard_;
    angle_guard_ = true;
    long done = 0;
    const double edge2 = edge * edge;
    for (int pass = 0; pass < 4; ++pass) {
      long changed = 0;
      for (size_t t = 0; t < tris_.size(); ++t) {
        if (!alive_[t]) continue;
        const auto tri = tris_[t];
        double len2[3];
        for (int k = 0; k < 3; ++k) len2[k] = (pos_[tri[(k + 1) % 3]] - pos_[tri[k]]).squaredNorm();
        for (int k : EdgesShortestFirst(len2)) {
          if (!(len2[k] < edge2)) break;
          const int u = tri[k], v = tri[(k + 1) % 3];
          if ((FlatFan(u) && Collapse(u, v)) || (FlatFan(v) && Collapse(v, u))) {
            ++changed;
            break;
          }
        }
      }
      done += changed;
      if (changed == 0) break;
    }
    angle_guard_ = angle_guard;
    return done;
  }

  // Vertices moved by Relax in Run.
  long relaxed() const { return relaxed_; }

  // Moves apart the live vertices that still share one position after Run (the link condition
  // kept them from merging: the zero set pinches there, e.g. a hole about one cell wide whose
  // diameter is a grid edge with both ends at zero, so the surface touches itself along it):
  // each moves along its own grid edge into the solid, by the first fraction of kZeroOffsets of
  // inward[v] (its edge, zero end to inside end) that turns none of its triangles over and folds
  // none onto a neighbour, so the surface stays embedded, the two sides of the pinch end up a
  // tenth of a cell apart (not a crack that TetGen fills with flat tets), and no weld tolerance
  // downstream joins them. With `stuck` (snapping), each is tested against the triangles of the
  // whole group too: the group's fans are the two sides of the pinch, which share no vertex, so
  // a move tested against its own neighbours alone could push a triangle through the other side;
  // and a member that still folds at the smallest fraction goes to `stuck`: the pinch is not
  // embedded. Without it the test is the one of before 2026-12-05 (the unsnapped mesh stays the
  // same bit for bit). Each group is kept as a pinch (pinch_of_; WidenPinch). Returns the number
  // moved.
  long SeparateCoincident(const std::vector<Eigen::Vector3d>& inward, std::vector<int>* stuck) {
    inward_ = &inward;
    std::vector<int> live;
    for (size_t v = 0; v < pos_.size(); ++v) {
      if (!vertex_tris_[v].empty()) live.push_back(static_cast<int>(v));
    }
    auto less = [&](int a, int b) {
      const Eigen::Vector3d &p = pos_[a], &q = pos_[b];
      return p.x() < q.x() ||
             (p.x() == q.x() && (p.y() < q.y() || (p.y() == q.y() && p.z() < q.z())));
    };
    std::sort(live.begin(), live.end(), less);
    long moved = 0;
    for (size_t i = 0; i < live.size();) {
      size_t j = i + 1;
      while (j < live.size() && pos_[live[j]] == pos_[live[i]]) ++j;
      if (j - i > 1) {
        // All of the group first (each side of the pinch moves off the other), then each one
        // steps back to a smaller fraction while its triangles fold.
        const Eigen::Vector3d start = pos_[live[i]];
        for (size_t k = i; k < j; ++k) pos_[live[k]] = start + kZeroOffsets[0] * inward[live[k]];
        group_.assign(live.begin() + i, live.begin() + j);
        const std::vector<int>* others = stuck != nullptr ? &group_ : nullptr;
        pinches_.push_back({start, group_, false});
        for (size_t k = i; k < j; ++k) {
          const int v = live[k];
          pinch_of_[v] = static_cast<int>(pinches_.size()) - 1;
          for (size_t f = 1; f < kZeroOffsets.size() && !Unfolded(v, start, others); ++f)
            pos_[v] = start + kZeroOffsets[f] * inward[v];
          moved += inward[v].squaredNorm() > 0.0;
          has_gradient_[v] = false;
        }
        // Each member again, where the others ended up (a later one may have stepped back).
        if (stuck != nullptr) {
          for (size_t k = i; k < j; ++k) {
            if (!Unfolded(live[k], start, &group_)) stuck->push_back(live[k]);
          }
        }
      }
      i = j;
    }
    return moved;
  }

  // Whether the triangles of v, with v moved from `before` to where it is now, keep facing the
  // way they did (positive dot product of old and new normals) and meet no triangle around them
  // (nor one of the vertices `others`, may be null).
  bool Unfolded(int v, const Eigen::Vector3d& before, const std::vector<int>* others = nullptr) {
    const Eigen::Vector3d now = pos_[v];
    changed_.clear();
    for (int t : vertex_tris_[v]) {
      const Eigen::Vector3d n_new = Normal(tris_[t]);
      pos_[v] = before;
      const Eigen::Vector3d n_old = Normal(tris_[t]);
      pos_[v] = now;
      if (!(n_new.dot(n_old) > 0.0)) return false;
      changed_.emplace_back(t, tris_[t]);
    }
    return !WouldMeet(changed_, -1, -1, others);
  }

  // Removes dead triangles and unused vertices (renumbering, order kept).
  void Compact() {
    std::vector<int> new_id(pos_.size(), -1);
    std::vector<std::array<int, 3>> tris;
    for (size_t t = 0; t < tris_.size(); ++t) {
      if (alive_[t]) tris.push_back(tris_[t]);
    }
    std::vector<Eigen::Vector3d> pos;
    for (auto& tri : tris) {
      for (int& v : tri) {
        if (new_id[v] < 0) {
          new_id[v] = static_cast<int>(pos.size());
          pos.push_back(pos_[v]);
        }
        v = new_id[v];
      }
    }
    // Keep the mesher's vertex order (first use order changes it): sort ids by old index.
    std::vector<int> order;  // old ids in increasing order
    for (size_t v = 0; v < new_id.size(); ++v) {
      if (new_id[v] >= 0) order.push_back(static_cast<int>(v));
    }
    std::vector<int> remap(pos.size());
    for (size_t i = 0; i < order.size(); ++i) remap[new_id[order[i]]] = static_cast<int>(i);
    std::vector<Eigen::Vector3d> sorted(pos.size());
    for (size_t i = 0; i < order.size(); ++i) sorted[i] = pos_[order[i]];
    for (auto& tri : tris) {
      for (int& v : tri) v = remap[v];
    }
    pos_ = std::move(sorted);
    tris_ = std::move(tris);
  }

 private:
  Eigen::Vector3d Normal(const std::array<int, 3>& t) const {
    return (pos_[t[1]] - pos_[t[0]]).cross(pos_[t[2]] - pos_[t[0]]);
  }

  // Unit gradient of the field at p (zero where it vanishes).
  Eigen::Vector3d UnitGradient(const Eigen::Vector3d& p) const {
    if (cancel_ != nullptr && cancel_->load(std::memory_order_relaxed)) throw MeshingCancelled();
    Eigen::Vector3d g;
    solid_.ValueAndGradient(p, &g);
    const double n = g.norm();
    return n > 0.0 ? Eigen::Vector3d(g / n) : Eigen::Vector3d::Zero();
  }

  // Unit gradient at vertex v, cached until v moves.
  const Eigen::Vector3d& VertexGradient(int v) {
    if (!has_gradient_[v]) {
      gradient_[v] = UnitGradient(pos_[v]);
      has_gradient_[v] = true;
    }
    return gradient_[v];
  }

  // Whether triangle t faces out of the solid: its normal has a positive dot product with the
  // field's gradient at one or more of its corners (cached: the clean-up moves no vertex) or
  // its centroid. Several points, because at a crease a corner's gradient is that of one face
  // only, and a triangle of the other face may see only crease corners. The check is against
  // the field, not the triangle's previous normal, so successive collapses and flips that each
  // turn a triangle a little cannot add up to turning it over.
  bool FacesOut(const std::array<int, 3>& t) {
    const Eigen::Vector3d n = Normal(t);
    for (int v : t) {
      if (n.dot(VertexGradient(v)) > 0.0) return true;
    }
    return n.dot(UnitGradient((pos_[t[0]] + pos_[t[1]] + pos_[t[2]]) / 3.0)) > 0.0;
  }

  // Whether one of the `changed` triangles (id, new corners) would meet, other than along what
  // they share, a live triangle incident to one of its corners (with the changes applied;
  // `dying` triangles left out), or of one of the vertices `others` (may be null). Collapses and
  // flips only reshape triangles around them, so this local test keeps them from folding a
  // triangle onto a neighbour or a fan over itself.
  bool WouldMeet(const std::vector<std::pair<int, std::array<int, 3>>>& changed, int dying0,
                 int dying1, const std::vector<int>* others = nullptr) {
    // Each triangle once: a stamp per triangle marks the changed and dying ones (skipped) and
    // those already gathered, and each gathered one keeps its corners and box for every changed
    // triangle it is tested against. The answer does not depend on the order of the tests.
    if (tri_stamp_.size() != tris_.size()) tri_stamp_.assign(tris_.size(), 0);
    if (++stamp_ == 0) {  // wrapped: clear the stamps
      std::fill(tri_stamp_.begin(), tri_stamp_.end(), 0);
      stamp_ = 1;
    }
    for (const auto& c : changed) tri_stamp_[c.first] = stamp_;
    if (dying0 >= 0) tri_stamp_[dying0] = stamp_;
    if (dying1 >= 0) tri_stamp_[dying1] = stamp_;
    nearby_.clear();
    for (const auto& [id, tri] : changed) {
      for (int w : tri) {
        for (int u : vertex_tris_[w]) {
          if (tri_stamp_[u] == stamp_ || !alive_[u]) continue;
          tri_stamp_[u] = stamp_;
          Gather(tris_[u], &nearby_);
        }
      }
    }
    if (others != nullptr) {
      for (int w : *others) {
        for (int u : vertex_tris_[w]) {
          if (tri_stamp_[u] == stamp_ || !alive_[u]) continue;
          tri_stamp_[u] = stamp_;
          Gather(tris_[u], &nearby_);
        }
      }
    }
    changed_corners_.clear();
    for (const auto& c : changed) Gather(c.second, &changed_corners_);
    for (size_t i = 0; i < changed_corners_.size(); ++i) {
      const GatheredTriangle& a = changed_corners_[i];
      // Against the other changed triangles (each pair once) ...
      for (size_t j = i + 1; j < changed_corners_.size(); ++j) {
        if (a.Meets(changed_corners_[j])) return true;
      }
      // ... and the unchanged ones nearby.
      for (const GatheredTriangle& b : nearby_) {
        if (a.Meets(b)) return true;
      }
    }
    return false;
  }

  // A triangle's corners (ids and positions), normal and bounding box, as WouldMeet tests it.
  struct GatheredTriangle {
    GatheredTriangle() {}  // left unset (Gather sets every field)
    std::array<int, 3> ids;
    std::array<Eigen::Vector3d, 3> p;
    Eigen::Vector3d n;  // (p[1] - p[0]).cross(p[2] - p[0])
    Eigen::Vector3d lo, hi;
    // Whether the boxes meet (closed boxes, as Eigen::AlignedBox3d::intersects).
    bool Overlaps(const GatheredTriangle& o) const {
      return (lo.array() <= o.hi.array()).all() && (o.lo.array() <= hi.array()).all();
    }
    // TrianglesMeet of the two where their boxes meet (its form with the normals, which reads
    // most sides of corners against planes from them: the same answer).
    bool Meets(const GatheredTriangle& o) const {
      if (!Overlaps(o)) return false;
      const double diagonal2 = (hi.cwiseMax(o.hi) - lo.cwiseMin(o.lo)).squaredNorm();
      return TrianglesMeet(ids, p, n, o.ids, o.p, o.n, diagonal2);
    }
  };
  // Appends triangle t, gathered, to *out (built in place: no copy of the record).
  void Gather(const std::array<int, 3>& t, std::vector<GatheredTriangle>* out) const {
    GatheredTriangle& g = out->emplace_back();
    g.ids = t;
    g.p = {pos_[t[0]], pos_[t[1]], pos_[t[2]]};
    g.n = (g.p[1] - g.p[0]).cross(g.p[2] - g.p[0]);
    g.lo = g.p[0].cwiseMin(g.p[1]).cwiseMin(g.p[2]);
    g.hi = g.p[0].cwiseMax(g.p[1]).cwiseMax(g.p[2]);
  }

  static double MinAngle(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                         const Eigen::Vector3d& c) {
    auto angle = [](const Eigen::Vector3d& u, const Eigen::Vector3d& w) {
      return std::atan2(u.cross(w).norm(), u.dot(w));
    };
    return std::min({angle(b - a, c - a), angle(a - b, c - b), angle(a - c, b - c)});
  }

  // Whether every triangle around v has its unit normal within kFlatFanDegrees of the first's.
  bool FlatFan(int v) const {
    static const double kCos = std::cos(kFlatFanDegrees * M_PI / 180.0);
    Eigen::Vector3d first = Eigen::Vector3d::Zero();
    for (int t : vertex_tris_[v]) {
      const Eigen::Vector3d n = Normal(tris_[t]);
      const double len = n.norm();
      if (!(len > 0.0)) return false;
      if (first.squaredNorm() == 0.0) {
        first = n / len;
      } else if (first.dot(n) < kCos * len) {
        return false;
      }
    }
    return first.squaredNorm() > 0.0;
  }

  // Smallest angle of the live triangles of v (radians; pi for none).
  double FanMinAngle(int v) const {
    double m = M_PI;
    for (int t : vertex_tris_[v]) {
      const auto& tri = tris_[t];
      m = std::min(m, MinAngle(pos_[tri[0]], pos_[tri[1]], pos_[tri[2]]));
    }
    return m;
  }

  // Largest |value| sampled on the triangles of v: their centroids and the midpoints of the
  // edges at v (where a chord strays farthest from the surface), m.
  double FanDeviation(int v) const {
    double m = 0.0;
    for (int t : vertex_tris_[v]) {
      const auto& tri = tris_[t];
      m = std::max(m, std::abs(solid_.Value((pos_[tri[0]] + pos_[tri[1]] + pos_[tri[2]]) / 3.0)));
      for (int w : tri) {
        if (w != v) m = std::max(m, std::abs(solid_.Value(0.5 * (pos_[v] + pos_[w]))));
      }
    }
    return m;
  }

  // Tangential relaxation of v: towards the centroid of its neighbours within the tangent plane
  // (the field's gradient at v), then onto the surface by Newton steps. Kept if it raises the
  // smallest angle of v's triangles, moves v less than half a cell, turns none of them by 60° or
  // more or against the field, leaves their sampled distance to the surface (FanDeviation) no
  // larger (with `mend`, no larger than MendDeviationBound), and folds none onto a triangle
  // around it (WouldMeet).
  // Returns whether v moved.
  bool Relax(int v, bool mend = false) {
    const auto& fan = vertex_tris_[v];
    if (fan.size() < 3) return false;
    const Eigen::Vector3d p = pos_[v];
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int t : fan) {
      const auto& tri = tris_[t];
      const int at = tri[0] == v ? 0 : tri[1] == v ? 1 : 2;
      centre += pos_[tri[(at + 1) % 3]];  // each neighbour once (it follows v in one triangle)
    }
    centre /= static_cast<double>(fan.size());
    const Eigen::Vector3d n = VertexGradient(v);
    if (n.squaredNorm() == 0.0) return false;
    Eigen::Vector3d x = centre - n * n.dot(centre - p);
    for (int i = 0; i < 2; ++i) {
      Eigen::Vector3d g;
      const double f = solid_.ValueAndGradient(x, &g);
      const double g2 = g.squaredNorm();
      if (std::abs(f) <= 1e-9 * cell_ || !(g2 > 1e-12)) break;
      x -= (f / g2) * g;
    }
    if (!x.allFinite() || (x - p).squaredNorm() > 0.25 * cell_ * cell_) return false;
    const double old_min = FanMinAngle(v);
    const double old_deviation = FanDeviation(v);
    normals_.clear();
    for (int t : fan) normals_.push_back(Normal(tris_[t]));
    const Eigen::Vector3d old_gradient = gradient_[v];
    pos_[v] = x;
    has_gradient_[v] = false;
    bool ok = FanMinAngle(v) > old_min;
    changed_.clear();
    for (size_t i = 0; ok && i < fan.size(); ++i) {
      const Eigen::Vector3d m = Normal(tris_[fan[i]]);
      ok = m.dot(normals_[i]) > 0.5 * m.norm() * normals_[i].norm() && FacesOut(tris_[fan[i]]);
      changed_.emplace_back(fan[i], tris_[fan[i]]);
    }
    if (ok) {
      const double deviation = FanDeviation(v);
      ok = (deviation <= old_deviation + 1e-9 * cell_ ||
            (mend && deviation <= MendDeviationBound())) &&
           !WouldMeet(changed_, -1, -1);
    }
    if (!ok) {
      pos_[v] = p;
      gradient_[v] = old_gradient;
      has_gradient_[v] = true;
    }
    return ok;
  }

  // Number of vertices that are neighbours (over live triangles) of both u and v: a stamp per
  // vertex marks u's neighbours, and each is counted once among v's.
  int CommonNeighbours(int u, int v) {
    if (vertex_mark_.size() != pos_.size()) vertex_mark_.assign(pos_.size(), 0);
    if (mark_ >= std::numeric_limits<unsigned>::max() - 2) {  // about to wrap: clear the marks
      std::fill(vertex_mark_.begin(), vertex_mark_.end(), 0);
      mark_ = 0;
    }
    const unsigned neighbour = ++mark_, counted = ++mark_;
    for (int t : vertex_tris_[u]) {
      for (int w : tris_[t]) {
        if (w != u) vertex_mark_[w] = neighbour;
      }
    }
    int common = 0;
    for (int t : vertex_tris_[v]) {
      for (int w : tris_[t]) {
        if (w != v && vertex_mark_[w] == neighbour) {
          vertex_mark_[w] = counted;
          ++common;
        }
      }
    }
    return common;
  }

  // Whether u and v are joined by an edge (of a live triangle).
  bool Adjacent(int u, int v) const {
    for (int t : vertex_tris_[u]) {
      const auto& tri = tris_[t];
      if (tri[0] == v || tri[1] == v || tri[2] == v) return true;
    }
    return false;
  }

  // The live triangles holding edge (u, v): the first two in (*t)[0], (*t)[1]; returns how
  // many there are (2 on a closed manifold).
  int EdgeTriangles(int u, int v, std::array<int, 2>* t) const {
    int count = 0;
    for (int id : vertex_tris_[u]) {
      const auto& tri = tris_[id];
      if (tri[0] == v || tri[1] == v || tri[2] == v) {
        if (count < 2) (*t)[count] = id;
        ++count;
      }
    }
    return count;
  }

  static int Third(const std::array<int, 3>& tri, int u, int v) {
    for (int w : tri) {
      if (w != u && w != v) return w;
    }
    return -1;
  }

  // Merges u into v (u's triangles take v; the two triangles of edge uv die) if that keeps
  // the mesh a closed manifold and turns no triangle over.
  bool Collapse(int u, int v) {
    std::array<int, 2> shared;
    if (EdgeTriangles(u, v, &shared) != 2) return false;
    const int a = Third(tris_[shared[0]], u, v), b = Third(tris_[shared[1]], u, v);
    if (a == b || a < 0 || b < 0) return false;
    if (vertex_tris_[a].size() <= 3 || vertex_tris_[b].size() <= 3) return false;
    // Link condition: the common neighbours of u and v are exactly a and b.
    if (CommonNeighbours(u, v) != 2) return false;
    // Geometry (when u and v do not coincide): the triangles of u that survive keep their facing
    // (within 60° of their previous normal, and out of the solid by the field's gradient if they
    // faced out before), none shrinks to a sliver, and none folds onto or cuts through a
    // triangle around it (WouldMeet).
    // Vertices closer than `coincident` (Run) count as one point: no geometric check.
    const bool coincident = (pos_[u] - pos_[v]).squaredNorm() <= coincident2_;
    // No edge longer than 1.5 cells (the raw mesh has edges up to a cube diagonal, 1.73 cells,
    // but inside one tet), so triangles stay as close to the surface as the raw ones.
    if (!coincident) {
      for (int t : vertex_tris_[u]) {
        for (int w : tris_[t]) {
          if (w == u || w == v) continue;
          const double new2 = (pos_[w] - pos_[v]).squaredNorm();
          if (new2 > max_edge2_ && new2 > (pos_[w] - pos_[u]).squaredNorm()) return false;
        }
      }
    }
    changed_.clear();
    double fan_min = -1.0;  // FanMinAngle(u), once needed
    for (int t : vertex_tris_[u]) {
      if (t == shared[0] || t == shared[1]) continue;
      std::array<int, 3> moved = tris_[t];
      for (int& w : moved) {
        if (w == u) w = v;
      }
      if (coincident) continue;
      // Never a worse worst triangle: the surviving triangles' smallest angle stays at or above
      // the smaller of the fan's before (the dying pair included) and small_angle_.
      if (angle_guard_) {
        const double new_min = MinAngle(pos_[moved[0]], pos_[moved[1]], pos_[moved[2]]);
        if (new_min < small_angle_) {
          if (fan_min < 0.0) fan_min = FanMinAngle(u);
          if (new_min < fan_min) return false;
        }
      }
      const Eigen::Vector3d n_old = Normal(tris_[t]), n_new = Normal(moved);
      if (n_new.norm() <= 0.5 * n_old.norm() * 1e-3 && n_old.norm() > 0.0) return false;
      if (n_old.norm() > 0.0 && n_new.dot(n_old) < 0.5 * n_new.norm() * n_old.norm()) return false;
      if (!FacesOut(moved) && FacesOut(tris_[t])) return false;
      changed_.emplace_back(t, moved);
    }
    if (!coincident && WouldMeet(changed_, shared[0], shared[1])) return false;
    for (int t : shared) alive_[t] = false;
    for (int t : vertex_tris_[u]) {
      if (!alive_[t]) continue;
      for (int& w : tris_[t]) {
        if (w == u) w = v;
      }
      vertex_tris_[v].push_back(t);
    }
    vertex_tris_[u].clear();
    for (int w : {v, a, b}) {
      auto& list = vertex_tris_[w];
      list.erase(std::remove_if(list.begin(), list.end(), [&](int t) { return !alive_[t]; }),
                 list.end());
    }
    return true;
  }

  // The quad of edge (p, q) of triangle t, oriented so that t = (p, q, c) (p and q swapped if
  // need be) and its neighbour across the edge is t2 = (q, p, d), if the edge can flip to cd: it
  // has two triangles, c and d differ and are not joined already, and p and q keep three or more
  // triangles.
  bool FlippableQuad(int t, int* p, int* q, int* t2, int* c, int* d) const {
    std::array<int, 2> shared;
    if (EdgeTriangles(*p, *q, &shared) != 2) return false;
    *t2 = shared[0] == t ? shared[1] : shared[0];
    // Orient so that t = (p, q, c): rotate t until p is first and q follows.
    std::array<int, 3> tri = tris_[t];
    while (tri[0] != *p) std::rotate(tri.begin(), tri.begin() + 1, tri.end());
    if (tri[1] != *q) std::swap(*p, *q), tri = tris_[t];
    while (tri[0] != *p) std::rotate(tri.begin(), tri.begin() + 1, tri.end());
    if (tri[1] != *q) return false;
    *c = tri[2];
    *d = Third(tris_[*t2], *p, *q);
    if (*c == *d || *d < 0) return false;
    if (vertex_tris_[*p].size() <= 3 || vertex_tris_[*q].size() <= 3) return false;
    return !Adjacent(*c, *d);
  }

  // Replaces triangles t and t2 of the quad (p, q, c, d) (FlippableQuad) by (p, d, c) and
  // (q, c, d), and updates the vertices' triangle lists.
  void ApplyFlip(int t, int t2, int p, int q, int c, int d) {
    tris_[t] = {p, d, c};
    tris_[t2] = {q, c, d};
    // t lost q, gained d; t2 lost p, gained c.
    auto erase = [&](int v, int tt) {
      auto& list = vertex_tris_[v];
      list.erase(std::remove(list.begin(), list.end(), tt), list.end());
    };
    erase(q, t);
    vertex_tris_[d].push_back(t);
    erase(p, t2);
    vertex_tris_[c].push_back(t2);
  }

  // Flips edge (p, q) of triangle t to the diagonal of its two triangles' quad if that is
  // legal (no existing edge, degrees stay >= 3), keeps the surface's facing and improves the
  // smaller minimum angle.
  bool Flip(int t, int p, int q) {
    int t2, c, d;
    if (!FlippableQuad(t, &p, &q, &t2, &c, &d)) return false;
    if ((pos_[c] - pos_[d]).squaredNorm() > max_edge2_) return false;
    const std::array<int, 3> n1 = {p, d, c}, n2 = {q, c, d};
    const Eigen::Vector3d ref = Normal(tris_[t]) + Normal(tris_[t2]);
    const Eigen::Vector3d m1 = Normal(n1), m2 = Normal(n2);
    const double cos30 = std::cos(M_PI / 6);
    if (m1.dot(m2) < cos30 * m1.norm() * m2.norm()) return false;
    if (m1.dot(ref) <= 0.0 || m2.dot(ref) <= 0.0) return false;
    const double old_min =
        std::min(MinAngle(pos_[p], pos_[q], pos_[c]), MinAngle(pos_[q], pos_[p], pos_[d]));
    const double new_min =
        std::min(MinAngle(pos_[p], pos_[d], pos_[c]), MinAngle(pos_[q], pos_[c], pos_[d]));
    if (!(new_min > old_min)) return false;
    // Neither new triangle turned over (against the field), nor folded onto a neighbour.
    if (!(FacesOut(n1) && FacesOut(n2)) && FacesOut(tris_[t]) && FacesOut(tris_[t2])) return false;
    changed_.assign({{t, n1}, {t2, n2}});
    if (WouldMeet(changed_, -1, -1)) return false;
    ApplyFlip(t, t2, p, q, c, d);
    return true;
  }

  // Mend's steps for triangle t, the first that succeeds (see Mend). Returns 1 if one did.
  int MendTriangle(int t, long* collapses, long* flips) {
    for (int v : tris_[t]) {
      if (pinch_of_[v] >= 0 && WidenPinch(pinch_of_[v])) return 1;
    }
    if (Improve(t, 0.0, small_angle_, collapses, flips)) return 1;
    const auto tri = tris_[t];
    double len[3];
    for (int k = 0; k < 3; ++k) len[k] = (pos_[tri[(k + 1) % 3]] - pos_[tri[k]]).squaredNorm();
    const int longest = static_cast<int>(std::max_element(len, len + 3) - len);
    if (FlattenCap(t, tri[longest], tri[(longest + 1) % 3])) {
      ++*flips;
      return 1;
    }
    for (int k = 0; k < 3; ++k) {
      if (k != longest && Flip(t, tri[k], tri[(k + 1) % 3])) {
        ++*flips;
        return 1;
      }
    }
    for (int v : tri) {
      if (Relax(v, true)) {
        ++relaxed_;
        return 1;
      }
    }
    return 0;
  }

  // Opens pinch g wider (once): its vertices move from where they met, along their grid edges
  // (inward), by the fraction of kWideZeroOffsets whose smallest angle over their triangles is
  // the largest, if that is larger than now and no triangle of theirs turns over or meets another
  // (Unfolded, tested against the whole group as SeparateCoincident does). Returns whether they
  // moved.
  bool WidenPinch(int g) {
    Pinch& pinch = pinches_[g];
    if (pinch.widened) return false;
    pinch.widened = true;
    double best_min = M_PI, best = 0.0;
    saved_.clear();
    for (int v : pinch.members) {
      best_min = std::min(best_min, FanMinAngle(v));
      saved_.push_back(pos_[v]);
    }
    const double old_deviation = PinchDeviation(g);
    for (double f : kWideZeroOffsets) {
      for (int v : pinch.members) pos_[v] = pinch.start + f * (*inward_)[v];
      bool unfolded = true;
      for (int v : pinch.members) unfolded = unfolded && Unfolded(v, pinch.start, &pinch.members);
      double new_min = M_PI;
      for (int v : pinch.members) new_min = std::min(new_min, FanMinAngle(v));
      if (unfolded && new_min > best_min) {
        const double deviation = PinchDeviation(g);
        if (deviation <= old_deviation || deviation <= MendDeviationBound())
          best_min = new_min, best = f;
      }
    }
    for (size_t k = 0; k < pinch.members.size(); ++k) {
      const int v = pinch.members[k];
      pos_[v] = best > 0.0 ? pinch.start + best * (*inward_)[v] : saved_[k];
      if (best > 0.0) has_gradient_[v] = false;
    }
    return best > 0.0;
  }

  // Mend's bound on the sampled distance to the surface of what its steps change: MeshDeviation
  // when first asked for in a Mend (Mend asks before its first step).
  double MendDeviationBound() {
    if (mesh_deviation_ < 0.0) mesh_deviation_ = MeshDeviation();
    return mesh_deviation_;
  }

  // Largest |value| over the live triangles' corners, edge midpoints and centroids (m); each
  // corner once.
  double MeshDeviation() const {
    double m = 0.0;
    for (size_t t = 0; t < tris_.size(); ++t) {
      if (alive_[t]) m = std::max(m, TriangleDeviation(tris_[t]));
    }
    for (size_t v = 0; v < pos_.size(); ++v) {
      if (!vertex_tris_[v].empty()) m = std::max(m, std::abs(solid_.Value(pos_[v])));
    }
    return m;
  }

  // Largest |value| at the vertices of pinch g and their triangles' sampled points (FanDeviation).
  double PinchDeviation(int g) const {
    double m = 0.0;
    for (int v : pinches_[g].members)
      m = std::max({m, std::abs(solid_.Value(pos_[v])), FanDeviation(v)});
    return m;
  }

  // Largest |value| at triangle tri's centroid and edge midpoints (m).
  double TriangleDeviation(const std::array<int, 3>& tri) const {
    const Eigen::Vector3d &a = pos_[tri[0]], &b = pos_[tri[1]], &c = pos_[tri[2]];
    return std::max({std::abs(solid_.Value((a + b + c) / 3.0)),
                     std::abs(solid_.Value(0.5 * (a + b))), std::abs(solid_.Value(0.5 * (b + c))),
                     std::abs(solid_.Value(0.5 * (c + a)))});
  }

  // Removes the cap t = (p, q, c) (long edge pq, apex c) where a flip cannot (its neighbour
  // across pq lies across a crease or a pinch): c moves onto pq, to the foot of its perpendicular
  // (within 0.2 cells, not within 5 % of p or q), and pq flips to cd, so the neighbour (q, p, d)
  // becomes (p, d, c) and (q, c, d), which lie in its plane: the surface changes by the cap's
  // height. Kept if the smallest angle of c's triangles and the neighbour rises, none of c's
  // other triangles turns by 60° or more or against the field, the new two face as the
  // neighbour did and out of the solid, the sampled distance to the surface of what changed stays
  // within the old triangles' or MendDeviationBound, and nothing folds (WouldMeet).
  bool FlattenCap(int t, int p, int q) {
    int t2, c, d;
    if (!FlippableQuad(t, &p, &q, &t2, &c, &d)) return false;
    const Eigen::Vector3d from = pos_[c];
    const double s = (from - pos_[p]).dot(pos_[q] - pos_[p]) / (pos_[q] - pos_[p]).squaredNorm();
    if (!(s > 0.05 && s < 0.95)) return false;
    const Eigen::Vector3d foot = pos_[p] + s * (pos_[q] - pos_[p]);
    if ((foot - from).squaredNorm() > 0.04 * cell_ * cell_) return false;
    const double old_min = std::min(FanMinAngle(c), MinAngle(pos_[q], pos_[p], pos_[d]));
    double old_deviation = TriangleDeviation(tris_[t2]);
    normals_.clear();
    for (int f : vertex_tris_[c]) {
      old_deviation = std::max(old_deviation, TriangleDeviation(tris_[f]));
      normals_.push_back(Normal(tris_[f]));
    }
    const std::array<int, 3> n1 = {p, d, c}, n2 = {q, c, d};
    const Eigen::Vector3d ref = Normal(tris_[t2]);
    const Eigen::Vector3d old_gradient = gradient_[c];
    const bool had_gradient = has_gradient_[c];
    pos_[c] = foot;
    has_gradient_[c] = false;
    double new_min =
        std::min(MinAngle(pos_[p], pos_[d], pos_[c]), MinAngle(pos_[q], pos_[c], pos_[d]));
    double new_deviation = std::max(TriangleDeviation(n1), TriangleDeviation(n2));
    bool ok = true;
    changed_.assign({{t, n1}, {t2, n2}});
    for (size_t i = 0; ok && i < vertex_tris_[c].size(); ++i) {
      const int f = vertex_tris_[c][i];
      if (f == t) continue;
      const auto& ft = tris_[f];
      const Eigen::Vector3d m = Normal(ft);
      new_min = std::min(new_min, MinAngle(pos_[ft[0]], pos_[ft[1]], pos_[ft[2]]));
      new_deviation = std::max(new_deviation, TriangleDeviation(ft));
      ok = m.dot(normals_[i]) > 0.5 * m.norm() * normals_[i].norm() && FacesOut(ft);
      changed_.emplace_back(f, ft);
    }
    new_deviation = std::max(new_deviation, std::abs(solid_.Value(foot)));
    ok = ok && new_min > old_min &&
         (new_deviation <= old_deviation || new_deviation <= MendDeviationBound());
    for (const auto& n : {n1, n2}) {
      const Eigen::Vector3d m = Normal(n);
      ok = ok && m.dot(ref) > 0.5 * m.norm() * ref.norm() && FacesOut(n);
    }
    if (!ok || WouldMeet(changed_, -1, -1)) {
      pos_[c] = from;
      gradient_[c] = old_gradient;
      has_gradient_[c] = had_gradient;
      return false;
    }
    ApplyFlip(t, t2, p, q, c, d);
    return true;
  }

  // Whether triangle tri has an edge shorter than short_edge or an angle whose sine is below
  // `sine` (an angle under 90°), without square roots or arc tangents: the smallest angle is the
  // one across the shortest edge, and its sine is |cross| / (product of the two other edges).
  bool Sharp(const std::array<int, 3>& tri, double short_edge, double sine) const {
    const Eigen::Vector3d e0 = pos_[tri[1]] - pos_[tri[0]], e1 = pos_[tri[2]] - pos_[tri[1]],
                          e2 = pos_[tri[0]] - pos_[tri[2]];
    const double l0 = e0.squaredNorm(), l1 = e1.squaredNorm(), l2 = e2.squaredNorm();
    const double shortest = std::min({l0, l1, l2});
    if (shortest < short_edge * short_edge) return true;
    const double others = shortest == l0 ? l1 * l2 : shortest == l1 ? l0 * l2 : l0 * l1;
    return e0.cross(e1).squaredNorm() < sine * sine * others;
  }

  int Improve(int t, double short_edge, double small_angle, long* collapses, long* flips) {
    const auto tri = tris_[t];
    if (!Sharp(tri, short_edge, sin_small_angle_)) return 0;
    double len[3];
    for (int k = 0; k < 3; ++k)
      len[k] = (pos_[tri[(k + 1) % 3]] - pos_[tri[k]]).norm();  // edge k: k -> k+1
    const int shortest = static_cast<int>(std::min_element(len, len + 3) - len);
    const int longest = static_cast<int>(std::max_element(len, len + 3) - len);
    const bool tiny = len[shortest] < short_edge;
    // A needle has a short edge (the angle across it is the small one); a cap has none.
    const bool needle = len[shortest] < 2.0 * std::sin(0.5 * small_angle) * len[longest] * 1.5;
    if (tiny || needle) {
      // Every short edge, shortest first: in a zero-area triangle all three edges are equally
      // short, and the first may fail the link condition where another passes (a fan of three
      // coincident triangles around a vertex of degree 3: only the spokes can go).
      for (int k : EdgesShortestFirst(len)) {
        if (k != shortest && !(len[k] < short_edge)) break;
        const int u = tri[k], v = tri[(k + 1) % 3];
        if (Collapse(u, v) || Collapse(v, u)) {
          ++*collapses;
          return 1;
        }
      }
    }
    if (!tiny) {
      const int p = tri[longest], q = tri[(longest + 1) % 3], apex = tri[(longest + 2) % 3];
      if (Flip(t, p, q)) {
        ++*flips;
        return 1;
      }
      // A cap that cannot be flipped (its neighbour lies across a crease): move its apex onto
      // the nearer end of the long edge.
      const bool p_nearer =
          (pos_[apex] - pos_[p]).squaredNorm() <= (pos_[apex] - pos_[q]).squaredNorm();
      const int near = p_nearer ? p : q, far = p_nearer ? q : p;
      if (Collapse(apex, near) || Collapse(apex, far)) {
        ++*collapses;
        return 1;
      }
    }
    return 0;
  }

  const PointField& solid_;
  const std::atomic<bool>* cancel_;
  std::vector<Eigen::Vector3d>& pos_;
  std::vector<std::array<int, 3>>& tris_;
  std::vector<bool> alive_;
  double max_edge2_ = 0.0;
  double coincident2_ = 0.0;
  std::vector<std::vector<int>> vertex_tris_;
  std::vector<Eigen::Vector3d> gradient_;  // per vertex: unit gradient, once has_gradient_
  std::vector<bool> has_gradient_;
  long relaxed_ = 0;
  // A coincident group SeparateCoincident moved apart: where its vertices met,
  // which they are, and whether WidenPinch has tried it.
  struct Pinch {
    Eigen::Vector3d start;
    std::vector<int> members;
    bool widened;
  };
  std::vector<Pinch> pinches_;
  std::vector<int> pinch_of_;     // per vertex: its pinch (moved by SeparateCoincident), or -1
  double mesh_deviation_ = -1.0;  // MendDeviationBound's (-1: not sampled in this Mend yet)
  const std::vector<Eigen::Vector3d>* inward_ = nullptr;  // SeparateCoincident's
  bool angle_guard_ = false;  // Run's angle_guard: Collapse keeps the fan's worst angle
  double small_angle_ = 0.0;  // Run's small_angle_rad
  double sin_small_angle_ = 0.0;
  double cell_ = 0.0;                                        // grid cell (m), Run's max_edge / 1.5
  std::vector<GatheredTriangle> nearby_;                     // scratch of WouldMeet
  std::vector<GatheredTriangle> changed_corners_;            // scratch of WouldMeet
  std::vector<unsigned> vertex_mark_;                        // per vertex: CommonNeighbours' marks
  unsigned mark_ = 0;                                        // CommonNeighbours' last mark
  std::vector<unsigned> tri_stamp_;                          // per triangle: WouldMeet's stamp
  unsigned stamp_ = 0;                                       // WouldMeet's current stamp
  std::vector<Eigen::Vector3d> normals_;                     // scratch of Relax, FlattenCap
  std::vector<Eigen::Vector3d> saved_;                       // scratch of WidenPinch
  std::vector<int> group_;                                   // scratch of SeparateCoincident
  std::vector<std::pair<int, std::array<int, 3>>> changed_;  // scratch of Collapse and Flip
};

class Mesher {
 public:
  Mesher(const CompiledSolid& solid, const SurfaceMeshSettings& s) : solid_(solid), settings_(s) {
    if (s.bounds.isEmpty() || !s.bounds.min().allFinite() || !s.bounds.max().allFinite()) {
      throw std::invalid_argument("MeshSurface: settings.bounds must be a finite, non-empty box");
    }
    if (!(s.cell_size > 0.0) || !std::isfinite(s.cell_size)) {
      throw std::invalid_argument("MeshSurface: settings.cell_size must be > 0 m, got " +
                                  std::to_string(s.cell_size));
    }
    if (s.refine_steps < 0)
      throw std::invalid_argument("MeshSurface: settings.refine_steps must be >= 0");
    if (!(s.snap_cells >= 0.0 && s.snap_cells <= 0.25))
      throw std::invalid_argument("MeshSurface: settings.snap_cells must be in [0, 0.25], got " +
                                  std::to_string(s.snap_cells));
    if (!(s.mend_angle_deg >= 0.0 && s.mend_angle_deg <= 20.0))
      throw std::invalid_argument("MeshSurface: settings.mend_angle_deg must be in [0, 20], got " +
                                  std::to_string(s.mend_angle_deg));
    if (!(s.flat_coarsen_cells >= 0.0 && s.flat_coarsen_cells <= 1.0))
      throw std::invalid_argument(
          "MeshSurface: settings.flat_coarsen_cells must be in [0, 1], got " +
          std::to_string(s.flat_coarsen_cells));
    h_ = s.cell_size;
    const Eigen::Vector3d extent = s.bounds.sizes();
    double cells = 1.0;
    for (int a = 0; a < 3; ++a) {
      n_[a] = std::max<long>(1, static_cast<long>(std::ceil(extent[a] / h_ - 1e-9)));
      cells *= static_cast<double>(n_[a]);
    }
    if (cells > static_cast<double>(1L << 30)) {
      throw std::invalid_argument("MeshSurface: the grid would have " + std::to_string(cells) +
                                  " cells (more than 2^30): raise cell_size");
    }
    // Centre the grid on the bounds.
    origin_ =
        s.bounds.center() - 0.5 * h_ * Eigen::Vector3d(double(n_[0]), double(n_[1]), double(n_[2]));
    total_cells_ = n_[0] * n_[1] * n_[2];
    values_ = BrickMap<double, 1>(GridVertices());
    raw_values_ = BrickMap<double, 1>(GridVertices());
    edge_vertices_ = BrickMap<int, 7>(GridVertices());
  }

  TriangleMesh Run(SurfaceMeshStats* stats) {
    const auto start = std::chrono::steady_clock::now();
    if (settings_.progress) settings_.progress(0.0);
    // Point values through pruned tapes (bit-identical); interval bounds on the full tape.
    const PointField field(solid_, settings_.bounds, h_);
    field_ = &field;
    long collapses = 0, flips = 0, flat_collapses = 0;
    // Snapping (snap_cells > 0) comes with the angle guard, the projection of the snapped
    // vertices and the polish; without it the clean-up is the one measured before 2026-12-04.
    const bool snapping = settings_.clean && settings_.snap_cells > 0.0;
    for (;;) {
      Visit({0, 0, 0}, {n_[0], n_[1], n_[2]});
      if (!settings_.clean) break;
      Cleaner cleaner(*field_, &vertices_, &triangles_, settings_.cancel);
      cleaner.Run(settings_.short_edge_fraction * h_, settings_.small_angle_deg * M_PI / 180.0,
                  1.5 * h_, kCoincident * h_, snapping, &collapses, &flips);
      std::vector<int> stuck;
      cleaner.SeparateCoincident(inward_, snapping ? &stuck : nullptr);
      // A pinch the snapping made (a grid vertex within the band but not within kZeroBand of
      // zero: a hole or gap narrower than the band there) that cannot be opened without a fold:
      // that grid vertex keeps its own value, and the solid is meshed again.
      if (Unsnap(stuck)) {
        Restart();
        continue;
      }
      if (snapping) {
        cleaner.ProjectSnapped(inward_);
        cleaner.Polish(settings_.short_edge_fraction * h_, &collapses, &flips);
      }
      if (settings_.flat_coarsen_cells > 0.0) {
        flat_collapses = cleaner.CoarsenFlat(settings_.flat_coarsen_cells * h_);
        collapses += flat_collapses;
        if (flat_collapses > 0 && snapping)
          cleaner.Polish(settings_.short_edge_fraction * h_, &collapses, &flips);
      }
      if (snapping && settings_.mend_angle_deg > 0.0)
        cleaner.Mend(settings_.mend_angle_deg * M_PI / 180.0, std::sqrt(3.0) * h_, &collapses,
                     &flips);
      cleaner.Compact();
      break;
    }
    if (settings_.progress) settings_.progress(1.0);
    TriangleMesh mesh;
    mesh.vertices.resize(3, static_cast<Eigen::Index>(vertices_.size()));
    for (size_t i = 0; i < vertices_.size(); ++i)
      mesh.vertices.col(static_cast<Eigen::Index>(i)) = vertices_[i];
    mesh.triangles.resize(3, static_cast<Eigen::Index>(triangles_.size()));
    for (size_t i = 0; i < triangles_.size(); ++i) {
      for (int k = 0; k < 3; ++k)
        mesh.triangles(k, static_cast<Eigen::Index>(i)) = triangles_[i][k];
    }
    if (stats) {
      stats->grid_cells = total_cells_;
      stats->evaluated_cells = evaluated_cells_;
      stats->field_evaluations = evaluations_;
      stats->collapsed_edges = collapses;
      stats->flat_collapses = flat_collapses;
      stats->flipped_edges = flips;
      stats->seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    return mesh;
  }

 private:
  using Index3 = std::array<long, 3>;

  Eigen::Vector3d Position(const Index3& v) const {
    return origin_ + h_ * Eigen::Vector3d(double(v[0]), double(v[1]), double(v[2]));
  }
  // Grid vertices per axis.
  Index3 GridVertices() const { return {n_[0] + 1, n_[1] + 1, n_[2] + 1}; }
  long VertexId(const Index3& v) const { return v[0] + (n_[0] + 1) * (v[1] + (n_[1] + 1) * v[2]); }
  bool OnBoundary(const Index3& v) const {
    for (int a = 0; a < 3; ++a) {
      if (v[a] == 0 || v[a] == n_[a]) return true;
    }
    return false;
  }

  // Field value at a grid vertex, cached. Values within kZeroBand cells of zero become exactly
  // zero, and zero counts as outside: where the surface runs through grid vertices (a face on a
  // grid plane) rounding noise (±1e-17 m) or a blend's tail (-1e-12 m) would otherwise give those
  // vertices random signs, and the surface would weave through them with mesh vertices a hair
  // apart (distinct, but within any weld tolerance). Boundary vertices count as outside (value
  // at least zero) so the mesh closes along the bounds.
  double VertexValue(const Index3& v) {
    if (const double* cached = values_.Find(v, 0)) return *cached;
    const long id = VertexId(v);
    // Without snapping the band is kZeroBand: no neighbour is asked, so no second cache.
    double f = SnapBand() > kZeroBand * h_ ? RawValue(v) : FieldValue(v);
    const bool unsnapped = unsnapped_.size() > 0 && unsnapped_.Find(id) != nullptr;
    const double band = unsnapped ? kZeroBand * h_ : SnapBand();
    // An inside value within the snap band (not within kZeroBand) is snapped only where the
    // solid goes deeper than the band next to it: otherwise the grid vertex is the deepest of a
    // wall under about 1 + 2 snap_cells cells thick, and snapping it would lose the wall.
    if (std::abs(f) <= band && !(f < -kZeroBand * h_ && !DeeperNeighbour(v, band))) f = 0.0;
    if (OnBoundary(v)) f = std::max(f, 0.0);
    values_.Insert(v, 0, f);
    return f;
  }

  // Marks the grid vertices of the mesh vertices `stuck` (SeparateCoincident's) that the snap
  // band made zero as unsnapped (VertexValue then keeps their value). Returns whether it marked
  // one.
  bool Unsnap(const std::vector<int>& stuck) {
    bool marked = false;
    for (int v : stuck) {
      const Index3 g = grid_index_[v];
      if (g[0] < 0 || OnBoundary(g)) continue;
      const long id = VertexId(g);
      if (unsnapped_.Find(id) != nullptr) continue;
      const double f = RawValue(g);  // cached: snapping asked for it
      if (std::abs(f) <= kZeroBand * h_) continue;
      unsnapped_.Insert(id, f);
      marked = true;
    }
    return marked;
  }

  // Forgets the raw mesh and the grid values (not the unsnapped grid vertices) before meshing
  // again.
  void Restart() {
    values_ = BrickMap<double, 1>(GridVertices());
    edge_vertices_ = BrickMap<int, 7>(GridVertices());
    vertices_.clear();
    inward_.clear();
    grid_index_.clear();
    triangles_.clear();
    done_cells_ = 0;
  }

  // Field value at a grid vertex as it is (no band, no boundary).
  double FieldValue(const Index3& v) {
    Poll();
    ++evaluations_;
    return field_->Value(Position(v));
  }

  // FieldValue, cached (for snapping, which also asks the neighbours).
  double RawValue(const Index3& v) {
    if (const double* cached = raw_values_.Find(v, 0)) return *cached;
    const double f = FieldValue(v);
    raw_values_.Insert(v, 0, f);
    return f;
  }

  // Whether one of the 26 grid neighbours of v (within the grid) has a value below -band.
  bool DeeperNeighbour(const Index3& v, double band) {
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          if (dx == 0 && dy == 0 && dz == 0) continue;
          const Index3 w = {v[0] + dx, v[1] + dy, v[2] + dz};
          if (w[0] < 0 || w[1] < 0 || w[2] < 0 || w[0] > n_[0] || w[1] > n_[1] || w[2] > n_[2])
            continue;
          if (RawValue(w) < -band) return true;
        }
      }
    }
    return false;
  }

  // Grid values this close to zero (m) count as exactly zero (VertexValue).
  double SnapBand() const {
    return (settings_.clean ? std::max(kZeroBand, settings_.snap_cells) : kZeroBand) * h_;
  }

  // Descends the index box [lo, hi) of cells, skipping what the interval bounds rule out.
  void Visit(const Index3& lo, const Index3& hi) {
    // A box is skipped when its bounds prove every grid vertex in it outside after VertexValue's
    // snap (values at or above -kZeroBand cells: a value within the wider snap band may stay
    // inside, see VertexValue) or inside (below -SnapBand(), and not on the grid's boundary,
    // whose vertices count as outside): its cells then hold no surface.
    const Eigen::AlignedBox3d box(Position(lo), Position(hi));
    Poll();
    const Interval bounds = solid_.Bounds(box);
    bool touches_boundary = false;
    for (int a = 0; a < 3; ++a) touches_boundary |= lo[a] == 0 || hi[a] == n_[a];
    if (bounds.lo >= -kZeroBand * h_ || (bounds.hi < -SnapBand() && !touches_boundary)) {
      Done(lo, hi);
      return;
    }
    int axis = 0;
    for (int a = 1; a < 3; ++a) {
      if (hi[a] - lo[a] > hi[axis] - lo[axis]) axis = a;
    }
    if (hi[axis] - lo[axis] == 1) {
      Cell(lo);
      Done(lo, hi);
      return;
    }
    const long mid = (lo[axis] + hi[axis]) / 2;
    Index3 hi_a = hi, lo_b = lo;
    hi_a[axis] = mid;
    lo_b[axis] = mid;
    Visit(lo, hi_a);
    Visit(lo_b, hi);
  }

  void Done(const Index3& lo, const Index3& hi) {
    done_cells_ += (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
  }

  // Called before every field evaluation and box classification, whose cost grows with the
  // tape (a union of 100,000 primitives: 199,999 instructions each): checks cancel every time,
  // so Ctrl+C stops within one evaluation, and reports progress every 256 calls (the callback
  // throttles).
  void Poll() {
    if (settings_.cancel && settings_.cancel->load(std::memory_order_relaxed))
      throw MeshingCancelled();
    if (++polls_ % 256 == 0 && settings_.progress)
      settings_.progress(double(done_cells_) / double(total_cells_));
  }

  void Cell(const Index3& c) {
    ++evaluated_cells_;
    std::array<double, 8> f;
    std::array<Index3, 8> v;
    bool any_in = false, any_out = false;
    for (int code = 0; code < 8; ++code) {
      v[code] = {c[0] + (code & 1), c[1] + ((code >> 1) & 1), c[2] + ((code >> 2) & 1)};
      f[code] = VertexValue(v[code]);
      (f[code] < 0.0 ? any_in : any_out) = true;
    }
    if (!any_in || !any_out) return;
    for (int code = 0; code < 8; ++code) corner_[code] = Position(v[code]);
    cell_edges_.fill(-1);
    for (const auto& tet : kKuhnTets) Tetrahedron(c, tet, f, v);
  }

  // Mesh vertex on the grid edge between corner codes a and b of cell c (one inside, one out).
  int EdgeVertex(const Index3& c, int a, int b, const std::array<double, 8>& f,
                 const std::array<Index3, 8>& v) {
    if ((a & b) != a) std::swap(a, b);  // Kuhn edges join u to v with bits(u) ⊂ bits(v)
    // Most edges serve several of the cell's six tetrahedra: asked again, the cell's own table
    // answers without a probe into the grid-wide one.
    int& in_cell = cell_edges_[8 * a + b];
    if (in_cell >= 0) return in_cell;
    // The edge's slot at its lower end v[a]: its direction a ^ b (1 to 7) less one.
    const int slot = (a ^ b) - 1;
    if (const int* cached = edge_vertices_.Find(v[a], slot)) return in_cell = *cached;
    Eigen::Vector3d pa = corner_[a], pb = corner_[b];
    double fa = f[a], fb = f[b];
    // An outside end at exactly zero (on the surface, or clamped on the boundary): the vertex is
    // that grid vertex exactly, so the vertices of all edges ending there coincide and the
    // clean-up merges them; inward_ says where it goes if it cannot (SeparateCoincident).
    double t = fa / (fa - fb);
    if (fa != 0.0 && fb != 0.0) {
      // Regula falsi (Illinois variant: halve the stale end's value so it cannot stagnate),
      // keeping the bracket [pa, pb] with opposite signs.
      int last = 0;
      for (int s = 0; s < settings_.refine_steps; ++s) {
        const Eigen::Vector3d p = pa + t * (pb - pa);
        Poll();
        const double fp = field_->Value(p);
        ++evaluations_;
        if (fp == 0.0) break;
        if ((fp < 0.0) == (fa < 0.0)) {
          pa = p;
          fa = fp;
          if (last == -1) fb *= 0.5;
          last = -1;
        } else {
          pb = p;
          fb = fp;
          if (last == 1) fa *= 0.5;
          last = 1;
        }
        t = fa / (fa - fb);
      }
    }
    const int id = static_cast<int>(vertices_.size());
    const Eigen::Vector3d edge = corner_[b] - corner_[a];
    if (f[a] == 0.0) {
      vertices_.push_back(corner_[a]);
      inward_.push_back(edge);
      grid_index_.push_back(v[a]);
    } else if (f[b] == 0.0) {
      vertices_.push_back(corner_[b]);
      inward_.push_back(-edge);
      grid_index_.push_back(v[b]);
    } else {
      vertices_.push_back(pa + t * (pb - pa));
      inward_.push_back(Eigen::Vector3d::Zero());
      grid_index_.push_back({-1, -1, -1});
    }
    edge_vertices_.Insert(v[a], slot, id);
    return in_cell = id;
  }

  // Appends triangle (i0, i1, i2), oriented by the triangle (m0, m1, m2) of the midpoints of
  // the same grid edges: the midpoints never coincide, so the orientation stays consistent even
  // where mesh vertices do (a grid vertex exactly on the surface).
  void Emit(int i0, int i1, int i2, const Eigen::Vector3d& m0, const Eigen::Vector3d& m1,
            const Eigen::Vector3d& m2, const Eigen::Vector3d& outward) {
    if ((m1 - m0).cross(m2 - m0).dot(outward) < 0.0) std::swap(i1, i2);
    triangles_.push_back({i0, i1, i2});
  }

  void Tetrahedron(const Index3& c, const std::array<int, 4>& tet, const std::array<double, 8>& f,
                   const std::array<Index3, 8>& v) {
    int in[4], out[4], n_in = 0, n_out = 0;
    for (int code : tet) (f[code] < 0.0 ? in[n_in++] : out[n_out++]) = code;
    if (n_in == 0 || n_out == 0) return;
    Eigen::Vector3d in_centre = Eigen::Vector3d::Zero(), out_centre = Eigen::Vector3d::Zero();
    for (int i = 0; i < n_in; ++i) in_centre += corner_[in[i]] / n_in;
    for (int i = 0; i < n_out; ++i) out_centre += corner_[out[i]] / n_out;
    // The plane through the edge midpoints separates the inside corners from the outside ones.
    const Eigen::Vector3d outward = out_centre - in_centre;
    auto mid = [&](int a, int b) -> Eigen::Vector3d { return 0.5 * (corner_[a] + corner_[b]); };
    if (n_in == 1) {
      Emit(EdgeVertex(c, in[0], out[0], f, v), EdgeVertex(c, in[0], out[1], f, v),
           EdgeVertex(c, in[0], out[2], f, v), mid(in[0], out[0]), mid(in[0], out[1]),
           mid(in[0], out[2]), outward);
    } else if (n_in == 3) {
      Emit(EdgeVertex(c, in[0], out[0], f, v), EdgeVertex(c, in[1], out[0], f, v),
           EdgeVertex(c, in[2], out[0], f, v), mid(in[0], out[0]), mid(in[1], out[0]),
           mid(in[2], out[0]), outward);
    } else {
      // Quad with corners on edges (a,c), (a,d), (b,d), (b,c), in cyclic order.
      const int ac = EdgeVertex(c, in[0], out[0], f, v), ad = EdgeVertex(c, in[0], out[1], f, v);
      const int bd = EdgeVertex(c, in[1], out[1], f, v), bc = EdgeVertex(c, in[1], out[0], f, v);
      const Eigen::Vector3d m_ac = mid(in[0], out[0]), m_ad = mid(in[0], out[1]);
      const Eigen::Vector3d m_bd = mid(in[1], out[1]), m_bc = mid(in[1], out[0]);
      Emit(ac, ad, bd, m_ac, m_ad, m_bd, outward);
      Emit(ac, bd, bc, m_ac, m_bd, m_bc, outward);
    }
  }

  const CompiledSolid& solid_;
  const PointField* field_ = nullptr;  // point values of solid_ (Run's; pruned tapes)
  const SurfaceMeshSettings& settings_;
  double h_ = 0.0;
  Index3 n_{};
  Eigen::Vector3d origin_;
  long total_cells_ = 0;
  long done_cells_ = 0;
  long polls_ = 0;
  long evaluated_cells_ = 0;
  long evaluations_ = 0;
  BrickMap<double, 1> values_;        // grid vertex -> value
  BrickMap<double, 1> raw_values_;    // grid vertex -> value as it is (kept by Restart)
  BrickMap<int, 7> edge_vertices_;    // grid vertex, edge code - 1 -> mesh vertex
  std::array<int, 64> cell_edges_{};  // the current cell's edge (8 a + b) -> mesh vertex, or -1
  std::array<Eigen::Vector3d, 8> corner_;  // the current cell's corners (Position), by code
  std::vector<Eigen::Vector3d> vertices_;
  std::vector<Eigen::Vector3d>
      inward_;                      // per vertex at a zero grid vertex: its edge, into the solid
  std::vector<Index3> grid_index_;  // per vertex at a zero grid vertex: its index (else -1s)
  std::vector<std::array<int, 3>> triangles_;
  FlatMap<double> unsnapped_;  // grid vertex id -> value, kept out of the snap band
};

// Tapes longer than this are pruned to every box FarthestLeaf splits (CompiledSolid::Specialize),
// and each half is classified with its parent's pruned tape: a union of n primitives spread
// over space then costs about n per level of the descent instead of n per box (a union of
// 100,000 spheres: seconds instead of minutes). Shorter tapes are classified as they are: there
// a Specialize per box costs more than it saves.
constexpr int kFindBoundsPruneInstructions = 256;

// Whether FarthestLeaf splits the boxes of `tape` across the searched axis first (down to the
// resolution) rather than across their largest side: for long tapes without Lipschitz-only
// primitives. The boxes are then slabs at the extreme side that hold ever fewer primitives and
// prune from the first levels on; cubes there would each hold nearly every primitive, and be
// classified with the whole tape, until they were smaller than the solid. A union of 100,000
// spheres: 61 boxes per side instead of 180 to 2,661, a sixth of the time. A cone's or an
// extrusion's bounds over a slab are as wide as its diagonal, so slabs near one stay ambiguous:
// the platform with 1,000 bolt-hole sets (an extrusion among them) took 50 times longer with
// slabs. (Measured 2026-12-03 with FindBounds over [-10, 10]^3 at 1 cm.)
bool SplitsSlabs(const CompiledSolid& tape) {
  return tape.instruction_count() > kFindBoundsPruneInstructions && tape.LipschitzOnlyCount() == 0;
}

// The largest coordinate along `axis` (times `sign`, +1 or -1) of the leaves of the octree
// descent over `search` (halving the largest side at its centre, or `axis` first where
// SplitsSlabs, down to boxes of side <= `resolution`; a box the bounds call inside is a leaf
// too) that the bounds do not call
// outside. Best first, with no recursion: boxes are taken in decreasing order of their extreme
// (ties: the smaller box first, so the search dives), so the first leaf taken holds the answer
// and every box whose extreme cannot beat it is never split. NaN when every leaf is outside.
// A box is classified with the tape pruned to its parent box (kFindBoundsPruneInstructions):
// within that box the pruned tape has the same values, so its bounds are as valid (and can
// only be tighter).
double FarthestLeaf(const CompiledSolid& solid, const Eigen::AlignedBox3d& search,
                    double resolution, int axis, double sign, const std::atomic<bool>* cancel) {
  struct Entry {
    double extreme;  // sign × the box's extreme along axis
    double size;     // its largest side
    Eigen::AlignedBox3d box;
    std::shared_ptr<const CompiledSolid> tape;  // pruned to the parent box; null: `solid`
    bool slabs;                                 // SplitsSlabs(tape)
    bool operator<(const Entry& other) const {
      return extreme < other.extreme || (extreme == other.extreme && size > other.size);
    }
  };
  auto entry = [&](const Eigen::AlignedBox3d& box, std::shared_ptr<const CompiledSolid> tape,
                   bool slabs) {
    return Entry{sign > 0 ? box.max()[axis] : -box.min()[axis], box.sizes().maxCoeff(), box,
                 std::move(tape), slabs};
  };
  std::priority_queue<Entry> queue;
  queue.push(entry(search, nullptr, SplitsSlabs(solid)));
  while (!queue.empty()) {
    const Entry top = queue.top();
    queue.pop();
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) throw MeshingCancelled();
    const CompiledSolid& tape = top.tape != nullptr ? *top.tape : solid;
    const BoxClass cls = tape.Classify(top.box);
    if (cls == BoxClass::kOutside) continue;
    if (cls == BoxClass::kInside || top.size <= resolution) return sign * top.extreme;
    std::shared_ptr<const CompiledSolid> halves = top.tape;
    bool slabs = top.slabs;
    if (tape.instruction_count() > kFindBoundsPruneInstructions) {
      // Kept only when it drops a quarter or more: over boxes larger than the primitives'
      // spacing the bounds prune little, and near-copies of a long tape would pile up in the
      // queue (gigabytes for 100,000 primitives).
      CompiledSolid pruned = tape.Specialize(top.box);
      if (4 * pruned.instruction_count() <= 3 * tape.instruction_count()) {
        halves = std::make_shared<const CompiledSolid>(std::move(pruned));
        slabs = SplitsSlabs(*halves);
      }
    }
    int split = 0;
    top.box.sizes().maxCoeff(&split);
    if (top.slabs && top.box.sizes()[axis] > resolution) split = axis;
    Eigen::AlignedBox3d a = top.box, b = top.box;
    a.max()[split] = b.min()[split] = top.box.center()[split];
    queue.push(entry(a, halves, slabs));
    queue.push(entry(b, std::move(halves), slabs));
  }
  return std::nan("");
}

// Checks the settings MeshSurface needs before it can size its grid.
void CheckGridSettings(const SurfaceMeshSettings& s) {
  if (s.bounds.isEmpty() || !s.bounds.min().allFinite() || !s.bounds.max().allFinite()) {
    throw std::invalid_argument("MeshSurface: settings.bounds must be a finite, non-empty box");
  }
  if (!(s.cell_size > 0.0) || !std::isfinite(s.cell_size)) {
    throw std::invalid_argument("MeshSurface: settings.cell_size must be > 0 m, got " +
                                std::to_string(s.cell_size));
  }
}

// Cells per axis of a grid of `cell` over `extent` (as MeshSurface sizes it; doubles, may be inf).
Eigen::Vector3d GridCells(const Eigen::Vector3d& extent, double cell) {
  Eigen::Vector3d n;
  for (int a = 0; a < 3; ++a) n[a] = std::max(1.0, std::ceil(extent[a] / cell - 1e-9));
  return n;
}

// Coarse-grid look of EstimateSurfaceMesh: counts the leaves of an octree descent over a grid
// of cell h (n cells per axis from origin) that the bounds cannot rule out, and the boxes
// classified on the way.
void CountAmbiguous(const CompiledSolid& solid, const Eigen::Vector3d& origin, double h,
                    const std::array<long, 3>& lo, const std::array<long, 3>& hi, double* leaves,
                    double* classified) {
  const Eigen::Vector3d p_lo =
      origin + h * Eigen::Vector3d(double(lo[0]), double(lo[1]), double(lo[2]));
  const Eigen::Vector3d p_hi =
      origin + h * Eigen::Vector3d(double(hi[0]), double(hi[1]), double(hi[2]));
  *classified += 1.0;
  if (solid.Classify(Eigen::AlignedBox3d(p_lo, p_hi)) != BoxClass::kAmbiguous) return;
  int axis = 0;
  for (int a = 1; a < 3; ++a) {
    if (hi[a] - lo[a] > hi[axis] - lo[axis]) axis = a;
  }
  if (hi[axis] - lo[axis] == 1) {
    *leaves += 1.0;
    return;
  }
  const long mid = (lo[axis] + hi[axis]) / 2;
  std::array<long, 3> hi_a = hi, lo_b = lo;
  hi_a[axis] = mid;
  lo_b[axis] = mid;
  CountAmbiguous(solid, origin, h, lo, hi_a, leaves, classified);
  CountAmbiguous(solid, origin, h, lo_b, hi, leaves, classified);
}

// Constants of the estimate, fitted to MeshSurface's SurfaceMeshStats and peak memory on the
// test solids (sphere, torus, platform) at 1 to 8 mm (see EstimateSurfaceMesh's test).
constexpr double kCoarseCellsAcross = 32.0;
constexpr double kCoarseTapeBudget = 2000.0;
constexpr double kTrianglesPerSurfaceCell = 4.0;
// Point evaluations per meshed cell: new grid vertices, refinement steps per new edge vertex
// (about 1.5 edge vertices per cell), clean-up gradients (about 4 evaluations' work each).
constexpr double kVertexEvaluationsPerCell = 2.5;
constexpr double kEdgeVerticesPerCell = 1.5;
constexpr double kCleanupEvaluationsPerCell = 6.0;
// Interval-bound classifications cost about 4 point evaluations; about 2 per meshed cell.
constexpr double kBoundsEvaluationsPerCell = 8.0;
// Bytes per meshed cell at the peak (value and edge hash maps, vertices, triangles, the
// clean-up's per-vertex adjacency) and the fixed overhead.
constexpr double kBytesPerSurfaceCell = 600.0;
constexpr double kFixedBytes = 1 << 20;

std::string Sci(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.2g", v);
  return buffer;
}

}  // namespace

Eigen::AlignedBox3d FindBounds(const CompiledSolid& solid, const Eigen::AlignedBox3d& search,
                               double resolution, const std::atomic<bool>* cancel) {
  if (search.isEmpty() || !search.min().allFinite() || !search.max().allFinite() ||
      !(resolution > 0.0)) {
    throw std::invalid_argument(
        "FindBounds: need a finite, non-empty search box and a resolution > 0");
  }
  // Halving stops at this size: bounded depth, and no box so thin that its centre rounds to a
  // side (which would split forever).
  const double finest = search.sizes().maxCoeff() * kMinFindBoundsFraction;
  const double cell = std::max(resolution, finest);
  Eigen::AlignedBox3d found;  // empty
  for (int axis = 0; axis < 3; ++axis) {
    const double lo = FarthestLeaf(solid, search, cell, axis, -1.0, cancel);
    if (std::isnan(lo)) return Eigen::AlignedBox3d();  // no leaf anywhere: empty
    found.min()[axis] = lo;
    found.max()[axis] = FarthestLeaf(solid, search, cell, axis, +1.0, cancel);
  }
  return found;
}

std::string SurfaceMeshEstimate::Describe() const {
  return "grid " + Sci(grid_cells) + " cells, surface ~" + Sci(surface_cells) + " cells, ~" +
         Sci(triangles) + " triangles, tape " + std::to_string(tape_instructions) +
         " instructions" +
         (evaluation_cost > tape_instructions ? " (cost " + Sci(evaluation_cost) + " each)" : "") +
         ", ~" + Sci(evaluations) + " evaluations, work ~" + Sci(work) + " instructions, memory ~" +
         Sci(bytes / (1 << 20)) + " MiB";
}

SurfaceMeshEstimate EstimateSurfaceMesh(const CompiledSolid& solid,
                                        const SurfaceMeshSettings& settings) {
  CheckGridSettings(settings);
  SurfaceMeshEstimate e;
  const Eigen::Vector3d extent = settings.bounds.sizes();
  const double h = settings.cell_size;
  const Eigen::Vector3d n = GridCells(extent, h);
  e.grid_cells = n.prod();
  e.tape_instructions = solid.instruction_count();
  // The coarse grid: at most kCoarseCellsAcross cells along the largest side, never finer than
  // the real one; centred on the bounds as MeshSurface centres its grid.
  // Long tapes (large unions) make each classification dear: fewer coarse cells keep the
  // estimate's own cost near kCoarseCellsAcross² × kCoarseTapeBudget instructions.
  const double across = std::max(
      4.0, kCoarseCellsAcross *
               std::sqrt(std::min(1.0, kCoarseTapeBudget / std::max(1, e.tape_instructions))));
  const double hc = std::max(h, extent.maxCoeff() / across);
  const Eigen::Vector3d nc = GridCells(extent, hc);
  const Eigen::Vector3d origin = settings.bounds.center() - 0.5 * hc * nc;
  double leaves = 0.0, classified = 0.0;
  CountAmbiguous(solid, origin, hc, {0, 0, 0}, {long(nc[0]), long(nc[1]), long(nc[2])}, &leaves,
                 &classified);
  // The surface's area in fine cells: each coarse cell it crosses holds (hc/h)² of them.
  const double ratio = hc / h;
  e.surface_cells = leaves > 0.0 ? std::min(leaves * ratio * ratio, e.grid_cells) : 0.0;
  e.triangles = kTrianglesPerSurfaceCell * e.surface_cells;
  e.evaluations =
      e.surface_cells *
          (kVertexEvaluationsPerCell + kEdgeVerticesPerCell * settings.refine_steps +
           (settings.clean ? kCleanupEvaluationsPerCell : 0.0) + kBoundsEvaluationsPerCell) +
      4.0 * classified;
  e.evaluation_cost = std::max(1.0, solid.EvaluationCost());
  e.work = e.evaluations * e.evaluation_cost;
  e.bytes = kFixedBytes + kBytesPerSurfaceCell * e.surface_cells;
  return e;
}

TriangleMesh MeshSurface(const CompiledSolid& solid, const SurfaceMeshSettings& settings,
                         SurfaceMeshStats* stats) {
  Mesher mesher(solid, settings);  // checks the settings
  if (settings.mesher == SurfaceMesher::kLattice) {
    if (!(settings.lattice_snap >= 0.0 && settings.lattice_snap <= kMaxLatticeSnap))
      throw std::invalid_argument("MeshSurface: settings.lattice_snap must be in [0, " +
                                  std::to_string(kMaxLatticeSnap) + "], got " +
                                  std::to_string(settings.lattice_snap));
    return internal::MeshSurfaceLattice(solid, settings, stats);
  }
  return mesher.Run(stats);
}

SurfaceError MeasureSurfaceError(const CompiledSolid& solid, const TriangleMesh& mesh) {
  SurfaceError e;
  double sum2 = 0.0;
  long count = 0;
  auto sample = [&](const Eigen::Vector3d& p) {
    const double d = std::abs(solid.Value(p));
    e.max = std::max(e.max, d);
    sum2 += d * d;
    ++count;
  };
  for (Eigen::Index i = 0; i < mesh.vertices.cols(); ++i) sample(mesh.vertices.col(i));
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.triangles(0, t));
    const Eigen::Vector3d b = mesh.vertices.col(mesh.triangles(1, t));
    const Eigen::Vector3d c = mesh.vertices.col(mesh.triangles(2, t));
    sample((a + b + c) / 3.0);
    sample((a + b) / 2.0);
    sample((b + c) / 2.0);
    sample((c + a) / 2.0);
  }
  e.rms = count > 0 ? std::sqrt(sum2 / double(count)) : 0.0;
  return e;
}

TriangleAngleStats MeasureTriangleAngles(const TriangleMesh& mesh, double small_angle_deg) {
  TriangleAngleStats stats;
  if (mesh.triangles.cols() == 0) return stats;
  stats.min_angle_deg = 180.0;
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.triangles(0, t));
    const Eigen::Vector3d b = mesh.vertices.col(mesh.triangles(1, t));
    const Eigen::Vector3d c = mesh.vertices.col(mesh.triangles(2, t));
    auto angle = [](const Eigen::Vector3d& u, const Eigen::Vector3d& w) {
      return std::atan2(u.cross(w).norm(), u.dot(w)) * 180.0 / M_PI;
    };
    const double m = std::min({angle(b - a, c - a), angle(a - b, c - b), angle(a - c, b - c)});
    if ((b - a).cross(c - a).norm() == 0.0) ++stats.zero_area;
    if (m < small_angle_deg) ++stats.small_angle;
    stats.min_angle_deg = std::min(stats.min_angle_deg, m);
  }
  return stats;
}

double MeshVolume(const TriangleMesh& mesh) {
  double v = 0.0;
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.triangles(0, t));
    const Eigen::Vector3d b = mesh.vertices.col(mesh.triangles(1, t));
    const Eigen::Vector3d c = mesh.vertices.col(mesh.triangles(2, t));
    v += a.dot(b.cross(c));
  }
  return v / 6.0;
}

}  // namespace spidarcad::modeling
