// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// MeshSurface's lattice route (SurfaceMesher::kLattice).
//
// The lattice is body-centred cubic: the corners of the mesher's grid cells and their centres.
// In doubled coordinates D (position = origin + D × cell / 2) corners have all three components
// even and centres all odd; every lattice vertex has 14 neighbours, 6 of its own kind at ±2 along
// an axis and 8 of the other kind at (±1, ±1, ±1). The tetrahedra are those of two neighbouring
// centres and one edge of the face between their cells (four per face), all congruent, and the
// tetrahedralization is conforming, so marching tetrahedra on it is watertight and manifold.
//
// A lattice vertex whose nearest crossing lies within settings.lattice_snap of an edge length
// is moved onto the surface along that edge, and every crossing of its edges becomes that one
// mesh vertex: the short edges and needles marching tetrahedra would make around it never
// appear, so there is no clean-up. (The snapping of lattice vertices onto the zero set follows
// Labelle and Shewchuk's isosurface stuffing, SIGGRAPH 2007, and manifold3d's level-set mesher,
// which bound the move to a quarter of the spacing.) Collapsing crossings can make a mesh vertex
// whose triangles form more than one fan; there the snap of the lattice vertex that moved
// farthest (that vertex or a snapped neighbour) is undone and the triangles are made again. A
// lattice vertex that had a crossing within the snap distance but did not snap keeps the
// crossings of its edges kMinFraction of an edge away.
//
// The field is max(value, distance to the bounds' box) (the solid clipped to the bounds). It is
// sampled in blocks of kBlock³ cells; a block whose interval bound, over the block grown by one
// cell, excludes zero is not sampled (its values are ±infinity: no edge from it crosses).
#include "lattice_mesher.h"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <limits>
#include <utility>
#include <vector>

#include "point_field.h"

namespace spidarcad::modeling::internal {

namespace {

using Vec = Eigen::Vector3d;
using D3 = std::array<int, 3>;

constexpr int kBlock = 4;  // lattice index units per block side
// Edge crossings stay this fraction of the edge away from a lattice vertex that had a crossing
// within the snap distance but could not snap.
constexpr double kMinFraction = 0.25;
constexpr double kInf = std::numeric_limits<double>::infinity();
// Sample: a block whose interval bound stays this far (m, relative beyond 1 m) above its
// greatest distance outside the bounds' box takes the solid's values as they are.
constexpr double kBoxMargin = 1e-9;

// The 14 neighbour offsets in doubled coordinates; k + 7 is the opposite of k (k < 7).
constexpr int kOffsets[14][3] = {{2, 0, 0},    {0, 2, 0},   {0, 0, 2},   {1, 1, 1},  {1, 1, -1},
                                 {1, -1, 1},   {1, -1, -1}, {-2, 0, 0},  {0, -2, 0}, {0, 0, -2},
                                 {-1, -1, -1}, {-1, -1, 1}, {-1, 1, -1}, {-1, 1, 1}};

// A lattice vertex with at least one crossing edge.
struct Active {
  D3 d;
  double value = 0.0;
  bool snapped = false;
  bool kept = false;  // a crossing lies within lattice_snap of it, yet it did not snap (or undone)
  int edges[7] = {-1, -1, -1, -1, -1, -1, -1};  // crossings of its edges kOffsets[0..6]
  unsigned crossing_dirs = 0;                   // bit k: the edge along kOffsets[k] crosses
  int best_dir = -1;    // the crossing edge with the nearest (linear) crossing
  double best_t = 2.0;  // its fraction from this vertex
  void Candidate(int k, double t) {
    crossing_dirs |= 1u << k;
    if (t < best_t) {
      best_t = t;
      best_dir = k;
    }
  }
  Vec position = Vec::Zero();  // when snapped
};

bool Inside(double v) { return v < 0.0; }

constexpr int kBlockVertices = kBlock * kBlock * kBlock;  // of each kind
// The corners of a face, in cyclic order: signs along the two other axes (axis + 1, axis + 2).
constexpr int kSigns[4][2] = {{1, 1}, {1, -1}, {-1, -1}, {-1, 1}};
// The 13 edges of a face's four tetrahedra, between its vertices 0 (the cell's centre), 1 (the
// neighbour's centre) and 2..5 (the face's corners in cyclic order).
constexpr std::pair<int, int> kFaceEdges[13] = {{0, 1}, {0, 2}, {0, 3}, {0, 4}, {0, 5},
                                                {1, 2}, {1, 3}, {1, 4}, {1, 5}, {2, 3},
                                                {3, 4}, {4, 5}, {5, 2}};
constexpr int kFarOutside = -1, kFarInside = -2;  // block_slot_ of unsampled blocks

// A sampled block: values and indices in active_ (-1: none) of its corners, then its centres.
// Values not sampled (beyond the grid's upper ends) stay +infinity, as beyond the grid.
struct NearBlock {
  NearBlock() {
    std::fill(std::begin(values), std::end(values), kInf);
    std::fill(std::begin(active), std::end(active), -1);
  }
  double values[2 * kBlockVertices];
  int active[2 * kBlockVertices];
};

class LatticeMesher {
 public:
  LatticeMesher(const CompiledSolid& solid, const SurfaceMeshSettings& s)
      : solid_(solid), settings_(s), field_(solid, s.bounds, s.cell_size) {
    h_ = s.cell_size;
    for (int a = 0; a < 3; ++a)
      n_[a] = std::max(1, static_cast<int>(std::ceil(s.bounds.sizes()[a] / h_ - 1e-9)));
    // The grid of MeshSurface's other route: centred on the bounds.
    origin_ = s.bounds.center() - 0.5 * h_ * Vec(n_[0], n_[1], n_[2]);
    for (int a = 0; a < 3; ++a) {
      corners_[a] = n_[a] + 3;  // doubled coordinates -2 .. 2n + 2
      centres_[a] = n_[a] + 2;  // -1 .. 2n + 1
      blocks_[a] = (corners_[a] + kBlock - 1) / kBlock;
    }
    block_slot_.assign(static_cast<size_t>(blocks_[0]) * blocks_[1] * blocks_[2], kFarOutside);
  }

  TriangleMesh Run(SurfaceMeshStats* stats) {
    const auto start = std::chrono::steady_clock::now();
    if (settings_.progress) settings_.progress(0.0);
    Sample();
    FindMixedFaces();
    if (settings_.clean) Snap();
    for (int round = 0;; ++round) {
      MakeTriangles();
      if (!settings_.clean) break;
      const int forbidden = ForbidNonManifold(round >= kMaxRounds);
      if (forbidden == 0) break;
    }
    TriangleMesh mesh = Compact();
    if (settings_.progress) settings_.progress(1.0);
    if (stats != nullptr) {
      stats->grid_cells = static_cast<long>(n_[0]) * n_[1] * n_[2];
      stats->evaluated_cells = static_cast<long>(near_.size()) * kBlockVertices;
      stats->field_evaluations = evaluations_;
      stats->collapsed_edges = 0;
      stats->snapped_vertices = snapped_;
      stats->flipped_edges = 0;
      stats->seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    return mesh;
  }

 private:
  static constexpr int kMaxRounds = 16;
  // A mixed face (FindMixedFaces).
  struct Face {
    D3 c;                                   // centre of the cell
    unsigned char axis = 0;                 // the face towards the cell at c + 2 e_axis
    unsigned char inside = 0;               // bit x: vertex x (c, c2, corners 0..3) is inside
    int act[6] = {-1, -1, -1, -1, -1, -1};  // their indices in active_, or -1
  };
  // MakeTriangles: no mesh vertex looked up yet (ids are >= 0 for crossings, <= -1 for snapped
  // lattice vertices).
  static constexpr int kNoVertex = std::numeric_limits<int>::min();

  // A lattice vertex's block (index into block_slot_) and its place in the block's arrays.
  long BlockOf(const D3& d) const {
    const unsigned i = unsigned(d[0] + 2) >> 1, j = unsigned(d[1] + 2) >> 1,
                   k = unsigned(d[2] + 2) >> 1;
    return long(i / kBlock) + blocks_[0] * (long(j / kBlock) + long(blocks_[1]) * (k / kBlock));
  }
  static int Local(const D3& d) {
    const unsigned i = unsigned(d[0] + 2) >> 1, j = unsigned(d[1] + 2) >> 1,
                   k = unsigned(d[2] + 2) >> 1;
    return (d[0] & 1) * kBlockVertices +
           int(i % kBlock + kBlock * (j % kBlock + kBlock * (k % kBlock)));
  }
  // Value of a lattice vertex: ±infinity in a block the bounds keep away from the surface.
  double ValueAt(const D3& d) const {
    const int slot = block_slot_[BlockOf(d)];
    if (slot < 0) return slot == kFarOutside ? kInf : -kInf;
    return near_blocks_data_[slot].values[Local(d)];
  }
  Vec Position(const D3& d) const { return origin_ + 0.5 * h_ * Vec(d[0], d[1], d[2]); }

  double BoxDistance(const Vec& p) const {
    const Vec below = settings_.bounds.min() - p, above = p - settings_.bounds.max();
    return below.cwiseMax(above).maxCoeff();
  }
  double Field(const Vec& p) {
    ++evaluations_;
    return std::max(field_.Value(p), BoxDistance(p));
  }
  // Value of a lattice vertex, evaluated if its block was not sampled.
  double ExactValue(const D3& d) {
    const double v = ValueAt(d);
    return std::isinf(v) ? Field(Position(d)) : v;
  }

  // Values of every lattice vertex: sampled in blocks near the surface, ±infinity elsewhere.
  void Sample() {
    const long total = static_cast<long>(blocks_[0]) * blocks_[1] * blocks_[2];
    Eigen::Matrix3Xd points(3, 2 * kBlock * kBlock * kBlock);
    Eigen::VectorXd values(2 * kBlock * kBlock * kBlock);
    std::vector<D3> ds;
    ds.reserve(2 * kBlock * kBlock * kBlock);
    const bool specialize = solid_.instruction_count() > PointField::kMinPrunedInstructions &&
                            solid_.instruction_count() <= PointField::kMaxPrunedInstructions;
    // First the interval bounds of every block (the blocks to sample in near_, their boxes and
    // bounds here), so that the sampled blocks' storage is made once at its size (growing it by
    // copies touched twice the memory).
    struct Bound {
      Eigen::AlignedBox3d box;
      double solid_lo, box_hi;
    };
    std::vector<Bound> near;
    long done = 0;
    for (int bk = 0; bk < blocks_[2]; ++bk)
      for (int bj = 0; bj < blocks_[1]; ++bj)
        for (int bi = 0; bi < blocks_[0]; ++bi, ++done) {
          if (settings_.cancel != nullptr && settings_.cancel->load(std::memory_order_relaxed))
            throw MeshingCancelled();
          if (settings_.progress && done % 4096 == 0)
            settings_.progress(0.25 * static_cast<double>(done) / static_cast<double>(total));
          const std::array<int, 3> b = {bi, bj, bk};
          // Lattice index i of either kind in [b kBlock, b kBlock + kBlock) lies at
          // origin + cell (i - 1) (corner) or (i - 1/2) (centre); grown by one cell.
          Vec lo, hi;
          for (int a = 0; a < 3; ++a) {
            lo[a] = origin_[a] + h_ * (b[a] * kBlock - 2.0);
            hi[a] = origin_[a] + h_ * (b[a] * kBlock + kBlock - 0.5);
          }
          const Eigen::AlignedBox3d box(lo, hi);
          Interval bound = solid_.Bounds(box);
          const double solid_lo = bound.lo;
          const Vec below_lo = settings_.bounds.min() - hi, below_hi = settings_.bounds.min() - lo;
          const Vec above_lo = lo - settings_.bounds.max(), above_hi = hi - settings_.bounds.max();
          const double box_lo = below_lo.cwiseMax(above_lo).maxCoeff();
          const double box_hi = below_hi.cwiseMax(above_hi).maxCoeff();
          bound.lo = std::max(bound.lo, box_lo);
          bound.hi = std::max(bound.hi, box_hi);
          const long block = bi + blocks_[0] * (static_cast<long>(bj) + blocks_[1] * bk);
          if (bound.lo > 0.0 || bound.hi < 0.0) {
            block_slot_[block] = bound.lo > 0.0 ? kFarOutside : kFarInside;
            continue;
          }
          block_slot_[block] = static_cast<int>(near.size());
          near_.push_back(b);
          near.push_back({box, solid_lo, box_hi});
        }
    near_blocks_data_.resize(near.size());
    for (size_t n = 0; n < near.size(); ++n) {
      if (settings_.cancel != nullptr && settings_.cancel->load(std::memory_order_relaxed))
        throw MeshingCancelled();
      if (settings_.progress && n % 1024 == 0)
        settings_.progress(0.25 + 0.25 * static_cast<double>(n) / static_cast<double>(near.size()));
      const std::array<int, 3>& b = near_[n];
      const auto& [box, solid_lo, box_hi] = near[n];
      ds.clear();
      for (int kind = 0; kind < 2; ++kind) {
        const int* dims = kind == 0 ? corners_ : centres_;
        for (int k = b[2] * kBlock; k < std::min(dims[2], b[2] * kBlock + kBlock); ++k)
          for (int j = b[1] * kBlock; j < std::min(dims[1], b[1] * kBlock + kBlock); ++j)
            for (int i = b[0] * kBlock; i < std::min(dims[0], b[0] * kBlock + kBlock); ++i)
              ds.push_back({2 * i - 2 + kind, 2 * j - 2 + kind, 2 * k - 2 + kind});
      }
      NearBlock& data = near_blocks_data_[n];
      const int count = static_cast<int>(ds.size());
      for (int p = 0; p < count; ++p) points.col(p) = Position(ds[p]);
      if (specialize) {
        const CompiledSolid tape = solid_.Specialize(box);
        tape.Values(points.leftCols(count), values.head(count));
      } else {
        solid_.Values(points.leftCols(count), values.head(count));
      }
      evaluations_ += count;
      // The block's values are already in Local's order when it is whole (not cut off by the
      // grid's upper ends); the bounds' box does not change them where it stays farther from
      // every point than the solid (by a margin above the rounding of either).
      const bool whole = count == 2 * kBlockVertices;
      if (whole && box_hi < solid_lo - kBoxMargin * (1.0 + std::abs(solid_lo))) {
        std::copy(values.data(), values.data() + count, data.values);
      } else {
        for (int p = 0; p < count; ++p)
          data.values[whole ? p : Local(ds[p])] = std::max(values[p], BoxDistance(points.col(p)));
      }
    }
  }

  // The faces between neighbouring cells whose four tetrahedra have vertices on both sides
  // (mixed_faces_), found block by block from a local copy of the values, and the lattice
  // vertices with a crossing edge (active_): every edge lies in the tetrahedra of some face.
  // Per block, the inside flags of the copy are bit sets over its flattened index, so that the
  // mixed faces along an axis come from a few shifts and masks; they are then visited in the
  // order of the cells (flattened index) and, per cell, of the axes.
  void FindMixedFaces() {
    // Capacities from the sampled blocks (measured on spheres and the platform: about 27 active
    // vertices, 40 mixed faces and 16 crossings per sampled block); reserving address space
    // touches no memory, and growing these arrays by copies cost a tenth of the run.
    active_.reserve(40 * near_.size());
    mixed_faces_.reserve(64 * near_.size());
    crossings_.reserve(32 * near_.size());
    // Values and inside flags of the corners and centres with lattice index in [block start,
    // block start + kBlock] per axis, flattened as i + kL j + kL² k (BlockCopy).
    BlockCopy copy;
    int corner_offset[3][4];
    for (int axis = 0; axis < 3; ++axis)
      for (int r = 0; r < 4; ++r)
        corner_offset[axis][r] = kStride[axis] + (kSigns[r][0] > 0 ? kStride[(axis + 1) % 3] : 0) +
                                 (kSigns[r][1] > 0 ? kStride[(axis + 2) % 3] : 0);
    // The cells of a block (flattened index with i, j, k < kBlock), and of those the ones with a
    // neighbour along each axis, for a block away from the grid's upper ends.
    Bits full_cells = 0, full_faces[3] = {0, 0, 0};
    for (int k = 0; k < kBlock; ++k)
      for (int j = 0; j < kBlock; ++j)
        for (int i = 0; i < kBlock; ++i) full_cells |= Bits{1} << (i + kL * (j + kL * k));
    for (int axis = 0; axis < 3; ++axis) full_faces[axis] = full_cells;
    for (const auto& b : near_) {
      const int base[3] = {b[0] * kBlock, b[1] * kBlock, b[2] * kBlock};
      CopyBlock(base, &copy);
      const Bits any = copy.corner_in | copy.centre_in;
      // The bounds are loose: some sampled blocks have no sign change at all.
      if (any == 0 || (copy.corner_in & copy.centre_in) == kAllBits) continue;
      const Bits* faces = full_faces;
      Bits edge_faces[3];
      if (base[0] + kBlock >= centres_[0] || base[1] + kBlock >= centres_[1] ||
          base[2] + kBlock >= centres_[2]) {
        // Near the grid's upper ends: only cells that exist, with a neighbour along the axis.
        for (int axis = 0; axis < 3; ++axis) edge_faces[axis] = 0;
        for (int k = 0; k < kBlock && base[2] + k < centres_[2]; ++k)
          for (int j = 0; j < kBlock && base[1] + j < centres_[1]; ++j)
            for (int i = 0; i < kBlock && base[0] + i < centres_[0]; ++i) {
              const int m[3] = {i, j, k};
              for (int axis = 0; axis < 3; ++axis)
                if (base[axis] + m[axis] + 1 < centres_[axis])
                  edge_faces[axis] |= Bits{1} << (i + kL * (j + kL * k));
            }
        faces = edge_faces;
      }
      Bits mixed[3];
      for (int axis = 0; axis < 3; ++axis) {
        const int* q = corner_offset[axis];
        const Bits c = copy.centre_in, n = copy.corner_in;
        const Bits some = c | c >> kStride[axis] | n >> q[0] | n >> q[1] | n >> q[2] | n >> q[3];
        const Bits all = c & c >> kStride[axis] & n >> q[0] & n >> q[1] & n >> q[2] & n >> q[3];
        mixed[axis] = some & ~all & faces[axis];
      }
      for (Bits cells = mixed[0] | mixed[1] | mixed[2]; cells != 0;) {
        const int at = LowestBit(cells);
        cells &= cells - 1;
        for (int axis = 0; axis < 3; ++axis)
          if ((mixed[axis] >> at & 1) != 0) AddFace(base, at, axis, corner_offset[axis], &copy);
      }
    }
  }

  // kBlock + 1 lattice indices per axis: a block's own and the first of the next block.
  static constexpr int kL = kBlock + 1;
  static constexpr int kStride[3] = {1, kL, kL* kL};
  __extension__ typedef unsigned __int128 Bits;  // one bit per flattened index (kL³ <= 128)
  static_assert(kL * kL * kL < 128);
  static constexpr Bits kAllBits = (Bits{1} << (kL * kL * kL)) - 1;
  static int LowestBit(Bits b) {
    const auto low = static_cast<std::uint64_t>(b);
    return low != 0 ? std::countr_zero(low)
                    : 64 + std::countr_zero(static_cast<std::uint64_t>(b >> 64));
  }

  // A block's values and inside flags (corners and centres, flattened as i + kL j + kL² k), and
  // the active_ indices of the eight blocks it reads (null: an unsampled block, or beyond the
  // grid, where no vertex is made active).
  struct BlockCopy {
    double corner[kL * kL * kL], centre[kL * kL * kL];
    Bits corner_in = 0, centre_in = 0;
    int* active[8];
  };

  // Per flattened index: which of the eight blocks holds it (bit 0: the next along x, bit 1: y,
  // bit 2: z) and its index there (corners; centres kBlockVertices on).
  struct CopyTables {
    unsigned char block[kL * kL * kL];
    unsigned char local[kL * kL * kL];
  };
  static const CopyTables& Tables() {
    static const CopyTables t = [] {
      CopyTables c{};
      for (int k = 0, at = 0; k < kL; ++k)
        for (int j = 0; j < kL; ++j)
          for (int i = 0; i < kL; ++i, ++at) {
            c.block[at] = static_cast<unsigned char>((i == kBlock ? 1 : 0) | (j == kBlock ? 2 : 0) |
                                                     (k == kBlock ? 4 : 0));
            c.local[at] = static_cast<unsigned char>(
                (i % kBlock) + kBlock * ((j % kBlock) + kBlock * (k % kBlock)));
          }
      return c;
    }();
    return t;
  }

  // Fills `copy` for the block starting at lattice index `base`: its own values, and those of
  // the next blocks along each axis; ±infinity in unsampled blocks (as ValueAt), +infinity beyond
  // the grid (blocks beyond it, and a sampled block's vertices beyond it: NearBlock).
  void CopyBlock(const int (&base)[3], BlockCopy* copy) {
    static const auto filled = [](double v) {
      std::array<double, 2 * kBlockVertices> a;
      a.fill(v);
      return a;
    };
    static const std::array<double, 2 *kBlockVertices> outside = filled(kInf),
                                                       inside = filled(-kInf);
    const double* values[8];
    for (int nb = 0; nb < 8; ++nb) {
      const int g[3] = {base[0] + (nb & 1) * kBlock, base[1] + (nb >> 1 & 1) * kBlock,
                        base[2] + (nb >> 2 & 1) * kBlock};
      values[nb] = outside.data();
      copy->active[nb] = nullptr;
      if (g[0] >= corners_[0] || g[1] >= corners_[1] || g[2] >= corners_[2]) continue;
      const int slot = block_slot_[BlockOf({2 * g[0] - 2, 2 * g[1] - 2, 2 * g[2] - 2})];
      if (slot >= 0) {
        values[nb] = near_blocks_data_[slot].values;
        copy->active[nb] = near_blocks_data_[slot].active;
      } else if (slot == kFarInside) {
        values[nb] = inside.data();
      }
    }
    const CopyTables& t = Tables();
    for (int at = 0; at < kL * kL * kL; ++at) {
      const double* v = values[t.block[at]] + t.local[at];
      copy->corner[at] = v[0];
      copy->centre[at] = v[kBlockVertices];
    }
    std::uint64_t in[4] = {0, 0, 0, 0};  // corners' bits 0..63, 64..; centres' the same
    for (int at = 0; at < 64; ++at) {
      in[0] |= std::uint64_t{Inside(copy->corner[at])} << at;
      in[2] |= std::uint64_t{Inside(copy->centre[at])} << at;
    }
    for (int at = 64; at < kL * kL * kL; ++at) {
      in[1] |= std::uint64_t{Inside(copy->corner[at])} << (at - 64);
      in[3] |= std::uint64_t{Inside(copy->centre[at])} << (at - 64);
    }
    copy->corner_in = Bits{in[1]} << 64 | in[0];
    copy->centre_in = Bits{in[3]} << 64 | in[2];
  }

  // Doubled coordinates of vertex x of the face of the cell with centre c along `axis` (as
  // FaceVertices).
  static D3 FaceVertex(const D3& c, int axis, int x) {
    if (x == 0) return c;
    if (x == 1) {
      D3 d = c;
      d[axis] += 2;
      return d;
    }
    return FaceCorner(c, axis, x - 2);
  }

  // Of a face whose vertex x is inside when bit x is set: its crossing edges (bit e of
  // kFaceEdges), and the vertices on them in the order of their first crossing edge.
  struct FacePattern {
    std::uint16_t edges = 0;
    int count = 0;
    int vertices[6] = {};
  };
  static const std::array<FacePattern, 64>& FacePatterns() {
    static const std::array<FacePattern, 64> table = [] {
      std::array<FacePattern, 64> t{};
      for (int p = 0; p < 64; ++p) {
        unsigned seen = 0;
        for (int e = 0; e < 13; ++e) {
          const auto [x, y] = kFaceEdges[e];
          if ((p >> x & 1) == (p >> y & 1)) continue;
          t[p].edges |= static_cast<std::uint16_t>(1u << e);
          for (int z : {x, y})
            if ((seen >> z & 1) == 0) {
              seen |= 1u << z;
              t[p].vertices[t[p].count++] = z;
            }
        }
      }
      return t;
    }();
    return table;
  }

  // Records the mixed face of cell `at` (flattened in the block at `base`) along `axis`: its six
  // vertices (c, c2, the four corners at `at` + q[r]) as active where they have a crossing edge
  // among the face's tetrahedra (c and c2 are joined to all, corner r to corners r ± 1), and each
  // crossing edge as a snap candidate of both its ends.
  void AddFace(const int (&base)[3], int at, int axis, const int (&q)[4], BlockCopy* copy) {
    const int i = at % kL, j = at / kL % kL, k = at / (kL * kL);
    Face face;
    face.c = {2 * (base[0] + i) - 1, 2 * (base[1] + j) - 1, 2 * (base[2] + k) - 1};
    face.axis = static_cast<unsigned char>(axis);
    const int at2 = at + kStride[axis];
    const double v[6] = {copy->centre[at],        copy->centre[at2],       copy->corner[at + q[0]],
                         copy->corner[at + q[1]], copy->corner[at + q[2]], copy->corner[at + q[3]]};
    const int index[6] = {at, at2, at + q[0], at + q[1], at + q[2], at + q[3]};
    for (int x = 0; x < 6; ++x)
      if (Inside(v[x])) face.inside |= static_cast<unsigned char>(1u << x);
    // The index in active_ of each vertex on a crossing edge (made now if new; -1 where no
    // block was sampled, not reached: the bounds keep crossings out of unsampled blocks).
    const CopyTables& tables = Tables();
    const FacePattern& pattern = FacePatterns()[face.inside];
    for (int n = 0; n < pattern.count; ++n) {
      const int x = pattern.vertices[n];
      int* block = copy->active[tables.block[index[x]]];
      if (block == nullptr) continue;
      int& id = block[(x < 2 ? kBlockVertices : 0) + tables.local[index[x]]];
      if (id < 0) {
        id = static_cast<int>(active_.size());
        Active a;
        a.d = FaceVertex(face.c, axis, x);
        a.value = v[x];
        active_.push_back(a);
      }
      face.act[x] = id;
    }
    const auto& offsets = FaceOffsets()[axis];
    for (unsigned edges = pattern.edges; edges != 0; edges &= edges - 1) {
      const int e = std::countr_zero(edges);
      const auto [x, y] = kFaceEdges[e];
      const int kk = offsets[6 * x + y];
      const double t = std::isinf(v[y]) ? 0.0 : v[x] / (v[x] - v[y]);
      if (face.act[x] >= 0) active_[face.act[x]].Candidate(kk, t);
      if (face.act[y] >= 0) active_[face.act[y]].Candidate((kk + 7) % 14, 1.0 - t);
    }
    mixed_faces_.push_back(face);
  }

  // The six vertices of a face: the cell's centre c, its neighbour's centre, the four corners.
  static void FaceVertices(const D3& c, int axis, D3 (&d)[6]) {
    for (int x = 0; x < 6; ++x) d[x] = FaceVertex(c, axis, x);
  }

  // Corner r of the face between the cell of centre c and its neighbour along axis.
  static D3 FaceCorner(const D3& c, int axis, int r) {
    D3 q = c;
    q[axis] += 1;
    q[(axis + 1) % 3] += kSigns[r][0];
    q[(axis + 2) % 3] += kSigns[r][1];
    return q;
  }

  // The surface point on the lattice edge from a (value va) to b (value vb), opposite signs, as
  // the fraction of the way to b: regula falsi (Illinois) for settings.refine_steps steps, then
  // the secant.
  double CrossingFraction(const Vec& a, double va, const Vec& b, double vb) {
    if (va == 0.0) return 0.0;
    if (vb == 0.0) return 1.0;
    double ta = 0.0, tb = 1.0;
    int side = 0;
    for (int step = 0; step < settings_.refine_steps; ++step) {
      const double t = ta + (tb - ta) * va / (va - vb);
      const double vt = Field(a + t * (b - a));
      if (vt == 0.0) return t;
      if (Inside(vt) == Inside(va)) {
        ta = t;
        va = vt;
        if (side == -1) vb *= 0.5;
        side = -1;
      } else {
        tb = t;
        vb = vt;
        if (side == 1) va *= 0.5;
        side = 1;
      }
    }
    return ta + (tb - ta) * va / (va - vb);
  }

  // Moves each active lattice vertex whose nearest crossing is within lattice_snap of its edge
  // onto the surface along that edge, unless it lies in a sheet thinner than two edges on more
  // than three axes (its crossings on opposite sides would collapse a thin feature).
  void Snap() {
    const double limit = settings_.lattice_snap;
    for (Active& a : active_) {
      const double v = a.value;
      const int best = a.best_dir;
      const unsigned opposed_axes = a.crossing_dirs & (a.crossing_dirs >> 7) & 0x7fu;
      const int opposed = std::popcount(opposed_axes);
      if (best < 0 || !(a.best_t < limit)) continue;
      a.kept = true;  // unless it snaps below
      if (opposed > 3) continue;
      const D3 e = {a.d[0] + kOffsets[best][0], a.d[1] + kOffsets[best][1],
                    a.d[2] + kOffsets[best][2]};
      const Vec p0 = Position(a.d);
      const Vec p1 = Position(e);
      const Vec p = p0 + CrossingFraction(p0, v, p1, ExactValue(e)) * (p1 - p0);
      if (((p - p0).cwiseAbs().array() <= limit * h_ * (1.0 + 1e-9)).all()) {
        a.snapped = true;
        a.kept = false;
        a.position = p;
        ++snapped_;
      }
    }
  }

  // Mesh vertex ids: an edge crossing's index in crossings_ (>= 0), or -1 - the index in
  // active_ of a snapped lattice vertex.
  static int SnappedId(int active) { return -1 - active; }
  static size_t ActiveOf(int id) { return static_cast<size_t>(-1 - id); }
  Vec Point(int id) const { return id >= 0 ? crossings_[id] : active_[ActiveOf(id)].position; }

  // The mesh vertex of the crossing on the edge between vertices x0 and x1 of face f (as
  // FaceVertices): a snapped end's (the one nearer the surface when both are), else the edge's
  // own, made once.
  int EdgeVertex(const Face& f, int x0, int x1) {
    // Both ends have a crossing edge (this one), so both are active; the interval bounds
    // guarantee it, and a vertex missed anyway gets its exact value and no snap.
    Active* a0 = f.act[x0] >= 0 ? &active_[f.act[x0]] : nullptr;
    Active* a1 = f.act[x1] >= 0 ? &active_[f.act[x1]] : nullptr;
    const bool s0 = a0 != nullptr && a0->snapped, s1 = a1 != nullptr && a1->snapped;
    if (s0 || s1) {
      Active* pick = a0;
      if (!s0 || (s1 && (std::abs(a1->value) < std::abs(a0->value) ||
                         (std::abs(a1->value) == std::abs(a0->value) && a1->d < a0->d))))
        pick = a1;
      return SnappedId(static_cast<int>(pick - active_.data()));
    }
    // The edge belongs to the end from which it is one of the first seven offsets.
    const int k = FaceOffsets()[f.axis][6 * x0 + x1];
    Active* owner = k < 7 ? a0 : a1;
    int* id = owner != nullptr ? &owner->edges[k % 7] : nullptr;
    if (id != nullptr && *id >= 0) return *id;
    const int index = static_cast<int>(crossings_.size());
    // An end that could not snap (a thin feature, or a snap that was undone) keeps the
    // crossings on its edges kMinFraction of the edge away, so that they stay apart.
    const D3 d0 = a0 != nullptr ? a0->d : FaceVertex(f.c, f.axis, x0);
    const D3 d1 = a1 != nullptr ? a1->d : FaceVertex(f.c, f.axis, x1);
    const Vec p0 = Position(d0), p1 = Position(d1);
    double t = CrossingFraction(p0, a0 != nullptr ? a0->value : ExactValue(d0), p1,
                                a1 != nullptr ? a1->value : ExactValue(d1));
    if (a0 != nullptr && a0->kept) t = std::max(t, kMinFraction);
    if (a1 != nullptr && a1->kept) t = std::min(t, 1.0 - kMinFraction);
    crossings_.push_back(p0 + t * (p1 - p0));
    if (id != nullptr) *id = index;
    return index;
  }

  // OffsetIndex between vertices x0 and x1 of any face along `axis` (as FaceVertices), per axis:
  // entry 6 x0 + x1 of FaceOffsets()[axis].
  using FaceOffsetTable = std::array<std::array<signed char, 6 * 6>, 3>;
  static const FaceOffsetTable& FaceOffsets() {
    static const FaceOffsetTable table = [] {
      FaceOffsetTable t{};
      for (int axis = 0; axis < 3; ++axis) {
        D3 d[6];
        FaceVertices({1, 1, 1}, axis, d);
        for (int i = 0; i < 6; ++i)
          for (int j = 0; j < 6; ++j)
            t[axis][6 * i + j] = static_cast<signed char>(i == j ? -1 : OffsetIndex(d[i], d[j]));
      }
      return t;
    }();
    return table;
  }

  // Index k of kOffsets with d0 + kOffsets[k] = d1.
  static int OffsetIndex(const D3& d0, const D3& d1) {
    static const std::array<signed char, 125> table = [] {
      std::array<signed char, 125> t{};
      t.fill(-1);
      for (int k = 0; k < 14; ++k)
        t[(kOffsets[k][0] + 2) * 25 + (kOffsets[k][1] + 2) * 5 + kOffsets[k][2] + 2] =
            static_cast<signed char>(k);
      return t;
    }();
    return table[(d1[0] - d0[0] + 2) * 25 + (d1[1] - d0[1] + 2) * 5 + d1[2] - d0[2] + 2];
  }

  void Emit(int a, int b, int c) {
    if (a == b || b == c || c == a) return;
    triangles_.push_back({a, b, c});
  }

  // What marching tetrahedra makes in one tetrahedron of a face for one sign pattern: nothing,
  // a triangle or a quad, as its crossed edges (pairs of the tetrahedron's vertices) in the order
  // that faces outward. Tetrahedra of faces along the same axis, at the same corner r, are
  // translates of each other, so the order depends only on (axis, r, pattern).
  struct TetCase {
    int corners = 0;  // 0, 3 or 4
    int edges[4][2] = {};
  };

  // The case of the tetrahedron with doubled coordinates t whose vertex i is inside when bit i of
  // pattern is set: the crossings' order from the outward normal at the edge midpoints (the same
  // as at any points inside those edges).
  static TetCase MakeTetCase(const D3 (&t)[4], int pattern) {
    TetCase tc;
    int in[4] = {0, 0, 0, 0}, out[4] = {0, 0, 0, 0}, ni = 0, no = 0;
    for (int i = 0; i < 4; ++i) ((pattern >> i & 1) != 0 ? in[ni++] : out[no++]) = i;
    if (ni == 0 || no == 0) return tc;
    auto mid = [&](int i, int j) -> Vec {
      return Vec(t[i][0] + t[j][0], t[i][1] + t[j][1], t[i][2] + t[j][2]) * 0.5;
    };
    auto point = [&](int i) -> Vec { return Vec(t[i][0], t[i][1], t[i][2]); };
    if (ni == 1 || no == 1) {
      const int lone = ni == 1 ? in[0] : out[0];
      int others[3] = {0, 0, 0}, n = 0;
      for (int i = 0; i < 4; ++i)
        if (i != lone) others[n++] = i;
      const Vec ma = mid(lone, others[0]), mb = mid(lone, others[1]), mc = mid(lone, others[2]);
      // Outward: away from a lone inside vertex, towards a lone outside one.
      const Vec outward = (ni == 1 ? 1.0 : -1.0) * (ma - point(lone));
      if ((mb - ma).cross(mc - ma).dot(outward) < 0.0) std::swap(others[1], others[2]);
      tc.corners = 3;
      for (int k = 0; k < 3; ++k) {
        tc.edges[k][0] = lone;
        tc.edges[k][1] = others[k];
      }
      return tc;
    }
    // Two inside, two outside: the quad of the four crossings, in cyclic order.
    int ends[4][2] = {{in[0], out[0]}, {in[0], out[1]}, {in[1], out[1]}, {in[1], out[0]}};
    const Vec outward = point(out[0]) + point(out[1]) - point(in[0]) - point(in[1]);
    const Vec m0 = mid(ends[0][0], ends[0][1]), m1 = mid(ends[1][0], ends[1][1]),
              m2 = mid(ends[2][0], ends[2][1]);
    if ((m1 - m0).cross(m2 - m0).dot(outward) < 0.0) std::swap(ends[1], ends[3]);
    tc.corners = 4;
    for (int k = 0; k < 4; ++k) {
      tc.edges[k][0] = ends[k][0];
      tc.edges[k][1] = ends[k][1];
    }
    return tc;
  }

  // The case of tetrahedron r of a face along `axis` for its sign pattern, from a table built
  // once from a face at the lattice's origin.
  static const TetCase& TetCaseOf(int axis, int r, int pattern) {
    static const std::vector<TetCase> table = [] {
      std::vector<TetCase> t(3 * 4 * 16);
      for (int axis = 0; axis < 3; ++axis) {
        D3 d[6];
        FaceVertices({1, 1, 1}, axis, d);
        for (int r = 0; r < 4; ++r) {
          const D3 tet[4] = {d[0], d[1], d[2 + r], d[2 + (r + 1) % 4]};
          for (int pattern = 0; pattern < 16; ++pattern)
            t[(axis * 4 + r) * 16 + pattern] = MakeTetCase(tet, pattern);
        }
      }
      return t;
    }();
    return table[(axis * 4 + r) * 16 + pattern];
  }

  // The tetrahedra of a face along `axis` whose vertex x (as FaceVertices) is inside when bit x
  // of `inside` is set, with a crossing: their cases with the crossed edges' ends as face
  // vertices.
  struct FaceTets {
    int count = 0;
    TetCase tets[4];
  };
  static const FaceTets& FaceTetsOf(int axis, int inside) {
    static const std::vector<FaceTets> table = [] {
      std::vector<FaceTets> t(3 * 64);
      for (int axis = 0; axis < 3; ++axis)
        for (int in = 0; in < 64; ++in) {
          FaceTets& ft = t[axis * 64 + in];
          for (int r = 0; r < 4; ++r) {
            const int x[4] = {0, 1, 2 + r, 2 + (r + 1) % 4};
            const int pattern = (in >> x[0] & 1) | (in >> x[1] & 1) << 1 | (in >> x[2] & 1) << 2 |
                                (in >> x[3] & 1) << 3;
            TetCase tc = TetCaseOf(axis, r, pattern);
            if (tc.corners == 0) continue;
            for (auto& edge : tc.edges)
              for (int& end : edge) end = x[end];
            ft.tets[ft.count++] = tc;
          }
        }
      return t;
    }();
    return table[axis * 64 + inside];
  }

  // The triangles of one tetrahedron of a face for its case (edges' ends as face vertices);
  // `edge_of(a, b)` gives the mesh vertex on the face's edge between face vertices a and b.
  template <typename EdgeOf>
  void Tetrahedron(const TetCase& tc, EdgeOf&& edge_of) {
    auto edge = [&](int k) { return edge_of(tc.edges[k][0], tc.edges[k][1]); };
    if (tc.corners == 3) {
      Emit(edge(0), edge(1), edge(2));
      return;
    }
    if (tc.corners != 4) return;
    int q[4];
    for (int k = 0; k < 4; ++k) q[k] = edge(k);
    // Split along the diagonal whose ends coincide (both halves vanish), else the shorter.
    bool diagonal02;
    if (q[0] == q[2]) {
      diagonal02 = true;
    } else if (q[1] == q[3]) {
      diagonal02 = false;
    } else {
      diagonal02 =
          (Point(q[0]) - Point(q[2])).squaredNorm() <= (Point(q[1]) - Point(q[3])).squaredNorm();
    }
    if (diagonal02) {
      Emit(q[0], q[1], q[2]);
      Emit(q[0], q[2], q[3]);
    } else {
      Emit(q[0], q[1], q[3]);
      Emit(q[1], q[2], q[3]);
    }
  }

  // Marching tetrahedra over the tetrahedra of the mixed faces. Each crossing edge of a face is
  // looked up once per face (the edge between the two centres is in all four of its
  // tetrahedra, the others in one or two).
  void MakeTriangles() {
    triangles_.clear();
    triangles_.reserve(3 * mixed_faces_.size());
    for (const Face& f : mixed_faces_) {
      int vertex_of[6][6];  // mesh vertex on the edge between face vertices a and b, once made
      for (auto& row : vertex_of) std::fill(std::begin(row), std::end(row), kNoVertex);
      auto edge_of = [&](int a, int b) {
        int& id = vertex_of[std::min(a, b)][std::max(a, b)];
        if (id == kNoVertex) id = EdgeVertex(f, a, b);
        return id;
      };
      const FaceTets& ft = FaceTetsOf(f.axis, f.inside);
      for (int n = 0; n < ft.count; ++n) Tetrahedron(ft.tets[n], edge_of);
    }
  }

  // Snapped mesh vertices whose triangles are not one fan keep their lattice vertex in place
  // (all of them when `all`); returns how many were forbidden.
  int ForbidNonManifold(bool all) {
    // Link edges (b, c) of every triangle (s, b, c) at each snapped corner s, by active index.
    std::vector<int> start(active_.size() + 1, 0);
    for (const auto& t : triangles_)
      for (int c : t)
        if (c < 0) ++start[ActiveOf(c) + 1];
    for (size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
    std::vector<std::array<int, 2>> links(start.back());
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (const auto& t : triangles_)
      for (int r = 0; r < 3; ++r)
        if (t[r] < 0) links[fill[ActiveOf(t[r])]++] = {t[(r + 1) % 3], t[(r + 2) % 3]};
    for (size_t s = 0; s < active_.size(); ++s) {
      if (!active_[s].snapped) continue;
      const int b = start[s], e = start[s + 1];
      if (b == e) continue;  // in no triangle: not in the mesh
      bool manifold = e - b >= 3;
      // One directed cycle: every vertex once as a source and once as a target, and a walk from
      // the first edge comes back after all of them.
      for (int i = b; manifold && i < e; ++i)
        for (int j = i + 1; j < e; ++j)
          if (links[i][0] == links[j][0] || links[i][1] == links[j][1]) {
            manifold = false;
            break;
          }
      if (manifold) {
        int steps = 0, at = links[b][1];
        while (at != links[b][0] && steps <= e - b) {
          int i = b;
          while (i < e && links[i][0] != at) ++i;
          if (i == e) break;
          at = links[i][1];
          ++steps;
        }
        manifold = at == links[b][0] && steps == e - b - 1;
      }
      if (manifold && !all) continue;
      // Undo the snap of the lattice vertex, of s and the snapped vertices around it, that
      // moved farthest (the largest fraction of its edge): the one whose crossings, kept apart
      // again, make the best triangles.
      size_t undo = s;
      if (!all)
        for (int i = b; i < e; ++i)
          for (int id : links[i])
            if (id < 0 && active_[ActiveOf(id)].snapped &&
                active_[ActiveOf(id)].best_t > active_[undo].best_t)
              undo = ActiveOf(id);
      undo_.push_back(undo);
    }
    int forbidden = 0;
    for (size_t undo : undo_) {
      if (!active_[undo].snapped) continue;  // named twice
      active_[undo].snapped = false;
      active_[undo].kept = true;
      --snapped_;
      ++forbidden;
    }
    undo_.clear();
    return forbidden;
  }

  // The mesh of the referenced vertices.
  TriangleMesh Compact() {
    // Vertex ids: crossings c >= 0 at remap[c], snapped vertices at remap[crossings + active].
    const size_t base = crossings_.size();
    std::vector<int> remap(base + active_.size(), -1);
    std::vector<Vec> points;
    points.reserve(triangles_.size() / 2 + 8);
    for (const auto& t : triangles_)
      for (int c : t) {
        const size_t slot = c >= 0 ? static_cast<size_t>(c) : base + ActiveOf(c);
        if (remap[slot] < 0) {
          remap[slot] = static_cast<int>(points.size());
          points.push_back(Point(c));
        }
      }
    TriangleMesh mesh;
    mesh.vertices.resize(3, static_cast<Eigen::Index>(points.size()));
    for (size_t i = 0; i < points.size(); ++i)
      mesh.vertices.col(static_cast<Eigen::Index>(i)) = points[i];
    mesh.triangles.resize(3, static_cast<Eigen::Index>(triangles_.size()));
    for (size_t t = 0; t < triangles_.size(); ++t)
      for (int r = 0; r < 3; ++r) {
        const int c = triangles_[t][r];
        mesh.triangles(r, static_cast<Eigen::Index>(t)) =
            remap[c >= 0 ? static_cast<size_t>(c) : base + ActiveOf(c)];
      }
    return mesh;
  }

  const CompiledSolid& solid_;
  const SurfaceMeshSettings& settings_;
  const PointField field_;
  double h_ = 0.0;
  int n_[3] = {};
  int corners_[3] = {}, centres_[3] = {}, blocks_[3] = {};
  Vec origin_;
  // Per block: its index in near_blocks_data_ (sampled), or kFarOutside / kFarInside.
  std::vector<int> block_slot_;
  std::vector<NearBlock> near_blocks_data_;
  std::vector<std::array<int, 3>> near_;  // the sampled blocks' indices, in sampling order
  std::vector<Face> mixed_faces_;
  long evaluations_ = 0;
  long snapped_ = 0;
  std::vector<Active> active_;
  std::vector<Vec> crossings_;  // edge crossings, by Active::edges
  std::vector<size_t> undo_;    // ForbidNonManifold's choices
  std::vector<std::array<int, 3>> triangles_;
};

}  // namespace

TriangleMesh MeshSurfaceLattice(const CompiledSolid& solid, const SurfaceMeshSettings& settings,
                                SurfaceMeshStats* stats) {
  LatticeMesher mesher(solid, settings);
  return mesher.Run(stats);
}

}  // namespace spidarcad::modeling::internal
