// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/implicit_evaluator.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "primitive_lanes.h"
#include "primitives.h"

namespace spidarcad::modeling {

using internal::Dual;
using Op = CompiledSolid::Op;

namespace {

// Constant layout of a primitive instruction: the map q = A p + b from world to local frame
// (A row-major, 9 values; b, 3 values), the value scale k, the Lipschitz constant L = k·|A|₂
// of the world field, then the primitive's own parameters.
constexpr int kA = 0;
constexpr int kB = 9;
constexpr int kScale = 12;
constexpr int kLipschitz = 13;
constexpr int kParams = 14;

// Primitives whose formulas have no branches: interval arithmetic applies directly.
template <typename T>
T EvalBranchFree(Op op, const double* c, T x, T y, T z) noexcept {
  using namespace internal;
  switch (op) {
    case Op::kSphere:
      return SphereField(x, y, z, c[0]);
    case Op::kBox:
      return BoxField(x, y, z, c[0], c[1], c[2]);
    case Op::kRoundedBox:
      return RoundedBoxField(x, y, z, c[0], c[1], c[2], c[3]);
    case Op::kCylinder:
      return CylinderField(x, y, z, c[0], c[1]);
    case Op::kCapsule:
      return CapsuleField(x, y, z, c, c + 3, c[6], c[7]);
    case Op::kTorus:
      return TorusField(x, y, z, c[0], c[1]);
    case Op::kHalfSpace:
      return HalfSpaceField(x, y, z, c[0], c[1], c[2], c[3]);
    default:
      return x * 0.0;  // unreachable for branch-free opcodes
  }
}

// Every primitive, for the point types (double and Dual).
template <typename T>
T EvalPrimitive(Op op, const double* c, T x, T y, T z) noexcept {
  using namespace internal;
  switch (op) {
    case Op::kCone:
      return ConeField(x, y, z, c[0], c[1], c[2]);
    case Op::kExtrusion:
      return ExtrusionField(x, y, z, c + 3, static_cast<int>(c[1]), c[2] > 0.0, c[0]);
    default:
      return EvalBranchFree(op, c, x, y, z);
  }
}

bool IsBranchFree(Op op) { return op != Op::kCone && op != Op::kExtrusion; }

// The world-to-local map accumulated while descending the tree.
struct Affine {
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double k = 1.0;
};

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

// Interval bounds of one primitive instruction over a box (interval arithmetic, tightened by
// the Lipschitz bound value(centre) ± L·half-diagonal).
struct PrimitiveBounder {
  explicit PrimitiveBounder(const Eigen::AlignedBox3d& box)
      : lo(box.min()),
        hi(box.max()),
        centre(0.5 * (lo + hi)),
        half_diagonal(0.5 * (hi - lo).norm()) {}

  Interval operator()(Op op, const double* c) const noexcept {
    double qc[3];
    Interval q[3];
    for (int r = 0; r < 3; ++r) {
      Interval acc = Interval::Point(c[kB + r]);
      qc[r] = c[kB + r];
      for (int j = 0; j < 3; ++j) {
        const double a = c[3 * r + j];
        acc = acc + Interval{lo[j], hi[j]} * a;
        qc[r] += a * centre[j];
      }
      q[r] = acc;
    }
    const double k = c[kScale];
    const double value_at_centre = k * EvalPrimitive(op, c + kParams, qc[0], qc[1], qc[2]);
    const double reach = c[kLipschitz] * half_diagonal;
    // Widen by a few ulps so rounding in the two evaluations cannot exclude a true value.
    const double slack = 1e-12 * (std::fabs(value_at_centre) + reach) + 1e-15;
    const Interval lipschitz{value_at_centre - reach - slack, value_at_centre + reach + slack};
    if (!IsBranchFree(op)) return lipschitz;
    const Interval ia = EvalBranchFree(op, c + kParams, q[0], q[1], q[2]) * k;
    return Intersect(Interval{ia.lo - slack, ia.hi + slack}, lipschitz);
  }

  Eigen::Vector3d lo, hi, centre;
  double half_diagonal;
};

}  // namespace

// Emits the tape for a tree; each Emit returns the stack depth its code needs.
class TapeCompiler {
 public:
  explicit TapeCompiler(CompiledSolid* out) : out_(out) {}

  int Emit(const ImplicitNode& node, const Affine& m, const std::string& path) {
    return std::visit(
        Overloaded{
            [&](const SphereParams& p) { return Primitive(Op::kSphere, m, {p.radius}, path); },
            [&](const BoxParams& p) {
              return Primitive(Op::kBox, m, {p.size.x() / 2, p.size.y() / 2, p.size.z() / 2}, path);
            },
            [&](const RoundedBoxParams& p) {
              return Primitive(Op::kRoundedBox, m,
                               {p.size.x() / 2, p.size.y() / 2, p.size.z() / 2, p.radius}, path);
            },
            [&](const CylinderParams& p) {
              return Primitive(Op::kCylinder, m, {p.radius, p.height / 2}, path);
            },
            [&](const CapsuleParams& p) {
              const double len2 = (p.b - p.a).squaredNorm();
              return Primitive(Op::kCapsule, m,
                               {p.a.x(), p.a.y(), p.a.z(), p.b.x(), p.b.y(), p.b.z(), p.radius,
                                len2 > 0 ? 1 / len2 : 0.0},
                               path);
            },
            [&](const ConeParams& p) {
              return Primitive(Op::kCone, m, {p.radius_bottom, p.radius_top, p.height / 2}, path);
            },
            [&](const TorusParams& p) {
              return Primitive(Op::kTorus, m, {p.major_radius, p.minor_radius}, path);
            },
            [&](const HalfSpaceParams& p) {
              const Eigen::Vector3d n = p.normal.normalized();
              return Primitive(Op::kHalfSpace, m, {n.x(), n.y(), n.z(), p.offset}, path);
            },
            [&](const ExtrusionParams& p) {
              // Half height, vertex count, orientation (1 counter-clockwise), the vertices.
              std::vector<double> params = {p.height / 2, static_cast<double>(p.profile.size()),
                                            0.0};
              for (const Eigen::Vector2d& v : p.profile) {
                params.push_back(v.x());
                params.push_back(v.y());
              }
              params[2] = internal::PolygonIsCounterClockwise(params.data() + 3,
                                                              static_cast<int>(p.profile.size()))
                              ? 1.0
                              : 0.0;
              return Primitive(Op::kExtrusion, m, params, path);
            },
            [&](const UnionParams&) { return Fold(node, m, path, Op::kMin, -1.0); },
            [&](const IntersectionParams&) { return Fold(node, m, path, Op::kMax, -1.0); },
            [&](const DifferenceParams&) { return Fold(node, m, path, Op::kMaxNeg, -1.0); },
            [&](const SmoothUnionParams& p) {
              return Fold(node, m, path, Op::kSmoothMin, p.radius * m.k);
            },
            [&](const SmoothIntersectionParams& p) {
              return Fold(node, m, path, Op::kSmoothMax, p.radius * m.k);
            },
            [&](const SmoothDifferenceParams& p) {
              return Fold(node, m, path, Op::kSmoothMaxNeg, p.radius * m.k);
            },
            [&](const OffsetParams& p) {
              const int depth = Group(node, m, path);
              Push(Op::kOffset, {p.distance * m.k}, path);
              return depth;
            },
            [&](const ShellParams& p) {
              const int depth = Group(node, m, path);
              Push(Op::kShell, {p.thickness * m.k}, path);
              return depth;
            },
            [&](const TranslateParams& p) {
              Affine c = m;
              c.b -= p.translation;
              return Group(node, c, path);
            },
            [&](const RotateParams& p) { return Group(node, Rotated(m, p.axis, p.angle), path); },
            [&](const ScaleParams& p) {
              Affine c = m;
              const Eigen::Vector3d inv = p.factors.cwiseInverse();
              c.A = inv.asDiagonal() * m.A;
              c.b = inv.asDiagonal() * m.b;
              c.k = m.k * p.factors.minCoeff();
              return Group(node, c, path);
            },
            [&](const MirrorParams& p) {
              const Eigen::Vector3d n = p.normal.normalized();
              const Eigen::Matrix3d H = Eigen::Matrix3d::Identity() - 2.0 * n * n.transpose();
              Affine c = m;
              c.A = H * m.A;
              c.b = H * m.b + 2.0 * p.offset * n;
              if (!p.keep_original) return Group(node, c, path);
              const int d0 = Group(node, m, path);
              const int d1 = Group(node, c, path);
              Push(Op::kMin, {}, path);
              return std::max(d0, d1 + 1);
            },
            [&](const LinearArrayParams& p) {
              int depth = 0;
              for (int i = 0; i < p.count; ++i) {
                Affine c = m;
                c.b -= i * p.step;
                const int d = Group(node, c, path);
                depth = std::max(depth, d + (i > 0 ? 1 : 0));
                if (i > 0) Push(Op::kMin, {}, path);
              }
              return depth;
            },
            [&](const PolarArrayParams& p) {
              int depth = 0;
              for (int i = 0; i < p.count; ++i) {
                const int d = Group(node, Rotated(m, p.axis, i * p.step_angle), path);
                depth = std::max(depth, d + (i > 0 ? 1 : 0));
                if (i > 0) Push(Op::kMin, {}, path);
              }
              return depth;
            },
        },
        node.params);
  }

 private:
  // Child frame of a rotation R (child to parent): q_child = Rᵀ q_parent.
  static Affine Rotated(const Affine& m, const Eigen::Vector3d& axis, double angle) {
    const Eigen::Matrix3d Rt =
        Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix().transpose();
    Affine c = m;
    c.A = Rt * m.A;
    c.b = Rt * m.b;
    return c;
  }

  void Push(Op op, std::initializer_list<double> constants, const std::string& path) {
    PushRange(op, constants.begin(), constants.end(), path);
  }
  void PushRange(Op op, const double* begin, const double* end, const std::string& path) {
    if (static_cast<int>(out_->code_.size()) >= CompiledSolid::kMaxInstructions) {
      throw ModelError(path, "count",
                       "node at " + (path.empty() ? std::string("/") : path) +
                           ": the compiled solid exceeds " +
                           std::to_string(CompiledSolid::kMaxInstructions) +
                           " instructions (arrays nested too deep?)");
    }
    out_->code_.push_back({op, static_cast<std::uint32_t>(out_->constants_.size())});
    out_->constants_.insert(out_->constants_.end(), begin, end);
  }

  int Primitive(Op op, const Affine& m, const std::vector<double>& params,
                const std::string& path) {
    std::vector<double> c(kParams);
    for (int r = 0; r < 3; ++r) {
      for (int col = 0; col < 3; ++col) c[kA + 3 * r + col] = m.A(r, col);
      c[kB + r] = m.b[r];
    }
    c[kScale] = m.k;
    c[kLipschitz] = m.k * Eigen::JacobiSVD<Eigen::Matrix3d>(m.A).singularValues()[0];
    c.insert(c.end(), params.begin(), params.end());
    PushRange(op, c.data(), c.data() + c.size(), path);
    ++out_->primitive_count_;
    return 1;
  }

  // Union of a node's children (the argument of a unary node).
  int Group(const ImplicitNode& node, const Affine& m, const std::string& path) {
    int depth = 0;
    for (size_t i = 0; i < node.children.size(); ++i) {
      const int d = Emit(node.children[i], m, path + "/children/" + std::to_string(i));
      depth = std::max(depth, d + (i > 0 ? 1 : 0));
      if (i > 0) Push(Op::kMin, {}, path);
    }
    return depth;
  }

  // Left fold of the children with a binary operator (radius < 0: none).
  int Fold(const ImplicitNode& node, const Affine& m, const std::string& path, Op op,
           double radius) {
    int depth = 0;
    for (size_t i = 0; i < node.children.size(); ++i) {
      const int d = Emit(node.children[i], m, path + "/children/" + std::to_string(i));
      depth = std::max(depth, d + (i > 0 ? 1 : 0));
      if (i > 0) {
        if (radius >= 0.0) {
          Push(op, {radius}, path);
        } else {
          Push(op, {}, path);
        }
      }
    }
    return depth;
  }

  CompiledSolid* out_;
};

CompiledSolid CompiledSolid::Compile(const ImplicitNode& root, const std::string& root_path) {
  ValidateTree(root, root_path);
  CompiledSolid solid;
  TapeCompiler compiler(&solid);
  solid.stack_depth_ = compiler.Emit(root, Affine{}, root_path);
  if (solid.stack_depth_ > kMaxStackDepth) {
    throw ModelError(root_path, "children",
                     "solid at " + (root_path.empty() ? std::string("/") : root_path) +
                         " needs a value stack of " + std::to_string(solid.stack_depth_) +
                         " entries, more than the evaluator's " + std::to_string(kMaxStackDepth) +
                         ": nest booleans less deeply");
  }
  return solid;
}

template <typename T, typename Primitive>
T CompiledSolid::Run(Primitive&& primitive) const noexcept {
  using namespace internal;
  T stack[kMaxStackDepth];
  int top = 0;
  const double* pool = constants_.data();
  for (const Instruction& ins : code_) {
    const double* c = pool + ins.constants;
    switch (ins.op) {
      case Op::kMin:
        --top;
        stack[top - 1] = Min(stack[top - 1], stack[top]);
        break;
      case Op::kMax:
        --top;
        stack[top - 1] = Max(stack[top - 1], stack[top]);
        break;
      case Op::kMaxNeg:
        --top;
        stack[top - 1] = Max(stack[top - 1], -stack[top]);
        break;
      case Op::kSmoothMin:
        --top;
        stack[top - 1] = SmoothMin(stack[top - 1], stack[top], c[0]);
        break;
      case Op::kSmoothMax:
        --top;
        stack[top - 1] = SmoothMax(stack[top - 1], stack[top], c[0]);
        break;
      case Op::kSmoothMaxNeg:
        --top;
        stack[top - 1] = SmoothMax(stack[top - 1], -stack[top], c[0]);
        break;
      case Op::kOffset:
        stack[top - 1] = stack[top - 1] - c[0];
        break;
      case Op::kShell:
        stack[top - 1] = Abs(stack[top - 1] + 0.5 * c[0]) - 0.5 * c[0];
        break;
      case Op::kNeg:
        stack[top - 1] = -stack[top - 1];
        break;
      default:
        stack[top++] = primitive(ins.op, c);
        break;
    }
  }
  return stack[0];
}

double CompiledSolid::Value(const Eigen::Vector3d& p) const noexcept {
  if (code_.empty()) return INFINITY;
  const double px = p.x(), py = p.y(), pz = p.z();
  return Run<double>([px, py, pz](Op op, const double* c) {
    const double x = c[0] * px + c[1] * py + c[2] * pz + c[kB];
    const double y = c[3] * px + c[4] * py + c[5] * pz + c[kB + 1];
    const double z = c[6] * px + c[7] * py + c[8] * pz + c[kB + 2];
    return c[kScale] * EvalPrimitive(op, c + kParams, x, y, z);
  });
}

double CompiledSolid::ValueAndGradient(const Eigen::Vector3d& p,
                                       Eigen::Vector3d* gradient) const noexcept {
  if (code_.empty()) {
    gradient->setZero();
    return INFINITY;
  }
  const double px = p.x(), py = p.y(), pz = p.z();
  const Dual r = Run<Dual>([px, py, pz](Op op, const double* c) {
    const Dual x{c[0] * px + c[1] * py + c[2] * pz + c[kB], c[0], c[1], c[2]};
    const Dual y{c[3] * px + c[4] * py + c[5] * pz + c[kB + 1], c[3], c[4], c[5]};
    const Dual z{c[6] * px + c[7] * py + c[8] * pz + c[kB + 2], c[6], c[7], c[8]};
    return EvalPrimitive(op, c + kParams, x, y, z) * c[kScale];
  });
  *gradient = Eigen::Vector3d(r.gx, r.gy, r.gz);
  return r.v;
}

namespace {

// Points per pass of the tape in Values and ValuesAndGradients (SIMD across points).
constexpr int kW = 4;
using internal::DualLanes;
using internal::Lanes;

// Every primitive over W points: the branch-free ones through the shared templates, cones and
// extrusions (whose formulas branch on values) lane by lane through the scalar ones.
Lanes<kW> EvalPrimitiveLanes(Op op, const double* c, const Lanes<kW>& x, const Lanes<kW>& y,
                             const Lanes<kW>& z) noexcept {
  if (IsBranchFree(op)) return EvalBranchFree(op, c, x, y, z);
  Lanes<kW> r;
  for (int i = 0; i < kW; ++i) r.v[i] = EvalPrimitive(op, c, x.v[i], y.v[i], z.v[i]);
  return r;
}
DualLanes<kW> EvalPrimitiveLanes(Op op, const double* c, const DualLanes<kW>& x,
                                 const DualLanes<kW>& y, const DualLanes<kW>& z) noexcept {
  if (IsBranchFree(op)) return EvalBranchFree(op, c, x, y, z);
  DualLanes<kW> r;
  for (int i = 0; i < kW; ++i) {
    SetLane(&r, i,
            EvalPrimitive(op, c, internal::LaneOf(x, i), internal::LaneOf(y, i),
                          internal::LaneOf(z, i)));
  }
  return r;
}

// Structure of arrays: W points, one coordinate per array.
struct LanePoints {
  double x[kW], y[kW], z[kW];
};

// Columns [begin, begin + count) of points, the last one repeated in the lanes past count
// (their results are dropped).
void LoadLanes(const Eigen::Ref<const Eigen::Matrix3Xd>& points, Eigen::Index begin, int count,
               LanePoints* p) noexcept {
  for (int i = 0; i < kW; ++i) {
    const Eigen::Index k = begin + std::min(i, count - 1);
    p->x[i] = points(0, k);
    p->y[i] = points(1, k);
    p->z[i] = points(2, k);
  }
}

// A primitive instruction over W points, as Value's: the map to the primitive's frame
// c[0] px + c[1] py + c[2] pz + b per lane, then the primitive scaled.
Lanes<kW> LaneValue(Op op, const double* c, const LanePoints& p) noexcept {
  Lanes<kW> x, y, z;
  for (int i = 0; i < kW; ++i) {
    x.v[i] = c[0] * p.x[i] + c[1] * p.y[i] + c[2] * p.z[i] + c[kB];
    y.v[i] = c[3] * p.x[i] + c[4] * p.y[i] + c[5] * p.z[i] + c[kB + 1];
    z.v[i] = c[6] * p.x[i] + c[7] * p.y[i] + c[8] * p.z[i] + c[kB + 2];
  }
  return c[kScale] * EvalPrimitiveLanes(op, c + kParams, x, y, z);
}

// The same with gradients, as ValueAndGradient's: the map's rows are the gradients of the
// local coordinates.
DualLanes<kW> LaneValueAndGradient(Op op, const double* c, const LanePoints& p) noexcept {
  DualLanes<kW> x, y, z;
  for (int i = 0; i < kW; ++i) {
    x.v[i] = c[0] * p.x[i] + c[1] * p.y[i] + c[2] * p.z[i] + c[kB];
    y.v[i] = c[3] * p.x[i] + c[4] * p.y[i] + c[5] * p.z[i] + c[kB + 1];
    z.v[i] = c[6] * p.x[i] + c[7] * p.y[i] + c[8] * p.z[i] + c[kB + 2];
    x.gx[i] = c[0];
    x.gy[i] = c[1];
    x.gz[i] = c[2];
    y.gx[i] = c[3];
    y.gy[i] = c[4];
    y.gz[i] = c[5];
    z.gx[i] = c[6];
    z.gy[i] = c[7];
    z.gz[i] = c[8];
  }
  return EvalPrimitiveLanes(op, c + kParams, x, y, z) * c[kScale];
}

}  // namespace

// Batches: kW points per pass of the tape, each lane bit-identical to Value / ValueAndGradient
// of its point (primitive_lanes.h; the flags of this file in modeling/CMakeLists.txt).
void CompiledSolid::Values(const Eigen::Ref<const Eigen::Matrix3Xd>& points,
                           Eigen::Ref<Eigen::VectorXd> values) const noexcept {
  const Eigen::Index n = std::min<Eigen::Index>(points.cols(), values.size());
  if (code_.empty()) {
    for (Eigen::Index i = 0; i < n; ++i) values[i] = INFINITY;
    return;
  }
  LanePoints p;
  for (Eigen::Index i = 0; i < n; i += kW) {
    const int count = static_cast<int>(std::min<Eigen::Index>(kW, n - i));
    LoadLanes(points, i, count, &p);
    const Lanes<kW> r =
        Run<Lanes<kW>>([&p](Op op, const double* c) { return LaneValue(op, c, p); });
    for (int k = 0; k < count; ++k) values[i + k] = r.v[k];
  }
}

void CompiledSolid::ValuesAndGradients(const Eigen::Ref<const Eigen::Matrix3Xd>& points,
                                       Eigen::Ref<Eigen::VectorXd> values,
                                       Eigen::Ref<Eigen::Matrix3Xd> gradients) const noexcept {
  const Eigen::Index n = std::min({points.cols(), values.size(), gradients.cols()});
  if (code_.empty()) {
    for (Eigen::Index i = 0; i < n; ++i) {
      values[i] = INFINITY;
      gradients.col(i).setZero();
    }
    return;
  }
  LanePoints p;
  for (Eigen::Index i = 0; i < n; i += kW) {
    const int count = static_cast<int>(std::min<Eigen::Index>(kW, n - i));
    LoadLanes(points, i, count, &p);
    const DualLanes<kW> r =
        Run<DualLanes<kW>>([&p](Op op, const double* c) { return LaneValueAndGradient(op, c, p); });
    for (int k = 0; k < count; ++k) {
      values[i + k] = r.v[k];
      gradients(0, i + k) = r.gx[k];
      gradients(1, i + k) = r.gy[k];
      gradients(2, i + k) = r.gz[k];
    }
  }
}

Interval CompiledSolid::Bounds(const Eigen::AlignedBox3d& box) const noexcept {
  if (code_.empty()) return {INFINITY, INFINITY};
  return Run<Interval>(PrimitiveBounder(box));
}

BoxClass CompiledSolid::Classify(const Eigen::AlignedBox3d& box) const noexcept {
  const Interval b = Bounds(box);
  if (b.hi < 0.0) return BoxClass::kInside;
  if (b.lo > 0.0) return BoxClass::kOutside;
  return BoxClass::kAmbiguous;
}

namespace {

// How many operands an opcode pops (primitives pop none and push one).
int Arity(Op op) {
  switch (op) {
    case Op::kMin:
    case Op::kMax:
    case Op::kMaxNeg:
    case Op::kSmoothMin:
    case Op::kSmoothMax:
    case Op::kSmoothMaxNeg:
      return 2;
    case Op::kOffset:
    case Op::kShell:
    case Op::kNeg:
      return 1;
    default:
      return 0;
  }
}

// True when every value in x is below every value in y by more than `gap` plus a margin that
// covers rounding in the bounds (which are widened by ~1e-12 relative) and in the blend's
// difference. Non-finite bounds never qualify.
bool SurelyBelow(const Interval& x, const Interval& y, double gap) {
  if (!std::isfinite(x.lo) || !std::isfinite(x.hi) || !std::isfinite(y.lo) || !std::isfinite(y.hi))
    return false;
  const double margin = 1e-9 * (std::fabs(x.hi) + std::fabs(y.lo) + gap) + 1e-12;
  return y.lo - x.hi > gap + margin;
}

// Which operand of a binary instruction survives over the box: 0 both, 1 the left one (a), 2
// the right one (b; for the *Neg ops the result is then −b).
//  - Min(a, b): double std::min and Dual Min both return a when a < b strictly, else b.
//  - SmoothMin(a, b, r) with |a − b| > r: h = max(r − |a − b|, 0)/r is exactly +0 (value and
//    gradient), so the result is Min(a, b) − (+0), bit-identical to the selected operand.
//    SmoothMax = −SmoothMin(−a, −b) and negation is exact. r <= 0 is a plain min/max.
int Survivor(Op op, const double* c, const Interval& a, const Interval& b0) {
  const bool negated = op == Op::kMaxNeg || op == Op::kSmoothMaxNeg;
  const Interval b = negated ? -b0 : b0;
  double gap = 0.0;
  if (op == Op::kSmoothMin || op == Op::kSmoothMax || op == Op::kSmoothMaxNeg) {
    // A radius so small that 1/r overflows makes the blend's h = 0·∞ = NaN: keep both.
    if (!std::isfinite(c[0]) || (c[0] > 0.0 && !std::isfinite(1.0 / c[0]))) return 0;
    gap = std::max(c[0], 0.0);
  }
  const bool is_min = op == Op::kMin || op == Op::kSmoothMin;
  if (SurelyBelow(a, b, gap)) return is_min ? 1 : 2;
  if (SurelyBelow(b, a, gap)) return is_min ? 2 : 1;
  return 0;
}

}  // namespace

double CompiledSolid::EvaluationCost() const noexcept {
  double cost = 0.0;
  for (const Instruction& ins : code_) {
    cost += 1.0;
    if (ins.op == Op::kExtrusion) cost += constants_[ins.constants + kParams + 1];
  }
  return cost;
}

int CompiledSolid::LipschitzOnlyCount() const noexcept {
  int count = 0;
  for (const Instruction& ins : code_) count += !IsBranchFree(ins.op);
  return count;
}

bool CompiledSolid::SameTape(const CompiledSolid& other) const noexcept {
  if (code_.size() != other.code_.size() || constants_.size() != other.constants_.size())
    return false;
  for (std::size_t i = 0; i < code_.size(); ++i) {
    if (code_[i].op != other.code_[i].op || code_[i].constants != other.code_[i].constants)
      return false;
  }
  return constants_.empty() || std::memcmp(constants_.data(), other.constants_.data(),
                                           constants_.size() * sizeof(double)) == 0;
}

std::uint64_t CompiledSolid::TapeHash() const noexcept {
  std::uint64_t hash = 1469598103934665603ull;
  auto mix = [&](const void* data, std::size_t bytes) {
    const auto* b = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) hash = (hash ^ b[i]) * 1099511628211ull;
  };
  for (const Instruction& ins : code_) {
    mix(&ins.op, sizeof(ins.op));
    mix(&ins.constants, sizeof(ins.constants));
  }
  mix(constants_.data(), constants_.size() * sizeof(double));
  return hash;
}

CompiledSolid CompiledSolid::Specialize(const Eigen::AlignedBox3d& box) const {
  const int n = static_cast<int>(code_.size());
  if (n == 0 || box.isEmpty() || !box.min().allFinite() || !box.max().allFinite()) return *this;
  using namespace internal;
  // Forward pass: the bounds of every instruction's result over the box and its operands.
  const PrimitiveBounder bound(box);
  std::vector<Interval> value(n);
  std::vector<int> left(n, -1), right(n, -1);
  std::vector<int> stack;
  stack.reserve(static_cast<std::size_t>(stack_depth_) + 1);
  const double* pool = constants_.data();
  for (int i = 0; i < n; ++i) {
    const Op op = code_[i].op;
    const double* c = pool + code_[i].constants;
    const int arity = Arity(op);
    if (arity == 2) {
      right[i] = stack.back();
      stack.pop_back();
      left[i] = stack.back();
      stack.pop_back();
      const Interval a = value[left[i]], b = value[right[i]];
      switch (op) {
        case Op::kMin:
          value[i] = Min(a, b);
          break;
        case Op::kMax:
          value[i] = Max(a, b);
          break;
        case Op::kMaxNeg:
          value[i] = Max(a, -b);
          break;
        case Op::kSmoothMin:
          value[i] = SmoothMin(a, b, c[0]);
          break;
        case Op::kSmoothMax:
          value[i] = SmoothMax(a, b, c[0]);
          break;
        default:
          value[i] = SmoothMax(a, -b, c[0]);
          break;  // kSmoothMaxNeg
      }
    } else if (arity == 1) {
      left[i] = stack.back();
      stack.pop_back();
      const Interval a = value[left[i]];
      switch (op) {
        case Op::kOffset:
          value[i] = a - c[0];
          break;
        case Op::kShell:
          value[i] = Abs(a + 0.5 * c[0]) - 0.5 * c[0];
          break;
        default:
          value[i] = -a;
          break;  // kNeg
      }
    } else {
      value[i] = bound(op, c);
    }
    stack.push_back(i);
  }
  // Backward pass (parents come after their operands): mark what the root still needs.
  // emit: 0 dropped, 1 kept, 2 replaced by kNeg.
  std::vector<std::uint8_t> live(n, 0), emit(n, 0);
  live[n - 1] = 1;
  for (int i = n - 1; i >= 0; --i) {
    if (!live[i]) continue;
    const Op op = code_[i].op;
    const int arity = Arity(op);
    emit[i] = 1;
    if (arity == 2) {
      const int keep = Survivor(op, pool + code_[i].constants, value[left[i]], value[right[i]]);
      if (keep == 1) {
        live[left[i]] = 1;
        emit[i] = 0;
      } else if (keep == 2) {
        live[right[i]] = 1;
        emit[i] = (op == Op::kMaxNeg || op == Op::kSmoothMaxNeg) ? 2 : 0;
      } else {
        live[left[i]] = live[right[i]] = 1;
      }
    } else if (arity == 1) {
      live[left[i]] = 1;
    }
  }
  // Emit the kept instructions in order with their constants.
  CompiledSolid out;
  int depth = 0, max_depth = 0;
  for (int i = 0; i < n; ++i) {
    if (emit[i] == 0) continue;
    const Op op = emit[i] == 2 ? Op::kNeg : code_[i].op;
    out.code_.push_back({op, static_cast<std::uint32_t>(out.constants_.size())});
    if (emit[i] == 1) {
      const std::size_t begin = code_[i].constants;
      const std::size_t end = i + 1 < n ? code_[i + 1].constants : constants_.size();
      out.constants_.insert(out.constants_.end(), constants_.begin() + begin,
                            constants_.begin() + end);
    }
    const int arity = Arity(op);
    if (arity == 0) ++out.primitive_count_;
    depth += arity == 2 ? -1 : arity == 0 ? 1 : 0;
    max_depth = std::max(max_depth, depth);
  }
  out.stack_depth_ = max_depth;
  return out;
}

}  // namespace spidarcad::modeling
