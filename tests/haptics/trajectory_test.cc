// Tests of the scripted trajectory format, interpolation and generators. Expected values are
// written out by hand or computed from the generator's definition, not read back.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <string>

namespace spidarcad::haptics {
namespace {

std::string ErrorOf(const std::string& text) {
  std::istringstream in(text);
  try {
    Trajectory::Parse(in, "T.csv");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(Trajectory, ParsesSamplesSkippingCommentsAndBlankLines) {
  std::istringstream in(
      "# t,x,y,z,qw,qx,qy,qz,grasp\n"
      "\n"
      "0, 0.01,0.02,0.03, 1,0,0,0, 1.5\n"
      "  # indented comment\n"
      "0.5,0.02,0.02,0.03,0.70710678,0,0,0.70710678,1.2\r\n");
  const Trajectory tr = Trajectory::Parse(in, "T.csv");
  ASSERT_EQ(tr.samples().size(), 2u);
  EXPECT_EQ(tr.samples()[1].t, 0.5);
  EXPECT_EQ(tr.samples()[0].p_DT.y(), 0.02);
  EXPECT_EQ(tr.samples()[1].grasp, 1.2);
  EXPECT_NEAR(tr.samples()[1].q_DT.norm(), 1.0, 1e-15);
}

TEST(Trajectory, ErrorsNameFileLineAndField) {
  EXPECT_EQ(ErrorOf("# c\n0,0,0,0,1,0,0,0,1.5\n1,0,abc,0,1,0,0,0,1.5\n"),
            "T.csv:3: field 'y': 'abc' is not a number");
  EXPECT_EQ(ErrorOf("0,0,0,0,1,0,0,0\n"),
            "T.csv:1: 8 fields, expected 9: t,x,y,z,qw,qx,qy,qz,grasp");
  EXPECT_NE(ErrorOf("0,0,0,0,1,0,0,0,1.5,7\n").find("T.csv:1: too many fields"), std::string::npos);
  EXPECT_NE(ErrorOf("0,0,0,0,2,0,0,0,1.5\n").find("T.csv:1: field 'qw': quaternion"),
            std::string::npos);
  EXPECT_NE(ErrorOf("0,0,0,0,1,0,0,0,1.5\n0,0,0,0,1,0,0,0,1.5\n").find("T.csv:2: field 't'"),
            std::string::npos);
  EXPECT_NE(ErrorOf("0,0,0,0,1,0,0,0,3.5\n").find("T.csv:1: field 'grasp'"), std::string::npos);
  EXPECT_NE(ErrorOf("0,0,0,0,1,0,0,0,\n").find("T.csv:1: field 'grasp': '' is not a number"),
            std::string::npos);
  EXPECT_EQ(ErrorOf("# only comments\n"), "T.csv: no samples");
  EXPECT_THROW(Trajectory::Load("/nonexistent/T.csv"), std::invalid_argument);
}

TEST(Trajectory, InterpolatesPositionGraspAndRotation) {
  Trajectory tr;
  TrajectorySample a, b;
  a.t = 1.0;
  a.p_DT = {0, 0, 0};
  a.grasp = 1.0;
  b.t = 3.0;
  b.p_DT = {0.04, -0.02, 0.01};
  b.grasp = 2.0;
  b.q_DT = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  tr.Add(a);
  tr.Add(b);
  const TrajectorySample s = tr.Sample(1.5);  // a quarter of the way
  EXPECT_NEAR(s.p_DT.x(), 0.01, 1e-15);
  EXPECT_NEAR(s.p_DT.y(), -0.005, 1e-15);
  EXPECT_NEAR(s.grasp, 1.25, 1e-15);
  const Eigen::AngleAxisd aa(s.q_DT);
  EXPECT_NEAR(aa.angle(), M_PI / 8, 1e-12);
  EXPECT_NEAR(aa.axis().z(), 1.0, 1e-12);
  EXPECT_EQ(tr.Sample(0.0).p_DT, a.p_DT);  // held before the start
  EXPECT_EQ(tr.Sample(9.0).p_DT, b.p_DT);  // and after the end
  EXPECT_THROW(tr.Add(a), std::invalid_argument);
}

// Found by the trajectory fuzz harness (tests/fuzz/regressions/trajectory/huge_span.csv): times
// and coordinates of opposite signs near the largest double made b.t - a.t and b - a overflow,
// and Sample returned NaN between the two samples.
TEST(Trajectory, SampleStaysFiniteWhenTimesAndPositionsSpanMoreThanTheLargestDouble) {
  std::istringstream in(
      "-1e308,-1e308,0,0,1,0,0,0,1\n"
      "1e308,1e308,0,0,1,0,0,0,2\n");
  const Trajectory tr = Trajectory::Parse(in, "huge.csv");
  // At t = 0.5e308 the fraction is (0.5e308 + 1e308) / 2e308 = 0.75, so x = -0.25e308 + 0.75e308.
  const TrajectorySample s = tr.Sample(0.5e308);
  EXPECT_NEAR(s.p_DT.x() / 0.5e308, 1.0, 1e-12);
  EXPECT_EQ(s.p_DT.y(), 0.0);
  EXPECT_NEAR(s.grasp, 1.75, 1e-12);
  // Halfway (t = 0): x = 0 up to the rounding of 1e308 (the overflowing code gave NaN).
  EXPECT_NEAR(tr.Sample(0.0).p_DT.x(), 0.0, 1e295);
}

TEST(Trajectory, WriteThenParseRoundTripsExactly) {
  const Trajectory tr =
      Twist(Eigen::Vector3d(0.01, 0.02, -0.03), Eigen::Vector3d(1, 1, 0), 0.4, 1.0, 0.5, 100.0);
  std::stringstream io;
  tr.Write(io);
  const Trajectory back = Trajectory::Parse(io, "round-trip");
  ASSERT_EQ(back.samples().size(), tr.samples().size());
  for (std::size_t i = 0; i < tr.samples().size(); ++i) {
    EXPECT_EQ(back.samples()[i].t, tr.samples()[i].t);
    EXPECT_EQ(back.samples()[i].p_DT, tr.samples()[i].p_DT);
    EXPECT_NEAR(back.samples()[i].q_DT.angularDistance(tr.samples()[i].q_DT), 0.0, 1e-7);
  }
}

TEST(Trajectory, GeneratorsFollowTheirDefinitions) {
  const Eigen::Vector3d start(0, 0, 0.02), surface(0, 0, -0.03), n(0, 0, 1);
  const Trajectory press = ApproachPressRelease(start, surface, n, 0.005, 2.0, 1000.0);
  EXPECT_EQ(press.samples().front().p_DT, start);
  EXPECT_NEAR((press.Sample(0.8).p_DT - surface).norm(), 0.0, 1e-12);  // 40 %: on the surface
  EXPECT_NEAR(press.Sample(1.3).p_DT.z(), -0.035, 1e-12);              // hold: 5 mm in
  EXPECT_NEAR((press.samples().back().p_DT - start).norm(), 0.0, 1e-12);
  EXPECT_NEAR(press.end_time(), 2.0, 1e-12);

  const Eigen::Vector3d c(0.01, 0, 0), axis(0, 0, 1);
  const Trajectory circle = Circle(c, 0.03, axis, 1.0, 1.0, 500.0);
  double max_off_plane = 0, max_radius_error = 0;
  for (const auto& s : circle.samples()) {
    max_off_plane = std::max(max_off_plane, std::abs((s.p_DT - c).dot(axis)));
    max_radius_error = std::max(max_radius_error, std::abs((s.p_DT - c).norm() - 0.03));
  }
  EXPECT_LT(max_off_plane, 1e-15);
  EXPECT_LT(max_radius_error, 1e-15);
  EXPECT_NEAR((circle.Sample(0.5).p_DT - (2 * c - circle.Sample(0.0).p_DT)).norm(), 0, 1e-12);

  const Trajectory twist = Twist(c, Eigen::Vector3d(0, 1, 0), 0.3, 1.0, 2.0, 100.0);
  EXPECT_NEAR(Eigen::AngleAxisd(twist.Sample(0.5).q_DT).angle(), 0.3, 1e-12);  // sin peak

  const Trajectory squeeze = Squeeze(c, 0.9, 2.0, 2.0, 100.0);
  EXPECT_NEAR(squeeze.Sample(0.5).grasp, 0.9, 1e-12);
  EXPECT_NEAR(squeeze.Sample(1.0).grasp, M_PI / 2, 1e-12);
  EXPECT_THROW(Squeeze(c, 0.0, 1, 1, 100), std::invalid_argument);
  EXPECT_THROW(Circle(c, 0.03, axis, 1, -1, 100), std::invalid_argument);
}

}  // namespace
}  // namespace spidarcad::haptics
