// Haptic tick time per scene kind: HapticLoop::Step on the simulated SPIDAR-G gripped by the
// simulated hand, as in `spidarcad run`, for every kind of scene the window shows (empty, demo,
// implicit proxy, six-DOF shell, FE contact, sculpt, assembly). Used by `spidarcad report`
// (section "tick") and by bench/app_scene_tick_bench.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace spidarcad::app {

// Tick-time figures of one scene (µs), with the samples.
struct SceneTickRow {
  std::string name;
  double p50 = 0, p99 = 0, p999 = 0, max = 0, mean = 0;        // wall clock (steady clock)
  double cpu_p50 = 0, cpu_p99 = 0, cpu_p999 = 0, cpu_max = 0;  // thread CPU time
  std::string note;             // scene-specific figures (FE: contact nodes reached, ...)
  std::vector<double> us, cpu;  // the samples, per tick (wall clock, thread CPU), µs
};

// Runs every scene kind for `ticks` ticks (>= 1; the trajectories repeat) and returns one row
// per scene, plus rows over the FE ticks with 16 contact nodes and the assembly ticks carrying
// a part. `progress(fraction)` is called after each scene.
std::vector<SceneTickRow> MeasureSceneTicks(long ticks,
                                            const std::function<void(double)>& progress = {});

}  // namespace spidarcad::app
