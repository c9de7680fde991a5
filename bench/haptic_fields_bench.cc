// Evaluate time of the haptic force fields, one per tick along a moving tool path that keeps
// them busy (in contact most of the time): the god-object proxy on a sphere and on a rotated
// box, the six-DOF point shell with 100/500/2000 points against a box, the point shell (a 3 cm
// box tool, 216 points) flicked 4 cm through a 2 mm plate and back every 50 ticks (the
// conservative advancement's worst case), snap with 100 features, grasp on a sphere. Besides Google
// Benchmark's mean, each run reports p50/p99/max (µs) from a per-call histogram. Run:
// build/bench/haptic_fields_bench Copyright the spidarcad authors. SPDX-License-Identifier:
// AGPL-3.0-or-later
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <memory>

#include "bench_cli.h"
#include "spidarcad/haptics/distance_field.h"
#include "spidarcad/haptics/grasp_field.h"
#include "spidarcad/haptics/loop_runner.h"
#include "spidarcad/haptics/point_shell_field.h"
#include "spidarcad/haptics/proxy_field.h"
#include "spidarcad/haptics/snap_field.h"

namespace spidarcad::haptics {
namespace {

// Times field->Evaluate on tool states from path(k), k = tick; reports the share of ticks
// with a non-zero wrench as "busy".
template <class Path>
void TimeField(benchmark::State& state, ForceField* field, Path path) {
  LatencyHistogram histogram(1e-8, 100000);
  long k = 0, busy = 0;
  for (auto _ : state) {
    const ToolKinematics tool = path(k++);
    const auto start = std::chrono::steady_clock::now();
    const ToolWrench w = field->Evaluate(tool);
    const auto stop = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(w.f_T_W.data());
    busy += (w.f_T_W.norm() + std::abs(w.g)) > 0;
    histogram.Add(std::chrono::duration<double>(stop - start).count());
  }
  state.counters["busy"] = k > 0 ? double(busy) / k : 0.0;
  state.counters["p50_us"] = histogram.Percentile(0.5) * 1e6;
  state.counters["p99_us"] = histogram.Percentile(0.99) * 1e6;
  state.counters["max_us"] = histogram.max() * 1e6;
}

std::shared_ptr<DistanceField> RotatedBox() {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  return std::make_shared<TransformedDistanceField>(
      std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.05, 0.05, 0.05)), X);
}

// A tool wandering 0-6 mm inside a sphere of radius 0.05 (and out of it now and then).
ToolKinematics SpherePath(long k) {
  const double t = 1e-3 * k;
  ToolKinematics tool;
  tool.time = t;
  const Eigen::Vector3d dir(std::cos(1.3 * t) * std::sin(0.7 * t + 0.5),
                            std::sin(1.3 * t) * std::sin(0.7 * t + 0.5), std::cos(0.7 * t + 0.5));
  tool.p_WT = (0.047 + 0.004 * std::sin(9 * t)) * dir;
  return tool;
}

void BM_ProxySphere(benchmark::State& state) {
  ProxySettings s;
  s.static_friction = 0.3;
  s.dynamic_friction = 0.2;
  ProxyField field(std::make_shared<SphereDistanceField>(Eigen::Vector3d::Zero(), 0.05), s);
  TimeField(state, &field, SpherePath);
}

void BM_ProxyBox(benchmark::State& state) {
  ProxySettings s;
  s.static_friction = 0.3;
  s.dynamic_friction = 0.2;
  ProxyField field(RotatedBox(), s);
  TimeField(state, &field, SpherePath);  // crosses faces, edges and corners of the box
}

void BM_PointShellBox(benchmark::State& state) {
  // A table: the top face of a box at z = 0; a spherical tool shell of radius 2 cm pressing
  // 0-3 mm into it while sliding and turning.
  auto table = std::make_shared<TransformedDistanceField>(
      std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.2, 0.2, 0.05)),
      Eigen::Isometry3d(Eigen::Translation3d(0, 0, -0.05)));
  PointShellField field(table, PointShell::Sphere(0.02, static_cast<int>(state.range(0))));
  TimeField(state, &field, [](long k) {
    const double t = 1e-3 * k;
    ToolKinematics tool;
    tool.time = t;
    tool.p_WT = Eigen::Vector3d(0.05 * std::sin(t), 0.05 * std::cos(0.7 * t),
                                0.0185 - 0.0015 * std::sin(5 * t));
    tool.R_WT = Eigen::AngleAxisd(t, Eigen::Vector3d(0.2, 0.3, 1).normalized()).toRotationMatrix();
    return tool;
  });
}

void BM_PointShellPlateFlick(benchmark::State& state) {
  auto plate = std::make_shared<BoxDistanceField>(Eigen::Vector3d(0.1, 0.1, 0.001));
  PointShellField field(plate, PointShell::Box(Eigen::Vector3d::Constant(0.015), 0.005));
  TimeField(state, &field, [](long k) {
    ToolKinematics tool;
    tool.time = 1e-3 * k;
    const bool below = (k / 50) % 2 == 1;  // 4 cm down through the plate, then back up
    tool.p_WT = Eigen::Vector3d(0.002 * std::sin(1e-3 * k), 0.0, below ? -0.019 : 0.021);
    tool.R_WT =
        Eigen::AngleAxisd(0.1 * std::sin(2e-3 * k), Eigen::Vector3d::UnitX()).toRotationMatrix();
    return tool;
  });
}

void BM_Snap100Features(benchmark::State& state) {
  // A 4 × 5 grid of square faces: 30 vertices, 49 edges, 20 faces... topped up to 100 with
  // vertices of a second row.
  SnapFeatures f;
  const double a = 0.02;
  for (int i = 0; i <= 4; ++i)
    for (int j = 0; j <= 5; ++j) f.vertices_W.emplace_back(a * i, a * j, 0);
  for (int i = 0; i <= 4; ++i)
    for (int j = 0; j < 5; ++j)
      f.edges_W.emplace_back(Eigen::Vector3d(a * i, a * j, 0),
                             Eigen::Vector3d(a * i, a * (j + 1), 0));
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j <= 5; ++j)
      f.edges_W.emplace_back(Eigen::Vector3d(a * i, a * j, 0),
                             Eigen::Vector3d(a * (i + 1), a * j, 0));
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 5; ++j) {
      SnapFace face;
      face.polygon_W = {{a * i, a * j, 0},
                        {a * (i + 1), a * j, 0},
                        {a * (i + 1), a * (j + 1), 0},
                        {a * i, a * (j + 1), 0}};
      f.faces_W.push_back(face);
    }
  }
  const int count = static_cast<int>(f.vertices_W.size() + f.edges_W.size() + f.faces_W.size());
  f.vertices_W.resize(f.vertices_W.size() + (100 - count), Eigen::Vector3d(1, 1, 1));
  SnapField field(f);
  TimeField(state, &field, [](long k) {
    const double t = 1e-3 * k;
    ToolKinematics tool;
    tool.p_WT = Eigen::Vector3d(0.04 + 0.04 * std::sin(0.9 * t), 0.05 + 0.05 * std::cos(0.6 * t),
                                0.003 * std::sin(4 * t));
    return tool;
  });
}

void BM_GraspSphere(benchmark::State& state) {
  const Eigen::Vector3d b = Eigen::Vector3d(1, 1, 0) / std::sqrt(2.0);
  GraspField field(std::make_shared<SphereDistanceField>(Eigen::Vector3d::Zero(), 0.015),
                   Eigen::Isometry3d(Eigen::Translation3d(0.03 * b)));
  TimeField(state, &field, [](long k) {
    const double t = 1e-3 * k;
    ToolKinematics tool;
    tool.time = t;
    tool.grasp = 1.2 + 0.3 * std::sin(3 * t);  // through the contact angle (1.047 rad)
    tool.grasp_rate = 0.9 * std::cos(3 * t);
    return tool;
  });
}

BENCHMARK(BM_ProxySphere)->Iterations(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ProxyBox)->Iterations(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PointShellBox)
    ->Arg(100)
    ->Arg(500)
    ->Arg(2000)
    ->Iterations(20000)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PointShellPlateFlick)->Iterations(20000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Snap100Features)->Iterations(50000)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_GraspSphere)->Iterations(50000)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace spidarcad::haptics

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Evaluate time of the haptic force fields, one per tick along a moving tool path that keeps\n"
    "them busy (in contact most of the time): the god-object proxy on a sphere and on a rotated\n"
    "box, the six-DOF point shell with 100/500/2000 points against a box, the point shell (a 3 cm\n"
    "box tool, 216 points) flicked 4 cm through a 2 mm plate and back every 50 ticks (the\n"
    "conservative advancement's worst case), snap with 100 features, grasp on a sphere. Besides "
    "Google Benchmark's mean, each run reports p50/p99/max (µs) from a\n"
    "per-call histogram.\n"
    "Run: build/bench/haptic_fields_bench";

int main(int argc, char** argv) {
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
