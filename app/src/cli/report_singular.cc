// Report section: the conditioning of forward kinematics and its interior singular set, as 2-D
// maps of the error gain (1/sigma_min of the scaled length Jacobian) on slices of the workspace
// (haptics::SampleFkConditioning), with where a cold FK solve refuses and why.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "cli/report_sections.h"
#include "spidarcad/haptics/kinematics.h"

namespace spidarcad::app {

namespace {

using haptics::FkConditioningMap;
using haptics::FkSlice;
using haptics::FkStatus;
using haptics::PoseAxis;

// Colour range of the maps: log10 of the error gain from 0 (1 m/m) to 4 (1e4 m/m: FK refuses
// above 1e3); larger and infinite gains take the top colour.
constexpr double kLogGainMax = 4.0;

struct SliceSpec {
  std::string name;   // file stem
  std::string title;  // chart title
  std::string fixed;  // the other coordinates, for the table
  FkSlice slice;
  std::string x_label, y_label;
  double x_scale = 1.0;  // plotted = coordinate × scale (m, or rad -> deg)
  double y_scale = 1.0;
};

std::string AxisLabel(PoseAxis axis) {
  switch (axis) {
    case PoseAxis::kX:
    case PoseAxis::kY:
    case PoseAxis::kZ:
      return std::string(haptics::PoseAxisName(axis)) + " [m]";
    default:
      return std::string(haptics::PoseAxisName(axis)) + " [deg]";
  }
}

double AxisScale(PoseAxis axis) {
  return axis == PoseAxis::kX || axis == PoseAxis::kY || axis == PoseAxis::kZ
             ? 1.0
             : 180.0 / std::numbers::pi;
}

SliceSpec Spec(std::string name, std::string title, std::string fixed, FkSlice slice) {
  SliceSpec s{std::move(name),         std::move(title),
              std::move(fixed),        slice,
              AxisLabel(slice.u_axis), AxisLabel(slice.v_axis),
              AxisScale(slice.u_axis), AxisScale(slice.v_axis)};
  return s;
}

// Cell-centred colour map of a sampled slice: sample (j, k) is the cell around (u(k), v(j)).
ColourMap ToColourMap(const SliceSpec& spec, const FkConditioningMap& map) {
  const int nu = static_cast<int>(map.u.size()), nv = static_cast<int>(map.v.size());
  const double du = (map.u(nu - 1) - map.u(0)) / (nu - 1);
  const double dv = (map.v(nv - 1) - map.v(0)) / (nv - 1);
  ColourMap out;
  out.title = spec.title;
  out.x_label = spec.x_label;
  out.y_label = spec.y_label;
  out.value_label = "log10 error gain [m/m]";
  out.nx = nu;
  out.ny = nv;
  out.x0 = (map.u(0) - 0.5 * du) * spec.x_scale;
  out.x1 = (map.u(nu - 1) + 0.5 * du) * spec.x_scale;
  out.y0 = (map.v(0) - 0.5 * dv) * spec.y_scale;
  out.y1 = (map.v(nv - 1) + 0.5 * dv) * spec.y_scale;
  out.value_min = 0.0;
  out.value_max = kLogGainMax;
  out.values.resize(static_cast<size_t>(nu) * nv);
  for (int j = 0; j < nv; ++j) {
    for (int k = 0; k < nu; ++k) {
      const double gain = map.error_gain(j, k);
      double value = NAN;
      if (!std::isnan(gain)) value = std::isfinite(gain) ? std::log10(std::max(gain, 1.0)) : 99.0;
      out.values[static_cast<size_t>(j) * nu + k] = std::min(value, kLogGainMax);
    }
  }
  return out;
}

}  // namespace

void ReportSingularSet(ReportContext& ctx) {
  const haptics::SpidarGeometry g;
  // Samples per side: 4 k + 1, so the grids hold the centre and yaw = ±90° (the singular family).
  const int n = ctx.Pick(33, 81);
  const double pi = std::numbers::pi;
  // The frame's central slices at rest (z = 0 and y = 0, grasp 90°), the z = 0 slice with the
  // grip turned 90° about z, and the singular family of docs/kinematics.md: the centre on the z
  // axis against the yaw. (Measured: at yaw 90° and grasp 90° the whole z = 0 slice, and the
  // z = 5 cm one, is singular, not only the z axis: the family spans the centre's x and y too.)
  std::vector<SliceSpec> specs;
  {
    FkSlice s;
    s.u_axis = PoseAxis::kX;
    s.v_axis = PoseAxis::kY;
    s.u_min = s.v_min = -g.a;
    s.u_max = s.v_max = g.a;
    s.u_count = s.v_count = n;
    specs.push_back(Spec("fk_gain_xy", "Error gain, z = 0, rest", "z = 0, rest, grasp 90°", s));
    s.v_axis = PoseAxis::kZ;
    s.v_min = -g.c;
    s.v_max = g.c;
    specs.push_back(Spec("fk_gain_xz", "Error gain, y = 0, rest", "y = 0, rest, grasp 90°", s));
    s.v_axis = PoseAxis::kY;
    s.v_min = -g.b;
    s.v_max = g.b;
    s.rpy = Eigen::Vector3d(0, 0, pi / 2);
    specs.push_back(
        Spec("fk_gain_xy_yaw90", "Error gain, z = 0, yaw 90°", "z = 0, yaw 90°, grasp 90°", s));
    FkSlice family;
    family.u_axis = PoseAxis::kZ;
    family.u_min = -g.c + 2 * g.d;
    family.u_max = g.c - 2 * g.d;
    family.v_axis = PoseAxis::kYaw;
    family.v_min = -pi;
    family.v_max = pi;
    family.u_count = family.v_count = n;
    specs.push_back(Spec("fk_gain_z_yaw", "Error gain, centre on the z axis",
                         "x = y = 0, roll = pitch = 0, grasp 90°", family));
  }
  std::vector<std::vector<std::string>> table, csv;
  std::vector<std::string> images;
  double total_seconds = 0.0;
  long total_samples = 0;
  double xy_median = NAN, xy_refused = NAN, yaw_refused = NAN;
  for (size_t m = 0; m < specs.size(); ++m) {
    const SliceSpec& spec = specs[m];
    const auto start = std::chrono::steady_clock::now();
    const FkConditioningMap map = haptics::SampleFkConditioning(g, spec.slice);
    total_seconds += SecondsSince(start);
    std::vector<double> gains;
    long inside = 0, ok = 0, singular = 0, ambiguous = 0, other = 0, below10 = 0, above1000 = 0;
    for (int j = 0; j < map.v.size(); ++j) {
      for (int k = 0; k < map.u.size(); ++k) {
        const double gain = map.error_gain(j, k), status = map.fk_status(j, k);
        csv.push_back({spec.name, Sig(map.u(k), 6), Sig(map.v(j), 6), Sig(gain, 6),
                       Sig(map.position_gain(j, k), 6), Sig(status, 2)});
        if (std::isnan(gain)) continue;
        ++inside;
        gains.push_back(gain);
        below10 += gain < 10.0;
        above1000 += !(gain < 1000.0);
        const auto s = static_cast<FkStatus>(static_cast<int>(status));
        if (s == FkStatus::kOk) {
          ++ok;
        } else if (s == FkStatus::kSingular) {
          ++singular;
        } else if (s == FkStatus::kAmbiguous) {
          ++ambiguous;
        } else {
          ++other;
        }
      }
    }
    total_samples += inside;
    auto share = [&](long count) { return inside ? 100.0 * count / inside : NAN; };
    const double median = Median(gains);
    if (m == 0) {
      xy_median = median;
      xy_refused = share(inside - ok);
    }
    if (m == 3) yaw_refused = share(singular + ambiguous);
    table.push_back({spec.title, spec.fixed, std::to_string(inside), Sig(median, 3),
                     Sig(gains.empty() ? NAN : *std::max_element(gains.begin(), gains.end()), 3),
                     Fixed(share(below10), 1) + " %", Fixed(share(above1000), 1) + " %",
                     Fixed(share(ok), 1) + " %", Fixed(share(singular), 1) + " %",
                     Fixed(share(ambiguous), 1) + " %", Fixed(share(other), 1) + " %"});
    images.push_back(ctx.MapFigure(spec.name, ToColourMap(spec, map)));
    ctx.Progress((m + 1.0) / specs.size());
  }
  const double us_per_sample = 1e6 * total_seconds / std::max(1L, total_samples);
  ctx.md() << "How well the eight string lengths fix the grip pose: the error gain is 1/σ_min of "
              "the 8 × 7 Jacobian of the lengths against the pose (rotation and grasp scaled by "
              "the pole half-length d = "
           << g.d
           << " m), in metres of pose error per metre of length error (docs/kinematics.md); "
              "the interior singular set is where it is infinite. Each map samples a slice of "
              "the pose space (haptics::SampleFkConditioning) on "
           << n << " × " << n << " points; the colour is log10 of the gain, capped at "
           << Sig(kLogGainMax, 2)
           << " (FK refuses as `singular` above 1000). White: an attachment point outside the "
              "frame (a = b = c = "
           << g.a
           << " m). At each point a cold FK solve on the exact lengths gives the status columns "
              "(`ambiguous`: another branch reproduces the lengths within half an encoder count). "
           << Sig(us_per_sample, 2)
           << " µs per sample (conditioning and FK solve). With the grip turned 90° about z at a "
              "90° grasp, every point of the z = 0 slice is singular: the family of "
              "docs/kinematics.md (named there for the centre on the z axis) covers the centre's "
              "x and y as well.\n\n";
  ctx.md() << "| | |\n|---|---|\n";
  for (size_t m = 0; m + 1 < images.size(); m += 2)
    ctx.md() << "| " << images[m] << " | " << images[m + 1] << " |\n";
  ctx.md() << "\n";
  ctx.Table({"slice", "fixed", "points", "median gain", "max gain", "gain < 10", "gain ≥ 1000",
             "FK ok", "singular", "ambiguous", "other"},
            table);
  ctx.Csv("fk_conditioning",
          {"slice", "u", "v", "error_gain_m_per_m", "position_gain_m_per_m", "fk_status"}, csv);
  ctx.Headline("median error gain " + Sig(xy_median, 3) + " m/m on the frame's z = 0 slice (" +
               Fixed(xy_refused, 1) + " % refused); centre on the z axis: " +
               Fixed(yaw_refused, 1) + " % of yaw angles refused (singular or ambiguous); " +
               Sig(us_per_sample, 2) + " µs per sample");
  ctx.Summary((us_per_sample < 1000 ? Sig(us_per_sample, 2) + " µs"
                                    : Sig(1e-3 * us_per_sample, 2) + " ms") +
                  " per sample (conditioning and a cold FK solve)",
              "median error gain " + Sig(xy_median, 3) + " m/m (z = 0 slice)");
}

}  // namespace spidarcad::app
