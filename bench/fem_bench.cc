// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
//
// FE benchmarks on a cantilever (L = 1 m, 0.1 m × 0.1 m section, clamped at x = 0, 1 kN tip
// shear) meshed with 10r × r × r cells, six tetrahedra each, linear or quadratic:
//   BM_Precompute/order/r      assembly + CHOLMOD factorisation time and memory, compliance
//                              column time, tip deflection against Timoshenko.
//   BM_ContactTick/order/r/k   one haptic tick: contact forces for k pushed nodes.
//   BM_ContactTickUpdate/...   one node leaves and re-enters contact (incremental factor
//                              update) plus the solve.
//   BM_SurfaceDisplacement/... displacement of every surface node by superposition (display).
//   BM_FullSparseSolve/...     the same contact problem as a full sparse solve per tick
//                              (re-factor with the contact nodes prescribed, then solve), and
//                              the lower bound of one back-substitution with a kept factor.
// Run e.g.: build/bench/fem_bench --benchmark_filter='Precompute|/1/12/' (see README).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <vector>

#include <benchmark/benchmark.h>

#include "spidarcad/fem/condensation.h"

namespace spidarcad::fem {
namespace {

constexpr double kLength = 1.0, kSide = 0.1, kForce = 1000.0;
constexpr int kMaxContacts = 64;
const Material kSteel{2.0e11, 0.3};

struct Model {
  TetMesh mesh;
  MaterialTable materials{kSteel};
  std::unique_ptr<BoundaryConditions> bcs;
  std::unique_ptr<StaticSolver> solver;
  std::unique_ptr<Compliance> compliance;
  double tip_ratio = 0.0;  // FE tip deflection / Timoshenko
  double build_seconds = 0.0;
};

double Timoshenko() {
  const double i = kSide * std::pow(kSide, 3) / 12.0;
  const double nu = kSteel.poisson_ratio;
  const double kappa = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu);
  return kForce * std::pow(kLength, 3) / (3.0 * kSteel.youngs_modulus * i) +
         kForce * kLength / (kappa * kSteel.Mu() * kSide * kSide);
}

Model& GetModel(int order, int r) {
  static std::map<std::pair<int, int>, std::unique_ptr<Model>> cache;
  auto& slot = cache[{order, r}];
  if (slot) return *slot;
  const auto t0 = std::chrono::steady_clock::now();
  slot = std::make_unique<Model>();
  Model& m = *slot;
  BoxMeshSettings s;
  s.upper = Eigen::Vector3d(kLength, kSide, kSide);
  s.nx = 10 * r;
  s.ny = s.nz = r;
  s.order = order;
  m.mesh = MakeBoxMesh(s);
  m.bcs = std::make_unique<BoundaryConditions>(m.mesh.num_nodes());
  FixNodesInBox(m.mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1), m.bcs.get());
  const Surface surf = ExtractSurface(m.mesh);
  AddTractionInBox(m.mesh, surf, Eigen::Vector3d(kLength - 1e-9, -1, -1), Eigen::Vector3d(2, 2, 2),
                   Eigen::Vector3d(0, 0, -kForce / (kSide * kSide)), m.bcs.get());
  m.solver = std::make_unique<StaticSolver>(m.mesh, m.materials, *m.bcs);
  // Condensed: the kMaxContacts top-face nodes nearest the middle of the top of the tip.
  std::vector<int> top = NodesInBox(m.mesh, Eigen::Vector3d(0.5, -1, kSide), Eigen::Vector3d(2, 2, 2));
  const Eigen::Vector3d centre(kLength, kSide / 2, kSide);
  std::sort(top.begin(), top.end(), [&](int a, int b) {
    return (m.mesh.nodes.row(a).transpose() - centre).norm() <
           (m.mesh.nodes.row(b).transpose() - centre).norm();
  });
  top.resize(std::min<size_t>(top.size(), kMaxContacts));
  CondensationSettings cs;
  cs.block_nodes = 32;
  m.compliance = std::make_unique<Compliance>(*m.solver, surf.nodes, top, cs);
  // Tip deflection: mean z-displacement of the end-face nodes (the baseline).
  const auto tip = NodesInBox(m.mesh, Eigen::Vector3d(kLength - 1e-9, -1, -1), Eigen::Vector3d(2, 2, 2));
  const StaticSolution sol = m.solver->Solve();
  double sum = 0.0;
  for (int v : tip) sum += sol.displacement(3 * v + 2);
  m.tip_ratio = -sum / tip.size() / Timoshenko();
  m.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return m;
}

void BM_Precompute(benchmark::State& state) {
  const int order = static_cast<int>(state.range(0)), r = static_cast<int>(state.range(1));
  Model* m = nullptr;
  for (auto _ : state) m = &GetModel(order, r);
  const FactorStats& st = m->solver->stats();
  state.counters["tets"] = m->mesh.num_elements();
  state.counters["dofs"] = st.num_free;
  state.counters["assembly_s"] = st.assembly_seconds;
  state.counters["factor_s"] = st.factor_seconds;
  state.counters["factor_nnz"] = st.factor_nonzeros;
  state.counters["cholmod_peak_MB"] = st.factor_peak_bytes / 1e6;
  state.counters["column_ms_per_node"] =
      1e3 * m->compliance->compute_seconds() / m->compliance->condensed_nodes().size();
  state.counters["G_MB_per_node"] = 24.0 * m->compliance->output_nodes().size() * 3 / 1e6;
  state.counters["surface_nodes"] = m->compliance->output_nodes().size();
  state.counters["tip_over_timoshenko"] = m->tip_ratio;
  state.counters["tip_error_pct"] = 100.0 * std::abs(m->tip_ratio - 1.0);
}

// Targets: push the contact nodes 0.1 mm down from where the baseline put them.
std::vector<double> Targets(const Model& m, const ContactSolver& solver) {
  std::vector<double> t(3 * solver.num_contacts());
  for (int s = 0; s < solver.num_contacts(); ++s) {
    const int row = 3 * m.compliance->OutputIndexOfCondensed(solver.contact(s));
    for (int i = 0; i < 3; ++i) t[3 * s + i] = m.compliance->baseline()(row + i) - (i == 2 ? 1e-4 : 0.0);
  }
  return t;
}

void SetUpContacts(const Model& m, int k, ContactSolver* solver) {
  for (int b = 0; b < static_cast<int>(m.compliance->condensed_nodes().size()) && solver->num_contacts() < k; ++b)
    solver->Add(b);
}

void BM_ContactTick(benchmark::State& state) {
  const Model& m = GetModel(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const int k = static_cast<int>(state.range(2));
  ContactSolver solver(*m.compliance, kMaxContacts);
  SetUpContacts(m, k, &solver);
  const auto target = Targets(m, solver);
  std::vector<double> f(target.size());
  for (auto _ : state) {
    solver.Solve(target.data(), f.data());
    benchmark::DoNotOptimize(f.data());
  }
  state.counters["k"] = solver.num_contacts();
  state.counters["tets"] = m.mesh.num_elements();
}

void BM_ContactTickUpdate(benchmark::State& state) {
  const Model& m = GetModel(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const int k = static_cast<int>(state.range(2));
  ContactSolver solver(*m.compliance, kMaxContacts);
  SetUpContacts(m, k, &solver);
  const auto target = Targets(m, solver);
  std::vector<double> f(target.size());
  int next = 0;
  for (auto _ : state) {
    // The node in slot `next` leaves contact and enters again (as the last slot).
    const int b = solver.contact(next % solver.num_contacts());
    solver.Remove(b);
    solver.Add(b);
    solver.Solve(target.data(), f.data());
    benchmark::DoNotOptimize(f.data());
    ++next;
  }
  state.counters["k"] = solver.num_contacts();
}

void BM_SurfaceDisplacement(benchmark::State& state) {
  const Model& m = GetModel(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const int k = static_cast<int>(state.range(2));
  ContactSolver solver(*m.compliance, kMaxContacts);
  SetUpContacts(m, k, &solver);
  const auto target = Targets(m, solver);
  std::vector<double> f(target.size());
  solver.Solve(target.data(), f.data());
  Eigen::VectorXd u(3 * m.compliance->output_nodes().size());
  for (auto _ : state) {
    solver.OutputDisplacement(f.data(), &u);
    benchmark::DoNotOptimize(u.data());
  }
  state.counters["surface_nodes"] = m.compliance->output_nodes().size();
}

void BM_FullSparseSolve(benchmark::State& state) {
  const Model& m = GetModel(static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
  const int k = static_cast<int>(state.range(2));
  ContactSolver solver(*m.compliance, kMaxContacts);
  SetUpContacts(m, k, &solver);
  const auto target = Targets(m, solver);
  std::vector<double> f(target.size());
  // Condensed tick, timed here too for the ratio in the same run.
  const int reps = 2000;
  auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < reps; ++i) solver.Solve(target.data(), f.data());
  const double tick_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / reps;
  // Lower bound: one back-substitution with the kept factor.
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Ones(m.solver->num_free(), 1), x;
  t0 = std::chrono::steady_clock::now();
  m.solver->SolveFree(rhs, &x);
  const double backsub_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  double max_force_diff = 0.0;
  for (auto _ : state) {
    BoundaryConditions bcs = *m.bcs;
    for (int s = 0; s < solver.num_contacts(); ++s) {
      const int node = m.compliance->condensed_nodes()[solver.contact(s)];
      bcs.PrescribeNode(node, Eigen::Vector3d(target[3 * s], target[3 * s + 1], target[3 * s + 2]));
    }
    StaticSolver full(m.mesh, m.materials, bcs);
    const StaticSolution sol = full.Solve();
    for (int s = 0; s < solver.num_contacts(); ++s) {
      const int node = m.compliance->condensed_nodes()[solver.contact(s)];
      for (int i = 0; i < 3; ++i)
        max_force_diff = std::max(max_force_diff, std::abs(sol.reaction(3 * node + i) - f[3 * s + i]));
    }
  }
  state.counters["condensed_tick_us"] = 1e6 * tick_s;
  state.counters["backsub_ms"] = 1e3 * backsub_s;
  state.counters["backsub_over_tick"] = backsub_s / tick_s;
  state.counters["max_force_diff_N"] = max_force_diff;
  state.counters["k"] = solver.num_contacts();
}

void PrecomputeArgs(benchmark::internal::Benchmark* b) {
  for (int r : {1, 2, 4, 8, 12}) b->Args({1, r});
  for (int r : {1, 2, 4, 6}) b->Args({2, r});
}
void TickArgs(benchmark::internal::Benchmark* b) {
  for (auto [order, r] : {std::pair{1, 4}, std::pair{1, 12}, std::pair{2, 4}, std::pair{2, 6}})
    for (int k : {1, 4, 16, 64}) b->Args({order, r, k});
}

BENCHMARK(BM_Precompute)->Apply(PrecomputeArgs)->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK(BM_ContactTick)->Apply(TickArgs)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ContactTickUpdate)->Apply(TickArgs)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_SurfaceDisplacement)->Apply(TickArgs)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FullSparseSolve)
    ->Args({1, 4, 16})->Args({1, 12, 16})->Args({2, 4, 16})->Args({2, 6, 16})
    ->Iterations(1)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace spidarcad::fem

BENCHMARK_MAIN();
