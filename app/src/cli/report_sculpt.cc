// Report section: sculpting, stroke update time against touched vertices and the volume
// error with and without volume conservation.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <vector>

#include "cli/report_sections.h"
#include "spidarcad/modeling/sculpt.h"
#include "spidarcad/workloads/sculpt.h"

namespace spidarcad::app {

namespace {

using namespace spidarcad::modeling;

}  // namespace

void ReportSculpt(ReportContext& ctx) {
  const int subdivisions = ctx.Pick(6, 7);
  const double sphere_radius = 0.1;
  SculptMesh sculpt(IcosphereMesh(sphere_radius, subdivisions), 0.005);
  // The grab point: the top vertex, the grip's z along its normal.
  int top = 0;
  for (int v = 0; v < sculpt.vertex_count(); ++v) {
    if (sculpt.positions()[v].z() > sculpt.positions()[top].z()) top = v;
  }
  Eigen::Isometry3d X0 = Eigen::Isometry3d::Identity();
  X0.linear() = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), sculpt.normals()[top])
                    .toRotationMatrix();
  X0.translation() = sculpt.positions()[top];
  const std::vector<double> radii = ctx.Pick(std::vector<double>{0.005, 0.01, 0.02, 0.04},
                                             {0.005, 0.01, 0.015, 0.02, 0.03, 0.04, 0.06});
  const SculptTool tools[] = {SculptTool::kGrab, SculptTool::kPushPull, SculptTool::kTwist};
  struct Row {
    std::string tool;
    bool conserve;
    double radius;
    int touched;
    double update_us, volume_error;
  };
  std::vector<Row> rows;
  const int updates = ctx.Pick(20, 60);
  const double total = 3.0 * radii.size() * 2;
  int done = 0;
  for (SculptTool tool : tools) {
    for (bool conserve : {false, true}) {
      for (double radius : radii) {
        SculptToolSettings settings;
        settings.tool = tool;
        settings.radius = radius;
        settings.grasp_controls_strength = false;
        settings.conserve_volume = conserve;
        const Eigen::Isometry3d full = workloads::SculptTargetPose(tool, X0, radius, 1.0),
                                half = workloads::SculptTargetPose(tool, X0, radius, 0.5);
        sculpt.BeginStroke(settings, X0, 0.0);
        std::vector<double> times;
        for (int i = 0; i < updates; ++i) {
          const auto start = std::chrono::steady_clock::now();
          sculpt.UpdateStroke(i % 2 ? half : full, 0.0);
          times.push_back(SecondsSince(start));
        }
        sculpt.UpdateStroke(full, 0.0);
        const StrokeStats stats = sculpt.stroke_stats();
        // The volume recomputed from scratch, against the stroke-start volume.
        const double error = sculpt.ComputeVolume() / stats.start_volume - 1.0;
        rows.push_back({SculptToolName(tool), conserve, radius, stats.affected_vertices,
                        1e6 * Median(times), error});
        sculpt.CancelStroke();
        ctx.Progress(++done / total);
      }
    }
  }
  ctx.md() << "SculptMesh::UpdateStroke (one stroke step: move the vertices within the radius, "
              "refresh their normals, correct the volume when asked) on an icosphere of "
           << sculpt.vertex_count()
           << " vertices (radius 10 cm), the tool at the top vertex, for falloff radii "
              "from 5 mm up; median of "
           << updates
           << " updates alternating between half and full stroke. Volume error: the enclosed "
              "volume recomputed from scratch after the full stroke against the volume at the "
              "stroke start (conservation keeps it; without it a grab adds material).\n";
  std::vector<std::vector<std::string>> table, csv;
  for (const Row& r : rows) {
    table.push_back({r.tool, r.conserve ? "on" : "off", Fixed(1e3 * r.radius, 0),
                     std::to_string(r.touched), Sig(r.update_us), Sig(100 * r.volume_error, 2)});
    csv.push_back({r.tool, r.conserve ? "1" : "0", Sig(r.radius, 6), std::to_string(r.touched),
                   Sig(r.update_us, 6), Sig(r.volume_error, 6)});
  }
  ctx.Table(
      {"tool", "conserve volume", "radius mm", "touched vertices", "update µs", "volume error %"},
      table);
  ctx.Csv("sculpt", {"tool", "conserve", "radius_m", "touched", "update_us", "volume_error"}, csv);
  Chart time{"Sculpting: update time against touched vertices",
             "touched vertices",
             "update time [us]",
             true,
             true,
             {}};
  Chart volume{"Sculpting: volume error against touched vertices",
               "touched vertices",
               "|volume error| (floor 1e-16)",
               true,
               true,
               {}};
  int colour = 0;
  for (SculptTool tool : tools) {
    for (bool conserve : {false, true}) {
      ChartSeries t{std::string(SculptToolName(tool)) + (conserve ? ", conserved" : ""),
                    {},
                    {},
                    colour,
                    true,
                    conserve,
                    0};
      ChartSeries v = t;
      for (const Row& r : rows) {
        if (r.tool != SculptToolName(tool) || r.conserve != conserve) continue;
        t.x.push_back(r.touched);
        t.y.push_back(r.update_us);
        v.x.push_back(r.touched);
        v.y.push_back(std::max(1e-16, std::abs(r.volume_error)));
      }
      time.series.push_back(t);
      volume.series.push_back(v);
    }
    ++colour;
  }
  ctx.Figure("sculpt_time_vs_touched", {time, volume},
             "Solid: volume conservation off; dashed: on. One point per falloff radius.");
  auto find = [&](bool conserve) {
    for (const Row& r : rows) {
      if (r.tool == SculptToolName(SculptTool::kGrab) && r.conserve == conserve &&
          r.radius == 0.02) {
        return r;
      }
    }
    return rows.front();
  };
  const Row off = find(false), on = find(true);
  ctx.Headline("grab, 2 cm radius (" + std::to_string(off.touched) +
               " vertices): " + Sig(off.update_us, 2) + " µs per update, volume error " +
               Sig(100 * off.volume_error, 2) + " %; with conservation " + Sig(on.update_us, 2) +
               " µs, " + Sig(100 * on.volume_error, 2) + " %");
  ctx.Summary(Sig(on.update_us, 2) + " µs per update (" + std::to_string(off.touched) +
                  " vertices, conserving)",
              Sig(100 * on.volume_error, 2) + " % volume error (" + Sig(100 * off.volume_error, 2) +
                  " % without conservation)");
}

}  // namespace spidarcad::app
