// Implicit solids as a tree of nodes: primitives, booleans, smooth blends, offset and shell,
// transforms and arrays. Sign convention (paper Sec. 7): value < 0 inside, > 0 outside, 0 on the
// surface. Units: metres and radians. Every primitive sits at its local origin (axis along local
// z where it has one); place it with transform nodes.
//
// Distance quality (the haptic proxy uses the value as a distance):
// - exact signed distance: every primitive; translate, rotate, mirror and uniform scale of an
//   exact child; union outside the solid.
// - Lipschitz-1 bound (|value| never exceeds the true distance, |gradient| <= 1): union inside,
//   intersection, difference, smooth blends, offset, shell, non-uniform scale (value multiplied
//   by the smallest factor), arrays (a union of copies).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

namespace spidarcad::modeling {

// Sphere of `radius` centred at the origin.
struct SphereParams {
  double radius = 0.05;
};
// Box of full edge lengths `size` (x, y, z), centred at the origin.
struct BoxParams {
  Eigen::Vector3d size = Eigen::Vector3d(0.1, 0.1, 0.1);
};
// Box of full edge lengths `size` with edges rounded by `radius` (<= half the smallest size).
struct RoundedBoxParams {
  Eigen::Vector3d size = Eigen::Vector3d(0.1, 0.1, 0.1);
  double radius = 0.01;
};
// Cylinder of `radius` along z, of total `height`, centred at the origin.
struct CylinderParams {
  double radius = 0.05;
  double height = 0.1;
};
// Capsule: all points within `radius` of the segment from `a` to `b`.
struct CapsuleParams {
  Eigen::Vector3d a = Eigen::Vector3d(0, 0, -0.05);
  Eigen::Vector3d b = Eigen::Vector3d(0, 0, 0.05);
  double radius = 0.02;
};
// Cone frustum along z of total `height`, centred: `radius_bottom` at z = -height/2,
// `radius_top` at z = +height/2 (one of them may be 0 for a pointed cone).
struct ConeParams {
  double radius_bottom = 0.05;
  double radius_top = 0.0;
  double height = 0.1;
};
// Torus around z: centre circle of `major_radius` in the xy plane, tube `minor_radius`
// (0 < minor_radius <= major_radius).
struct TorusParams {
  double major_radius = 0.05;
  double minor_radius = 0.01;
};
// Half-space {x : normal·x <= offset}; `normal` need not be unit (it is normalised when
// compiled), `offset` is the plane's signed distance from the origin along the unit normal.
struct HalfSpaceParams {
  Eigen::Vector3d normal = Eigen::Vector3d(0, 0, 1);
  double offset = 0.0;
};
// A simple polygon `profile` (>= 3 vertices (x, y), either orientation, not self-intersecting)
// in the local xy plane, extruded along z over [-height/2, height/2].
struct ExtrusionParams {
  std::vector<Eigen::Vector2d> profile;
  double height = 0.01;
};
// Union (min) of all children.
struct UnionParams {};
// Intersection (max) of all children.
struct IntersectionParams {};
// First child minus the union of the others: max(a, -b).
struct DifferenceParams {};
// Union blended with a fillet of about `radius` where children meet.
struct SmoothUnionParams {
  double radius = 0.01;
};
// Intersection blended with `radius`.
struct SmoothIntersectionParams {
  double radius = 0.01;
};
// Difference blended with `radius`.
struct SmoothDifferenceParams {
  double radius = 0.01;
};
// Grows the child by `distance` (negative shrinks): value - distance.
struct OffsetParams {
  double distance = 0.0;
};
// Hollows the child to a wall of `thickness` inside its surface: |value + t/2| - t/2.
struct ShellParams {
  double thickness = 0.002;
};
// Moves the children by `translation`.
struct TranslateParams {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
};
// Rotates the children by `angle` (rad, right hand) about `axis` through the origin.
struct RotateParams {
  Eigen::Vector3d axis = Eigen::Vector3d(0, 0, 1);
  double angle = 0.0;
};
// Scales the children by `factors` (x, y, z), all > 0, about the origin.
struct ScaleParams {
  Eigen::Vector3d factors = Eigen::Vector3d::Ones();
};
// Reflects the children through the plane {x : n·x = offset} (n = normalised `normal`);
// with `keep_original` the result is the union of the children and their mirror image.
struct MirrorParams {
  Eigen::Vector3d normal = Eigen::Vector3d(1, 0, 0);
  double offset = 0.0;
  bool keep_original = false;
};
// `count` copies of the children, copy i moved by i * `step`.
struct LinearArrayParams {
  Eigen::Vector3d step = Eigen::Vector3d(0.1, 0, 0);
  int count = 2;
};
// `count` copies of the children, copy i rotated by i * `step_angle` (rad) about `axis`
// through the origin (step_angle = 2π/count spaces them around the full circle).
struct PolarArrayParams {
  Eigen::Vector3d axis = Eigen::Vector3d(0, 0, 1);
  int count = 4;
  double step_angle = 1.5707963267948966;
};

// The parameters of a node; the alternative held is the node's type.
using NodeParams =
    std::variant<SphereParams, BoxParams, RoundedBoxParams, CylinderParams, CapsuleParams,
                 ConeParams, TorusParams, HalfSpaceParams, ExtrusionParams, UnionParams,
                 IntersectionParams, DifferenceParams, SmoothUnionParams, SmoothIntersectionParams,
                 SmoothDifferenceParams, OffsetParams, ShellParams, TranslateParams, RotateParams,
                 ScaleParams, MirrorParams, LinearArrayParams, PolarArrayParams>;

// One node of an implicit solid. Primitives have no children; every other node has at least
// one (difference at least two). A non-boolean node with several children acts on their union.
struct ImplicitNode {
  // Optional identifier, unique within a scene (used in error messages and by editors).
  std::string id;
  // Optional human-readable name.
  std::string name;
  NodeParams params;
  std::vector<ImplicitNode> children;

  ImplicitNode() = default;
  explicit ImplicitNode(NodeParams p, std::vector<ImplicitNode> c = {}, std::string node_id = {})
      : id(std::move(node_id)), params(std::move(p)), children(std::move(c)) {}
};

// Deepest tree ValidateTree accepts: the root is level 1 (docs/limits.md). Bounds the recursion of
// every tree walk (validation, compilation, the reference evaluator, JSON output).
inline constexpr int kMaxTreeDepth = 256;
// Most nodes in one tree ValidateTree accepts (docs/limits.md).
inline constexpr int kMaxTreeNodes = 500000;

// The scene-file name of the type of params, e.g. "sphere", "smooth_union", "polar_array".
const char* NodeTypeName(const NodeParams& params);
// True for the primitive types (those that take no children).
bool IsPrimitive(const NodeParams& params);
// Number of nodes in the tree rooted at node (node included). Iterative: any depth.
int CountNodes(const ImplicitNode& node);

// An invalid tree: says which node (id, name, type, path) and which field was wrong.
class ModelError : public std::invalid_argument {
 public:
  // path: JSON-pointer-style location of the node ("/children/2" style below the root);
  // field: the offending field name ("radius", "children", ...).
  ModelError(const std::string& path, const std::string& field, const std::string& message)
      : std::invalid_argument(message), path_(path), field_(field) {}
  // Location of the node, e.g. "/solids/0/root/children/2".
  const std::string& path() const { return path_; }
  // The offending field of that node.
  const std::string& field() const { return field_; }

 private:
  std::string path_;
  std::string field_;
};

// Checks every node below (and including) root: depth at most kMaxTreeDepth and at most
// kMaxTreeNodes nodes (checked first, without recursion, so any tree is safe to pass), finite
// values, positive sizes, radii that fit, child counts, simple polygons, unique non-empty ids.
// root_path is the location of root used in the error (e.g. "/solids/0/root"). Throws
// ModelError naming the first bad node and field (field "children" for the size limits).
void ValidateTree(const ImplicitNode& root, const std::string& root_path = "");

// Reference evaluator: walks the tree recursively, transforming the point node by node. Slow
// (allocation-free but recursive); meant for tests and tools, not for the haptic tick. The tree
// must be valid (ValidateTree: so the recursion is at most kMaxTreeDepth deep).
double EvaluateTree(const ImplicitNode& node, const Eigen::Vector3d& p_W);

}  // namespace spidarcad::modeling
