// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/calibration_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "doc/input_error.h"
#include "spidarcad/modeling/scene_io.h"

namespace spidarcad::app {

namespace {

using nlohmann::json;

constexpr const char* kFormat = "spidarcad-calibration";
constexpr int kVersion = 1;

bool IsSimulatedKind(const std::string& kind) { return kind == "simulated" || kind == "board-sim"; }

// Field readers: each names the file and the field path when the value is missing or wrong.
class Reader {
 public:
  explicit Reader(std::string path) : path_(std::move(path)) {}

  [[noreturn]] void Fail(const std::string& field, const std::string& what) const {
    throw InputError(path_ + ": field '" + field + "': " + what);
  }
  const json& Member(const json& object, const std::string& where, const std::string& key) const {
    const std::string field = where.empty() ? key : where + "." + key;
    if (!object.is_object()) Fail(where, "expected an object, got " + object.dump());
    if (!object.contains(key)) {
      throw InputError(path_ + ": field '" + field +
                       "' is missing (see docs/calibration-format.md)");
    }
    return object.at(key);
  }
  double Number(const json& object, const std::string& where, const std::string& key) const {
    const json& v = Member(object, where, key);
    const std::string field = where.empty() ? key : where + "." + key;
    if (!v.is_number()) Fail(field, "expected a number, got " + v.dump());
    const double x = v.get<double>();
    if (!std::isfinite(x)) Fail(field, "expected a finite number");
    return x;
  }
  double Positive(const json& object, const std::string& where, const std::string& key) const {
    const double x = Number(object, where, key);
    if (!(x > 0.0)) Fail(where + "." + key, "expected a positive number, got " + Dump(x));
    return x;
  }
  double NonNegative(const json& object, const std::string& where, const std::string& key) const {
    const double x = Number(object, where, key);
    if (!(x >= 0.0)) Fail(where + "." + key, "expected a number >= 0, got " + Dump(x));
    return x;
  }
  std::uint64_t Unsigned(const json& object, const std::string& where, const std::string& key,
                         std::uint64_t max) const {
    const json& v = Member(object, where, key);
    const std::string field = where.empty() ? key : where + "." + key;
    if (!v.is_number_integer() ||
        (v.is_number_integer() && !v.is_number_unsigned() && v.get<std::int64_t>() < 0)) {
      Fail(field, "expected an integer >= 0, got " + v.dump());
    }
    const std::uint64_t x = v.get<std::uint64_t>();
    if (x > max) Fail(field, "expected at most " + std::to_string(max) + ", got " + v.dump());
    return x;
  }
  std::string String(const json& object, const std::string& where, const std::string& key) const {
    const json& v = Member(object, where, key);
    if (!v.is_string())
      Fail(where.empty() ? key : where + "." + key, "expected a string, got " + v.dump());
    return v.get<std::string>();
  }

 private:
  static std::string Dump(double x) { return json(x).dump(); }
  std::string path_;
};

// "YYYY-MM-DDTHH:MM:SSZ" with a plausible calendar date and time.
bool IsIso8601Utc(const std::string& s) {
  if (s.size() != 20) return false;
  static const char kPattern[] = "dddd-dd-ddTdd:dd:ddZ";
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char p = kPattern[i];
    if (p == 'd' ? (s[i] < '0' || s[i] > '9') : s[i] != p) return false;
  }
  const int month = std::stoi(s.substr(5, 2)), day = std::stoi(s.substr(8, 2));
  const int hour = std::stoi(s.substr(11, 2)), minute = std::stoi(s.substr(14, 2));
  const int second = std::stoi(s.substr(17, 2));
  return month >= 1 && month <= 12 && day >= 1 && day <= 31 && hour <= 23 && minute <= 59 &&
         second <= 60;
}

std::string Metres(double x) {
  std::ostringstream os;
  os << x;
  return os.str();
}

std::string GeometryText(const haptics::SpidarGeometry& g) {
  return "--frame " + Metres(g.a) + "," + Metres(g.b) + "," + Metres(g.c) + " --pole " +
         Metres(g.d);
}

}  // namespace

std::string CalibrationDevice::Describe() const {
  if (kind == "usb") {
    return "USB board serial " + (serial.empty() ? std::string("(none)") : serial);
  }
  return "simulated SPIDAR-G seed " + std::to_string(seed);
}

CalibrationFit FitOf(const haptics::CalibrationResult& result, int samples) {
  CalibrationFit fit;
  fit.samples = samples;
  fit.iterations = result.iterations;
  fit.condition = result.condition;
  fit.rms_residual = result.rms_residual;
  fit.string_rms_residual = result.string_rms_residual;
  return fit;
}

std::string NowIso8601Utc() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

std::string CalibrationFileJson(const CalibrationFile& file) {
  json j;
  j["format"] = kFormat;
  j["version"] = kVersion;
  json device;
  device["kind"] = file.device.kind;
  if (file.device.kind == "usb") {
    device["serial"] = file.device.serial;
  } else {
    device["seed"] = file.device.seed;
  }
  const haptics::SpidarGeometry& g = file.device.geometry;
  device["frame"] = {{"a", g.a}, {"b", g.b}, {"c", g.c}};
  device["pole"] = g.d;
  j["device"] = device;
  j["date"] = file.date;
  j["method"] = file.method;
  j["encoder"] = {{"counts_per_rev", file.calibration.spec.counts_per_rev},
                  {"pulley_radius", file.calibration.spec.pulley_radius}};
  json strings = json::array();
  for (const auto& p : file.calibration.strings) {
    strings.push_back({{"offset", p.offset},
                       {"gain", p.gain},
                       {"quadratic", p.quadratic},
                       {"stretch", p.stretch}});
  }
  j["strings"] = strings;
  json per_string = json::array();
  for (int i = 0; i < haptics::kNumStrings; ++i)
    per_string.push_back(file.fit.string_rms_residual[i]);
  j["fit"] = {
      {"samples", file.fit.samples},
      {"iterations", file.fit.iterations},
      {"condition", std::isfinite(file.fit.condition) ? json(file.fit.condition) : json(nullptr)},
      {"rms_residual", file.fit.rms_residual},
      {"string_rms_residual", per_string}};
  return j.dump(2) + "\n";
}

void SaveCalibrationFile(const CalibrationFile& file, const std::string& path,
                         const std::string& option) {
  const std::string text = CalibrationFileJson(file);
  const std::filesystem::path target(path);
  const std::filesystem::path dir = target.parent_path().empty() ? "." : target.parent_path();
  std::string temporary = (dir / ("." + target.filename().string() + ".XXXXXX")).string();
  const int fd = mkstemp(temporary.data());
  if (fd < 0) {
    throw InputError(option + ": cannot create a temporary file next to '" + path +
                     "': " + std::strerror(errno));
  }
  const auto fail = [&](const std::string& what) {
    const int error = errno;
    ::close(fd);
    ::unlink(temporary.c_str());
    throw InputError(option + ": writing '" + path + "' failed (" + what +
                     "): " + std::strerror(error));
  };
  std::size_t written = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("write");
    }
    written += static_cast<std::size_t>(n);
  }
  if (::fchmod(fd, 0644) != 0) fail("chmod");
  if (::fsync(fd) != 0) fail("fsync");
  if (::close(fd) != 0) {
    const int error = errno;
    ::unlink(temporary.c_str());
    throw InputError(option + ": writing '" + path + "' failed (close): " + std::strerror(error));
  }
  if (std::rename(temporary.c_str(), path.c_str()) != 0) {
    const int error = errno;
    ::unlink(temporary.c_str());
    throw InputError(option + ": cannot rename the temporary file to '" + path +
                     "': " + std::strerror(error));
  }
}

CalibrationFile LoadCalibrationFile(const std::string& path) {
  json j;
  try {
    // Refuses a missing file, /dev/zero or a pipe, and a file past the limit, before reading;
    // then syntax, nesting and number errors with line, column and field.
    j = modeling::ParseJsonText(
        modeling::ReadBoundedFile(path, kMaxCalibrationFileBytes, "calibration file"), path);
  } catch (const modeling::SceneError& e) {
    throw InputError(e.what());
  }
  const Reader r(path);
  if (!j.is_object()) throw InputError(path + ": expected a JSON object at the top level");
  const json& format = r.Member(j, "", "format");
  if (format != kFormat) {
    r.Fail("format", std::string("expected \"") + kFormat + "\", got " + format.dump() +
                         "; is this a calibration file?");
  }
  const json& version = r.Member(j, "", "version");
  if (version != kVersion) {
    r.Fail("version", "only version 1 is supported, got " + version.dump() +
                          " (written by a newer spidarcad?)");
  }
  CalibrationFile file;
  const json& device = r.Member(j, "", "device");
  file.device.kind = r.String(device, "device", "kind");
  if (file.device.kind == "usb") {
    file.device.serial = r.String(device, "device", "serial");
  } else if (IsSimulatedKind(file.device.kind)) {
    file.device.seed =
        r.Unsigned(device, "device", "seed", std::numeric_limits<std::uint64_t>::max());
  } else {
    r.Fail("device.kind",
           "expected \"simulated\", \"board-sim\" or \"usb\", got \"" + file.device.kind + "\"");
  }
  const json& frame = r.Member(device, "device", "frame");
  file.device.geometry.a = r.Positive(frame, "device.frame", "a");
  file.device.geometry.b = r.Positive(frame, "device.frame", "b");
  file.device.geometry.c = r.Positive(frame, "device.frame", "c");
  file.device.geometry.d = r.Positive(device, "device", "pole");
  try {
    file.device.geometry.Validate();
  } catch (const std::invalid_argument& e) {
    r.Fail("device", e.what());
  }
  file.date = r.String(j, "", "date");
  if (!IsIso8601Utc(file.date)) {
    r.Fail("date",
           "expected ISO 8601 UTC time \"YYYY-MM-DDTHH:MM:SSZ\", got \"" + file.date + "\"");
  }
  file.method = r.String(j, "", "method");
  if (file.method != "self" && file.method != "line") {
    r.Fail("method", "expected \"self\" or \"line\", got \"" + file.method + "\"");
  }
  const json& encoder = r.Member(j, "", "encoder");
  file.calibration.spec.counts_per_rev =
      static_cast<int>(r.Unsigned(encoder, "encoder", "counts_per_rev", 1000000000));
  if (file.calibration.spec.counts_per_rev == 0) {
    r.Fail("encoder.counts_per_rev", "expected a positive integer, got 0");
  }
  file.calibration.spec.pulley_radius = r.Positive(encoder, "encoder", "pulley_radius");
  file.device.encoder = file.calibration.spec;
  const json& strings = r.Member(j, "", "strings");
  if (!strings.is_array() || strings.size() != haptics::kNumStrings) {
    r.Fail("strings",
           "expected an array of 8 objects (one per string), got " +
               (strings.is_array() ? std::to_string(strings.size()) + " entries" : strings.dump()));
  }
  for (int i = 0; i < haptics::kNumStrings; ++i) {
    const std::string where = "strings[" + std::to_string(i) + "]";
    haptics::StringEncoderParams& p = file.calibration.strings[i];
    p.offset = r.Number(strings[i], where, "offset");
    p.gain = r.Positive(strings[i], where, "gain");
    p.quadratic = r.Number(strings[i], where, "quadratic");
    p.stretch = r.NonNegative(strings[i], where, "stretch");
  }
  try {
    file.calibration.Validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(path + ": " + e.what());
  }
  const json& fit = r.Member(j, "", "fit");
  file.fit.samples = static_cast<int>(r.Unsigned(fit, "fit", "samples", 1000000000));
  file.fit.iterations = static_cast<int>(r.Unsigned(fit, "fit", "iterations", 1000000000));
  const json& condition = r.Member(fit, "fit", "condition");
  file.fit.condition = condition.is_null() ? std::numeric_limits<double>::infinity()
                                           : r.NonNegative(fit, "fit", "condition");
  file.fit.rms_residual = r.NonNegative(fit, "fit", "rms_residual");
  const json& per_string = r.Member(fit, "fit", "string_rms_residual");
  if (!per_string.is_array() || per_string.size() != haptics::kNumStrings) {
    r.Fail("fit.string_rms_residual", "expected an array of 8 numbers, got " + per_string.dump());
  }
  for (int i = 0; i < haptics::kNumStrings; ++i) {
    const json& v = per_string[i];
    const std::string field = "fit.string_rms_residual[" + std::to_string(i) + "]";
    if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < 0.0) {
      r.Fail(field, "expected a number >= 0 (m), got " + v.dump());
    }
    file.fit.string_rms_residual[i] = v.get<double>();
  }
  return file;
}

std::string CalibrationMismatch(const CalibrationFile& file, const CalibrationDevice& device) {
  const CalibrationDevice& made = file.device;
  if (IsSimulatedKind(made.kind) != IsSimulatedKind(device.kind)) {
    return "it was made on a " + made.Describe() + ", this session uses a " + device.Describe();
  }
  if (IsSimulatedKind(made.kind) && made.seed != device.seed) {
    return "it was made on the " + made.Describe() + ", this session uses seed " +
           std::to_string(device.seed) + " (--seed)";
  }
  if (!IsSimulatedKind(made.kind) && made.serial != device.serial) {
    return "it was made on the " + made.Describe() + ", the connected board is serial " +
           (device.serial.empty() ? std::string("(none)") : device.serial);
  }
  const haptics::SpidarGeometry& a = made.geometry;
  const haptics::SpidarGeometry& b = device.geometry;
  const auto same = [](double x, double y) { return std::abs(x - y) <= 1e-9; };
  if (!same(a.a, b.a) || !same(a.b, b.b) || !same(a.c, b.c) || !same(a.d, b.d)) {
    return "it was made for the frame " + GeometryText(a) + ", this session's frame is " +
           GeometryText(b) + " (a calibration holds only for the frame it was made on)";
  }
  if (file.calibration.spec.counts_per_rev != device.encoder.counts_per_rev ||
      !same(file.calibration.spec.pulley_radius, device.encoder.pulley_radius)) {
    return "its encoder (" + std::to_string(file.calibration.spec.counts_per_rev) +
           " counts/rev, pulley radius " + Metres(file.calibration.spec.pulley_radius) +
           " m) is not this device's (" + std::to_string(device.encoder.counts_per_rev) +
           " counts/rev, " + Metres(device.encoder.pulley_radius) + " m)";
  }
  return {};
}

namespace {

// "usb:SERIAL" for a board with a serial number; "" for anything the memory does not keep.
std::string MemoryKey(const CalibrationDevice& device) {
  if (device.kind != "usb" || device.serial.empty()) return {};
  return "usb:" + device.serial;
}

// The memory's calibrations object; empty when the file is missing or not a memory file.
json ReadMemory(const std::string& path) {
  json empty = json::object();
  std::ifstream in(path);
  if (!in) return empty;
  try {
    const json doc = json::parse(in);
    if (doc.is_object() && doc.value("format", "") == "spidarcad-devices" &&
        doc.contains("calibrations") && doc["calibrations"].is_object()) {
      return doc["calibrations"];
    }
  } catch (const json::exception&) {
  }
  return empty;
}

}  // namespace

std::string DeviceMemoryPath() {
  const char* xdg = std::getenv("XDG_CONFIG_HOME");
  if (xdg != nullptr && *xdg == '/') return std::string(xdg) + "/spidarcad/devices.json";
  const char* home = std::getenv("HOME");
  if (home != nullptr && *home == '/') return std::string(home) + "/.config/spidarcad/devices.json";
  return {};
}

std::string RememberedCalibration(const CalibrationDevice& device) {
  const std::string key = MemoryKey(device);
  const std::string path = DeviceMemoryPath();
  if (key.empty() || path.empty()) return {};
  const json calibrations = ReadMemory(path);
  const auto it = calibrations.find(key);
  if (it == calibrations.end() || !it->is_string()) return {};
  return it->get<std::string>();
}

bool RememberCalibration(const CalibrationDevice& device, const std::string& path,
                         std::string* why) {
  const std::string key = MemoryKey(device);
  if (key.empty()) return true;
  const std::string memory = DeviceMemoryPath();
  if (memory.empty()) {
    if (why != nullptr) *why = "neither XDG_CONFIG_HOME nor HOME is set";
    return false;
  }
  std::error_code ec;
  const std::filesystem::path absolute = std::filesystem::absolute(path, ec);
  if (ec) {
    if (why != nullptr) *why = path + ": " + ec.message();
    return false;
  }
  json calibrations = ReadMemory(memory);
  calibrations[key] = absolute.lexically_normal().string();
  json doc = {{"format", "spidarcad-devices"}, {"version", 1}, {"calibrations", calibrations}};
  const std::filesystem::path target(memory);
  std::filesystem::create_directories(target.parent_path(), ec);
  const std::string temporary = memory + ".tmp";
  {
    std::ofstream out(temporary, std::ios::trunc);
    out << doc.dump(2) << "\n";
    if (!out.flush()) {
      if (why != nullptr) *why = "cannot write " + temporary;
      std::filesystem::remove(temporary, ec);
      return false;
    }
  }
  std::filesystem::rename(temporary, target, ec);
  if (ec) {
    if (why != nullptr) *why = "cannot write " + memory + ": " + ec.message();
    std::filesystem::remove(temporary, ec);
    return false;
  }
  return true;
}

}  // namespace spidarcad::app
