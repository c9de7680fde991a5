// The window's calibration wizard (Haptics → Calibrate device...): the self-calibration session
// of `spidarcad calibrate --device` on the device the window runs, in a panel over the view so
// that the grip can still be moved. Pages: intro (the device, how many poses, Start), collecting
// (a progress bar "N of M useful poses", the octants that need more, Cancel, Fit now), fitting
// (on a worker thread), result (the before/after table; Save, Use now, Discard) and error (what
// went wrong; nothing changed).
// The haptic thread commands the session's tensions and publishes its readings
// (HapticRuntime::SetCalibrationTensions, TakeCalibrationReadings); the wizard feeds them to a
// CalibrationCollector on the main thread once per frame, so neither the UI nor the loop waits.
// Main thread only.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "doc/job.h"
#include "scene/calibration_collector.h"
#include "scene/calibration_file.h"
#include "scene/haptic_runtime.h"
#include "spidarcad/haptics/trajectory.h"

namespace spidarcad::app {

class CalibrationWizard {
 public:
  enum class Step { kClosed, kIntro, kCollecting, kFitting, kResult, kError };

  CalibrationWizard() = default;
  // Cancels a running fit and waits for it.
  ~CalibrationWizard();
  CalibrationWizard(const CalibrationWizard&) = delete;
  CalibrationWizard& operator=(const CalibrationWizard&) = delete;

  // The runtime the wizard calibrates (the window's; null: none). A change closes the wizard
  // (a session on the old runtime is cancelled).
  void Attach(HapticRuntime* runtime);
  // Opens the intro page (nothing happens to the device yet).
  void Open();
  // The intro's Start: a new session of poses() useful poses. The ideal device, a board that does
  // not answer or one whose serial number is unknown go to the error page instead.
  void Start();
  // Collecting: fits with the poses kept so far (too few: the error page says so).
  void FitNow();
  // Any page: closes; a session's tensions stop, a running fit is abandoned, nothing is written.
  void Cancel();
  // Every frame: moves the haptic thread's readings into the collector; once it is done, stops
  // the session's tensions and starts the fit; lands a finished fit on the result or error page.
  void Update();
  // Draws the wizard's panel (when open) with its top left at (x, y), `width` pixels wide.
  void Draw(float x, float y, float width);

  // The result page: writes the calibration file to `path` (its folder is made), and remembers
  // it for the device (RememberCalibration: USB boards). False, with message() saying why,
  // when it cannot be written (nothing is written then).
  bool Save(const std::string& path);
  // The result page: the running device is read through the new calibration from now on
  // (HapticRuntime::UseCalibration; the window publishes its haptic scene again).
  bool UseNow();
  // The result page: closes, dropping the calibration (a saved file stays).
  void Discard() { Cancel(); }

  // Useful poses a session collects (intro; 40..5000, default 200).
  int poses() const { return poses_; }
  void set_poses(int poses);
  // Simulated devices: the wizard moves the grip itself along haptics::WavingTrajectory while
  // collecting (intro's checkbox; default off: the user waves it).
  bool auto_wave() const { return auto_wave_; }
  void set_auto_wave(bool on) { auto_wave_ = on; }
  // While collecting with auto_wave on a simulated device: where the grip should be at loop
  // time `loop_time` (s; ToolState::time), D. Empty otherwise.
  std::optional<haptics::TrajectorySample> WaveTarget(double loop_time);

  Step step() const { return step_; }
  bool open() const { return step_ != Step::kClosed; }
  // Collecting or fitting (a --screenshot waits for it).
  bool busy() const { return step_ == Step::kCollecting || step_ == Step::kFitting; }
  // The session's collector (null before Start).
  const CalibrationCollector* collector() const { return collector_.get(); }
  // The fit's outcome on the result page (null otherwise).
  const CalibrationOutcome* outcome() const { return outcome_ ? &*outcome_ : nullptr; }
  // The error page's text.
  const std::string& error() const { return error_; }
  // What the last Save or Use now did (or why it failed); message_failed() for a failure.
  const std::string& message() const { return message_; }
  bool message_failed() const { return message_failed_; }
  // Where Save writes by default: calibrations/ beside the device memory (DeviceMemoryPath),
  // named after the device and the date, e.g. ".../spidarcad/calibrations/usb-SIM-0001-
  // 20261202T114503Z.json"; the working directory when there is no configuration folder.
  std::string DefaultPath() const;
  // The file the last successful Save wrote ("" when none).
  const std::string& saved_path() const { return saved_path_; }
  // True after Use now; the window republishes its haptic scene once when this turns true.
  bool TakeRepublish();
  // Readings the haptic thread dropped because the wizard did not take them in time.
  long dropped() const { return dropped_; }

 private:
  void Fail(const std::string& error);
  void StopTensions();
  void DrawIntro();
  void DrawCollecting();
  void DrawResult();

  HapticRuntime* runtime_ = nullptr;
  Step step_ = Step::kClosed;
  int poses_ = 200;
  bool auto_wave_ = false;
  CalibrationDevice device_;
  bool simulated_ = false;  // the device has a simulated physical SPIDAR-G (its truth)
  std::shared_ptr<CalibrationCollector> collector_;
  std::vector<CalibrationReading> readings_;  // scratch, reused every frame
  long dropped_ = 0;
  haptics::Trajectory wave_;
  double wave_start_ = -1.0;  // loop time of the first WaveTarget, s
  std::unique_ptr<JobQueue> jobs_;
  Job* fit_job_ = nullptr;
  std::optional<CalibrationOutcome> outcome_;
  std::string error_;
  std::string message_;
  bool message_failed_ = false;
  std::string saved_path_;
  bool used_ = false;
  bool republish_ = false;
  char path_[1024] = "";  // the result page's file field
};

}  // namespace spidarcad::app
