// Tests of `spidarcad run`, run as a separate process. The wall force in the output is checked
// against the wall law applied to the output's own grip positions, and the tensions against
// their bounds; errors must exit with status 2 and say where.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "spidarcad_runner.h"

namespace {

using spidarcad::test_support::CommandRun;
using spidarcad::test_support::ReadWholeFile;

std::string OutputPath(const std::string& name) {
  return std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/run_" + name;
}

// Runs `spidarcad run ARGS`; `tag` names the scratch files.
CommandRun RunSpidarcad(const std::string& args, const std::string& tag) {
  return spidarcad::test_support::RunSpidarcad("run " + args, "", "run_" + tag);
}

// Press into the demo floor (z = −0.03 m) from 2 cm above, the hand aiming 1 cm deep, in 1.5 s.
std::string WritePressTrajectory() {
  const std::string path = OutputPath("press.csv");
  std::ofstream out(path);
  out << "# t,x,y,z,qw,qx,qy,qz,grasp\n";
  for (int k = 0; k <= 150; ++k) {
    const double t = 0.01 * k;
    const double s = t < 0.6 ? t / 0.6 : (t < 1.2 ? 1.0 : 1.0 - (t - 1.2) / 0.3);
    out << t << ",0.05,0," << (-0.01 - 0.03 * s) << ",1,0,0,0,1.5707963\n";
  }
  return path;
}

std::vector<std::vector<std::string>> ReadCsv(const std::string& path) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> row;
    std::stringstream fields(line);
    std::string f;
    while (std::getline(fields, f, ',')) row.push_back(f);
    rows.push_back(row);
  }
  return rows;
}

TEST(RunCommand, WritesOneRowPerTickWithTheWallForceOfTheDemoScene) {
  const std::string traj = WritePressTrajectory();
  const std::string out = OutputPath("press_result.csv");
  const CommandRun r = RunSpidarcad("demo --trajectory '" + traj + "' --out '" + out + "'", "press");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.out.find("tick time [us]: p50"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("ramping="), std::string::npos);
  const auto rows = ReadCsv(out);
  ASSERT_EQ(rows.size(), 1u + 1501u);  // header + 1.5 s at 1 kHz inclusive
  const std::string header =
      "t,x,y,z,qw,qx,qy,qz,grasp,fx,fy,fz,mx,my,mz,g,tau1,tau2,tau3,tau4,tau5,tau6,tau7,tau8,"
      "tick_us";
  std::string got;
  for (std::size_t i = 0; i < 25; ++i) got += (i ? "," : "") + rows[0][i];
  EXPECT_EQ(got, header);
  double max_fz_inside = 0;
  int checked = 0, above = 0;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), rows[0].size()) << "row " << i;
    const double t = std::stod(rows[i][0]);
    const double z = std::stod(rows[i][3]);
    const double fz = std::stod(rows[i][11]);
    for (int s = 16; s < 24; ++s) {
      const double tau = std::stod(rows[i][s]);
      ASSERT_GE(tau, 0.2 - 1e-12);
      ASSERT_LE(tau, 8.0 + 1e-12);
    }
    // After the ramp (0.5 s), with the hand at rest in the hold phase: the demo's laws at the
    // position the loop measured (fk_z): floor 2000 N/m × depth plus the 20 N/m spring toward
    // z = 0 (damping terms vanish at rest). The true grip is within the encoder error of it.
    const double fk_z = std::stod(rows[i][28]);
    if (t > 0.9 && t < 1.2) {
      const double depth = std::max(0.0, -0.03 - fk_z);
      EXPECT_NEAR(fz, 2000.0 * depth - 20.0 * fk_z, 0.3) << "t " << t;
      EXPECT_NEAR(z, fk_z, 5e-3) << "t " << t;
      max_fz_inside = std::max(max_fz_inside, fz);
      ++checked;
    }
    // Above the floor on the way down, in the force ramp (0.5 s, from 0 at the first tick): the
    // ramped spring (its damping, 0.5 N·s/m × 5 cm/s, is within the tolerance).
    if (t < 0.6 && fk_z > -0.02) {
      const double ramp = std::min(1.0, (i) * 1e-3 / 0.5);
      EXPECT_NEAR(fz, ramp * -20.0 * fk_z, 0.03) << "above the floor, t " << t;
      ++above;
    }
  }
  EXPECT_GT(checked, 200);
  EXPECT_GT(above, 100);
  EXPECT_GT(max_fz_inside, 2.0);  // the hand really pressed into the floor
}

TEST(RunCommand, SameRunGivesTheSameNumbersExceptTickTime) {
  const std::string traj = WritePressTrajectory();
  const std::string a = OutputPath("det_a.csv"), b = OutputPath("det_b.csv");
  ASSERT_EQ(RunSpidarcad("demo --trajectory '" + traj + "' --out '" + a + "' --hand 500,30", "det_a").status, 0);
  ASSERT_EQ(RunSpidarcad("demo --trajectory '" + traj + "' --out '" + b + "' --hand 500,30", "det_b").status, 0);
  const auto ra = ReadCsv(a), rb = ReadCsv(b);
  ASSERT_EQ(ra.size(), rb.size());
  for (std::size_t i = 0; i < ra.size(); ++i) {
    for (std::size_t j = 0; j < ra[i].size(); ++j) {
      if (j == 24) continue;  // tick_us
      ASSERT_EQ(ra[i][j], rb[i][j]) << "row " << i << " column " << ra[0][j];
    }
  }
}

TEST(RunCommand, BadInputExitsWithStatusTwoAndSaysWhere) {
  const std::string bad = OutputPath("bad.csv");
  std::ofstream(bad) << "# comment\n0,0,0,0,1,0,0,0,1.5\n0.1,0,zz,0,1,0,0,0,1.5\n";
  const std::string out = OutputPath("bad_result.csv");
  CommandRun r = RunSpidarcad("--trajectory '" + bad + "' --out '" + out + "'", "bad_traj");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find(bad + ":3: field 'y': 'zz' is not a number"), std::string::npos) << r.err;

  const std::string traj = WritePressTrajectory();
  r = RunSpidarcad("no_such_scene.json --trajectory '" + traj + "' --out '" + out + "'", "bad_scene");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("SCENE: no_such_scene.json"), std::string::npos) << r.err;
  r = RunSpidarcad("--trajectory '" + traj + "' --out '" + out + "' --hand -1,2", "bad_hand");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--hand"), std::string::npos) << r.err;
  r = RunSpidarcad("--trajectory '" + traj + "' --out '" + out + "' --device usb", "bad_device");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--device"), std::string::npos) << r.err;
}

TEST(RunCommand, EmptySceneCommandsNoForce) {
  const std::string traj = WritePressTrajectory();
  const std::string out = OutputPath("empty_result.csv");
  const CommandRun r = RunSpidarcad("--trajectory '" + traj + "' --out '" + out + "'", "empty");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto rows = ReadCsv(out);
  ASSERT_GT(rows.size(), 1000u);
  for (std::size_t i = 1; i < rows.size(); ++i) {
    for (int c = 9; c < 16; ++c) ASSERT_EQ(std::stod(rows[i][c]), 0.0) << "row " << i;
  }
}

}  // namespace

namespace {

TEST(RunCommand, AssemblySceneRendersTheFixedBodyWhenPressedAgainst) {
  // assets/scenes/assembly.json: the torso (fixed) spans y in [-0.015, 0.015] m at z 0.055..0.115
  // with X_WD identity. The hand comes from y = -0.04 toward y = -0.005 (1 cm into the plain front
  // face) at z = 0.085, holds, and leaves; the assembly field must push the grip back along -y.
  const std::string traj = OutputPath("assembly_press.csv");
  {
    std::ofstream out(traj);
    out << "# t,x,y,z,qw,qx,qy,qz,grasp\n";
    for (int k = 0; k <= 200; ++k) {
      const double t = 0.01 * k;
      const double s = t < 0.8 ? t / 0.8 : (t < 1.6 ? 1.0 : 1.0 - (t - 1.6) / 0.4);
      out << t << ",0," << (-0.04 + 0.035 * s) << ",0.085,1,0,0,0,1.5707963\n";
    }
  }
  const std::string scene = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/assembly.json";
  const std::string out = OutputPath("assembly_result.csv");
  const CommandRun r = RunSpidarcad("'" + scene + "' --trajectory '" + traj + "' --out '" + out + "'", "assembly");
  ASSERT_EQ(r.status, 0) << r.all();
  EXPECT_NE(r.out.find("fields: assembly (6 parts)"), std::string::npos) << r.out;
  const auto rows = ReadCsv(out);
  ASSERT_GT(rows.size(), 1000u);
  const auto& header = rows.front();
  const auto column = [&](const std::string& name) {
    return static_cast<int>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  const int iy = column("y"), ify = column("fy"), ifx = column("fx"), ifz = column("fz");
  ASSERT_LT(ify, static_cast<int>(header.size()));
  double min_fy = 0.0, max_free = 0.0;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    const double y = std::stod(rows[i][iy]), fy = std::stod(rows[i][ify]);
    const double f = std::hypot(std::stod(rows[i][ifx]), fy, std::stod(rows[i][ifz]));
    min_fy = std::min(min_fy, fy);
    if (y < -0.025) max_free = std::max(max_free, f);  // 7 mm clear of the face (sphere 3 mm)
  }
  EXPECT_LT(min_fy, -0.5) << "the grip pressed 1 cm into the torso but felt no push back along -y";
  EXPECT_LT(max_free, 0.05) << "force felt while clear of every part";
}

}  // namespace
