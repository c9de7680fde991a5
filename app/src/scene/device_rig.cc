// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/device_rig.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include "spidarcad/haptics/board_simulator.h"
#include "spidarcad/haptics/calibration.h"
#include "spidarcad/haptics/kinematics.h"

namespace spidarcad::app {

namespace {

using haptics::DeviceStatus;

// The driver's state into `link` (tick path: copies only).
void CopyDriverState(const haptics::usb::UsbSpidarG& driver, RigLink* link) noexcept {
  link->has_driver = true;
  link->status = driver.status();
  link->stats = driver.stats();
  // A plain bounded copy (printf-family functions may allocate).
  const char* error = driver.last_error();
  std::size_t i = 0;
  for (; i + 1 < sizeof(link->error) && error[i] != '\0'; ++i) link->error[i] = error[i];
  link->error[i] = '\0';
}

// Shared by board-sim and usb: the USB driver's link summary.
std::string DriverLinkSummary(const haptics::usb::UsbSpidarG& driver) {
  const haptics::usb::UsbLinkStats& s = driver.stats();
  std::ostringstream os;
  os << "usb link: states " << s.states << ", lost " << s.lost << ", corrupt " << s.corrupt
     << ", stale " << s.stale << ", timeouts " << s.timeouts << ", comm_error ticks "
     << s.comm_error_ticks << ", disconnects " << s.disconnects << ", connects " << s.connects
     << "; final status " << haptics::DeviceStatusName(driver.status());
  return os.str();
}

// The serial number of the driver's last handshake ("" before one).
std::string BoardSerial(const haptics::usb::UsbSpidarG& driver) {
  const auto& serial = driver.board_info().serial;
  std::size_t n = 0;
  while (n < serial.size() && serial[n] != '\0') ++n;
  return std::string(serial.data(), n);
}

// What a real board is assumed to be: the options' device description.
haptics::DeviceInfo AssumedInfo(const haptics::SimulatedDeviceConfig& device) {
  device.Validate();
  haptics::DeviceInfo info;
  info.geometry = device.geometry;
  info.encoder = device.encoder;
  info.home_pose = device.home_pose;
  info.tension_min = 0.0;
  info.tension_max = device.tension_max;
  return info;
}

// --device simulated: the loop talks to SimulatedSpidarG directly.
class SimulatedRig final : public DeviceRig {
 public:
  explicit SimulatedRig(const haptics::SimulatedDeviceConfig& config)
      : seed_(config.seed), device_(config) {}
  const haptics::DeviceInfo& info() const override { return device_.info(); }
  haptics::SimulatedSpidarG* physical() override { return &device_; }
  void Read(double dt, haptics::EncoderReading* reading) noexcept override {
    device_.Step(dt);
    device_.Read(reading);
  }
  void Write(const haptics::Vector8d& tau) noexcept override { device_.WriteTensions(tau); }
  std::string Describe() const override { return "simulated (seed " + std::to_string(seed_) + ")"; }

 private:
  std::uint64_t seed_;
  haptics::SimulatedSpidarG device_;
};

// --device board-sim: UsbSpidarG over LoopbackTransport to a BoardSimulator whose physical
// device has the configuration (and seed) of `simulated`. The board advances one sample period
// each time the driver waits for a State (Read), so the session stays on the virtual clock.
class BoardSimRig final : public DeviceRig {
 public:
  explicit BoardSimRig(const RigOptions& options)
      : seed_(options.device.seed),
        board_(BoardConfigFor(options.device)),
        driver_(MakeLoopback(&board_, options.link_faults, &loopback_), board_.device().info(),
                options.usb) {}
  const haptics::DeviceInfo& info() const override { return driver_.info(); }
  haptics::SimulatedSpidarG* physical() override { return &board_.device(); }
  bool Start(const haptics::GripPose& initial) override {
    // The board's device runs during the handshake: put the grip where the hand holds it.
    board_.device().SetTruePose(initial);
    return driver_.Open() == DeviceStatus::kOk;
  }
  std::string StartFailure() const override {
    return std::string(
               "--device board-sim: the driver's handshake with the board simulator "
               "failed: ") +
           driver_.last_error();
  }
  void Read(double dt, haptics::EncoderReading* reading) noexcept override {
    const int plug = plug_request_.exchange(kNoRequest, std::memory_order_acq_rel);
    if (plug != kNoRequest) loopback_->SetPlugged(plug == kPlugIn);
    haptics::SimulatedSpidarG& device = board_.device();
    const double before = device.time();
    driver_.Read(reading);
    if (device.time() == before) {
      // The board did not run (unplugged, link closed): its motors are unpowered, and the
      // strings and the hand go on moving.
      device.WriteTensions(haptics::Vector8d::Zero());
      device.Step(dt);
    }
  }
  void Write(const haptics::Vector8d& tau) noexcept override { driver_.WriteTensions(tau); }
  void Link(RigLink* link) const noexcept override {
    CopyDriverState(driver_, link);
    link->plugged = loopback_->plugged();
  }
  void RequestPlugged(bool plugged) noexcept override {
    plug_request_.store(plugged ? kPlugIn : kUnplug, std::memory_order_release);
  }
  std::string Describe() const override {
    return "board-sim (USB driver over the board simulator, seed " + std::to_string(seed_) + ")";
  }
  std::string Serial() const override { return BoardSerial(driver_); }
  std::string LinkSummary() const override {
    return DriverLinkSummary(driver_) + "; board rejected " +
           std::to_string(board_.rejected_packets()) + ", watchdog trips " +
           std::to_string(board_.watchdog_trips());
  }

 private:
  static constexpr int kNoRequest = 0, kPlugIn = 1, kUnplug = 2;
  static haptics::usb::BoardConfig BoardConfigFor(const haptics::SimulatedDeviceConfig& device) {
    haptics::usb::BoardConfig config;
    config.device = device;
    return config;
  }
  static std::unique_ptr<haptics::usb::Transport> MakeLoopback(
      haptics::usb::BoardSimulator* board, const haptics::usb::LinkFaults& faults,
      haptics::usb::LoopbackTransport** out) {
    auto link = std::make_unique<haptics::usb::LoopbackTransport>(board, faults);
    *out = link.get();
    return link;
  }
  std::uint64_t seed_;
  haptics::usb::BoardSimulator board_;                   // outlives the driver
  haptics::usb::LoopbackTransport* loopback_ = nullptr;  // owned by the driver; set before it
  haptics::usb::UsbSpidarG driver_;
  std::atomic<int> plug_request_{kNoRequest};
};

// --device usb: a real board over libusb (or a test transport).
class UsbRig final : public DeviceRig {
 public:
  explicit UsbRig(const RigOptions& options)
      : off_tick_(options.reconnect_off_tick),
        interval_(options.usb.reconnect_every > 0 ? options.usb.reconnect_every * 1e-3 : 0.0),
        libusb_(!options.make_transport),
        driver_(options.make_transport ? options.make_transport()
                                       : std::make_unique<haptics::usb::LibusbTransport>(),
                AssumedInfo(options.device), DriverConfig(options)) {
    CopyDriverState(driver_, &link_);
  }
  const haptics::DeviceInfo& info() const override { return driver_.info(); }
  haptics::SimulatedSpidarG* physical() override { return nullptr; }
  bool Start(const haptics::GripPose&) override {
    const bool ok = driver_.Open() == DeviceStatus::kOk;
    CopyDriverState(driver_, &link_);
    if (ok) SetSerial(BoardSerial(driver_));
    return ok;
  }
  std::string StartFailure() const override {
    std::string what = std::string("--device usb: no SPIDAR-G controller board could be opened (") +
                       haptics::DeviceStatusName(link_.status) + ": " + link_.error + ").\n";
    what +=
        "  Check that the board is plugged in and powered, and run `spidarcad device list`: it\n"
        "  lists the boards on the bus and says when permission is missing. To use the board\n"
        "  without root, install the udev rules assets/udev/99-spidarcad.rules once:\n"
        "    sudo cp assets/udev/99-spidarcad.rules /etc/udev/rules.d/\n"
        "    sudo udevadm control --reload-rules && sudo udevadm trigger\n"
        "  and replug the board. To run without hardware use --device simulated or board-sim.";
    return what;
  }
  void Read(double, haptics::EncoderReading* reading) noexcept override {
    if (off_tick_ && service_owns_.load(std::memory_order_acquire)) {
      // Service() is re-opening the board: the driver is not ours to touch.
      *reading = last_reading_;
      reading->status = DeviceStatus::kNotConnected;
      link_.status = DeviceStatus::kNotConnected;
      return;
    }
    driver_.Read(reading);
    last_reading_ = *reading;
    CopyDriverState(driver_, &link_);
    if (off_tick_ && !driver_.transport().is_open()) {
      service_owns_.store(true, std::memory_order_release);  // hand the link to Service
    }
  }
  void Write(const haptics::Vector8d& tau) noexcept override {
    if (off_tick_ && service_owns_.load(std::memory_order_acquire)) return;
    driver_.WriteTensions(tau);
    link_.status = driver_.status();
  }
  void Link(RigLink* link) const noexcept override { *link = link_; }
  bool Service() override {
    if (!off_tick_ || !service_owns_.load(std::memory_order_acquire)) return false;
    // May allocate and wait for the handshake: this is not the tick. A board that answers gives
    // its serial number (it may have been absent at start, or replaced).
    if (driver_.Open() == DeviceStatus::kOk) SetSerial(BoardSerial(driver_));
    service_owns_.store(false, std::memory_order_release);
    return true;
  }
  double service_interval() const override { return off_tick_ ? interval_ : 0.0; }
  std::string Describe() const override {
    return libusb_ ? "usb (libusb)" : "usb (test transport)";
  }
  std::string LinkSummary() const override { return DriverLinkSummary(driver_); }
  std::string Serial() const override {
    const std::lock_guard<std::mutex> lock(serial_mutex_);
    return serial_;
  }

 private:
  void SetSerial(std::string serial) {
    const std::lock_guard<std::mutex> lock(serial_mutex_);
    serial_ = std::move(serial);
  }
  static haptics::usb::UsbDeviceConfig DriverConfig(const RigOptions& options) {
    haptics::usb::UsbDeviceConfig config = options.usb;
    if (options.reconnect_off_tick) config.reconnect_every = 0;
    return config;
  }
  bool off_tick_;
  double interval_;
  bool libusb_;
  haptics::usb::UsbSpidarG driver_;
  // Who may touch driver_: the tick (false) or Service (true). Release/acquire hands it over.
  std::atomic<bool> service_owns_{false};
  haptics::EncoderReading last_reading_;  // tick-owned
  RigLink link_;                          // tick-owned snapshot
  // The serial number of the last successful handshake (Start or Service), for the main thread
  // while Service may be re-opening (the tick never takes this lock).
  mutable std::mutex serial_mutex_;
  std::string serial_;
};

}  // namespace

bool ParseRigKind(const std::string& name, RigKind* kind) {
  if (name == "simulated") {
    *kind = RigKind::kSimulated;
  } else if (name == "board-sim") {
    *kind = RigKind::kBoardSim;
  } else if (name == "usb") {
    *kind = RigKind::kUsb;
  } else {
    return false;
  }
  return true;
}

std::string DescribeLink(const RigLink& link) {
  if (!link.has_driver) return {};
  const haptics::usb::UsbLinkStats& s = link.stats;
  if (link.status == DeviceStatus::kNotConnected) {
    std::string text =
        "not connected — retrying; run `spidarcad device list`, udev rules "
        "assets/udev/99-spidarcad.rules";
    if (!link.plugged) {
      text += " (board simulator unplugged)";
    } else if (link.error[0] != '\0') {
      text += std::string(" (") + link.error + ")";
    }
    return text;
  }
  char line[300];
  std::snprintf(line, sizeof(line),
                "%s: states %llu, lost %llu, timeouts %llu, comm errors %llu, disconnects %llu, "
                "reconnects %llu",
                haptics::DeviceStatusName(link.status), static_cast<unsigned long long>(s.states),
                static_cast<unsigned long long>(s.lost),
                static_cast<unsigned long long>(s.timeouts),
                static_cast<unsigned long long>(s.comm_error_ticks),
                static_cast<unsigned long long>(s.disconnects),
                static_cast<unsigned long long>(s.connects > 0 ? s.connects - 1 : 0));
  std::string text = line;
  if (link.status == DeviceStatus::kFault && link.error[0] != '\0') {
    text += std::string(" (") + link.error + ")";
  }
  return text;
}

std::unique_ptr<DeviceRig> MakeDeviceRig(RigKind kind, const RigOptions& options) {
  switch (kind) {
    case RigKind::kBoardSim:
      return std::make_unique<BoardSimRig>(options);
    case RigKind::kUsb:
      return std::make_unique<UsbRig>(options);
    case RigKind::kSimulated:
      break;
  }
  return std::make_unique<SimulatedRig>(options.device);
}

haptics::DeviceInfo NominalDeviceInfo() {
  const haptics::SimulatedDeviceConfig nominal;
  haptics::DeviceInfo info;
  info.geometry = nominal.geometry;
  info.encoder = nominal.encoder;
  info.home_pose = nominal.home_pose;
  info.tension_min = 0.0;
  info.tension_max = nominal.tension_max;
  return info;
}

haptics::EncoderCalibration NominalCalibration(const haptics::DeviceInfo& info) {
  return haptics::EncoderCalibration::Nominal(
      info.encoder, haptics::InverseKinematics(info.geometry, info.home_pose));
}

SimulatedCalibration CalibrateSimulated(haptics::SimulatedSpidarG* device) {
  if (device == nullptr) throw std::invalid_argument("CalibrateSimulated: no simulated device");
  const haptics::DeviceInfo& info = device->info();
  const haptics::SpidarGeometry& g = info.geometry;
  const haptics::EncoderCalibration nominal = NominalCalibration(info);
  const std::vector<haptics::GripPose> jig = haptics::RandomGripPoses(
      g, kCalibrationJigPoses, 0.5 * std::min({g.a, g.b, g.c}), 0.5, 0.4, /*seed=*/7);
  const haptics::CalibrationResult fit = haptics::FitLinesPerString(
      g, nominal, haptics::GatherKnownSamples(device, jig, kCalibrationJigTension));
  SimulatedCalibration result;
  char text[160];
  if (fit.status == haptics::CalibrationStatus::kOk) {
    result.ok = true;
    result.calibration = fit.calibration;
    result.rms_residual = fit.rms_residual;
    std::snprintf(text, sizeof(text), "line-fit calibration on %d jig poses (rms %.3f mm)",
                  kCalibrationJigPoses, fit.rms_residual * 1e3);
  } else {
    result.calibration = nominal;
    std::snprintf(text, sizeof(text), "NOMINAL calibration (line fit failed: %s)",
                  haptics::CalibrationStatusName(fit.status));
  }
  result.description = text;
  return result;
}

RigServiceThread::RigServiceThread(DeviceRig* rig) {
  const double interval = rig->service_interval();
  if (!(interval > 0.0)) return;
  thread_ = std::thread([this, rig, interval] {
    const auto slice = std::chrono::milliseconds(10);
    const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(interval));
    auto next = std::chrono::steady_clock::now();
    while (!stop_.load(std::memory_order_acquire)) {
      if (std::chrono::steady_clock::now() >= next && rig->Service()) {
        next = std::chrono::steady_clock::now() + period;
      }
      std::this_thread::sleep_for(slice);
    }
  });
}

RigServiceThread::~RigServiceThread() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

}  // namespace spidarcad::app
