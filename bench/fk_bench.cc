// Speed and accuracy of SPIDAR-G kinematics: closed form alone, refined from a cold start,
// refined from a warm start during motion, and inverse kinematics, on exact, quantized and
// noisy string lengths. Besides time per call, each benchmark reports (as counters) the
// position error of p0 in mm and the rotation error of R_DT in degrees against the true pose,
// mean and max over its data set, the mean Gauss-Newton iterations and the fraction solved.
//
// Run: build/bench/fk_bench   (add --benchmark_filter=... to pick cases)
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "bench_cli.h"
#include "spidarcad/haptics/kinematics.h"

namespace {

using namespace spidarcad::haptics;

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180;
constexpr double kQuantum = 2 * kPi * 0.008 / 2000;  // paper's encoder: 0.0251327 mm per count
constexpr int kSetSize = 1000;

// kCalibrated08: independent 0.8 % Gaussian error on every length of every sample.
// kScale08: the paper's calibrated device read as a per-string gain error: each string's
// lengths are off by a fixed factor 1 + e_i, e_i ~ N(0.8 %, 0.4 %) drawn once per data set
// (string stretch and winding are persistent), plus quantization.
enum class Noise { kExact, kQuantized, kGauss10um, kCalibrated08, kScale08 };

const char* NoiseName(Noise noise) {
  switch (noise) {
    case Noise::kExact:
      return "exact";
    case Noise::kQuantized:
      return "quantized";
    case Noise::kGauss10um:
      return "gauss_0.01mm";
    case Noise::kCalibrated08:
      return "random_0.8pct";
    case Noise::kScale08:
      return "gain_0.8+-0.4pct";
  }
  return "?";
}

Vector8d Measure(const SpidarGeometry& g, const GripPose& pose, Noise noise, std::mt19937& rng,
                 const Vector8d& gain) {
  std::normal_distribution<double> normal;
  Vector8d l = InverseKinematics(g, pose);
  for (int i = 0; i < 8; ++i) {
    switch (noise) {
      case Noise::kExact:
        break;
      case Noise::kQuantized:
        l(i) = std::round(l(i) / kQuantum) * kQuantum;
        break;
      case Noise::kGauss10um:
        l(i) += 1e-5 * normal(rng);
        break;
      case Noise::kCalibrated08:
        l(i) *= 1 + 0.008 * normal(rng);
        break;
      case Noise::kScale08:
        l(i) = std::round(l(i) * gain(i) / kQuantum) * kQuantum;
        break;
    }
  }
  return l;
}

struct DataSet {
  std::vector<GripPose> truth;
  std::vector<Vector8d> lengths;
};

enum class Poses { kCube40cm, kRot45Centre, kRot45Off20cm, kSlowPath, kFastPath };

const char* PosesName(Poses poses) {
  switch (poses) {
    case Poses::kCube40cm:
      return "cube40";
    case Poses::kRot45Centre:
      return "rot45_centre";
    case Poses::kRot45Off20cm:
      return "rot45_off20cm";
    case Poses::kSlowPath:
      return "path_0.1m/s";
    case Poses::kFastPath:
      return "path_2m/s_20rad/s";
  }
  return "?";
}

// Closed path sampled at 1 kHz: centre on a circle of radius 0.1 m at angular rate `rate`
// (speed 0.1·rate m/s), grip spinning at `rate` rad/s about a tilted axis, grasp swinging.
GripPose PathPose(const SpidarGeometry& g, int tick, double rate) {
  const double t = tick * 1e-3;
  const Eigen::Vector3d p0(0.1 * std::cos(rate * t), 0.1 * std::sin(rate * t),
                           0.05 * std::sin(2 * rate * t));
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.5 * std::sin(rate * t), Eigen::Vector3d(0.3, -0.5, 1).normalized())
          .toRotationMatrix() *
      Eigen::AngleAxisd(rate * t, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const double grasp = kPi / 2 + 30 * kDeg * std::sin(rate * t);
  return GripPose::FromFrame(p0, R, grasp, g.d);
}

DataSet MakeDataSet(const SpidarGeometry& g, Poses poses, Noise noise) {
  DataSet set;
  std::mt19937 rng(2024);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uni(0, 1);
  Vector8d gain;
  for (int i = 0; i < 8; ++i) gain(i) = 1 + 0.008 + 0.004 * normal(rng);
  auto random_axis = [&]() {
    Eigen::Vector3d axis(normal(rng), normal(rng), normal(rng));
    return axis.normalized();
  };
  for (int k = 0; k < kSetSize; ++k) {
    GripPose pose;
    switch (poses) {
      case Poses::kCube40cm: {
        const Eigen::Vector3d p0 =
            0.2 * Eigen::Vector3d(2 * uni(rng) - 1, 2 * uni(rng) - 1, 2 * uni(rng) - 1);
        const Eigen::Matrix3d R =
            Eigen::AngleAxisd(45 * kDeg * uni(rng), random_axis()).toRotationMatrix();
        pose = GripPose::FromFrame(p0, R, (60 + 60 * uni(rng)) * kDeg, g.d);
        break;
      }
      case Poses::kRot45Centre:
      case Poses::kRot45Off20cm: {
        Eigen::Vector3d p0 = Eigen::Vector3d::Zero();
        if (poses == Poses::kRot45Off20cm) p0 = 0.2 * random_axis();
        pose = GripPose::FromFrame(
            p0, Eigen::AngleAxisd(45 * kDeg, random_axis()).toRotationMatrix(), kPi / 2, g.d);
        break;
      }
      case Poses::kSlowPath:
        pose = PathPose(g, k, 1.0);
        break;
      case Poses::kFastPath:
        pose = PathPose(g, k, 20.0);
        break;
    }
    set.truth.push_back(pose);
    set.lengths.push_back(Measure(g, pose, noise, rng, gain));
  }
  return set;
}

FkSettings SettingsFor(Noise noise) {
  FkSettings settings;
  if (noise == Noise::kCalibrated08 || noise == Noise::kScale08) settings.max_residual = 5e-3;
  return settings;
}

struct Accuracy {
  double pos_mean = 0, pos_max = 0, rot_mean = 0, rot_max = 0, iterations = 0, ok = 0;
};

void Accumulate(const GripPose& truth, const GripPose& fit, Accuracy* acc) {
  const double pos = (fit.p0 - truth.p0).norm() * 1e3;
  const double rot = RotationAngleBetween(fit.Rotation(), truth.Rotation()) / kDeg;
  acc->pos_mean += pos;
  acc->rot_mean += rot;
  acc->pos_max = std::max(acc->pos_max, pos);
  acc->rot_max = std::max(acc->rot_max, rot);
  acc->ok += 1;
}

void SetCounters(benchmark::State& state, Accuracy acc, int n) {
  if (acc.ok > 0) {
    acc.pos_mean /= acc.ok;
    acc.rot_mean /= acc.ok;
    acc.iterations /= n;
  }
  state.counters["pos_mm_mean"] = acc.pos_mean;
  state.counters["pos_mm_max"] = acc.pos_max;
  state.counters["rot_deg_mean"] = acc.rot_mean;
  state.counters["rot_deg_max"] = acc.rot_max;
  state.counters["iters"] = acc.iterations;
  state.counters["ok_frac"] = acc.ok / n;
}

void BenchClosedForm(benchmark::State& state, Poses poses, Noise noise) {
  const SpidarGeometry g;
  const DataSet set = MakeDataSet(g, poses, noise);
  Accuracy acc;
  for (int k = 0; k < kSetSize; ++k) {
    GripPose fit;
    if (ClosedFormPose(g, set.lengths[k], &fit)) Accumulate(set.truth[k], fit, &acc);
  }
  int k = 0;
  GripPose fit;
  for (auto _ : state) {
    benchmark::DoNotOptimize(ClosedFormPose(g, set.lengths[k], &fit));
    benchmark::DoNotOptimize(fit);
    k = (k + 1) % kSetSize;
  }
  SetCounters(state, acc, kSetSize);
}

void BenchFk(benchmark::State& state, Poses poses, Noise noise, bool warm) {
  const SpidarGeometry g;
  const DataSet set = MakeDataSet(g, poses, noise);
  ForwardKinematics fk(g, SettingsFor(noise));
  Accuracy acc;
  for (int pass = 0; pass < 2; ++pass) {  // pass 0 primes the warm start (path wraps around)
    for (int k = 0; k < kSetSize; ++k) {
      if (!warm) fk.Reset();
      const FkResult r = fk.Solve(set.lengths[k]);
      if (pass == 0) continue;
      acc.iterations += r.iterations;
      if (r.status == FkStatus::kOk) Accumulate(set.truth[k], r.pose, &acc);
    }
  }
  int k = 0;
  for (auto _ : state) {
    if (!warm) fk.Reset();
    benchmark::DoNotOptimize(fk.Solve(set.lengths[k]));
    k = (k + 1) % kSetSize;
  }
  SetCounters(state, acc, kSetSize);
}

// Cold FK with the branch check on (FkSettings::branch_residual = half an encoder count, as
// `spidarcad fk --bound` sets it) on quantized lengths.
void BenchFkBranchCheck(benchmark::State& state) {
  const SpidarGeometry g;
  const DataSet set = MakeDataSet(g, Poses::kCube40cm, Noise::kQuantized);
  FkSettings settings;
  settings.branch_residual = 0.5 * kQuantum;
  ForwardKinematics fk(g, settings);
  Accuracy acc;
  for (int k = 0; k < kSetSize; ++k) {
    fk.Reset();
    const FkResult r = fk.Solve(set.lengths[k]);
    acc.iterations += r.iterations + r.branch_iterations;
    if (r.status == FkStatus::kOk) Accumulate(set.truth[k], r.pose, &acc);
  }
  int k = 0;
  for (auto _ : state) {
    fk.Reset();
    benchmark::DoNotOptimize(fk.Solve(set.lengths[k]));
    k = (k + 1) % kSetSize;
  }
  SetCounters(state, acc, kSetSize);
}

// FkPositionBound for a solved pose (lengths known to ±half a count); counters: median bound
// and median actual error (mm) and the share of poses with a finite bound.
void BenchPositionBound(benchmark::State& state) {
  const SpidarGeometry g;
  const DataSet set = MakeDataSet(g, Poses::kCube40cm, Noise::kQuantized);
  ForwardKinematics fk(g);
  std::vector<GripPose> fits(kSetSize);
  std::vector<double> bounds, errors;
  for (int k = 0; k < kSetSize; ++k) {
    fk.Reset();
    const FkResult r = fk.Solve(set.lengths[k]);
    fits[k] = r.status == FkStatus::kOk ? r.pose : set.truth[k];
    const double b = FkPositionBound(g, fits[k], set.lengths[k], 0.5 * kQuantum).position;
    if (r.status == FkStatus::kOk && std::isfinite(b)) {
      bounds.push_back(b * 1e3);
      errors.push_back((r.pose.p0 - set.truth[k].p0).norm() * 1e3);
    }
  }
  std::sort(bounds.begin(), bounds.end());
  std::sort(errors.begin(), errors.end());
  int k = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(FkPositionBound(g, fits[k], set.lengths[k], 0.5 * kQuantum));
    k = (k + 1) % kSetSize;
  }
  state.counters["bound_mm_median"] = bounds.empty() ? 0 : bounds[bounds.size() / 2];
  state.counters["err_mm_median"] = errors.empty() ? 0 : errors[errors.size() / 2];
  state.counters["finite_frac"] = static_cast<double>(bounds.size()) / kSetSize;
}

void BenchIk(benchmark::State& state) {
  const SpidarGeometry g;
  const DataSet set = MakeDataSet(g, Poses::kCube40cm, Noise::kExact);
  int k = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(InverseKinematics(g, set.truth[k]));
    k = (k + 1) % kSetSize;
  }
}

void BenchStringJacobian(benchmark::State& state) {
  const SpidarGeometry g;
  const DataSet set = MakeDataSet(g, Poses::kCube40cm, Noise::kExact);
  int k = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(StringJacobian(g, set.truth[k]));
    k = (k + 1) % kSetSize;
  }
}

void RegisterAll() {
  const Noise noises[] = {Noise::kExact, Noise::kQuantized, Noise::kGauss10um, Noise::kCalibrated08,
                          Noise::kScale08};
  for (Poses poses : {Poses::kCube40cm, Poses::kRot45Centre, Poses::kRot45Off20cm}) {
    for (Noise noise : noises) {
      const std::string suffix = std::string("/") + PosesName(poses) + "/" + NoiseName(noise);
      benchmark::RegisterBenchmark(("closed_form" + suffix).c_str(), BenchClosedForm, poses, noise);
      benchmark::RegisterBenchmark(("fk_cold" + suffix).c_str(), BenchFk, poses, noise, false);
    }
  }
  for (Poses poses : {Poses::kSlowPath, Poses::kFastPath}) {
    for (Noise noise : noises) {
      const std::string suffix = std::string("/") + PosesName(poses) + "/" + NoiseName(noise);
      benchmark::RegisterBenchmark(("fk_warm" + suffix).c_str(), BenchFk, poses, noise, true);
    }
  }
  benchmark::RegisterBenchmark("fk_cold_branch_check/cube40/quantized", BenchFkBranchCheck);
  benchmark::RegisterBenchmark("position_bound/cube40/quantized", BenchPositionBound);
  benchmark::RegisterBenchmark("ik/cube40", BenchIk);
  benchmark::RegisterBenchmark("string_jacobian/cube40", BenchStringJacobian);
}

}  // namespace

// What this program measures (its --help).
constexpr const char* kBenchDescription =
    "Speed and accuracy of SPIDAR-G kinematics: closed form alone, refined from a cold start,\n"
    "refined from a warm start during motion, and inverse kinematics, on exact, quantized and\n"
    "noisy string lengths. Besides time per call, each benchmark reports (as counters) the\n"
    "position error of p0 in mm and the rotation error of R_DT in degrees against the true pose,\n"
    "mean and max over its data set, the mean Gauss-Newton iterations and the fraction solved.\n"
    "\n"
    "Run: build/bench/fk_bench   (add --benchmark_filter=... to pick cases)";

int main(int argc, char** argv) {
  RegisterAll();
  return spidarcad::bench::RunBenchmarkMain(argc, argv, kBenchDescription);
}
