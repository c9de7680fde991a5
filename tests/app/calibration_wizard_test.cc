// Tests of the window's calibration wizard (gui/calibration_wizard.h; need an X display: run
// under xvfb-run). The window's haptic runtime is stopped and ticked by the test on a virtual
// clock while the test waves the grip (the grip control for board-sim; the board's own device
// for a USB board over the loopback), so a session takes seconds, not minutes. A board-sim
// session is fitted, shown, saved (the file loads and belongs to the device) and used without a
// restart; a USB board's saved calibration is remembered and read by the next window; Cancel and
// a fit with too few poses leave nothing written; the ideal device is refused with the reason.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/calibration_wizard.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "gui/app_window.h"
#include "scene/calibration_file.h"
#include "scene/grip_control.h"
#include "scene/haptic_runtime.h"
#include "scene/scene_model.h"
#include "spidarcad/haptics/board_simulator.h"
#include "spidarcad/haptics/calibration_session.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/simulated_device.h"
#include "support/scripted_window.h"

namespace spidarcad::app {
namespace {

namespace fs = std::filesystem;
using haptics::GripPose;
using test_support::HaveDisplay;
using testing::HasSubstr;
using Step = CalibrationWizard::Step;

constexpr int kTicksPerFrame = 200;  // 0.2 s of haptic time per window frame
constexpr int kMaxFrames = 3000;     // a guard: a session of 60 poses needs a few hundred

// Options of a scripted window on the empty document with `device`.
GuiOptions WizardOptions(const std::string& device) {
  GuiOptions options = test_support::ScriptedWindowOptions(kNoSceneName);
  options.device = device;
  return options;
}

// Waves the grip through the workspace in haptic time while the window runs frames.
class Waver {
 public:
  // `move(pose)` puts the grip (or the hand's target) at `pose`.
  Waver(AppWindow* window, std::function<void(const GripPose&)> move)
      : window_(window),
        move_(std::move(move)),
        wave_(haptics::WavingTrajectory(window->runtime().info().geometry, 600.0, 7)) {
    window_->runtime().Stop();  // the test ticks it
  }
  // One frame: 200 ticks, the grip moved every 20, then the window's frame.
  void Frame() {
    const double d = window_->runtime().info().geometry.d;
    for (int j = 0; j < kTicksPerFrame / 20; ++j) {
      const haptics::TrajectorySample s = wave_.Sample(t_);
      move_(GripPose::FromFrame(s.p_DT, s.q_DT.toRotationMatrix(), s.grasp, d));
      for (int k = 0; k < 20; ++k, ++timing_.tick) window_->runtime().Tick(timing_);
      t_ += 0.02;
    }
    window_->Frame();
  }
  // Frames until the wizard leaves `step` (or the guard). Returns the frames run.
  int FramesWhile(Step step) {
    int frames = 0;
    while (window_->calibration_wizard().step() == step && frames < kMaxFrames) {
      Frame();
      ++frames;
    }
    return frames;
  }
  // Holds the grip at `pose` for `frames` frames (of 200 ticks).
  void Hold(const GripPose& pose, int frames) {
    for (int f = 0; f < frames; ++f) {
      move_(pose);
      for (int k = 0; k < kTicksPerFrame; ++k, ++timing_.tick) window_->runtime().Tick(timing_);
      window_->Frame();
    }
  }
  double seconds() const { return t_; }

 private:
  AppWindow* window_;
  std::function<void(const GripPose&)> move_;
  haptics::Trajectory wave_;
  haptics::TickTiming timing_;
  double t_ = 0.0;
};

// Largest string-length error of the runtime's latest frame against the true lengths of the
// hand's pose (inverse kinematics: the closed form), m.
double LengthError(HapticRuntime& runtime) {
  const haptics::Vector8d truth =
      haptics::InverseKinematics(runtime.info().geometry, runtime.Latest().hand_pose);
  return (runtime.Latest().lengths - truth).cwiseAbs().maxCoeff();
}

TEST(CalibrationWizard, BoardSimSessionIsFittedShownSavedAndUsedWithoutARestart) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("calibration_wizard_board_sim");
  GuiOptions options = WizardOptions("board-sim");
  options.seed = 3;
  AppWindow window(options);
  window.Frame();
  CalibrationWizard& wizard = window.calibration_wizard();
  EXPECT_EQ(wizard.step(), Step::kClosed);
  EXPECT_TRUE(window.DrawnPanel("Calibrate device").w == 0.0f);
  // The grip control moves the simulated hand (as a mouse drag does).
  Waver waver(&window, [&window](const GripPose& pose) {
    window.grip().SetPose(pose.p0, pose.Rotation(), pose.Grasp());
    window.runtime().SetTarget(window.grip().Pose());
  });
  waver.Frame();
  const std::string nominal_description = window.runtime().description();

  wizard.Open();
  waver.Frame();
  EXPECT_EQ(wizard.step(), Step::kIntro);
  EXPECT_GT(window.DrawnPanel("Calibrate device").w, 0.0f);
  wizard.set_poses(60);
  wizard.Start();
  ASSERT_EQ(wizard.step(), Step::kCollecting) << wizard.error();
  EXPECT_TRUE(window.runtime().calibration_tensions());
  const int frames = waver.FramesWhile(Step::kCollecting);
  ASSERT_NE(wizard.step(), Step::kCollecting)
      << wizard.collector()->Progress() << " after " << waver.seconds() << " s";
  ASSERT_NE(wizard.collector(), nullptr);
  EXPECT_TRUE(wizard.collector()->Done());
  EXPECT_EQ(wizard.dropped(), 0);
  EXPECT_FALSE(window.runtime().calibration_tensions());  // the session's pull has stopped
  waver.FramesWhile(Step::kFitting);
  ASSERT_EQ(wizard.step(), Step::kResult) << wizard.error();
  waver.Frame();
  EXPECT_GT(window.DrawnPanel("Calibrate device").w, 0.0f);

  // The table: before, after and the floor against the simulator's truth.
  const CalibrationOutcome& outcome = *wizard.outcome();
  ASSERT_EQ(outcome.rows.size(), 3u);
  ASSERT_TRUE(outcome.rows[0].accuracy && outcome.rows[1].accuracy);
  const double before = outcome.rows[0].accuracy->position_error_max;
  const double after = outcome.rows[1].accuracy->position_error_max;
  EXPECT_GT(before, 3e-3);
  EXPECT_LT(after, 0.5e-3);
  RecordProperty("figure", "max position error " + std::to_string(1e3 * after) + " mm (before " +
                               std::to_string(1e3 * before) + " mm), 60 poses in " +
                               std::to_string(waver.seconds()) + " s haptic time, " +
                               std::to_string(frames) + " frames");

  // Save: by default beside the device memory; the file loads and belongs to this device.
  EXPECT_EQ(
      wizard.DefaultPath().rfind(
          (scratch.dir / "config" / "spidarcad" / "calibrations" / "board-sim-seed3-").string(), 0),
      0u)
      << wizard.DefaultPath();
  const std::string path = (scratch.dir / "cals" / "board-sim-3.json").string();
  ASSERT_TRUE(wizard.Save(path)) << wizard.message();
  EXPECT_THAT(wizard.message(), HasSubstr("saved " + path));
  const CalibrationFile file = LoadCalibrationFile(path);
  EXPECT_EQ(file.device.kind, "board-sim");
  EXPECT_EQ(file.device.seed, 3u);
  EXPECT_EQ(file.method, "self");
  CalibrationDevice device;
  device.kind = "board-sim";
  device.seed = 3;
  device.geometry = window.runtime().info().geometry;
  device.encoder = window.runtime().info().encoder;
  EXPECT_EQ(CalibrationMismatch(file, device), "");
  const haptics::SimulatedSpidarG twin(window.runtime().physical_device()->config());
  for (int i = 0; i < 8; ++i) {
    EXPECT_NEAR(file.calibration.strings[i].gain, twin.true_encoder().strings[i].gain, 3e-3);
  }

  // Use now: the running session reads through it at once. The lengths at one held pose, off
  // centre, before and after.
  const GripPose held = GripPose::FromFrame(Eigen::Vector3d(0.07, -0.06, 0.05),
                                            Eigen::Matrix3d::Identity(), 1.6, 0.04);
  waver.Hold(held, 5);
  const double nominal_error = LengthError(window.runtime());
  EXPECT_GT(nominal_error, 1e-3);
  const int publishes = window.publish_count();
  ASSERT_TRUE(wizard.UseNow()) << wizard.message();
  waver.Frame();
  EXPECT_GT(window.publish_count(), publishes);  // the rebuilt loop got its scene again
  EXPECT_NE(window.runtime().description(), nominal_description);
  EXPECT_THAT(window.runtime().description(), HasSubstr("calibration wizard (saved as " + path));
  waver.Hold(held, 5);
  EXPECT_LT(LengthError(window.runtime()), 0.2 * nominal_error);
  wizard.Discard();
  waver.Frame();
  EXPECT_EQ(wizard.step(), Step::kClosed);
  EXPECT_TRUE(window.DrawnPanel("Calibrate device").w == 0.0f);
}

TEST(CalibrationWizard, AUsbBoardsSavedCalibrationIsRememberedAndReadByTheNextWindow) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("calibration_wizard_usb");
  haptics::usb::BoardSimulator board;  // serial SIM-0001; the test's hand holds its grip
  GuiOptions options = WizardOptions("usb");
  options.usb_transport = [&board] {
    return std::make_unique<haptics::usb::LoopbackTransport>(&board);
  };
  std::string path;
  {
    AppWindow window(options);
    window.Frame();
    ASSERT_EQ(window.runtime().serial(), "SIM-0001");
    Waver waver(&window, [&board](const GripPose& pose) { board.device().SetTruePose(pose); });
    CalibrationWizard& wizard = window.calibration_wizard();
    wizard.Open();
    wizard.set_poses(60);
    wizard.Start();
    ASSERT_EQ(wizard.step(), Step::kCollecting) << wizard.error();
    waver.FramesWhile(Step::kCollecting);
    waver.FramesWhile(Step::kFitting);
    ASSERT_EQ(wizard.step(), Step::kResult) << wizard.error();
    // A real board knows no truth: the residuals only.
    ASSERT_EQ(wizard.outcome()->rows.size(), 2u);
    EXPECT_FALSE(wizard.outcome()->rows[1].accuracy.has_value());
    EXPECT_LT(wizard.outcome()->rows[1].residual.rms, 0.2 * wizard.outcome()->rows[0].residual.rms);
    path = wizard.DefaultPath();
    ASSERT_TRUE(wizard.Save(path)) << wizard.message();
    EXPECT_THAT(wizard.message(), HasSubstr("remembered for the USB board serial SIM-0001"));
    waver.Frame();
  }
  const CalibrationFile file = LoadCalibrationFile(path);
  EXPECT_EQ(file.device.kind, "usb");
  EXPECT_EQ(file.device.serial, "SIM-0001");
  CalibrationDevice device;
  device.kind = "usb";
  device.serial = "SIM-0001";
  EXPECT_EQ(RememberedCalibration(device), fs::absolute(path).string());
  // The next window on the same board reads it through the remembered file.
  haptics::usb::BoardSimulator board2;
  options.usb_transport = [&board2] {
    return std::make_unique<haptics::usb::LoopbackTransport>(&board2);
  };
  AppWindow again(options);
  again.Frame();
  EXPECT_THAT(again.runtime().description(), HasSubstr("(remembered for this board)"));
  EXPECT_THAT(again.runtime().description(), HasSubstr(path));
}

TEST(CalibrationWizard, CancelAndAFitWithTooFewPosesLeaveNothingWritten) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("calibration_wizard_cancel");
  AppWindow window(WizardOptions("board-sim"));
  window.Frame();
  Waver waver(&window, [&window](const GripPose& pose) {
    window.grip().SetPose(pose.p0, pose.Rotation(), pose.Grasp());
  });
  const std::string description = window.runtime().description();
  CalibrationWizard& wizard = window.calibration_wizard();
  // Cancel while collecting.
  wizard.Open();
  wizard.Start();
  ASSERT_EQ(wizard.step(), Step::kCollecting) << wizard.error();
  for (int k = 0; k < 20; ++k) waver.Frame();
  EXPECT_GT(wizard.collector()->counts().offered, 0);
  wizard.Cancel();
  waver.Frame();
  EXPECT_EQ(wizard.step(), Step::kClosed);
  EXPECT_FALSE(window.runtime().calibration_tensions());
  EXPECT_TRUE(window.DrawnPanel("Calibrate device").w == 0.0f);
  // Fit now with a handful of poses: the solver's reason, on the error page.
  wizard.Open();
  wizard.Start();
  ASSERT_EQ(wizard.step(), Step::kCollecting) << wizard.error();
  for (int k = 0; k < 8 && wizard.collector()->collected() < 3; ++k) waver.Frame();
  ASSERT_GT(wizard.collector()->collected(), 0);
  wizard.FitNow();
  waver.FramesWhile(Step::kFitting);
  ASSERT_EQ(wizard.step(), Step::kError);
  EXPECT_THAT(wizard.error(), HasSubstr("too_few_samples"));
  EXPECT_FALSE(wizard.Save((scratch.dir / "never.json").string()));  // no result to save
  EXPECT_FALSE(wizard.UseNow());
  waver.Frame();
  EXPECT_GT(window.DrawnPanel("Calibrate device").w, 0.0f);  // the error is shown
  wizard.Cancel();
  waver.Frame();
  // Nothing written, nothing remembered, the device read as before.
  EXPECT_FALSE(fs::exists(scratch.dir / "never.json"));
  EXPECT_FALSE(fs::exists(scratch.dir / "config" / "spidarcad" / "calibrations"));
  EXPECT_FALSE(fs::exists(scratch.dir / "config" / "spidarcad" / "devices.json"));
  EXPECT_EQ(window.runtime().description(), description);
  EXPECT_FALSE(window.runtime().calibration_tensions());
}

TEST(CalibrationWizard, TheIdealDeviceIsRefusedWithTheReason) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("calibration_wizard_ideal");
  AppWindow window(WizardOptions("ideal"));
  window.Frame();
  CalibrationWizard& wizard = window.calibration_wizard();
  wizard.Open();
  window.Frame();
  wizard.Start();
  EXPECT_EQ(wizard.step(), Step::kError);
  EXPECT_THAT(wizard.error(), HasSubstr("ideal device has no encoder errors to calibrate"));
  EXPECT_FALSE(window.runtime().calibration_tensions());
  window.Frame();
  EXPECT_GT(window.DrawnPanel("Calibrate device").w, 0.0f);
}

TEST(CalibrationWizard, AUsbBoardThatDoesNotAnswerIsRefusedWithTheReason) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("calibration_wizard_no_board");
  haptics::usb::BoardSimulator board;
  GuiOptions options = WizardOptions("usb");
  options.usb_transport = [&board] {
    auto transport = std::make_unique<haptics::usb::LoopbackTransport>(&board);
    transport->SetPlugged(false);
    return transport;
  };
  AppWindow window(options);
  for (int k = 0; k < 3; ++k) window.Frame();
  CalibrationWizard& wizard = window.calibration_wizard();
  wizard.Open();
  wizard.Start();
  EXPECT_EQ(wizard.step(), Step::kError);
  EXPECT_THAT(wizard.error(), HasSubstr("no board answers"));
  EXPECT_THAT(wizard.error(), HasSubstr("spidarcad device list"));
  EXPECT_FALSE(window.runtime().calibration_tensions());
  EXPECT_FALSE(fs::exists(scratch.dir / "config" / "spidarcad"));
}

// --show calibrate (the documentation's screenshot): the wizard collects from the first frame and
// waves the simulated grip itself, on the running haptic thread.
TEST(CalibrationWizard, ShowCalibrateCollectsAtOnceWavingTheSimulatedGrip) {
  if (!HaveDisplay()) GTEST_SKIP() << "no X display: run under xvfb-run";
  const test_support::WindowScratch scratch("calibration_wizard_show");
  GuiOptions options = WizardOptions("board-sim");
  options.show = "calibrate";
  AppWindow window(options);
  CalibrationWizard& wizard = window.calibration_wizard();
  EXPECT_EQ(wizard.step(), Step::kCollecting) << wizard.error();
  EXPECT_TRUE(wizard.auto_wave());
  const Eigen::Vector3d start = window.grip().p0();
  for (int k = 0; k < 2000 && window.runtime().Latest().tool.time < 1.5; ++k) window.Frame();
  window.Frame();
  EXPECT_GT((window.grip().p0() - start).norm(), 5e-3);  // the grip follows the waving
  EXPECT_GT(wizard.collector()->counts().offered, 0);
  EXPECT_TRUE(window.runtime().calibration_tensions());
  wizard.Cancel();
  window.Frame();
  EXPECT_FALSE(window.runtime().calibration_tensions());
}

}  // namespace
}  // namespace spidarcad::app
