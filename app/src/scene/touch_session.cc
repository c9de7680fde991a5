// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/touch_session.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <variant>

#include "spidarcad/haptics/snap_field.h"

namespace spidarcad::app {

bool SqueezeDetector::Update(double t, double grasp) {
  if (!std::isfinite(t) || !std::isfinite(grasp)) return false;
  if (!samples_.empty() && t < samples_.back().first) samples_.clear();  // the clock restarted
  samples_.emplace_back(t, grasp);
  while (samples_.size() > 1 && t - samples_.front().first > kHistory) samples_.pop_front();
  // The smallest angle of the last kWindow s.
  std::size_t lowest = samples_.size() - 1;
  for (std::size_t i = samples_.size(); i-- > 0 && t - samples_[i].first <= kWindow;) {
    if (samples_[i].second < samples_[lowest].second) lowest = i;
  }
  // Where the closing toward it began: back from the lowest sample while the angle rises
  // (going back in time), allowing kNoise of jitter.
  std::size_t first = lowest;
  while (first > 0 && samples_[first - 1].second >= samples_[first].second - kNoise) --first;
  // The gesture starts when the angle last left its top (a steady hold before it is not part
  // of the squeeze).
  double top = samples_[first].second;
  for (std::size_t i = first; i <= lowest; ++i) top = std::max(top, samples_[i].second);
  std::size_t start = first;
  for (std::size_t i = first; i <= lowest; ++i) {
    if (samples_[i].second >= top - kNoise) start = i;
  }
  const double low = samples_[lowest].second;
  const bool deep = samples_[start].second - low >= kDepth && grasp - low >= kDepth;
  if (deep && t - samples_[start].first <= kWindow) {
    last_start_ = samples_[start].first;
    samples_.clear();
    samples_.emplace_back(t, grasp);
    return true;
  }
  return false;
}

int AlignKindNumber(AlignKind kind) {
  switch (kind) {
    case AlignKind::kFace:
      return 1;
    case AlignKind::kEdge:
      return 2;
    case AlignKind::kAxis:
      return 3;
    case AlignKind::kVertex:
      return 4;
    case AlignKind::kNone:
      break;
  }
  return 0;
}

namespace {

// The tree of `root` with the node at `path` replaced by a speck far away (its features gone,
// the rest of the tree as it was).
modeling::ImplicitNode WithoutNode(modeling::ImplicitNode root, const NodePath& path) {
  modeling::ImplicitNode* n = &root;
  for (int i : path) n = &n->children[i];
  *n = modeling::ImplicitNode(modeling::TranslateParams{Eigen::Vector3d(1e6, 1e6, 1e6)},
                              {modeling::ImplicitNode(modeling::SphereParams{1e-6})});
  return root;
}

}  // namespace

TouchSession::TouchSession(double pole_length) : pole_length_(pole_length) {}

void TouchSession::SetWorldScale(double world_scale) {
  if (world_scale > 0.0 && std::isfinite(world_scale)) world_scale_ = world_scale;
}

bool TouchSession::SetPlacing(std::optional<PlaceKind> kind) {
  placing_ = kind;
  history_.clear();
  ghost_ = {};
  if (!placing_) return DropFeltSnap();
  return false;
}

void TouchSession::UpdateFeatures(const Document& doc, int generation, ObjectId excluded,
                                  const NodePath& excluded_path) {
  if (features_doc_ == &doc && features_generation_ == generation &&
      features_revision_ == doc.revision() && excluded_ == excluded &&
      excluded_path_ == excluded_path)
    return;
  features_doc_ = &doc;
  features_generation_ = generation;
  features_revision_ = doc.revision();
  excluded_ = excluded;
  excluded_path_ = excluded_path;
  ++features_count_;  // the felt field follows the new features
  modeling::Scene scene;
  for (const DocObject& o : doc.objects()) {
    const auto* solid = std::get_if<SolidData>(&o.data);
    if (solid == nullptr) continue;
    if (o.id != excluded) {
      scene.solids.push_back({o.name, solid->root});
    } else if (!excluded_path.empty()) {
      scene.solids.push_back({o.name, WithoutNode(solid->root, excluded_path)});
    }
  }
  try {
    features_ = ExtractTouchSnapFeatures(scene);
  } catch (const std::exception& e) {
    features_ = {};  // too many features, or a tree that does not evaluate: no alignment
    message_ = std::string("no snapping: ") + e.what();
  }
}

const Alignment& TouchSession::Align(const Eigen::Isometry3d& X_WN,
                                     const Eigen::AlignedBox3d& box_N) {
  ghost_ = AlignToFeatures(features_, X_WN, box_N, settings_, world_scale_);
  return ghost_;
}

bool TouchSession::UpdateFeltSnap(double rest_height) {
  const bool fresh = felt_features_ == features_count_ &&
                     std::abs(rest_height - felt_rest_height_) <= 0.02 * felt_rest_height_;
  if (fresh) return false;
  felt_features_ = features_count_;
  felt_rest_height_ = rest_height;
  felt_snap_.reset();
  const haptics::SnapFeatures features = FeltSnapFeatures(features_, rest_height);
  if (features.edges_W.empty() && features.faces_W.empty()) return true;
  haptics::SnapSettings settings;
  settings.max_force = settings_.max_force;
  settings.edge_radius = world_scale_ * settings_.line_capture;
  settings.face_radius = world_scale_ * settings_.face_capture;
  settings.vertex_radius = world_scale_ * settings_.vertex_capture;
  try {
    felt_snap_ = std::make_shared<haptics::SnapField>(features, settings);
  } catch (const std::exception& e) {
    message_ = std::string("no snap force: ") + e.what();
  }
  return true;
}

bool TouchSession::DropFeltSnap() {
  const bool had = felt_snap_ != nullptr;
  felt_snap_.reset();
  felt_features_ = ~std::uint64_t{0};
  felt_rest_height_ = -1.0;
  return had;
}

TouchSession::PlaceFrame TouchSession::UpdatePlacing(const haptics::ToolState& tool, Document* doc,
                                                     int generation, bool squeezed,
                                                     double squeeze_start, bool place_key) {
  PlaceFrame frame;
  if (!placing_ || doc == nullptr) return frame;
  UpdateFeatures(*doc, generation);
  Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
  X_WT.linear() = tool.tool_W.R_WT;
  X_WT.translation() = tool.tool_W.p_WT;
  if (!X_WT.matrix().allFinite()) return frame;
  const double size = PlaceSize(tool.pose_D.Grasp(), pole_length_, world_scale_);
  if (!std::isfinite(size)) return frame;
  const Eigen::AlignedBox3d box(Eigen::Vector3d::Constant(-0.5 * size),
                                Eigen::Vector3d::Constant(0.5 * size));
  Align(X_WT, box);
  ghost_size_ = size;
  history_.push_back({tool.time, ghost_, size});
  while (history_.size() > 1 && tool.time - history_.front().time > SqueezeDetector::kHistory)
    history_.pop_front();
  // The felt faces' lift: half the size once the grasp is steady, else the field's as it is.
  bool steady = true;
  for (const GhostSample& g : history_) {
    if (tool.time - g.time <= kSteadyTime && std::abs(g.size - size) > kSteadyTolerance * size)
      steady = false;
  }
  const double rest = steady || felt_rest_height_ <= 0.0 ? 0.5 * size : felt_rest_height_;
  frame.felt_changed = UpdateFeltSnap(rest);
  if (squeezed) {
    // The ghost as it was when the squeeze began (the squeeze itself changes the size).
    GhostSample before = history_.front();
    for (const GhostSample& g : history_)
      if (g.time <= squeeze_start) before = g;
    ghost_ = before.pose;
    ghost_size_ = before.size;
    frame.placed = Place(doc);
  } else if (place_key) {
    frame.placed = Place(doc);
  }
  if (frame.placed) frame.placed_id = placed_id_;
  return frame;
}

bool TouchSession::Place(Document* doc) {
  if (!placing_ || doc == nullptr || !std::isfinite(ghost_size_) || ghost_size_ <= 0) {
    message_ = "place: nothing to place (choose a primitive first)";
    return false;
  }
  const std::string name = UniqueObjectName(*doc, PlaceKindName(*placing_));
  try {
    doc->Execute(edit::AddSolid(name, PlacedNode(*placing_, ghost_.X_WN, ghost_size_)));
  } catch (const std::exception& e) {
    message_ = std::string("place failed (nothing changed): ") + e.what();
    return false;
  }
  placed_id_ = doc->last_created().empty() ? 0 : doc->last_created().back();
  ++placed_count_;
  char size[64];
  std::snprintf(size, sizeof size, "%.1f mm", 1000.0 * ghost_size_);
  message_ = "placed '" + name + "' (" + size + ")";
  if (ghost_.kind != AlignKind::kNone) message_ += ", aligned to " + ghost_.Text();
  return true;
}

haptics::ToolWrench TouchSnapSlotField::Evaluate(const haptics::ToolKinematics& tool) noexcept {
  const std::shared_ptr<haptics::ForceField>& field = session_->felt_snap();
  if (field == nullptr) return {};
  return field->Evaluate(tool);
}

}  // namespace spidarcad::app
