// Tests of `spidarcad fk --batch` and `spidarcad ik --batch`, run as a separate process on the
// built binary (SPIDARCAD_EXE). Expected values come from the paper's Eq. 7 written out here.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "spidarcad_runner.h"

namespace {

using spidarcad::test_support::CommandRun;
using spidarcad::test_support::RunSpidarcad;

constexpr double kPi = std::numbers::pi;

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::stringstream s(text);
  std::string line;
  while (std::getline(s, line)) lines.push_back(line);
  return lines;
}

std::vector<std::string> DataLines(const std::string& text) {
  std::vector<std::string> lines;
  for (const std::string& line : Lines(text)) {
    if (!line.empty() && line[0] != '#') lines.push_back(line);
  }
  return lines;
}

std::vector<std::string> Fields(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream s(line);
  std::string f;
  while (std::getline(s, f, ',')) fields.push_back(f);
  return fields;
}

struct Pose {
  Eigen::Vector3d p0, p1, p2;
};

// A pose from centre, rotation and grasp angle (ARCHITECTURE.md grip frame), written out.
Pose MakePose(const Eigen::Vector3d& p0, const Eigen::Matrix3d& R, double grasp, double d) {
  const Eigen::Vector3d b(1 / std::sqrt(2.0), 1 / std::sqrt(2.0), 0);
  const Eigen::Vector3d a(1 / std::sqrt(2.0), -1 / std::sqrt(2.0), 0);
  return {p0, d * R * (std::cos(grasp / 2) * b - std::sin(grasp / 2) * a),
          d * R * (std::cos(grasp / 2) * b + std::sin(grasp / 2) * a)};
}

// Eq. 7a-h.
std::vector<double> Eq7(const Pose& p, double a, double b, double c) {
  const Eigen::Vector3d u = p.p0 + p.p1, v = p.p0 - p.p1, s = p.p0 + p.p2, t = p.p0 - p.p2;
  return {(u - Eigen::Vector3d(a, b, c)).norm(),   (u - Eigen::Vector3d(-a, b, c)).norm(),
          (v - Eigen::Vector3d(a, -b, c)).norm(),  (v - Eigen::Vector3d(-a, -b, c)).norm(),
          (s - Eigen::Vector3d(a, b, -c)).norm(),  (t - Eigen::Vector3d(-a, b, -c)).norm(),
          (s - Eigen::Vector3d(a, -b, -c)).norm(), (t - Eigen::Vector3d(-a, -b, -c)).norm()};
}

std::string Csv(const std::vector<double>& values) {
  std::string line;
  char buffer[64];
  for (std::size_t k = 0; k < values.size(); ++k) {
    std::snprintf(buffer, sizeof(buffer), "%.17g", values[k]);
    line += buffer;
    line += k + 1 < values.size() ? "," : "\n";
  }
  return line;
}

std::vector<Pose> RandomPoses(int n, unsigned seed, double d) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(-0.15, 0.15), uni(0, 1);
  std::normal_distribution<double> normal;
  std::vector<Pose> poses;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d axis =
        Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
    const Eigen::Matrix3d R = Eigen::AngleAxisd(kPi / 2 * uni(rng), axis).toRotationMatrix();
    poses.push_back(MakePose(Eigen::Vector3d(pos(rng), pos(rng), pos(rng)), R,
                             (30 + 120 * uni(rng)) * kPi / 180, d));
  }
  return poses;
}

TEST(FkCommand, RecoversPosesFromExactLengths) {
  const std::vector<Pose> poses = RandomPoses(40, 1, 0.04);
  std::string input = "# l1,...,l8\n";
  for (const Pose& p : poses) input += Csv(Eq7(p, 0.24, 0.24, 0.24));
  const CommandRun run = RunSpidarcad("fk --batch", input, "exact");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.err, "");
  const std::vector<std::string> lines = DataLines(run.out);
  ASSERT_EQ(lines.size(), poses.size());
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const std::vector<std::string> f = Fields(lines[k]);
    ASSERT_EQ(f.size(), 12u) << lines[k];
    EXPECT_EQ(f[11], "ok");
    const Eigen::Vector3d* expected[3] = {&poses[k].p0, &poses[k].p1, &poses[k].p2};
    for (int j = 0; j < 9; ++j) {
      EXPECT_NEAR(std::stod(f[j]), (*expected[j / 3])(j % 3), 1e-9) << "line " << k << " col " << j;
    }
    EXPECT_NEAR(std::stod(f[9]), std::acos(poses[k].p1.dot(poses[k].p2) / (0.04 * 0.04)), 1e-7);
    EXPECT_LT(std::stod(f[10]), 1e-12);
  }
}

TEST(FkCommand, GivesOneLinePerCaseWithAStatusAndNamesBadLines) {
  const Pose rest = MakePose(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(), kPi / 2, 0.04);
  const std::string good = Csv(Eq7(rest, 0.24, 0.24, 0.24));
  std::string input;
  input += "# header\n";                                 // line 1: skipped
  input += good;                                         // line 2: ok
  input += "\n";                                         // line 3: blank, skipped
  input += "0.3,0.3,0.3\n";                              // line 4: 3 fields
  input += "0.3,0.3,abc,0.3,0.3,0.3,0.3,0.3\n";          // line 5: not a number
  input += "0.3,0.3,nan,0.3,0.3,0.3,0.3,0.3\n";          // line 6: NaN
  input += "0.3,0.3,-0.3,0.3,0.3,0.3,0.3,0.3\n";         // line 7: negative
  input += "0.05,0.05,0.05,0.05,0.05,0.05,0.05,0.05\n";  // line 8: no pose
  input += "0.3,0.3,0.3,0.3,0.3,0.3,0.3,0.3,0.3\n";      // line 9: 9 fields
  input += good;                                         // line 10: ok
  const CommandRun run = RunSpidarcad("fk --batch", input, "mixed");
  EXPECT_EQ(run.status, 0);
  const std::vector<std::string> lines = DataLines(run.out);
  const std::vector<std::string> expected_status = {"ok",
                                                    "invalid_input",
                                                    "invalid_input",
                                                    "invalid_input",
                                                    "invalid_input",
                                                    "unreachable",
                                                    "invalid_input",
                                                    "ok"};
  ASSERT_EQ(lines.size(), expected_status.size()) << run.out;
  for (std::size_t k = 0; k < lines.size(); ++k) {
    const std::vector<std::string> f = Fields(lines[k]);
    ASSERT_EQ(f.size(), 12u);
    EXPECT_EQ(f[11], expected_status[k]) << "output line " << k;
    if (f[11] != "ok") {
      for (int j = 0; j < 11; ++j) EXPECT_EQ(f[j], "nan") << lines[k];
    }
  }
  EXPECT_EQ(lines[0], lines[7]);
  // Parse errors name their line on stderr.
  for (const char* where : {"<stdin>:4:", "<stdin>:5:", "<stdin>:9:"}) {
    EXPECT_NE(run.err.find(where), std::string::npos) << where << " in\n" << run.err;
  }
  EXPECT_NE(run.err.find("'abc'"), std::string::npos);
  // A header line starting with '#' comes first.
  ASSERT_FALSE(Lines(run.out).empty());
  EXPECT_EQ(Lines(run.out)[0].rfind("# x,y,z,x1,y1,z1,x2,y2,z2,grasp_rad,residual_m,status", 0),
            0u);
}

TEST(FkCommand, AnswerOfALineDoesNotDependOnTheLinesBeforeIt) {
  // Quantized lengths (the paper's 0.0251327 mm encoder count), solved in two orders.
  const double quantum = 2 * kPi * 0.008 / 2000;
  const std::vector<Pose> poses = RandomPoses(30, 2, 0.04);
  std::vector<std::string> rows;
  for (const Pose& p : poses) {
    std::vector<double> l = Eq7(p, 0.24, 0.24, 0.24);
    for (double& x : l) x = std::round(x / quantum) * quantum;
    rows.push_back(Csv(l));
  }
  std::string forward, backward;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    forward += rows[k];
    backward += rows[rows.size() - 1 - k];
  }
  const CommandRun a = RunSpidarcad("fk --batch", forward, "order_a");
  const CommandRun b = RunSpidarcad("fk --batch", backward, "order_b");
  const std::vector<std::string> la = DataLines(a.out), lb = DataLines(b.out);
  ASSERT_EQ(la.size(), rows.size());
  ASSERT_EQ(lb.size(), rows.size());
  for (std::size_t k = 0; k < rows.size(); ++k) {
    EXPECT_EQ(la[k], lb[rows.size() - 1 - k]) << k;
    EXPECT_EQ(Fields(la[k])[11], "ok");
  }
}

TEST(FkCommand, UsesFrameAndPoleOptions) {
  const Pose p =
      MakePose(Eigen::Vector3d(0.05, -0.03, 0.02),
               Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitX()).toRotationMatrix(), 1.2, 0.05);
  const CommandRun run = RunSpidarcad("fk --batch --no-header --frame 0.3,0.2,0.25 --pole 0.05",
                                      Csv(Eq7(p, 0.3, 0.2, 0.25)), "frame");
  ASSERT_EQ(run.status, 0) << run.err;
  const std::vector<std::string> lines = Lines(run.out);
  ASSERT_EQ(lines.size(), 1u);
  const std::vector<std::string> f = Fields(lines[0]);
  EXPECT_EQ(f[11], "ok");
  EXPECT_NEAR(std::stod(f[0]), 0.05, 1e-9);
  EXPECT_NEAR(std::stod(f[4]), p.p1.y(), 1e-9);
  EXPECT_NEAR(std::stod(f[9]), 1.2, 1e-8);
}

TEST(FkCommand, RejectsBadOptionsWithStatus2) {
  EXPECT_EQ(RunSpidarcad("fk --batch --pole 0.5", "", "badpole").status, 2);
  EXPECT_EQ(RunSpidarcad("fk --batch --frame 0.2,-0.1,0.2", "", "badframe").status, 2);
  const CommandRun no_batch = RunSpidarcad("fk", "", "nobatch");
  EXPECT_EQ(no_batch.status, 2);
  EXPECT_NE(no_batch.err.find("--batch"), std::string::npos);
}

TEST(FkCommand, HelpTeachesUnitsFrameNumberingAndExample) {
  for (const char* command : {"fk --help", "ik --help"}) {
    const CommandRun run = RunSpidarcad(command, "", "help");
    EXPECT_EQ(run.status, 0);
    for (const char* needle : {"metres", "Q1 = ( A, B, C)", "Strings 1, 2 end at p0 + p1",
                               "--batch", "Example", "--frame", "--pole"}) {
      EXPECT_NE(run.out.find(needle), std::string::npos) << command << ": " << needle;
    }
  }
}

TEST(IkCommand, ComputesEq7LengthsAndFlagsBadLines) {
  const std::vector<Pose> poses = RandomPoses(20, 3, 0.04);
  std::string input;
  for (const Pose& p : poses) {
    input += Csv(
        {p.p0.x(), p.p0.y(), p.p0.z(), p.p1.x(), p.p1.y(), p.p1.z(), p.p2.x(), p.p2.y(), p.p2.z()});
  }
  input += "1,2,3\n";  // line 21: bad
  const CommandRun run = RunSpidarcad("ik --batch", input, "ik");
  ASSERT_EQ(run.status, 0) << run.err;
  const std::vector<std::string> lines = DataLines(run.out);
  ASSERT_EQ(lines.size(), poses.size() + 1);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const std::vector<double> expected = Eq7(poses[k], 0.24, 0.24, 0.24);
    const std::vector<std::string> f = Fields(lines[k]);
    ASSERT_EQ(f.size(), 8u);
    for (int i = 0; i < 8; ++i) EXPECT_NEAR(std::stod(f[i]), expected[i], 1e-15);
  }
  EXPECT_EQ(lines.back(), "nan,nan,nan,nan,nan,nan,nan,nan");
  EXPECT_NE(run.err.find("<stdin>:21:"), std::string::npos) << run.err;
  EXPECT_EQ(Lines(run.out)[0], "# l1,l2,l3,l4,l5,l6,l7,l8");
}

TEST(IkCommand, RoundTripsThroughFk) {
  const std::vector<Pose> poses = RandomPoses(10, 4, 0.04);
  std::string input;
  for (const Pose& p : poses) {
    input += Csv(
        {p.p0.x(), p.p0.y(), p.p0.z(), p.p1.x(), p.p1.y(), p.p1.z(), p.p2.x(), p.p2.y(), p.p2.z()});
  }
  const CommandRun ik = RunSpidarcad("ik --batch", input, "rt_ik");
  ASSERT_EQ(ik.status, 0);
  const CommandRun fk = RunSpidarcad("fk --batch", ik.out, "rt_fk");  // ik's '#' header is skipped
  ASSERT_EQ(fk.status, 0);
  const std::vector<std::string> lines = DataLines(fk.out);
  ASSERT_EQ(lines.size(), poses.size());
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const std::vector<std::string> f = Fields(lines[k]);
    EXPECT_EQ(f[11], "ok");
    EXPECT_NEAR(std::stod(f[2]), poses[k].p0.z(), 1e-9);
    EXPECT_NEAR(std::stod(f[8]), poses[k].p2.z(), 1e-9);
  }
}

TEST(FkCommand, BoundColumnHoldsOnQuantizedLengthsAndIsAbsentWithoutTheOption) {
  // Lengths quantized to the paper's encoder count are within ±Q = half a count of the truth:
  // the bound_m column must exceed the actual distance of the printed p0 from the true one.
  const double quantum = 2 * kPi * 0.008 / 2000;
  const std::vector<Pose> poses = RandomPoses(80, 5, 0.04);
  std::string input;
  for (const Pose& p : poses) {
    std::vector<double> l = Eq7(p, 0.24, 0.24, 0.24);
    for (double& x : l) x = std::round(x / quantum) * quantum;
    input += Csv(l);
  }
  char q_text[64];
  std::snprintf(q_text, sizeof(q_text), "%.17g", 0.5 * quantum);
  const CommandRun run = RunSpidarcad(std::string("fk --batch --bound ") + q_text, input, "bound");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(Lines(run.out)[0], "# x,y,z,x1,y1,z1,x2,y2,z2,grasp_rad,residual_m,status,bound_m");
  const CommandRun plain = RunSpidarcad("fk --batch", input, "plain");
  ASSERT_EQ(plain.status, 0);
  EXPECT_EQ(Lines(plain.out)[0], "# x,y,z,x1,y1,z1,x2,y2,z2,grasp_rad,residual_m,status");
  const std::vector<std::string> lines = DataLines(run.out), plain_lines = DataLines(plain.out);
  ASSERT_EQ(lines.size(), poses.size());
  ASSERT_EQ(plain_lines.size(), poses.size());
  std::vector<double> actual, bound;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const std::vector<std::string> f = Fields(lines[k]);
    ASSERT_EQ(f.size(), 13u) << lines[k];
    EXPECT_EQ(Fields(plain_lines[k]).size(), 12u);
    if (f[11] != "ok") {
      EXPECT_EQ(f[12], "nan");
      continue;
    }
    // The pose columns are those of the plain run.
    EXPECT_EQ(lines[k].substr(0, lines[k].rfind(',')), plain_lines[k]);
    const double b = std::stod(f[12]);
    const double error =
        (Eigen::Vector3d(std::stod(f[0]), std::stod(f[1]), std::stod(f[2])) - poses[k].p0).norm();
    EXPECT_LE(error, b) << "line " << k;
    if (std::isfinite(b)) {
      actual.push_back(error);
      bound.push_back(b);
    }
  }
  ASSERT_GT(actual.size(), 50u);
  std::sort(actual.begin(), actual.end());
  std::sort(bound.begin(), bound.end());
  EXPECT_LE(bound[bound.size() / 2], 10 * actual[actual.size() / 2]);
  EXPECT_GT(bound[bound.size() / 2], 0.0);
}

TEST(FkCommand, RejectsANegativeOrNonFiniteBoundWithStatus2) {
  for (const char* value : {"-1e-5", "inf", "abc"}) {
    const CommandRun run = RunSpidarcad(std::string("fk --batch --bound ") + value, "", "badbound");
    EXPECT_EQ(run.status, 2) << value;
    EXPECT_NE(run.err.find("--bound"), std::string::npos) << value << ": " << run.err;
  }
}

TEST(IkCommand, RefusesInfiniteAndNanCoordinatesLikeOtherBadLines) {
  std::string input;
  input += "0,0,0,0,0.04,0,0.04,0,0\n";    // line 1: ok
  input += "inf,0,0,0,0.04,0,0.04,0,0\n";  // line 2: x infinite
  input += "0,0,0,0,-inf,0,0.04,0,0\n";    // line 3: y1 minus infinity
  input += "0,0,0,0,0.04,0,0.04,0,nan\n";  // line 4: z2 NaN
  input += "0,0,0,0,0.04,0,0.04,0,0\n";    // line 5: ok
  const CommandRun run = RunSpidarcad("ik --batch", input, "inf");
  ASSERT_EQ(run.status, 0) << run.err;
  const std::vector<std::string> lines = DataLines(run.out);
  ASSERT_EQ(lines.size(), 5u);
  for (int k : {1, 2, 3}) EXPECT_EQ(lines[k], "nan,nan,nan,nan,nan,nan,nan,nan") << k;
  EXPECT_EQ(lines[0], lines[4]);
  EXPECT_EQ(Fields(lines[0]).size(), 8u);
  EXPECT_NE(lines[0].find("0.39395"), std::string::npos) << lines[0];
  for (const char* where :
       {"<stdin>:2: column 1 (x)", "<stdin>:3: column 5 (y1)", "<stdin>:4: column 9 (z2)"}) {
    EXPECT_NE(run.err.find(where), std::string::npos) << where << " in\n" << run.err;
  }
  EXPECT_EQ(run.err.find("<stdin>:1:"), std::string::npos);
}

}  // namespace
