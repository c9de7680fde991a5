// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Modelling by touch (the paper's Fig. 7 modeller "takes advantage of haptics"; docs/user-guide.md,
// "Model mode"): the geometry behind placing a primitive where the grip is, sizing it with the
// grasp, aligning it (or a grabbed node) to the faces, edges and axes of the document's solids,
// and turning the result into one undoable command. No GUI here: ModelMode (gui/modes.h) drives
// it frame by frame; the tests check it against closed forms.
//
// Frames: W the world (the scene), T the grip, N the node placed or grabbed, A the frame its
// parent's transforms put it in (X_WA: the product of the translate, rotate, scale and mirror
// nodes above it; booleans and arrays add nothing). A node's pose X_AN is read from the
// translate and rotate nodes it starts with: translate{rotate{...}} gives X_AN = T(t)·R(axis,
// angle). Units: m, rad.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

#include "doc/command.h"
#include "doc/document.h"
#include "spidarcad/haptics/snap_field.h"
#include "spidarcad/modeling/implicit_node.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::app {

// The primitives the grip places.
enum class PlaceKind { kSphere, kBox, kCylinder };
// Scene-format name of the kind: "sphere", "box", "cylinder".
const char* PlaceKindName(PlaceKind kind);
// The kind named `name` (as PlaceKindName spells it). Throws std::invalid_argument naming the
// value and the choices.
PlaceKind ParsePlaceKind(const std::string& name);

// The grasp range the size map uses (the simulated hand's range): θ is clamped to it.
inline constexpr double kPlaceMinGrasp = 20.0 * 3.14159265358979323846 / 180.0;   // rad
inline constexpr double kPlaceMaxGrasp = 160.0 * 3.14159265358979323846 / 180.0;  // rad

// The size c (m in W) the grasp gives a placed primitive: the arc between the two pole tips,
// c = s·d·clamp(θ, kPlaceMinGrasp, kPlaceMaxGrasp), with d the pole half-length (m in D) and s
// the world scale (W metres per D metre). Linear in θ: 14 mm at 20°, 63 mm at rest (90°), 112 mm
// at 160° for d = 40 mm and s = 1. c is the sphere's diameter, the box's edge and the
// cylinder's diameter and height. NaN for a non-finite θ.
double PlaceSize(double grasp, double pole_length, double world_scale);

// The node placed: translate{rotate{primitive}} with the primitive of size `size` (PlaceSize)
// centred at the origin of N (a cylinder along N's z), so that its pose is X_WN. The rotation
// is stored as an axis and angle (angle 0 about z for R = I).
modeling::ImplicitNode PlacedNode(PlaceKind kind, const Eigen::Isometry3d& X_WN, double size);

// The pose X_AN a node carries (see the file comment): translate{rotate{...}}, a translate or a
// rotate at its top; the identity for any other node. `depth` counts the pose nodes read (0, 1
// or 2).
struct NodePose {
  Eigen::Isometry3d X_AN = Eigen::Isometry3d::Identity();
  int depth = 0;
};
NodePose PoseOfNode(const modeling::ImplicitNode& node);

// X_WA of the node at `path` below `root` (the root's own A is W). Throws DocumentError naming the
// path when it leads nowhere.
Eigen::Affine3d FrameOfNode(const modeling::ImplicitNode& root, const NodePath& path);

// True when X is a rigid motion (orthonormal linear part with determinant +1, within `tolerance`).
bool IsRigid(const Eigen::Affine3d& X, double tolerance = 1e-9);

// The command that gives the node at `path` of solid `id` the pose X_AN (in its frame A): it
// edits the node's translate/rotate (PoseOfNode) or, when it has none, wraps it in a translate
// and a rotate (the node keeps its id and name; the wrappers take its place at `path`). The
// rest of the tree is unchanged. One undo step, "Move NAME by touch". Throws DocumentError for
// a bad id or path, a non-rigid X_AN or non-finite values.
std::unique_ptr<Command> PoseNodeCommand(const Document& doc, ObjectId id, const NodePath& path,
                                         const Eigen::Isometry3d& X_AN);

// ---- snap alignment ----

// Capture distances of the alignment, m in D (multiplied by the world scale): a moved body's
// centre goes onto the nearest vertex within `vertex_capture` of it, else the body aligns to the
// nearest axis or edge whose line passes within `line_capture` of its centre, else to a face
// whose plane its lowest point is within `face_capture` of (its centre over the face).
// `max_force` (N) is the pull of the felt snap field (haptics::SnapField) toward the same
// places.
struct TouchSnapSettings {
  double vertex_capture = 0.005;  // m in D
  double line_capture = 0.004;    // m in D
  double face_capture = 0.006;    // m in D
  double max_force = 0.8;         // N
  // Throws std::invalid_argument naming the field when a value is not finite and > 0.
  void Validate() const;
};

// The segment of a primitive's axis (cylinder and cone: their height; capsule: a to b; torus: its
// tube's width), W.
struct SnapAxis {
  Eigen::Vector3d a_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_W = Eigen::Vector3d::UnitZ();
};

// What a moved body aligns to: the snap features of the scene (ExtractSnapFeatures), the outward
// unit normal of each face, and the axes of the round primitives (cylinders, cones, capsules,
// tori) placed by the transforms above them.
struct TouchSnapFeatures {
  haptics::SnapFeatures features;
  std::vector<Eigen::Vector3d> face_normals_W;  // one per features.faces_W, outward, unit
  std::vector<SnapAxis> axes;
};

// The features of `scene` (throws as ExtractSnapFeatures).
TouchSnapFeatures ExtractTouchSnapFeatures(const modeling::Scene& scene);

// Which feature a pose was aligned to.
enum class AlignKind { kNone, kFace, kEdge, kAxis, kVertex };
// Text of an alignment ("face 2", "edge 7", "axis 0", "vertex 3"; "" for none).
struct Alignment {
  AlignKind kind = AlignKind::kNone;
  int index = -1;
  Eigen::Isometry3d X_WN = Eigen::Isometry3d::Identity();  // the aligned pose
  std::string Text() const;
};

// Aligns the pose X_WN of a body whose extent in its own frame N is `box_N` (m):
//  - vertex (the nearest within s·vertex_capture of the centre p): the centre moves onto it, the
//    orientation is kept (a corner has no direction to square to);
//  - else axis or edge (the nearest whose line, within the segment — an axis extended by its own
//    length at each end, to stack on it — passes within s·line_capture of the centre p): the
//    centre moves onto the line; the local axis (±x, ±y or ±z) nearest the line's direction u
//    turns onto it by the smallest rotation;
//  - else a face (outward normal n, the centre's foot inside its polygon): the local axis
//    nearest −n turns onto −n by the smallest rotation, and the body is moved along n so that
//    its extent along that axis rests on the plane; taken when the lowest point is within
//    s·face_capture of the plane before the move;
//  - else X_WN unchanged (kNone).
Alignment AlignToFeatures(const TouchSnapFeatures& features, const Eigen::Isometry3d& X_WN,
                          const Eigen::AlignedBox3d& box_N, const TouchSnapSettings& settings,
                          double world_scale);

// The features of a felt snap field that pulls the grip centre toward where AlignToFeatures
// puts the body's centre: the vertices, the edges and the axes (extended as above) as edges, the
// faces moved out by `rest_height` (m: the body's extent below its centre).
haptics::SnapFeatures FeltSnapFeatures(const TouchSnapFeatures& features, double rest_height);

// A coarse surface of `node` (its own frame: the node as a root), about `cells_across` cells
// across its box, for the ghost drawn while placing or grabbing. Throws std::runtime_error when
// the node is empty or unbounded, ModelError for an invalid tree.
modeling::TriangleMesh GhostMesh(const modeling::ImplicitNode& node, double cells_across = 24.0);

}  // namespace spidarcad::app
