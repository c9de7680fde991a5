// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/workspace.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "spidarcad/haptics/tension.h"

namespace spidarcad::haptics {

DeliverableWrench MaxWrenchAlong(const Matrix78d& A, const Vector7d& e, double tau_min,
                                 double tau_max) {
  DeliverableWrench out;
  out.s_max = std::nan("");
  out.tau.setConstant(std::nan(""));
  if (!A.allFinite() || !e.allFinite() || !(tau_min < tau_max)) return out;

  // A = U Σ Vᵀ: the last column of V spans the null space; A⁺e = V Σ⁻¹ Uᵀ e.
  const Eigen::JacobiSVD<Matrix78d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Vector7d& sigma = svd.singularValues();
  if (!(sigma(6) > 1e-10 * sigma(0))) return out;
  const Vector7d ut_e = svd.matrixU().transpose() * e;
  const Vector8d u = svd.matrixV().leftCols<7>() * ut_e.cwiseQuotient(sigma);
  const Vector8d n = svd.matrixV().col(7);

  // Half-planes a_k s + b_k α <= c_k: τ_i <= τ_max and −τ_i <= −τ_min.
  std::array<double, 16> ca, cb, cc;
  for (int i = 0; i < kNumStrings; ++i) {
    ca[2 * i] = u(i);
    cb[2 * i] = n(i);
    cc[2 * i] = tau_max;
    ca[2 * i + 1] = -u(i);
    cb[2 * i + 1] = -n(i);
    cc[2 * i + 1] = -tau_min;
  }
  const double tol = 1e-9 * std::max(1.0, tau_max);
  double best_s = -std::numeric_limits<double>::infinity();
  double best_alpha = 0;
  bool found = false;
  for (int k = 0; k < 16; ++k) {
    for (int l = k + 1; l < 16; ++l) {
      const double det = ca[k] * cb[l] - ca[l] * cb[k];
      const double scale = std::hypot(ca[k], cb[k]) * std::hypot(ca[l], cb[l]);
      if (!(std::abs(det) > 1e-12 * scale)) continue;  // parallel lines: no vertex
      const double s = (cc[k] * cb[l] - cc[l] * cb[k]) / det;
      const double alpha = (ca[k] * cc[l] - ca[l] * cc[k]) / det;
      bool feasible = true;
      for (int m = 0; m < 16 && feasible; ++m) {
        feasible = ca[m] * s + cb[m] * alpha - cc[m] <= tol;
      }
      if (feasible && s > best_s) {
        best_s = s;
        best_alpha = alpha;
        found = true;
      }
    }
  }
  if (!found) {
    out.status = DeliverableStatus::kInfeasible;
    return out;
  }
  out.s_max = best_s;
  for (int i = 0; i < kNumStrings; ++i) {
    out.tau(i) = std::clamp(best_s * u(i) + best_alpha * n(i), tau_min, tau_max);
  }
  out.status = DeliverableStatus::kOk;
  return out;
}

void WorkspaceSweepSettings::Validate() const {
  auto fail = [](const std::string& field, double v, const std::string& rule) {
    throw std::invalid_argument("WorkspaceSweepSettings: field '" + field + "' " + rule + ", got " +
                                std::to_string(v));
  };
  if (!std::isfinite(step) || step <= 0) fail("step", step, "must be a positive length in m");
  if (!std::isfinite(angle_step_deg) || angle_step_deg <= 0) {
    fail("angle_step_deg", angle_step_deg, "must be a positive angle in degrees");
  }
  if (!std::isfinite(max_angle_deg) || max_angle_deg < 0 || max_angle_deg > 180) {
    fail("max_angle_deg", max_angle_deg, "must be in [0, 180] degrees");
  }
  TensionSettings tension;
  tension.tau_min = tau_min;
  tension.tau_max = tau_max;
  tension.Validate();
}

namespace {

// Deliverable value along e, 0 when it cannot be displayed at all.
double Deliverable(const Matrix78d& A, const Vector7d& e, const WorkspaceSweepSettings& s) {
  const DeliverableWrench r = MaxWrenchAlong(A, e, s.tau_min, s.tau_max);
  if (r.status != DeliverableStatus::kOk) return 0.0;
  return std::max(r.s_max, 0.0);
}

Vector7d Unit(int row, int sign) {
  Vector7d e = Vector7d::Zero();
  e(row) = sign;
  return e;
}

void FillCommon(const Matrix78d& A, int axis, const WorkspaceSweepSettings& s,
                WorkspaceSample* sample) {
  double force_min = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    for (int sg : {+1, -1}) force_min = std::min(force_min, Deliverable(A, Unit(k, sg), s));
  }
  sample->force_min = force_min;
  sample->moment_pos = Deliverable(A, Unit(3 + axis, +1), s);
  sample->moment_neg = Deliverable(A, Unit(3 + axis, -1), s);
  sample->grasp_close = Deliverable(A, Unit(6, +1), s);
  sample->grasp_open = Deliverable(A, Unit(6, -1), s);
}

bool AttachmentsInside(const SpidarGeometry& g, const GripPose& pose) {
  const Eigen::Vector3d half(g.a, g.b, g.c);
  for (int i = 0; i < kNumStrings; ++i) {
    const Eigen::Vector3d p = pose.Attachment(i);
    if ((p.cwiseAbs() - half).maxCoeff() >= -1e-9) return false;
  }
  return true;
}

}  // namespace

std::vector<WorkspaceSample> SweepWorkspace(const SpidarGeometry& geometry,
                                            const WorkspaceSweepSettings& settings) {
  geometry.Validate();
  settings.Validate();
  std::vector<WorkspaceSample> samples;
  const char kAxes[3] = {'x', 'y', 'z'};
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign : {+1, -1}) {
      for (int j = 0;; ++j) {
        const double distance = j * settings.step;
        GripPose pose = GripPose::Rest(geometry.d);
        pose.p0(axis) = sign * distance;
        if (!AttachmentsInside(geometry, pose)) break;
        const Matrix78d A = WrenchMatrix(geometry, pose);
        WorkspaceSample sample;
        sample.sweep = "translate";
        sample.axis = kAxes[axis];
        sample.sign = sign;
        sample.distance = distance;
        sample.force = Deliverable(A, Unit(axis, sign), settings);
        FillCommon(A, axis, settings, &sample);
        samples.push_back(sample);
      }
    }
  }
  for (int axis = 0; axis < 3; ++axis) {
    for (int sign : {+1, -1}) {
      for (int j = 0;; ++j) {
        const double angle_deg = j * settings.angle_step_deg;
        if (angle_deg > settings.max_angle_deg + 1e-9) break;
        const Eigen::Matrix3d R =
            Eigen::AngleAxisd(sign * angle_deg * M_PI / 180.0, Eigen::Vector3d::Unit(axis))
                .toRotationMatrix();
        const GripPose pose = GripPose::FromFrame(Eigen::Vector3d::Zero(), R, M_PI / 2, geometry.d);
        if (!AttachmentsInside(geometry, pose)) break;
        const Matrix78d A = WrenchMatrix(geometry, pose);
        WorkspaceSample sample;
        sample.sweep = "rotate";
        sample.axis = kAxes[axis];
        sample.sign = sign;
        sample.angle_deg = angle_deg;
        sample.force = std::nan("");
        FillCommon(A, axis, settings, &sample);
        samples.push_back(sample);
      }
    }
  }
  return samples;
}

std::vector<SweepFalloff> SummarizeSweep(const std::vector<WorkspaceSample>& samples,
                                         const std::string& sweep, double rated) {
  std::vector<SweepFalloff> out;
  const bool translate = sweep == "translate";
  for (char axis : {'x', 'y', 'z'}) {
    for (int sign : {+1, -1}) {
      SweepFalloff f;
      f.axis = axis;
      f.sign = sign;
      f.first_zero = std::nan("");
      bool first = true;
      bool still_full = true;
      for (const WorkspaceSample& s : samples) {
        if (s.sweep != sweep || s.axis != axis || s.sign != sign) continue;
        const double x = translate ? s.distance : s.angle_deg;
        const double v = translate ? s.force : std::min(s.moment_pos, s.moment_neg);
        if (first) {
          f.centre = v;
          f.full = rated > 0 ? std::min(v, rated) : v;
          first = false;
        }
        if (still_full && v >= 0.95 * f.full) {
          f.last_full = x;
        } else {
          still_full = false;
        }
        if (std::isnan(f.first_zero) && v <= 0.01 * f.full) f.first_zero = x;
      }
      if (!first) out.push_back(f);
    }
  }
  return out;
}

}  // namespace spidarcad::haptics
