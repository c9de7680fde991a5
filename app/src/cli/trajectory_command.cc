// `spidarcad trajectory KIND --out T.csv`: writes a scripted grip trajectory for `spidarcad run`
// (and the window's --trajectory) from the generators of haptics/trajectory.h. The defaults of
// each kind reproduce the file of the same name in assets/trajectories/.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <Eigen/Core>
#include <cmath>
#include <fstream>
#include <iostream>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "spidarcad/haptics/trajectory.h"

namespace spidarcad::app {

namespace {

constexpr const char* kTrajectoryHelp =
    "Writes a grip trajectory (CSV t,x,y,z,qw,qx,qy,qz,grasp: s, m in the device frame D, unit\n"
    "quaternion R_DT, rad) for `spidarcad run SCENE --trajectory T.csv` or the window's\n"
    "--trajectory. Kinds and what their options mean (all positions in D, metres):\n"
    "  press    from --start down to the --surface point, pressing --depth further along\n"
    "           -normal, hold, back to --start (40/20/10/30 % of --duration, cosine blends)\n"
    "  circle   --turns turns of radius --radius about --center in the plane normal to --axis\n"
    "  twist    rotates the grip about --axis through --center, --amplitude rad, --cycles times\n"
    "  squeeze  closes the grasp from pi/2 to --grasp-min rad and back, --cycles times, at "
    "--center\n"
    "The grip keeps its rest orientation and grasp pi/2 where the kind does not vary them.\n"
    "Defaults reproduce assets/trajectories/KIND.csv (made for the demo scene: floor at\n"
    "z = -0.03 m). Device coordinates are what the hand holds; `run` maps them into the scene\n"
    "through X_WD (see `spidarcad run --help`).\n"
    "\n"
    "Examples:\n"
    "  spidarcad trajectory press --out press.csv\n"
    "  spidarcad trajectory press --surface 0,0,-0.01 --depth 0.005 --duration 2 --out p.csv\n"
    "  spidarcad trajectory circle --center 0,0,-0.035 --radius 0.02 --turns 2 --out c.csv\n"
    "  spidarcad trajectory squeeze --grasp-min 0.6 --out - | head\n";

// Longest trajectory written, s: the longest `spidarcad run` accepts by default.
constexpr double kMaxTrajectorySeconds = 3600.0;
// Highest sample rate, samples per second (100 per haptic tick of 1 ms is already pointless).
constexpr double kMaxTrajectoryRate = 1e5;

struct TrajectoryOptions {
  std::string kind;
  std::string out;
  std::vector<double> start{0.05, 0.0, 0.0};
  std::vector<double> surface{0.05, 0.0, -0.03};
  std::vector<double> normal{0.0, 0.0, 1.0};
  double depth = 0.01;
  std::vector<double> center;  // per kind when not given
  std::vector<double> axis{0.0, 0.0, 1.0};
  double radius = 0.04;
  double turns = 1.0;
  double amplitude = 0.5;
  double cycles = 2.0;
  double grasp_min = 0.9;
  double duration = 0.0;  // per kind when not given (0)
  double rate = 50.0;
};

Eigen::Vector3d ToVector(const std::vector<double>& v) { return Eigen::Vector3d(v[0], v[1], v[2]); }

// Checks that every value of an x,y,z option is finite; unit-direction options must not be zero.
Eigen::Vector3d CheckedVector(const std::vector<double>& v, const char* option, bool direction) {
  const Eigen::Vector3d p = ToVector(v);
  if (!p.allFinite()) {
    throw InputError(std::string(option) + ": every coordinate must be a finite number");
  }
  if (direction && p.norm() < 1e-12) {
    throw InputError(std::string(option) + ": a direction cannot be the zero vector");
  }
  return p;
}

void RequirePositive(double value, const char* option) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    std::ostringstream s;
    s << option << ": must be a positive number, got " << value;
    throw InputError(s.str());
  }
}

// The header comment of the file: what made it, with every parameter.
std::string Describe(const TrajectoryOptions& o, const Eigen::Vector3d& center) {
  std::ostringstream s;
  auto vec = [](const Eigen::Vector3d& v) {
    std::ostringstream t;
    t << v.x() << "," << v.y() << "," << v.z();
    return t.str();
  };
  s << "# spidarcad trajectory " << o.kind;
  if (o.kind == "press") {
    s << " --start " << vec(ToVector(o.start)) << " --surface " << vec(ToVector(o.surface))
      << " --normal " << vec(ToVector(o.normal)) << " --depth " << o.depth;
  } else if (o.kind == "circle") {
    s << " --center " << vec(center) << " --radius " << o.radius << " --axis "
      << vec(ToVector(o.axis)) << " --turns " << o.turns;
  } else if (o.kind == "twist") {
    s << " --center " << vec(center) << " --axis " << vec(ToVector(o.axis)) << " --amplitude "
      << o.amplitude << " --cycles " << o.cycles;
  } else {
    s << " --center " << vec(center) << " --grasp-min " << o.grasp_min << " --cycles " << o.cycles;
  }
  s << " --duration " << o.duration << " --rate " << o.rate << "\n";
  return s.str();
}

void RunTrajectory(TrajectoryOptions o) {
  if (o.duration == 0.0) o.duration = o.kind == "circle" ? 4.0 : 3.0;
  RequirePositive(o.duration, "--duration");
  RequirePositive(o.rate, "--rate");
  if (o.duration > kMaxTrajectorySeconds) {
    throw InputError(
        "--duration: must be in (0, 3600] s (what `spidarcad run` accepts by default; "
        "docs/limits.md), got " +
        FormatNumber(o.duration));
  }
  if (o.rate > kMaxTrajectoryRate) {
    throw InputError("--rate: must be in (0, 100000] samples per second (docs/limits.md), got " +
                     FormatNumber(o.rate));
  }
  if (o.rate * o.duration > 1e7) {
    throw InputError("--rate × --duration: " + FormatNumber(o.rate * o.duration) +
                     " samples, more than 10 million (docs/limits.md); lower --rate (run "
                     "interpolates between samples)");
  }
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  if (!o.center.empty()) {
    center = CheckedVector(o.center, "--center", false);
  } else if (o.kind == "circle") {
    center = Eigen::Vector3d(0.0, 0.0, -0.035);  // 5 mm below the demo floor
  }
  haptics::Trajectory trajectory;
  try {
    if (o.kind == "press") {
      const Eigen::Vector3d start = CheckedVector(o.start, "--start", false);
      const Eigen::Vector3d surface = CheckedVector(o.surface, "--surface", false);
      const Eigen::Vector3d normal = CheckedVector(o.normal, "--normal", true);
      if (!(o.depth >= 0.0) || !std::isfinite(o.depth)) {
        throw InputError("--depth: must be a finite number >= 0 (m)");
      }
      trajectory = haptics::ApproachPressRelease(start, surface, normal.normalized(), o.depth,
                                                 o.duration, o.rate);
    } else if (o.kind == "circle") {
      RequirePositive(o.radius, "--radius");
      RequirePositive(o.turns, "--turns");
      trajectory =
          haptics::Circle(center, o.radius, CheckedVector(o.axis, "--axis", true).normalized(),
                          o.turns, o.duration, o.rate);
    } else if (o.kind == "twist") {
      if (!std::isfinite(o.amplitude) || std::abs(o.amplitude) > std::numbers::pi) {
        throw InputError("--amplitude: must be within [-pi, pi] rad");
      }
      RequirePositive(o.cycles, "--cycles");
      trajectory = haptics::Twist(center, CheckedVector(o.axis, "--axis", true).normalized(),
                                  o.amplitude, o.cycles, o.duration, o.rate);
    } else {  // squeeze (CLI11 checked the kind)
      if (!(o.grasp_min > 0.0 && o.grasp_min < std::numbers::pi / 2)) {
        throw InputError("--grasp-min: must lie in (0, pi/2) rad (pi/2 is the open grip)");
      }
      RequirePositive(o.cycles, "--cycles");
      trajectory = haptics::Squeeze(center, o.grasp_min, o.cycles, o.duration, o.rate);
    }
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("trajectory ") + o.kind + ": " + e.what());
  }
  const std::string header = Describe(o, center);
  if (o.out == "-") {
    std::cout << header;
    trajectory.Write(std::cout);
    std::cout.flush();
  } else {
    std::ofstream file(o.out);
    if (!file) throw InputError("--out: cannot write '" + o.out + "' (check the directory exists)");
    file << header;
    trajectory.Write(file);
    if (!file) throw InputError("--out: writing '" + o.out + "' failed");
    std::cerr << "spidarcad trajectory: " << trajectory.samples().size() << " samples over "
              << trajectory.end_time() - trajectory.start_time() << " s written to " << o.out
              << "\n";
  }
  throw CommandExit{0};
}

}  // namespace

void RegisterTrajectoryCommand(CLI::App& app) {
  auto o = std::make_shared<TrajectoryOptions>();
  CLI::App* cmd = app.add_subcommand(
      "trajectory", "Write a scripted grip trajectory (press, circle, twist, squeeze)");
  cmd->footer(kTrajectoryHelp);
  cmd->add_option("kind", o->kind, "press, circle, twist or squeeze")
      ->required()
      ->check(CLI::IsMember({"press", "circle", "twist", "squeeze"}));
  cmd->add_option("--out", o->out, "Output CSV ('-' for stdout)")->required();
  auto vector_option = [&](const char* name, std::vector<double>* v, const char* what) {
    cmd->add_option(name, *v, what)->delimiter(',')->expected(3)->type_name("X,Y,Z");
  };
  vector_option("--start", &o->start,
                "press: where the grip starts and returns, m (default 0.05,0,0)");
  vector_option("--surface", &o->surface,
                "press: the surface point it moves to, m (default 0.05,0,-0.03)");
  vector_option("--normal", &o->normal, "press: outward surface normal (default 0,0,1)");
  cmd->add_option("--depth", o->depth,
                  "press: how far past the surface the hand aims, m (default 0.01)");
  vector_option("--center", &o->center,
                "circle, twist, squeeze: centre, m (default 0,0,-0.035 for circle, else 0,0,0)");
  vector_option("--axis", &o->axis, "circle: plane normal; twist: rotation axis (default 0,0,1)");
  cmd->add_option("--radius", o->radius, "circle: radius, m (default 0.04)");
  cmd->add_option("--turns", o->turns, "circle: number of turns (default 1)");
  cmd->add_option("--amplitude", o->amplitude, "twist: amplitude, rad (default 0.5)");
  cmd->add_option("--cycles", o->cycles, "twist, squeeze: number of cycles (default 2)");
  cmd->add_option("--grasp-min", o->grasp_min, "squeeze: smallest grasp angle, rad (default 0.9)");
  cmd->add_option("--duration", o->duration,
                  "seconds, in (0, 3600] (default 4 for circle, 3 otherwise)");
  cmd->add_option(
      "--rate", o->rate,
      "samples per second, in (0, 1e5], at most 1e7 samples in all (default 50; run interpolates)");
  cmd->callback([o]() { RunTrajectory(*o); });
}

}  // namespace spidarcad::app
