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
#include <string>
#include <vector>

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

// Runs `spidarcad run ARGS --out ...` and compares (or, when updating, writes) the golden
// tests/golden/<name>.csv on the signals of `tolerances`. The run's stdout goes to *stdout_text
// when given. The run's FE columns go to a disk cache of the test's own (SPIDARCAD_CACHE_DIR).
void RunAndCompare(const std::string& name, const std::string& args,
                   std::string* stdout_text = nullptr,
                   const std::vector<SignalTolerance>& tolerances = Tolerances()) {
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
    std::string shown = args;  // paths relative to the source tree in the comment
    const std::string root = std::string(SPIDARCAD_SOURCE_DIR) + "/";
    for (std::size_t at; (at = shown.find(root)) != std::string::npos;)
      shown.erase(at, root.size());
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

// The assets' paths with arguments in the form used by the goldens' comments.
std::string Asset(const std::string& relative) { return "'" + Source("assets/" + relative) + "'"; }

TEST(Regression, DemoSceneWithPressMatchesGolden) {
  RunAndCompare("demo_press", "demo --trajectory " + Asset("trajectories/press.csv"));
}

// The plate's top face (z = 0.01 m) at grip z = −0.03 m: the press's 1 cm-deep aim.
TEST(Regression, PlatformProxyWithPressMatchesGolden) {
  RunAndCompare("platform_press", Asset("scenes/platform.json") + " --trajectory " +
                                      Asset("trajectories/press.csv") +
                                      " --world-scale 1 --world-origin 0.1,0,0.04");
}

// The circle (grip z = −0.035 m, radius 4 cm) at world z = 0.06 m: it cuts the blob's top.
TEST(Regression, ClayProxyWithCircleMatchesGolden) {
  RunAndCompare("clay_circle", Asset("scenes/clay.json") + " --trajectory " +
                                   Asset("trajectories/circle.csv") +
                                   " --world-scale 1 --world-origin 0,0,0.095");
}

// The cross grip's pole 2 (along x, end at 4.6 cm) 3 mm into the wall face x = 0, twisting.
TEST(Regression, PlatformShellToolWithTwistMatchesGolden) {
  RunAndCompare("platform_shell_twist", Asset("scenes/platform.json") +
                                            " --tool shell --trajectory " +
                                            Asset("trajectories/twist.csv") +
                                            " --world-scale 1 --world-origin 0.043,0.2,-0.1");
}

// The toy robot's right leg seated by script (assets/scenes/assembly.json, X_WD identity; see
// the trajectory's key poses): picked up in front of the torso, carried under the right hip
// hole, the peg pushed in, released. With --calibrate, as the window: through the nominal
// encoder model the grip is ~4 mm from where the loop sees it and the peg (0.6 mm clearance)
// misses. Frozen after checking the run: every force ≤ 5.2 N (the 4.2 N peak is the hand,
// 300 N/m, aiming 14 mm into the torso's bottom at t 1.2–1.8 s: 300 × 0.0138 m = 4.15 N, the
// script's "up" pose grazes it); g ≤ 0 always, < 0 without a break from the grab (t 5.0 s) to
// the release (14.7 s), clamped at the 0.3 N·m limit while held; tensions in [0.2, 8] N; no
// nan, fk_refused or device_error event; FK within 0.6 mm of the true grip.
TEST(Regression, AssemblySeatRightLegMatchesGolden) {
  std::string out;
  RunAndCompare("assembly_seat_right_leg",
                Asset("scenes/assembly.json") + " --trajectory " +
                    Asset("trajectories/seat_right_leg.csv") + " --calibrate",
                &out);
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
// device_error event; every force <= 1.54 N (the right arm's peg pushed against its hole's rim
// at t 62.4 s); g in [-0.3, 0] N·m, clamped at -0.3 while a part is squeezed; tensions in
// [0.2, 8] N; FK within 1.5 mm of the true grip. The pitched grip of the left arm costs force
// closure: the tension solve saturates on every tick from t 67.9 s (the turn) to the end, as
// it does on 26% of the ticks before; the energy limiter acts on 1069 ticks while the head is
// grasped and lifted (t 5.4-8.7 s).
TEST(Regression, AssemblyWholeRobotMatchesGolden) {
  std::string out;
  RunAndCompare("assembly_whole_robot",
                Asset("scenes/assembly.json") + " --trajectory " +
                    Asset("trajectories/whole_robot.csv") + " --calibrate",
                &out);
  EXPECT_NE(out.find("assembly: 5 of 5 parts seated (head, right_arm, left_arm, right_leg, "
                     "left_leg), carried: none"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("nan=0 (bit 0), fk_refused=0 (bit 1), device_error=0 (bit 2)"),
            std::string::npos)
      << out;
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
  RunAndCompare("snap_tour",
                Asset("scenes/snap_box.json") + " --trajectory " +
                    Asset("trajectories/snap_tour.csv") +
                    " --world-scale 1 --world-origin 0,0,0 --calibrate",
                &out);
  EXPECT_NE(out.find("fields: proxy 'cube', snap '8 vertices, 12 edges, 6 faces'"),
            std::string::npos)
      << out;
}

// The steel platform's FE model (assets/scenes/platform_fe.json: linear tetrahedra of 10 mm
// cells, clamped at the wall face x = 0, 50 N on the tip) pushed by the tool sphere along
// press.csv at world scale 1, the aim 1 cm into the plate's top face (z = 0.01 m), as
// platform_press presses the rigid solid. Frozen after checking the run (and
// RunCommand.FeModelIsPushedExactlyAndTheRunIsDeterministic, which checks its contact forces
// against a full sparse solve to 1e-9 and its determinism): no force until the sphere (radius
// 8.6 mm, the mesh's mean surface edge) reaches the plate at t = 0.925 s; then one contact node
// (10 mm cells), the felt fz rising to 3.351 N at t = 1.966 s, which is 0.99e-4 of the 33.86 kN
// FE reaction (the coupling's equilibrium, force scale 1e-4) and the hand's 300 N/m × 11.2 mm (its
// grip at z = −28.8 mm aiming at −40 mm); |fx|, |fy| ≤ 0.011 N (frictionless, pressed straight
// down); contact lost at t = 2.505 s on the way up; events only the start ramp; no tick read a
// substitute column.
TEST(Regression, PlatformFePushP1WithPressMatchesGolden) {
  std::string out;
  RunAndCompare("platform_fe_press",
                Asset("scenes/platform_fe.json") + " --trajectory " +
                    Asset("trajectories/press.csv") + " --world-scale 1 --world-origin 0.1,0,0.04",
                &out, FeTolerances());
  EXPECT_NE(out.find("fields: fe_touch 'platform FE'\n"), std::string::npos) << out;
  EXPECT_NE(out.find(" 0 ticks read a substitute column"), std::string::npos) << out;
}

// The same push on the platform's FE model with quadratic tetrahedra
// (assets/scenes/platform_fe_p2.json: 18563 nodes). Frozen after checking the run: the course of
// the P1 run (one contact node, from t = 0.887 s as a midside node of the top face is met first,
// to 2.532 s), softer as
// P2 should be where linear tetrahedra lock in bending and indentation: the FE reaction peaks at
// 29.5 kN (P1 33.9 kN) and the felt force at 2.95 N (P1 3.37 N), again 1e-4 of the reaction and
// the hand's spring; 198 of the 453 surface nodes near the path fit the 256 MB column budget,
// nearest first, and no tick read a substitute column.
TEST(Regression, PlatformFePushP2WithPressMatchesGolden) {
  std::string out;
  RunAndCompare("platform_fe_p2_press",
                Asset("scenes/platform_fe_p2.json") + " --trajectory " +
                    Asset("trajectories/press.csv") + " --world-scale 1 --world-origin 0.1,0,0.04",
                &out, FeTolerances());
  EXPECT_NE(out.find("(order 2)"), std::string::npos) << out;
  EXPECT_NE(out.find(" 0 ticks read a substitute column"), std::string::npos) << out;
}

// FE squeeze (two-point grasp contact, --fe-grasp): an ABS block
// (assets/scenes/squeeze_block_fe.json, 20 mm thick along a = (x − y)/√2, 3 mm cells, clamped at
// its far end) between the pole tips, the grasp closing from π/2 to 0.9 rad twice (squeeze.csv) at
// world scale 1, origin 0. Frozen after checking the run: a tip sphere (radius 1.8 mm, 0.02 m from
// the grip centre) first reaches the block at t = 0.45 s (grasp 1.16 rad), both tips from t = 0.49
// s (up to 3 contact nodes); the grasp torque g is never > 0 and reaches −0.042 N·m at t = 2.273 s
// (grasp 0.944 rad): the block pushes the poles apart, 1e-4 of about 21 kN per tip through the
// tips' 10 mm lever (L/2); the net FE force on the tool stays below 3.6 kN, largest while one tip
// alone touches (14 N net at the deepest squeeze); felt forces ≤ 0.26 N and moments ≤ 0.0063 N·m;
// the energy limiter acts on 89 ticks (bit 9); no tick read a substitute column.
TEST(Regression, BlockFeSqueezeWithSqueezeMatchesGolden) {
  std::string out;
  RunAndCompare("block_fe_squeeze",
                Asset("scenes/squeeze_block_fe.json") + " --trajectory " +
                    Asset("trajectories/squeeze.csv") +
                    " --world-scale 1 --world-origin 0,0,0 --fe-grasp",
                &out, FeTolerances());
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
  RunAndCompare("clay_sculpt_" + tool + (conserve ? "_conserved" : ""),
                Asset("scenes/clay_sculpt.json") + " --trajectory " +
                    Asset("trajectories/sculpt_" + tool + ".csv") +
                    " --world-origin 0,-0.038,0.0739 --sculpt-radius 0.03 --sculpt-tool " + tool +
                    (conserve ? " --conserve-volume" : ""),
                &out, SculptTolerances());
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

// FE grab and twist (--fe-grab, scene/fe_grab_field.h): the grip goes down into the free end of
// the steel platform (assets/scenes/platform_fe.json) unresisted, closes the grasp there, twists
// by 0.25 rad about the plate's long axis (+x), pulls up 4 mm, opens the grasp and leaves
// (assets/trajectories/grab_twist.csv, scripts/make-grab-twist-trajectory.py) at world scale 1,
// origin (0.28, 0, 0.005). The FE columns fe_contacts (grabbed nodes), fe_fx..fe_fz and
// fe_mx..fe_mz (FE moment on the tool about the grip centre; 0.1 N·m: the felt 1e-5 N·m) are
// compared. Frozen after checking the run: no force at all before the grab (the grip passes into
// the plate unresisted); the grasp closes past 70 deg at t = 1.199 s and 16 surface nodes are
// grabbed (radius 17.3 mm, twice the mean surface edge), no substitute column; held, the twist
// is resisted: mx reaches −0.140 N·m (t = 3.196 s), opposite to the grip's twist (qx = +0.055,
// 0.11 rad of the 0.25 asked: the hand's 1 N·m/rad wrist against the grab's 1.2 N·m/rad, the
// 2 N·m/rad coupling in series with 1e-4 of the patch's ~3e4 N·m/rad), and 1e-4 of the FE moment
// (−1399 N·m; FeGrabField.CouplingHoldsThePatchAtTheSeriesEquilibrium and
// HeldWrenchEqualsTheFullSparseGrabSolve check those against fem::SolveGrab); the pull is resisted:
// fz down to −0.506 N (the hand's 300 N/m over its 1.6 mm lag; grip up 2.4 mm of 4); |f| <= 0.52 N,
// events only the start ramp; the grasp opens past 80 deg at t = 3.203 s and the force is zero
// from then on.
TEST(Regression, PlatformFeGrabWithGrabTwistMatchesGolden) {
  std::vector<SignalTolerance> tolerances = FeTolerances();
  for (const char* c : {"fe_mx", "fe_my", "fe_mz"}) tolerances.push_back({c, 0.1, "N·m"});
  std::string out;
  RunAndCompare("platform_fe_grab_twist",
                Asset("scenes/platform_fe.json") + " --trajectory " +
                    Asset("trajectories/grab_twist.csv") +
                    " --world-scale 1 --world-origin 0.28,0,0.005 --fe-grab",
                &out, tolerances);
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
  RunAndCompare("demo_press_board_faults",
                "demo --trajectory " + Asset("trajectories/press.csv") +
                    " --device board-sim --link-loss 0.002 --link-corruption 0.002 --link-seed 3 "
                    "--unplug 1.7 --replug 1.8",
                &out, tolerances);
  EXPECT_NE(out.find("link faults: loss 0.002, corruption 0.002 per packet (seed 3)"),
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
