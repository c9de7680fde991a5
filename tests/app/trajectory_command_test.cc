// Tests of `spidarcad trajectory`, run as a separate process: the written files parse as
// trajectories, the defaults reproduce the shipped assets/trajectories files, the geometry of
// each kind matches its closed form, and bad options exit with status 2 naming the option.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <string>

#include "spidarcad/haptics/trajectory.h"
#include "spidarcad_runner.h"

namespace {

using spidarcad::haptics::Trajectory;
using spidarcad::test_support::CommandRun;
using spidarcad::test_support::RunSpidarcad;
using spidarcad::test_support::TestOutputPath;

// Runs `spidarcad trajectory ARGS --out -` and parses its stdout.
Trajectory Generate(const std::string& args) {
  const CommandRun run = RunSpidarcad("trajectory " + args + " --out -", "", "traj");
  EXPECT_EQ(run.status, 0) << run.all();
  std::istringstream in(run.out);
  return Trajectory::Parse(in, "stdout of spidarcad trajectory " + args);
}

std::string Asset(const std::string& name) {
  return std::string(SPIDARCAD_SOURCE_DIR) + "/assets/trajectories/" + name;
}

// Same samples within `tol` (positions m, quaternion components, grasp rad; times exact to 1e-12).
void ExpectSameSamples(const Trajectory& a, const Trajectory& b, double tol) {
  ASSERT_EQ(a.samples().size(), b.samples().size());
  for (std::size_t i = 0; i < a.samples().size(); ++i) {
    const auto& x = a.samples()[i];
    const auto& y = b.samples()[i];
    ASSERT_NEAR(x.t, y.t, 1e-12) << "sample " << i;
    ASSERT_LT((x.p_DT - y.p_DT).norm(), tol) << "sample " << i;
    ASSERT_LT(x.q_DT.angularDistance(y.q_DT), tol) << "sample " << i;
    ASSERT_NEAR(x.grasp, y.grasp, tol) << "sample " << i;
  }
}

TEST(TrajectoryCommand, DefaultsReproduceTheShippedTrajectories) {
  for (const char* kind : {"press", "circle", "twist", "squeeze"}) {
    SCOPED_TRACE(kind);
    ExpectSameSamples(Generate(kind), Trajectory::Load(Asset(std::string(kind) + ".csv")), 1e-12);
  }
}

TEST(TrajectoryCommand, PressReachesTheSurfacePlusDepthAlongTheNormal) {
  // Surface point (0.01, 0.02, 0), normal along +x: the deepest sample is 4 mm past the
  // surface along −x, and the path starts and ends at --start.
  const Trajectory t = Generate(
      "press --start 0.05,0.02,0 --surface 0.01,0.02,0 --normal 2,0,0 --depth 0.004 --duration 2 "
      "--rate 200");
  EXPECT_NEAR(t.end_time(), 2.0, 1e-12);
  double min_x = 1.0;
  for (const auto& s : t.samples()) {
    min_x = std::min(min_x, s.p_DT.x());
    EXPECT_NEAR(s.p_DT.y(), 0.02, 1e-12);
    EXPECT_NEAR(s.p_DT.z(), 0.0, 1e-12);
  }
  EXPECT_NEAR(min_x, 0.01 - 0.004, 1e-9);
  EXPECT_LT((t.samples().front().p_DT - Eigen::Vector3d(0.05, 0.02, 0)).norm(), 1e-12);
  EXPECT_LT((t.samples().back().p_DT - Eigen::Vector3d(0.05, 0.02, 0)).norm(), 1e-12);
}

TEST(TrajectoryCommand, CircleLiesOnItsCircle) {
  const Eigen::Vector3d c(0.01, -0.02, 0.03);
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 1, 0).normalized();
  const Trajectory t =
      Generate("circle --center 0.01,-0.02,0.03 --axis 1,1,0 --radius 0.025 --turns 2");
  EXPECT_NEAR(t.end_time(), 4.0, 1e-12);  // the circle's default duration
  for (const auto& s : t.samples()) {
    const Eigen::Vector3d r = s.p_DT - c;
    EXPECT_NEAR(r.dot(axis), 0.0, 1e-12);
    EXPECT_NEAR(r.norm(), 0.025, 1e-12);
  }
  // Starts and ends at the same point after whole turns.
  EXPECT_LT((t.samples().front().p_DT - t.samples().back().p_DT).norm(), 1e-9);
}

TEST(TrajectoryCommand, TwistRotatesAboutItsAxisWithinTheAmplitude) {
  const Eigen::Vector3d axis = Eigen::Vector3d(0, 1, 1).normalized();
  const Trajectory t =
      Generate("twist --axis 0,1,1 --amplitude 0.3 --cycles 1 --duration 1 --rate 400");
  double largest = 0.0;
  for (const auto& s : t.samples()) {
    const Eigen::AngleAxisd aa(s.q_DT);
    if (aa.angle() > 1e-9) {
      EXPECT_NEAR(std::abs(aa.axis().dot(axis)), 1.0, 1e-9);
    }
    largest = std::max(largest, aa.angle());
    EXPECT_LT(s.p_DT.norm(), 1e-15);
  }
  EXPECT_LE(largest, 0.3 + 1e-12);
  EXPECT_GT(largest, 0.3 - 1e-3);  // 400 Hz samples reach the sine's peak within 1e-3 rad
}

TEST(TrajectoryCommand, SqueezeClosesTheGraspToItsMinimumAndOpensAgain) {
  const Trajectory t = Generate("squeeze --grasp-min 0.6 --cycles 1 --duration 2 --rate 100");
  double smallest = 10.0;
  for (const auto& s : t.samples()) smallest = std::min(smallest, s.grasp);
  EXPECT_NEAR(smallest, 0.6, 1e-9);
  EXPECT_NEAR(t.samples().front().grasp, std::numbers::pi / 2, 1e-12);
  EXPECT_NEAR(t.samples().back().grasp, std::numbers::pi / 2, 1e-12);
}

TEST(TrajectoryCommand, WritesAFileThatRunAccepts) {
  const std::string path = TestOutputPath("trajectory_press_for_run.csv");
  const CommandRun made =
      RunSpidarcad("trajectory press --duration 0.5 --out '" + path + "'", "", "make");
  ASSERT_EQ(made.status, 0) << made.all();
  EXPECT_NE(made.err.find("samples over 0.5 s written to"), std::string::npos) << made.err;
  const std::string result = TestOutputPath("trajectory_press_run_result.csv");
  const CommandRun run =
      RunSpidarcad("run demo --trajectory '" + path + "' --out '" + result + "'", "", "run");
  EXPECT_EQ(run.status, 0) << run.all();
}

TEST(TrajectoryCommand, BadOptionsExitWithStatusTwoNamingTheOption) {
  struct Case {
    std::string args, expected;
  };
  const Case cases[] = {
      {"wobble --out -", "kind"},
      {"press --duration -1 --out -", "--duration"},
      {"press --rate 0 --out -", "--rate"},
      {"press --normal 0,0,0 --out -", "--normal"},
      {"press --depth -0.001 --out -", "--depth"},
      {"circle --radius 0 --out -", "--radius"},
      {"circle --axis 0,0,0 --out -", "--axis"},
      {"twist --amplitude 4 --out -", "--amplitude"},
      {"squeeze --grasp-min 2 --out -", "--grasp-min"},
      {"press --center 1,2 --out -", "--center"},
      {"press --out /nonexistent-dir/t.csv", "/nonexistent-dir/t.csv"},
      {"press", "--out"},
      // A trajectory `run` would refuse (and 1e300 s used to give it a negative tick count).
      {"press --duration 1e300 --rate 1e-300 --out -", "--duration: must be in (0, 3600] s"},
      {"press --duration 3601 --rate 1 --out -", "--duration"},
      {"press --rate 1e6 --duration 1 --out -", "--rate: must be in (0, 100000]"},
  };
  for (const Case& c : cases) {
    const CommandRun run = RunSpidarcad("trajectory " + c.args, "", "bad");
    EXPECT_EQ(run.status, 2) << c.args << "\n" << run.all();
    EXPECT_NE(run.err.find(c.expected), std::string::npos) << c.args << "\n" << run.err;
  }
}

}  // namespace
