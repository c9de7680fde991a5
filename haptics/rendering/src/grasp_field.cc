// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/grasp_field.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics {

namespace {
void Require(bool ok, const char* field, double value, const char* what) {
  if (!ok) {
    throw std::invalid_argument(std::string("GraspSettings.") + field + " = " +
                                std::to_string(value) + ": " + what);
  }
}
}  // namespace

void GraspSettings::Validate() const {
  Require(pole_length > 0 && std::isfinite(pole_length), "pole_length", pole_length,
          "must be finite and > 0");
  Require(samples >= 3 && samples <= 10000, "samples", samples, "must be in [3, 10000]");
  Require(refine_iterations >= 0 && refine_iterations <= 100, "refine_iterations",
          refine_iterations, "must be in [0, 100]");
  Require(stiffness >= 0 && std::isfinite(stiffness), "stiffness", stiffness,
          "must be finite and >= 0");
  Require(damping >= 0 && std::isfinite(damping), "damping", damping, "must be finite and >= 0");
  Require(grab_depth > 0 && std::isfinite(grab_depth), "grab_depth", grab_depth,
          "must be finite and > 0");
}

GraspField::GraspField(std::shared_ptr<const DistanceField> object_O, const Eigen::Isometry3d& X_WO,
                       const GraspSettings& settings)
    : object_(std::move(object_O)), settings_(settings), X_WO_(X_WO) {
  if (object_ == nullptr) throw std::invalid_argument("GraspField: the object field is null");
  settings_.Validate();
  const Eigen::Matrix3d R = X_WO.linear();
  if (!X_WO.matrix().allFinite() ||
      (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-9 || R.determinant() < 0) {
    throw std::invalid_argument("GraspField: X_WO is not a rigid transform");
  }
  X_OW_ = X_WO_.inverse(Eigen::Isometry);
  GraspState s;
  s.X_WO = X_WO_;
  published_.Write(s);
}

double GraspField::Phi(const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) const noexcept {
  if (gradient_W == nullptr) return object_->Evaluate(X_OW_ * p_W, nullptr);
  Eigen::Vector3d g_O;
  const double v = object_->Evaluate(X_OW_ * p_W, &g_O);
  *gradient_W = X_WO_.linear() * g_O;
  return v;
}

ToolWrench GraspField::Evaluate(const ToolKinematics& tool) noexcept {
  const GraspSettings& s = settings_;
  if (grasped_) {
    // The held object moves with the grip.
    Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
    X_WT.linear() = tool.R_WT;
    X_WT.translation() = tool.p_WT;
    X_WO_ = X_WT * X_TO_;
    X_OW_ = X_WO_.inverse(Eigen::Isometry);
  }
  const PoleDirections poles = GripPoleDirections(tool.grasp);
  auto phi = [this](const Eigen::Vector3d& p_W, Eigen::Vector3d* g) { return Phi(p_W, g); };
  PoleContact contact[2];
  for (int k = 0; k < 2; ++k) {
    contact[k] = FindPoleContact(phi, tool.p_WT, tool.R_WT, poles, k, s.pole_length, s.samples,
                                 s.refine_iterations);
    depth_[k] = contact[k].depth;
  }

  ToolWrench w;
  if (contact[0].pushing && contact[1].pushing) {
    w.g = -2.0 * SqueezeOf(contact[0], contact[1], tool.grasp_rate, s);
    if (!grasped_ && depth_[0] >= s.grab_depth && depth_[1] >= s.grab_depth) {
      grasped_ = true;
      Eigen::Isometry3d X_WT = Eigen::Isometry3d::Identity();
      X_WT.linear() = tool.R_WT;
      X_WT.translation() = tool.p_WT;
      X_TO_ = X_WT.inverse(Eigen::Isometry) * X_WO_;
    }
  } else if (grasped_) {
    grasped_ = false;  // released where it is
  }
  grasped_flag_.store(grasped_, std::memory_order_release);
  GraspState& out = published_.WriteSlot();
  out.grasped = grasped_;
  out.X_WO = X_WO_;
  out.depth1 = depth_[0];
  out.depth2 = depth_[1];
  published_.Publish();
  return w;
}

}  // namespace spidarcad::haptics
