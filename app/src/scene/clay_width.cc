// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/clay_width.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "spidarcad/haptics/geometry.h"

namespace spidarcad::app {

void ClayWidthSettings::Validate() const {
  grasp.Validate();
  if (!(full_squeeze_depth > 0.0) || !std::isfinite(full_squeeze_depth)) {
    throw std::invalid_argument("clay width setting full_squeeze_depth = " +
                                std::to_string(full_squeeze_depth) + ": must be > 0 m");
  }
  if (!(grid.cell > 0.0) || !std::isfinite(grid.cell)) {
    throw std::invalid_argument("clay width setting grid.cell = " + std::to_string(grid.cell) +
                                ": must be > 0 m");
  }
}

ClaySqueeze ComputeClaySqueeze(const haptics::DistanceField& clay, const Eigen::Isometry3d& X_WC,
                               const haptics::ToolKinematics& tool,
                               const ClayWidthSettings& settings) noexcept {
  ClaySqueeze out;
  const haptics::GraspSettings& s = settings.grasp;
  if (!tool.p_WT.allFinite() || !tool.R_WT.allFinite() || !std::isfinite(tool.grasp)) return out;
  // The clay's field in W: φ(X_CW p), its gradient turned back into W.
  const Eigen::Isometry3d X_CW = X_WC.inverse(Eigen::Isometry);
  auto phi = [&](const Eigen::Vector3d& p_W, Eigen::Vector3d* gradient_W) {
    if (gradient_W == nullptr) return clay.Evaluate(X_CW * p_W, nullptr);
    Eigen::Vector3d g_C;
    const double v = clay.Evaluate(X_CW * p_W, &g_C);
    *gradient_W = X_WC.linear() * g_C;
    return v;
  };
  const haptics::PoleDirections poles = haptics::GripPoleDirections(tool.grasp);
  for (int k = 0; k < 2; ++k) {
    out.pole[k] = haptics::FindPoleContact(phi, tool.p_WT, tool.R_WT, poles, k, s.pole_length,
                                           s.samples, s.refine_iterations);
  }
  if (!(out.pole[0].pushing && out.pole[1].pushing)) return out;
  const int j = out.pole[0].depth <= out.pole[1].depth ? 0 : 1;  // the shallower pole
  out.squeeze = out.pole[j].depth;
  for (int k = 0; k < 2; ++k) {
    const int pole = k == 0 ? j : 1 - j;
    out.contact_W[k] = tool.p_WT + out.pole[pole].t * (tool.R_WT * poles.u_T[pole]);
  }
  out.g = -2.0 * haptics::SqueezeQ(out.squeeze, out.pole[j].a, tool.grasp_rate, s);
  return out;
}

double SqueezeStrength(double squeeze, double full_depth) noexcept {
  if (!std::isfinite(squeeze) || !(full_depth > 0.0)) return 0.0;
  return std::clamp(squeeze / full_depth, 0.0, 1.0);
}

}  // namespace spidarcad::app
