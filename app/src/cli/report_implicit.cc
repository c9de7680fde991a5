// Report section: implicit evaluation, time of a point query (value and gradient) against the
// tree size, on the full tape and on the per-cell pruned tapes (CellSpecializedSolid).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "cli/report_sections.h"
#include "spidarcad/modeling/cell_specialized_solid.h"
#include "spidarcad/modeling/implicit_evaluator.h"

namespace spidarcad::app {

namespace {

using namespace spidarcad::modeling;
using Vec = Eigen::Vector3d;

// A part of `lumps` primitives (spheres, boxes, cylinders, tori in turn, rotated and placed at
// random in a 20 cm cube) in a union, minus a hole through every fourth one. Deterministic.
ImplicitNode RandomPart(int lumps) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(-0.1, 0.1), s(0.01, 0.025), angle(-45, 45);
  ImplicitNode body(UnionParams{});
  ImplicitNode holes(UnionParams{});
  for (int i = 0; i < lumps; ++i) {
    NodeParams p;
    switch (i % 4) {
      case 0:
        p = SphereParams{s(rng)};
        break;
      case 1:
        p = BoxParams{Vec(s(rng), s(rng), s(rng)) * 2};
        break;
      case 2:
        p = CylinderParams{s(rng), 2 * s(rng)};
        break;
      default:
        p = TorusParams{s(rng), 0.006};
        break;
    }
    const Vec at(u(rng), u(rng), u(rng));
    body.children.push_back(ImplicitNode(
        TranslateParams{at},
        {ImplicitNode(RotateParams{Vec(u(rng), u(rng), 1.0), angle(rng)}, {ImplicitNode(p)})}));
    if (i % 4 == 1) {
      holes.children.push_back(
          ImplicitNode(TranslateParams{at}, {ImplicitNode(CylinderParams{0.004, 0.2})}));
    }
  }
  if (holes.children.empty()) return body;
  return ImplicitNode(DifferenceParams{}, {body, holes});
}

}  // namespace

void ReportImplicit(ReportContext& ctx) {
  const std::vector<int> sizes =
      ctx.Pick(std::vector<int>{1, 4, 16, 64}, {1, 2, 4, 8, 16, 32, 64, 128, 256});
  const int queries = ctx.Pick(20000, 100000);
  const Eigen::AlignedBox3d region(Vec::Constant(-0.13), Vec::Constant(0.13));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.13, 0.13);
  std::vector<Vec> points(queries);
  for (Vec& p : points) p = Vec(u(rng), u(rng), u(rng));
  struct Row {
    int lumps, nodes, instructions;
    double full_ns, pruned_ns, mean_pruned_instructions, build_s, max_difference;
  };
  std::vector<Row> rows;
  for (size_t k = 0; k < sizes.size(); ++k) {
    const ImplicitNode tree = RandomPart(sizes[k]);
    auto solid = std::make_shared<const CompiledSolid>(CompiledSolid::Compile(tree));
    CellSpecializationSettings settings;
    settings.cell_size = 0.01;
    const CellSpecializedSolid cells(solid, region, settings);
    std::vector<double> full(queries), pruned(queries);
    Vec g;
    double sink = 0;
    const double full_s = MedianSeconds(5, [&] {
      for (int i = 0; i < queries; ++i) full[i] = solid->ValueAndGradient(points[i], &g);
      sink += g.x();
    });
    const double pruned_s = MedianSeconds(5, [&] {
      for (int i = 0; i < queries; ++i) pruned[i] = cells.ValueAndGradient(points[i], &g);
      sink += g.x();
    });
    double difference = 0;
    for (int i = 0; i < queries; ++i)
      difference = std::max(difference, std::abs(full[i] - pruned[i]));
    rows.push_back({sizes[k], CountNodes(tree), solid->instruction_count(), 1e9 * full_s / queries,
                    1e9 * pruned_s / queries, cells.stats().mean_instructions,
                    cells.stats().build_seconds, difference + 0 * sink});
    ctx.Progress((k + 1.0) / sizes.size());
  }
  ctx.md() << "CompiledSolid::ValueAndGradient (the haptic proxy's per-tick query) on parts of "
              "growing size: n primitives (spheres, boxes, cylinders, tori, each rotated and "
              "placed at random in a 20 cm cube) in a union, minus a bore through every fourth. "
           << queries
           << " random points in a 26 cm cube; median of 5 passes. Pruned: CellSpecializedSolid "
              "with 1 cm cells (each cell's tape keeps only the primitives its interval bounds "
              "cannot rule out); its values must equal the full tape's bit for bit (difference "
              "column).\n";
  std::vector<std::vector<std::string>> table, csv;
  for (const Row& r : rows) {
    table.push_back({std::to_string(r.lumps), std::to_string(r.nodes),
                     std::to_string(r.instructions), Sig(r.full_ns), Sig(r.pruned_ns),
                     Sig(r.mean_pruned_instructions), Sig(r.build_s, 2), Sig(r.max_difference, 2)});
    csv.push_back({std::to_string(r.lumps), std::to_string(r.nodes), std::to_string(r.instructions),
                   Sig(r.full_ns, 6), Sig(r.pruned_ns, 6), Sig(r.mean_pruned_instructions, 6),
                   Sig(r.build_s, 6), Sig(r.max_difference, 6)});
  }
  ctx.Table(
      {"primitives", "tree nodes", "tape instructions", "full ns per query", "pruned ns per query",
       "pruned instructions (mean)", "pruning build s", "max |full − pruned|"},
      table);
  ctx.Csv("implicit",
          {"primitives", "nodes", "instructions", "full_ns", "pruned_ns",
           "pruned_instructions_mean", "build_s", "max_difference"},
          csv);
  Chart chart{"Implicit evaluation: time against tree size",
              "tree nodes",
              "time per value+gradient [ns]",
              true,
              true,
              {}};
  ChartSeries full{"full tape", {}, {}, 0, true, false, 0},
      pruned{"pruned tapes (1 cm cells)", {}, {}, 1, true, false, 0};
  for (const Row& r : rows) {
    full.x.push_back(r.nodes);
    full.y.push_back(r.full_ns);
    pruned.x.push_back(r.nodes);
    pruned.y.push_back(r.pruned_ns);
  }
  chart.series = {full, pruned};
  ctx.Figure("implicit_time_vs_size", {chart},
             "Full tape: time grows with the tree; pruned tapes: with what is near the query.", 900,
             560);
  const Row& big = rows.back();
  ctx.Headline(std::to_string(big.nodes) + "-node tree: " + Sig(big.full_ns, 3) + " ns full, " +
               Sig(big.pruned_ns, 3) + " ns pruned per value+gradient; 1 primitive: " +
               Sig(rows.front().full_ns, 2) + " ns");
  ctx.Summary(Sig(big.pruned_ns, 3) + " ns per value+gradient (" + std::to_string(big.nodes) +
                  "-node tree, pruned)",
              "pruned against full tape: " + Sig(big.max_difference, 2) + " m max difference");
}

}  // namespace spidarcad::app
