// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Golden regression runs of `spidarcad run`: each demo scene on a scripted trajectory, compared
// with a golden result in tests/golden/<scene>_<trajectory>.csv under stated tolerances. The
// run is deterministic on the virtual clock (the simulated device's errors are seeded), so the
// tolerances are tight; they only allow for floating-point differences between compilers and
// libm versions. tick_us (wall-clock time) and fk_x..fk_z (derived from the compared tensions'
// inputs) are never compared. Goldens keep every 20th tick (and the last) of the compared
// columns.
//
// Tolerances per signal (absolute):
//   t 1e-9 s; x, y, z 1e-6 m; qw..qz 1e-6; grasp 1e-6 rad; fx, fy, fz 1e-4 N;
//   mx, my, mz 1e-5 N·m; g 1e-5 N·m; tau1..tau8 1e-4 N; events exact (bit set).
// FE runs (documents with an FE model) also compare fe_contacts exactly and fe_fx, fe_fy, fe_fz
// (the unscaled FE reaction) to 1 N: the felt force is 1e-4 of it (FE mode's default force
// scale at world scale 1), so that is the felt forces' 1e-4 N.
//
// Regenerating the goldens (after a deliberate change of the physics; check the new runs'
// physics first, see scene_haptics_test.cc and the README):
//   SPIDARCAD_UPDATE_GOLDEN=1 build/tests/app_tests --gtest_filter='Regression.*'
// or scripts/update-golden.sh [build dir]. The tests then write tests/golden/*.csv in the source
// tree instead of comparing, and say so.
//
// The comparison itself (golden_compare.h) is tested here too: it must catch a perturbed signal.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli/golden_runs.h"
#include "golden_compare.h"
#include "spidarcad_runner.h"

namespace {

using spidarcad::test_support::CompareToGolden;
using spidarcad::test_support::CsvTable;
using spidarcad::test_support::Decimate;
using spidarcad::test_support::GoldenComparison;
using spidarcad::test_support::SignalTolerance;

// Every this many ticks a row goes into the golden file.
constexpr int kDecimation = 20;

std::vector<SignalTolerance> Tolerances() {
  std::vector<SignalTolerance> t = {{"t", 1e-9, "s"}};
  for (const char* c : {"x", "y", "z"}) t.push_back({c, 1e-6, "m"});
  for (const char* c : {"qw", "qx", "qy", "qz"}) t.push_back({c, 1e-6, ""});
  t.push_back({"grasp", 1e-6, "rad"});
  for (const char* c : {"fx", "fy", "fz"}) t.push_back({c, 1e-4, "N"});
  for (const char* c : {"mx", "my", "mz", "g"}) t.push_back({c, 1e-5, "N·m"});
  for (int i = 1; i <= 8; ++i) t.push_back({"tau" + std::to_string(i), 1e-4, "N"});
  t.push_back({"events", 0.0, "bits"});
  return t;
}

// The tolerances of an FE run: today's and the FE columns'.
std::vector<SignalTolerance> FeTolerances() {
  std::vector<SignalTolerance> t = Tolerances();
  t.push_back({"fe_contacts", 0.0, "nodes"});
  for (const char* c : {"fe_fx", "fe_fy", "fe_fz"}) t.push_back({c, 1.0, "N"});
  return t;
}

std::vector<std::string> ComparedColumns(const std::vector<SignalTolerance>& tolerances) {
  std::vector<std::string> columns;
  for (const SignalTolerance& s : tolerances) columns.push_back(s.column);
  return columns;
}

std::string Source(const std::string& relative) {
  return std::string(SPIDARCAD_SOURCE_DIR) + "/" + relative;
}

bool UpdateGolden() {
  const char* v = std::getenv("SPIDARCAD_UPDATE_GOLDEN");
  return v != nullptr && std::string(v) == "1";
}

// Runs `spidarcad run ARGS --out ...` with the golden run's arguments (cli/golden_runs.h: one
// list, which the tick table reads too) and compares (or, when updating, writes) the golden
// tests/golden/<name>.csv on the signals of `tolerances`. The run's stdout goes to *stdout_text
// when given. The run's FE columns go to a disk cache of the test's own (SPIDARCAD_CACHE_DIR).
void RunAndCompare(const std::string& name, std::string* stdout_text = nullptr,
                   const std::vector<SignalTolerance>& tolerances = Tolerances()) {
  std::string args;
  for (const std::string& a :
       spidarcad::app::GoldenRunArguments(spidarcad::app::FindGoldenRun(name), Source("assets")))
    args += (args.empty() ? "'" : " '") + a + "'";
  const std::string out = spidarcad::test_support::TestOutputPath("regression_" + name + ".csv");
  const std::string cache = spidarcad::test_support::TestOutputPath("regression_fe_cache");
  const auto run = spidarcad::test_support::RunSpidarcad("run " + args + " --out '" + out + "'", "",
                                                         "regression_" + name,
                                                         "env SPIDARCAD_CACHE_DIR='" + cache + "'");
  ASSERT_EQ(run.status, 0) << run.err;
  if (stdout_text != nullptr) *stdout_text = run.out;
  const CsvTable actual = Decimate(spidarcad::test_support::ReadCsvTable(out), kDecimation,
                                   ComparedColumns(tolerances));
  const std::string golden_path = Source("tests/golden/" + name + ".csv");
  if (UpdateGolden()) {
    std::string shown;  // paths relative to the source tree in the comment
    for (const std::string& a : spidarcad::app::FindGoldenRun(name).arguments)
      shown += (shown.empty() ? "" : " ") + a;
    spidarcad::test_support::WriteCsvTable(
        actual, golden_path,
        {"golden result of: spidarcad run " + shown,
         "every " + std::to_string(kDecimation) +
             "th tick; regenerate with SPIDARCAD_UPDATE_GOLDEN=1 (tests/app/regression_test.cc)"});
    std::cout << "[ UPDATED  ] " << golden_path << "\n";
    return;
  }
  const CsvTable golden = spidarcad::test_support::ReadCsvTable(golden_path);
  const GoldenComparison result = CompareToGolden(golden, actual, tolerances);
  EXPECT_TRUE(result.ok()) << name << " (" << golden_path << " vs " << out << "):\n"
                           << result.Report();
}

// The golden runs are one list (cli/golden_runs.h) that this test and the tick table read: every
// golden file in tests/golden has its run there, every run its file, no name twice.
TEST(Regression, EveryGoldenFileHasItsRunInTheOneListAndEveryRunItsFile) {
  std::set<std::string> files, runs;
  for (const auto& entry : std::filesystem::directory_iterator(Source("tests/golden")))
    if (entry.path().extension() == ".csv") files.insert(entry.path().stem().string());
  for (const spidarcad::app::GoldenRun& run : spidarcad::app::GoldenRuns()) {
    EXPECT_TRUE(runs.insert(run.name).second) << run.name << " twice";
    EXPECT_NO_THROW(spidarcad::app::GoldenRunOptions(run, Source("assets"))) << run.name;
  }
  EXPECT_EQ(files, runs);
  // The options are the CLI's: a golden's arguments land in ScriptedRunOptions as `run` reads them.
  const spidarcad::app::ScriptedRunOptions o = spidarcad::app::GoldenRunOptions(
      spidarcad::app::FindGoldenRun("block_fe_squeeze"), Source("assets"));
  EXPECT_EQ(o.scene, Source("assets/scenes/squeeze_block_fe.json"));
  EXPECT_EQ(o.trajectory, Source("assets/trajectories/squeeze.csv"));
  EXPECT_EQ(o.world_scale, 1.0);
  EXPECT_EQ(o.world_origin, (std::vector<double>{0, 0, 0}));
  EXPECT_TRUE(o.fe_grasp);
  EXPECT_THROW(spidarcad::app::FindGoldenRun("no such run"), std::out_of_range);
}

TEST(Regression, DemoSceneWithPressMatchesGolden) { RunAndCompare("demo_press"); }

// The plate's top face (z = 0.01 m) at grip z = −0.03 m: the press's 1 cm-deep aim.
TEST(Regression, PlatformProxyWithPressMatchesGolden) { RunAndCompare("platform_press"); }

// The circle (grip z = −0.035 m, radius 4 cm) at world z = 0.06 m: it cuts the blob's top.
TEST(Regression, ClayProxyWithCircleMatchesGolden) { RunAndCompare("clay_circle"); }

// The cross grip's pole 2 (along x, end at 4.6 cm) 3 mm into the wall face x = 0, twisting.
TEST(Regression, PlatformShellToolWithTwistMatchesGolden) { RunAndCompare("platform_shell_twist"); }

// The toy robot's right leg seated by script (assets/scenes/assembly.json, X_WD identity; see
// the trajectory's key poses): picked up in front of the torso, carried under the right hip
// hole, the peg pushed in, released. With --calibrate, as the window: through the nominal
// encoder model the grip is ~4 mm from where the loop sees it and the peg (0.6 mm clearance)
// misses. Frozen after checking the run: every force ≤ 5.2 N (the 4.2 N peak is the hand,
// 300 N/m, aiming 14 mm into the torso's bottom at t 1.2–1.8 s: 300 × 0.0138 m = 4.15 N, the
// script's "up" pose grazes it); g ≤ 0 always, < 0 without a break from the grab (t 4.97 s) to
// the release (14.78 s), down to −0.284 N·m while held (the squeeze of the shallower pole,
// grasp_field.h: under the 0.3 N·m limit); tensions in [0.2, 8] N; no nan, fk_refused or
// device_error event; FK within 0.6 mm of the true grip. Regenerated 2026-12-05 for the
// squeeze's change from the sum over the poles to the shallower pole.
TEST(Regression, AssemblySeatRightLegMatchesGolden) {
  std::string out;
  RunAndCompare("assembly_seat_right_leg", &out);
  EXPECT_NE(out.find("calibration: line-fit calibration on 24 jig poses"), std::string::npos)
      << out;
  EXPECT_NE(out.find("assembly: 1 of 5 parts seated (right_leg), carried: none"), std::string::npos)
      << out;
}

// The whole robot (assets/trajectories/whole_robot.csv from scripts/make-seat-trajectory.py
// --whole-robot, 85.8 s): one trajectory picks up, carries and seats the head, the right leg, the
// left leg, the right arm (the grip at rest, the poles on the corner of its -y face and peg end)
// and the left arm (the grip pitched 90 deg about y, the poles around its section) in turn; all
// five end seated. Frozen after checking the run (spidarcad run assets/scenes/assembly.json
// --trajectory assets/trajectories/whole_robot.csv --calibrate): no nan, fk_refused or
// device_error event; every force <= 0.58 N; g in [-0.3, 0] N·m (at the -0.3 limit on 7764
// ticks); g never changes by more than 0.1 N·m from one tick to the next but once (t 46.36 s,
// checked below); tensions in [0.2, 8] N; FK
// within 1.5 mm of the true grip. Regenerated 2026-12-05: with the squeeze summed over the poles
// the grasp torque buzzed between 0 and -0.3 N·m from tick to tick while the right arm was
// grabbed (t 54-56 s: 870 such jumps over the run), and a change in the FK's last digits
// decided whether the right arm ended seated; with the shallower pole's squeeze
// (grasp_field.h) the run is the same to 1e-9 m with either FK iteration path. The pitched grip
// of the left arm costs force closure: the tension solve saturates on every tick from t 65.5 s
// (the turn is at 67.9 s) to the end, as it does on 22% of the ticks before; the energy
// limiter acts on 1009 ticks while the head is grasped and lifted (t 7.1-8.7 s).
TEST(Regression, AssemblyWholeRobotMatchesGolden) {
  std::string out;
  RunAndCompare("assembly_whole_robot", &out);
  EXPECT_NE(out.find("assembly: 5 of 5 parts seated (head, right_arm, left_arm, right_leg, "
                     "left_leg), carried: none"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("nan=0 (bit 0), fk_refused=0 (bit 1), device_error=0 (bit 2)"),
            std::string::npos)
      << out;
  // No buzz: every tick of the run (not only the golden's every 20th), the grasp torque's
  // tick-to-tick changes above 0.1 N·m. Summed over the poles, the squeeze made 1123.
  const CsvTable run = spidarcad::test_support::ReadCsvTable(
      spidarcad::test_support::TestOutputPath("regression_assembly_whole_robot.csv"));
  const int g = run.Column("g");
  ASSERT_GE(g, 0);
  int jumps = 0;
  for (size_t k = 1; k < run.rows.size(); ++k)
    jumps += std::abs(run.rows[k][g] - run.rows[k - 1][g]) > 0.1;
  EXPECT_GT(run.rows.size(), 85000u);
  EXPECT_LE(jumps, 1);
}

// Snap forces (assets/scenes/snap_box.json: a 40 mm cube with snap, vertex/edge/face radii 8, 5
// and 3 mm, 1 N) toured by assets/trajectories/snap_tour.csv (scripts/make-snap-trajectory.py):
// past the top right vertex, along the edge from it, onto the top face, and away. Frozen after
// checking the run against the cube's geometry, with the grip where the loop sees it (FK): no
// force at all farther than 8.5 mm from the cube; along the edge and over the face the force
// points toward the cube's nearest point (cosine of the angle: mean 0.96 on 2533 and 2983
// ticks, least 0.58 and 0.44 where the edge's and the face's pulls meet); within half the vertex
// radius of the vertex mean 0.75, least 0.32, on 116 ticks that all have the energy limiter
// acting (the grip passes the vertex fast); every force <= 0.97 N; no nan, fk_refused or
// device_error event.
TEST(Regression, SnapTourMatchesGolden) {
  std::string out;
  RunAndCompare("snap_tour", &out);
  EXPECT_NE(out.find("fields: proxy 'cube', snap '8 vertices, 12 edges, 6 faces'"),
            std::string::npos)
      << out;
}

// The steel platform's FE model (assets/scenes/platform_fe.json: linear tetrahedra of 10 mm
// cells, clamped at the wall face x = 0, 50 N on the tip) pushed by FE mode's tool (the tool patch
// of radius 10 mm, sticking; scene/fe_touch_field.h) along press.csv at world scale 1, the aim
// 1 cm into the plate's top face (z = 0.01 m) at W (0.15, 0), as platform_press presses the rigid
// solid. Re-frozen 2026-12-04 (the tool patch) after checking the run: the coupled point stops at
// the plate's plane at t = 0.839 s (0.033 N felt through the coupling on that tick) and the patch
// is in contact from 0.840 s to 2.543 s (up to 3 nodes: 10 mm cells); the felt force is normal
// only (fx = fy = 0 on every tick) and peaks at fz 4.235 N at t = 1.843 s, which is 1.00e-4 of the
// 42.35 kN FE normal reaction and the hand's 300 N/m × 14.1 mm (grip z −25.9 mm aiming at
// −40 mm); the sticking patch's tangential reaction (fe_fx up to 79 kN) holds the patch and is not
// felt; events only the start ramp; no tick read a substitute column. The earlier node-to-sphere
// run felt 3.35 N from one node (a node's stiffness, which falls with the cell size).
TEST(Regression, PlatformFePushP1WithPressMatchesGolden) {
  std::string out;
  RunAndCompare("platform_fe_press", &out, FeTolerances());
  EXPECT_NE(out.find("fields: fe_touch 'platform FE'\n"), std::string::npos) << out;
  EXPECT_NE(out.find(" 0 ticks read a substitute column"), std::string::npos) << out;
}

// The same push on the platform's FE model with quadratic tetrahedra
// (assets/scenes/platform_fe_p2.json: 18563 nodes). Re-frozen 2026-12-04 (the tool patch) after
// checking the run: the course of the P1 run (contact from t = 0.840 s to 2.546 s), up to 12 patch
// nodes, softer as P2 should be where linear tetrahedra lock in bending: the felt fz peaks at
// 3.965 N (P1 4.235 N) at t = 1.843 s, 1.00e-4 of the 39.6 kN FE normal reaction and the hand's
// spring; felt fx = fy = 0; 198 of the 487 surface nodes near the path fit the 256 MB column
// budget, nearest first, and no tick read a substitute column; events only the start ramp.
TEST(Regression, PlatformFePushP2WithPressMatchesGolden) {
  std::string out;
  RunAndCompare("platform_fe_p2_press", &out, FeTolerances());
  EXPECT_NE(out.find("(order 2)"), std::string::npos) << out;
  EXPECT_NE(out.find(" 0 ticks read a substitute column"), std::string::npos) << out;
}

// FE squeeze (two-point grasp contact, --fe-grasp): an ABS block
// (assets/scenes/squeeze_block_fe.json, 20 mm thick along a = (x − y)/√2, 3 mm cells, clamped at
// its far end) between the pole tips, the grasp closing from π/2 to 0.9 rad twice (squeeze.csv) at
// world scale 1, origin 0, each tip a tool patch of radius 2 mm (--fe-tool-radius 0.002: the pole
// tip's size; FE mode's 10 mm would cover the 20 mm block from both sides). Re-frozen 2026-12-04
// (the tool patch) after checking the run: both tips in contact from t = 0.361 s (up to 4 patch
// nodes); the grasp torque g is never > 0 and reaches −0.0543 N·m at t = 0.766 s (grasp
// 0.956 rad) and −0.0539 N·m in the second squeeze: the block pushes the poles apart; the felt
// forces are the tips' normal forces, net ≤ 0.60 N (the two tips' forces nearly cancel), moments
// ≤ 0.010 N·m; the energy limiter acts on 353 ticks (bit 9) as patch nodes enter and leave the
// 2 mm tips on 3 mm cells; no tick read a substitute column.
TEST(Regression, BlockFeSqueezeWithSqueezeMatchesGolden) {
  std::string out;
  RunAndCompare("block_fe_squeeze", &out, FeTolerances());
  EXPECT_NE(out.find("fields: fe_touch 'block FE'\n"), std::string::npos) << out;
  EXPECT_NE(out.find(" 0 ticks read a substitute column"), std::string::npos) << out;
}

// The tolerances of a sculpt run: today's, the stroke flag exactly and the clay's volume to
// 1e-12 m³ (about 6e-10 of it).
std::vector<SignalTolerance> SculptTolerances() {
  std::vector<SignalTolerance> t = Tolerances();
  t.push_back({"sculpt_stroke", 0.0, ""});
  t.push_back({"sculpt_volume", 1e-12, "m³"});
  return t;
}

// Sculpt strokes on assets/scenes/clay_sculpt.json (scripts/make-sculpt-trajectories.py: the
// grip comes down on the clay's top, placed at the device origin by --world-origin, closes the
// grasp at t = 1.0-1.3 s and grabs (30 mm up), twists (0.8 rad about z) or bends (0.5 rad about
// y) at 1.4-2.4 s, the stroke under way to the end), radius 0.03 m, with and without volume
// conservation. Frozen after tests/app/run_sculpt_test.cc's checks of the same runs passed: the
// grab moves every vertex to p0 + w Δp of sculpt.h's formula within 1e-12 m and adds the bump's
// volume (+0.565 %, 3 % under Δz π R²/4 on a flat face); the felt force is −300 N/m × the grip's
// measured motion (fz −4.288 N at the end); the twist and bend keep every vertex's distance to
// the grab centre and turn it by w·α or w·t·φ within 2e-4 and 0.011 rad, and the felt moment is
// k R² = 0.27 N·m/rad times the measured turn (0.159 N·m at 0.587 rad of twist, 0.088 N·m
// at 0.327 rad of bend); with conservation the divergence-theorem volume of the exported clay is
// the start's within 1e-9; no tension saturation (the clay's top at the device centre), events
// only the start ramp.
void RunSculpt(const std::string& tool, bool conserve) {
  std::string out;
  RunAndCompare("clay_sculpt_" + tool + (conserve ? "_conserved" : ""), &out, SculptTolerances());
  EXPECT_NE(out.find("sculpt 'clay': 1 stroke (" + tool + ", radius 0.03 m, volume " +
                     (conserve ? "conserved" : "not conserved") + ")"),
            std::string::npos)
      << out;
}

TEST(Regression, ClaySculptGrabMatchesGolden) { RunSculpt("grab", false); }
TEST(Regression, ClaySculptGrabConservedMatchesGolden) { RunSculpt("grab", true); }
TEST(Regression, ClaySculptTwistMatchesGolden) { RunSculpt("twist", false); }
TEST(Regression, ClaySculptTwistConservedMatchesGolden) { RunSculpt("twist", true); }
TEST(Regression, ClaySculptBendMatchesGolden) { RunSculpt("bend", false); }
TEST(Regression, ClaySculptBendConservedMatchesGolden) { RunSculpt("bend", true); }

// Pinches of the clay's top lobe with the clay width (scripts/make-sculpt-trajectories.py
// sculpt_pinch_hard and sculpt_pinch_light; tests/app/run_sculpt_test.cc
// RunSculpt.APinchGrabsAsHardAsItSqueezes checks the same runs' physics): the fingers stop at
// the clay, a squeeze stroke grabs it as hard as they squeeze, pulls 20 mm out and lets go.
// Frozen after checking every tick of both runs: g <= 0 throughout and 0 before the grasp
// closes and after it opens; the squeeze began the stroke at 79.5 deg (above the 70 deg angle
// trigger) and it ended as the fingers let go (80.5 / 80.8 deg); mean g over the held squeeze
// −0.300 N·m (hard, at the loop's grasp torque limit) against −0.133 N·m (light); volume
// +0.340 % against +0.086 %, kept after the release.
void RunPinch(const std::string& which) {
  std::string out;
  RunAndCompare("clay_sculpt_pinch_" + which, &out, SculptTolerances());
  EXPECT_NE(out.find("sculpt 'clay': 1 stroke (grab, radius 0.03 m, volume not conserved)"),
            std::string::npos)
      << out;
}

TEST(Regression, ClaySculptPinchHardMatchesGolden) { RunPinch("hard"); }
TEST(Regression, ClaySculptPinchLightMatchesGolden) { RunPinch("light"); }

// FE grab and twist (--fe-grab, scene/fe_grab_field.h): the grip goes down into the free end of
// the steel platform (assets/scenes/platform_fe.json) unresisted, closes the grasp there, twists
// by 0.25 rad about the plate's long axis (+x), pulls up 4 mm, opens the grasp and leaves
// (assets/trajectories/grab_twist.csv, scripts/make-grab-twist-trajectory.py) at world scale 1,
// origin (0.28, 0, 0.005). The FE columns fe_contacts (grabbed nodes), fe_fx..fe_fz and
// fe_mx..fe_mz (FE moment on the tool about the grip centre; 0.1 N·m: the felt 1e-5 N·m) are
// compared. Re-frozen 2026-12-04 (the grab radius is the tool's physical 10 mm, no longer twice
// the mean edge) after checking the run: no force at all before the grab; the grasp closes past
// 70 deg at t = 1.199 s and 4 surface nodes are grabbed (10 mm cells), no substitute column;
// held, the twist is resisted: mx reaches −0.1376 N·m (t = 3.195 s; 1e-4 of the FE moment
// −1376 N·m), opposite to the grip's twist (qx = +0.056); the pull is resisted: fz down to
// −0.504 N; |f| <= 0.52 N, events only the start ramp; the grasp opens past 80 deg at t = 3.203 s
// and the force is zero from then on. (With 16 nodes, radius 17.3 mm, it was −0.140 N·m and
// −0.506 N: the coupling in series dominates what is felt.)
TEST(Regression, PlatformFeGrabWithGrabTwistMatchesGolden) {
  std::vector<SignalTolerance> tolerances = FeTolerances();
  for (const char* c : {"fe_mx", "fe_my", "fe_mz"}) tolerances.push_back({c, 0.1, "N·m"});
  std::string out;
  RunAndCompare("platform_fe_grab_twist", &out, tolerances);
  EXPECT_NE(out.find("fields: fe_grab 'platform FE'\n"), std::string::npos) << out;
  EXPECT_NE(out.find(" 0 ticks read a substitute column"), std::string::npos) << out;
}

// The board-sim device through a faulty link (--link-loss 0.002 --link-corruption 0.002
// --link-seed 3) on the demo press, its cable pulled at t = 1.7 s (the floor pushing) and put
// back at 1.8 s. The link
// columns link_status, plugged, link_lost and link_corrupt are compared exactly. Frozen after
// checking the run (ScriptedRun.BoardSimUnpluggedGivesZeroForceAndRampsBackAfterTheReplug in
// tests/app/scripted_run_test.cc checks the same run): zero force (device_error, bit 2) on
// every tick while unplugged and until the driver has re-handshaken after the replug; from
// then the force ramps in from zero (bit 8), never faster than the loop's 0.5 s ramp; States lost
// and corrupt in the driver's counters (and its summary line); two runs write the same CSV but
// for tick_us.
TEST(Regression, BoardSimThroughLossAndAnUnplugMatchesGolden) {
  std::vector<SignalTolerance> tolerances = Tolerances();
  for (const char* c : {"link_status", "plugged", "link_lost", "link_corrupt"})
    tolerances.push_back({c, 0.0, ""});
  std::string out;
  RunAndCompare("demo_press_board_faults", &out, tolerances);
  EXPECT_NE(out.find("link faults: loss 0.002, corruption 0.002 per packet (seed 3)"),
            std::string::npos)
      << out;
}

// Modelling by touch (--place sphere): the grip closes its grasp to 50 deg far above the top face
// of a 40 mm cube (assets/scenes/touch_box.json), comes down to 1 mm above where the ghost sphere
// would rest on it, holds, squeezes once and goes back up (assets/trajectories/touch_place.csv,
// scripts/make-touch-trajectory.py), X_WD the identity, --calibrate. touch_feature and placed are
// compared exactly, touch_size and touch_lift (the ghost's size from the measured grasp, the felt
// faces' lift) to 1e-7 m. Frozen
// after ScriptedRun.PlacesASphereByTouchOnTheFaceItsSnapPullLeadsTo
// (tests/app/scripted_run_test.cc) checked the same run tick by tick (2026-12-04), with the grip
// where the loop sees it (FK) and the felt faces' lift of the tick: no force at all on the 5757
// ticks farther than the 6 mm capture from the lifted face (nor before the first frame); on 2616
// of the 3228 ticks within it no safety event, and there the force is SnapField's pull toward
// the lifted face along its normal to 3e-16 N (fx = fy = 0); on the other 612 the passivity
// observer (bit 9) adds its damping (sideways up to 0.54 N); every force <= 0.772 N; the felt
// lift moved only with a steady grasp (t = 0.015, 2.031, 7.183, 8.351 s), never in the squeeze;
// exactly one place, at t = 6.255 s in the squeeze (6.0-6.3 s), aligned to the top face: a
// sphere of 34.72 mm (the measured grasp when the squeeze began, 49.7 deg; the script's 50:
// -0.5 %), its centre c/2 above the face to 1e-12 m and 0.012 mm from the measured grip in x, y.
TEST(Regression, TouchPlaceSphereMatchesGolden) {
  std::vector<SignalTolerance> tolerances = Tolerances();
  tolerances.push_back({"touch_feature", 0.0, ""});
  tolerances.push_back({"touch_size", 1e-7, "m"});
  tolerances.push_back({"touch_lift", 1e-7, "m"});
  tolerances.push_back({"placed", 0.0, ""});
  std::string out;
  RunAndCompare("touch_place_sphere", &out, tolerances);
  EXPECT_NE(out.find("touch: placing sphere (snap pull at most 0.8 N); 1 placed"),
            std::string::npos)
      << out;
}

CsvTable SmallTable() {
  CsvTable t;
  t.columns = {"t", "x", "fx", "events"};
  for (int i = 0; i < 10; ++i) {
    t.rows.push_back({0.02 * i, 0.001 * i, std::sin(0.3 * i), static_cast<double>(i % 3)});
  }
  return t;
}

std::vector<SignalTolerance> SmallTolerances() {
  return {{"t", 1e-9, "s"}, {"x", 1e-6, "m"}, {"fx", 1e-4, "N"}, {"events", 0.0, "bits"}};
}

TEST(GoldenCompare, DetectsAPerturbedSignalAndSaysWhereAndByHowMuch) {
  const CsvTable golden = SmallTable();
  CsvTable actual = golden;
  actual.rows[6][2] += 3e-4;  // fx off by 3× its tolerance at row 6 (t = 0.12 s)
  actual.rows[8][2] -= 5e-4;
  const GoldenComparison r = CompareToGolden(golden, actual, SmallTolerances());
  ASSERT_FALSE(r.ok());
  ASSERT_EQ(r.divergences.size(), 1u);
  const auto& d = r.divergences[0];
  EXPECT_EQ(d.column, "fx");
  EXPECT_EQ(d.row, 6u);
  EXPECT_DOUBLE_EQ(d.time, 0.12);
  EXPECT_DOUBLE_EQ(d.expected, std::sin(1.8));
  EXPECT_NEAR(d.difference, 3e-4, 1e-12);
  EXPECT_EQ(d.rows_over, 2u);
  EXPECT_NEAR(d.max_difference, 5e-4, 1e-12);
  const std::string report = r.Report();
  EXPECT_NE(report.find("signal 'fx' diverged at row 6 (t = 0.12 s)"), std::string::npos) << report;
}

TEST(GoldenCompare, AcceptsDifferencesWithinToleranceButNotAFlippedEventBit) {
  const CsvTable golden = SmallTable();
  CsvTable actual = golden;
  for (auto& row : actual.rows) {
    row[1] += 0.9e-6;
    row[2] -= 0.9e-4;
  }
  EXPECT_TRUE(CompareToGolden(golden, actual, SmallTolerances()).ok());
  actual.rows[3][3] = 1.0;  // events: was 0
  const GoldenComparison r = CompareToGolden(golden, actual, SmallTolerances());
  ASSERT_EQ(r.divergences.size(), 1u);
  EXPECT_EQ(r.divergences[0].column, "events");
  EXPECT_EQ(r.divergences[0].row, 3u);
}

TEST(GoldenCompare, ReportsMissingColumnsRowCountsAndNan) {
  const CsvTable golden = SmallTable();
  CsvTable actual = golden;
  actual.rows.pop_back();
  actual.rows[2][1] = NAN;
  const GoldenComparison r = CompareToGolden(golden, actual, {{"x", 1e-6, "m"}, {"fy", 1e-4, "N"}});
  EXPECT_EQ(r.structural.size(), 2u);  // row count, fy missing
  ASSERT_EQ(r.divergences.size(), 1u);
  EXPECT_EQ(r.divergences[0].row, 2u);
  EXPECT_TRUE(std::isinf(r.divergences[0].difference));
}

TEST(GoldenCompare, DecimateKeepsEveryNthAndTheLastRowInTheGivenColumnOrder) {
  const CsvTable t = SmallTable();
  const CsvTable d = Decimate(t, 4, {"fx", "t"});
  ASSERT_EQ(d.columns, (std::vector<std::string>{"fx", "t"}));
  ASSERT_EQ(d.rows.size(), 4u);  // rows 0, 4, 8, 9
  EXPECT_DOUBLE_EQ(d.rows[1][1], 0.08);
  EXPECT_DOUBLE_EQ(d.rows[3][1], 0.18);
  EXPECT_DOUBLE_EQ(d.rows[2][0], std::sin(2.4));
}

TEST(GoldenCompare, WrittenTableReadsBackBitForBit) {
  const CsvTable t = SmallTable();
  const std::string path = spidarcad::test_support::TestOutputPath("golden_roundtrip.csv");
  spidarcad::test_support::WriteCsvTable(t, path, {"comment"});
  const CsvTable back = spidarcad::test_support::ReadCsvTable(path);
  ASSERT_EQ(back.columns, t.columns);
  ASSERT_EQ(back.rows, t.rows);
}

}  // namespace
