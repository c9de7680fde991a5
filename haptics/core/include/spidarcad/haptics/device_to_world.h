// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// X_WD: the map from the device frame D (the SPIDAR-G's workspace, origin at the frame centre)
// to the world frame W (the scene). The one type for it: the haptic loop (LoopSettings::X_WD),
// the scene's fitted workspace (app WorkspaceMap) and the window's views all hold this.
//
// A uniform scale s > 0 and an offset, no rotation (the axes of D and W are parallel). Units:
// metres in both frames, s in world metres per device metre.
//     p_W = s·p_D + p_WDo                       (point, m)
//     p_D = (p_W − p_WDo) / s                   (the inverse, X_DW)
//     v_W = s·v_D                               (velocity of a point, m/s)
//     ω_W = ω_D,  R_WT = R_DT                   (no rotation, uniform scale)
// Forces and moments map back by the transpose of that Jacobian (virtual work): a world force
// f_W on the tool point is the device force f_D = s·f_W and a world moment m_W is m_D = m_W, so
// the power is the same in both frames, f_D·v_D + m_D·ω_D = f_W·v_W + m_W·ω_W.
// The haptic loop displays force_scale·f_W instead (LoopSettings::force_scale, 1 by default):
// the scene adapters divide their stiffness by s, so the stiffness felt at the grip is the one
// set in N per metre of grip motion (app/src/scene/scene_haptics.h).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

namespace spidarcad::haptics {

// X_WD: p_W = world_scale·p_D + p_WDo (see the file comment). An aggregate: {s, p_WDo}.
struct DeviceToWorld {
  double world_scale = 1.0;                         // s: world metres per device metre, > 0
  Eigen::Vector3d p_WDo = Eigen::Vector3d::Zero();  // world position of the device origin, m

  // True when s is finite and > 0 and p_WDo is finite.
  bool IsValid() const {
    return world_scale > 0 && std::isfinite(world_scale) && p_WDo.allFinite();
  }
  // p_W = s·p_D + p_WDo (m).
  Eigen::Vector3d PointToWorld(const Eigen::Vector3d& p_D) const {
    return world_scale * p_D + p_WDo;
  }
  // p_D = (p_W − p_WDo) / s (m), the inverse of PointToWorld.
  Eigen::Vector3d PointToDevice(const Eigen::Vector3d& p_W) const {
    return (p_W - p_WDo) / world_scale;
  }
  // v_W = s·v_D (m/s): a velocity, or any displacement.
  Eigen::Vector3d VectorToWorld(const Eigen::Vector3d& v_D) const { return world_scale * v_D; }
  // v_D = v_W / s (m/s), the inverse of VectorToWorld.
  Eigen::Vector3d VectorToDevice(const Eigen::Vector3d& v_W) const { return v_W / world_scale; }
  // The power-conjugate device force of a world force: f_D = s·f_W (N).
  Eigen::Vector3d ForceToDevice(const Eigen::Vector3d& f_W) const { return world_scale * f_W; }
  // The power-conjugate device moment of a world moment: m_D = m_W (N·m).
  Eigen::Vector3d MomentToDevice(const Eigen::Vector3d& m_W) const { return m_W; }
  // The box (D, m) of the points p_D whose image lies in box_W (W, m); an empty box is
  // returned as it is.
  Eigen::AlignedBox3d BoxToDevice(const Eigen::AlignedBox3d& box_W) const {
    if (box_W.isEmpty()) return box_W;
    return Eigen::AlignedBox3d(PointToDevice(box_W.min()), PointToDevice(box_W.max()));
  }
};

}  // namespace spidarcad::haptics
