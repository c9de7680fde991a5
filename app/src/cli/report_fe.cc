// Report section: finite elements on a cantilever with a closed-form tip deflection:
// precompute and tick time against tip error for P1 and P2 over resolutions, float against
// double columns, the borrowed-column force error against distance, condensed against full
// solve.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cli/report_sections.h"
#include "spidarcad/fem/column_cache.h"
#include "spidarcad/fem/condensation.h"
#include "spidarcad/workloads/fe.h"

namespace spidarcad::app {

namespace {

using namespace spidarcad::fem;

// The cantilever of workloads/fe.h (1 m steel beam, 0.1 m square section, 1 kN tip shear).
using Model = workloads::CantileverModel;
constexpr int kCondensed = 64;  // compliance nodes: top-face nodes nearest the tip
constexpr int kContacts = 16;   // contact nodes of a tick

std::unique_ptr<Model> BuildModel(int order, int r) {
  return workloads::BuildCantilever(order, r, kCondensed);
}

// |FE tip deflection / Timoshenko − 1|.
double TipError(const Model& m) { return std::abs(m.tip_ratio - 1.0); }

// Targets 0.1 mm below the baseline position of each contact node.
std::vector<double> PushTargets(const Compliance& c, const ContactSolver& solver) {
  std::vector<double> t(3 * solver.num_contacts());
  for (int s = 0; s < solver.num_contacts(); ++s) {
    const int row = 3 * c.OutputIndexOfCondensed(solver.contact(s));
    for (int i = 0; i < 3; ++i) t[3 * s + i] = c.baseline()(row + i) - (i == 2 ? 1e-4 : 0.0);
  }
  return t;
}

// Median time of one ContactSolver::Solve with k contact nodes, µs.
double TickMicros(const Model& m, int k, int calls) {
  ContactSolver solver(*m.compliance, kContacts);
  for (int b = 0;
       b < static_cast<int>(m.compliance->condensed_nodes().size()) && solver.num_contacts() < k;
       ++b) {
    solver.Add(b);
  }
  const auto target = PushTargets(*m.compliance, solver);
  std::vector<double> f(target.size());
  return 1e6 *
         MedianSeconds(7,
                       [&] {
                         for (int i = 0; i < calls; ++i) solver.Solve(target.data(), f.data());
                       }) /
         calls;
}

// Copies the eager compliance columns into a cache (no solves).
void Fill(const Compliance& c, ColumnCache* cache) {
  ColumnSet set;
  set.output_nodes = c.output_nodes();
  set.nodes = c.condensed_nodes();
  set.baseline = c.baseline();
  set.columns = c.matrix();
  cache->Import(set);
}

struct PrecisionRow {
  std::string name;
  double force_error = NAN;  // relative to double, k = 16
  double tick_us = NAN;
  double kb_per_node = NAN;
};

// Contact forces and tick time on cached columns of the given precision.
std::vector<double> CachedForces(const Model& m, ColumnPrecision precision, double* tick_us,
                                 double* kb_per_node) {
  ColumnCacheSettings settings;
  settings.start_worker = false;
  settings.precision = precision;
  ColumnCache cache(*m.solver, m.mesh.nodes, m.compliance->output_nodes(),
                    m.compliance->condensed_nodes(), settings);
  Fill(*m.compliance, &cache);
  CachedContactSolver solver(&cache, kContacts);
  for (int b = 0; b < cache.num_candidates() && solver.num_contacts() < kContacts; ++b) {
    solver.Add(b);
  }
  std::vector<double> target(3 * solver.num_contacts()), f(target.size());
  for (int s = 0; s < solver.num_contacts(); ++s) {
    for (int i = 0; i < 3; ++i) {
      target[3 * s + i] =
          cache.baseline()(3 * cache.OutputIndexOfCandidate(solver.contact(s)) + i) -
          (i == 2 ? 1e-4 : 0.0);
    }
  }
  constexpr int kCalls = 2000;
  *tick_us = 1e6 *
             MedianSeconds(7,
                           [&] {
                             for (int i = 0; i < kCalls; ++i) solver.Solve(target.data(), f.data());
                           }) /
             kCalls;
  *kb_per_node = cache.BytesPerNode() / 1e3;
  return f;
}

struct FullRow {
  double full_ms = NAN, condensed_us = NAN, force_diff = NAN, force_norm = NAN;
};

// The same k = 16 contact problem as a full sparse solve (re-factor with the contact nodes
// prescribed, then solve) against the condensed tick.
FullRow CondensedAgainstFull(const Model& m, int repeats) {
  FullRow row;
  ContactSolver solver(*m.compliance, kContacts);
  for (int b = 0; solver.num_contacts() < kContacts; ++b) solver.Add(b);
  const auto target = PushTargets(*m.compliance, solver);
  std::vector<double> f(target.size());
  constexpr int kCalls = 2000;
  row.condensed_us = 1e6 *
                     MedianSeconds(7,
                                   [&] {
                                     for (int i = 0; i < kCalls; ++i)
                                       solver.Solve(target.data(), f.data());
                                   }) /
                     kCalls;
  double diff = 0, norm = 0;
  row.full_ms = 1e3 * MedianSeconds(repeats, [&] {
                  BoundaryConditions bcs = *m.bcs;
                  for (int s = 0; s < solver.num_contacts(); ++s) {
                    const int node = m.compliance->condensed_nodes()[solver.contact(s)];
                    bcs.PrescribeNode(
                        node, Eigen::Vector3d(target[3 * s], target[3 * s + 1], target[3 * s + 2]));
                  }
                  StaticSolver full(m.mesh, m.materials, bcs);
                  const StaticSolution solution = full.Solve();
                  diff = norm = 0;
                  for (int s = 0; s < solver.num_contacts(); ++s) {
                    const int node = m.compliance->condensed_nodes()[solver.contact(s)];
                    for (int i = 0; i < 3; ++i) {
                      diff =
                          std::max(diff, std::abs(solution.reaction(3 * node + i) - f[3 * s + i]));
                      norm = std::max(norm, std::abs(f[3 * s + i]));
                    }
                  }
                });
  row.force_diff = diff;
  row.force_norm = norm;
  return row;
}

}  // namespace

void ReportFe(ReportContext& ctx) {
  const std::vector<int> p1 =
      ctx.Pick(std::vector<int>{2, 3, 4, 6}, std::vector<int>{2, 3, 4, 6, 8, 10, 12});
  const std::vector<int> p2 = ctx.Pick(std::vector<int>{2, 3, 4}, std::vector<int>{2, 3, 4, 6});
  const double steps = p1.size() + p2.size() + 3;
  int done = 0;
  std::map<std::pair<int, int>, std::unique_ptr<Model>> models;
  struct Row {
    int order, r, tets, dofs;
    double precompute_s, tick_us, tip_error;
  };
  std::vector<Row> rows;
  for (int order : {1, 2}) {
    for (int r : order == 1 ? p1 : p2) {
      auto m = BuildModel(order, r);
      rows.push_back({order, r, m->mesh.num_elements(), m->solver->num_free(),
                      m->precompute_seconds, TickMicros(*m, kContacts, 2000), TipError(*m)});
      models[{order, r}] = std::move(m);
      ctx.Progress(++done / steps);
    }
  }
  ctx.md() << "A cantilever (L = 1 m, 0.1 × 0.1 m section, steel, clamped at x = 0, 1 kN tip "
              "shear) meshed with 10r × r × r cells of six tetrahedra, linear (P1) or quadratic "
              "(P2). Tip error: mean end-face deflection against the Timoshenko closed form ("
           << Sig(workloads::CantileverTimoshenkoTip() * 1e3, 4)
           << " mm). Precompute: mesh, assembly, CHOLMOD factorisation and the compliance "
              "columns of the 64 top-face nodes nearest the tip (wall clock). Tick: one "
              "ContactSolver::Solve with 16 contact nodes pushed 0.1 mm (median).\n";
  std::vector<std::vector<std::string>> table, csv;
  for (const Row& r : rows) {
    table.push_back({"P" + std::to_string(r.order), std::to_string(r.r), std::to_string(r.tets),
                     std::to_string(r.dofs), Sig(r.precompute_s), Sig(r.tick_us),
                     Sig(100 * r.tip_error)});
    csv.push_back({std::to_string(r.order), std::to_string(r.r), std::to_string(r.tets),
                   std::to_string(r.dofs), Sig(r.precompute_s, 6), Sig(r.tick_us, 6),
                   Sig(r.tip_error, 6)});
  }
  ctx.Table(
      {"element", "r", "tets", "free dofs", "precompute s", "tick µs (k = 16)", "tip error %"},
      table);
  ctx.Csv("fe_resolution",
          {"order", "r", "tets", "free_dofs", "precompute_s", "tick_us", "tip_error"}, csv);
  Chart pre{"FE: precompute time against tip error",
            "precompute time [s]",
            "tip deflection error (Timoshenko)",
            true,
            true,
            {}};
  Chart tick{"FE: tick time against tip error",
             "tick time, k = 16 [us]",
             "tip deflection error (Timoshenko)",
             true,
             true,
             {}};
  for (int order : {1, 2}) {
    ChartSeries a{"P" + std::to_string(order), {}, {}, order - 1, true, false, 0};
    ChartSeries b = a;
    for (const Row& r : rows) {
      if (r.order != order) continue;
      a.x.push_back(r.precompute_s);
      a.y.push_back(r.tip_error);
      b.x.push_back(r.tick_us);
      b.y.push_back(r.tip_error);
    }
    pre.series.push_back(a);
    tick.series.push_back(b);
    // Markers over the lines.
    ChartSeries am = a, bm = b;
    am.lines = bm.lines = false;
    am.label = bm.label = "P" + std::to_string(order) +
                          " (r = " + std::to_string((order == 1 ? p1 : p2).front()) + "..." +
                          std::to_string((order == 1 ? p1 : p2).back()) + ")";
    am.marker = bm.marker = order - 1;
    pre.series.push_back(am);
    tick.series.push_back(bm);
  }
  ctx.Figure("fe_time_vs_tip_error", {pre, tick},
             "Each point one resolution r; finer meshes lie lower (smaller error) and to the "
             "right (slower).");

  // Float against double columns.
  const Model& mid = *models.at({1, 4});
  const Model& quad = *models.at({2, 3});
  std::vector<std::vector<std::string>> precision_rows;
  for (const Model* m : {&mid, &quad}) {
    double tick_d, kb_d, tick_f, kb_f;
    const auto fd = CachedForces(*m, ColumnPrecision::kDouble, &tick_d, &kb_d);
    const auto ff = CachedForces(*m, ColumnPrecision::kFloat, &tick_f, &kb_f);
    const Eigen::Map<const Eigen::VectorXd> a(fd.data(), fd.size()), b(ff.data(), ff.size());
    const std::string name = "P" + std::to_string(m->order) + ", r = " + std::to_string(m->r);
    precision_rows.push_back({name, "double", "0", Sig(tick_d), Sig(kb_d)});
    precision_rows.push_back(
        {name, "float", Sig((a - b).norm() / a.norm(), 2), Sig(tick_f), Sig(kb_f)});
  }
  ctx.Progress(++done / steps);
  ctx.md() << "Columns kept as float against double (the column cache, 16 contact nodes): "
              "contact force error relative to the double result, tick time, memory per node.\n";
  ctx.Table({"model", "columns", "force error", "tick µs", "kB per node"}, precision_rows);

  // Borrowed columns.
  const std::vector<double> e1 = workloads::BorrowedColumnErrors(mid);
  const Model& quad_even = *models.at({2, 2});
  const std::vector<double> e2 = workloads::BorrowedColumnErrors(quad_even);
  ctx.Progress(++done / steps);
  Chart borrowed{"FE: borrowed-column force error against distance",
                 "distance of the borrowed node [cells]",
                 "relative force error",
                 false,
                 true,
                 {}};
  ChartSeries s1{"P1, r = 4 (cell 25 mm)", {1, 2, 3, 4}, e1, 0, true, false, 0};
  ChartSeries s2{"P2, r = 2 (cell 50 mm)", {1, 2, 3, 4}, e2, 1, true, false, 0};
  borrowed.series = {s1, s2};
  ctx.md() << "A node's column missing from the cache is borrowed from a nearby ready node: "
              "force error of a single 0.1 mm push at mid-span when the column of the node 1–4 "
              "cells further along the beam stands in.\n";
  ctx.Table({"model", "1 cell", "2 cells", "3 cells", "4 cells"},
            {{"P1, r = 4", Sig(e1[0], 2), Sig(e1[1], 2), Sig(e1[2], 2), Sig(e1[3], 2)},
             {"P2, r = 2", Sig(e2[0], 2), Sig(e2[1], 2), Sig(e2[2], 2), Sig(e2[3], 2)}});

  // Condensed against full solve.
  std::vector<std::vector<std::string>> full_rows;
  FullRow headline_full;
  for (const Model* m : {&mid, &quad}) {
    const FullRow f = CondensedAgainstFull(*m, ctx.Pick(2, 5));
    if (m == &mid) headline_full = f;
    full_rows.push_back({"P" + std::to_string(m->order) + ", r = " + std::to_string(m->r),
                         Sig(f.condensed_us), Sig(f.full_ms), Sig(1e3 * f.full_ms / f.condensed_us),
                         Sig(f.force_diff / f.force_norm, 2)});
  }
  ctx.Progress(++done / steps);
  ctx.Figure("fe_borrowed_columns", {borrowed},
             "Relative contact force error when a neighbour's column stands in, against the "
             "neighbour's distance in cells.",
             800, 520);
  ctx.md() << "The condensed tick against the same 16-node contact problem solved in full "
              "(re-factor with the contact nodes prescribed, then solve): time and the largest "
              "force difference relative to the largest force.\n";
  ctx.Table({"model", "condensed tick µs", "full solve ms", "full / condensed", "force difference"},
            full_rows);
  const Row* best_p2 = nullptr;
  for (const Row& r : rows) {
    if (r.order == 2) best_p2 = &r;
  }
  const Row* p1_4 = nullptr;
  for (const Row& r : rows) {
    if (r.order == 1 && r.r == 4) p1_4 = &r;
  }
  ctx.Headline("tick " + Sig(p1_4->tick_us, 2) + " µs (P1, k = 16); tip error P1 r = 4 " +
               Sig(100 * p1_4->tip_error, 2) + " %, P2 r = " + std::to_string(best_p2->r) + " " +
               Sig(100 * best_p2->tip_error, 2) + " % after " + Sig(best_p2->precompute_s, 2) +
               " s precompute; condensed " +
               Sig(1e3 * headline_full.full_ms / headline_full.condensed_us, 2) +
               "× faster than a full solve");
  ctx.Summary(Sig(p1_4->tick_us, 2) + " µs per tick (P1, k = 16)",
              Sig(100 * best_p2->tip_error, 2) +
                  " % tip error (P2, r = " + std::to_string(best_p2->r) + ")");
}

}  // namespace spidarcad::app
