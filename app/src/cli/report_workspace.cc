// Report section: deliverable force and moment on slices through the frame (2-D maps), and
// the line sweeps from the centre side by side with the paper's Sec. 6 figures.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "cli/report_sections.h"
#include "spidarcad/haptics/tension.h"
#include "spidarcad/haptics/workspace.h"

namespace spidarcad::app {

namespace {

using haptics::GripPose;
using haptics::SpidarGeometry;
using haptics::Vector7d;

struct Deliverable {
  double force = NAN;   // least deliverable force over ±x, ±y, ±z, N (NaN: pose impossible)
  double moment = NAN;  // least deliverable moment over ±x, ±y, ±z, N·m
};

// True when every attachment point is inside the frame with `margin` to spare.
bool Inside(const SpidarGeometry& g, const GripPose& pose, double margin) {
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d p = pose.Attachment(i);
    if (std::abs(p.x()) > g.a - margin || std::abs(p.y()) > g.b - margin ||
        std::abs(p.z()) > g.c - margin) {
      return false;
    }
  }
  return true;
}

Deliverable AtPose(const SpidarGeometry& g, const GripPose& pose, double tau_min, double tau_max,
                   long* lps) {
  Deliverable out;
  if (!Inside(g, pose, 1e-3)) return out;
  const haptics::Matrix78d A = haptics::WrenchMatrix(g, pose);
  out.force = out.moment = INFINITY;
  for (int axis = 0; axis < 6; ++axis) {
    for (int sign : {+1, -1}) {
      Vector7d e = Vector7d::Zero();
      e(axis) = sign;
      const haptics::DeliverableWrench w = haptics::MaxWrenchAlong(A, e, tau_min, tau_max);
      ++*lps;
      const double s = w.status == haptics::DeliverableStatus::kOk ? std::max(0.0, w.s_max) : 0.0;
      double& v = axis < 3 ? out.force : out.moment;
      v = std::min(v, s);
    }
  }
  return out;
}

std::string Cm(double metres) {
  return std::isnan(metres) ? std::string("never") : Fixed(100 * metres, 1) + " cm";
}
std::string Deg(double degrees) {
  return std::isnan(degrees) ? std::string("never") : Fixed(degrees, 0) + "°";
}

}  // namespace

void ReportWorkspace(ReportContext& ctx) {
  const SpidarGeometry g;
  const double tau_min = 0.2, tau_max = 8.0;
  const int n = ctx.Pick(25, 61);  // cells per side
  // Two slices through the centre: z = 0 (x–y) and y = 0 (x–z); rest orientation, grasp 90°.
  struct Slice {
    std::string name, title, x_label, y_label;
    int x_axis, y_axis;
  };
  const Slice slices[] = {{"xy", "z = 0", "x [m]", "y [m]", 0, 1},
                          {"xz", "y = 0", "x [m]", "z [m]", 0, 2}};
  long lps = 0;
  const auto start = std::chrono::steady_clock::now();
  std::vector<ColourMap> maps;
  std::vector<std::vector<std::string>> csv;
  double centre_force = NAN, centre_moment = NAN, max_force = 0, max_moment = 0;
  for (int s = 0; s < 2; ++s) {
    const Slice& slice = slices[s];
    ColourMap force{"Least deliverable force, " + slice.title,
                    slice.x_label,
                    slice.y_label,
                    "force [N]",
                    n,
                    n,
                    -g.a,
                    g.a,
                    -g.c,
                    g.c,
                    0,
                    1,
                    {}};
    ColourMap moment = force;
    moment.title = "Least deliverable moment, " + slice.title;
    moment.value_label = "moment [N*m]";
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        Eigen::Vector3d p = Eigen::Vector3d::Zero();
        p(slice.x_axis) = -g.a + (i + 0.5) * 2 * g.a / n;
        p(slice.y_axis) = -g.c + (j + 0.5) * 2 * g.c / n;
        const GripPose pose =
            GripPose::FromFrame(p, Eigen::Matrix3d::Identity(), std::numbers::pi / 2, g.d);
        const Deliverable d = AtPose(g, pose, tau_min, tau_max, &lps);
        force.values.push_back(d.force);
        moment.values.push_back(d.moment);
        if (std::isfinite(d.force)) max_force = std::max(max_force, d.force);
        if (std::isfinite(d.moment)) max_moment = std::max(max_moment, d.moment);
        csv.push_back({slice.name, Sig(p.x(), 6), Sig(p.y(), 6), Sig(p.z(), 6), Sig(d.force, 6),
                       Sig(d.moment, 6)});
      }
      ctx.Progress(0.8 * (s + (j + 1.0) / n) / 2);
    }
    maps.push_back(force);
    maps.push_back(moment);
  }
  const double lp_us = 1e6 * SecondsSince(start) / std::max(1L, lps);
  for (size_t m = 0; m < maps.size(); ++m) {
    maps[m].value_max = m % 2 == 0 ? max_force : max_moment;
  }
  {
    const GripPose rest = GripPose::FromFrame(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(),
                                              std::numbers::pi / 2, g.d);
    long unused = 0;
    const Deliverable d = AtPose(g, rest, tau_min, tau_max, &unused);
    centre_force = d.force;
    centre_moment = d.moment;
  }
  ctx.md() << "Deliverable wrench across the frame (a = b = c = " << g.a << " m, d = " << g.d
           << " m, tensions in [" << tau_min << ", " << tau_max
           << "] N): at each grip position (rest orientation, grasp 90°) the largest force "
              "(moment) the strings can display along each of ±x, ±y, ±z with every other "
              "wrench component exactly zero (MaxWrenchAlong, an exact LP), and the least of "
              "the six. White: an attachment point would leave the frame. "
           << n << " × " << n << " cells per slice, " << Sig(lp_us, 2)
           << " µs per LP (wrench matrix included).\n\n";
  ctx.md() << "| force | moment |\n|---|---|\n";
  for (int s = 0; s < 2; ++s) {
    ctx.md() << "| " << ctx.MapFigure("workspace_force_" + slices[s].name, maps[2 * s]) << " | "
             << ctx.MapFigure("workspace_moment_" + slices[s].name, maps[2 * s + 1]) << " |\n";
  }
  ctx.md() << "\n";
  ctx.Csv("workspace_maps", {"slice", "x_m", "y_m", "z_m", "force_min_N", "moment_min_Nm"}, csv);

  // Line sweeps from the centre (as `spidarcad workspace`) beside the paper's figures.
  haptics::WorkspaceSweepSettings sweep;
  sweep.step = ctx.Pick(0.01, 0.005);
  sweep.tau_min = tau_min;
  sweep.tau_max = tau_max;
  const auto samples = haptics::SweepWorkspace(g, sweep);
  ctx.Progress(0.95);
  auto worst = [](const std::vector<haptics::SweepFalloff>& fs, const std::string& axes) {
    double full = INFINITY, zero = INFINITY;
    for (const haptics::SweepFalloff& f : fs) {
      if (axes.find(f.axis) == std::string::npos) continue;
      full = std::min(full, f.last_full);
      if (!std::isnan(f.first_zero)) zero = std::min(zero, f.first_zero);
    }
    return std::make_pair(full, std::isinf(zero) ? NAN : zero);
  };
  const auto translate = haptics::SummarizeSweep(samples, "translate");
  const auto rotate = haptics::SummarizeSweep(samples, "rotate");
  const auto xy = worst(translate, "xy"), z = worst(translate, "z"), r = worst(rotate, "xyz");
  ctx.md() << "Falloff along the axes from the centre (force toward the face, moment about the "
              "axis at the centre), full = ≥ 95 % of the centre value, zero = ≤ 1 %; the "
              "worst direction of each group, beside the paper's Sec. 6 figures (the paper's "
              "device: measured, real strings; this model: ideal strings, point attachments, "
              "every other wrench component held at zero):\n";
  ctx.Table({"sweep", "paper: full to", "paper: zero at", "model: full to", "model: zero from"},
            {{"x and y", "10 cm", "about 23 cm", Cm(xy.first), Cm(xy.second)},
             {"z", "23 cm", "25 cm", Cm(z.first), Cm(z.second)},
             {"rotation", "45°", "—", Deg(r.first), Deg(r.second)}});
  ctx.Headline("centre: " + Sig(centre_force, 3) + " N force, " + Sig(centre_moment, 3) +
               " N·m moment in every direction; force toward a side face zero from " +
               Cm(xy.second) + " (paper: about 23 cm), toward top/bottom " +
               (std::isnan(z.second) ? std::string("never zero in the frame")
                                     : "zero from " + Cm(z.second)) +
               " (paper: 25 cm); moment zero from " + Deg(r.second) +
               " of rotation (paper: full to 45°); " + Sig(lp_us, 2) + " µs per LP");
  ctx.Summary(Sig(lp_us, 2) + " µs per deliverable-wrench LP",
              "side-face force zero from " + Cm(xy.second) + " (paper: about 23 cm)");
}

}  // namespace spidarcad::app
