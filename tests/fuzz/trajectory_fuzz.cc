// Fuzz harness: trajectory CSV (haptics::Trajectory::Parse). Any text either parses or is refused
// with std::invalid_argument; an accepted trajectory has increasing times, unit quaternions and
// grasps in (0, π), survives Write/Parse (times, positions and grasps exactly, quaternions to
// 1e-15), and Sample gives finite states between and beyond its samples.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>

#include "fuzz_support.h"
#include "spidarcad/haptics/trajectory.h"

namespace {

using spidarcad::fuzz::Violated;
using spidarcad::haptics::Trajectory;
using spidarcad::haptics::TrajectorySample;

void CheckFinite(const TrajectorySample& s, const char* where) {
  if (!std::isfinite(s.t) || !s.p_DT.allFinite() || !s.q_DT.coeffs().allFinite() ||
      !std::isfinite(s.grasp)) {
    Violated("trajectory", std::string("Sample gives a non-finite state ") + where);
  }
  if (std::abs(s.q_DT.norm() - 1.0) > 1e-9) {
    Violated("trajectory", std::string("Sample gives a non-unit quaternion ") + where);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  Trajectory trajectory;
  try {
    trajectory = Trajectory::Parse(in, "fuzz.csv");
  } catch (const std::invalid_argument&) {
    return 0;
  }
  const auto& samples = trajectory.samples();
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const TrajectorySample& s = samples[i];
    if (i > 0 && !(s.t > samples[i - 1].t)) Violated("trajectory", "times do not increase");
    if (!(s.grasp > 0 && s.grasp < M_PI)) Violated("trajectory", "grasp outside (0, pi)");
    CheckFinite(s, "at a sample");
  }
  std::ostringstream out;
  trajectory.Write(out);
  std::istringstream again_in(out.str());
  Trajectory again;
  try {
    again = Trajectory::Parse(again_in, "round-trip.csv");
  } catch (const std::invalid_argument& e) {
    Violated("trajectory", std::string("a written trajectory does not parse: ") + e.what());
  }
  if (again.samples().size() != samples.size()) Violated("trajectory", "round trip changes size");
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const TrajectorySample& a = samples[i];
    const TrajectorySample& b = again.samples()[i];
    if (a.t != b.t || a.p_DT != b.p_DT || a.grasp != b.grasp ||
        (a.q_DT.coeffs() - b.q_DT.coeffs()).cwiseAbs().maxCoeff() > 1e-15) {
      Violated("trajectory", "round trip changes sample " + std::to_string(i));
    }
  }
  CheckFinite(trajectory.Sample(trajectory.start_time() - 1.0), "before the start");
  CheckFinite(trajectory.Sample(trajectory.end_time() + 1.0), "after the end");
  for (std::size_t i = 0; i + 1 < samples.size() && i < 64; ++i) {
    const double mid = 0.5 * samples[i].t + 0.5 * samples[i + 1].t;  // no overflow
    CheckFinite(trajectory.Sample(mid), "between two samples");
  }
  return 0;
}
