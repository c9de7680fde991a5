// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/touch_modelling.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <variant>

#include "scene/scene_haptics.h"
#include "scene/snap_features.h"
#include "spidarcad/modeling/implicit_evaluator.h"

namespace spidarcad::app {

namespace {

using Eigen::Affine3d;
using Eigen::Isometry3d;
using Eigen::Matrix3d;
using Eigen::Vector3d;

// The smallest rotation taking unit vector a onto unit vector b.
Matrix3d SmallestRotation(const Vector3d& a, const Vector3d& b) {
  return Eigen::Quaterniond::FromTwoVectors(a, b).toRotationMatrix();
}

// translate{rotate{child}} of pose X (rotation as axis and angle; angle 0 about z for R = I).
modeling::ImplicitNode PoseNodes(const Isometry3d& X, modeling::ImplicitNode child) {
  const Eigen::AngleAxisd aa(X.linear());
  modeling::RotateParams rotate;
  if (aa.angle() > 0.0 && aa.axis().allFinite()) {
    rotate.axis = aa.axis();
    rotate.angle = aa.angle();
  }
  modeling::ImplicitNode r(rotate, {std::move(child)});
  return modeling::ImplicitNode(modeling::TranslateParams{X.translation()}, {std::move(r)});
}

// Closest point to p on the segment a..b.
Vector3d ClosestOnSegment(const Vector3d& a, const Vector3d& b, const Vector3d& p) {
  const Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return a + t * ab;
}

// The local axis (column k of R, signed by sigma) nearest direction u: max over k, σ of σ·R_k·u.
std::pair<int, double> NearestAxis(const Matrix3d& R, const Vector3d& u) {
  int best = 2;
  double best_dot = -std::numeric_limits<double>::infinity();
  double sigma = 1.0;
  for (int k = 2; k >= 0; --k) {  // z first: it wins ties (a cylinder's own axis)
    const double d = R.col(k).dot(u);
    if (std::abs(d) > best_dot + 1e-12) {
      best_dot = std::abs(d);
      best = k;
      sigma = d >= 0.0 ? 1.0 : -1.0;
    }
  }
  return {best, sigma};
}

// True when the foot f (on the face's plane) lies inside the face's polygon (crossing number in
// the plane's 2D frame); an unbounded plane holds every point.
bool FootInside(const haptics::SnapFace& face, const Vector3d& n, const Vector3d& f) {
  if (face.polygon_W.empty()) return true;
  const Vector3d u = n.unitOrthogonal();
  const Vector3d v = n.cross(u);
  const Vector3d o = face.polygon_W.front();
  const double x = (f - o).dot(u), y = (f - o).dot(v);
  bool inside = false;
  const std::size_t m = face.polygon_W.size();
  for (std::size_t i = 0, j = m - 1; i < m; j = i++) {
    const double xi = (face.polygon_W[i] - o).dot(u), yi = (face.polygon_W[i] - o).dot(v);
    const double xj = (face.polygon_W[j] - o).dot(u), yj = (face.polygon_W[j] - o).dot(v);
    if ((yi > y) != (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi) inside = !inside;
  }
  return inside;
}

// An axis extended by its own length at each end (where a body stacked on it still aligns).
std::pair<Vector3d, Vector3d> ExtendedAxis(const SnapAxis& axis) {
  const Vector3d d = axis.b_W - axis.a_W;
  return {axis.a_W - d, axis.b_W + d};
}

}  // namespace

const char* PlaceKindName(PlaceKind kind) {
  switch (kind) {
    case PlaceKind::kSphere:
      return "sphere";
    case PlaceKind::kBox:
      return "box";
    case PlaceKind::kCylinder:
      return "cylinder";
  }
  return "sphere";
}

PlaceKind ParsePlaceKind(const std::string& name) {
  for (PlaceKind k : {PlaceKind::kSphere, PlaceKind::kBox, PlaceKind::kCylinder}) {
    if (name == PlaceKindName(k)) return k;
  }
  throw std::invalid_argument("'" + name +
                              "' is not a primitive the grip places: use sphere, box or cylinder");
}

double PlaceSize(double grasp, double pole_length, double world_scale) {
  if (!std::isfinite(grasp)) return std::numeric_limits<double>::quiet_NaN();
  return world_scale * pole_length * std::clamp(grasp, kPlaceMinGrasp, kPlaceMaxGrasp);
}

modeling::ImplicitNode PlacedNode(PlaceKind kind, const Isometry3d& X_WN, double size) {
  modeling::NodeParams params;
  switch (kind) {
    case PlaceKind::kSphere:
      params = modeling::SphereParams{0.5 * size};
      break;
    case PlaceKind::kBox:
      params = modeling::BoxParams{Vector3d::Constant(size)};
      break;
    case PlaceKind::kCylinder:
      params = modeling::CylinderParams{0.5 * size, size};
      break;
  }
  return PoseNodes(X_WN, modeling::ImplicitNode(params));
}

NodePose PoseOfNode(const modeling::ImplicitNode& node) {
  NodePose pose;
  const modeling::ImplicitNode* n = &node;
  if (const auto* t = std::get_if<modeling::TranslateParams>(&n->params)) {
    pose.X_AN.translation() = t->translation;
    pose.depth = 1;
    if (n->children.size() != 1) return pose;
    n = &n->children.front();
  }
  if (const auto* r = std::get_if<modeling::RotateParams>(&n->params)) {
    pose.X_AN.linear() = Eigen::AngleAxisd(r->angle, r->axis.normalized()).toRotationMatrix();
    ++pose.depth;
  }
  return pose;
}

Affine3d FrameOfNode(const modeling::ImplicitNode& root, const NodePath& path) {
  Affine3d X = Affine3d::Identity();
  const modeling::ImplicitNode* n = &root;
  for (std::size_t level = 0; level < path.size(); ++level) {
    const int i = path[level];
    if (i < 0 || i >= static_cast<int>(n->children.size())) {
      throw DocumentError("node path " + PathPointer(path) + ": no child " + std::to_string(i) +
                          " at " + PathPointer(NodePath(path.begin(), path.begin() + level)));
    }
    std::visit(
        [&](const auto& p) {
          using P = std::decay_t<decltype(p)>;
          if constexpr (std::is_same_v<P, modeling::TranslateParams>) {
            X = X * Eigen::Translation3d(p.translation);
          } else if constexpr (std::is_same_v<P, modeling::RotateParams>) {
            X = X * Eigen::AngleAxisd(p.angle, p.axis.normalized());
          } else if constexpr (std::is_same_v<P, modeling::ScaleParams>) {
            X = X * Eigen::Scaling(p.factors);
          } else if constexpr (std::is_same_v<P, modeling::MirrorParams>) {
            if (!p.keep_original) {
              const Vector3d m = p.normal.normalized();
              Affine3d M = Affine3d::Identity();
              M.linear() = Matrix3d::Identity() - 2.0 * m * m.transpose();
              M.translation() = 2.0 * p.offset * m;
              X = X * M;
            }
          }
        },
        n->params);
    n = &n->children[i];
  }
  return X;
}

bool IsRigid(const Affine3d& X, double tolerance) {
  const Matrix3d& R = X.linear();
  return X.matrix().allFinite() &&
         (R.transpose() * R - Matrix3d::Identity()).cwiseAbs().maxCoeff() <= tolerance &&
         std::abs(R.determinant() - 1.0) <= tolerance;
}

std::unique_ptr<Command> PoseNodeCommand(const Document& doc, ObjectId id, const NodePath& path,
                                         const Isometry3d& X_AN) {
  const DocObject& object = doc.Get(id);
  const modeling::ImplicitNode* root = TreeOf(object);
  if (root == nullptr) {
    throw DocumentError("object '" + object.name + "' has no tree: only nodes of solids move");
  }
  if (!IsRigid(Affine3d(X_AN.matrix()))) {
    throw DocumentError("moving node " + PathPointer(path) + " of '" + object.name +
                        "': the pose is not a rigid motion (or not finite)");
  }
  modeling::ImplicitNode tree = *root;
  modeling::ImplicitNode* node = &tree;
  for (int i : path) {
    if (i < 0 || i >= static_cast<int>(node->children.size())) {
      throw DocumentError("object '" + object.name + "' has no node " + PathPointer(path));
    }
    node = &node->children[i];
  }
  const NodePose old = PoseOfNode(*node);
  const Eigen::AngleAxisd aa(X_AN.linear());
  const bool turned = aa.angle() > 0.0;
  const bool translate = std::holds_alternative<modeling::TranslateParams>(node->params);
  auto set_rotation = [&](modeling::RotateParams* r) {
    r->axis = turned ? aa.axis() : Vector3d::UnitZ();
    r->angle = turned ? aa.angle() : 0.0;
  };
  if (old.depth == 2) {  // translate{rotate{...}}: edit both
    std::get<modeling::TranslateParams>(node->params).translation = X_AN.translation();
    set_rotation(&std::get<modeling::RotateParams>(node->children.front().params));
  } else if (old.depth == 1 && !translate) {  // a lone rotate: edit it, a translate above it
    set_rotation(&std::get<modeling::RotateParams>(node->params));
    modeling::ImplicitNode inner = std::move(*node);
    *node =
        modeling::ImplicitNode(modeling::TranslateParams{X_AN.translation()}, {std::move(inner)});
  } else if (old.depth == 1) {  // a translate over anything else
    std::get<modeling::TranslateParams>(node->params).translation = X_AN.translation();
    if (turned) {
      modeling::RotateParams r{aa.axis(), aa.angle()};
      modeling::ImplicitNode rotate(r, std::move(node->children));
      node->children.clear();
      node->children.push_back(std::move(rotate));
    }
  } else {  // no pose of its own: wrap it
    modeling::ImplicitNode inner = std::move(*node);
    *node = PoseNodes(X_AN, std::move(inner));
  }
  std::vector<std::unique_ptr<Command>> steps;
  steps.push_back(edit::ReplaceTree(id, std::move(tree)));
  return std::make_unique<MacroCommand>("Move " + object.name + " by touch", std::move(steps));
}

void TouchSnapSettings::Validate() const {
  auto check = [](double v, const char* field) {
    if (!(std::isfinite(v) && v > 0.0)) {
      throw std::invalid_argument(std::string("touch snap: ") + field +
                                  " must be finite and > 0, got " + std::to_string(v));
    }
  };
  check(vertex_capture, "vertex_capture");
  check(line_capture, "line_capture");
  check(face_capture, "face_capture");
  check(max_force, "max_force");
}

TouchSnapFeatures ExtractTouchSnapFeatures(const modeling::Scene& scene) {
  TouchSnapFeatures out;
  out.features = ExtractSnapFeatures(scene);
  auto value = [&](const Vector3d& x) {
    double v = std::numeric_limits<double>::infinity();
    for (const modeling::Solid& s : scene.solids)
      v = std::min(v, modeling::EvaluateTree(s.root, x));
    return v;
  };
  for (const haptics::SnapFace& face : out.features.faces_W) {
    Vector3d n = face.normal_W.normalized();
    Vector3d c = face.point_W;
    double size = 1e-3;
    if (!face.polygon_W.empty()) {  // Newell's normal of the polygon
      n.setZero();
      c.setZero();
      const std::size_t m = face.polygon_W.size();
      for (std::size_t i = 0; i < m; ++i) {
        const Vector3d& p = face.polygon_W[i];
        const Vector3d& q = face.polygon_W[(i + 1) % m];
        n += Vector3d((p.y() - q.y()) * (p.z() + q.z()), (p.z() - q.z()) * (p.x() + q.x()),
                      (p.x() - q.x()) * (p.y() + q.y()));
        c += p;
      }
      n.normalize();
      c /= static_cast<double>(m);
      size = (face.polygon_W.front() - c).norm();
    }
    const double step = 1e-3 * size;
    if (value(c + step * n) < value(c - step * n)) n = -n;  // outward: the value grows outside
    out.face_normals_W.push_back(n);
  }
  for (const auto& [a, b] : ExtractSnapAxes(scene)) out.axes.push_back({a, b});
  return out;
}

std::string Alignment::Text() const {
  switch (kind) {
    case AlignKind::kFace:
      return "face " + std::to_string(index);
    case AlignKind::kEdge:
      return "edge " + std::to_string(index);
    case AlignKind::kAxis:
      return "axis " + std::to_string(index);
    case AlignKind::kVertex:
      return "vertex " + std::to_string(index);
    case AlignKind::kNone:
      break;
  }
  return "";
}

Alignment AlignToFeatures(const TouchSnapFeatures& features, const Isometry3d& X_WN,
                          const Eigen::AlignedBox3d& box_N, const TouchSnapSettings& settings,
                          double world_scale) {
  Alignment out;
  out.X_WN = X_WN;
  const Vector3d p = X_WN.translation();
  const Matrix3d R = X_WN.linear();
  if (!p.allFinite() || !R.allFinite()) return out;
  // Vertices first: the nearest within its capture distance takes the centre, as it is.
  double best_vertex = world_scale * settings.vertex_capture;
  const std::vector<Vector3d>& vertices = features.features.vertices_W;
  for (int i = 0; i < static_cast<int>(vertices.size()); ++i) {
    const double d = (vertices[i] - p).norm();
    if (d <= best_vertex) {
      best_vertex = d;
      out.kind = AlignKind::kVertex;
      out.index = i;
      out.X_WN.translation() = vertices[i];
    }
  }
  if (out.kind != AlignKind::kNone) return out;
  // Lines: axes and edges, the nearest within the capture distance.
  const double line_capture = world_scale * settings.line_capture;
  double best = line_capture;
  Vector3d foot = Vector3d::Zero(), u = Vector3d::UnitZ();
  auto try_line = [&](const Vector3d& a, const Vector3d& b, AlignKind kind, int index) {
    const Vector3d c = ClosestOnSegment(a, b, p);
    const double d = (p - c).norm();
    if (d <= best) {
      best = d;
      foot = c;
      u = (b - a).normalized();
      out.kind = kind;
      out.index = index;
    }
  };
  for (int i = 0; i < static_cast<int>(features.axes.size()); ++i) {
    const auto [a, b] = ExtendedAxis(features.axes[i]);
    try_line(a, b, AlignKind::kAxis, i);
  }
  for (int i = 0; i < static_cast<int>(features.features.edges_W.size()); ++i) {
    const auto& [a, b] = features.features.edges_W[i];
    try_line(a, b, AlignKind::kEdge, i);
  }
  if (out.kind != AlignKind::kNone) {
    const auto [k, sigma] = NearestAxis(R, u);
    out.X_WN.linear() = SmallestRotation(sigma * R.col(k), u) * R;
    out.X_WN.translation() = foot;
    return out;
  }
  // Faces: the nearest plane the body's lowest point is within the capture distance of.
  const double face_capture = world_scale * settings.face_capture;
  double best_gap = face_capture;
  for (int i = 0; i < static_cast<int>(features.features.faces_W.size()); ++i) {
    const haptics::SnapFace& face = features.features.faces_W[i];
    const Vector3d& n = features.face_normals_W[i];
    const Vector3d q = face.polygon_W.empty() ? face.point_W : face.polygon_W.front();
    const double height = n.dot(p - q);  // of the centre above the plane
    const auto [k, sigma] = NearestAxis(R, -n);
    const double rest = sigma > 0 ? box_N.max()[k] : -box_N.min()[k];  // extent along −n
    const double gap = std::abs(height - rest);
    if (height <= 0.0 || gap > best_gap) continue;
    const Vector3d f = p - height * n;
    if (!FootInside(face, n, f)) continue;
    best_gap = gap;
    out.kind = AlignKind::kFace;
    out.index = i;
    out.X_WN.linear() = SmallestRotation(sigma * R.col(k), -n) * R;
    out.X_WN.translation() = f + rest * n;
  }
  return out;
}

haptics::SnapFeatures FeltSnapFeatures(const TouchSnapFeatures& features, double rest_height) {
  haptics::SnapFeatures out;
  out.vertices_W = features.features.vertices_W;
  out.edges_W = features.features.edges_W;
  for (const SnapAxis& axis : features.axes) out.edges_W.push_back(ExtendedAxis(axis));
  for (std::size_t i = 0; i < features.features.faces_W.size(); ++i) {
    haptics::SnapFace face = features.features.faces_W[i];
    const Vector3d shift = rest_height * features.face_normals_W[i];
    for (Vector3d& p : face.polygon_W) p += shift;
    face.point_W += shift;
    out.faces_W.push_back(std::move(face));
  }
  return out;
}

modeling::TriangleMesh GhostMesh(const modeling::ImplicitNode& node, double cells_across) {
  const modeling::CompiledSolid solid = modeling::CompiledSolid::Compile(node);
  // A node inside at a point of the ±10 m cube's surface (corners, edge and face middles) reaches
  // it: unbounded for the ghost. Checked first, because SolidBounds takes seconds to find that
  // out for a half-space.
  for (int i = 0; i < 27; ++i) {
    const Vector3d q(i % 3 - 1, (i / 3) % 3 - 1, i / 9 - 1);
    if (i != 13 && solid.Value(10.0 * q) < 0.0)
      throw std::runtime_error("the node is unbounded (a half-space): no ghost");
  }
  bool unbounded = false;
  const Eigen::AlignedBox3d box = SolidBounds(solid, &unbounded);
  if (unbounded) throw std::runtime_error("the node is unbounded (a half-space): no ghost");
  if (box.isEmpty()) throw std::runtime_error("the node is empty: no ghost");
  const double cell = box.sizes().maxCoeff() / cells_across;
  modeling::SurfaceMeshSettings s;
  s.bounds = box;
  s.bounds.min().array() -= 2.0 * cell;
  s.bounds.max().array() += 2.0 * cell;
  s.cell_size = cell;
  return modeling::MeshSurface(solid, s);
}

}  // namespace spidarcad::app
