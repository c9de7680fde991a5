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
#include <cctype>
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
#include "cli/interrupt_output.h"
#include "scene/assembly_scene.h"
#include "scene/calibration_file.h"
#include "scene/device_rig.h"
#include "scene/document_file.h"
#include "scene/fe_part.h"
#include "scene/scene_haptics.h"
#include "scene/sculpt_document.h"
#include "scene/trajectory_player.h"
#include "spidarcad/haptics/haptic_loop.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/loop_runner.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "spidarcad/haptics/trajectory.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

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
    "solids, FE models, rigid parts and sculpt objects (below); a document's other meshes are\n"
    "not rendered yet (the summary lists them as skipped); a document of rigid parts\n"
    "and no solid (an assembly saved from the window) is one assembly field, as a scene's\n"
    "\"parts\" are. Solids:\n"
    "  --tool proxy   each solid is a god-object proxy on the grip centre, with friction\n"
    "  --tool shell   the cross grip (poles +-d, radius 6 mm) is a six-DOF point shell with\n"
    "                 virtual coupling against the union of the solids: torques are felt\n"
    "--stiffness and --damping are what the hand feels at the grip (N/m and N·s/m of grip motion;\n"
    "the fields get them divided by the world scale s).\n"
    "FE models: each is an FE part pushed by a sphere on the grip centre, as in the window's FE\n"
    "mode and with its default touch settings (scene/fe_part.h: radius the mesh's mean surface\n"
    "edge; felt force 1e-4/s of the FE reaction, at most 8 N; virtual coupling 1500/s N/m, s\n"
    "the world scale; frictionless); the solid its mesh was made from is not felt as a rigid\n"
    "solid too. The model is assembled and factored before the first tick (FeModel::Build, with\n"
    "the disk cache of FE columns, $SPIDARCAD_CACHE_DIR or ~/.cache/spidarcad), and the\n"
    "compliance columns of its surface nodes within 3 cm of grip motion (plus the sphere) of the\n"
    "trajectory's path are made ready then (read from the disk cache, else computed and saved\n"
    "there); none is computed during the run, so its forces depend on the trajectory alone and\n"
    "two runs give the same CSV. A contact node off that path reads the nearest ready column (the\n"
    "summary counts such ticks). The summary gives the build and column times.\n"
    "--fe-grasp: instead, a sphere of that radius at each pole tip, 0.02 m (W) from the grip\n"
    "centre (FE mode's two-point grasp, no coupling): closing the grasp squeezes the part between\n"
    "the tips, and the grasp torque g pushes back.\n"
    "Sculpt objects: the document's first sculpt object is sculpted by the grip, as in the\n"
    "window's sculpt mode (scene/sculpt_field.h; any other sculpt object is skipped). Every 16\n"
    "ticks of the virtual clock (62.5 Hz, the window's frame) the sculpt session steps on the\n"
    "tool state: a stroke begins when the grasp closes below 70 deg with the grip centre within\n"
    "the tool radius of the clay, follows the grip, and ends when the grasp opens above 80 deg\n"
    "(a stroke still under way at the last tick ends there); each stroke is recorded in the\n"
    "document. The stroke's resisting wrench is felt through the sculpt tool field (300 N/m).\n"
    "--sculpt-tool (grab, twist, bend, push_pull, smooth; default grab), --sculpt-radius (m,\n"
    "default 0.02) and --conserve-volume set the tool (a sculpt object stores none). With only\n"
    "sculpt objects X_WD is the identity, as in the window, unless --world-scale/--world-origin\n"
    "say otherwise; beside solids the sculpt does not take part in the fit.\n"
    "--fe-grab: instead, the FE parts are grabbed, not pushed (FE mode's grab,\n"
    "scene/fe_grab_field.h): closing the grasp (below 70 deg) while the grip centre is within\n"
    "twice the mesh's mean surface edge of the surface grabs those surface nodes (at most 64),\n"
    "which then follow the grip rigidly in six DOF; the felt force and moment are 1e-4/s of the\n"
    "FE reaction (at most 8 N and 0.5 N·m); opening the grasp (above 80 deg) lets go. With\n"
    "--fe-grasp too, the nodes near the pole tips are grabbed. The patch is factored on the grab\n"
    "tick (the window factors it on a worker).\n"
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
    "  fe_contacts       (documents with FE models only) FE contact nodes of the tick, all parts\n"
    "  fe_fx,fe_fy,fe_fz (the same) FE reaction on the tool, W, N: the unscaled FE force, summed\n"
    "                    over the parts (the felt force is in fx..fz); with --fe-grab: grabbed\n"
    "                    nodes and the FE reaction of the grab\n"
    "  fe_mx,fe_my,fe_mz (--fe-grab only) FE moment on the tool about the grip centre, W, N·m\n"
    "  sculpt_stroke     (documents with a sculpt object only) 1 while a stroke is under way\n"
    "  sculpt_volume     (the same) enclosed volume of the sculpted clay, m^3\n"
    "\n"
    "Example:\n"
    "  spidarcad run demo --trajectory assets/trajectories/press.csv --out press_result.csv\n"
    "  spidarcad run assets/scenes/platform.json --trajectory assets/trajectories/press.csv \\\n"
    "      --out platform_press.csv --world-scale 1 --world-origin 0.1,0,0.04\n"
    "  spidarcad run assets/scenes/platform_fe.json --trajectory assets/trajectories/press.csv \\\n"
    "      --out platform_fe_press.csv --world-scale 1 --world-origin 0.1,0,0.04";

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
  bool fe_grab = false;              // FE parts: grabbed by the closing grasp instead of pushed
  bool fe_grasp = false;             // FE parts: two-point grasp contact instead of the push sphere
  std::vector<std::string> save;     // --save OUT: the document at the end of the run
  std::vector<std::string> exports;  // --export NAME=FILE: one object's final state
  std::string sculpt_tool = "grab";  // sculpt objects: the tool of every stroke
  double sculpt_radius = 0.02;       // sculpt objects: falloff radius R, m (W)
  bool conserve_volume = false;      // sculpt objects: keep each stroke's enclosed volume
};

// The sculpt session is stepped every this many ticks of the virtual clock (62.5 Hz), as the
// window steps it once a frame: the same ticks every run, so the CSV is reproducible.
constexpr long kSculptFrameTicks = 16;

// True when path ends in .stl, .obj or .ply (any case): the files WriteTriangleMesh writes.
bool IsSurfaceMeshFile(const std::string& path) {
  const std::string ext = std::filesystem::path(path).extension().string();
  std::string lower;
  for (char c : ext) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return lower == ".stl" || lower == ".obj" || lower == ".ply";
}

// The sculpt tool named `name` (SculptToolName's spelling); InputError naming the option else.
modeling::SculptTool ParseSculptTool(const std::string& name) {
  for (modeling::SculptTool tool :
       {modeling::SculptTool::kGrab, modeling::SculptTool::kTwist, modeling::SculptTool::kBend,
        modeling::SculptTool::kPushPull, modeling::SculptTool::kSmooth}) {
    if (name == modeling::SculptToolName(tool)) return tool;
  }
  throw InputError("--sculpt-tool: '" + name +
                   "' is not a sculpt tool; use grab, twist, bend, push_pull or smooth");
}

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

// --world-origin as a point (m); exit 2 unless it has three numbers.
Eigen::Vector3d WorldOrigin(const RunOptions& options) {
  if (options.world_origin.size() != 3) {
    throw InputError("--world-origin: expected x,y,z (m), got " +
                     std::to_string(options.world_origin.size()) + " numbers");
  }
  return Eigen::Vector3d(options.world_origin[0], options.world_origin[1], options.world_origin[2]);
}

// Applies the --world-scale and --world-origin that were given to X_WD; true when either was.
bool GivenWorldMap(const RunOptions& options, haptics::DeviceToWorld* X_WD) {
  if (options.world_scale < 0.0) throw InputError("--world-scale: must be > 0 (0: default)");
  if (options.world_scale > 0.0) X_WD->world_scale = options.world_scale;
  if (!options.world_origin.empty()) X_WD->p_WDo = WorldOrigin(options);
  return options.world_scale > 0.0 || !options.world_origin.empty();
}

// The summary's line for a map: "X_WD: p_W = s p_D + (x, y, z) m".
std::string MapLine(const haptics::DeviceToWorld& X_WD) {
  const Eigen::Vector3d& o = X_WD.p_WDo;
  return "X_WD: p_W = " + FormatNumber(X_WD.world_scale) + " p_D + (" + FormatNumber(o.x()) + ", " +
         FormatNumber(o.y()) + ", " + FormatNumber(o.z()) + ") m";
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
  ParseSculptTool(options.sculpt_tool);  // a bad name fails before any work
  if (!(options.sculpt_radius > 0.0 && std::isfinite(options.sculpt_radius))) {
    throw InputError("--sculpt-radius: must be > 0 m, got " + FormatNumber(options.sculpt_radius));
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
      nullptr;                           // an assembly scene's field (owned by the loop)
  std::vector<FeTouchField*> fe_fields;  // the document's FE parts' fields (owned by the loop)
  std::vector<std::shared_ptr<FeModel>> fe_parts;  // their models, in the same order
  std::vector<std::string> fe_names;               // and their names
  std::unique_ptr<Document> document;              // the document run (null: demo or empty)
  std::unique_ptr<DocumentSculpt> sculpt;          // its sculpt object sculpted (null: none)
  std::string fe_lines;                            // what the FE parts' set-up did, for the summary
  // With --fe-grab: the FE parts' grab fields (owned by the loop) and their touch fields (kept
  // for --export, not felt).
  std::vector<const FeGrabField*> fe_grabs;
  std::vector<std::unique_ptr<FeTouchField>> fe_touch_fields;
  haptics::LoopSettings settings;
  settings.fk.max_residual = kNominalFkMaxResidual;  // nominal encoder model: mm-level errors
  // --export NAME=FILE: split (at the first '='), checked once the document is open.
  std::vector<std::pair<std::string, std::string>> exports;
  for (const std::string& e : options.exports) {
    const auto eq = e.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == e.size()) {
      throw InputError("--export '" + e +
                       "': expected NAME=FILE (an object's name, then the file)");
    }
    exports.emplace_back(e.substr(0, eq), e.substr(eq + 1));
  }
  const bool scene_is_file =
      !(options.scene.empty() || options.scene == "none" || options.scene == "demo");
  if (!scene_is_file && (!options.save.empty() || !exports.empty())) {
    throw InputError(std::string(options.save.empty() ? "--export" : "--save") +
                     ": needs a scene file or document (SCENE is " +
                     (options.scene.empty() ? std::string("empty") : "'" + options.scene + "'") +
                     ")");
  }
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
    // window), the assembly of its rigid parts as the window feels it; beside its solids, its FE
    // models (each one FE part, scene/fe_part.h; the solid an FE model's mesh was made from is
    // not a rigid solid too, as FE mode hides it), its rigid parts (one assembly field) and its
    // first sculpt object; and snap. The other kinds are listed in the summary as skipped.
    const modeling::Scene loaded = opened.doc->ToScene();
    // Rigid parts beside solids (and FE models) are one assembly field in the solids' scene.
    std::vector<AssemblyPartInput> parts_beside = RigidPartInputs(*opened.doc, nullptr);
    const std::vector<AssemblyPartInput> rigid_parts =
        loaded.solids.empty() ? parts_beside : std::vector<AssemblyPartInput>{};
    if (loaded.solids.empty()) parts_beside.clear();
    const std::size_t part_count = rigid_parts.empty() ? loaded.parts.size() : rigid_parts.size();
    // FE models are rendered beside solids, not in an assembly.
    const std::vector<ObjectId> fe_models =
        part_count == 0 ? FeModelsOf(*opened.doc) : std::vector<ObjectId>{};
    // The sculpt object sculpted: the document's first (not beside an assembly's parts).
    ObjectId sculpt_id = 0;
    for (const DocObject& o : opened.doc->objects()) {
      if (part_count == 0 && sculpt_id == 0 && std::holds_alternative<SculptData>(o.data))
        sculpt_id = o.id;
    }
    std::vector<ObjectId> fe_meshes, fe_sources;
    for (ObjectId fe : fe_models) {
      fe_meshes.push_back(std::get<FeModelData>(opened.doc->Get(fe).data).tet_mesh);
      if (const ObjectId source = FeModelSource(*opened.doc, fe); source != 0)
        fe_sources.push_back(source);
    }
    const auto listed = [](const std::vector<ObjectId>& ids, ObjectId id) {
      return std::find(ids.begin(), ids.end(), id) != ids.end();
    };
    for (const DocObject& o : opened.doc->objects()) {
      if (std::holds_alternative<SolidData>(o.data)) continue;
      if ((!rigid_parts.empty() || !parts_beside.empty()) &&
          std::holds_alternative<RigidPartData>(o.data))
        continue;
      if (listed(fe_models, o.id) || listed(fe_meshes, o.id) || o.id == sculpt_id) continue;
      skipped_line += std::string(skipped_line.empty() ? "" : ", ") + ObjectKindName(o.data) +
                      " '" + o.name + "'";
    }
    if (!skipped_line.empty()) {
      skipped_line =
          "skipped (run renders solids, FE models, rigid parts, the first sculpt object and "
          "snap; not yet other meshes or other sculpts): " +
          skipped_line;
    }
    // --export: objects whose final state run can write (FE parts, as .vtu; sculpt objects, as
    // .stl, .obj or .ply), checked before any work.
    for (const auto& [name, file] : exports) {
      const std::string what = "--export " + name + "=" + file + ": ";
      const DocObject* object = nullptr;
      for (const DocObject& o : opened.doc->objects())
        if (o.name == name && object == nullptr) object = &o;
      if (object == nullptr) {
        throw InputError(what + "the document has no object named '" + name +
                         "'; its FE models: " + ObjectNames(*opened.doc, {"fe_model"}) +
                         "; its sculpt objects: " + ObjectNames(*opened.doc, {"sculpt"}));
      }
      if (std::holds_alternative<SculptData>(object->data)) {
        if (!IsSurfaceMeshFile(file)) {
          throw InputError(what +
                           "a sculpt object is written as a surface mesh: name the file "
                           "FILE.stl, FILE.obj or FILE.ply");
        }
        continue;
      }
      if (!listed(fe_models, object->id)) {
        throw InputError(
            what + "'" + name + "' is a " + ObjectKindName(object->data) +
            ", not an FE model run renders nor a sculpt object; run exports those only (" +
            ObjectNames(*opened.doc, {"fe_model", "sculpt"}) + ")");
      }
      if (file.size() < 4 || file.compare(file.size() - 4, 4, ".vtu") != 0) {
        throw InputError(what + "an FE model is written as .vtu: name the file FILE.vtu");
      }
    }
    if (opened.version == 2 && loaded.solids.empty() && rigid_parts.empty() && fe_models.empty()) {
      // Nothing to render (but a sculpt object, added below): the grip moves freely.
      scene = std::make_unique<haptics::HapticScene>();
      scene_name = options.scene + " (no solid)";
      if (sculpt_id != 0) {
        // X_WD: the identity, as the window's for a document without solids, unless given.
        if (GivenWorldMap(options, &settings.X_WD)) map_line = MapLine(settings.X_WD);
      }
    } else if (part_count > 0) {
      // An assembly: one field owns every part (grasp, carry, contact, seats).
      std::unique_ptr<haptics::AssemblyField> assembly;
      try {
        // Alignment snap (a carried part drawn toward its seat's axis) where the document
        // enables snap.
        AssemblySceneSettings assembly_settings;
        assembly_settings.field.align.enabled = opened.doc->snap().has_value();
        assembly = rigid_parts.empty()
                       ? BuildAssemblyField(loaded, assembly_settings)
                       : BuildAssemblyField(rigid_parts, assembly_settings, nullptr);
      } catch (const std::invalid_argument& e) {
        throw InputError(options.scene + ": " + e.what());
      }
      GivenWorldMap(options, &settings.X_WD);
      scene = std::make_unique<haptics::HapticScene>();
      assembly_field = assembly.get();
      scene->Add(std::move(assembly));
      scene_name = options.scene + " (assembly, " + std::to_string(part_count) + " parts)";
      fields_line = "fields: assembly (" + std::to_string(part_count) + " parts)";
      map_line = MapLine(settings.X_WD);
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
      if (!options.world_origin.empty()) haptic_options.p_WDo = WorldOrigin(options);
      haptic_options.grip_d = geometry.d;
      // The solids rendered as rigid solids: all but the FE models' sources.
      modeling::Scene rigid = loaded;
      rigid.solids.clear();
      for (const DocObject& o : opened.doc->objects()) {
        if (const auto* solid = std::get_if<SolidData>(&o.data); solid && !listed(fe_sources, o.id))
          rigid.solids.push_back({o.name, solid->root});
      }
      // The FE meshes take part in the fit of X_WD as the solids do.
      Eigen::AlignedBox3d fe_box_W;
      for (ObjectId fe : fe_models) {
        fem::TetMesh mesh;
        try {
          mesh = FeMeshOf(*opened.doc, std::get<FeModelData>(opened.doc->Get(fe).data));
        } catch (const std::exception& e) {
          throw InputError(options.scene + ": FE model '" + opened.doc->Get(fe).name +
                           "': " + e.what());
        }
        for (Eigen::Index v = 0; v < mesh.nodes.rows(); ++v)
          fe_box_W.extend(mesh.nodes.row(v).transpose().eval());
      }
      // The rigid parts beside take part in the fit too (each part's solid box at its pose).
      for (const AssemblyPartInput& part : parts_beside) {
        if (part.root == nullptr) continue;  // BuildAssemblyField names it below
        bool unbounded = false;
        const Eigen::AlignedBox3d box_P =
            SolidBounds(modeling::CompiledSolid::Compile(*part.root), &unbounded);
        if (box_P.isEmpty()) continue;
        for (int k = 0; k < 8; ++k)
          fe_box_W.extend(part.X_WP *
                          box_P.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k)));
      }
      SceneHaptics built;
      try {
        haptic_options.Validate();
        haptic_options.extra_bounds_W = fe_box_W;  // the FE parts are fitted with the solids
        built = BuildHapticScene(rigid, haptic_options);
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
      // The tool model applies to rigid solids; an FE part is pushed by its sphere either way.
      scene_name = rigid.solids.empty()
                       ? options.scene
                       : options.scene + " (tool " + ToolModelName(haptic_options.tool) + ")";
      fields_line = "fields:";
      for (std::size_t i = 0; i < built.fields.size(); ++i) {
        fields_line += std::string(i ? "," : "") + " " + built.fields[i].kind + " '" +
                       built.fields[i].solid + "'";
      }
      // The FE parts: built now (the window does it in a Job), their columns along the path.
      for (ObjectId fe : fe_models) {
        const std::string name = opened.doc->Get(fe).name;
        FePartOptions fe_options;
        fe_options.world_scale = built.map.X_WD.world_scale;
        fe_options.model.cache.start_worker = false;  // PrepareColumns below, nothing after
        fe_options.touch.grasp = options.fe_grasp && !options.fe_grab;
        fe_options.grab = options.fe_grab;
        fe_options.grab_settings.grasp = options.fe_grasp;
        fe_options.grab_settings.worker = false;  // factored on the grab tick: deterministic
        FePart part;
        FeColumnPlan plan;
        try {
          part = BuildFePart(*opened.doc, fe, fe_options);
          plan = PrepareTrajectoryColumns(&part, trajectory, built.map.X_WD,
                                          fe_options.model.use_disk_cache);
        } catch (const std::exception& e) {
          throw InputError(options.scene + ": FE model '" + name + "': " + e.what());
        }
        fields_line += std::string(fields_line == "fields:" ? "" : ",") +
                       (options.fe_grab ? " fe_grab '" : " fe_touch '") + name + "'";
        const FeModel& model = *part.model;
        const FeTouchSettings& ts = part.field->settings();
        fe_lines += "fe '" + name + "': " + std::to_string(model.mesh().num_nodes()) + " nodes, " +
                    std::to_string(model.mesh().num_elements()) + " tets (order " +
                    std::to_string(model.mesh().Order()) + "), " +
                    std::to_string(model.num_fixed_nodes()) + " clamped; built in " +
                    Fixed(model.build_seconds(), 2) + " s (" +
                    std::to_string(model.imported_nodes()) + " columns in the disk cache)\n";
        fe_lines += "fe '" + name + "' columns: " + std::to_string(plan.ready) + " ready of " +
                    std::to_string(plan.requested) + " surface nodes near the trajectory (" +
                    std::to_string(plan.from_disk) + " from the disk cache, " +
                    std::to_string(plan.computed) + " computed" + (plan.saved ? " and saved" : "") +
                    ", " + Fixed(plan.seconds, 2) + " s); none computed during the run\n";
        fe_lines += "fe '" + name + "' touch: sphere radius " + FormatNumber(ts.tool_radius) +
                    " m, force scale " + FormatNumber(ts.force_scale) + ", coupling " +
                    FormatNumber(ts.coupling_stiffness) + " N/m, max felt " +
                    FormatNumber(ts.max_force) + " N (W)\n";
        if (part.grab_field) {
          const FeGrabSettings& gs = part.grab_field->settings();
          fe_lines += "fe '" + name + "' grab: sphere radius " + FormatNumber(gs.tool_radius) +
                      " m" + (gs.grasp ? " at each pole tip" : "") + ", at most " +
                      std::to_string(gs.max_patch) + " nodes, force scale " +
                      FormatNumber(gs.force_scale) + ", max felt " + FormatNumber(gs.max_force) +
                      " N, " + FormatNumber(gs.max_torque) + " N·m (W)\n";
          fe_grabs.push_back(part.grab_field.get());
        }
        fe_fields.push_back(part.field.get());
        fe_parts.push_back(part.model);
        fe_names.push_back(name);
        if (part.grab_field) {
          scene->Add(std::move(part.grab_field));
          fe_touch_fields.push_back(std::move(part.field));  // kept for --export, not felt
        } else {
          scene->Add(std::move(part.field));
        }
      }
      if (!parts_beside.empty()) {
        // The rigid parts beside: one assembly field (grasp, carry, seats; alignment snap where
        // the document has snap), in the solids' W (their boxes were fitted with the solids).
        AssemblySceneSettings assembly_settings;
        assembly_settings.field.align.enabled = opened.doc->snap().has_value();
        std::unique_ptr<haptics::AssemblyField> assembly;
        try {
          assembly = BuildAssemblyField(parts_beside, assembly_settings, nullptr);
        } catch (const std::invalid_argument& e) {
          throw InputError(options.scene + ": " + e.what());
        }
        assembly_field = assembly.get();
        scene->Add(std::move(assembly));
        fields_line += std::string(fields_line == "fields:" ? "" : ",") + " assembly (" +
                       std::to_string(parts_beside.size()) + " parts)";
      }
      map_line = MapLine(built.map.X_WD) + "; scale " +
                 (built.map.scale_fitted ? "fitted" : "given") + ", origin " +
                 (built.map.origin_fitted ? "fitted" : "given");
      if (!built.map.bounds_W.isEmpty()) {
        const Eigen::AlignedBox3d& b = built.map.bounds_W;
        map_line += "; scene box (" + FormatNumber(b.min().x()) + ", " + FormatNumber(b.min().y()) +
                    ", " + FormatNumber(b.min().z()) + ") .. (" + FormatNumber(b.max().x()) + ", " +
                    FormatNumber(b.max().y()) + ", " + FormatNumber(b.max().z()) + ") m";
      }
    }  // not an assembly
    if (sculpt_id != 0) {
      // The sculpt object: a session on its mesh, felt through the sculpt tool field.
      SculptModeSettings sculpt_settings;
      sculpt_settings.tool.tool = ParseSculptTool(options.sculpt_tool);
      sculpt_settings.tool.radius = options.sculpt_radius;
      sculpt_settings.tool.conserve_volume = options.conserve_volume;
      try {
        sculpt = std::make_unique<DocumentSculpt>(opened.doc.get(), sculpt_id, sculpt_settings);
      } catch (const std::invalid_argument& e) {
        throw InputError(options.scene + ": " + e.what());
      }
      scene->Add(sculpt->session().MakeField());
      if (fields_line.empty()) fields_line = "fields:";
      fields_line += std::string(fields_line == "fields:" ? "" : ",") + " sculpt_tool '" +
                     sculpt->name() + "'";
    }
    document = std::move(opened.doc);
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

  // Ctrl+C stops the loop at the next tick (the rig is stopped as on any exit) with status 130;
  // the CSV goes to a hidden temporary renamed over --out when complete, so no half-written
  // file is left (a second Ctrl+C ends at once, removing the temporary).
  InterruptibleOutput output(options.out, "run", InterruptibleOutput::Mode::kFlag);
  std::ofstream out(output.temporary());
  if (!out) throw InputError("--out: cannot write '" + options.out + "'");
  // Columns after today's only when the document has an FE part (older outputs stay as they were).
  const bool fe_columns = !fe_fields.empty();
  out << "t,x,y,z,qw,qx,qy,qz,grasp,fx,fy,fz,mx,my,mz,g,tau1,tau2,tau3,tau4,tau5,tau6,tau7,tau8,"
         "tick_us,events,fk_x,fk_y,fk_z"
      << (fe_columns ? ",fe_contacts,fe_fx,fe_fy,fe_fz" : "")
      << (fe_grabs.empty() ? "" : ",fe_mx,fe_my,fe_mz")
      << (sculpt ? ",sculpt_stroke,sculpt_volume" : "") << "\n";
  const bool sculpt_columns = sculpt != nullptr;
  haptics::ToolKinematics last_tool_W;    // the tool state of the last tick
  double sculpt_max_volume_change = 0.0;  // largest |V - V0| / V0 over the run
  long fe_substituted_ticks = 0;          // ticks with a contact on a substitute column
  int fe_max_contacts = 0;
  double fe_max_reaction = 0.0;
  std::string buffer;
  double max_force = 0.0;
  const auto wall_start = std::chrono::steady_clock::now();
  RunProgress progress(options.progress || isatty(STDERR_FILENO) == 1, ticks);
  for (long k = 0; k < ticks; ++k) {
    if (output.interrupted()) output.Stop();
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
    last_tool_W = result.tool_W;
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
      buffer += i < 2 || fe_columns || sculpt_columns ? ',' : '\n';
    }
    if (fe_columns) {
      // The FE parts' contact state of this tick (this thread ran it: it is the one reader).
      int contacts = 0, substituted = 0;
      Eigen::Vector3d f = Eigen::Vector3d::Zero();
      Eigen::Vector3d m = Eigen::Vector3d::Zero();
      for (const FeTouchField* field : fe_fields) {
        if (!fe_grabs.empty()) break;  // grabbed, not pushed
        const FeContactState& st = field->last_state();
        contacts += st.num_contacts;
        substituted += st.num_substituted;
        f += st.f_tool_W;
      }
      for (const FeGrabField* grab : fe_grabs) {
        const FeGrabState& st = grab->last_state();
        if (!st.ready) continue;
        contacts += st.num_nodes;
        substituted += st.num_substituted;
        f += st.f_tool_W;
        m += st.m_tool_W;
      }
      if (substituted > 0) ++fe_substituted_ticks;
      fe_max_contacts = std::max(fe_max_contacts, contacts);
      fe_max_reaction = std::max(fe_max_reaction, f.norm());
      buffer += std::to_string(contacts) + ',' + FormatNumber(f.x()) + ',' + FormatNumber(f.y()) +
                ',' + FormatNumber(f.z());
      if (!fe_grabs.empty())
        buffer += ',' + FormatNumber(m.x()) + ',' + FormatNumber(m.y()) + ',' + FormatNumber(m.z());
      buffer += sculpt_columns ? ',' : '\n';
    }
    if (sculpt_columns) {
      // The sculpt session's frame (every kSculptFrameTicks ticks): the stroke follows this
      // tick's tool state; the field reads the published force model from the next tick on.
      if ((k + 1) % kSculptFrameTicks == 0) {
        try {
          sculpt->Step(result.tool_W);
        } catch (const std::exception& e) {
          throw InputError("sculpt '" + sculpt->name() + "' at t = " + FormatNumber(t) +
                           " s: " + e.what());
        }
      }
      const double volume = sculpt->session().volume();
      sculpt_max_volume_change =
          std::max(sculpt_max_volume_change,
                   std::abs(volume - sculpt->start_volume()) / sculpt->start_volume());
      buffer += std::string(sculpt->session().stroke_active() ? "1" : "0") + ',' +
                FormatNumber(volume) + '\n';
    }
    if (buffer.size() > (1 << 16)) {
      out << buffer;
      buffer.clear();
    }
  }
  out << buffer;
  out.close();
  if (!out) throw InputError("--out: failed writing '" + options.out + "'");
  output.Commit();
  // A stroke still under way ends at the last tick, as if the grasp opened there.
  if (sculpt) sculpt->Finish(last_tool_W);

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
  std::cout << fe_lines;
  if (fe_columns) {
    std::cout << "fe contact: at most " << fe_max_contacts << " nodes, largest FE reaction "
              << Fixed(fe_max_reaction, 3) << " N (unscaled, W); " << fe_substituted_ticks
              << " ticks read a substitute column (a node off the prepared path)\n";
  }
  if (sculpt) {
    const modeling::SculptToolSettings& st = sculpt->session().settings().tool;
    const double v0 = sculpt->start_volume(), v1 = sculpt->session().volume();
    std::cout << "sculpt '" << sculpt->name() << "': " << sculpt->strokes() << " stroke"
              << (sculpt->strokes() == 1 ? "" : "s") << " (" << modeling::SculptToolName(st.tool)
              << ", radius " << FormatNumber(st.radius) << " m, volume "
              << (st.conserve_volume ? "conserved" : "not conserved") << "); volume "
              << FormatNumber(v0) << " -> " << FormatNumber(v1) << " m^3 (" << (v1 >= v0 ? "+" : "")
              << Fixed(100.0 * (v1 - v0) / v0, 3) << " %), at most "
              << Fixed(100.0 * sculpt_max_volume_change, 3) << " % off the start during the run; "
              << sculpt->session().mesh()->vertex_count() << " vertices\n";
  }
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
  std::cout << "wrote " << options.out << " (" << ticks << " rows)\n";
  // The final state of each exported FE part: its last tick's contacts, solved in full.
  for (const auto& [name, file] : exports) {
    const DocObject* object = nullptr;  // the first object of that name, as checked above
    for (const DocObject& o : document->objects())
      if (o.name == name && object == nullptr) object = &o;
    if (const auto* clay = object ? std::get_if<SculptData>(&object->data) : nullptr) {
      // A sculpt object's surface as it stands at the end of the run (its strokes recorded).
      try {
        modeling::WriteTriangleMesh(*clay->mesh, file);
      } catch (const std::exception& e) {
        throw InputError("--export " + name + "=" + file + ": " + e.what());
      }
      std::cout << "wrote " << file << " ('" << name
                << "' at the end of the run: " << clay->mesh->vertices.cols() << " vertices, "
                << clay->mesh->triangles.cols() << " triangles)\n";
      continue;
    }
    const std::size_t i = std::find(fe_names.begin(), fe_names.end(), name) - fe_names.begin();
    const FeContactState& state = fe_fields[i]->last_state();
    const FeGrabState* grab = fe_grabs.empty() ? nullptr : &fe_grabs[i]->last_state();
    try {
      WriteFeStateVtu(
          *fe_parts[i],
          grab ? SolveFeGrabState(*fe_parts[i], *grab) : SolveFeState(*fe_parts[i], state), file);
    } catch (const std::exception& e) {
      throw InputError("--export " + name + "=" + file + ": " + e.what());
    }
    const int nodes = grab ? (grab->ready ? grab->num_nodes : 0) : state.num_contacts;
    const double reaction = grab ? grab->f_tool_W.norm() : state.f_tool_W.norm();
    std::cout << "wrote " << file << " ('" << name << "' at the last tick: " << nodes
              << (grab ? " grabbed" : " contact") << " nodes, FE reaction on the tool "
              << Fixed(reaction, 3) << " N; displacement and von_mises by a full solve)\n";
  }
  for (const std::string& path : options.save) {
    try {
      document->Save(path);
    } catch (const std::exception& e) {
      throw InputError(std::string("--save ") + path + ": " + e.what());
    }
    std::cout << "wrote " << path << " (the document at the end of the run)\n";
  }
  std::cout << std::flush;
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
  cmd->add_flag("--fe-grab", options->fe_grab,
                "Documents: FE models are grabbed by closing the grasp on them and follow the grip "
                "rigidly (FE mode's grab) instead of being pushed");
  cmd->add_flag("--fe-grasp", options->fe_grasp,
                "Documents: FE models are squeezed between the pole tips (two-point grasp contact, "
                "as FE mode's checkbox) instead of pushed by the sphere on the grip centre");
  cmd->add_option("--save", options->save,
                  "Documents: write the document as it stands at the end of the run to OUT "
                  "(repeatable)")
      ->type_name("OUT")
      ->allow_extra_args(false);
  cmd->add_option("--export", options->exports,
                  "Documents: write one object's final state, NAME=FILE (repeatable); an FE model "
                  "as .vtu with point data displacement and von_mises, a sculpt object's surface "
                  "as .stl, .obj or .ply")
      ->type_name("NAME=FILE")
      ->allow_extra_args(false);
  cmd->add_option("--sculpt-tool", options->sculpt_tool,
                  "Documents: the tool of the sculpt object's strokes: grab (default), twist, "
                  "bend, push_pull or smooth");
  cmd->add_option("--sculpt-radius", options->sculpt_radius,
                  "Documents: the sculpt tool's falloff radius, m (W; default 0.02)");
  cmd->add_flag("--conserve-volume", options->conserve_volume,
                "Documents: each sculpt stroke keeps the clay's enclosed volume");
  cmd->callback([options]() { RunRun(*options); });
}

}  // namespace spidarcad::app
