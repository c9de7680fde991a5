// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Tests of the window's pieces that need no display (colour map, picking and drag math, the
// demo field, the device session, option parsing), and a smoke test of the window itself that
// runs the spidarcad binary with --screenshot when an X display is available (CI: xvfb-run).
#include <sys/wait.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <set>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>

#include "gui/colour_map.h"
#include "gui/device_session.h"
#include "gui/grip_control.h"
#include "gui/gui.h"
#include "gui/panels.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/tension.h"

namespace spidarcad::app {
namespace {

using haptics::GripPose;
using haptics::SpidarGeometry;
constexpr double kPi = std::numbers::pi;

TEST(TensionColourMap, HitsItsStopsAndInterpolatesLinearlyBetween) {
  for (int k = 0; k < 4; ++k) {
    const Rgb c = TensionColourMap(k / 3.0);
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(c[j], kTensionColourStops[k][j], 1e-12);
  }
  const Rgb mid = TensionColourMap(0.5 / 3.0);  // halfway between blue and teal
  for (int j = 0; j < 3; ++j) {
    EXPECT_NEAR(mid[j], 0.5 * (kTensionColourStops[0][j] + kTensionColourStops[1][j]), 1e-12);
  }
  // Clamped outside [0, 1]; grey for NaN or an empty range.
  EXPECT_EQ(TensionColourMap(-3.0), TensionColourMap(0.0));
  EXPECT_EQ(TensionColourMap(7.0), TensionColourMap(1.0));
  EXPECT_EQ(TensionColourMap(std::nan("")), (Rgb{0.5, 0.5, 0.5}));
  EXPECT_EQ(TensionColour(1.0, 2.0, 2.0), (Rgb{0.5, 0.5, 0.5}));
  // τ_min is blue, τ_max red.
  const Rgb lo = TensionColour(0.2, 0.2, 8.0), hi = TensionColour(8.0, 0.2, 8.0);
  EXPECT_GT(lo[2], 0.9);
  EXPECT_LT(lo[0], 0.2);
  EXPECT_GT(hi[0], 0.8);
  EXPECT_LT(hi[2], 0.2);
}

TEST(IntersectRayPlane, FindsTheClosedFormPointAndRejectsParallelOrBehind) {
  Ray ray{{0.1, -2.0, 0.3}, {0.2, 1.0, -0.1}};
  Eigen::Vector3d hit;
  // Plane y = 0.5: s = 2.5, hit = origin + 2.5 direction.
  ASSERT_TRUE(IntersectRayPlane(ray, {7, 0.5, -3}, {0, 2, 0}, &hit));
  EXPECT_NEAR((hit - Eigen::Vector3d(0.6, 0.5, 0.05)).norm(), 0.0, 1e-12);
  EXPECT_FALSE(IntersectRayPlane(ray, {0, 0, 0}, {1, -0.2, 0}, &hit));  // parallel
  EXPECT_FALSE(IntersectRayPlane(ray, {0, -3.0, 0}, {0, 1, 0}, &hit));  // behind the origin
}

TEST(IntersectRaySphere, ReturnsEntryDistanceMissesAndInside) {
  double s = -1;
  ASSERT_TRUE(IntersectRaySphere({{-1, 0, 0}, {3, 0, 0}}, {0, 0, 0}, 0.5, &s));
  EXPECT_NEAR(s, 0.5, 1e-12);
  // Off-axis: the ray y = 0.3 enters the unit sphere at x = −sqrt(1 − 0.09).
  ASSERT_TRUE(IntersectRaySphere({{-2, 0.3, 0}, {1, 0, 0}}, {0, 0, 0}, 1.0, &s));
  EXPECT_NEAR(s, 2.0 - std::sqrt(0.91), 1e-12);
  EXPECT_FALSE(IntersectRaySphere({{-1, 0.6, 0}, {1, 0, 0}}, {0, 0, 0}, 0.5, &s));
  EXPECT_FALSE(IntersectRaySphere({{1, 0, 0}, {1, 0, 0}}, {0, 0, 0}, 0.5, &s));  // behind
  ASSERT_TRUE(IntersectRaySphere({{0.1, 0, 0}, {0, 1, 0}}, {0, 0, 0}, 0.5, &s));
  EXPECT_EQ(s, 0.0);
}

TEST(RollPitchYaw, RecoversTheAnglesOfZyxComposition) {
  const double roll = 0.3, pitch = -0.7, yaw = 2.1;
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  const Eigen::Vector3d rpy = RollPitchYaw(R);
  EXPECT_NEAR(rpy[0], roll, 1e-12);
  EXPECT_NEAR(rpy[1], pitch, 1e-12);
  EXPECT_NEAR(rpy[2], yaw, 1e-12);
}

TEST(GripControl, ResetGivesTheRestPose) {
  const SpidarGeometry g;
  GripControl grip(g);
  grip.SetPose({0.05, 0.02, -0.01}, Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()).matrix(), 1.0);
  grip.Reset();
  const GripPose rest = GripPose::Rest(g.d);
  const GripPose pose = grip.Pose();
  EXPECT_NEAR((pose.p0 - rest.p0).norm(), 0.0, 1e-15);
  EXPECT_NEAR((pose.p1 - rest.p1).norm(), 0.0, 1e-15);
  EXPECT_NEAR((pose.p2 - rest.p2).norm(), 0.0, 1e-15);
}

TEST(GripControl, TranslateKeepsTheGrabbedPointUnderTheRay) {
  const SpidarGeometry g;
  GripControl grip(g);
  grip.SetPose({0.01, 0.02, 0.03}, Eigen::Matrix3d::Identity(), kPi / 2);
  const Eigen::Vector3d eye(1.0, -1.5, 0.8);
  const Eigen::Vector3d normal = (Eigen::Vector3d(0.01, 0.02, 0.03) - eye).normalized();
  // Grab 1 cm right of the centre, then move the ray to a point 5 cm further in the plane.
  const Eigen::Vector3d right = normal.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d up = right.cross(normal);
  const Eigen::Vector3d grabbed = Eigen::Vector3d(0.01, 0.02, 0.03) + 0.01 * right;
  ASSERT_TRUE(grip.BeginTranslate({eye, grabbed - eye}, normal));
  const Eigen::Vector3d target = grabbed + 0.03 * right - 0.04 * up;
  grip.Translate({eye, 2.0 * (target - eye)});
  // The centre moved by exactly the in-plane displacement of the grabbed point.
  EXPECT_NEAR((grip.p0() - (Eigen::Vector3d(0.01, 0.02, 0.03) + 0.03 * right - 0.04 * up)).norm(),
              0.0, 1e-12);
  EXPECT_TRUE(grip.dragging());
  grip.EndTranslate();
  grip.Translate({eye, -eye});
  EXPECT_NEAR((grip.p0() - (Eigen::Vector3d(0.01, 0.02, 0.03) + 0.03 * right - 0.04 * up)).norm(),
              0.0, 1e-12);  // no drag: ignored
}

TEST(GripControl, ClampsPositionInsideTheFrameAndGraspToItsRange) {
  const SpidarGeometry g;
  GripControl grip(g);
  grip.SetPose({1.0, -1.0, 0.1}, Eigen::Matrix3d::Identity(), 3.0);
  const double limit = g.a - g.d - GripControl::kMargin;  // 0.19 m
  EXPECT_NEAR(grip.p0().x(), limit, 1e-15);
  EXPECT_NEAR(grip.p0().y(), -limit, 1e-15);
  EXPECT_NEAR(grip.p0().z(), 0.1, 1e-15);
  EXPECT_NEAR(grip.grasp(), 160.0 * kPi / 180.0, 1e-12);
  grip.AdjustGrasp(-10.0);
  EXPECT_NEAR(grip.grasp(), 20.0 * kPi / 180.0, 1e-12);
  grip.AdjustGrasp(5.0 * kPi / 180.0);
  EXPECT_NEAR(grip.grasp(), 25.0 * kPi / 180.0, 1e-12);
}

TEST(GripControl, RotateComposesOnTheLeftAndStaysOrthonormal) {
  const SpidarGeometry g;
  GripControl grip(g);
  grip.Rotate(Eigen::Vector3d(0, 0, 2.0), kPi / 2);  // axis need not be unit length
  Eigen::Matrix3d Rz;
  Rz << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_NEAR((grip.R() - Rz).norm(), 0.0, 1e-12);
  for (int k = 0; k < 1000; ++k) grip.Rotate(Eigen::Vector3d(0.3, -0.5, 0.8), 0.0137);
  EXPECT_NEAR((grip.R().transpose() * grip.R() - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
  EXPECT_NEAR(grip.R().determinant(), 1.0, 1e-12);
  // The pole vectors keep length d.
  EXPECT_NEAR(grip.Pose().p1.norm(), g.d, 1e-12);
  EXPECT_NEAR(grip.Pose().p2.norm(), g.d, 1e-12);
}

TEST(DemoSpringWrench, MatchesTheClosedFormSprings) {
  const SpidarGeometry g;
  DemoFieldSettings field;
  // Translation only: f = −k p0, no moment, no grasp torque.
  GripPose pose = GripPose::FromFrame({0.05, -0.02, 0.03}, Eigen::Matrix3d::Identity(), kPi / 2, g.d);
  haptics::Vector7d q = DemoSpringWrench(field, pose);
  EXPECT_NEAR(q[0], -5.0, 1e-12);
  EXPECT_NEAR(q[1], 2.0, 1e-12);
  EXPECT_NEAR(q[2], -3.0, 1e-12);
  EXPECT_NEAR(q.tail<4>().norm(), 0.0, 1e-12);
  // A turn of 0.3 rad about z: m = −k_r 0.3 z.
  pose = GripPose::FromFrame(Eigen::Vector3d::Zero(),
                             Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).matrix(), kPi / 2, g.d);
  q = DemoSpringWrench(field, pose);
  EXPECT_NEAR((q.segment<3>(3) - Eigen::Vector3d(0, 0, -0.3 * field.k_rotation)).norm(), 0.0,
              1e-12);
  // Grasp: −g/2 is the generalised force on θ, which must be −dU/dθ for
  // U = ½ k_g (θ − π/2)²; check it by central differences of U.
  const double theta = 1.9, h = 1e-6;
  pose = GripPose::FromFrame(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(), theta, g.d);
  q = DemoSpringWrench(field, pose);
  auto U = [&](double t) { return 0.5 * field.k_grasp * (t - kPi / 2) * (t - kPi / 2); };
  EXPECT_NEAR(-q[6] / 2.0, -(U(theta + h) - U(theta - h)) / (2 * h), 1e-8);
  EXPECT_GT(q[6], 0.0);  // opened beyond rest: the field squeezes (g > 0 closes)
  field.enabled = false;
  EXPECT_EQ(DemoSpringWrench(field, pose), haptics::Vector7d::Zero());
}

TEST(DeviceSession, IdealDeviceMeasuresTheHandPoseAndDisplaysTheSolvedWrench) {
  const SpidarGeometry g;
  const haptics::TensionSettings ts = haptics::TensionSettings::ForPoleLength(g.d);
  DeviceSession session(g, ts, LengthSource::kIdeal);
  const GripPose hand = GripPose::FromFrame(
      {0.06, -0.04, 0.05}, Eigen::AngleAxisd(0.2, Eigen::Vector3d(1, 2, 3).normalized()).matrix(),
      1.8, g.d);
  const DeviceFrame& f = session.Update(hand);
  ASSERT_EQ(f.fk_status, haptics::FkStatus::kOk);
  EXPECT_NEAR((f.measured_pose.p0 - hand.p0).norm(), 0.0, 1e-8);
  EXPECT_NEAR((f.measured_pose.p1 - hand.p1).norm(), 0.0, 1e-8);
  EXPECT_NEAR((f.measured_pose.p2 - hand.p2).norm(), 0.0, 1e-8);
  for (int i = 0; i < haptics::kNumStrings; ++i) {
    EXPECT_NEAR(f.lengths[i], (g.Corner(i) - hand.Attachment(i)).norm(), 1e-12);
    EXPECT_GE(f.tensions[i], ts.tau_min - 1e-9);
    EXPECT_LE(f.tensions[i], ts.tau_max + 1e-9);
  }
  // The displayed wrench is A τ at the measured pose; the field pulls back toward the centre.
  const haptics::Vector7d achieved = haptics::WrenchMatrix(g, f.measured_pose) * f.tensions;
  EXPECT_NEAR((achieved - f.achieved).norm(), 0.0, 1e-9);
  EXPECT_NEAR((f.wrench.head<3>() - (-100.0 * hand.p0)).norm(), 0.0, 1e-6);
  EXPECT_LT(f.achieved.head<3>().dot(hand.p0), 0.0);
}

TEST(DeviceSession, SimulatedDeviceMeasuresTheHandPoseWithinCalibrationError) {
  const SpidarGeometry g;
  DeviceSession session(g, haptics::TensionSettings::ForPoleLength(g.d),
                        LengthSource::kSimulatedDevice);
  EXPECT_NE(session.calibration_note().find("line fit"), std::string::npos)
      << session.calibration_note();
  const GripPose hand = GripPose::FromFrame(
      {-0.05, 0.07, -0.03}, Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()).matrix(), 1.4, g.d);
  for (int k = 0; k < 10; ++k) session.Update(hand);  // let the motors settle
  const DeviceFrame& f = session.frame();
  ASSERT_EQ(f.fk_status, haptics::FkStatus::kOk);
  // Calibrated encoders: within a millimetre and a degree of the hand (uncalibrated, the
  // paper's 6 % gain error would give centimetres).
  EXPECT_LT((f.measured_pose.p0 - hand.p0).norm(), 1e-3);
  EXPECT_LT(haptics::RotationAngleBetween(f.measured_pose.Rotation(), hand.Rotation()),
            kPi / 180.0);
  const haptics::Vector8d exact = haptics::InverseKinematics(g, hand);
  EXPECT_LT((f.lengths - exact).cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_FALSE((f.lengths - exact).isZero(1e-9));  // really measured, not copied from IK
}

TEST(GuiOptions, ParsesSizeAndGripAndRejectsBadValues) {
  int w = 0, h = 0;
  ParseWindowSize("1024x640", &w, &h);
  EXPECT_EQ(w, 1024);
  EXPECT_EQ(h, 640);
  EXPECT_THROW(ParseWindowSize("1024", &w, &h), CLI::ValidationError);
  EXPECT_THROW(ParseWindowSize("100x100", &w, &h), CLI::ValidationError);
  EXPECT_THROW(ParseWindowSize("800x600junk", &w, &h), CLI::ValidationError);
  std::array<double, 7> grip = {0, 0, 0, 0, 0, 0, 90};
  ParseGripPose("10,-20,30", &grip);
  EXPECT_EQ(grip, (std::array<double, 7>{10, -20, 30, 0, 0, 0, 90}));
  ParseGripPose("1,2,3,4,5,6,100", &grip);
  EXPECT_EQ(grip, (std::array<double, 7>{1, 2, 3, 4, 5, 6, 100}));
  try {
    ParseGripPose("1,2,x", &grip);
    FAIL() << "no exception";
  } catch (const CLI::ValidationError& e) {
    EXPECT_NE(std::string(e.what()).find("z [mm]"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ParseGripPose("1,2,3,4", &grip), CLI::ValidationError);
}

// Runs a shell command; returns its exit status (−1 when it did not exit normally).
int RunCommand(const std::string& command, std::string* output) {
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return -1;
  char buffer[512];
  while (std::fgets(buffer, sizeof(buffer), pipe) != nullptr) *output += buffer;
  const int status = pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(SpidarcadWindow, ExplainsHowToRunHeadlessWithoutADisplay) {
  std::string output;
  const int status = RunCommand(std::string("env -u DISPLAY '") + SPIDARCAD_EXE + "' 2>&1", &output);
  EXPECT_EQ(status, 1) << output;
  EXPECT_NE(output.find("xvfb-run"), std::string::npos) << output;
}

TEST(SpidarcadWindow, ScreenshotShowsTheDeviceStringsByTensionAndThePanel) {
  // Only the variable: connecting here and disconnecting would let Xvfb reset just as the
  // child connects.
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') {
    GTEST_SKIP() << "no X display: run the tests under `xvfb-run -a -s \"-screen 0 "
                    "1280x1024x24\" ctest` to include the window smoke test";
  }
  const std::string png = std::string(SPIDARCAD_TEST_OUTPUT_DIR) + "/gui_screenshot.png";
  std::filesystem::remove(png);
  // A displaced, turned grip on the ideal device, so that the expected tensions are known.
  const double x = 90, y = -60, z = 50, grasp = 110;
  std::string output;
  const int status = RunCommand(std::string("'") + SPIDARCAD_EXE + "' --screenshot '" + png +
                             "' --size 1100x720 --device ideal --grip 90,-60,50,0,0,0,110 2>&1",
                         &output);
  ASSERT_EQ(status, 0) << output;
  vtkNew<vtkPNGReader> reader;
  reader->SetFileName(png.c_str());
  reader->Update();
  vtkImageData* image = reader->GetOutput();
  int dims[3];
  image->GetDimensions(dims);
  ASSERT_EQ(dims[0], 1100);
  ASSERT_EQ(dims[1], 720);
  ASSERT_GE(image->GetNumberOfScalarComponents(), 3);
  const int comps = image->GetNumberOfScalarComponents();
  const auto* px = static_cast<const unsigned char*>(image->GetScalarPointer());
  auto at = [&](int i, int j) {  // column i, row j (bottom up)
    const unsigned char* p = px + (static_cast<size_t>(j) * dims[0] + i) * comps;
    return std::array<int, 3>{p[0], p[1], p[2]};
  };

  // Expected tensions, computed here from the haptics library.
  const SpidarGeometry g;
  const haptics::TensionSettings ts = haptics::TensionSettings::ForPoleLength(g.d);
  const GripPose pose = GripPose::FromFrame(Eigen::Vector3d(x, y, z) * 1e-3,
                                            Eigen::Matrix3d::Identity(), grasp * kPi / 180, g.d);
  haptics::TensionSolver solver(ts);
  const haptics::TensionResult tension =
      solver.Solve(haptics::WrenchMatrix(g, pose), DemoSpringWrench(DemoFieldSettings{}, pose));
  int lo = 0, hi = 0;
  tension.tau.minCoeff(&lo);
  tension.tau.maxCoeff(&hi);
  ASSERT_GT(tension.tau[hi] - tension.tau[lo], 0.3 * (ts.tau_max - ts.tau_min))
      << "pose does not spread the tensions: " << tension.tau.transpose();

  // Pixels of the 3D view (right of the panel) whose chromaticity matches a string colour.
  const int panel = static_cast<int>(kPanelWidth) + 2;
  auto count_colour = [&](const Rgb& rgb) {
    const double s = rgb[0] + rgb[1] + rgb[2];
    int count = 0;
    for (int j = 0; j < dims[1]; ++j) {
      for (int i = panel; i < dims[0]; ++i) {
        const auto p = at(i, j);
        const double ps = p[0] + p[1] + p[2];
        if (ps < 60) continue;
        double err = 0;
        for (int k = 0; k < 3; ++k) err = std::max(err, std::abs(p[k] / ps - rgb[k] / s));
        if (err < 0.035) ++count;
      }
    }
    return count;
  };
  const Rgb low = TensionColour(tension.tau[lo], ts.tau_min, ts.tau_max);
  const Rgb high = TensionColour(tension.tau[hi], ts.tau_min, ts.tau_max);
  EXPECT_GT(count_colour(low), 40) << "least-tensioned string " << lo + 1 << " not seen";
  EXPECT_GT(count_colour(high), 40) << "most-tensioned string " << hi + 1 << " not seen";

  // A real picture: many distinct colours overall.
  std::set<int> colours;
  for (int j = 0; j < dims[1]; j += 2) {
    for (int i = 0; i < dims[0]; i += 2) {
      const auto p = at(i, j);
      colours.insert((p[0] << 16) | (p[1] << 8) | p[2]);
    }
  }
  EXPECT_GT(colours.size(), 1000u);

  // The panel is drawn: its region differs from the 3D background and contains text (dark
  // pixels) on its light window colour.
  int dark = 0, differing = 0;
  for (int j = 0; j < dims[1]; ++j) {
    for (int i = 0; i < panel - 4; ++i) {
      const auto p = at(i, j);
      const auto bg = at(dims[0] - 3, j);  // the 3D view's gradient background at this row
      if (p[0] + p[1] + p[2] < 200) ++dark;
      if (std::abs(p[0] - bg[0]) + std::abs(p[1] - bg[1]) + std::abs(p[2] - bg[2]) > 20) {
        ++differing;
      }
    }
  }
  EXPECT_GT(dark, 2000);
  EXPECT_GT(differing, (panel - 4) * dims[1] / 2);
}

}  // namespace
}  // namespace spidarcad::app
