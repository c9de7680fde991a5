// Tension distribution and workspace LP timings, and the achieved-wrench error of the default
// weights (S0 = S1 = 1/d²) against weights of order 1.
//   build-*/bench/tension_bench                 # report + all benchmarks
//   build-*/bench/tension_bench --benchmark_filter=Solve
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "bench_cli.h"
#include "spidarcad/haptics/tension.h"
#include "spidarcad/haptics/workspace.h"
#include "spidarcad/workloads/tension.h"

namespace spidarcad::haptics {
namespace {

using Request = workloads::TensionRequest;

const SpidarGeometry kGeometry;

// Independent random poses (cold-start workload); `scale` 1: displayable, 50: saturating.
std::vector<Request> RandomRequests(int count, double scale, unsigned seed) {
  return workloads::RandomTensionRequests(kGeometry, count, scale, seed);
}

// A smooth 1 kHz trajectory (warm-start workload).
std::vector<Request> Trajectory(int count, double scale) {
  return workloads::TrajectoryTensionRequests(kGeometry, count, scale);
}

void RunSolves(benchmark::State& state, const std::vector<Request>& requests, bool warm) {
  TensionSolver solver;
  size_t k = 0;
  long iterations = 0, solves = 0, saturated = 0;
  for (auto _ : state) {
    const Request& r = requests[k];
    if (!warm) solver.Reset();
    const TensionResult result = solver.Solve(r.A, r.q);
    benchmark::DoNotOptimize(result.tau);
    iterations += result.iterations;
    saturated += result.status == TensionStatus::kSaturated;
    ++solves;
    if (++k == requests.size()) k = 0;
  }
  state.counters["active_set_changes"] = static_cast<double>(iterations) / solves;
  state.counters["saturated_fraction"] = static_cast<double>(saturated) / solves;
}

void BM_WrenchMatrix(benchmark::State& state) {
  GripPose pose = GripPose::FromFrame(
      Eigen::Vector3d(0.02, -0.03, 0.05),
      Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix(), 1.4, kGeometry.d);
  for (auto _ : state) {
    pose.p0.x() += 1e-12;
    benchmark::DoNotOptimize(WrenchMatrix(kGeometry, pose));
  }
}
BENCHMARK(BM_WrenchMatrix);

// Force-closure margin of a pose (SVD of the scaled 7 by 8 wrench matrix), as
// `spidarcad tension --lost` prints it.
void BM_ForceClosure(benchmark::State& state) {
  const std::vector<Request> requests = RandomRequests(256, 1.0, 7);
  std::size_t k = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ForceClosureAt(requests[k].A, kGeometry.d));
    k = (k + 1) % requests.size();
  }
}
BENCHMARK(BM_ForceClosure);

void BM_SolveColdFeasible(benchmark::State& state) {
  static const auto requests = RandomRequests(512, 1.0, 1);
  RunSolves(state, requests, false);
}
BENCHMARK(BM_SolveColdFeasible);

void BM_SolveColdSaturated(benchmark::State& state) {
  static const auto requests = RandomRequests(512, 50.0, 2);
  RunSolves(state, requests, false);
}
BENCHMARK(BM_SolveColdSaturated);

void BM_SolveColdTrajectoryFeasible(benchmark::State& state) {
  static const auto requests = Trajectory(5000, 1.0);
  RunSolves(state, requests, false);
}
BENCHMARK(BM_SolveColdTrajectoryFeasible);

void BM_SolveWarmTrajectoryFeasible(benchmark::State& state) {
  static const auto requests = Trajectory(5000, 1.0);
  RunSolves(state, requests, true);
}
BENCHMARK(BM_SolveWarmTrajectoryFeasible);

void BM_SolveColdTrajectorySaturated(benchmark::State& state) {
  static const auto requests = Trajectory(5000, 20.0);
  RunSolves(state, requests, false);
}
BENCHMARK(BM_SolveColdTrajectorySaturated);

void BM_SolveWarmTrajectorySaturated(benchmark::State& state) {
  static const auto requests = Trajectory(5000, 20.0);
  RunSolves(state, requests, true);
}
BENCHMARK(BM_SolveWarmTrajectorySaturated);

void BM_MaxWrenchAlong(benchmark::State& state) {
  static const auto requests = RandomRequests(512, 1.0, 3);
  Vector7d e = Vector7d::Zero();
  e(0) = -1;
  size_t k = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(MaxWrenchAlong(requests[k].A, e, 0.2, 8.0));
    if (++k == requests.size()) k = 0;
  }
}
BENCHMARK(BM_MaxWrenchAlong);

void BM_SweepWorkspace(benchmark::State& state) {
  WorkspaceSweepSettings s;
  for (auto _ : state) benchmark::DoNotOptimize(SweepWorkspace(kGeometry, s));
}
BENCHMARK(BM_SweepWorkspace)->Unit(benchmark::kMillisecond);

// Mean fraction of the commanded force / moment / grasp torque actually displayed.
struct Displayed {
  double force = 0, moment = 0, grasp = 0;
};

Displayed MeanDisplayed(const std::vector<Request>& requests, const TensionSettings& settings) {
  TensionSolver solver(settings);
  Displayed sum;
  int nf = 0, nm = 0, ng = 0;
  for (const Request& r : requests) {
    const TensionResult result = solver.Solve(r.A, r.q);
    // Fraction displayed along the commanded direction: achieved·q / |q|².
    if (r.q.head<3>().norm() > 1e-9) {
      sum.force += result.achieved.head<3>().dot(r.q.head<3>()) / r.q.head<3>().squaredNorm();
      ++nf;
    }
    if (r.q.segment<3>(3).norm() > 1e-9) {
      sum.moment +=
          result.achieved.segment<3>(3).dot(r.q.segment<3>(3)) / r.q.segment<3>(3).squaredNorm();
      ++nm;
    }
    if (std::abs(r.q(6)) > 1e-9) {
      sum.grasp += result.achieved(6) / r.q(6);
      ++ng;
    }
  }
  return {nf ? sum.force / nf : NAN, nm ? sum.moment / nm : NAN, ng ? sum.grasp / ng : NAN};
}

void PrintWeightReport() {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  auto with = [&](double force, double moment, double grasp) {
    std::vector<Request> out = RandomRequests(400, 1.0, 9);
    for (Request& r : out) {
      r.q << force * u(rng), force * u(rng), force * u(rng), moment * u(rng), moment * u(rng),
          moment * u(rng), grasp * u(rng);
    }
    return out;
  };
  struct Row {
    const char* name;
    std::vector<Request> requests;
  };
  const std::vector<Row> rows = {
      {"moment only, |m_i| <= 0.05 N*m", with(0, 0.05, 0)},
      {"grasp only, |g| <= 0.05 N*m", with(0, 0, 0.05)},
      {"force 2 N + moment 0.05 + grasp 0.05", with(2, 0.05, 0.05)},
      {"force 15 N (saturating) + moment 0.05 + grasp 0.05", with(15, 0.05, 0.05)},
  };
  TensionSettings by_d;  // S0 = S1 = 625 (1/d², d = 4 cm), S2 = 1e-3
  TensionSettings ones = by_d;
  ones.s0 = 1;
  ones.s1 = 1;
  std::printf(
      "Fraction of the commanded wrench displayed (mean of achieved.q/|q|^2, 400 random "
      "poses each)\n");
  std::printf("%-52s | %-26s | %-26s\n", "request", "S0=S1=1/d^2=625 f / m / g",
              "S0=S1=1 f / m / g");
  for (const Row& row : rows) {
    const Displayed a = MeanDisplayed(row.requests, by_d);
    const Displayed b = MeanDisplayed(row.requests, ones);
    std::printf("%-52s | %6.3f / %6.3f / %6.3f   | %6.3f / %6.3f / %6.3f\n", row.name, a.force,
                a.moment, a.grasp, b.force, b.moment, b.grasp);
  }
  std::printf("\n");
}

}  // namespace
}  // namespace spidarcad::haptics

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Tension distribution and workspace LP timings, and the achieved-wrench error of the default\n"
    "weights (S0 = S1 = 1/d²) against weights of order 1.\n"
    "  build-*/bench/tension_bench                 # report + all benchmarks\n"
    "  build-*/bench/tension_bench --benchmark_filter=Solve";

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription,
                                            spidarcad::haptics::PrintWeightReport);
}
