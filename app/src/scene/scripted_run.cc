// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/scripted_run.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <optional>
#include <sstream>
#include <thread>
#include <utility>
#include <variant>

#include "doc/input_error.h"
#include "doc/number_format.h"
#include "scene/assembly_scene.h"
#include "scene/calibration_file.h"
#include "scene/device_rig.h"
#include "scene/document_file.h"
#include "scene/fe_part.h"
#include "scene/scene_haptics.h"
#include "scene/sculpt_document.h"
#include "scene/touch_session.h"
#include "scene/trajectory_player.h"
#include "spidarcad/haptics/board_simulator.h"
#include "spidarcad/haptics/kinematics.h"
#include "spidarcad/haptics/loop_runner.h"
#include "spidarcad/haptics/simulated_device.h"
#include "spidarcad/haptics/simulated_hand.h"
#include "spidarcad/haptics/trajectory.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::app {

namespace {

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

std::string Fixed(double v, int digits) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(digits) << v;
  return os.str();
}

// --world-origin as a point (m); exit 2 unless it has three numbers.
Eigen::Vector3d WorldOrigin(const ScriptedRunOptions& options) {
  if (options.world_origin.size() != 3) {
    throw InputError("--world-origin: expected x,y,z (m), got " +
                     std::to_string(options.world_origin.size()) + " numbers");
  }
  return Eigen::Vector3d(options.world_origin[0], options.world_origin[1], options.world_origin[2]);
}

// Applies the --world-scale and --world-origin that were given to X_WD; true when either was.
bool GivenWorldMap(const ScriptedRunOptions& options, haptics::DeviceToWorld* X_WD) {
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

// A probability option in [0, 1); InputError naming it else.
void CheckProbability(const char* option, double p) {
  if (!(p >= 0.0 && p < 1.0)) {
    throw InputError(std::string(option) + ": must be a probability in [0, 1), got " +
                     FormatNumber(p));
  }
}

// Distance from p_W to the nearest clay vertex within `radius` of it (m); +inf when none.
double NearestVertexDistance(const SculptSession& session, const Eigen::Vector3d& p_W,
                             double radius, std::vector<int>* scratch) {
  if (!session.has_mesh()) return std::numeric_limits<double>::infinity();
  scratch->clear();
  session.mesh()->QueryBall(p_W, radius, scratch);
  double best = std::numeric_limits<double>::infinity();
  for (int v : *scratch) best = std::min(best, (session.mesh()->positions()[v] - p_W).norm());
  return best;
}

}  // namespace

struct ScriptedRun::Impl {
  ScriptedRunOptions options;
  std::function<void()> before_step, after_step;  // SetStepHooks
  haptics::Trajectory trajectory;
  haptics::SpidarGeometry geometry;
  std::string frame_source = "default";
  std::string scene_name = "empty";
  std::string fields_line;   // per-field names for the summary
  std::string skipped_line;  // a document's objects that run does not render yet
  std::string map_line = "X_WD: identity (device coordinates)";
  std::string fe_lines;  // what the FE parts' set-up did, for the summary
  std::string calibration_line;
  haptics::AssemblyField* assembly_field = nullptr;  // an assembly's field (owned by the loop)
  std::vector<FeTouchField*> fe_fields;              // the FE parts' fields (owned by the loop)
  std::vector<std::shared_ptr<FeModel>> fe_parts;    // their models, in the same order
  std::vector<std::string> fe_names;                 // and their names
  // With --fe-grab: the FE parts' grab fields (owned by the loop) and their touch fields (kept
  // for --export, not felt).
  std::vector<const FeGrabField*> fe_grabs;
  std::vector<std::unique_ptr<FeTouchField>> fe_touch_fields;
  std::unique_ptr<Document> own_document;  // the document run opened (null: demo, empty, given)
  Document* document = nullptr;            // the document run (null: demo or empty)
  std::vector<std::unique_ptr<DocumentSculpt>> sculpts;  // its sculpt objects, document order
  std::vector<double> sculpt_max_volume_change;          // largest |V - V0| / V0 of each
  int stroking = -1;                                     // the sculpt under a stroke (-1: none)
  // --place: modelling by touch on the document, its squeeze detector and what it placed.
  std::unique_ptr<TouchSession> touch;
  SqueezeDetector squeeze;
  std::vector<std::string> placed_lines;
  std::vector<int> query;  // scratch of the nearest-clay search
  haptics::LoopSettings settings;
  std::optional<CalibrationFile> calibration_file;  // --calibration, read
  haptics::EncoderCalibration calibration;          // what the loop reads the encoders with
  std::vector<std::pair<std::string, std::string>> exports;  // --export NAME=FILE, split
  int num_fields = 0;
  haptics::HandSettings hand_settings;
  std::unique_ptr<haptics::SimulatedHand> hand;
  RigKind kind = RigKind::kSimulated;
  bool ideal = false;  // --device ideal: the grip is exactly the trajectory's pose
  std::unique_ptr<DeviceRig> rig;
  haptics::SimulatedSpidarG* physical = nullptr;  // null for a real board
  std::unique_ptr<haptics::HapticLoop> loop;
  haptics::LatencyHistogram tick_time{1e-7, 100000};
  std::unique_ptr<RigServiceThread> service;
  double dt = 1e-3;
  double t0 = 0.0;
  long ticks = 0;
  long k = 0;  // the next tick
  long unplug_tick = -1, replug_tick = -1;
  bool fe_columns = false, link_columns = false;
  std::string header;
  long fe_substituted_ticks = 0;  // ticks with a contact on a substitute column
  long fe_truncated_ticks = 0;    // ticks whose tool patch had more than kMaxFeContacts nodes
  int fe_max_contacts = 0;
  double fe_max_reaction = 0.0;
  double max_force = 0.0;
  std::chrono::steady_clock::time_point wall_start;
  RuntimeFrame frame;

  void CheckOptions();
  void BuildScene(Document* given, std::unique_ptr<haptics::HapticScene>* scene);
  void BuildDocumentScene(int version, std::unique_ptr<haptics::HapticScene>* scene);
  void MakeDevice(std::unique_ptr<haptics::HapticScene> scene);
  void StepSculpts(const haptics::ToolKinematics& tool_W, double t);
  void AddTouch(haptics::HapticScene* scene);
  void StepTouch(const haptics::ToolState& tool);
};

void ScriptedRun::Impl::CheckOptions() {
  if (options.device != "simulated" && options.device != "ideal" && options.device != "board-sim" &&
      options.device != "usb") {
    throw InputError("--device: '" + options.device +
                     "' is not a device; use simulated, ideal, board-sim or usb");
  }
  if (options.calibrate && !options.calibration.empty()) {
    throw InputError(
        "--calibrate and --calibration: choose one (--calibrate fits the simulated device at "
        "start-up, --calibration reads a file made by `spidarcad calibrate --out`)");
  }
  try {
    options.geometry.Validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--frame/--pole: ") + e.what());
  }
  // A bad or foreign calibration file fails before any work.
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
  if (options.device == "ideal" && (options.calibrate || !options.calibration.empty())) {
    throw InputError(std::string(options.calibrate ? "--calibrate" : "--calibration") +
                     ": not with --device ideal (the ideal device has no encoder errors to "
                     "calibrate); use --device simulated, board-sim or usb");
  }
  if (!(options.max_duration > 0.0 && options.max_duration <= kMaxRunDurationCeiling)) {
    throw InputError("--max-duration: must be in (0, 1e7] s, got " +
                     FormatNumber(options.max_duration));
  }
  ParseSculptTool(options.sculpt_tool);  // a bad name fails before any work
  if (!options.place.empty()) {
    try {
      ParsePlaceKind(options.place);
    } catch (const std::invalid_argument& e) {
      throw InputError(std::string("--place: ") + e.what());
    }
  }
  if (!(options.fe_tool_radius > 0.0 && std::isfinite(options.fe_tool_radius))) {
    throw InputError("--fe-tool-radius: must be > 0 m, got " +
                     FormatNumber(options.fe_tool_radius));
  }
  if (!(options.sculpt_radius > 0.0 && std::isfinite(options.sculpt_radius))) {
    throw InputError("--sculpt-radius: must be > 0 m, got " + FormatNumber(options.sculpt_radius));
  }
  // The board-sim faults: probabilities, and an unplug before its replug.
  CheckProbability("--link-loss", options.link_loss);
  CheckProbability("--link-corruption", options.link_corruption);
  const bool unplug = !std::isnan(options.unplug_at), replug = !std::isnan(options.replug_at);
  const bool faults = options.link_loss > 0.0 || options.link_corruption > 0.0 || unplug ||
                      replug || options.link_seed != 0;
  if (faults && options.device != "board-sim") {
    throw InputError(
        "--link-loss/--link-corruption/--link-seed/--unplug/--replug: board-sim only (they "
        "script the simulated link to the board); add --device board-sim");
  }
  if (unplug && !std::isfinite(options.unplug_at)) {
    throw InputError("--unplug: must be a finite time, s, got " + FormatNumber(options.unplug_at));
  }
  if (replug &&
      !(unplug && std::isfinite(options.replug_at) && options.replug_at > options.unplug_at)) {
    throw InputError("--replug: needs --unplug T1 and a later time T2 > T1 (s), got " +
                     FormatNumber(options.replug_at));
  }
}

void ScriptedRun::Impl::BuildScene(Document* given, std::unique_ptr<haptics::HapticScene>* scene) {
  const bool scene_is_file =
      !(options.scene.empty() || options.scene == "none" || options.scene == "demo");
  if (!scene_is_file && !options.place.empty()) {
    throw InputError(
        "--place: needs a scene file or document (the solids the grip places are added to it); "
        "SCENE is " +
        (options.scene.empty() ? std::string("empty") : "'" + options.scene + "'"));
  }
  if (!scene_is_file && (!options.save.empty() || !exports.empty())) {
    throw InputError(std::string(options.save.empty() ? "--export" : "--save") +
                     ": needs a scene file or document (SCENE is " +
                     (options.scene.empty() ? std::string("empty") : "'" + options.scene + "'") +
                     ")");
  }
  if (options.scene.empty() || options.scene == "none") {
    *scene = std::make_unique<haptics::HapticScene>();
    return;
  }
  if (options.scene == "demo") {
    *scene = haptics::MakeDemoScene();
    scene_name = "demo";
    fields_line = "fields: plane_wall (floor z = -0.03 m), spring (toward (0.05, 0, 0) m)";
    return;
  }
  int version = DocumentFileVersion(options.scene);
  if (given != nullptr) {
    document = given;
  } else {
    OpenedDocument opened;
    try {
      opened = OpenDocumentFile(options.scene);
    } catch (const InputError& e) {
      throw InputError(std::string("SCENE: ") + e.what());
    }
    version = opened.version;
    own_document = std::move(opened.doc);
    document = own_document.get();
  }
  if (document->device() && !options.geometry_given) {
    geometry = *document->device();
    frame_source = "the document's";
  }
  BuildDocumentScene(version, scene);
}

void ScriptedRun::Impl::BuildDocumentScene(int version,
                                           std::unique_ptr<haptics::HapticScene>* scene) {
  Document& doc = *document;
  // What `run` renders of a document: its solids (one field each, or an assembly of "parts"),
  // or, in a document of rigid parts and no solid (an assembly saved from the window), the
  // assembly of its rigid parts as the window feels it; beside its solids, its FE models (each
  // one FE part, scene/fe_part.h; the solid an FE model's mesh was made from is not a rigid
  // solid too, as FE mode hides it), its rigid parts (one assembly field) and every sculpt
  // object; and snap. The other kinds are listed in the summary as skipped.
  const modeling::Scene loaded = doc.ToScene();
  // Rigid parts beside solids (and FE models) are one assembly field in the solids' scene.
  std::vector<AssemblyPartInput> parts_beside = RigidPartInputs(doc, nullptr);
  const std::vector<AssemblyPartInput> rigid_parts =
      loaded.solids.empty() ? parts_beside : std::vector<AssemblyPartInput>{};
  if (loaded.solids.empty()) parts_beside.clear();
  const std::size_t part_count = rigid_parts.empty() ? loaded.parts.size() : rigid_parts.size();
  // FE models are rendered beside solids, not in an assembly.
  const std::vector<ObjectId> fe_models =
      part_count == 0 ? FeModelsOf(doc) : std::vector<ObjectId>{};
  // The sculpt objects sculpted: all of them (not beside an assembly's parts).
  std::vector<ObjectId> sculpt_ids;
  for (const DocObject& o : doc.objects()) {
    if (part_count == 0 && std::holds_alternative<SculptData>(o.data)) sculpt_ids.push_back(o.id);
  }
  std::vector<ObjectId> fe_meshes, fe_sources;
  for (ObjectId fe : fe_models) {
    fe_meshes.push_back(std::get<FeModelData>(doc.Get(fe).data).tet_mesh);
    if (const ObjectId source = FeModelSource(doc, fe); source != 0) fe_sources.push_back(source);
  }
  const auto listed = [](const std::vector<ObjectId>& ids, ObjectId id) {
    return std::find(ids.begin(), ids.end(), id) != ids.end();
  };
  for (const DocObject& o : doc.objects()) {
    if (std::holds_alternative<SolidData>(o.data)) continue;
    if ((!rigid_parts.empty() || !parts_beside.empty()) &&
        std::holds_alternative<RigidPartData>(o.data))
      continue;
    if (listed(fe_models, o.id) || listed(fe_meshes, o.id) || listed(sculpt_ids, o.id)) continue;
    skipped_line += std::string(skipped_line.empty() ? "" : ", ") + ObjectKindName(o.data) + " '" +
                    o.name + "'";
  }
  if (!skipped_line.empty()) {
    skipped_line =
        "skipped (run renders solids, FE models, rigid parts, sculpt objects and snap; not yet "
        "other meshes): " +
        skipped_line;
  }
  // --export: objects whose final state run can write (FE parts, as .vtu; sculpt objects, as
  // .stl, .obj or .ply), checked before any work.
  for (const auto& [name, file] : exports) {
    const std::string what = "--export " + name + "=" + file + ": ";
    const DocObject* object = nullptr;
    for (const DocObject& o : doc.objects())
      if (o.name == name && object == nullptr) object = &o;
    if (object == nullptr) {
      throw InputError(what + "the document has no object named '" + name +
                       "'; its FE models: " + ObjectNames(doc, {"fe_model"}) +
                       "; its sculpt objects: " + ObjectNames(doc, {"sculpt"}));
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
      throw InputError(what + "'" + name + "' is a " + ObjectKindName(object->data) +
                       ", not an FE model run renders nor a sculpt object; run exports those "
                       "only (" +
                       ObjectNames(doc, {"fe_model", "sculpt"}) + ")");
    }
    if (file.size() < 4 || file.compare(file.size() - 4, 4, ".vtu") != 0) {
      throw InputError(what + "an FE model is written as .vtu: name the file FILE.vtu");
    }
  }
  if (version == 2 && loaded.solids.empty() && rigid_parts.empty() && fe_models.empty()) {
    // Nothing to render (but sculpt objects, added below): the grip moves freely.
    *scene = std::make_unique<haptics::HapticScene>();
    scene_name = options.scene + " (no solid)";
    if (!sculpt_ids.empty()) {
      // X_WD: the identity, as the window's for a document without solids, unless given.
      if (GivenWorldMap(options, &settings.X_WD)) map_line = MapLine(settings.X_WD);
    }
  } else if (part_count > 0) {
    // An assembly: one field owns every part (grasp, carry, contact, seats).
    if (!options.place.empty()) {
      throw InputError("--place: " + options.scene +
                       " is an assembly (its solids are the parts, carried and seated by the "
                       "grasp); primitives are placed in documents of solids");
    }
    std::unique_ptr<haptics::AssemblyField> assembly;
    try {
      // Alignment snap (a carried part drawn toward its seat's axis) where the document
      // enables snap.
      AssemblySceneSettings assembly_settings;
      assembly_settings.field.align.enabled = doc.snap().has_value();
      assembly = rigid_parts.empty() ? BuildAssemblyField(loaded, assembly_settings)
                                     : BuildAssemblyField(rigid_parts, assembly_settings, nullptr);
    } catch (const std::invalid_argument& e) {
      throw InputError(options.scene + ": " + e.what());
    }
    GivenWorldMap(options, &settings.X_WD);
    *scene = std::make_unique<haptics::HapticScene>();
    assembly_field = assembly.get();
    (*scene)->Add(std::move(assembly));
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
    for (const DocObject& o : doc.objects()) {
      if (const auto* solid = std::get_if<SolidData>(&o.data); solid && !listed(fe_sources, o.id))
        rigid.solids.push_back({o.name, solid->root});
    }
    // The FE meshes take part in the fit of X_WD as the solids do.
    Eigen::AlignedBox3d fe_box_W;
    for (ObjectId fe : fe_models) {
      fem::TetMesh mesh;
      try {
        mesh = FeMeshOf(doc, std::get<FeModelData>(doc.Get(fe).data));
      } catch (const std::exception& e) {
        throw InputError(options.scene + ": FE model '" + doc.Get(fe).name + "': " + e.what());
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
      for (int c = 0; c < 8; ++c)
        fe_box_W.extend(part.X_WP * box_P.corner(static_cast<Eigen::AlignedBox3d::CornerType>(c)));
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
    *scene = std::move(built.scene);
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
      const std::string name = doc.Get(fe).name;
      FePartOptions fe_options;
      fe_options.world_scale = built.map.X_WD.world_scale;
      fe_options.model.cache.start_worker = false;  // PrepareColumns below, nothing after
      fe_options.touch.grasp = options.fe_grasp && !options.fe_grab;
      fe_options.touch.tool_radius = options.fe_tool_radius;
      fe_options.grab_settings.tool_radius = options.fe_tool_radius;
      fe_options.grab = options.fe_grab;
      fe_options.grab_settings.grasp = options.fe_grasp;
      fe_options.grab_settings.worker = false;  // factored on the grab tick: deterministic
      FePart part;
      FeColumnPlan plan;
      try {
        part = BuildFePart(doc, fe, fe_options);
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
      fe_lines += "fe '" + name +
                  "' touch: " + (ts.patch_contact ? "tool patch, radius " : "sphere radius ") +
                  FormatNumber(ts.tool_radius) + " m" + (ts.grasp ? " at each pole tip" : "") +
                  (ts.frictionless ? ", frictionless" : ", sticking") + ", force scale " +
                  FormatNumber(ts.force_scale) + ", coupling " +
                  FormatNumber(ts.coupling_stiffness) + " N/m, max felt " +
                  FormatNumber(ts.max_force) + " N (W)\n";
      if (part.grab_field) {
        const FeGrabSettings& gs = part.grab_field->settings();
        fe_lines += "fe '" + name + "' grab: sphere radius " + FormatNumber(gs.tool_radius) + " m" +
                    (gs.grasp ? " at each pole tip" : "") + ", at most " +
                    std::to_string(gs.max_patch) + " nodes, force scale " +
                    FormatNumber(gs.force_scale) + ", max felt " + FormatNumber(gs.max_force) +
                    " N, " + FormatNumber(gs.max_torque) + " N·m (W)\n";
        fe_grabs.push_back(part.grab_field.get());
      }
      fe_fields.push_back(part.field.get());
      fe_parts.push_back(part.model);
      fe_names.push_back(name);
      if (part.grab_field) {
        (*scene)->Add(std::move(part.grab_field));
        fe_touch_fields.push_back(std::move(part.field));  // kept for --export, not felt
      } else {
        (*scene)->Add(std::move(part.field));
      }
    }
    if (!parts_beside.empty()) {
      // The rigid parts beside: one assembly field (grasp, carry, seats; alignment snap where
      // the document has snap), in the solids' W (their boxes were fitted with the solids).
      AssemblySceneSettings assembly_settings;
      assembly_settings.field.align.enabled = doc.snap().has_value();
      std::unique_ptr<haptics::AssemblyField> assembly;
      try {
        assembly = BuildAssemblyField(parts_beside, assembly_settings, nullptr);
      } catch (const std::invalid_argument& e) {
        throw InputError(options.scene + ": " + e.what());
      }
      assembly_field = assembly.get();
      (*scene)->Add(std::move(assembly));
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
  // The sculpt objects: a session on each one's mesh, each felt through its sculpt tool field.
  SculptModeSettings sculpt_settings;
  sculpt_settings.tool.tool = ParseSculptTool(options.sculpt_tool);
  sculpt_settings.tool.radius = options.sculpt_radius;
  sculpt_settings.tool.conserve_volume = options.conserve_volume;
  // The clay width's poles: the grip's, in W.
  sculpt_settings.clay_width.grasp.pole_length = settings.X_WD.world_scale * geometry.d;
  for (ObjectId id : sculpt_ids) {
    try {
      sculpts.push_back(std::make_unique<DocumentSculpt>(&doc, id, sculpt_settings));
    } catch (const std::invalid_argument& e) {
      throw InputError(options.scene + ": " + e.what());
    }
    (*scene)->Add(sculpts.back()->session().MakeField());
    if (fields_line.empty()) fields_line = "fields:";
    fields_line += std::string(fields_line == "fields:" ? "" : ",") + " sculpt_tool '" +
                   sculpts.back()->name() + "'";
  }
  sculpt_max_volume_change.assign(sculpts.size(), 0.0);
}

void ScriptedRun::Impl::MakeDevice(std::unique_ptr<haptics::HapticScene> scene) {
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
  ideal = options.device == "ideal";
  if (!ideal) ParseRigKind(options.device, &kind);  // checked above
  RigOptions rig_options;
  if (ideal) rig_options.device = haptics::SimulatedDeviceConfig::Ideal();
  rig_options.device.seed = options.seed;
  rig_options.device.geometry = geometry;
  rig_options.device.home_pose = haptics::GripPose::Rest(geometry.d);
  // A real board lost mid-run is re-opened by a service thread, not inside the tick (re-opening
  // goes through libusb, which allocates and locks); board-sim keeps its deterministic re-open
  // on the virtual clock.
  rig_options.reconnect_off_tick = kind == RigKind::kUsb;
  rig_options.link_faults.loss = options.link_loss;
  rig_options.link_faults.corruption = options.link_corruption;
  rig_options.link_faults.seed = options.link_seed != 0 ? options.link_seed : options.seed;
  rig = MakeDeviceRig(kind, rig_options);
  const haptics::DeviceInfo& info = rig->info();
  physical = rig->physical();
  calibration = NominalCalibration(info);
  t0 = trajectory.start_time();
  // At most 1e10 + 1 (duration checked above): fits a long.
  ticks = static_cast<long>(std::floor((trajectory.end_time() - t0) / dt + 1e-9)) + 1;
  const auto tick_at = [&](double t) {
    return std::clamp(static_cast<long>(std::ceil((t - t0) / dt - 1e-9)), 0L, ticks);
  };
  if (!std::isnan(options.unplug_at)) unplug_tick = tick_at(options.unplug_at);
  if (!std::isnan(options.replug_at)) replug_tick = tick_at(options.replug_at);
  link_columns = kind == RigKind::kBoardSim &&
                 (options.link_loss > 0.0 || options.link_corruption > 0.0 || unplug_tick >= 0);
  hand = std::make_unique<haptics::SimulatedHand>(hand_settings, trajectory.Sample(t0),
                                                  info.geometry.d);
  if (ideal) {
    // No encoder errors: FK's default acceptance, as the window's ideal device.
    settings.fk.max_residual = haptics::FkSettings().max_residual;
    physical->SetTruePose(hand->pose());
  }
  if (options.calibrate) {
    // As the window at start-up (device_rig.h); physical is not null (usb rejected above).
    const SimulatedCalibration fit = CalibrateSimulated(physical);
    calibration = fit.calibration;
    // Calibrated: FK's default acceptance, as the window; a failed fit keeps the nominal one.
    if (fit.ok) settings.fk.max_residual = haptics::FkSettings().max_residual;
    calibration_line = "calibration: " + fit.description;
    // The jig left the grip elsewhere at 1 N per string: back into the hand at minimum tension.
    physical->SetTruePose(hand->pose());
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
  loop = std::make_unique<haptics::HapticLoop>(info, calibration, settings);
  loop->Publish(std::move(scene));
  // board-sim / usb: the driver's handshake; no board answering is bad input (exit 2).
  if (!rig->Start(hand->pose())) throw InputError(rig->StartFailure());
  if (calibration_file && physical == nullptr) check_file(rig->Serial());
  service = std::make_unique<RigServiceThread>(rig.get());  // a thread only for usb
  frame.hand_pose = hand->pose();
  frame.tool.pose_D = hand->pose();
  frame.lengths = haptics::InverseKinematics(info.geometry, hand->pose());
  rig->Link(&frame.link);
}

ScriptedRun::ScriptedRun(const ScriptedRunOptions& options, Document* doc)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.options = options;
  s.CheckOptions();
  CheckTrajectoryFile(options.trajectory);
  try {
    s.trajectory = haptics::Trajectory::Load(options.trajectory);
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--trajectory: ") + e.what());
  }
  // The run lasts from the first sample to the last: refuse it before any tick if that is longer
  // than --max-duration (also when the difference overflows).
  if (!(s.trajectory.end_time() - s.trajectory.start_time() <= options.max_duration)) {
    const double limit = s.trajectory.start_time() + options.max_duration;
    const int line = LineOfTimePast(options.trajectory, limit);
    throw InputError(
        "--trajectory " + options.trajectory +
        (line > 0 ? ":" + std::to_string(line) : std::string("")) +
        ": field t: the trajectory runs from t = " + FormatNumber(s.trajectory.start_time()) +
        " s to t = " + FormatNumber(s.trajectory.end_time()) + " s, longer than the " +
        FormatNumber(options.max_duration) +
        " s a run may last (--max-duration, in (0, 1e7] s; docs/limits.md); shorten "
        "the trajectory or raise --max-duration");
  }
  // The frame: --frame/--pole, else the document's own (its "device"), else the paper's.
  s.geometry = options.geometry;
  if (options.geometry_given) s.frame_source = "--frame/--pole";
  s.settings.fk.max_residual = kNominalFkMaxResidual;  // nominal encoder model: mm-level errors
  // --export NAME=FILE: split (at the first '='), checked once the document is open.
  for (const std::string& e : options.exports) {
    const auto eq = e.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == e.size()) {
      throw InputError("--export '" + e +
                       "': expected NAME=FILE (an object's name, then the file)");
    }
    s.exports.emplace_back(e.substr(0, eq), e.substr(eq + 1));
  }
  std::unique_ptr<haptics::HapticScene> scene;
  s.BuildScene(doc, &scene);
  if (!options.place.empty()) s.AddTouch(scene.get());
  s.num_fields = scene->size();
  s.MakeDevice(std::move(scene));
  // Columns after today's only when the document has FE parts, sculpt objects or scripted link
  // faults (older outputs stay as they were).
  s.fe_columns = !s.fe_fields.empty();
  s.header =
      "t,x,y,z,qw,qx,qy,qz,grasp,fx,fy,fz,mx,my,mz,g,tau1,tau2,tau3,tau4,tau5,tau6,tau7,tau8,"
      "tick_us,events,fk_x,fk_y,fk_z";
  if (s.fe_columns) s.header += ",fe_contacts,fe_fx,fe_fy,fe_fz";
  if (!s.fe_grabs.empty()) s.header += ",fe_mx,fe_my,fe_mz";
  if (!s.sculpts.empty()) s.header += ",sculpt_stroke,sculpt_volume";
  for (std::size_t i = 1; i < s.sculpts.size(); ++i)
    s.header += ",sculpt_volume" + std::to_string(i + 1);
  if (s.link_columns) s.header += ",link_status,plugged,link_lost,link_corrupt";
  if (s.touch) s.header += ",touch_feature,touch_size,touch_lift,placed";
  s.header += '\n';
}

ScriptedRun::~ScriptedRun() = default;

long ScriptedRun::ticks() const { return impl_->ticks; }
long ScriptedRun::ticks_done() const { return impl_->k; }
const std::string& ScriptedRun::CsvHeader() const { return impl_->header; }
std::vector<std::string> ScriptedRun::TimingColumns() { return {"tick_us"}; }
const RuntimeFrame& ScriptedRun::frame() const { return impl_->frame; }
const haptics::DeviceToWorld& ScriptedRun::X_WD() const { return impl_->settings.X_WD; }
const haptics::DeviceInfo& ScriptedRun::info() const { return impl_->rig->info(); }
const haptics::HapticLoop& ScriptedRun::loop() const { return *impl_->loop; }

const TouchSession* ScriptedRun::touch() const { return impl_->touch.get(); }

int ScriptedRun::sculpt_strokes() const {
  int n = 0;
  for (const auto& sculpt : impl_->sculpts) n += sculpt->strokes();
  return n;
}

void ScriptedRun::Impl::StepSculpts(const haptics::ToolKinematics& tool_W, double t) {
  // The rule of the file comment: the clay under a stroke, else the nearest within reach.
  int chosen = stroking;
  if (chosen < 0) {
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < sculpts.size(); ++i) {
      const SculptSession& session = sculpts[i]->session();
      const double reach = session.settings().snap_distance > 0.0 ? session.settings().snap_distance
                                                                  : session.settings().tool.radius;
      const double d = NearestVertexDistance(session, tool_W.p_WT, reach, &query);
      if (d < best) {
        best = d;
        chosen = static_cast<int>(i);
      }
    }
    if (chosen < 0) chosen = 0;  // none in reach: the first sees the frame (it begins nothing)
  }
  DocumentSculpt& sculpt = *sculpts[chosen];
  try {
    sculpt.Step(tool_W);
  } catch (const std::exception& e) {
    throw InputError("sculpt '" + sculpt.name() + "' at t = " + FormatNumber(t) +
                     " s: " + e.what());
  }
  stroking = sculpt.session().stroke_active() ? chosen : -1;
}

void ScriptedRun::Impl::AddTouch(haptics::HapticScene* scene) {
  // Model mode's session, with the run's X_WD and grip; its felt pull is in the scene from the
  // first tick (zero until the first frame builds it).
  touch = std::make_unique<TouchSession>(geometry.d);
  touch->SetWorldScale(settings.X_WD.world_scale);
  touch->SetPlacing(ParsePlaceKind(options.place));
  scene->Add(std::make_unique<TouchSnapSlotField>(touch.get()));
  if (fields_line.empty()) fields_line = "fields:";
  fields_line += std::string(fields_line == "fields:" ? "" : ",") + " touch_snap (place " +
                 options.place + ")";
}

void ScriptedRun::Impl::StepTouch(const haptics::ToolState& tool) {
  // As model mode's frame: the squeeze, then the ghost, the felt field and the place.
  const bool squeezed = squeeze.Update(tool.time, tool.pose_D.Grasp());
  const TouchSession::PlaceFrame frame =
      touch->UpdatePlacing(tool, document, 0, squeezed, squeeze.last_start(), false);
  if (frame.placed) {
    const Alignment& ghost = touch->ghost();
    const Eigen::Vector3d& p = ghost.X_WN.translation();
    placed_lines.push_back(touch->message() + " at t = " + FormatNumber(t0 + k * dt) +
                           " s, centre (" + FormatNumber(p.x()) + ", " + FormatNumber(p.y()) +
                           ", " + FormatNumber(p.z()) + ") m");
  }
}

void ScriptedRun::SetStepHooks(std::function<void()> before, std::function<void()> after) {
  impl_->before_step = std::move(before);
  impl_->after_step = std::move(after);
}

void ScriptedRun::Step(std::string* csv) {
  Impl& s = *impl_;
  const long k = s.k;
  const double dt = s.dt;
  const double t = s.t0 + k * dt;
  if (k == 0) s.wall_start = std::chrono::steady_clock::now();
  // Scripted link faults (board-sim): the cable out at --unplug's tick, back at --replug's.
  if (k == s.unplug_tick) s.rig->RequestPlugged(false);
  if (k == s.replug_tick) s.rig->RequestPlugged(true);
  haptics::TickInputs inputs;
  haptics::SimulatedHand& hand = *s.hand;
  if (s.ideal) {
    // A rigid hand: the grip is where the trajectory puts it.
    const haptics::TrajectorySample target = s.trajectory.Sample(t);
    s.frame.hand_pose = haptics::GripPose::FromFrame(target.p_DT, target.q_DT.toRotationMatrix(),
                                                     target.grasp, s.rig->info().geometry.d);
    s.physical->SetTruePose(s.frame.hand_pose);
  } else if (s.physical) {
    hand.Step(s.trajectory.Sample(t), s.physical->TrueWrench(), dt);
    s.physical->SetTruePose(hand.pose());
    s.frame.hand_pose = hand.pose();
  } else {
    // A real board: tick k starts at its absolute time (no drift); lateness is reported.
    const auto due = s.wall_start + std::chrono::microseconds(k * 1000);
    std::this_thread::sleep_until(due);
    inputs.lateness = std::chrono::duration<double>(std::chrono::steady_clock::now() - due).count();
  }
  s.rig->Read(dt, &inputs.reading);
  if (s.before_step) s.before_step();
  const auto start = std::chrono::steady_clock::now();
  const haptics::TickOutputs result = s.loop->Step(inputs, dt);
  const auto stop = std::chrono::steady_clock::now();
  if (s.after_step) s.after_step();
  s.rig->Write(result.tau);
  const double seconds = std::chrono::duration<double>(stop - start).count();
  s.tick_time.Add(seconds);
  s.max_force = std::max(s.max_force, result.wrench_D.head<3>().norm());
  s.frame.tool = result;
  s.frame.step_seconds = seconds;
  s.frame.lengths = s.calibration.Lengths(inputs.reading.counts, result.tau);
  s.rig->Link(&s.frame.link);

  Eigen::Vector3d p = s.frame.hand_pose.p0;
  Eigen::Quaterniond q(s.frame.hand_pose.Rotation());
  double grasp = s.frame.hand_pose.Grasp();
  if (!s.ideal) {
    p = hand.position();
    q = Eigen::Quaterniond(hand.rotation());
    grasp = hand.grasp();
  }
  if (!s.physical) {  // a real board: the measured pose (NaN without one)
    const bool ok = result.fk_status == haptics::FkStatus::kOk;
    p = ok ? result.pose_D.p0 : Eigen::Vector3d::Constant(std::nan(""));
    q = ok ? Eigen::Quaterniond(result.pose_D.Rotation())
           : Eigen::Quaterniond(std::nan(""), std::nan(""), std::nan(""), std::nan(""));
    grasp = ok ? result.pose_D.Grasp() : std::nan("");
    if (ok && inputs.reading.status == haptics::DeviceStatus::kOk)
      s.frame.hand_pose = result.pose_D;
  }
  std::string& buffer = *csv;
  const double row[] = {t, p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z(), grasp};
  for (double v : row) buffer += FormatNumber(v) + ',';
  for (int i = 0; i < 7; ++i) buffer += FormatNumber(result.wrench_D(i)) + ',';
  for (int i = 0; i < 8; ++i) buffer += FormatNumber(result.tau(i)) + ',';
  buffer += Fixed(seconds * 1e6, 2) + ',';
  buffer += std::to_string(result.events) + ',';
  const bool has_pose = result.fk_status == haptics::FkStatus::kOk;
  for (int i = 0; i < 3; ++i) {
    if (i > 0) buffer += ',';
    buffer += has_pose ? FormatNumber(result.pose_D.p0(i)) : std::string("nan");
  }
  if (s.fe_columns) {
    // The FE parts' contact state of this tick (this thread ran it: it is the one reader).
    int contacts = 0, substituted = 0, refused = 0;
    Eigen::Vector3d f = Eigen::Vector3d::Zero();
    Eigen::Vector3d m = Eigen::Vector3d::Zero();
    for (const FeTouchField* field : s.fe_fields) {
      if (!s.fe_grabs.empty()) break;  // grabbed, not pushed
      const FeContactState& st = field->last_state();
      contacts += st.num_contacts;
      substituted += st.num_substituted;
      if (field->settings().patch_contact) refused += st.refused;
      f += st.f_tool_W;
    }
    for (const FeGrabField* grab : s.fe_grabs) {
      const FeGrabState& st = grab->last_state();
      if (!st.ready) continue;
      contacts += st.num_nodes;
      substituted += st.num_substituted;
      f += st.f_tool_W;
      m += st.m_tool_W;
    }
    if (substituted > 0) ++s.fe_substituted_ticks;
    if (refused > 0) ++s.fe_truncated_ticks;
    s.fe_max_contacts = std::max(s.fe_max_contacts, contacts);
    s.fe_max_reaction = std::max(s.fe_max_reaction, f.norm());
    buffer += ',' + std::to_string(contacts) + ',' + FormatNumber(f.x()) + ',' +
              FormatNumber(f.y()) + ',' + FormatNumber(f.z());
    if (!s.fe_grabs.empty())
      buffer += ',' + FormatNumber(m.x()) + ',' + FormatNumber(m.y()) + ',' + FormatNumber(m.z());
  }
  if (!s.sculpts.empty()) {
    // The sculpt sessions' frame (every kSculptFrameTicks ticks): the stroke follows this
    // tick's tool state; the fields read the published force model from the next tick on.
    if ((k + 1) % kSculptFrameTicks == 0) s.StepSculpts(result.tool_W, t);
    // sculpt_stroke: the 1-based index of the clay under a stroke (0: none; 1 with one clay).
    buffer += ',' + std::to_string(s.stroking + 1);
    for (std::size_t i = 0; i < s.sculpts.size(); ++i) {
      const DocumentSculpt& sculpt = *s.sculpts[i];
      const double volume = sculpt.session().volume();
      s.sculpt_max_volume_change[i] =
          std::max(s.sculpt_max_volume_change[i],
                   std::abs(volume - sculpt.start_volume()) / sculpt.start_volume());
      buffer += ',' + FormatNumber(volume);
    }
  }
  if (s.link_columns) {
    // The driver's view of the link after this tick: status, cable, States lost and corrupt.
    const RigLink& link = s.frame.link;
    buffer += ',' + std::to_string(static_cast<int>(link.status)) + ',' +
              (link.plugged ? "1" : "0") + ',' + std::to_string(link.stats.lost) + ',' +
              std::to_string(link.stats.corrupt);
  }
  if (s.touch) {
    // Model mode's frame (every kSculptFrameTicks ticks, as the sculpt's): the felt field it
    // builds pulls from the next tick on. Then what the ghost aligned to, its size (m, W), the
    // felt faces' lift (m, W) and the solids placed so far.
    if ((k + 1) % kSculptFrameTicks == 0) s.StepTouch(result);
    buffer += ',' + std::to_string(AlignKindNumber(s.touch->ghost().kind)) + ',' +
              FormatNumber(s.touch->ghost_size()) + ',' +
              FormatNumber(s.touch->felt_rest_height()) + ',' +
              std::to_string(s.touch->placed_count());
  }
  buffer += '\n';
  ++s.k;
}

void ScriptedRun::Finish() {
  Impl& s = *impl_;
  // A stroke still under way ends at the last tick, as if the grasp opened there.
  for (auto& sculpt : s.sculpts) sculpt->Finish(s.frame.tool.tool_W);
  s.stroking = -1;
}

void ScriptedRun::EmergencyStop(bool stop) {
  if (stop) {
    impl_->loop->RequestEmergencyStop();
  } else {
    impl_->loop->ClearEmergencyStop();
  }
}

std::string ScriptedRun::Summary() const {
  const Impl& s = *impl_;
  std::ostringstream out;
  const long ticks = s.ticks;
  out << "run: " << ticks << " ticks (" << Fixed((ticks - 1) * s.dt, 3) << " s at 1000 Hz, "
      << (s.physical ? "virtual clock" : "real time") << "), scene " << s.scene_name << " ("
      << s.num_fields << " field" << (s.num_fields == 1 ? "" : "s") << "), device "
      << (s.ideal ? "ideal (no encoder errors, rigid hand)" : s.rig->Describe());
  if (s.physical && !s.ideal) {
    out << ", hand " << FormatNumber(s.hand_settings.stiffness) << " N/m, "
        << FormatNumber(s.hand_settings.damping) << " N·s/m";
  }
  out << "\n";
  const std::string link = s.rig->LinkSummary();
  if (!link.empty()) out << link << "\n";
  if (s.link_columns) {
    out << "link faults: loss " << FormatNumber(s.options.link_loss) << ", corruption "
        << FormatNumber(s.options.link_corruption) << " per packet (seed "
        << (s.options.link_seed != 0 ? s.options.link_seed : s.options.seed) << ")";
    if (s.unplug_tick >= 0)
      out << "; unplugged at t = " << FormatNumber(s.t0 + s.unplug_tick * s.dt) << " s";
    if (s.replug_tick >= 0)
      out << ", replugged at t = " << FormatNumber(s.t0 + s.replug_tick * s.dt) << " s";
    out << "\n";
  }
  if (!s.calibration_line.empty()) out << s.calibration_line << "\n";
  if (!s.fields_line.empty()) out << s.fields_line << "\n";
  if (!s.skipped_line.empty()) out << s.skipped_line << "\n";
  out << s.fe_lines;
  if (s.fe_columns) {
    out << "fe contact: at most " << s.fe_max_contacts << " nodes, largest FE reaction "
        << Fixed(s.fe_max_reaction, 3) << " N (unscaled, W); " << s.fe_substituted_ticks
        << " ticks read a substitute column (a node off the prepared path)";
    if (s.fe_truncated_ticks > 0)
      out << "; " << s.fe_truncated_ticks << " ticks left tool-patch nodes out (more than "
          << kMaxFeContacts << ": a smaller tool was felt)";
    out << "\n";
  }
  for (std::size_t i = 0; i < s.sculpts.size(); ++i) {
    const DocumentSculpt& sculpt = *s.sculpts[i];
    const modeling::SculptToolSettings& st = sculpt.session().settings().tool;
    const double v0 = sculpt.start_volume(), v1 = sculpt.session().volume();
    out << "sculpt '" << sculpt.name() << "': " << sculpt.strokes() << " stroke"
        << (sculpt.strokes() == 1 ? "" : "s") << " (" << modeling::SculptToolName(st.tool)
        << ", radius " << FormatNumber(st.radius) << " m, volume "
        << (st.conserve_volume ? "conserved" : "not conserved") << "); volume " << FormatNumber(v0)
        << " -> " << FormatNumber(v1) << " m^3 (" << (v1 >= v0 ? "+" : "")
        << Fixed(100.0 * (v1 - v0) / v0, 3) << " %), at most "
        << Fixed(100.0 * s.sculpt_max_volume_change[i], 3) << " % off the start during the run; "
        << sculpt.session().mesh()->vertex_count() << " vertices\n";
    if (const auto& grid = sculpt.session().clay_grid()) {
      const SculptSession& session = sculpt.session();
      out << "clay width '" << sculpt.name() << "': distance grid of " << grid->node_count()
          << " nodes (" << FormatNumber(grid->cell()) << " m), built in "
          << Fixed(1e3 * sculpt.start_grid_seconds(), 1) << " ms of thread CPU time; "
          << session.grid_builds() - 1 << " update" << (session.grid_builds() == 2 ? "" : "s")
          << " after strokes";
      if (session.grid_builds() > 1) {
        out << ", the last in " << Fixed(1e3 * session.last_grid_seconds(), 1) << " ms ("
            << session.last_grid_nodes() << " nodes recomputed)";
      }
      out << "\n";
    }
  }
  if (s.frame_source != "default") {
    out << "frame: half-sides " << FormatNumber(s.geometry.a) << ", " << FormatNumber(s.geometry.b)
        << ", " << FormatNumber(s.geometry.c) << " m, pole " << FormatNumber(s.geometry.d) << " m ("
        << s.frame_source << ")\n";
  }
  if (s.touch) {
    out << "touch: placing " << s.options.place << " (snap pull at most "
        << FormatNumber(s.touch->snap_settings().max_force) << " N); " << s.touch->placed_count()
        << " placed\n";
    for (const std::string& line : s.placed_lines) out << "touch: " << line << "\n";
  }
  out << s.map_line << "\n";
  const haptics::LatencyHistogram& tt = s.tick_time;
  out << "tick time [us]: p50 " << Fixed(tt.Percentile(0.5) * 1e6, 1) << "  p99 "
      << Fixed(tt.Percentile(0.99) * 1e6, 1) << "  p99.9 " << Fixed(tt.Percentile(0.999) * 1e6, 1)
      << "  max " << Fixed(tt.max() * 1e6, 1) << "  mean " << Fixed(tt.mean() * 1e6, 1) << "\n";
  out << "safety events [ticks]:";
  const auto& counts = s.loop->event_counts();
  for (int i = 0; i < haptics::kNumSafetyEvents; ++i) {
    out << ' ' << haptics::SafetyEventName(i) << '=' << counts[i] << " (bit " << i << ")"
        << (i + 1 < haptics::kNumSafetyEvents ? "," : "");
  }
  out << "\nmax commanded force: " << Fixed(s.max_force, 3) << " N\n";
  if (s.assembly_field != nullptr) {
    // The field's state after the last tick (this thread ran every tick: it is the one reader).
    out << FormatAssemblySummary(*s.assembly_field, s.assembly_field->LatestState());
  }
  return out.str();
}

void ScriptedRun::WriteOutputs(std::ostream* out) const {
  const Impl& s = *impl_;
  // The final state of each exported FE part: its last tick's contacts, solved in full.
  for (const auto& [name, file] : s.exports) {
    const DocObject* object = nullptr;  // the first object of that name, as checked above
    for (const DocObject& o : s.document->objects())
      if (o.name == name && object == nullptr) object = &o;
    if (const auto* clay = object ? std::get_if<SculptData>(&object->data) : nullptr) {
      // A sculpt object's surface as it stands at the end of the run (its strokes recorded).
      try {
        modeling::WriteTriangleMesh(*clay->mesh, file);
      } catch (const std::exception& e) {
        throw InputError("--export " + name + "=" + file + ": " + e.what());
      }
      *out << "wrote " << file << " ('" << name
           << "' at the end of the run: " << clay->mesh->vertices.cols() << " vertices, "
           << clay->mesh->triangles.cols() << " triangles)\n";
      continue;
    }
    const std::size_t i =
        std::find(s.fe_names.begin(), s.fe_names.end(), name) - s.fe_names.begin();
    const FeContactState& state = s.fe_fields[i]->last_state();
    const FeGrabState* grab = s.fe_grabs.empty() ? nullptr : &s.fe_grabs[i]->last_state();
    try {
      WriteFeStateVtu(
          *s.fe_parts[i],
          grab ? SolveFeGrabState(*s.fe_parts[i], *grab) : SolveFeState(*s.fe_parts[i], state),
          file);
    } catch (const std::exception& e) {
      throw InputError("--export " + name + "=" + file + ": " + e.what());
    }
    const int nodes = grab ? (grab->ready ? grab->num_nodes : 0) : state.num_contacts;
    const double reaction = grab ? grab->f_tool_W.norm() : state.f_tool_W.norm();
    *out << "wrote " << file << " ('" << name << "' at the last tick: " << nodes
         << (grab ? " grabbed" : " contact") << " nodes, FE reaction on the tool "
         << Fixed(reaction, 3) << " N; displacement and von_mises by a full solve)\n";
  }
  for (const std::string& path : s.options.save) {
    try {
      s.document->Save(path);
    } catch (const std::exception& e) {
      throw InputError(std::string("--save ") + path + ": " + e.what());
    }
    *out << "wrote " << path << " (the document at the end of the run)\n";
  }
}

}  // namespace spidarcad::app
