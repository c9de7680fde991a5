// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/implicit_node.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <vector>

#include "primitives.h"

namespace spidarcad::modeling {

namespace {

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

constexpr int kMaxArrayCount = 1000;

std::string FormatValue(double v) {
  std::ostringstream out;
  out.precision(17);
  out << v;
  return out.str();
}

// Collects the context needed to name a node in an error.
struct NodeContext {
  const ImplicitNode& node;
  std::string path;

  [[noreturn]] void Fail(const std::string& field, const std::string& what) const {
    std::string who = "node";
    if (!node.id.empty()) who += " '" + node.id + "'";
    if (!node.name.empty()) who += " \"" + node.name + "\"";
    who += std::string(" (") + NodeTypeName(node.params) + ") at " + (path.empty() ? "/" : path);
    throw ModelError(path, field, who + ": field '" + field + "' " + what);
  }
  void Positive(double v, const std::string& field) const {
    if (!std::isfinite(v) || v <= 0.0)
      Fail(field, "must be a finite length > 0 m, got " + FormatValue(v));
  }
  void NonNegative(double v, const std::string& field) const {
    if (!std::isfinite(v) || v < 0.0)
      Fail(field, "must be a finite length >= 0 m, got " + FormatValue(v));
  }
  void Finite(double v, const std::string& field) const {
    if (!std::isfinite(v)) Fail(field, "must be finite, got " + FormatValue(v));
  }
  void Finite(const Eigen::Vector3d& v, const std::string& field) const {
    for (int i = 0; i < 3; ++i) {
      if (!std::isfinite(v[i]))
        Fail(field, "component " + std::to_string(i) + " must be finite, got " + FormatValue(v[i]));
    }
  }
  void Positive(const Eigen::Vector3d& v, const std::string& field) const {
    for (int i = 0; i < 3; ++i) {
      if (!std::isfinite(v[i]) || v[i] <= 0.0) {
        Fail(field, "component " + std::to_string(i) + " must be finite and > 0, got " +
                        FormatValue(v[i]));
      }
    }
  }
  void Direction(const Eigen::Vector3d& v, const std::string& field) const {
    Finite(v, field);
    if (v.norm() < 1e-12) Fail(field, "must be a non-zero direction, got (0, 0, 0)");
  }
  void Count(int n, const std::string& field) const {
    if (n < 1 || n > kMaxArrayCount) {
      Fail(field, "must be an integer in [1, " + std::to_string(kMaxArrayCount) + "], got " +
                      std::to_string(n));
    }
  }
};

double Cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return a.x() * b.y() - a.y() * b.x();
}

// True when the closed segments p1-p2 and q1-q2 share a point.
bool SegmentsIntersect(const Eigen::Vector2d& p1, const Eigen::Vector2d& p2,
                       const Eigen::Vector2d& q1, const Eigen::Vector2d& q2) {
  const double d1 = Cross2(q2 - q1, p1 - q1), d2 = Cross2(q2 - q1, p2 - q1);
  const double d3 = Cross2(p2 - p1, q1 - p1), d4 = Cross2(p2 - p1, q2 - p1);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0)))
    return true;
  auto on_segment = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                       double d) {
    return d == 0.0 && std::min(a.x(), b.x()) <= c.x() && c.x() <= std::max(a.x(), b.x()) &&
           std::min(a.y(), b.y()) <= c.y() && c.y() <= std::max(a.y(), b.y());
  };
  return on_segment(q1, q2, p1, d1) || on_segment(q1, q2, p2, d2) || on_segment(p1, p2, q1, d3) ||
         on_segment(p1, p2, q2, d4);
}

void ValidateProfile(const NodeContext& ctx, const std::vector<Eigen::Vector2d>& profile) {
  const int n = static_cast<int>(profile.size());
  if (n < 3) ctx.Fail("profile", "needs at least 3 vertices, got " + std::to_string(n));
  double area2 = 0.0;
  for (int i = 0; i < n; ++i) {
    if (!profile[i].allFinite())
      ctx.Fail("profile", "vertex " + std::to_string(i) + " is not finite");
    area2 += Cross2(profile[i], profile[(i + 1) % n]);
  }
  if (std::fabs(area2) < 1e-18) ctx.Fail("profile", "encloses no area");
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      const bool adjacent = (j == i + 1) || (i == 0 && j == n - 1);
      const Eigen::Vector2d& a1 = profile[i];
      const Eigen::Vector2d& a2 = profile[(i + 1) % n];
      const Eigen::Vector2d& b1 = profile[j];
      const Eigen::Vector2d& b2 = profile[(j + 1) % n];
      if (adjacent) {
        // Adjacent edges may only share their common vertex: reject folding back on each other.
        const Eigen::Vector2d shared = (j == i + 1) ? a2 : a1;
        const Eigen::Vector2d u = ((j == i + 1) ? a1 : a2) - shared;
        const Eigen::Vector2d v = ((j == i + 1) ? b2 : b1) - shared;
        if (u.norm() == 0.0 || v.norm() == 0.0) {
          ctx.Fail("profile", "has a repeated vertex at index " + std::to_string(j));
        }
        if (std::fabs(Cross2(u, v)) <= 1e-15 * u.norm() * v.norm() && u.dot(v) > 0.0) {
          ctx.Fail("profile",
                   "folds back on itself at vertex " + std::to_string(j == i + 1 ? j : i));
        }
        continue;
      }
      if (SegmentsIntersect(a1, a2, b1, b2)) {
        ctx.Fail("profile", "is self-intersecting: edges " + std::to_string(i) + " and " +
                                std::to_string(j) + " cross");
      }
    }
  }
}

void ValidateNode(const ImplicitNode& node, const std::string& path, std::set<std::string>* ids) {
  const NodeContext ctx{node, path};
  if (!node.id.empty() && !ids->insert(node.id).second)
    ctx.Fail("id", "repeats id '" + node.id + "' used by an earlier node");
  std::visit(Overloaded{
                 [&](const SphereParams& p) { ctx.Positive(p.radius, "radius"); },
                 [&](const BoxParams& p) { ctx.Positive(p.size, "size"); },
                 [&](const RoundedBoxParams& p) {
                   ctx.Positive(p.size, "size");
                   ctx.NonNegative(p.radius, "radius");
                   if (2.0 * p.radius > p.size.minCoeff()) {
                     ctx.Fail("radius", "must be at most half the smallest size (" +
                                            FormatValue(0.5 * p.size.minCoeff()) + " m), got " +
                                            FormatValue(p.radius));
                   }
                 },
                 [&](const CylinderParams& p) {
                   ctx.Positive(p.radius, "radius");
                   ctx.Positive(p.height, "height");
                 },
                 [&](const CapsuleParams& p) {
                   ctx.Finite(p.a, "a");
                   ctx.Finite(p.b, "b");
                   ctx.Positive(p.radius, "radius");
                 },
                 [&](const ConeParams& p) {
                   ctx.NonNegative(p.radius_bottom, "radius_bottom");
                   ctx.NonNegative(p.radius_top, "radius_top");
                   if (p.radius_bottom == 0.0 && p.radius_top == 0.0)
                     ctx.Fail("radius_bottom", "and radius_top are both 0");
                   ctx.Positive(p.height, "height");
                 },
                 [&](const TorusParams& p) {
                   ctx.Positive(p.major_radius, "major_radius");
                   ctx.Positive(p.minor_radius, "minor_radius");
                   if (p.minor_radius > p.major_radius) {
                     ctx.Fail("minor_radius", "must not exceed major_radius (" +
                                                  FormatValue(p.major_radius) + " m), got " +
                                                  FormatValue(p.minor_radius));
                   }
                 },
                 [&](const HalfSpaceParams& p) {
                   ctx.Direction(p.normal, "normal");
                   ctx.Finite(p.offset, "offset");
                 },
                 [&](const ExtrusionParams& p) {
                   ValidateProfile(ctx, p.profile);
                   ctx.Positive(p.height, "height");
                 },
                 [&](const UnionParams&) {},
                 [&](const IntersectionParams&) {},
                 [&](const DifferenceParams&) {},
                 [&](const SmoothUnionParams& p) { ctx.NonNegative(p.radius, "radius"); },
                 [&](const SmoothIntersectionParams& p) { ctx.NonNegative(p.radius, "radius"); },
                 [&](const SmoothDifferenceParams& p) { ctx.NonNegative(p.radius, "radius"); },
                 [&](const OffsetParams& p) { ctx.Finite(p.distance, "distance"); },
                 [&](const ShellParams& p) { ctx.Positive(p.thickness, "thickness"); },
                 [&](const TranslateParams& p) { ctx.Finite(p.translation, "translation"); },
                 [&](const RotateParams& p) {
                   ctx.Direction(p.axis, "axis");
                   ctx.Finite(p.angle, "angle");
                 },
                 [&](const ScaleParams& p) { ctx.Positive(p.factors, "factors"); },
                 [&](const MirrorParams& p) {
                   ctx.Direction(p.normal, "normal");
                   ctx.Finite(p.offset, "offset");
                 },
                 [&](const LinearArrayParams& p) {
                   ctx.Finite(p.step, "step");
                   ctx.Count(p.count, "count");
                 },
                 [&](const PolarArrayParams& p) {
                   ctx.Direction(p.axis, "axis");
                   ctx.Count(p.count, "count");
                   ctx.Finite(p.step_angle, "step_angle");
                 },
             },
             node.params);
  const int n = static_cast<int>(node.children.size());
  if (IsPrimitive(node.params)) {
    if (n != 0)
      ctx.Fail("children", "must be empty for a primitive, got " + std::to_string(n) + " children");
  } else if (std::holds_alternative<DifferenceParams>(node.params) ||
             std::holds_alternative<SmoothDifferenceParams>(node.params)) {
    if (n < 2)
      ctx.Fail("children", "needs at least 2 children (the solid, then what to remove), got " +
                               std::to_string(n));
  } else if (n < 1) {
    ctx.Fail("children", "needs at least 1 child, got 0");
  }
  for (int i = 0; i < n; ++i)
    ValidateNode(node.children[i], path + "/children/" + std::to_string(i), ids);
}

// Depth-first walk with an explicit stack (no recursion): throws ModelError at the first node
// deeper than kMaxTreeDepth or past kMaxTreeNodes, naming its path.
void CheckTreeSize(const ImplicitNode& root, const std::string& root_path) {
  struct Frame {
    const ImplicitNode* node;
    size_t next_child;
  };
  std::vector<Frame> stack = {{&root, 0}};
  long nodes = 1;
  auto path_of_top = [&]() {
    std::string path = root_path;
    for (size_t i = 1; i < stack.size(); ++i)
      path += "/children/" + std::to_string(stack[i - 1].next_child - 1);
    return path;
  };
  while (!stack.empty()) {
    Frame& top = stack.back();
    if (top.next_child == top.node->children.size()) {
      stack.pop_back();
      continue;
    }
    const ImplicitNode* child = &top.node->children[top.next_child++];
    stack.push_back({child, 0});
    ++nodes;
    if (static_cast<int>(stack.size()) > kMaxTreeDepth) {
      const std::string path = path_of_top();
      throw ModelError(
          path, "children",
          "node at " + path + ": the tree is deeper than " + std::to_string(kMaxTreeDepth) +
              " levels (the limit of docs/limits.md); flatten it, e.g. fold nested translate nodes "
              "into one, or put siblings under one union instead of nesting them");
    }
    if (nodes > kMaxTreeNodes) {
      const std::string path = path_of_top();
      throw ModelError(
          path, "children",
          "node at " + path + ": the tree has more than " + std::to_string(kMaxTreeNodes) +
              " nodes (the limit of docs/limits.md); use linear_array or polar_array nodes for "
              "repeated parts, or split the solid");
    }
  }
}

Eigen::Vector3d Reflect(const Eigen::Vector3d& p, const Eigen::Vector3d& normal, double offset) {
  const Eigen::Vector3d n = normal.normalized();
  return p - 2.0 * (n.dot(p) - offset) * n;
}

double EvaluateChildren(const ImplicitNode& node, const Eigen::Vector3d& p) {
  double v = INFINITY;
  for (const ImplicitNode& c : node.children) v = std::min(v, EvaluateTree(c, p));
  return v;
}

// Independent double-only blend formula (kept apart from the compiled one on purpose).
double ReferenceSmoothMin(double a, double b, double r) {
  if (r <= 0.0) return std::min(a, b);
  const double h = std::max(r - std::fabs(a - b), 0.0) / r;
  return std::min(a, b) - r * h * h / 4.0;
}

}  // namespace

const char* NodeTypeName(const NodeParams& params) {
  static constexpr const char* kNames[] = {"sphere",
                                           "box",
                                           "rounded_box",
                                           "cylinder",
                                           "capsule",
                                           "cone",
                                           "torus",
                                           "half_space",
                                           "extrusion",
                                           "union",
                                           "intersection",
                                           "difference",
                                           "smooth_union",
                                           "smooth_intersection",
                                           "smooth_difference",
                                           "offset",
                                           "shell",
                                           "translate",
                                           "rotate",
                                           "scale",
                                           "mirror",
                                           "linear_array",
                                           "polar_array"};
  static_assert(sizeof(kNames) / sizeof(kNames[0]) == std::variant_size_v<NodeParams>);
  return kNames[params.index()];
}

bool IsPrimitive(const NodeParams& params) { return params.index() <= 8; }

int CountNodes(const ImplicitNode& node) {
  int n = 0;
  std::vector<const ImplicitNode*> stack = {&node};
  while (!stack.empty()) {
    const ImplicitNode* top = stack.back();
    stack.pop_back();
    ++n;
    for (const ImplicitNode& c : top->children) stack.push_back(&c);
  }
  return n;
}

void ValidateTree(const ImplicitNode& root, const std::string& root_path) {
  CheckTreeSize(root, root_path);
  std::set<std::string> ids;
  ValidateNode(root, root_path, &ids);
}

double EvaluateTree(const ImplicitNode& node, const Eigen::Vector3d& p) {
  using namespace internal;
  const double x = p.x(), y = p.y(), z = p.z();
  return std::visit(
      Overloaded{
          [&](const SphereParams& q) { return SphereField(x, y, z, q.radius); },
          [&](const BoxParams& q) {
            return BoxField(x, y, z, q.size.x() / 2, q.size.y() / 2, q.size.z() / 2);
          },
          [&](const RoundedBoxParams& q) {
            return RoundedBoxField(x, y, z, q.size.x() / 2, q.size.y() / 2, q.size.z() / 2,
                                   q.radius);
          },
          [&](const CylinderParams& q) { return CylinderField(x, y, z, q.radius, q.height / 2); },
          [&](const CapsuleParams& q) {
            const double len2 = (q.b - q.a).squaredNorm();
            return CapsuleField(x, y, z, q.a.data(), q.b.data(), q.radius,
                                len2 > 0 ? 1.0 / len2 : 0.0);
          },
          [&](const ConeParams& q) {
            return ConeField(x, y, z, q.radius_bottom, q.radius_top, q.height / 2);
          },
          [&](const TorusParams& q) { return TorusField(x, y, z, q.major_radius, q.minor_radius); },
          [&](const HalfSpaceParams& q) {
            const Eigen::Vector3d n = q.normal.normalized();
            return n.dot(p) - q.offset;
          },
          [&](const ExtrusionParams& q) {
            const int n = static_cast<int>(q.profile.size());
            return ExtrusionField(x, y, z, q.profile.front().data(), n,
                                  PolygonIsCounterClockwise(q.profile.front().data(), n),
                                  q.height / 2);
          },
          [&](const UnionParams&) { return EvaluateChildren(node, p); },
          [&](const IntersectionParams&) {
            double v = -INFINITY;
            for (const ImplicitNode& c : node.children) v = std::max(v, EvaluateTree(c, p));
            return v;
          },
          [&](const DifferenceParams&) {
            double v = EvaluateTree(node.children[0], p);
            for (size_t i = 1; i < node.children.size(); ++i)
              v = std::max(v, -EvaluateTree(node.children[i], p));
            return v;
          },
          [&](const SmoothUnionParams& q) {
            double v = EvaluateTree(node.children[0], p);
            for (size_t i = 1; i < node.children.size(); ++i)
              v = ReferenceSmoothMin(v, EvaluateTree(node.children[i], p), q.radius);
            return v;
          },
          [&](const SmoothIntersectionParams& q) {
            double v = EvaluateTree(node.children[0], p);
            for (size_t i = 1; i < node.children.size(); ++i) {
              v = -ReferenceSmoothMin(-v, -EvaluateTree(node.children[i], p), q.radius);
            }
            return v;
          },
          [&](const SmoothDifferenceParams& q) {
            double v = EvaluateTree(node.children[0], p);
            for (size_t i = 1; i < node.children.size(); ++i) {
              v = -ReferenceSmoothMin(-v, EvaluateTree(node.children[i], p), q.radius);
            }
            return v;
          },
          [&](const OffsetParams& q) { return EvaluateChildren(node, p) - q.distance; },
          [&](const ShellParams& q) {
            return std::fabs(EvaluateChildren(node, p) + q.thickness / 2) - q.thickness / 2;
          },
          [&](const TranslateParams& q) { return EvaluateChildren(node, p - q.translation); },
          [&](const RotateParams& q) {
            const Eigen::Matrix3d R =
                Eigen::AngleAxisd(q.angle, q.axis.normalized()).toRotationMatrix();
            return EvaluateChildren(node, R.transpose() * p);
          },
          [&](const ScaleParams& q) {
            return q.factors.minCoeff() * EvaluateChildren(node, p.cwiseQuotient(q.factors));
          },
          [&](const MirrorParams& q) {
            const double mirrored = EvaluateChildren(node, Reflect(p, q.normal, q.offset));
            return q.keep_original ? std::min(mirrored, EvaluateChildren(node, p)) : mirrored;
          },
          [&](const LinearArrayParams& q) {
            double v = INFINITY;
            for (int i = 0; i < q.count; ++i)
              v = std::min(v, EvaluateChildren(node, p - i * q.step));
            return v;
          },
          [&](const PolarArrayParams& q) {
            double v = INFINITY;
            for (int i = 0; i < q.count; ++i) {
              const Eigen::Matrix3d R =
                  Eigen::AngleAxisd(i * q.step_angle, q.axis.normalized()).toRotationMatrix();
              v = std::min(v, EvaluateChildren(node, R.transpose() * p));
            }
            return v;
          },
      },
      node.params);
}

}  // namespace spidarcad::modeling
