// `spidarcad run`: a headless haptic session. The full haptic loop (HapticLoop) runs on a
// virtual clock at 1 kHz against the simulated SPIDAR-G (strings, encoders and calibration
// error included), gripped by a simulated hand that follows a scripted trajectory and is pushed
// by the device's wrench. One CSV row per tick; a summary on stdout. --device picks the path to
// the device (DeviceRig, scene/device_rig.h, shared with the window): the simulated SPIDAR-G
// directly, the USB driver over the in-process board simulator (board-sim), or the USB driver
// over libusb to a real board (usb, real time).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "scene/assembly_scene.h"
#include "scene/calibration_file.h"
#include "scene/device_rig.h"
#include "scene/document_file.h"
#include "scene/scene_haptics.h"
#include "scene/trajectory_player.h"
#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/loop_runner.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "spidarcad/haptics/trajectory.h"
#include "spidarcad/modeling/scene_io.h"

namespace spidarcad::app {

namespace {

constexpr const char* kRunHelp =
    "Runs the 1 kHz haptic loop headless on a virtual clock: the simulated SPIDAR-G (encoder\n"
    "errors, noise, string stretch, motor lag; read through the nominal calibration unless\n"
    "--calibrate) is gripped by a simulated hand (mass-spring-damper) that follows the\n"
    "trajectory and is pushed by the device.\n"
    "\n"
    "--calibrate: before the run, calibrate the simulated SPIDAR-G as the window does at\n"
    "start-up (a line fit per string on 24 jig poses, seed 7, 1 N per string) and read its\n"
    "encoders through that fit instead of the nominal model; the summary prints the fit's rms\n"
    "residual. Without it the nominal model's encoder gain errors (about 6 %) put the measured\n"
    "grip millimetres from the true one, so the forces act on a grip that is not where the hand\n"
    "holds it. Use it when an open-loop script must hit millimetre targets, such as seating a\n"
    "peg (assets/trajectories/seat_right_leg.csv on assets/scenes/assembly.json seats the right\n"
    "leg only with it). Off by default (the golden runs use the nominal model). Simulated and\n"
    "board-sim only: a real board is calibrated with `spidarcad calibrate`.\n"
    "\n"
    "--calibration FILE: read the encoders through a calibration file written by `spidarcad\n"
    "calibrate --out` (docs/calibration-format.md) instead of the nominal model. The file must\n"
    "be this device's: the same simulated seed (simulated and board-sim share it) or the same\n"
    "board serial (usb), and the same --frame/--pole; otherwise exit 2 with the reason.\n"
    "\n"
    "--frame A,B,C --pole D: the device's size (frame half-sides and pole half-length, m;\n"
    "default 0.24,0.24,0.24 and 0.04, the paper's 48 cm frame and 4 cm grip; Sec. 8 scales\n"
    "the frame). The simulated SPIDAR-G is built that size; a real board is assumed to be.\n"
    "\n"
    "--device:\n"
    "  simulated  (default) the loop reads and commands the simulated SPIDAR-G directly\n"
    "  board-sim  the same simulated SPIDAR-G behind the controller board's firmware\n"
    "             simulator, driven by the USB driver (UsbSpidarG) over the in-process loopback\n"
    "             transport: the driver's whole path, packets byte for byte (docs/protocol.md),\n"
    "             without hardware. Forces match `simulated` to within a few hundredths of a\n"
    "             newton (tensions travel in mN; the handshake shifts the device's noise by a\n"
    "             sample); the summary adds the link statistics.\n"
    "  usb        a real controller board over libusb. The user's hand moves the grip: the loop\n"
    "             runs in real time (absolute 1 ms sleeps) for the trajectory's duration, which\n"
    "             is otherwise unused; x..grasp are then the pose measured by forward\n"
    "             kinematics. Nothing attached or no permission: exit 2 naming what to check\n"
    "             (`spidarcad device list`, the udev rules in assets/udev/).\n"
    "\n"
    "SCENE: omit it for an empty scene, 'demo' for the built-in demo (a floor wall at\n"
    "z = -0.03 m, normal +z, 2000 N/m, 5 N·s/m, and a 20 N/m spring toward (0.05, 0, 0) m; device\n"
    "coordinates), or a scene file or document (docs/scene-format.md, version 1 or 2) of implicit\n"
    "solids; a document's meshes, FE models and sculpts are not rendered yet, nor rigid parts\n"
    "beside solids (the summary lists them as skipped); a document of rigid parts and no solid\n"
    "(an assembly saved from the window) is one assembly field, as a scene's \"parts\" are:\n"
    "  --tool proxy   each solid is a god-object proxy on the grip centre, with friction\n"
    "  --tool shell   the cross grip (poles +-d, radius 6 mm) is a six-DOF point shell with\n"
    "                 virtual coupling against the union of the solids: torques are felt\n"
    "--stiffness and --damping are what the hand feels at the grip (N/m and N·s/m of grip motion;\n"
    "the fields get them divided by the world scale s). FE parts are not rendered by `run` yet.\n"
    "A scene with a \"snap\" object adds snap forces toward its solids' vertices, edges and\n"
    "faces (docs/scene-format.md, \"Snap forces\"); the summary gives the feature counts.\n"
    "A scene with `parts` (an assembly, e.g. assets/scenes/assembly.json) is rendered as one\n"
    "assembly field instead: parts are picked with the grasp, carried with six-DOF contact and\n"
    "seated peg in hole; X_WD is then identity unless --world-scale/--world-origin say otherwise.\n"
    "\n"
    "X_WD (scene files): p_W = s·p_D + p_WDo. By default the scene is fitted to the device's\n"
    "reachable cube (+-0.1 m): the box of its bounded solids (modeling::FindBounds) is centred on\n"
    "the device origin (p_WDo = box centre) and its largest side spans 80 % of the cube\n"
    "(s = side / 0.16 m). --world-scale and --world-origin override either part.\n"
    "\n"
    "Trajectory CSV: t,x,y,z,qw,qx,qy,qz,grasp (s; m in the device frame D; unit quaternion\n"
    "of the grip frame R_DT; grasp angle in rad, pi/2 at rest); '#' comments allowed.\n"
    "Samples are interpolated (linear, slerp); the run lasts from the first to the last t, at "
    "most\n"
    "--max-duration (default 3600 s; docs/limits.md). The file may have at most 256 MiB.\n"
    "Progress goes to stderr when it is a terminal or with --progress.\n"
    "\n"
    "Output CSV, one row per tick, header line first:\n"
    "  t                 time, s\n"
    "  x,y,z,qw..qz      true grip pose (the hand's), D (usb: the measured pose)\n"
    "  grasp             true grasp angle, rad (usb: measured)\n"
    "  fx,fy,fz,mx,my,mz,g  wrench commanded by the loop (after safety), D: N, N·m about p0,\n"
    "                    grasp torque N·m (> 0 squeezes)\n"
    "  tau1..tau8        string tensions sent to the device, N\n"
    "  tick_us           wall-clock compute time of HapticLoop::Step, µs\n"
    "  events            safety event bits of the tick (see summary for names)\n"
    "  fk_x,fk_y,fk_z    grip centre measured by forward kinematics, m\n"
    "\n"
    "Example:\n"
    "  spidarcad run demo --trajectory assets/trajectories/press.csv --out press_result.csv\n"
    "  spidarcad run assets/scenes/platform.json --trajectory assets/trajectories/press.csv \\\n"
    "      --out platform_press.csv --world-scale 1 --world-origin 0.1,0,0.04";

struct RunOptions {
  std::string scene;
  std::string trajectory;
  std::string out;
  std::string device = "simulated";
  std::vector<double> hand;
  std::uint64_t seed = 1;
  std::string tool = "proxy";
  double stiffness = 1500.0;
  double damping = 1.0;
  std::vector<double> friction;
  double world_scale = 0.0;  // 0: fitted
  std::vector<double> world_origin;
  bool calibrate = false;            // line-fit calibration of the simulated device before the run
  std::string calibration;           // calibration file to read the encoders through
  haptics::SpidarGeometry geometry;  // the device's frame and pole (--frame, --pole)
  bool geometry_given = false;       // --frame or --pole given: it overrides the document's
  double max_duration = 3600.0;      // s: longest run accepted (docs/limits.md)
  bool progress = false;             // progress on stderr even when it is not a terminal
};

// Ceiling of --max-duration, s: 1e7 s is 1e10 ticks, far inside a long tick counter.
constexpr double kMaxRunDurationCeiling = 1e7;
// Line (1-based) of the first sample of the trajectory file whose time is past `limit`, 0 if
// none is found.
int LineOfTimePast(const std::string& path, double limit) {
  std::ifstream in(path);
  std::string raw;
  int line = 0;
  while (std::getline(in, raw)) {
    ++line;
    const auto begin = raw.find_first_not_of(" \t\r");
    if (begin == std::string::npos || raw[begin] == '#') continue;
    const auto comma = raw.find(',', begin);
    std::string field =
        raw.substr(begin, comma == std::string::npos ? std::string::npos : comma - begin);
    while (!field.empty() && (field.back() == ' ' || field.back() == '\t')) field.pop_back();
    double t = 0.0;
    const auto r = std::from_chars(field.data(), field.data() + field.size(), t);
    if (r.ec == std::errc() && t > limit) return line;
  }
  return 0;
}

// Progress of a long run on stderr: a line redrawn at most 5 times a second.
class RunProgress {
 public:
  RunProgress(bool enabled, long ticks) : enabled_(enabled), ticks_(ticks) {}
  void Tick(long k) {
    if (!enabled_ || k % 1000 != 0) return;
    const auto now = std::chrono::steady_clock::now();
    if (shown_ && now - last_ < std::chrono::milliseconds(200)) return;
    last_ = now;
    shown_ = true;
    std::fprintf(stderr, "\rspidarcad run: %ld / %ld ticks (%5.1f %%)", k, ticks_,
                 100.0 * double(k) / double(ticks_));
    std::fflush(stderr);
  }
  ~RunProgress() {
    if (shown_)
      std::fprintf(stderr, "\rspidarcad run: %ld / %ld ticks (100.0 %%)\n", ticks_, ticks_);
  }

 private:
  bool enabled_;
  long ticks_;
  bool shown_ = false;
  std::chrono::steady_clock::time_point last_;
};

std::string Fixed(double v, int digits) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(digits) << v;
  return os.str();
}

void RunRun(const RunOptions& options) {
  if (options.device != "simulated" && options.device != "board-sim" && options.device != "usb") {
    throw InputError("--device: '" + options.device +
                     "' is not a device; use simulated, board-sim or usb");
  }
  if (options.calibrate && !options.calibration.empty()) {
    throw InputError(
        "--calibrate and --calibration: choose one (--calibrate fits the simulated device at "
        "start-up, --calibration reads a file made by `spidarcad calibrate --out`)");
  }
  ValidateGeometry(options.geometry);
  // A bad or foreign calibration file fails before any work.
  std::optional<CalibrationFile> calibration_file;
  if (!options.calibration.empty()) {
    try {
      calibration_file = LoadCalibrationFile(options.calibration);
    } catch (const InputError& e) {
      throw InputError(std::string("--calibration: ") + e.what());
    }
  }
  if (options.calibrate && options.device == "usb") {
    throw InputError(
        "--calibrate: not with --device usb; it calibrates the simulated SPIDAR-G (simulated, "
        "board-sim). Calibrate a real board with `spidarcad calibrate`");
  }
  if (!(options.max_duration > 0.0 && options.max_duration <= kMaxRunDurationCeiling)) {
    throw InputError("--max-duration: must be in (0, 1e7] s, got " +
                     FormatNumber(options.max_duration));
  }
  haptics::Trajectory trajectory;
  CheckTrajectoryFile(options.trajectory);
  try {
    trajectory = haptics::Trajectory::Load(options.trajectory);
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--trajectory: ") + e.what());
  }
  // The run lasts from the first sample to the last: refuse it before any tick if that is longer
  // than --max-duration (also when the difference overflows).
  if (!(trajectory.end_time() - trajectory.start_time() <= options.max_duration)) {
    const double limit = trajectory.start_time() + options.max_duration;
    const int line = LineOfTimePast(options.trajectory, limit);
    throw InputError(
        "--trajectory " + options.trajectory +
        (line > 0 ? ":" + std::to_string(line) : std::string("")) +
        ": field t: the trajectory runs from t = " + FormatNumber(trajectory.start_time()) +
        " s to t = " + FormatNumber(trajectory.end_time()) + " s, longer than the " +
        FormatNumber(options.max_duration) +
        " s a run may last (--max-duration, in (0, 1e7] s; docs/limits.md); shorten the trajectory "
        "or "
        "raise --max-duration");
  }

  // The frame: --frame/--pole, else the document's own (its "device"), else the paper's.
  haptics::SpidarGeometry geometry = options.geometry;
  std::string frame_source = options.geometry_given ? "--frame/--pole" : "default";
  std::unique_ptr<haptics::HapticScene> scene;
  std::string scene_name = "empty";
  std::string fields_line;   // per-field names for the summary
  std::string skipped_line;  // a document's objects that run does not render yet
  std::string map_line = "X_WD: identity (device coordinates)";
  haptics::AssemblyField* assembly_field =
      nullptr;  // an assembly scene's field (owned by the loop)
  haptics::LoopSettings settings;
  settings.fk.max_residual = kNominalFkMaxResidual;  // nominal encoder model: mm-level errors
  if (options.scene.empty() || options.scene == "none") {
    scene = std::make_unique<haptics::HapticScene>();
  } else if (options.scene == "demo") {
    scene = haptics::MakeDemoScene();
    scene_name = "demo";
    fields_line = "fields: plane_wall (floor z = -0.03 m), spring (toward (0.05, 0, 0) m)";
  } else {
    OpenedDocument opened;
    try {
      opened = OpenDocumentFile(options.scene);
    } catch (const InputError& e) {
      throw InputError(std::string("SCENE: ") + e.what());
    }
    if (opened.doc->device() && !options.geometry_given) {
      geometry = *opened.doc->device();
      frame_source = "the document's";
    }
    // What `run` renders of a document today: its solids (one field each, or an assembly of
    // "parts"), or, in a document of rigid parts and no solid (an assembly saved from the
    // window), the assembly of its rigid parts as the window feels it; and snap. The other kinds
    // are listed in the summary as skipped.
    const modeling::Scene loaded = opened.doc->ToScene();
    const std::vector<AssemblyPartInput> rigid_parts = loaded.solids.empty()
                                                           ? RigidPartInputs(*opened.doc, nullptr)
                                                           : std::vector<AssemblyPartInput>{};
    for (const DocObject& o : opened.doc->objects()) {
      if (std::holds_alternative<SolidData>(o.data)) continue;
      if (!rigid_parts.empty() && std::holds_alternative<RigidPartData>(o.data)) continue;
      skipped_line += std::string(skipped_line.empty() ? "" : ", ") + ObjectKindName(o.data) +
                      " '" + o.name + "'";
    }
    if (!skipped_line.empty()) {
      skipped_line =
          "skipped (run renders solids, assembly parts and snap; not yet meshes, "
          "FE models, sculpts or rigid parts): " +
          skipped_line;
    }
    const std::size_t part_count = rigid_parts.empty() ? loaded.parts.size() : rigid_parts.size();
    if (opened.version == 2 && loaded.solids.empty() && rigid_parts.empty()) {
      // Nothing to render: the grip moves freely.
      scene = std::make_unique<haptics::HapticScene>();
      scene_name = options.scene + " (no solid)";
    } else if (part_count > 0) {
      // An assembly: one field owns every part (grasp, carry, contact, seats).
      std::unique_ptr<haptics::AssemblyField> assembly;
      try {
        assembly = rigid_parts.empty()
                       ? BuildAssemblyField(loaded)
                       : BuildAssemblyField(rigid_parts, AssemblySceneSettings{}, nullptr);
      } catch (const std::invalid_argument& e) {
        throw InputError(options.scene + ": " + e.what());
      }
      if (options.world_scale < 0.0) throw InputError("--world-scale: must be > 0 (0: default)");
      if (options.world_scale > 0.0) settings.X_WD.world_scale = options.world_scale;
      if (!options.world_origin.empty()) {
        if (options.world_origin.size() != 3) {
          throw InputError("--world-origin: expected x,y,z (m), got " +
                           std::to_string(options.world_origin.size()) + " numbers");
        }
        settings.X_WD.p_WDo = Eigen::Vector3d(options.world_origin[0], options.world_origin[1],
                                              options.world_origin[2]);
      }
      scene = std::make_unique<haptics::HapticScene>();
      assembly_field = assembly.get();
      scene->Add(std::move(assembly));
      scene_name = options.scene + " (assembly, " + std::to_string(part_count) + " parts)";
      fields_line = "fields: assembly (" + std::to_string(part_count) + " parts)";
      const Eigen::Vector3d& o = settings.X_WD.p_WDo;
      map_line = "X_WD: p_W = " + FormatNumber(settings.X_WD.world_scale) + " p_D + (" +
                 FormatNumber(o.x()) + ", " + FormatNumber(o.y()) + ", " + FormatNumber(o.z()) +
                 ") m";
    } else {
      SceneHapticsOptions haptic_options;
      if (options.tool == "proxy") {
        haptic_options.tool = ToolModel::kProxy;
      } else if (options.tool == "shell") {
        haptic_options.tool = ToolModel::kShell;
      } else {
        throw InputError("--tool: '" + options.tool + "' is not a tool model; use proxy or shell");
      }
      haptic_options.stiffness = options.stiffness;
      haptic_options.damping = options.damping;
      haptic_options.coupling_stiffness = std::min(options.stiffness, 1000.0);
      if (!options.friction.empty()) {
        if (options.friction.size() != 2) {
          throw InputError("--friction: expected static,dynamic, got " +
                           std::to_string(options.friction.size()) + " numbers");
        }
        haptic_options.static_friction = options.friction[0];
        haptic_options.dynamic_friction = options.friction[1];
      }
      if (options.world_scale != 0.0) haptic_options.world_scale = options.world_scale;
      if (!options.world_origin.empty()) {
        if (options.world_origin.size() != 3) {
          throw InputError("--world-origin: expected x,y,z (m), got " +
                           std::to_string(options.world_origin.size()) + " numbers");
        }
        haptic_options.p_WDo = Eigen::Vector3d(options.world_origin[0], options.world_origin[1],
                                               options.world_origin[2]);
      }
      haptic_options.grip_d = geometry.d;
      SceneHaptics built;
      try {
        haptic_options.Validate();
        built = BuildHapticScene(loaded, haptic_options);
      } catch (const std::invalid_argument& e) {
        const std::string what = e.what();
        // Option problems name the option; solid problems name the file.
        if (what.rfind("scene haptics option", 0) == 0) {
          throw InputError("--stiffness/--damping/--friction/--world-scale: " + what);
        }
        throw InputError(options.scene + ": " + what);
      }
      built.ApplyTo(&settings);
      scene = std::move(built.scene);
      scene_name = options.scene + " (tool " + ToolModelName(haptic_options.tool) + ")";
      fields_line = "fields:";
      for (std::size_t i = 0; i < built.fields.size(); ++i) {
        fields_line += std::string(i ? "," : "") + " " + built.fields[i].kind + " '" +
                       built.fields[i].solid + "'";
      }
      const Eigen::Vector3d& o = built.map.X_WD.p_WDo;
      map_line = "X_WD: p_W = " + FormatNumber(built.map.X_WD.world_scale) + " p_D + (" +
                 FormatNumber(o.x()) + ", " + FormatNumber(o.y()) + ", " + FormatNumber(o.z()) +
                 ") m; scale " + (built.map.scale_fitted ? "fitted" : "given") + ", origin " +
                 (built.map.origin_fitted ? "fitted" : "given");
      if (!built.map.bounds_W.isEmpty()) {
        const Eigen::AlignedBox3d& b = built.map.bounds_W;
        map_line += "; scene box (" + FormatNumber(b.min().x()) + ", " + FormatNumber(b.min().y()) +
                    ", " + FormatNumber(b.min().z()) + ") .. (" + FormatNumber(b.max().x()) + ", " +
                    FormatNumber(b.max().y()) + ", " + FormatNumber(b.max().z()) + ") m";
      }
    }  // not an assembly
  }
  const int num_fields = scene->size();

  haptics::HandSettings hand_settings;
  if (!options.hand.empty()) {
    if (options.hand.size() != 2) {
      throw InputError("--hand: expected stiffness,damping (N/m,N·s/m), got " +
                       std::to_string(options.hand.size()) + " numbers");
    }
    hand_settings.stiffness = options.hand[0];
    hand_settings.damping = options.hand[1];
  }
  try {
    hand_settings.Validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--hand: ") + e.what());
  }

  RigKind kind = RigKind::kSimulated;
  ParseRigKind(options.device, &kind);  // checked above
  RigOptions rig_options;
  rig_options.device.seed = options.seed;
  rig_options.device.geometry = geometry;
  rig_options.device.home_pose = haptics::GripPose::Rest(geometry.d);
  // A real board lost mid-run is re-opened by a service thread, not inside the tick (re-opening
  // goes through libusb, which allocates and locks); board-sim keeps its deterministic re-open
  // on the virtual clock.
  rig_options.reconnect_off_tick = kind == RigKind::kUsb;
  std::unique_ptr<DeviceRig> rig = MakeDeviceRig(kind, rig_options);
  const haptics::DeviceInfo& info = rig->info();
  haptics::SimulatedSpidarG* physical = rig->physical();  // null for a real board
  haptics::EncoderCalibration calibration = NominalCalibration(info);
  const double dt = 1e-3;
  const double t0 = trajectory.start_time();
  // At most 1e10 + 1 (duration checked above): fits a long.
  const long ticks = static_cast<long>(std::floor((trajectory.end_time() - t0) / dt + 1e-9)) + 1;
  haptics::SimulatedHand hand(hand_settings, trajectory.Sample(t0), info.geometry.d);
  std::string calibration_line;
  if (options.calibrate) {
    // As the window at start-up (device_rig.h); physical is not null (usb rejected above).
    const SimulatedCalibration fit = CalibrateSimulated(physical);
    calibration = fit.calibration;
    // Calibrated: FK's default acceptance, as the window; a failed fit keeps the nominal one.
    if (fit.ok) settings.fk.max_residual = haptics::FkSettings().max_residual;
    calibration_line = "calibration: " + fit.description;
    // The jig left the grip elsewhere at 1 N per string: back into the hand at minimum tension.
    physical->SetTruePose(hand.pose());
    physical->WriteTensions(haptics::Vector8d::Constant(settings.tension.tau_min));
    physical->Step(dt);
  }
  // The calibration file must belong to this device and frame (usb: checked after the
  // handshake, which reports the board's serial number).
  const auto check_file = [&](const std::string& serial) {
    CalibrationDevice device;
    device.kind = options.device;
    device.seed = options.seed;
    device.serial = serial;
    device.geometry = info.geometry;
    device.encoder = info.encoder;
    const std::string why = CalibrationMismatch(*calibration_file, device);
    if (!why.empty()) {
      throw InputError("--calibration: " + options.calibration + " does not fit: " + why);
    }
  };
  if (calibration_file) {
    if (physical != nullptr) check_file("");
    calibration = calibration_file->calibration;
    settings.fk.max_residual = haptics::FkSettings().max_residual;  // calibrated, as the window
    calibration_line = "calibration: " + options.calibration + " (" +
                       (calibration_file->method == "self" ? "self-calibration" : "line fit") +
                       " of the " + calibration_file->device.Describe() + ", " +
                       calibration_file->date + ")";
  }
  haptics::HapticLoop loop(info, calibration, settings);
  loop.Publish(std::move(scene));
  haptics::LatencyHistogram tick_time(1e-7, 100000);
  // board-sim / usb: the driver's handshake; no board answering is bad input (exit 2).
  if (!rig->Start(hand.pose())) throw InputError(rig->StartFailure());
  if (calibration_file && physical == nullptr) check_file(rig->Serial());
  const RigServiceThread service(rig.get());  // a thread only when the rig needs one (usb)

  std::ofstream out(options.out);
  if (!out) throw InputError("--out: cannot write '" + options.out + "'");
  out << "t,x,y,z,qw,qx,qy,qz,grasp,fx,fy,fz,mx,my,mz,g,tau1,tau2,tau3,tau4,tau5,tau6,tau7,tau8,"
         "tick_us,events,fk_x,fk_y,fk_z\n";
  std::string buffer;
  double max_force = 0.0;
  const auto wall_start = std::chrono::steady_clock::now();
  RunProgress progress(options.progress || isatty(STDERR_FILENO) == 1, ticks);
  for (long k = 0; k < ticks; ++k) {
    progress.Tick(k);
    const double t = t0 + k * dt;
    haptics::TickInputs inputs;
    if (physical) {
      hand.Step(trajectory.Sample(t), physical->TrueWrench(), dt);
      physical->SetTruePose(hand.pose());
    } else {
      // A real board: tick k starts at its absolute time (no drift); lateness is reported.
      const auto due = wall_start + std::chrono::microseconds(k * 1000);
      std::this_thread::sleep_until(due);
      inputs.lateness =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - due).count();
    }
    rig->Read(dt, &inputs.reading);
    const auto start = std::chrono::steady_clock::now();
    const haptics::TickOutputs result = loop.Step(inputs, dt);
    const auto stop = std::chrono::steady_clock::now();
    rig->Write(result.tau);
    const double seconds = std::chrono::duration<double>(stop - start).count();
    tick_time.Add(seconds);
    max_force = std::max(max_force, result.wrench_D.head<3>().norm());

    Eigen::Vector3d p = hand.position();
    Eigen::Quaterniond q(hand.rotation());
    double grasp = hand.grasp();
    if (!physical) {  // a real board: the measured pose (NaN without one)
      const bool ok = result.fk_status == haptics::FkStatus::kOk;
      p = ok ? result.pose_D.p0 : Eigen::Vector3d::Constant(std::nan(""));
      q = ok ? Eigen::Quaterniond(result.pose_D.Rotation())
             : Eigen::Quaterniond(std::nan(""), std::nan(""), std::nan(""), std::nan(""));
      grasp = ok ? result.pose_D.Grasp() : std::nan("");
    }
    const double row[] = {t, p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z(), grasp};
    for (double v : row) buffer += FormatNumber(v) + ',';
    for (int i = 0; i < 7; ++i) buffer += FormatNumber(result.wrench_D(i)) + ',';
    for (int i = 0; i < 8; ++i) buffer += FormatNumber(result.tau(i)) + ',';
    buffer += Fixed(seconds * 1e6, 2) + ',';
    buffer += std::to_string(result.events) + ',';
    const bool has_pose = result.fk_status == haptics::FkStatus::kOk;
    for (int i = 0; i < 3; ++i) {
      buffer += has_pose ? FormatNumber(result.pose_D.p0(i)) : std::string("nan");
      buffer += i < 2 ? ',' : '\n';
    }
    if (buffer.size() > (1 << 16)) {
      out << buffer;
      buffer.clear();
    }
  }
  out << buffer;
  out.close();
  if (!out) throw InputError("--out: failed writing '" + options.out + "'");

  std::cout << "run: " << ticks << " ticks (" << Fixed((ticks - 1) * dt, 3) << " s at 1000 Hz, "
            << (physical ? "virtual clock" : "real time") << "), scene " << scene_name << " ("
            << num_fields << " field" << (num_fields == 1 ? "" : "s") << "), device "
            << rig->Describe();
  if (physical) {
    std::cout << ", hand " << FormatNumber(hand_settings.stiffness) << " N/m, "
              << FormatNumber(hand_settings.damping) << " N·s/m";
  }
  std::cout << "\n";
  const std::string link = rig->LinkSummary();
  if (!link.empty()) std::cout << link << "\n";
  if (!calibration_line.empty()) std::cout << calibration_line << "\n";
  if (!fields_line.empty()) std::cout << fields_line << "\n";
  if (!skipped_line.empty()) std::cout << skipped_line << "\n";
  if (frame_source != "default") {
    std::cout << "frame: half-sides " << FormatNumber(geometry.a) << ", "
              << FormatNumber(geometry.b) << ", " << FormatNumber(geometry.c) << " m, pole "
              << FormatNumber(geometry.d) << " m (" << frame_source << ")\n";
  }
  std::cout << map_line << "\n";
  std::cout << "tick time [us]: p50 " << Fixed(tick_time.Percentile(0.5) * 1e6, 1) << "  p99 "
            << Fixed(tick_time.Percentile(0.99) * 1e6, 1) << "  p99.9 "
            << Fixed(tick_time.Percentile(0.999) * 1e6, 1) << "  max "
            << Fixed(tick_time.max() * 1e6, 1) << "  mean " << Fixed(tick_time.mean() * 1e6, 1)
            << "\n";
  std::cout << "safety events [ticks]:";
  const auto& counts = loop.event_counts();
  for (int i = 0; i < haptics::kNumSafetyEvents; ++i) {
    std::cout << ' ' << haptics::SafetyEventName(i) << '=' << counts[i] << " (bit " << i << ")"
              << (i + 1 < haptics::kNumSafetyEvents ? "," : "");
  }
  std::cout << "\nmax commanded force: " << Fixed(max_force, 3) << " N\n";
  if (assembly_field != nullptr) {
    // The field's state after the last tick (this thread ran every tick: it is the one reader).
    std::cout << FormatAssemblySummary(*assembly_field, assembly_field->LatestState());
  }
  std::cout << "wrote " << options.out << " (" << ticks << " rows)\n" << std::flush;
  throw CommandExit{0};
}

}  // namespace

void RegisterRunCommand(CLI::App& app) {
  auto options = std::make_shared<RunOptions>();
  CLI::App* cmd = app.add_subcommand("run", "Headless haptic session on a scripted trajectory");
  cmd->footer(kRunHelp);
  cmd->add_option("scene", options->scene,
                  "Scene: omitted (empty), 'demo' or a scene file (.json)");
  cmd->add_option("--trajectory", options->trajectory, "Trajectory CSV (t,x,y,z,qw,qx,qy,qz,grasp)")
      ->required();
  cmd->add_option("--out", options->out, "Result CSV, one row per tick")->required();
  cmd->add_option("--device", options->device,
                  "Device: simulated (default), board-sim (USB driver over the board simulator) "
                  "or usb (a real board)");
  cmd->add_option("--hand", options->hand,
                  "Hand spring stiffness,damping [N/m,N·s/m] (default 300,20)")
      ->delimiter(',')
      ->expected(2);
  cmd->add_option("--seed", options->seed, "Seed of the simulated device's errors (default 1)");
  cmd->add_flag("--calibrate", options->calibrate,
                "Calibrate the simulated device first (line fit on 24 jig poses, as the window) "
                "and read it through that fit; for scripts that must hit mm targets");
  cmd->add_option("--calibration", options->calibration,
                  "Read the encoders through this calibration file (`spidarcad calibrate --out`; "
                  "it must be this device's and frame's)");
  AddGeometryOptions(*cmd, &options->geometry, &options->geometry_given);
  cmd->add_option("--tool", options->tool, "Scene files: tool model proxy (default) or shell");
  cmd->add_option("--stiffness", options->stiffness,
                  "Scene files: contact stiffness at the grip, N/m (default 1500; shell coupling "
                  "min(K, 1000))");
  cmd->add_option("--damping", options->damping,
                  "Scene files: proxy normal damping at the grip, N·s/m (default 1)");
  cmd->add_option("--friction", options->friction,
                  "Scene files: proxy friction static,dynamic (default 0.3,0.2)")
      ->delimiter(',')
      ->expected(2);
  cmd->add_option("--world-scale", options->world_scale,
                  "Scene files: world metres per grip metre (default: fitted)");
  cmd->add_option("--world-origin", options->world_origin,
                  "Scene files: world position of the device origin x,y,z, m (default: fitted)")
      ->delimiter(',')
      ->expected(3);
  cmd->add_option("--max-duration", options->max_duration,
                  "Longest run accepted, s: the trajectory's last minus first time (default 3600; "
                  "at most 1e7)");
  cmd->add_flag("--progress", options->progress,
                "Show progress on stderr even when it is not a terminal");
  cmd->callback([options]() { RunRun(*options); });
}

}  // namespace spidarcad::app
