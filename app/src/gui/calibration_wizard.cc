// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/calibration_wizard.h"

#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <stdexcept>

#include "doc/input_error.h"
#include "spidarcad/haptics/calibration_session.h"
#include "spidarcad/haptics/simulated_device.h"

namespace spidarcad::app {

namespace {

constexpr char kWindowName[] = "Calibrate device";
constexpr int kMinPoses = 40;    // fewer leave the fit too few equations (SelfCalibrate: 32+)
constexpr int kMaxPoses = 5000;  // a session of this many takes tens of minutes
constexpr double kWaveSeconds = 600.0;  // the automatic waving repeats after this, s
constexpr double kRadToDeg = 180.0 / std::numbers::pi;
const ImVec4 kErrorColour(0.80f, 0.10f, 0.10f, 1.0f);
const ImVec4 kOkColour(0.10f, 0.50f, 0.15f, 1.0f);

// "2026-12-02T11:45:03Z" -> "20261202T114503Z" (file-name friendly).
std::string CompactDate(const std::string& iso) {
  std::string out;
  for (char c : iso) {
    if (c != '-' && c != ':') out += c;
  }
  return out;
}

std::string Pair(double a, double b, int digits) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f / %.*f", digits, a, digits, b);
  return text;
}

}  // namespace

CalibrationWizard::~CalibrationWizard() {
  jobs_.reset();  // cancels and joins a running fit
}

void CalibrationWizard::Attach(HapticRuntime* runtime) {
  if (runtime == runtime_) return;
  Cancel();
  runtime_ = runtime;
}

void CalibrationWizard::Open() {
  if (busy()) return;  // a session is running: its page stays
  step_ = Step::kIntro;
  error_.clear();
  message_.clear();
  message_failed_ = false;
}

void CalibrationWizard::set_poses(int poses) { poses_ = std::clamp(poses, kMinPoses, kMaxPoses); }

void CalibrationWizard::Fail(const std::string& error) {
  StopTensions();
  error_ = error;
  step_ = Step::kError;
}

void CalibrationWizard::StopTensions() {
  if (runtime_ != nullptr) runtime_->SetCalibrationTensions(false);
}

void CalibrationWizard::Start() {
  if (busy()) return;
  outcome_.reset();
  collector_.reset();
  saved_path_.clear();
  used_ = false;
  message_.clear();
  message_failed_ = false;
  error_.clear();
  if (runtime_ == nullptr) return Fail("no device: the window has no haptic runtime");
  const RuntimeSettings& settings = runtime_->settings();
  const haptics::DeviceInfo& info = runtime_->info();
  if (settings.device == RuntimeDevice::kIdeal) {
    return Fail(
        "the ideal device has no encoder errors to calibrate: start the window with --device "
        "simulated, board-sim or usb");
  }
  // A board that is absent (not one that merely has not been read yet, or drops a packet: such
  // readings are not kept) is refused.
  const RuntimeFrame& latest = runtime_->Latest();
  if (latest.link.has_driver && latest.link.status == haptics::DeviceStatus::kNotConnected) {
    return Fail("no board answers (" + DescribeLink(latest.link) +
                "); plug it in (`spidarcad device list` shows the boards), then Start again");
  }
  device_ = CalibrationDevice{};
  device_.kind = RuntimeDeviceName(settings.device);
  device_.geometry = info.geometry;
  device_.encoder = info.encoder;
  simulated_ = runtime_->physical_device() != nullptr;
  if (simulated_) {
    device_.seed = settings.seed;
  } else {
    device_.serial = runtime_->serial();
    if (device_.serial.empty()) {
      return Fail(
          "the board has not reported a serial number (which the calibration file records): "
          "wait until its link is up (the device figures say ok), then Start again; a board "
          "that never reports one needs its firmware to set a USB serial number");
    }
  }
  try {
    collector_ = std::make_shared<CalibrationCollector>(device_, info, poses_);
  } catch (const std::invalid_argument& e) {
    return Fail(e.what());
  }
  wave_ = haptics::Trajectory{};
  wave_start_ = -1.0;
  if (simulated_) wave_ = haptics::WavingTrajectory(info.geometry, kWaveSeconds, settings.seed);
  readings_.clear();
  runtime_->TakeCalibrationReadings(&readings_);  // readings of an earlier session: dropped
  readings_.clear();
  dropped_ = 0;
  runtime_->SetCalibrationTensions(true);
  step_ = Step::kCollecting;
}

void CalibrationWizard::FitNow() {
  if (step_ != Step::kCollecting || runtime_ == nullptr) return;
  StopTensions();
  step_ = Step::kFitting;
  CalibrationFitOptions fit;
  std::optional<haptics::SimulatedDeviceConfig> truth;
  if (const haptics::SimulatedSpidarG* physical = runtime_->physical_device()) {
    // The device the haptic thread steps cannot be moved for the evaluation: a twin of it (the
    // same seed: the same hidden truth) is.
    truth = physical->config();
    fit.homing_tension = truth->homing_tension;
  }
  fit.eval_seed = runtime_->settings().seed * 7919 + 1;
  if (!jobs_) jobs_ = std::make_unique<JobQueue>();
  const std::shared_ptr<const CalibrationCollector> collector = collector_;
  fit_job_ = &jobs_->Start(
      "Self-calibration fit", [this, collector, fit, truth](JobContext&) -> Job::Finisher {
        CalibrationFitOptions options = fit;
        std::optional<haptics::SimulatedSpidarG> twin;
        if (truth) {
          twin.emplace(*truth);
          options.truth = &*twin;
        }
        auto outcome = std::make_shared<CalibrationOutcome>(collector->Fit(options));
        return [this, outcome] {
          fit_job_ = nullptr;
          if (!outcome->ok) return Fail(outcome->error);
          outcome_ = std::move(*outcome);
          std::snprintf(path_, sizeof(path_), "%s", DefaultPath().c_str());
          step_ = Step::kResult;
        };
      });
}

void CalibrationWizard::Cancel() {
  StopTensions();
  if (jobs_) jobs_->CancelAll();  // its finisher never runs
  fit_job_ = nullptr;
  step_ = Step::kClosed;
  outcome_.reset();
}

void CalibrationWizard::Update() {
  if (jobs_) {
    jobs_->Poll([this](const Job& job) {
      if (step_ == Step::kFitting && &job == fit_job_) {
        fit_job_ = nullptr;
        Fail("the fit failed: " + job.error());
      }
    });
    jobs_->Prune();
  }
  if (step_ != Step::kCollecting || runtime_ == nullptr) return;
  readings_.clear();
  dropped_ += runtime_->TakeCalibrationReadings(&readings_);
  for (const CalibrationReading& r : readings_) {
    collector_->Offer(r.reading, r.tension, r.held);
    if (collector_->Done()) break;
  }
  if (collector_->Done()) FitNow();
}

std::optional<haptics::TrajectorySample> CalibrationWizard::WaveTarget(double loop_time) {
  if (step_ != Step::kCollecting || !auto_wave_ || !simulated_ || wave_.empty()) return {};
  if (wave_start_ < 0.0 || loop_time < wave_start_) wave_start_ = loop_time;
  return wave_.Sample(std::fmod(loop_time - wave_start_, kWaveSeconds));
}

std::string CalibrationWizard::DefaultPath() const {
  namespace fs = std::filesystem;
  const std::string memory = DeviceMemoryPath();
  const fs::path folder =
      memory.empty() ? fs::current_path() : fs::path(memory).parent_path() / "calibrations";
  std::string name = device_.kind + "-";
  name += device_.serial.empty() ? "seed" + std::to_string(device_.seed) : device_.serial;
  name += "-" + CompactDate(outcome_ ? outcome_->file.date : NowIso8601Utc()) + ".json";
  return (folder / name).string();
}

bool CalibrationWizard::Save(const std::string& path) {
  if (step_ != Step::kResult || !outcome_) return false;
  message_failed_ = true;
  if (path.empty()) {
    message_ = "Save: give the file a name";
    return false;
  }
  std::error_code ec;
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();
  if (!folder.empty()) std::filesystem::create_directories(folder, ec);
  if (ec) {
    message_ = "Save: " + path + ": cannot make the folder " + folder.string() + ": " +
               ec.message() + " (nothing was written)";
    return false;
  }
  try {
    SaveCalibrationFile(outcome_->file, path, "Save");
  } catch (const InputError& e) {
    message_ = std::string(e.what()) + " (nothing was written)";
    return false;
  }
  saved_path_ = path;
  message_failed_ = false;
  message_ = "saved " + path;
  std::string why;
  if (device_.kind != "usb") {
    message_ += "; a simulated device is not remembered: start with --calibration " + path +
                " to read it through this file";
  } else if (RememberCalibration(device_, path, &why)) {
    message_ += "; remembered for the " + device_.Describe() +
                ": the window reads it through this file from its next start";
  } else {
    message_ += "; could not remember it for the board (" + why + ")";
    message_failed_ = true;
  }
  return true;
}

bool CalibrationWizard::UseNow() {
  if (step_ != Step::kResult || !outcome_ || runtime_ == nullptr) return false;
  const std::string source =
      saved_path_.empty() ? std::string("not saved") : "saved as " + saved_path_;
  const std::string description =
      std::string(RuntimeDeviceName(runtime_->settings().device)) + ": " + device_.Describe() +
      ", self-calibration from the calibration wizard (" + source + ") of " + outcome_->file.date;
  try {
    runtime_->UseCalibration(outcome_->file.calibration, description);
  } catch (const std::exception& e) {
    message_ = std::string("Use now: ") + e.what() + " (the device is read as before)";
    message_failed_ = true;
    return false;
  }
  used_ = true;
  republish_ = true;
  message_ = "the device is read through the new calibration now";
  if (saved_path_.empty()) message_ += " (until the window closes: Save keeps it)";
  message_failed_ = false;
  return true;
}

bool CalibrationWizard::TakeRepublish() {
  const bool r = republish_;
  republish_ = false;
  return r;
}

// ---- drawing ----

void CalibrationWizard::Draw(float x, float y, float width) {
  if (step_ == Step::kClosed) return;
  ImGui::SetNextWindowPos(ImVec2(x, y), ImGuiCond_Appearing);
  ImGui::SetNextWindowSizeConstraints(ImVec2(width, 0.0f), ImVec2(width, 10000.0f));
  bool keep_open = true;
  const ImGuiWindowFlags flags = ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoCollapse |
                                 ImGuiWindowFlags_NoSavedSettings;
  if (ImGui::Begin(kWindowName, &keep_open, flags)) {
    ImGui::PushTextWrapPos(width - 12.0f);
    switch (step_) {
      case Step::kIntro:
        DrawIntro();
        break;
      case Step::kCollecting:
      case Step::kFitting:
        DrawCollecting();
        break;
      case Step::kResult:
        DrawResult();
        break;
      case Step::kError:
        ImGui::TextColored(kErrorColour, "%s", error_.c_str());
        ImGui::TextDisabled("Nothing was changed: the device is read as before.");
        if (ImGui::Button("Back")) Open();
        ImGui::SameLine();
        if (ImGui::Button("Close")) Cancel();
        break;
      case Step::kClosed:
        break;
    }
    ImGui::PopTextWrapPos();
  }
  ImGui::End();
  if (!keep_open) Cancel();
}

void CalibrationWizard::DrawIntro() {
  if (runtime_ == nullptr) {
    ImGui::TextUnformatted("No device.");
    if (ImGui::Button("Close")) Cancel();
    return;
  }
  const RuntimeSettings& settings = runtime_->settings();
  ImGui::Text("Device: %s", runtime_->description().c_str());
  const bool ideal = settings.device == RuntimeDevice::kIdeal;
  const bool simulated = runtime_->physical_device() != nullptr;
  if (ideal) {
    ImGui::TextColored(kErrorColour,
                       "The ideal device has no encoder errors to calibrate: start the window "
                       "with --device simulated, board-sim or usb.");
  } else {
    ImGui::TextUnformatted(
        "Self-calibration: wave the grip through the whole frame, into every octant, turning "
        "and squeezing it, while the strings pull 0.3-3 N (a new pull every 0.1 s; the scene's "
        "forces are off meanwhile). Only the homing pose is needed: no jig.");
  }
  int poses = poses_;
  ImGui::SetNextItemWidth(120.0f);
  if (ImGui::InputInt("useful poses to collect", &poses, 10, 100)) set_poses(poses);
  if (simulated) {
    ImGui::Checkbox("wave the simulated grip for me", &auto_wave_);
  }
  ImGui::BeginDisabled(ideal);
  if (ImGui::Button("Start")) Start();
  ImGui::EndDisabled();
  ImGui::SameLine();
  if (ImGui::Button("Close")) Cancel();
}

void CalibrationWizard::DrawCollecting() {
  if (!collector_) return;
  const CalibrationCollector& c = *collector_;
  const int n = std::min(c.collected(), c.target());
  char label[64];
  std::snprintf(label, sizeof(label), "%d of %d useful poses", n, c.target());
  ImGui::ProgressBar(static_cast<float>(n) / static_cast<float>(c.target()), ImVec2(-1.0f, 0.0f),
                     label);
  // The octants: x and y sign across, z down; red where more are needed.
  ImGui::Text("Poses per octant (at least %d each):", c.per_octant());
  if (ImGui::BeginTable("octants", 5, ImGuiTableFlags_Borders | ImGuiTableFlags_SizingFixedFit)) {
    const float cell = ImGui::CalcTextSize("+x+y").x + 16.0f;
    for (int k = 0; k < 5; ++k) {
      ImGui::TableSetupColumn(nullptr, ImGuiTableColumnFlags_WidthFixed, cell);
    }
    ImGui::TableNextRow();
    ImGui::TableNextColumn();
    for (int xy = 0; xy < 4; ++xy) {
      ImGui::TableNextColumn();
      ImGui::Text("%sx%sy", (xy & 1) ? "+" : "-", (xy & 2) ? "+" : "-");
    }
    for (int z = 0; z < 2; ++z) {
      ImGui::TableNextRow();
      ImGui::TableNextColumn();
      ImGui::TextUnformatted(z ? "+z" : "-z");
      for (int xy = 0; xy < 4; ++xy) {
        const int o = xy | (z << 2);
        ImGui::TableNextColumn();
        const int count = c.octant_counts()[o];
        if (count < c.per_octant()) {
          ImGui::TextColored(kErrorColour, "%d", count);
        } else {
          ImGui::Text("%d", count);
        }
      }
    }
    ImGui::EndTable();
  }
  const std::vector<int> needed = c.NeededOctants();
  if (needed.empty()) {
    ImGui::TextUnformatted("Every octant is covered.");
  } else {
    std::string text = "More needed in";
    for (std::size_t i = 0; i < needed.size(); ++i) {
      text += (i ? ", " : " ") + haptics::OctantName(needed[i]);
    }
    ImGui::TextUnformatted(text.c_str());
  }
  const haptics::PoseCollectorCounts& k = c.counts();
  ImGui::TextDisabled(
      "%ld readings: %ld kept, %ld near a kept pose, %ld while tensions settled, %ld slack, %ld "
      "without a pose",
      k.offered, k.kept, k.too_close, k.unsettled, k.slack, k.no_pose);
  if (step_ == Step::kFitting) {
    ImGui::Text("Fitting the self-calibration to %d poses ...", c.collected());
    if (ImGui::Button("Cancel")) Cancel();
    return;
  }
  if (ImGui::Button("Cancel")) Cancel();
  ImGui::SameLine();
  ImGui::BeginDisabled(c.collected() == 0);
  if (ImGui::Button("Fit now")) FitNow();
  ImGui::EndDisabled();
  if (ImGui::IsItemHovered(ImGuiHoveredFlags_AllowWhenDisabled)) {
    ImGui::SetTooltip("Fit with the poses collected so far");
  }
}

void CalibrationWizard::DrawResult() {
  const CalibrationOutcome& o = *outcome_;
  ImGui::Text("Self-calibration of the %s from %d useful poses (%s).", device_.Describe().c_str(),
              o.poses, o.file.date.c_str());
  // Fixed column widths: an auto-resizing window cannot size a table's columns by themselves.
  const float number_width = ImGui::CalcTextSize("fk residual mm").x + 12.0f;
  const float name_width = ImGui::CalcTextSize("uncalibrated (nominal)").x + 12.0f;
  if (ImGui::BeginTable(
          "table", 4,
          ImGuiTableFlags_Borders | ImGuiTableFlags_RowBg | ImGuiTableFlags_SizingFixedFit)) {
    ImGui::TableSetupColumn("method", ImGuiTableColumnFlags_WidthFixed, name_width);
    ImGui::TableSetupColumn("fk residual mm\n(rms / max)", ImGuiTableColumnFlags_WidthFixed,
                            number_width);
    ImGui::TableSetupColumn("position mm\n(mean / max)", ImGuiTableColumnFlags_WidthFixed,
                            number_width);
    ImGui::TableSetupColumn("rotation deg\n(mean / max)", ImGuiTableColumnFlags_WidthFixed,
                            number_width);
    ImGui::TableHeadersRow();
    for (const CalibrationTableRow& row : o.rows) {
      ImGui::TableNextRow();
      ImGui::TableNextColumn();
      ImGui::TextUnformatted(row.name.c_str());
      ImGui::TableNextColumn();
      ImGui::TextUnformatted(Pair(1e3 * row.residual.rms, 1e3 * row.residual.max, 3).c_str());
      ImGui::TableNextColumn();
      ImGui::TextUnformatted(row.accuracy ? Pair(1e3 * row.accuracy->position_error_mean,
                                                 1e3 * row.accuracy->position_error_max, 3)
                                                .c_str()
                                          : "-");
      ImGui::TableNextColumn();
      ImGui::TextUnformatted(row.accuracy ? Pair(kRadToDeg * row.accuracy->rotation_error_mean,
                                                 kRadToDeg * row.accuracy->rotation_error_max, 2)
                                                .c_str()
                                          : "-");
    }
    ImGui::EndTable();
  }
  ImGui::TextDisabled(
      "fk residual: the redundant string's disagreement over the session's poses (what a device "
      "tells by itself).");
  if (simulated_) {
    ImGui::TextDisabled(
        "position, rotation: against the simulator's hidden truth on 200 other poses (0.2-3 N).");
  } else {
    ImGui::TextDisabled("position, rotation: only a simulated device knows its true pose.");
  }
  ImGui::Separator();
  ImGui::SetNextItemWidth(-60.0f);
  ImGui::InputText("file", path_, sizeof(path_));
  if (ImGui::Button("Save")) Save(path_);
  ImGui::SameLine();
  ImGui::BeginDisabled(used_);
  if (ImGui::Button("Use now")) UseNow();
  ImGui::EndDisabled();
  ImGui::SameLine();
  if (ImGui::Button(saved_path_.empty() && !used_ ? "Discard" : "Close")) Discard();
  if (!message_.empty()) {
    ImGui::TextColored(message_failed_ ? kErrorColour : kOkColour, "%s", message_.c_str());
  }
}

}  // namespace spidarcad::app
