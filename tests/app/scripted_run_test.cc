// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The scripted run (app/src/scene/scripted_run.h) through `spidarcad run`, run as a separate
// process:
//   - a document of two clays: each is sculpted where the grip grabs it, and only it, checked
//     against the grab formula of sculpt.h computed here (p = p0 + w(r) Δp, w = (1 − (r/R)²)³,
//     r from the clay vertex nearest the measured grip at the stroke's first frame, Δp the
//     grip's measured motion to the stroke's last update) and against volumes summed here;
//   - board-sim with scripted link faults (loss, corruption, an unplug and a replug): zero
//     force while the board is gone, the force ramping back from zero after the replug, the
//     loss in the driver's counters, and two runs giving the same CSV;
//   - modelling by touch (--place sphere, the golden run touch_place_sphere with --save), tick by
//     tick against the cube's geometry: no force far from the ghost's features, the face's snap
//     pull SnapField's closed form toward the lifted face (at most 0.8 N), exactly one place,
//     the saved sphere resting on the face at the measured grip, sized by the grasp's formula.
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
#include "scene/touch_modelling.h"
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

// SnapField's pull toward a feature at distance d with capture radius r, written out here from
// its documented profile (snap_field.h): F_max·tanh(d/d_s)·w(d), d_s = r/4,
// w = 1 − S((d − r/2)/(r/2)) clamped to [0, 1], S(u) = 3u² − 2u³; zero from d = r on.
double FacePull(double d, double r, double max_force) {
  if (!(d > 0.0 && d < r)) return 0.0;
  const double u = std::clamp((d - r / 2) / (r / 2), 0.0, 1.0);
  return max_force * std::tanh(d / (r / 4)) * (1.0 - (3 * u * u - 2 * u * u * u));
}

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

// Modelling by touch, headless: the golden run touch_place_sphere (assets/scenes/touch_box.json,
// a 40 mm cube centred at (0, 0, -0.04) m, top face z = -0.02 m; scripts/make-touch-trajectory.py:
// the grasp closes to 50 deg far above the face, the grip comes down to 1 mm above where the
// sphere would rest, holds, squeezes once at t = 6.0-6.3 s, goes back up) with --save, checked
// tick by tick with the grip where the loop sees it (FK), c the ghost's size of the tick:
//   - far from the features (more than the 6 mm capture from the face lifted by touch_lift, the
//     felt field's lift: c/2 of the latest steady grasp): no force at all;
//   - every force at most 0.8 N; near, on every tick without a safety event, along the face's
//     normal toward the lifted face and SnapField's pull F(|d|)·w(|d|) at the grip's height d
//     above it, to 1e-9 N (on the ticks with the passivity observer's damping, bit 9, the loop
//     adds −α·v to the pull: fewer than a quarter of the near ticks);
//   - exactly one place; the saved sphere's centre is on the lifted face (z = -0.02 + c/2) at the
//     measured grip's x, y of the place (within 0.5 mm), its diameter c = d·θ with θ the measured
//     grasp before the squeeze: 50 deg within 1 %.
TEST(ScriptedRun, PlacesASphereByTouchOnTheFaceItsSnapPullLeadsTo) {
  const std::string csv_path = TestOutputPath("touch_place.csv");
  const std::string saved = TestOutputPath("touch_place_saved.json");
  const auto run =
      RunSpidarcad("run '" + Source("assets/scenes/touch_box.json") + "' --trajectory '" +
                       Source("assets/trajectories/touch_place.csv") +
                       "' --world-scale 1 --world-origin 0,0,0 --calibrate --place "
                       "sphere --out '" +
                       csv_path + "' --save '" + saved + "'",
                   "", "touch_place");
  ASSERT_EQ(run.status, 0) << run.err;
  EXPECT_NE(run.out.find("fields: proxy 'cube', touch_snap (place sphere)"), std::string::npos)
      << run.out;
  EXPECT_NE(run.out.find("touch: placing sphere (snap pull at most 0.8 N); 1 placed"),
            std::string::npos)
      << run.out;
  const CsvTable csv = ReadCsvTable(csv_path);
  const int fx = csv.Column("fx"), fy = csv.Column("fy"), fz = csv.Column("fz");
  const int size = csv.Column("touch_size"), placed = csv.Column("placed");
  const int lift = csv.Column("touch_lift"), events = csv.Column("events");
  const int feature = csv.Column("touch_feature"), t = csv.Column("t");
  ASSERT_GE(size, 0);
  ASSERT_EQ(placed, static_cast<int>(csv.columns.size()) - 1) << "the touch columns come last";
  const double top = -0.02, capture = 0.006, max_force = 0.8;
  int far_ticks = 0, near_ticks = 0, closed_form_ticks = 0, limited_ticks = 0, place_row = -1;
  double largest = 0.0, worst_closed_form = 0.0;
  for (std::size_t k = 1; k < csv.rows.size(); ++k) {
    const std::vector<double>& r = csv.rows[k];
    const Eigen::Vector3d f(r[fx], r[fy], r[fz]);
    largest = std::max(largest, f.norm());
    if (r[placed] != csv.rows[k - 1][placed]) {
      EXPECT_EQ(place_row, -1) << "a second place at t = " << r[t];
      place_row = static_cast<int>(k);
    }
    EXPECT_LE(f.norm(), max_force + 1e-9) << "t = " << r[t];
    // The felt field of this tick is the one the previous row's frame left: its faces lifted by
    // that row's touch_lift (0: none yet).
    const double lifted = csv.rows[k - 1][lift];
    if (lifted == 0.0) {
      EXPECT_EQ(f.norm(), 0.0) << "t = " << r[t] << ": no felt field yet";
      continue;
    }
    const double d = Fk(csv, static_cast<int>(k)).z() - (top + lifted);  // above the lifted face
    if (std::abs(d) > capture) {
      ++far_ticks;
      EXPECT_EQ(f.norm(), 0.0) << "t = " << r[t] << ", " << d << " m from the lifted face";
      continue;
    }
    ++near_ticks;
    if (r[events] != 0.0) {  // the passivity observer's damping, −α·v, is added to the pull
      ++limited_ticks;
      continue;
    }
    // No ramp, no limiter: the loop commands the field's force, toward the lifted face along its
    // normal (down above it, up below it), SnapField's closed form.
    EXPECT_LE(f.head<2>().norm(), 1e-9) << "t = " << r[t];
    EXPECT_LE(f.z() * d, 0.0) << "t = " << r[t];
    {
      worst_closed_form =
          std::max(worst_closed_form,
                   std::abs(f.z() + std::copysign(FacePull(std::abs(d), capture, max_force), d)));
      ++closed_form_ticks;
    }
  }
  EXPECT_GT(far_ticks, 2000);
  EXPECT_GT(near_ticks, 1000);
  EXPECT_GT(closed_form_ticks, 2000);
  EXPECT_LT(limited_ticks, near_ticks / 4);
  EXPECT_LT(worst_closed_form, 1e-9);
  EXPECT_GT(largest, 0.1) << "the pull was felt";
  ASSERT_GT(place_row, 0) << "nothing placed";
  EXPECT_EQ(csv.rows[place_row][feature], 1.0) << "aligned to a face when placed";
  EXPECT_GT(csv.rows[place_row][t], 6.0);
  EXPECT_LT(csv.rows[place_row][t], 6.4);
  // The saved document: the cube and the sphere, resting on the top face at the grip.
  spidarcad::app::Document doc;
  doc.Load(saved);
  const spidarcad::app::DocObject* sphere = doc.FindByName("sphere");
  ASSERT_NE(sphere, nullptr) << "--save wrote no sphere";
  const auto& root = std::get<spidarcad::app::SolidData>(sphere->data).root;
  const spidarcad::app::NodePose pose = spidarcad::app::PoseOfNode(root);
  const double diameter = 2.0 * std::get<spidarcad::modeling::SphereParams>(
                                    root.children.front().children.front().params)
                                    .radius;
  const double theta = 50.0 * std::acos(-1.0) / 180.0;
  EXPECT_NEAR(diameter, 0.04 * theta, 0.01 * 0.04 * theta);
  // The ghost's size when the squeeze began (within its 0.4 s) is the one placed.
  bool seen = false;
  for (int k = place_row - 400; k < place_row; ++k) seen = seen || csv.rows[k][size] == diameter;
  EXPECT_TRUE(seen) << diameter;
  const Eigen::Vector3d centre = pose.X_AN.translation();
  EXPECT_NEAR(centre.z(), top + diameter / 2, 1e-12);
  const Eigen::Vector3d grip = Fk(csv, place_row);
  EXPECT_LT((centre.head<2>() - grip.head<2>()).norm(), 0.0005);
  // Squared to the face: its z axis exactly vertical (the yaw is the measured grip's, < 1°).
  EXPECT_NEAR(pose.X_AN.linear()(2, 2), 1.0, 1e-12);
  EXPECT_LT(Eigen::AngleAxisd(pose.X_AN.linear()).angle(), std::acos(-1.0) / 180.0);
}

// --place: a primitive the grip places, in a document of solids; else exit 2 saying why.
TEST(ScriptedRun, RefusesAPlaceOfAnotherKindOrWithoutADocumentOfSolids) {
  const std::string traj = Source("assets/trajectories/touch_place.csv");
  const std::string out = TestOutputPath("place_refused.csv");
  const auto cone =
      RunSpidarcad("run '" + Source("assets/scenes/touch_box.json") +
                       "' --place cone --trajectory '" + traj + "' --out '" + out + "'",
                   "", "refused_cone");
  EXPECT_EQ(cone.status, 2);
  EXPECT_NE(cone.err.find("--place: 'cone' is not a primitive the grip places: use sphere, box or "
                          "cylinder"),
            std::string::npos)
      << cone.err;
  const auto demo = RunSpidarcad(
      "run demo --place box --trajectory '" + traj + "' --out '" + out + "'", "", "refused_demo");
  EXPECT_EQ(demo.status, 2);
  EXPECT_NE(demo.err.find("--place: needs a scene file or document"), std::string::npos)
      << demo.err;
  const auto assembly =
      RunSpidarcad("run '" + Source("assets/scenes/assembly.json") +
                       "' --place box --trajectory '" + traj + "' --out '" + out + "'",
                   "", "refused_assembly");
  EXPECT_EQ(assembly.status, 2);
  EXPECT_NE(assembly.err.find("is an assembly"), std::string::npos) << assembly.err;
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
