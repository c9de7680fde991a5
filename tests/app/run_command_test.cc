// Tests of `spidarcad run`, run as a separate process. The wall force in the output is checked
// against the wall law applied to the output's own grip positions, and the tensions against
// their bounds; errors must exit with status 2 and say where.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "doc/command.h"
#include "doc/document.h"
#include "scene/assembly_scene.h"
#include "scene/document_file.h"
#include "scene/fe_part.h"
#include "spidarcad/fem/static_solver.h"
#include "spidarcad/haptics/trajectory.h"
#include "spidarcad/modeling/tet_mesh.h"
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
  const CommandRun r =
      RunSpidarcad("demo --trajectory '" + traj + "' --out '" + out + "'", "press");
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
      const double ramp = std::min(1.0, (i)*1e-3 / 0.5);
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
  ASSERT_EQ(
      RunSpidarcad("demo --trajectory '" + traj + "' --out '" + a + "' --hand 500,30", "det_a")
          .status,
      0);
  ASSERT_EQ(
      RunSpidarcad("demo --trajectory '" + traj + "' --out '" + b + "' --hand 500,30", "det_b")
          .status,
      0);
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
  r = RunSpidarcad("no_such_scene.json --trajectory '" + traj + "' --out '" + out + "'",
                   "bad_scene");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("SCENE: no_such_scene.json"), std::string::npos) << r.err;
  r = RunSpidarcad("--trajectory '" + traj + "' --out '" + out + "' --hand -1,2", "bad_hand");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--hand"), std::string::npos) << r.err;
  r = RunSpidarcad("--trajectory '" + traj + "' --out '" + out + "' --device usb", "bad_device");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--device"), std::string::npos) << r.err;
}

TEST(RunCommand, TrajectoryLongerThanTheLimitExitsTwoNamingLineAndField) {
  // From 0 to 1e300 s: used to report -9223372036854775807 ticks and exit 0.
  const std::string path = OutputPath("forever.csv");
  std::ofstream(path)
      << "# t,x,y,z,qw,qx,qy,qz,grasp\n0,0.05,0,0,1,0,0,0,1.5\n1,0.05,0,0,1,0,0,0,1.5\n"
         "1e300,0.05,0,0,1,0,0,0,1.5\n";
  const std::string out = OutputPath("forever_result.csv");
  std::remove(out.c_str());
  const CommandRun r =
      RunSpidarcad("demo --trajectory '" + path + "' --out '" + out + "'", "forever");
  EXPECT_EQ(r.status, 2) << r.all();
  EXPECT_NE(r.err.find(path + ":4: field t:"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--max-duration"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("3600 s"), std::string::npos) << r.err;
  EXPECT_FALSE(std::ifstream(out).good());
  // --max-duration raises the limit (here lowers it: 1 s of trajectory is over 0.5 s).
  std::ofstream(path) << "0,0.05,0,0,1,0,0,0,1.5\n1,0.05,0,0,1,0,0,0,1.5\n";
  const CommandRun lowered = RunSpidarcad(
      "demo --trajectory '" + path + "' --out '" + out + "' --max-duration 0.5", "lowered");
  EXPECT_EQ(lowered.status, 2) << lowered.all();
  EXPECT_NE(lowered.err.find(path + ":2: field t:"), std::string::npos) << lowered.err;
  const CommandRun bad = RunSpidarcad(
      "demo --trajectory '" + path + "' --out '" + out + "' --max-duration 1e300", "bad_max");
  EXPECT_EQ(bad.status, 2) << bad.all();
  EXPECT_NE(bad.err.find("--max-duration: must be in (0, 1e7] s"), std::string::npos) << bad.err;
}

TEST(RunCommand, TrajectoryThatIsNotARegularFileIsRefusedBeforeReading) {
  // /dev/zero used to be read as one endless line until std::bad_alloc (exit 1).
  const CommandRun r =
      RunSpidarcad("demo --trajectory /dev/zero --out '" + OutputPath("zero.csv") + "'", "zero");
  EXPECT_EQ(r.status, 2) << r.all();
  EXPECT_NE(r.err.find("--trajectory '/dev/zero': not a regular file"), std::string::npos) << r.err;
}

TEST(RunCommand, DocumentRendersItsSolidsAndListsTheKindsItSkips) {
  const std::string trajectory = WritePressTrajectory();
  const std::string scenes = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/scenes/";
  // The platform is the source of the FE model: it is felt as the FE part, not as a rigid solid.
  const CommandRun run = spidarcad::test_support::RunSpidarcad(
      "run '" + scenes + "workbench.json' --trajectory '" + trajectory + "' --out '" +
          OutputPath("wb.csv") + "'",
      "", "run_workbench",
      "env SPIDARCAD_CACHE_DIR='" + std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/run_wb_cache'");
  ASSERT_EQ(run.status, 0) << run.all();
  // Every object is rendered: the FE part, its rigid parts (a cap on a fixed base) as one
  // assembly field, and its sculpt object sculpted by the grip (a free grip here: the press never
  // closes the grasp). Nothing is skipped.
  EXPECT_NE(
      run.out.find("fields: fe_touch 'platform FE', assembly (2 parts), sculpt_tool 'clay'\n"),
      std::string::npos)
      << run.out;
  // The cap is saved in its seat on the base and the press never grasps it: seated, as the
  // window and `spidarcad info` say.
  EXPECT_NE(run.out.find("assembly: 1 of 1 parts seated (cap), carried: none\n"), std::string::npos)
      << run.out;
  EXPECT_EQ(run.out.find("skipped"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("sculpt 'clay': 0 strokes (grab, radius 0.02 m, volume not conserved)"),
            std::string::npos)
      << run.out;
  EXPECT_EQ(ReadCsv(OutputPath("wb.csv")).size(), 1502u);  // header + 1.5 s at 1 kHz

  // Only a sculpt object: its sculpt tool field alone, which is zero without a stroke (the press
  // never closes the grasp), so the grip moves freely; nothing is skipped.
  const CommandRun clay = RunSpidarcad("'" + scenes + "clay_sculpt.json' --trajectory '" +
                                           trajectory + "' --out '" + OutputPath("clay.csv") + "'",
                                       "clay");
  ASSERT_EQ(clay.status, 0) << clay.all();
  EXPECT_NE(clay.out.find("clay_sculpt.json (no solid) (1 field)"), std::string::npos) << clay.out;
  EXPECT_NE(clay.out.find("fields: sculpt_tool 'clay'\n"), std::string::npos) << clay.out;
  EXPECT_EQ(clay.out.find("skipped"), std::string::npos) << clay.out;
  const std::vector<std::vector<std::string>> rows = ReadCsv(OutputPath("clay.csv"));
  double max_force = 0.0;
  for (std::size_t r = 1; r < rows.size(); ++r)
    for (int c = 9; c < 12; ++c) max_force = std::max(max_force, std::abs(std::stod(rows[r][c])));
  EXPECT_EQ(max_force, 0.0);
}

TEST(RunCommand, DocumentFrameIsUsedUnlessFrameOrPoleIsGiven) {
  const std::string trajectory = WritePressTrajectory();
  const std::string doc = OutputPath("frame_doc.json");
  {
    std::ofstream out(doc);
    out << "{\"format\": \"spidarcad-scene\", \"version\": 2,\n"
           " \"device\": {\"frame\": [0.3, 0.28, 0.26], \"pole\": 0.05},\n"
           " \"objects\": [{\"kind\": \"solid\", \"name\": \"ball\", \"root\": "
           "{\"type\": \"sphere\", \"radius\": 0.02}}]}\n";
  }
  const std::string out = OutputPath("frame.csv");
  const CommandRun own =
      RunSpidarcad("'" + doc + "' --trajectory '" + trajectory + "' --out '" + out + "'", "frame");
  ASSERT_EQ(own.status, 0) << own.all();
  EXPECT_NE(own.out.find("frame: half-sides 0.3, 0.28, 0.26 m, pole 0.05 m (the document's)\n"),
            std::string::npos)
      << own.out;
  const CommandRun given = RunSpidarcad(
      "'" + doc + "' --trajectory '" + trajectory + "' --out '" + out + "' --pole 0.04",
      "frame_given");
  ASSERT_EQ(given.status, 0) << given.all();
  EXPECT_NE(given.out.find("frame: half-sides 0.24, 0.24, 0.24 m, pole 0.04 m (--frame/--pole)\n"),
            std::string::npos)
      << given.out;
  // A scene without a frame of its own runs on the default and prints no frame line.
  const CommandRun plain =
      RunSpidarcad("demo --trajectory '" + trajectory + "' --out '" + out + "'", "frame_default");
  ASSERT_EQ(plain.status, 0) << plain.all();
  EXPECT_EQ(plain.out.find("frame:"), std::string::npos) << plain.out;
}

// An assembly saved from the window is a version 2 document of rigid parts and no solid; run
// feels it as it felt the version 1 scene it came from: the same rows, tick for tick.
TEST(RunCommand, AssemblyOfRigidPartsRunsLikeTheVersion1SceneItCameFrom) {
  const std::string source = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/";
  const std::string v2 = OutputPath("assembly_v2.json");
  {
    spidarcad::app::Document doc;
    doc.Load(source + "scenes/assembly.json");
    ASSERT_TRUE(spidarcad::app::AdoptScenePartsAsRigidParts(&doc));
    doc.Save(v2);
  }
  const std::string traj = source + "trajectories/seat_right_leg.csv";
  const std::string a = OutputPath("asm_v1.csv"), b = OutputPath("asm_v2.csv");
  const CommandRun one = RunSpidarcad("'" + source + "scenes/assembly.json' --trajectory '" + traj +
                                          "' --out '" + a + "' --calibrate",
                                      "asm1");
  ASSERT_EQ(one.status, 0) << one.all();
  const CommandRun two = RunSpidarcad(
      "'" + v2 + "' --trajectory '" + traj + "' --out '" + b + "' --calibrate", "asm2");
  ASSERT_EQ(two.status, 0) << two.all();
  EXPECT_NE(two.out.find("fields: assembly (6 parts)"), std::string::npos) << two.out;
  EXPECT_EQ(two.out.find("skipped"), std::string::npos) << two.out;
  const size_t at = one.out.find("assembly: ");
  ASSERT_NE(at, std::string::npos) << one.out;
  const std::string seated = one.out.substr(at, one.out.find('\n', at) - at);
  EXPECT_NE(seated.find("right_leg"), std::string::npos) << seated;
  EXPECT_NE(two.out.find(seated), std::string::npos) << two.out;
  const auto ra = ReadCsv(a), rb = ReadCsv(b);
  ASSERT_EQ(ra.size(), rb.size());
  for (std::size_t i = 0; i < ra.size(); ++i) {
    for (std::size_t j = 0; j < ra[i].size(); ++j) {
      if (j == 24) continue;  // tick_us
      ASSERT_EQ(ra[i][j], rb[i][j]) << "row " << i << " column " << ra[0][j];
    }
  }
}

// Rigid parts beside a solid are felt as one assembly field in the solids' scene: the robot's
// rigid parts with a small ball 1 m away (X_WD fixed to the identity by --world-scale and
// --world-origin) run the seating trajectory as the parts alone do, row for row (the ball's
// proxy field adds nothing so far from the grip), and the right leg ends seated.
TEST(RunCommand, RigidPartsBesideASolidRunAsTheAssemblyAlone) {
  const std::string source = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/";
  const std::string parts = OutputPath("parts_only.json"), beside = OutputPath("parts_beside.json");
  {
    spidarcad::app::Document doc;
    doc.Load(source + "scenes/assembly.json");
    ASSERT_TRUE(spidarcad::app::AdoptScenePartsAsRigidParts(&doc));
    doc.Save(parts);
    std::vector<spidarcad::modeling::ImplicitNode> ball;
    ball.emplace_back(spidarcad::modeling::SphereParams{0.01},
                      std::vector<spidarcad::modeling::ImplicitNode>{}, "ball");
    doc.Execute(spidarcad::app::edit::AddSolid(
        "far", spidarcad::modeling::ImplicitNode(
                   spidarcad::modeling::TranslateParams{Eigen::Vector3d(1.0, 0.0, 0.0)},
                   std::move(ball), "far")));
    doc.Save(beside);
  }
  const std::string traj = source + "trajectories/seat_right_leg.csv";
  const std::string a = OutputPath("parts_only.csv"), b = OutputPath("parts_beside.csv");
  const std::string fixed = " --world-scale 1 --world-origin 0,0,0 --calibrate";
  const CommandRun one = RunSpidarcad(
      "'" + parts + "' --trajectory '" + traj + "' --out '" + a + "'" + fixed, "beside1");
  ASSERT_EQ(one.status, 0) << one.all();
  const CommandRun two = RunSpidarcad(
      "'" + beside + "' --trajectory '" + traj + "' --out '" + b + "'" + fixed, "beside2");
  ASSERT_EQ(two.status, 0) << two.all();
  EXPECT_NE(two.out.find("fields: proxy 'far', assembly (6 parts)"), std::string::npos) << two.out;
  EXPECT_EQ(two.out.find("skipped"), std::string::npos) << two.out;
  EXPECT_NE(two.out.find("assembly: 1 of 5 parts seated (right_leg), carried: none"),
            std::string::npos)
      << two.out;
  const auto ra = ReadCsv(a), rb = ReadCsv(b);
  ASSERT_EQ(ra.size(), rb.size());
  for (std::size_t i = 0; i < ra.size(); ++i) {
    for (std::size_t j = 0; j < ra[i].size(); ++j) {
      if (j == 24) continue;  // tick_us
      ASSERT_EQ(ra[i][j], rb[i][j]) << "row " << i << " column " << ra[0][j];
    }
  }
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
  const CommandRun r =
      RunSpidarcad("'" + scene + "' --trajectory '" + traj + "' --out '" + out + "'", "assembly");
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

namespace {

// Column index of `name` in a header row (-1 when absent).
int ColumnOf(const std::vector<std::string>& header, const std::string& name) {
  const auto it = std::find(header.begin(), header.end(), name);
  return it == header.end() ? -1 : static_cast<int>(it - header.begin());
}

// --device board-sim runs the USB driver (UsbSpidarG) against the board simulator over the
// loopback transport, with the same physical device (seed) as --device simulated. The contact
// force of the demo floor must be felt the same. Tolerance, per tick in the hold phase: 0.1 N.
// The two paths differ by (a) the tensions' 1 mN quantisation in the Command packet (< 4 mN of
// wrench), (b) one tick of delay: the driver's first Read has no State yet, so the loop starts a
// tick late and the board's device stepped through the handshake first, which shifts the
// device's noise stream (length noise 10 µm sd; × 2000 N/m = 0.02 N sd per sample, so per-tick
// forces may differ by up to ~0.1 N while their means agree; measured on this machine: 0.028 N
// at most, 0.0007 N on average). The means over the 0.3 s hold must agree within 0.02 N.
TEST(RunCommand, BoardSimDeviceFeelsTheSameFloorAsTheSimulatedDevice) {
  const std::string traj = WritePressTrajectory();
  const std::string sim = OutputPath("device_simulated.csv"),
                    board = OutputPath("device_board_sim.csv");
  const CommandRun a =
      RunSpidarcad("demo --trajectory '" + traj + "' --out '" + sim + "'", "dev_sim");
  ASSERT_EQ(a.status, 0) << a.err;
  const CommandRun b = RunSpidarcad(
      "demo --trajectory '" + traj + "' --out '" + board + "' --device board-sim", "dev_board");
  ASSERT_EQ(b.status, 0) << b.err;
  EXPECT_NE(b.out.find("device board-sim (USB driver over the board simulator, seed 1)"),
            std::string::npos)
      << b.out;
  EXPECT_NE(b.out.find("usb link: states 1501"), std::string::npos) << b.out;
  EXPECT_NE(b.out.find("disconnects 0"), std::string::npos) << b.out;
  const auto ra = ReadCsv(sim), rb = ReadCsv(board);
  ASSERT_EQ(ra.size(), rb.size());
  ASSERT_EQ(ra[0], rb[0]);  // same columns
  const int t = ColumnOf(ra[0], "t"), fz = ColumnOf(ra[0], "fz"), fx = ColumnOf(ra[0], "fx");
  const int events = ColumnOf(ra[0], "events");
  double sum_a = 0, sum_b = 0, max_diff = 0;
  int held = 0;
  for (std::size_t i = 1; i < ra.size(); ++i) {
    const double time = std::stod(ra[i][t]);
    if (time < 0.9 || time > 1.2) continue;
    const double fa = std::stod(ra[i][fz]), fb = std::stod(rb[i][fz]);
    sum_a += fa;
    sum_b += fb;
    max_diff = std::max(max_diff, std::abs(fa - fb));
    EXPECT_NEAR(std::stod(ra[i][fx]), std::stod(rb[i][fx]), 0.1) << "t " << time;
    EXPECT_EQ(std::stoi(rb[i][events]) & 0x3f, 0)
        << "zero-force event on the board-sim path at t " << time;
    ++held;
  }
  ASSERT_GT(held, 250);
  EXPECT_GT(sum_b / held, 2.0)
      << "the hand pressed 1 cm into the floor: the floor's force must be felt";
  EXPECT_NEAR(sum_b / held, sum_a / held, 0.02);
  EXPECT_LT(max_diff, 0.1);
}

// --device usb with no board attached: exit 2, saying what to check. (Assumes no SPIDAR-G
// controller is plugged into the machine running the tests.)
TEST(RunCommand, UsbDeviceWithNothingAttachedExitsTwoNamingWhatToCheck) {
  const std::string traj = WritePressTrajectory();
  const std::string out = OutputPath("usb_result.csv");
  std::remove(out.c_str());
  const CommandRun r =
      RunSpidarcad("demo --trajectory '" + traj + "' --out '" + out + "' --device usb", "usb");
  EXPECT_EQ(r.status, 2) << r.all();
  EXPECT_NE(r.err.find("--device usb: no SPIDAR-G controller board could be opened"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("spidarcad device list"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("assets/udev/99-spidarcad.rules"), std::string::npos) << r.err;
  EXPECT_FALSE(std::ifstream(out).good()) << "no output file when the device cannot be opened";
  const CommandRun bad =
      RunSpidarcad("demo --trajectory '" + traj + "' --out '" + out + "' --device bogus", "bogus");
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(
      bad.err.find("--device: 'bogus' is not a device; use simulated, ideal, board-sim or usb"),
      std::string::npos)
      << bad.err;
}

// A scene with "snap": a 40 mm cube at the origin (X_WD identity), snap max 0.8 N, vertex radius
// 30 mm. The hand holds the grip 8 mm outside the corner (20, 20, 20) mm along the diagonal.
// Checks, in the hold after the force ramp: (1) the loop commands the snap pull toward the corner
// as the loop sees it: 0.8 N · tanh(4d/r) (d < r/2: only the vertex pulls, w = 1) along the
// direction from the measured grip (fk, about 2 mm off the true grip with the nominal
// calibration) to the corner; (2) the hand is pulled: the true grip rests displaced from where
// the hand aims by the commanded force over the hand's stiffness (300 N/m), and closer to the
// corner than the aim. The same scene without "snap" commands no force (no contact).
TEST(RunCommand, SnapScenePullsTheGripTowardABoxCornerHeldNearIt) {
  const std::string solids =
      R"("solids": [{"name": "cube", "root": {"type": "box", "size": [0.04, 0.04, 0.04]}}])";
  const std::string with_snap = OutputPath("snap_cube.json"),
                    without = OutputPath("plain_cube.json");
  std::ofstream(with_snap)
      << R"({"format": "spidarcad-scene", "version": 1, "snap": {"max_force": 0.8,
      "vertex_radius": 0.03, "edge_radius": 0.01, "face_radius": 0.006}, )"
      << solids << "}\n";
  std::ofstream(without) << R"({"format": "spidarcad-scene", "version": 1, )" << solids << "}\n";
  const double d0 = 0.008, u = 1.0 / std::sqrt(3.0);
  const double aim = 0.02 + d0 * u;
  const std::string traj = OutputPath("snap_hold.csv");
  {
    std::ofstream out(traj);
    out << "# hold 8 mm off the corner (20, 20, 20) mm along the diagonal\n";
    out << "0," << aim << "," << aim << "," << aim << ",1,0,0,0,1.5707963\n";
    out << "1.5," << aim << "," << aim << "," << aim << ",1,0,0,0,1.5707963\n";
  }
  const std::string map = " --world-scale 1 --world-origin 0,0,0";
  const std::string out = OutputPath("snap_result.csv"),
                    plain_out = OutputPath("snap_plain_result.csv");
  const CommandRun r = RunSpidarcad(
      "'" + with_snap + "' --trajectory '" + traj + "' --out '" + out + "'" + map, "snap");
  ASSERT_EQ(r.status, 0) << r.all();
  EXPECT_NE(r.out.find("fields: proxy 'cube', snap '8 vertices, 12 edges, 6 faces'"),
            std::string::npos)
      << r.out;
  const auto rows = ReadCsv(out);
  const auto& h = rows.front();
  const int t = ColumnOf(h, "t"), x = ColumnOf(h, "x"), fx = ColumnOf(h, "fx"),
            fk_x = ColumnOf(h, "fk_x");
  const int events = ColumnOf(h, "events");
  ASSERT_GE(fk_x, 0);
  const Eigen::Vector3d corner(0.02, 0.02, 0.02);
  int checked = 0, observer = 0;
  double last_distance = 1.0;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    if (std::stod(rows[i][t]) < 1.0) continue;  // after the force ramp (0.5 s) and settling
    // Ticks where the passivity observer added damping (event bit 9, energy_limited: the encoder
    // noise feeds it a little energy) change the force on purpose; they must stay rare.
    if (std::stoi(rows[i][events]) & (1 << 9)) {
      ++observer;
      continue;
    }
    const Eigen::Vector3d f(std::stod(rows[i][fx]), std::stod(rows[i][fx + 1]),
                            std::stod(rows[i][fx + 2]));
    const Eigen::Vector3d p_fk(std::stod(rows[i][fk_x]), std::stod(rows[i][fk_x + 1]),
                               std::stod(rows[i][fk_x + 2]));
    const Eigen::Vector3d p(std::stod(rows[i][x]), std::stod(rows[i][x + 1]),
                            std::stod(rows[i][x + 2]));
    const Eigen::Vector3d to_corner = corner - p_fk;
    const double d = to_corner.norm();
    ASSERT_LT(d, 0.015) << "the measured grip left the vertex's inner zone at t " << rows[i][t];
    // (1) The snap profile at the measured position; the loop's damping and passivity terms
    // vanish at rest (tolerance 5 % + 5 mN).
    const double expected = 0.8 * std::tanh(4.0 * d / 0.03);
    EXPECT_NEAR(f.norm(), expected, 0.05 * expected + 0.005) << "t " << rows[i][t] << ", d " << d;
    EXPECT_GT(f.normalized().dot(to_corner.normalized()), std::cos(5.0 * M_PI / 180.0))
        << "t " << rows[i][t];
    // (2) The hand's spring balances the force the strings display: p − aim = f / 300 N/m
    // (within 10 % + 0.05 mm: the displayed force differs from the commanded by the tension
    // solve's and the motors' small errors).
    const Eigen::Vector3d displacement = p - Eigen::Vector3d::Constant(aim);
    EXPECT_LT((displacement - f / 300.0).norm(), 0.1 * f.norm() / 300.0 + 5e-5)
        << "t " << rows[i][t];
    last_distance = (corner - p).norm();
    ++checked;
  }
  EXPECT_GT(checked, 400);
  EXPECT_LT(observer, 25);
  EXPECT_LT(last_distance, d0 - 0.001) << "the grip was not pulled toward the corner";

  const CommandRun plain =
      RunSpidarcad("'" + without + "' --trajectory '" + traj + "' --out '" + plain_out + "'" + map,
                   "snap_plain");
  ASSERT_EQ(plain.status, 0) << plain.all();
  const auto plain_rows = ReadCsv(plain_out);
  for (std::size_t i = 1; i < plain_rows.size(); ++i) {
    for (int c = fx; c < fx + 3; ++c) ASSERT_EQ(std::stod(plain_rows[i][c]), 0.0) << "row " << i;
  }
}

}  // namespace

namespace {

// Distances |fk − true grip centre| (m) of every tick of a run's output: x,y,z is the hand's true
// grip centre p0, fk_x..fk_z the centre forward kinematics measured from the encoders. Ticks
// where FK refused (nan) count in *refused.
std::vector<double> FkErrors(const std::string& csv, int* refused) {
  const auto rows = ReadCsv(csv);
  std::vector<double> errors;
  *refused = 0;
  if (rows.empty()) return errors;
  const int x = ColumnOf(rows[0], "x"), fk = ColumnOf(rows[0], "fk_x");
  if (x < 0 || fk < 0) return errors;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    if (rows[i][fk] == "nan") {
      ++*refused;
      continue;
    }
    double sq = 0.0;
    for (int c = 0; c < 3; ++c) {
      const double e = std::stod(rows[i][fk + c]) - std::stod(rows[i][x + c]);
      sq += e * e;
    }
    errors.push_back(std::sqrt(sq));
  }
  return errors;
}

double Mean(const std::vector<double>& v) {
  double sum = 0.0;
  for (double e : v) sum += e;
  return v.empty() ? 0.0 : sum / static_cast<double>(v.size());
}

// --calibrate calibrates the simulated device as the window does (a line fit on 24 jig poses)
// and reads it through the fit: along the shipped circle (4 cm radius, 4 s, empty scene) forward
// kinematics must land much closer to the hand's true grip than through the nominal model, whose
// encoder gain errors (~6 %) put it millimetres off (measured: 3.0 mm mean nominal, 0.28 mm
// calibrated; the rest is string stretch and noise, which a line per string cannot remove).
TEST(RunCommand, CalibrateBringsForwardKinematicsCloseToTheTrueGrip) {
  const std::string traj = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/trajectories/circle.csv";
  const std::string nominal = OutputPath("fk_nominal.csv"),
                    calibrated = OutputPath("fk_calibrated.csv");
  const CommandRun a =
      RunSpidarcad("--trajectory '" + traj + "' --out '" + nominal + "'", "fk_nominal");
  ASSERT_EQ(a.status, 0) << a.all();
  EXPECT_EQ(a.out.find("calibration:"), std::string::npos) << "no calibration without --calibrate\n"
                                                           << a.out;
  const CommandRun b = RunSpidarcad(
      "--trajectory '" + traj + "' --out '" + calibrated + "' --calibrate", "fk_calibrated");
  ASSERT_EQ(b.status, 0) << b.all();
  EXPECT_NE(b.out.find("calibration: line-fit calibration on 24 jig poses (rms "),
            std::string::npos)
      << b.out;
  int refused_a = 0, refused_b = 0;
  const std::vector<double> ea = FkErrors(nominal, &refused_a),
                            eb = FkErrors(calibrated, &refused_b);
  ASSERT_EQ(ea.size() + refused_a, 4001u);
  ASSERT_EQ(eb.size() + refused_b, 4001u);
  EXPECT_EQ(refused_b, 0) << "FK refused ticks of the calibrated run";
  const double mean_a = Mean(ea), mean_b = Mean(eb);
  const double max_b = *std::max_element(eb.begin(), eb.end());
  EXPECT_GT(mean_a, 1e-3) << "the nominal model was expected to be millimetres off";
  EXPECT_LT(mean_b, 0.6e-3);
  EXPECT_LT(max_b, 1e-3);
  EXPECT_LT(mean_b, 0.25 * mean_a)
      << "nominal " << mean_a * 1e3 << " mm, calibrated " << mean_b * 1e3 << " mm";
}

// The calibration is the simulated device's: with a real board (--device usb) --calibrate is
// refused before anything is opened or written, naming the option and what to use instead.
TEST(RunCommand, CalibrateWithTheUsbDeviceExitsTwoNamingTheOption) {
  const std::string traj = WritePressTrajectory();
  const std::string out = OutputPath("calibrate_usb.csv");
  std::remove(out.c_str());
  const CommandRun r = RunSpidarcad(
      "demo --trajectory '" + traj + "' --out '" + out + "' --device usb --calibrate", "cal_usb");
  EXPECT_EQ(r.status, 2) << r.all();
  EXPECT_NE(r.err.find("--calibrate: not with --device usb"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("spidarcad calibrate"), std::string::npos) << r.err;
  EXPECT_FALSE(std::ifstream(out).good()) << "no output file for a refused option";
}

// A self-calibration file of the simulated SPIDAR-G of seed 1 (`calibrate --out`), made once.
std::string SelfCalibrationFile() {
  static const std::string path = [] {
    const std::string p = OutputPath("self_seed1.json");
    const CommandRun r = spidarcad::test_support::RunSpidarcad(
        "calibrate --simulated --seed 1 --method self --eval-poses 5 --out '" + p + "'", "",
        "run_make_calibration");
    EXPECT_EQ(r.status, 0) << r.all();
    return p;
  }();
  return path;
}

// --calibration reads the encoders through a file made by `calibrate`: along the circle,
// forward kinematics lands within a fraction of a millimetre of the hand's true grip (the
// self-calibration fits stretch too; measured: 0.03 mm mean).
TEST(RunCommand, CalibrationFileBringsForwardKinematicsToTheTrueGrip) {
  const std::string traj = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/trajectories/circle.csv";
  const std::string file = SelfCalibrationFile();
  const std::string out = OutputPath("fk_file.csv");
  const CommandRun r = RunSpidarcad(
      "--trajectory '" + traj + "' --out '" + out + "' --calibration '" + file + "'", "fk_file");
  ASSERT_EQ(r.status, 0) << r.all();
  EXPECT_NE(r.out.find("calibration: " + file +
                       " (self-calibration of the simulated SPIDAR-G seed 1, 20"),
            std::string::npos)
      << r.out;
  int refused = 0;
  const std::vector<double> e = FkErrors(out, &refused);
  ASSERT_EQ(e.size() + refused, 4001u);
  EXPECT_EQ(refused, 0);
  EXPECT_LT(Mean(e), 0.1e-3);
  EXPECT_LT(*std::max_element(e.begin(), e.end()), 0.2e-3);
  // The same simulated SPIDAR-G behind the board simulator takes the same file.
  const CommandRun b =
      RunSpidarcad("--trajectory '" + traj + "' --out '" + OutputPath("fk_file_b.csv") +
                       "' --device board-sim --calibration '" + file + "'",
                   "fk_file_board");
  EXPECT_EQ(b.status, 0) << b.all();
}

// A file made on another device or for another frame is refused before anything is written,
// with the reason.
TEST(RunCommand, CalibrationFileOfAnotherSeedOrFrameIsRefusedWithTheReason) {
  const std::string traj = WritePressTrajectory();
  const std::string file = SelfCalibrationFile();
  const std::string out = OutputPath("refused.csv");
  std::remove(out.c_str());
  const CommandRun seed = RunSpidarcad(
      "--trajectory '" + traj + "' --out '" + out + "' --seed 2 --calibration '" + file + "'",
      "cal_seed");
  EXPECT_EQ(seed.status, 2) << seed.all();
  EXPECT_NE(seed.err.find("does not fit: it was made on the simulated SPIDAR-G seed 1, this "
                          "session uses seed 2"),
            std::string::npos)
      << seed.err;
  const CommandRun frame = RunSpidarcad("--trajectory '" + traj + "' --out '" + out +
                                            "' --frame 0.3,0.3,0.3 --calibration '" + file + "'",
                                        "cal_frame");
  EXPECT_EQ(frame.status, 2) << frame.all();
  EXPECT_NE(frame.err.find("frame --frame 0.24,0.24,0.24 --pole 0.04, this session's frame is "
                           "--frame 0.3,0.3,0.3 --pole 0.04"),
            std::string::npos)
      << frame.err;
  EXPECT_FALSE(std::ifstream(out).good());
  const CommandRun both = RunSpidarcad(
      "--trajectory '" + traj + "' --out '" + out + "' --calibrate --calibration '" + file + "'",
      "cal_both");
  EXPECT_EQ(both.status, 2) << both.all();
  EXPECT_NE(both.err.find("choose one"), std::string::npos) << both.err;
  const CommandRun missing = RunSpidarcad("--trajectory '" + traj + "' --out '" + out +
                                              "' --calibration '" + OutputPath("none.json") + "'",
                                          "cal_missing");
  EXPECT_EQ(missing.status, 2) << missing.all();
  EXPECT_NE(missing.err.find("--calibration: "), std::string::npos) << missing.err;
}

// --frame/--pole size the simulated SPIDAR-G: the loop's forward kinematics then places the
// grip where the hand holds it in that frame (millimetres, the nominal model's gain error), and
// a grip that does not fit the frame is refused.
TEST(RunCommand, FrameAndPoleSizeTheDevice) {
  const std::string traj = std::string(SPIDARCAD_SOURCE_DIR) + "/assets/trajectories/circle.csv";
  const std::string out = OutputPath("frame.csv");
  const CommandRun r = RunSpidarcad(
      "--trajectory '" + traj + "' --out '" + out + "' --frame 0.3,0.28,0.26 --pole 0.05", "frame");
  ASSERT_EQ(r.status, 0) << r.all();
  int refused = 0;
  const std::vector<double> e = FkErrors(out, &refused);
  ASSERT_EQ(e.size() + refused, 4001u);
  EXPECT_EQ(refused, 0);
  EXPECT_LT(Mean(e), 1e-2);
  const CommandRun bad = RunSpidarcad(
      "--trajectory '" + traj + "' --out '" + out + "' --frame 0.2,0.2,0.2 --pole 0.25",
      "frame_bad");
  EXPECT_EQ(bad.status, 2) << bad.all();
  EXPECT_NE(bad.err.find("--frame/--pole"), std::string::npos) << bad.err;
}

}  // namespace

namespace {

// Index of column `name` in a CSV's header row (−1 when absent).
int ColumnIndex(const std::vector<std::vector<std::string>>& rows, const std::string& name) {
  const auto& h = rows.at(0);
  const auto it = std::find(h.begin(), h.end(), name);
  return it == h.end() ? -1 : static_cast<int>(it - h.begin());
}

// The steel platform of assets/scenes/platform_fe.json (clamped wall, 50 N on the tip) pressed
// with assets/trajectories/press.csv: X_WD puts the press's 1 cm-deep aim at the plate's top
// face (z = 0.01 m), as the platform_press golden does for the rigid solid.
const char* const kFePressMap = " --world-scale 1 --world-origin 0.1,0,0.04";

// `run` renders the document's FE model (not its source solid as a rigid one), feels it push
// back, and writes the same CSV twice: once computing the columns near the path (cold disk
// cache) and once reading them from the disk cache. Then, independently: a replay of the run's
// measured tool path through a field built in this process gives the CSV's FE columns tick for
// tick, and at the tick of the largest reaction the contact forces equal a full sparse solve of
// the model with the contact nodes' displacements prescribed (fem::StaticSolver, no
// condensation) to 1e-9 relative.
TEST(RunCommand, FeModelIsPushedExactlyAndTheRunIsDeterministic) {
  const std::string source = std::string(SPIDARCAD_SOURCE_DIR);
  const std::string scene = source + "/assets/scenes/platform_fe.json";
  const std::string traj = source + "/assets/trajectories/press.csv";
  const std::filesystem::path cache = OutputPath("fe_cache");
  std::filesystem::remove_all(cache);
  const std::string env = "env SPIDARCAD_CACHE_DIR='" + cache.string() + "'";
  const std::string args = "run '" + scene + "' --trajectory '" + traj + "'" + kFePressMap;
  const std::string cold_csv = OutputPath("fe_cold.csv"), warm_csv = OutputPath("fe_warm.csv");
  const CommandRun cold = spidarcad::test_support::RunSpidarcad(args + " --out '" + cold_csv + "'",
                                                                "", "run_fe_cold", env);
  ASSERT_EQ(cold.status, 0) << cold.all();
  EXPECT_NE(cold.out.find("fields: fe_touch 'platform FE'\n"), std::string::npos) << cold.out;
  EXPECT_EQ(cold.out.find("skipped"), std::string::npos) << cold.out;
  EXPECT_NE(cold.out.find("fe 'platform FE': "), std::string::npos) << cold.out;
  EXPECT_NE(cold.out.find("(0 from the disk cache, "), std::string::npos) << cold.out;
  EXPECT_NE(cold.out.find("0 ticks read a substitute column"), std::string::npos) << cold.out;
  // Again, from the disk cache, writing the final state of the FE model and the document.
  const std::string vtu = OutputPath("fe_final.vtu"), saved = OutputPath("fe_saved.json");
  const CommandRun warm = spidarcad::test_support::RunSpidarcad(
      args + " --out '" + warm_csv + "' --export 'platform FE=" + vtu + "' --save '" + saved + "'",
      "", "run_fe_warm", env);
  ASSERT_EQ(warm.status, 0) << warm.all();
  EXPECT_NE(warm.out.find(" 0 computed, "), std::string::npos) << warm.out;
  EXPECT_NE(warm.out.find("wrote " + vtu + " ('platform FE' at the last tick: "), std::string::npos)
      << warm.out;

  const auto rows = ReadCsv(cold_csv);
  const auto again = ReadCsv(warm_csv);
  ASSERT_EQ(rows.size(), again.size());
  ASSERT_GT(rows.size(), 2u);
  const int tick_us = ColumnIndex(rows, "tick_us");
  for (std::size_t r = 0; r < rows.size(); ++r) {
    std::vector<std::string> a = rows[r], b = again[r];
    ASSERT_EQ(a.size(), b.size()) << "row " << r;
    a[tick_us] = b[tick_us] = "";  // wall-clock time
    ASSERT_EQ(a, b) << "row " << r;
  }
  // Today's columns, then the FE ones.
  const std::vector<std::string> fe_names = {"fe_contacts", "fe_fx", "fe_fy", "fe_fz"};
  ASSERT_EQ(rows[0].size(), 33u);
  EXPECT_EQ(std::vector<std::string>(rows[0].end() - 4, rows[0].end()), fe_names);
  const int c_contacts = ColumnIndex(rows, "fe_contacts"), c_fx = ColumnIndex(rows, "fe_fx");
  const int c_fz = ColumnIndex(rows, "fz"), c_fk = ColumnIndex(rows, "fk_x");

  // The force felt rises as the tool presses the plate: nothing before the first contact, up
  // (+z) once the plate pushes back, most where the reaction is largest.
  std::size_t first = 0, deepest = 0;
  double largest = 0.0;
  for (std::size_t r = 1; r < rows.size(); ++r) {
    const Eigen::Vector3d f(std::stod(rows[r][c_fx]), std::stod(rows[r][c_fx + 1]),
                            std::stod(rows[r][c_fx + 2]));
    if (first == 0 && std::stoi(rows[r][c_contacts]) > 0) first = r;
    if (f.norm() > largest) {
      largest = f.norm();
      deepest = r;
    }
  }
  ASSERT_GT(first, 1u);
  ASSERT_GT(deepest, first);
  // Before the first contact only the coupling's stop at the surface (conservative advancement,
  // the tick before contact) may be felt, and little of it.
  for (std::size_t r = 1; r < first; ++r)
    EXPECT_LT(std::abs(std::stod(rows[r][c_fz])), 0.05) << "row " << r;
  const double fz_deep = std::stod(rows[deepest][c_fz]);
  EXPECT_GT(fz_deep, 0.2);                             // N, felt at the grip
  EXPECT_GT(std::stod(rows[deepest][c_fx + 2]), 0.0);  // the plate pushes the tool up
  EXPECT_GT(fz_deep, std::stod(rows[first][c_fz]));

  // The replay: the same builder, the same columns (from the same disk cache).
  const spidarcad::app::OpenedDocument opened = spidarcad::app::OpenDocumentFile(scene);
  const std::vector<spidarcad::app::ObjectId> fe = spidarcad::app::FeModelsOf(*opened.doc);
  ASSERT_EQ(fe.size(), 1u);
  spidarcad::app::FePartOptions options;
  options.world_scale = 1.0;
  options.model.cache.start_worker = false;
  options.model.cache_directory = cache;
  spidarcad::app::FePart part = spidarcad::app::BuildFePart(*opened.doc, fe[0], options);
  const spidarcad::haptics::DeviceToWorld X_WD{1.0, Eigen::Vector3d(0.1, 0, 0.04)};
  const spidarcad::app::FeColumnPlan plan = spidarcad::app::PrepareTrajectoryColumns(
      &part, spidarcad::haptics::Trajectory::Load(traj), X_WD, false, cache);
  EXPECT_EQ(plan.computed, 0);
  EXPECT_EQ(plan.ready, plan.requested);
  spidarcad::app::FeContactState deep;
  for (std::size_t r = 1; r < rows.size(); ++r) {
    if (rows[r][c_fk] == "nan") continue;  // no pose: the loop did not evaluate the field
    spidarcad::haptics::ToolKinematics tool;
    tool.time = std::stod(rows[r][0]);
    tool.p_WT = X_WD.PointToWorld(Eigen::Vector3d(
        std::stod(rows[r][c_fk]), std::stod(rows[r][c_fk + 1]), std::stod(rows[r][c_fk + 2])));
    part.field->Evaluate(tool);
    const spidarcad::app::FeContactState& st = part.field->last_state();
    ASSERT_EQ(st.num_contacts, std::stoi(rows[r][c_contacts])) << "row " << r;
    for (int i = 0; i < 3; ++i)
      ASSERT_EQ(st.f_tool_W(i), std::stod(rows[r][c_fx + i])) << "row " << r << " axis " << i;
    if (r == deepest) deep = st;
  }
  ASSERT_GT(deep.num_contacts, 0);
  EXPECT_EQ(deep.num_substituted, 0);

  // The full solve: clamps and loads of the model, the contact nodes moved to their targets.
  const spidarcad::app::FeModel& model = *part.model;
  spidarcad::fem::BoundaryConditions bcs = model.bcs();
  std::vector<int> nodes;
  for (int s = 0; s < deep.num_contacts; ++s) {
    nodes.push_back(model.cache().candidate_node(deep.candidate[s]));
    bcs.PrescribeNode(nodes.back(), Eigen::Vector3d(deep.target[3 * s], deep.target[3 * s + 1],
                                                    deep.target[3 * s + 2]));
  }
  const spidarcad::fem::StaticSolver full(model.mesh(), model.materials(), bcs);
  ASSERT_TRUE(full.factor_status().converged) << full.factor_status().message;
  const spidarcad::fem::StaticSolution solution = full.Solve();
  ASSERT_TRUE(solution.status.converged) << solution.status.message;
  Eigen::Vector3d f_full = Eigen::Vector3d::Zero();
  for (int s = 0; s < deep.num_contacts; ++s) {
    const Eigen::Vector3d f_s = solution.reaction.segment<3>(3 * nodes[s]);
    const Eigen::Vector3d f_fe(deep.force[3 * s], deep.force[3 * s + 1], deep.force[3 * s + 2]);
    EXPECT_LE((f_s - f_fe).norm(), 1e-9 * deep.f_tool_W.norm()) << "contact " << s;
    f_full -= f_s;
  }
  EXPECT_LE((f_full - deep.f_tool_W).norm(), 1e-9 * deep.f_tool_W.norm())
      << "full " << f_full.transpose() << " FE " << deep.f_tool_W.transpose();

  // --export: the last tick's state, read back with the project's VTU reader, is the full solve
  // of the replay's last contact state.
  const spidarcad::app::FeContactState last = part.field->last_state();
  spidarcad::fem::BoundaryConditions last_bcs = model.bcs();
  for (int s = 0; s < last.num_contacts; ++s)
    last_bcs.PrescribeNode(
        model.cache().candidate_node(last.candidate[s]),
        Eigen::Vector3d(last.target[3 * s], last.target[3 * s + 1], last.target[3 * s + 2]));
  const spidarcad::fem::StaticSolution last_solution =
      spidarcad::fem::StaticSolver(model.mesh(), model.materials(), last_bcs).Solve();
  const spidarcad::modeling::VtuGrid grid = spidarcad::modeling::ReadVtuGrid(vtu);
  ASSERT_EQ(grid.points.cols(), model.mesh().num_nodes());
  ASSERT_EQ(grid.point_data.count("displacement"), 1u);
  ASSERT_EQ(grid.point_data.count("von_mises"), 1u);
  const Eigen::MatrixXd& u = grid.point_data.at("displacement");
  ASSERT_EQ(u.rows(), 3);
  const double u_max = last_solution.displacement.cwiseAbs().maxCoeff();
  ASSERT_GT(u_max, 0.0);
  for (int v = 0; v < model.mesh().num_nodes(); ++v)
    for (int i = 0; i < 3; ++i)
      ASSERT_NEAR(u(i, v), last_solution.displacement(3 * v + i), 1e-9 * u_max) << v;
  EXPECT_GT(grid.point_data.at("von_mises").maxCoeff(), 0.0);
  EXPECT_GE(grid.point_data.at("von_mises").minCoeff(), 0.0);
  // --save: the document as it stands at the end (a run does not change it).
  const spidarcad::app::OpenedDocument reopened = spidarcad::app::OpenDocumentFile(saved);
  ASSERT_EQ(reopened.doc->objects().size(), opened.doc->objects().size());
  for (std::size_t i = 0; i < opened.doc->objects().size(); ++i)
    EXPECT_EQ(reopened.doc->objects()[i].name, opened.doc->objects()[i].name);
}

// --export and --save are checked before any work: a name that is no FE model, a file that is
// not .vtu, a missing '=', and either of them without a document exit 2 saying so.
TEST(RunCommand, ExportAndSaveRefuseBadInputBeforeTheRun) {
  const std::string source = std::string(SPIDARCAD_SOURCE_DIR);
  const std::string scene = "'" + source + "/assets/scenes/platform_fe.json'";
  const std::string run = scene + " --trajectory '" + source +
                          "/assets/trajectories/press.csv' --out '" + OutputPath("bad_fe.csv") +
                          "'";
  const struct {
    std::string args, message;
  } cases[] = {
      {run + " --export 'nothing=a.vtu'",
       "--export nothing=a.vtu: the document has no object named 'nothing'; its FE models: "
       "'platform FE'"},
      {run + " --export 'platform=a.vtu'",
       "--export platform=a.vtu: 'platform' is a solid, not an FE model run renders"},
      {run + " --export 'platform FE=a.stl'",
       "--export platform FE=a.stl: an FE model is written as .vtu"},
      {run + " --export 'platform FE'", "--export 'platform FE': expected NAME=FILE"},
      {"demo --trajectory '" + source + "/assets/trajectories/press.csv' --out '" +
           OutputPath("bad_fe.csv") + "' --save x.json",
       "--save: needs a scene file or document (SCENE is 'demo')"},
  };
  for (const auto& c : cases) {
    const CommandRun r = RunSpidarcad(c.args, "export_bad");
    EXPECT_EQ(r.status, 2) << c.args << "\n" << r.all();
    EXPECT_NE(r.err.find(c.message), std::string::npos) << r.err;
    EXPECT_EQ(r.out.find("fe 'platform FE'"), std::string::npos) << "built before refusing";
  }
}

}  // namespace
