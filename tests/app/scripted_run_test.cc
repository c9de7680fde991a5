// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The scripted run (app/src/scene/scripted_run.h) through `spidarcad run`, run as a separate
// process:
//   - a document of two clays: each is sculpted where the grip grabs it, and only it, checked
//     against the grab formula of sculpt.h computed here (p = p0 + w(r) Δp, w = (1 − (r/R)²)³,
//     r from the clay vertex nearest the measured grip at the stroke's first frame, Δp the
//     grip's measured motion to the stroke's last update) and against volumes summed here;
//   - board-sim with scripted link faults (loss, corruption, an unplug and a replug): zero
//     force while the board is gone, the force ramping back from zero after the replug, the
//     loss in the driver's counters, and two runs giving the same CSV.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <string>
#include <variant>
#include <vector>

#include "doc/document.h"
#include "golden_compare.h"
#include "sculpt_test_support.h"
#include "spidarcad/modeling/triangle_mesh_io.h"
#include "spidarcad_runner.h"

namespace {

using spidarcad::modeling::TriangleMesh;
using spidarcad::test_support::CsvTable;
using spidarcad::test_support::ReadCsvTable;
using spidarcad::test_support::RunSpidarcad;
using spidarcad::test_support::TestOutputPath;

std::string Source(const std::string& relative) {
  return std::string(SPIDARCAD_SOURCE_DIR) + "/" + relative;
}

void WriteFile(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  ASSERT_TRUE(out.good()) << path;
}

// A sculpt object generated from a sphere of radius 0.03 m centred at (x, 0, -0.03) m: its top
// at z = 0.
std::string ClayObject(const std::string& name, double x) {
  return R"({"kind": "sculpt", "name": ")" + name +
         R"(", "generate_from": {"root": {"type": "translate", "translation": [)" +
         std::to_string(x) +
         R"(, 0, -0.03], "children": [{"type": "sphere", "radius": 0.03}]}, "cell_size": 0.003}})";
}

// The sculpt object `name`'s mesh of a document file.
TriangleMesh ClayOf(const std::string& path, const std::string& name) {
  spidarcad::app::Document doc;
  doc.Load(path);
  for (const spidarcad::app::DocObject& o : doc.objects()) {
    const auto* s = std::get_if<spidarcad::app::SculptData>(&o.data);
    if (s != nullptr && o.name == name) return *s->mesh;
  }
  ADD_FAILURE() << path << " has no sculpt object '" << name << "'";
  return {};
}

// Enclosed volume by the divergence theorem, summed here (m³).
double Volume(const TriangleMesh& m) { return spidarcad::test_support::EnclosedVolume(m); }

Eigen::Vector3d Fk(const CsvTable& csv, int row) {
  return Eigen::Vector3d(csv.rows[row][csv.Column("fk_x")], csv.rows[row][csv.Column("fk_y")],
                         csv.rows[row][csv.Column("fk_z")]);
}

// Over clay A at x = -0.05 m: down onto its top, close the grasp (0.7 rad, past 45 deg: full
// strength), pull up 10 mm, open at once (between two frames of 16 ticks), up; then the same
// over clay B at x = +0.05 m. D = W (only sculpt objects: X_WD is the identity).
constexpr const char* kTwoClayTrajectory =
    "# t,x,y,z,qw,qx,qy,qz,grasp\n"
    "0,-0.05,0,0.02,1,0,0,0,1.5707963267948966\n"
    "0.5,-0.05,0,0.001,1,0,0,0,1.5707963267948966\n"
    "0.8,-0.05,0,0.001,1,0,0,0,0.7\n"
    "1.3,-0.05,0,0.011,1,0,0,0,0.7\n"
    "1.4,-0.05,0,0.011,1,0,0,0,0.7\n"
    "1.401,-0.05,0,0.011,1,0,0,0,1.6\n"
    "1.6,-0.05,0,0.02,1,0,0,0,1.6\n"
    "2.2,0.05,0,0.02,1,0,0,0,1.6\n"
    "2.7,0.05,0,0.001,1,0,0,0,1.6\n"
    "3.0,0.05,0,0.001,1,0,0,0,0.7\n"
    "3.5,0.05,0,0.011,1,0,0,0,0.7\n"
    "3.6,0.05,0,0.011,1,0,0,0,0.7\n"
    "3.601,0.05,0,0.011,1,0,0,0,1.6\n"
    "3.8,0.05,0,0.02,1,0,0,0,1.6\n";

// Checks one clay's stroke (sculpt_stroke == index): every vertex where the grab formula puts it.
void ExpectGrabOf(const CsvTable& csv, int index, const TriangleMesh& before,
                  const TriangleMesh& after, double radius) {
  const int stroke = csv.Column("sculpt_stroke");
  int begin = -1, last_frame = -1;
  for (std::size_t k = 0; k < csv.rows.size(); ++k) {
    if (csv.rows[k][stroke] != index) continue;
    if (begin < 0) begin = static_cast<int>(k);
    if ((k + 1) % 16 == 0) last_frame = static_cast<int>(k);
  }
  ASSERT_GE(begin, 0) << "no stroke on clay " << index;
  ASSERT_GT(last_frame, begin);
  // The grab centre: the clay vertex nearest the measured grip at the stroke's first frame.
  const Eigen::Vector3d p = Fk(csv, begin);
  Eigen::Index nearest = 0;
  for (Eigen::Index v = 0; v < before.vertices.cols(); ++v) {
    if ((before.vertices.col(v) - p).squaredNorm() <
        (before.vertices.col(nearest) - p).squaredNorm())
      nearest = v;
  }
  const Eigen::Vector3d c = before.vertices.col(nearest);
  const Eigen::Vector3d dp = Fk(csv, last_frame) - Fk(csv, begin);
  EXPECT_NEAR(dp.z(), 0.01, 0.002) << "clay " << index << ": the grip pulled up 10 mm";
  double worst = 0.0;
  int moved = 0;
  for (Eigen::Index v = 0; v < before.vertices.cols(); ++v) {
    const Eigen::Vector3d p0 = before.vertices.col(v);
    const double q = (p0 - c).norm() / radius;
    const double w = q < 1.0 ? std::pow(1.0 - q * q, 3.0) : 0.0;
    if (w > 0.0) ++moved;
    worst = std::max(worst, (after.vertices.col(v) - (p0 + w * dp)).norm());
  }
  EXPECT_LT(worst, 1e-12) << "clay " << index << ": largest distance from the formula, m";
  EXPECT_GT(moved, 20) << "clay " << index;
}

// Two clays in one document: one stroke on each, each where the grip grabbed it, each recorded
// in the saved document and exported; the clay not under the stroke does not move meanwhile.
TEST(ScriptedRun, SculptsEachOfTwoClaysWhereTheGripGrabsIt) {
  const std::string doc = TestOutputPath("two_clays.json");
  const std::string traj = TestOutputPath("two_clays_traj.csv");
  const std::string out = TestOutputPath("two_clays_out.csv");
  const std::string saved = TestOutputPath("two_clays_saved.json");
  const std::string a_ply = TestOutputPath("two_clays_a.ply");
  const std::string b_ply = TestOutputPath("two_clays_b.ply");
  WriteFile(doc, R"({"format": "spidarcad-scene", "version": 2, "units": "m", "objects": [)" +
                     ClayObject("clay_a", -0.05) + ", " + ClayObject("clay_b", 0.05) + "]}");
  WriteFile(traj, kTwoClayTrajectory);
  // The ideal device: the measured grip is the trajectory's, so the grasp is past 45 deg (full
  // strength) at every update of the stroke and fully open at the frame that ends it.
  const auto run = RunSpidarcad(
      "run '" + doc + "' --trajectory '" + traj + "' --out '" + out + "' --device ideal --save '" +
          saved + "' --export 'clay_a=" + a_ply + "' --export 'clay_b=" + b_ply + "'",
      "", "two_clays");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_NE(run.out.find("fields: sculpt_tool 'clay_a', sculpt_tool 'clay_b'"), std::string::npos)
      << run.out;
  EXPECT_NE(run.out.find("sculpt 'clay_a': 1 stroke (grab"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("sculpt 'clay_b': 1 stroke (grab"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("device ideal"), std::string::npos) << run.out;
  const CsvTable csv = ReadCsvTable(out);
  const int stroke = csv.Column("sculpt_stroke");
  const int va = csv.Column("sculpt_volume"), vb = csv.Column("sculpt_volume2");
  ASSERT_GE(stroke, 0);
  ASSERT_EQ(va, stroke + 1);
  ASSERT_EQ(vb, stroke + 2);
  EXPECT_EQ(csv.columns.back(), "sculpt_volume2");
  // sculpt_stroke runs 0, 1 (clay A), 0, 2 (clay B), 0.
  std::vector<double> runs;
  for (const auto& row : csv.rows)
    if (runs.empty() || runs.back() != row[stroke]) runs.push_back(row[stroke]);
  EXPECT_EQ(runs, (std::vector<double>{0, 1, 0, 2, 0}));
  // Each clay keeps its volume outside its own stroke (and the frame that ends it).
  for (std::size_t k = 1; k < csv.rows.size(); ++k) {
    const double now = csv.rows[k][stroke], before = csv.rows[k - 1][stroke];
    if (now != 1 && before != 1) {
      EXPECT_EQ(csv.rows[k][va], csv.rows[k - 1][va]) << "row " << k;
    }
    if (now != 2 && before != 2) {
      EXPECT_EQ(csv.rows[k][vb], csv.rows[k - 1][vb]) << "row " << k;
    }
  }
  const TriangleMesh a0 = ClayOf(doc, "clay_a"), b0 = ClayOf(doc, "clay_b");
  const TriangleMesh a1 = ClayOf(saved, "clay_a"), b1 = ClayOf(saved, "clay_b");
  ExpectGrabOf(csv, 1, a0, a1, 0.02);
  ExpectGrabOf(csv, 2, b0, b1, 0.02);
  // The exports are the saved clays; the volume columns are the clays' volumes, summed here.
  const TriangleMesh a_exported = spidarcad::modeling::ReadTriangleMesh(a_ply);
  const TriangleMesh b_exported = spidarcad::modeling::ReadTriangleMesh(b_ply);
  EXPECT_EQ(a_exported.vertices, a1.vertices);
  EXPECT_EQ(b_exported.vertices, b1.vertices);
  EXPECT_NEAR(csv.rows.front()[va], Volume(a0), 1e-12);
  EXPECT_NEAR(csv.rows.front()[vb], Volume(b0), 1e-12);
  EXPECT_NEAR(csv.rows.back()[va], Volume(a1), 1e-12);
  EXPECT_NEAR(csv.rows.back()[vb], Volume(b1), 1e-12);
  EXPECT_GT(Volume(a1), Volume(a0));  // a bump pulled out of each
  EXPECT_GT(Volume(b1), Volume(b0));
}

// board-sim through a lossy, corrupting link, unplugged at t = 1.7 s and replugged at 1.8 s on
// the demo press (the floor pushes the grip from about 1.5 s to 2.3 s).
const char* kFaultArgs =
    " --device board-sim --link-loss 0.002 --link-corruption 0.002 --link-seed 3 --unplug 1.7 "
    "--replug 1.8";

TEST(ScriptedRun, BoardSimUnpluggedGivesZeroForceAndRampsBackAfterTheReplug) {
  const std::string a = TestOutputPath("board_faults_a.csv");
  const std::string b = TestOutputPath("board_faults_b.csv");
  const std::string traj = Source("assets/trajectories/press.csv");
  const auto run_a = RunSpidarcad(
      "run demo --trajectory '" + traj + "' --out '" + a + "'" + kFaultArgs, "", "faults_a");
  ASSERT_EQ(run_a.status, 0) << run_a.err;
  const auto run_b = RunSpidarcad(
      "run demo --trajectory '" + traj + "' --out '" + b + "'" + kFaultArgs, "", "faults_b");
  ASSERT_EQ(run_b.status, 0) << run_b.err;
  // Deterministic: the same CSV twice but for the wall-clock column.
  const std::vector<std::string> lines_a = spidarcad::test_support::CsvLinesWithout(a, {"tick_us"});
  EXPECT_GT(lines_a.size(), 3000u);
  EXPECT_EQ(lines_a, spidarcad::test_support::CsvLinesWithout(b, {"tick_us"}));
  const CsvTable csv = ReadCsvTable(a);
  const int t = csv.Column("t"), ev = csv.Column("events"), st = csv.Column("link_status");
  const int plugged = csv.Column("plugged"), lost = csv.Column("link_lost");
  const int corrupt = csv.Column("link_corrupt");
  ASSERT_GE(st, 0);
  ASSERT_GE(corrupt, 0);
  const auto force = [&](std::size_t k) {
    return std::hypot(csv.rows[k][csv.Column("fx")], csv.rows[k][csv.Column("fy")],
                      csv.rows[k][csv.Column("fz")]);
  };
  constexpr std::uint32_t kDeviceError = 1u << 2, kRamping = 1u << 8;
  std::size_t back = 0;  // first tick with the link ok again after the replug
  double before_unplug = 0.0;
  for (std::size_t k = 0; k < csv.rows.size(); ++k) {
    const double time = csv.rows[k][t];
    const auto events = static_cast<std::uint32_t>(csv.rows[k][ev]);
    if (time < 1.7 - 1e-9) {
      before_unplug = std::max(before_unplug, force(k));
      continue;
    }
    if (time < 1.8 - 1e-9) {
      // Unplugged: the cable is out, the driver says so, the loop gives zero force.
      EXPECT_EQ(csv.rows[k][plugged], 0.0) << "t " << time;
      EXPECT_NE(csv.rows[k][st], 0.0) << "t " << time;
      EXPECT_NE(events & kDeviceError, 0u) << "t " << time;
      EXPECT_EQ(force(k), 0.0) << "t " << time;
      continue;
    }
    EXPECT_EQ(csv.rows[k][plugged], 1.0) << "t " << time;
    if (back == 0 && csv.rows[k][st] == 0.0) back = k;
    if (back == 0) {
      EXPECT_EQ(force(k), 0.0) << "t " << time << ": not reconnected yet";
    }
  }
  EXPECT_GT(before_unplug, 1.0) << "the floor pushed before the unplug";
  ASSERT_GT(back, 0u) << "the driver never reconnected";
  // No jolt: from the reconnection the force comes back through the loop's ramp (0.5 s), from
  // zero: the first tick after it is near zero, and every tick of the ramp has bit 8 set until
  // the ramp ends (or another zero-force event restarts it).
  EXPECT_LT(force(back), 0.1) << "t " << csv.rows[back][t];
  const double t_back = csv.rows[back][t];
  for (std::size_t k = back + 1; k < csv.rows.size() && csv.rows[k][t] < t_back + 0.49; ++k) {
    const auto events = static_cast<std::uint32_t>(csv.rows[k][ev]);
    if ((events & kDeviceError) != 0) break;  // a lost State: the ramp starts again
    EXPECT_NE(events & kRamping, 0u) << "t " << csv.rows[k][t];
  }
  double ramped = 0.0;
  for (std::size_t k = back; k < csv.rows.size() && csv.rows[k][t] < t_back + 0.6; ++k)
    ramped = std::max(ramped, force(k));
  EXPECT_GT(ramped, 0.5) << "the force came back";
  // The loss and the corruption in the driver's counters (the CSV's and the summary's).
  EXPECT_GT(csv.rows.back()[lost], 0.0);
  EXPECT_GT(csv.rows.back()[corrupt], 0.0);
  EXPECT_NE(run_a.out.find("link faults: loss 0.002, corruption 0.002 per packet (seed 3); "
                           "unplugged at t = 1.7 s, replugged at t = 1.8 s"),
            std::string::npos)
      << run_a.out;
  const std::size_t lost_at = run_a.out.find("usb link: states ");
  ASSERT_NE(lost_at, std::string::npos) << run_a.out;
  EXPECT_EQ(run_a.out.find(", lost 0,", lost_at), std::string::npos) << run_a.out;
  EXPECT_NE(run_a.out.find("connects 2"), std::string::npos) << run_a.out;
}

TEST(ScriptedRun, RefusesLinkFaultsOffBoardSimAndAReplugWithoutAnUnplug) {
  const std::string traj = Source("assets/trajectories/press.csv");
  const std::string out = TestOutputPath("faults_refused.csv");
  const auto sim =
      RunSpidarcad("run demo --trajectory '" + traj + "' --out '" + out + "' --link-loss 0.1", "",
                   "refused_sim");
  EXPECT_EQ(sim.status, 2);
  EXPECT_NE(sim.err.find("board-sim only"), std::string::npos) << sim.err;
  const auto replug = RunSpidarcad(
      "run demo --trajectory '" + traj + "' --out '" + out + "' --device board-sim --replug 1", "",
      "refused_replug");
  EXPECT_EQ(replug.status, 2);
  EXPECT_NE(replug.err.find("--replug: needs --unplug T1"), std::string::npos) << replug.err;
  const auto loss = RunSpidarcad(
      "run demo --trajectory '" + traj + "' --out '" + out + "' --device board-sim --link-loss 1.5",
      "", "refused_loss");
  EXPECT_EQ(loss.status, 2);
  EXPECT_NE(loss.err.find("--link-loss: must be a probability in [0, 1)"), std::string::npos)
      << loss.err;
}

}  // namespace
