// Tests of `spidarcad tension --batch`, run as a separate process (the stable CLI interface).
// Tensions are checked against the wrench they must display, computed here from the string
// geometry written out by hand, not against the library.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "spidarcad_runner.h"

namespace {

using spidarcad::test_support::CommandRun;
using spidarcad::test_support::RunSpidarcad;

std::vector<std::vector<double>> ParseLines(const std::string& text) {
  std::vector<std::vector<double>> rows;
  std::stringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    std::vector<double> row;
    std::stringstream fields(line);
    std::string field;
    while (std::getline(fields, field, ',')) {
      row.push_back(field == "nan" ? std::nan("") : std::stod(field));
    }
    rows.push_back(row);
  }
  return rows;
}

// Wrench (f, m, g) of tensions τ on a grip (p0, p1, p2) in the paper's 48 cm frame, from
// docs/architecture.md (Reading the paper) written out independently of the library.
Eigen::Matrix<double, 7, 1> WrenchOf(const std::vector<double>& pose,
                                     const std::vector<double>& tau) {
  const Eigen::Vector3d p0(pose[0], pose[1], pose[2]), p1(pose[3], pose[4], pose[5]),
      p2(pose[6], pose[7], pose[8]);
  const double h = 0.24;
  // Corner Q_i (1-based i): x = +h for odd i, y = +h for i in {1,2,5,6}, z = +h for i <= 4.
  const Eigen::Vector3d corners[8] = {{h, h, h},  {-h, h, h},  {h, -h, h},  {-h, -h, h},
                                      {h, h, -h}, {-h, h, -h}, {h, -h, -h}, {-h, -h, -h}};
  // Strings 1,2 -> p0 + p1; 3,4 -> p0 − p1; 5,7 -> p0 + p2; 6,8 -> p0 − p2.
  const Eigen::Vector3d lever[8] = {p1, p1, -p1, -p1, p2, -p2, p2, -p2};
  const Eigen::Vector3d n = p1.cross(p2).normalized();
  Eigen::Matrix<double, 7, 1> q = Eigen::Matrix<double, 7, 1>::Zero();
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d c = (corners[i] - (p0 + lever[i])).normalized();
    const Eigen::Vector3d rc = lever[i].cross(c);
    q.head<3>() += tau[i] * c;
    q.segment<3>(3) += tau[i] * rc;
    q(6) += tau[i] * (i < 4 ? 1.0 : -1.0) * n.dot(rc);
  }
  return q;
}

constexpr const char* kRestPose = "0,0,0,0,0.04,0,0.04,0,0";

TEST(TensionCommand, DisplaysFeasibleRequestsWithinBoundsAndReportsTheObjective) {
  const std::vector<std::string> wrenches = {"0,0,0,0,0,0,0",     "1,0,0,0,0,0,0",
                                             "0,-2,1,0,0,0,0",    "0,0,0,0.02,0,0,0",
                                             "0,0,0,0,0,-0.03,0", "0.5,0,0,0,0,0,0.02"};
  std::string input = "# x,y,z,x1,y1,z1,x2,y2,z2,fx,fy,fz,mx,my,mz,g\n";
  for (const std::string& w : wrenches) input += std::string(kRestPose) + "," + w + "\n";
  input += "0.03,-0.02,0.05,0,0.04,0,0.037588,0,0.013681,1,1,-1,0.01,0.01,0,0.01\n";
  const CommandRun run = RunSpidarcad("tension --batch", input, "feasible");
  ASSERT_EQ(run.status, 0) << run.err;
  const auto rows = ParseLines(run.out);
  const auto requests = ParseLines(input.substr(input.find('\n') + 1));
  ASSERT_EQ(rows.size(), requests.size());
  for (size_t k = 0; k < rows.size(); ++k) {
    ASSERT_EQ(rows[k].size(), 9u);
    const std::vector<double> tau(rows[k].begin(), rows[k].begin() + 8);
    for (double t : tau) {
      EXPECT_GE(t, 0.2 - 1e-12);
      EXPECT_LE(t, 8.0 + 1e-12);
    }
    const Eigen::Matrix<double, 7, 1> q = WrenchOf(requests[k], tau);
    Eigen::Matrix<double, 7, 1> want;
    for (int i = 0; i < 7; ++i) want(i) = requests[k][9 + i];
    EXPECT_LT((q.head<3>() - want.head<3>()).norm(), 0.01 * want.head<3>().norm() + 2e-3) << k;
    EXPECT_LT((q.tail<4>() - want.tail<4>()).norm(), 0.01 * want.tail<4>().norm() + 5e-4) << k;
    // objective = |f − Fτ|² + 625|m − Mτ|² + 625(g − Gτ)² + 0.001|τ|² (defaults, d = 0.04 m).
    const Eigen::Matrix<double, 7, 1> e = want - q;
    double tau2 = 0;
    for (double t : tau) tau2 += t * t;
    const double J = e.head<3>().squaredNorm() + 625 * e.tail<4>().squaredNorm() + 1e-3 * tau2;
    EXPECT_NEAR(rows[k][8], J, 1e-9 + 1e-7 * J) << k;
  }
}

TEST(TensionCommand, SolvesEachLineIndependentlyOfTheOthers) {
  std::vector<std::string> lines;
  for (int k = 0; k < 12; ++k) {
    std::ostringstream s;
    s << kRestPose << "," << (k % 3 == 0 ? 40 : 1) * std::sin(k) << "," << std::cos(3 * k) << ","
      << (k % 4 == 0 ? -30.0 : 0.5) << "," << 0.02 * std::sin(2 * k) << ",0,0,"
      << 0.01 * std::cos(k);
    lines.push_back(s.str());
  }
  std::string forward, backward;
  for (size_t k = 0; k < lines.size(); ++k) {
    forward += lines[k] + "\n";
    backward += lines[lines.size() - 1 - k] + "\n";
  }
  const CommandRun a = RunSpidarcad("tension --batch", forward, "forward");
  const CommandRun b = RunSpidarcad("tension --batch", backward, "backward");
  ASSERT_EQ(a.status, 0) << a.err;
  ASSERT_EQ(b.status, 0) << b.err;
  const auto ra = ParseLines(a.out), rb = ParseLines(b.out);
  ASSERT_EQ(ra.size(), lines.size());
  ASSERT_EQ(rb.size(), lines.size());
  for (size_t k = 0; k < lines.size(); ++k) {
    const CommandRun single = RunSpidarcad("tension --batch", lines[k] + "\n", "single");
    EXPECT_EQ(ra[k], rb[lines.size() - 1 - k]) << k;
    EXPECT_EQ(ra[k], ParseLines(single.out)[0]) << k;
  }
}

TEST(TensionCommand, PrintsNanLineForNanInputAndKeepsGoing) {
  const std::string input = std::string(kRestPose) + ",nan,0,0,0,0,0,0\n" +
                            "0,nan,0,0,0.04,0,0.04,0,0,0,0,0,0,0,0,0\n" + kRestPose +
                            ",1,0,0,0,0,0,0\n";
  const CommandRun run = RunSpidarcad("tension --batch", input, "nan");
  ASSERT_EQ(run.status, 0) << run.err;
  const auto rows = ParseLines(run.out);
  ASSERT_EQ(rows.size(), 3u);
  for (int k = 0; k < 2; ++k) {
    ASSERT_EQ(rows[k].size(), 9u);
    for (double v : rows[k]) EXPECT_TRUE(std::isnan(v));
  }
  for (double v : rows[2]) EXPECT_TRUE(std::isfinite(v));
}

TEST(TensionCommand, RejectsBadSettingsAndInputWithStatus2) {
  const std::string good = std::string(kRestPose) + ",0,0,0,0,0,0,0\n";
  struct Bad {
    std::string args;
    std::string input;
    std::string mention;
  };
  const std::vector<Bad> cases = {
      {"tension --batch --tmin -1", good, "tau_min"},
      {"tension --batch --tmin 5 --tmax 4", good, "tau_max"},
      {"tension --batch --weights 1,1,0", good, "s2"},
      {"tension --batch --weights 1,-1,0.001", good, "s1"},
      {"tension --batch --weights 1,2", good, "weights"},
      {"tension --batch --pole 0.5", good, "pole"},
      {"tension --batch", "0,0,0,0,0,0,0.04,0,0,0,0,0,0,0,0,0\n", ":1: degenerate pose"},
      {"tension --batch", good + "0,0,0,0,0.04,0,0,0.04,0,0,0,0,0,0,0,0\n", ":2: degenerate"},
      {"tension --batch", good + "1,2,x,4\n", ":2: column 3"},
      {"tension --batch", "1,2,3\n", "expected 16"},
      {"tension", good, "--batch"},
  };
  int k = 0;
  for (const Bad& c : cases) {
    const CommandRun run = RunSpidarcad(c.args, c.input, "bad" + std::to_string(k++));
    EXPECT_EQ(run.status, 2) << c.args << "\n" << run.err;
    EXPECT_NE(run.err.find(c.mention), std::string::npos) << c.args << "\n" << run.err;
  }
}

TEST(TensionCommand, HelpTeachesUnitsAndSignConventions) {
  const CommandRun run = RunSpidarcad("tension --help", "", "help");
  EXPECT_EQ(run.status, 0);
  for (const char* needle : {"[N]", "[N·m]", "[m]", "g > 0 squeezes", "t1,...,t8,objective",
                             "x,y,z, x1,y1,z1, x2,y2,z2, fx,fy,fz, mx,my,mz, g", "nan"}) {
    EXPECT_NE(run.out.find(needle), std::string::npos) << needle;
  }
}

std::vector<std::string> SplitFields(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream s(line);
  std::string f;
  while (std::getline(s, f, ',')) fields.push_back(f);
  return fields;
}

TEST(TensionCommand, LostFlagAppendsStatusTheLostWrenchAndTheClosureMargin) {
  // Line 1: 1 N at rest (displayed). Line 2: 100 N along x at rest (beyond eight 8 N strings).
  // Line 3: the grip turned 90° about z (pole 1 along x, pole 2 along y): A loses rank there
  // and force closure is lost; the request lies along the wrench direction no tension
  // displays. Line 4: NaN.
  const std::vector<double> turned = {0, 0, 0.05, -0.04, 0, 0, 0, 0.04, 0};
  // The lost direction: the left singular vector of A (unit tensions through WrenchOf) with
  // zero singular value, scaled to a 2 N force part.
  Eigen::Matrix<double, 7, 8> A;
  for (int i = 0; i < 8; ++i) {
    std::vector<double> unit(8, 0.0);
    unit[i] = 1;
    A.col(i) = WrenchOf(turned, unit);
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullU);
  ASSERT_LT(svd.singularValues()(6), 1e-9);
  Eigen::Matrix<double, 7, 1> y = svd.matrixU().col(6);
  y *= 2.0 / y.head<3>().norm();
  std::string input;
  input += std::string(kRestPose) + ",1,0,0,0,0,0,0\n";
  input += std::string(kRestPose) + ",100,0,0,0,0,0,0\n";
  char buffer[64];
  for (double v : turned) {
    std::snprintf(buffer, sizeof(buffer), "%.17g,", v);
    input += buffer;
  }
  for (int i = 0; i < 7; ++i) {
    std::snprintf(buffer, sizeof(buffer), i < 6 ? "%.17g," : "%.17g\n", y(i));
    input += buffer;
  }
  input += std::string(kRestPose) + ",nan,0,0,0,0,0,0\n";
  const CommandRun run = RunSpidarcad("tension --batch --lost", input, "lost");
  ASSERT_EQ(run.status, 0) << run.err;
  std::vector<std::string> lines;
  std::stringstream out(run.out);
  for (std::string line; std::getline(out, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), 4u) << run.out;
  const auto requests = ParseLines(input);
  for (std::size_t k = 0; k < 3; ++k) {
    const std::vector<std::string> f = SplitFields(lines[k]);
    ASSERT_EQ(f.size(), 18u) << lines[k];
    std::vector<double> tau;
    for (int i = 0; i < 8; ++i) tau.push_back(std::stod(f[i]));
    // lost = request − displayed wrench, the displayed wrench computed here from the tensions.
    const Eigen::Matrix<double, 7, 1> shown = WrenchOf(requests[k], tau);
    for (int i = 0; i < 7; ++i) {
      EXPECT_NEAR(std::stod(f[10 + i]), requests[k][9 + i] - shown(i), 1e-9) << k << " " << i;
    }
  }
  const std::vector<std::string> ok = SplitFields(lines[0]), big = SplitFields(lines[1]),
                                 lost = SplitFields(lines[2]), bad = SplitFields(lines[3]);
  EXPECT_EQ(ok[9], "ok");
  EXPECT_NEAR(std::stod(ok[17]), 1.0, 1e-9);  // at rest every string has the same share
  EXPECT_EQ(big[9], "saturated");
  EXPECT_GT(std::stod(big[10]), 50.0);  // most of the 100 N is lost, and reported
  EXPECT_EQ(lost[9], "saturated");
  EXPECT_LE(std::stod(lost[17]), 0.0);  // no force closure
  // Nothing of the request along the lost direction is displayed: lost·y = |y|².
  Eigen::Matrix<double, 7, 1> lost_wrench;
  for (int i = 0; i < 7; ++i) lost_wrench(i) = std::stod(lost[10 + i]);
  EXPECT_NEAR(lost_wrench.dot(y), y.squaredNorm(), 1e-6 * y.squaredNorm());
  ASSERT_EQ(bad.size(), 18u);
  EXPECT_EQ(bad[9], "invalid_input");
  // Without --lost the output is the nine columns it always was.
  const CommandRun plain = RunSpidarcad("tension --batch", input, "plain");
  ASSERT_EQ(plain.status, 0);
  std::stringstream plain_out(plain.out);
  for (std::string line; std::getline(plain_out, line);)
    EXPECT_EQ(SplitFields(line).size(), 9u) << line;
}

}  // namespace
