// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The window loop: GLFW events → grip control → target of the simulated hand → (haptic thread:
// hand, device, HapticLoop at 1 kHz) → latest ToolState → modes → VTK scene + ImGui panels;
// scene meshing in background Jobs.
#include "gui/app_window.h"

#include <dlfcn.h>
#include <link.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <ctime>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string_view>
#include <thread>
#include <variant>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>
#include <imgui_internal.h>
#include <vtkCallbackCommand.h>
#include <vtkCommand.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkNew.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>

#include <Eigen/Geometry>

#include "doc/assets.h"
#include "doc/autosave.h"
#include "doc/command.h"
#include "doc/input_error.h"
#include "doc/job.h"
#include "doc/mesh_import.h"
#include "doc/number_format.h"
#include "doc/recent_files.h"
#include "gui/calibration_wizard.h"
#include "gui/device_view.h"
#include "gui/file_browser.h"
#include "gui/gl_capture.h"
#include "gui/mode.h"
#include "gui/modes.h"
#include "gui/panels.h"
#include "gui/scene_view.h"
#include "gui/tree_panel.h"
#include "gui/virtual_clock.h"
#include "gui/workbench_panels.h"
#include "scene/assembly_scene.h"
#include "scene/device_session.h"
#include "scene/grip_control.h"
#include "scene/haptic_runtime.h"
#include "scene/scene_model.h"
#include "scene/trajectory_player.h"
#include "spidarcad/haptics/trajectory.h"

namespace spidarcad::app {

namespace {

#if defined(__SANITIZE_ADDRESS__)
// Sanitizer builds only (docs/sanitizers.md). Mesa loads its DRI driver (swrast_dri.so under
// Xvfb) when the first context is made and unloads it at exit; two 56-byte blocks the driver
// keeps through its own globals are then reachable from nothing, and LeakSanitizer reports
// them from frames it can no longer name, so no suppression can match them. Marking every
// loaded *_dri.so as never to be unloaded (RTLD_NOLOAD | RTLD_NODELETE: nothing new is loaded)
// keeps its globals, and so those blocks, reachable until the leak check; leaks of our own are
// still found.
void PinGlDriverForLeakCheck() {
  dl_iterate_phdr(
      [](dl_phdr_info* info, std::size_t, void*) {
        const std::string_view name = info->dlpi_name != nullptr ? info->dlpi_name : "";
        if (name.size() > 7 && name.substr(name.size() - 7) == "_dri.so") {
          dlopen(info->dlpi_name, RTLD_LAZY | RTLD_NOLOAD | RTLD_NODELETE);
        }
        return 0;
      },
      nullptr);
}
#else
void PinGlDriverForLeakCheck() {}
#endif

// Why --select or --set found nothing called `name`, and what it accepts.
std::string NoSuchNodeText(const std::string& name) {
  return "nothing named '" + name +
         "' in the document: give a solid's name, a node's name or id, SOLID/i/j for child j of "
         "child i of the solid's root, or the name of a mesh, FE model or sculpt object";
}

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
constexpr double kGraspStep = 5.0 * kDegToRad;           // per wheel notch or key press
constexpr double kRotateGain = 0.008;                    // rad per pixel of right-drag
constexpr double kOrbitGain = 0.3;                       // deg per pixel
constexpr double kClickSlop = 3.0;                       // pixels a click may move and stay a click
constexpr double kMaxWindowTrajectorySeconds = 86400.0;  // longest --trajectory the window plays, s
constexpr int kScreenshotFrames = 6;                     // frames rendered before the capture
constexpr double kSettleTimeout = 90.0;                  // s a screenshot waits for ramp and jobs
constexpr double kCalibrationTimeout = 600.0;            // ... and for a calibration session
constexpr int kReloadCheckFrames = 30;                   // frames between scene-file mtime checks
constexpr int kFiguresOpenHeight = 800;  // window height from which the strip starts open
constexpr char kFontPath[] = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
constexpr char kDocumentPanel[] = "Document";
constexpr char kModePanel[] = "Mode";
constexpr char kFiguresPanel[] = "Device and haptic loop";
constexpr char kDiscardPopup[] = "Unsaved changes";
constexpr char kRecoveryPopup[] = "Recover unsaved work";
constexpr char kFileErrorPopup[] = "Cannot open";
constexpr int kBuiltInModes = 4;  // model, FE, sculpt, assembly: remade for every document

// What waits for the unsaved-changes question (AppWindow::RequestAction).
enum PendingKind { kPendingNone = 0, kPendingNew, kPendingOpen, kPendingQuit };

// Local time of a file time, "2026-12-02 04:10:33".
std::string FileTimeText(std::filesystem::file_time_type t) {
  const auto sys = std::chrono::time_point_cast<std::chrono::system_clock::duration>(
      std::chrono::file_clock::to_sys(t));
  const std::time_t tt = std::chrono::system_clock::to_time_t(sys);
  std::tm tm{};
  localtime_r(&tt, &tm);
  char text[64];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M:%S", &tm);
  return text;
}

// The pid in "untitled-<pid>.spidarcad", 0 when the name is not one.
long UntitledPid(const std::filesystem::path& path) {
  const std::string stem = path.stem().string();
  if (stem.rfind("untitled-", 0) != 0) return 0;
  const std::string digits = stem.substr(9);
  if (digits.empty() || digits.size() > 9 ||
      digits.find_first_not_of("0123456789") != std::string::npos)
    return 0;
  return std::stol(digits);
}

// GLFW's drop callback: the files go to the window (its user pointer).
void OnDrop(GLFWwindow* glfw_window, int count, const char** paths) {
  auto* window = static_cast<AppWindow*>(glfwGetWindowUserPointer(glfw_window));
  if (window == nullptr || count <= 0) return;
  window->DropFiles(std::vector<std::string>(paths, paths + count));
}

void GlfwError(int code, const char* text) {
  std::cerr << "spidarcad: GLFW error " << code << ": " << text << "\n";
}

// Mouse action in progress in the 3D view.
enum class DragMode { kNone, kMoveGrip, kRotateGrip, kRollGrip, kOrbit };

const char* DragModeText(DragMode mode) {
  switch (mode) {
    case DragMode::kMoveGrip:
      return "moving grip";
    case DragMode::kRotateGrip:
      return "rotating grip";
    case DragMode::kRollGrip:
      return "rolling grip";
    case DragMode::kOrbit:
      return "orbit";
    case DragMode::kNone:
      break;
  }
  return "";
}

void OnMakeCurrent(vtkObject*, unsigned long, void* client, void*) {
  glfwMakeContextCurrent(static_cast<GLFWwindow*>(client));
}

void OnIsCurrent(vtkObject*, unsigned long, void* client, void* call) {
  *static_cast<bool*>(call) = glfwGetCurrentContext() == static_cast<GLFWwindow*>(client);
}

// RAII for GLFW and ImGui so that every exit path cleans up.
struct GlfwSession {
  bool ok = glfwInit() == GLFW_TRUE;
  ~GlfwSession() {
    if (ok) glfwTerminate();
  }
};

struct ImGuiSession {
  bool glfw = false, gl3 = false;
  ImGuiSession() { ImGui::CreateContext(); }
  ~ImGuiSession() {
    if (gl3) ImGui_ImplOpenGL3_Shutdown();
    if (glfw) ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
  }
};

void LoadFont() {
  ImGuiIO& io = ImGui::GetIO();
  // Latin-1, Greek (τ, θ), general punctuation (–, ·), super/subscripts, arrows, maths, shapes.
  static const ImWchar kRanges[] = {0x0020, 0x00FF, 0x0370, 0x03FF, 0x2010, 0x2044, 0x2070, 0x209F,
                                    0x2190, 0x21FF, 0x2200, 0x22FF, 0x25A0, 0x25FF, 0};
  std::error_code ec;
  if (std::filesystem::exists(kFontPath, ec)) {
    if (io.Fonts->AddFontFromFileTTF(kFontPath, 14.5f, nullptr, kRanges) != nullptr) return;
  }
  io.Fonts->AddFontDefault();
}

// The scene the window opens: the positional argument, else the mode's part, else the demo.
std::string DefaultSceneFor(const GuiOptions& options) {
  if (!options.scene.empty()) return options.scene;
  if (options.mode == "fe") return PlatformScenePath();
  if (options.mode == "sculpt") return AssetPath("scenes/clay.json");
  return kDemoSceneName;
}

// The box (in D) the camera fits: the selected solid's (selection) or every solid's, else the
// device frame.
Eigen::AlignedBox3d SubjectBox(const SceneModel& model, int selected, bool selection,
                               const DeviceView& view) {
  Eigen::AlignedBox3d box;
  const auto& objects = model.objects();
  for (int i = 0; i < static_cast<int>(objects.size()); ++i) {
    if (selection && i != selected) continue;
    if (!objects[i].bounds_W.isEmpty()) box.extend(objects[i].bounds_W);
  }
  if (box.isEmpty() && selection) return SubjectBox(model, selected, false, view);
  if (box.isEmpty()) return view.FrameBox();
  return model.device_to_world().BoxToDevice(box);
}

// True when two frames have the same half-sides and pole (exactly: both come from files or
// options).
bool SameFrame(const haptics::SpidarGeometry& x, const haptics::SpidarGeometry& y) {
  return x.a == y.a && x.b == y.b && x.c == y.c && x.d == y.d;
}

// "0.3, 0.3, 0.2 m / pole 0.04 m".
std::string FrameText(const haptics::SpidarGeometry& g) {
  return FormatNumber(g.a) + ", " + FormatNumber(g.b) + ", " + FormatNumber(g.c) + " m / pole " +
         FormatNumber(g.d) + " m";
}

// A version 1 assembly's parts become rigid parts of the document (scene/assembly_scene.h), so
// that the assembly mode's moves are undoable document content.
void AdoptParts(SceneModel* model) {
  if (AdoptScenePartsAsRigidParts(&model->document())) model->Refresh();
}

}  // namespace

// A document being read on a thread of its own (AppWindow::ReadOffThread: the start-up
// document, File → Open and the like, the reload after an outside change): shared by the
// window, which may give up waiting for it (Cancel), and the thread, which then ends at its
// next look at `cancel` and drops what it made.
struct OpenWork {
  std::atomic<bool> cancel{false};
  std::atomic<bool> done{false};  // the thread has set what follows
  PrepareProgress progress;
  PreparedScene prepared;
  std::exception_ptr failure;
};

namespace {

// The thread of an OpenWork: reads `source` (SceneModel::Prepare, which reads and parses the
// file once and says whether it is a version 1 assembly). Destroyed while still joinable (an
// exception left the wait), it raises the flag and joins.
struct OpenThread {
  std::shared_ptr<OpenWork> work = std::make_shared<OpenWork>();
  std::thread thread;
  explicit OpenThread(const std::string& source) {
    thread = std::thread([work = work, source] {
      try {
        work->prepared = SceneModel::Prepare(source, &work->cancel, &work->progress);
      } catch (...) {
        work->failure = std::current_exception();
      }
      work->done.store(true);
    });
  }
  OpenThread(const OpenThread&) = delete;
  OpenThread& operator=(const OpenThread&) = delete;
  ~OpenThread() {
    if (thread.joinable()) {
      work->cancel.store(true);
      thread.join();
    }
  }
};

}  // namespace

struct AppWindow::State {
  GuiOptions options;
  // The scene and its tree.
  std::unique_ptr<GripControl> grip;
  haptics::Trajectory trajectory;
  SceneModel model;
  std::unique_ptr<TreeController> tree;
  TreePanelState tree_state;
  // GLFW, the loop, the jobs.
  std::unique_ptr<GlfwSession> glfw;
  GLFWwindow* window = nullptr;
  RuntimeSettings runtime_settings;
  std::unique_ptr<HapticRuntime> runtime;
  DemoFieldSettings springs;
  std::unique_ptr<JobQueue> jobs;  // destroyed before model: joins the workers first
  CalibrationWizard calibration;   // Haptics → Calibrate device...
  int calibration_idle = 0;        // frames since the wizard was last busy (a page settles)
  WorkbenchState workbench;
  // VTK.
  std::unique_ptr<DeviceView> view;
  vtkSmartPointer<vtkGenericOpenGLRenderWindow> render_window;
  vtkNew<vtkCallbackCommand> make_current;
  vtkNew<vtkCallbackCommand> is_current;
  std::unique_ptr<SceneView> scene_view;
  // The modes: modelling first; exactly one active.
  std::vector<std::unique_ptr<Mode>> modes;
  ModelMode* model_mode = nullptr;
  AssemblyWindowMode* assembly_mode = nullptr;
  Mode* active = nullptr;
  ModeContext context;
  // ImGui.
  std::unique_ptr<ImGuiSession> imgui;
  // --trajectory.
  std::unique_ptr<TrajectoryPlayer> player;
  bool player_live = false;
  // --clock virtual: the scripted run that is felt and stepped, frame by frame (null: wall).
  std::unique_ptr<VirtualClock> scripted;
  int scripted_end_frame = 0;  // the frame that finished it (a screenshot is taken after it)
  // Frame state.
  const haptics::SpidarGeometry* geometry = nullptr;
  WindowLayout layout;
  float menu_height = 21.0f;
  float frame_height = 21.0f;
  bool figures_applied = true;
  bool fit_pending = false;  // fit the view to the scene and the grip at the first frame  // the
                             // strip's collapsed state as last set on the ImGui window
  int fb_w = 0, fb_h = 0, win_w = 0, win_h = 0;
  DragMode drag = DragMode::kNone;
  ImVec2 press{0.0f, 0.0f};   // where the left button went down (a click if it stays)
  double press_travel = 0.0;  // pixels the mouse moved since
  bool select_key = false;    // Enter this frame
  bool place_key = false;     // P this frame
  bool grab_key = false;      // G this frame
  bool quit = false;
  bool capture = false;
  bool done = false;
  bool print_summary = true;
  int exit_status = 0;
  int frame_index = 0;
  int last_frame = 0;
  double start_time = 0.0;
  int publishes = 0;
  bool republish = false;
  std::string window_title;
  RuntimeFrame latest;
  DeviceFrame device_frame;
  LoopStats stats;
  PanelActions panel_actions;
  WorkbenchActions actions;
  // Documents: the File menu's requests, the recent list, autosave and recovery.
  std::unique_ptr<RecentFiles> recent;
  std::unique_ptr<Autosaver> autosaver;
  bool autosave_wrote = false;  // the autosaver wrote this document's recovery file
  std::string autosave_error;   // the last autosave failure shown
  std::string recovered_file;   // the recovery file this document was recovered from, if any
  std::optional<RecoveryFile> recovery_offer;  // the start-up question while unanswered
  bool recovery_popup_requested = false;
  int recovery_answer = -1;                 // the buttons' answer, run at the next frame
  std::vector<RecentEntry> recent_entries;  // Open Recent, refreshed every kReloadCheckFrames
  std::string recorded_path;                // document path last put in the recent list
  int pending_kind = kPendingNone;
  std::string pending_path;
  bool pending_ready = false;  // run the pending action at the next frame
  bool ask_discard = false;    // the Save / Discard / Cancel question is up
  bool discard_popup_requested = false;
  bool pending_after_save_as = false;  // the action waits for Save As
  std::string file_error;
  bool file_error_popup = false;
  std::atomic<bool> opening{false};      // WaitForOpen is running (read by any thread)
  std::atomic<bool> cancel_open{false};  // CancelOpen (any thread)
  bool window_open = false;              // GLFW, the window and ImGui are up (OpenWindow)
  // Threads of cancelled opens, left to end on their own at their next look at the flag
  // (within one parse, one compile or one box); joined when the window goes.
  std::vector<std::thread> cancelled_opens;
  FileBrowserState open_browser;
  FileBrowserState import_browser;
  // Also when the constructor throws after a cancelled start-up read (no ~AppWindow then).
  ~State() {
    for (std::thread& t : cancelled_opens)
      if (t.joinable()) t.join();
  }
};

AppWindow::AppWindow(const GuiOptions& options) : s_(std::make_unique<State>()) {
  State& s = *s_;
  s.options = options;
  // The scene first: a bad file fails before any window opens.
  s.grip = std::make_unique<GripControl>(haptics::SpidarGeometry{});
  const auto& g0 = options.grip;
  const Eigen::Matrix3d R0 = (Eigen::AngleAxisd(g0[5] * kDegToRad, Eigen::Vector3d::UnitZ()) *
                              Eigen::AngleAxisd(g0[4] * kDegToRad, Eigen::Vector3d::UnitY()) *
                              Eigen::AngleAxisd(g0[3] * kDegToRad, Eigen::Vector3d::UnitX()))
                                 .toRotationMatrix();
  s.grip->SetPose(Eigen::Vector3d(g0[0], g0[1], g0[2]) * 1e-3, R0, g0[6] * kDegToRad);
  // --place: checked before any window opens.
  std::optional<PlaceKind> place;
  if (!options.place.empty()) {
    if (!options.mode.empty()) {
      throw WindowStartError(2,
                             "spidarcad: error: --place: primitives are placed in model mode; "
                             "drop --mode " +
                                 options.mode + " (or --place)");
    }
    try {
      place = ParsePlaceKind(options.place);
    } catch (const std::invalid_argument& e) {
      throw WindowStartError(2, std::string("spidarcad: error: --place: ") + e.what());
    }
  }
  // --trajectory: read before any window opens; the grip starts at its first sample.
  if (!options.trajectory.empty()) {
    try {
      CheckTrajectoryFile(options.trajectory);
      s.trajectory = haptics::Trajectory::Load(options.trajectory);
    } catch (const InputError& e) {
      throw WindowStartError(2, std::string("spidarcad: error: ") + e.what());
    } catch (const std::exception& e) {
      throw WindowStartError(2, std::string("spidarcad: error: --trajectory: ") + e.what());
    }
    // Played in wall-clock time (and waited for by --screenshot): at most one day.
    if (!(s.trajectory.end_time() - s.trajectory.start_time() <= kMaxWindowTrajectorySeconds)) {
      throw WindowStartError(
          2, "spidarcad: error: --trajectory " + options.trajectory +
                 ": it runs from t = " + FormatNumber(s.trajectory.start_time()) +
                 " s to t = " + FormatNumber(s.trajectory.end_time()) +
                 " s; the window plays trajectories in real time, up to 1 day (86400 s): "
                 "shorten it, or run it headless with `spidarcad run`");
    }
    const haptics::TrajectorySample first = s.trajectory.Sample(s.trajectory.start_time());
    s.grip->SetPose(first.p_DT, first.q_DT.toRotationMatrix(), first.grasp);
  }
  const bool virtual_clock = options.clock == "virtual";
  if (virtual_clock && (options.trajectory.empty() || options.out.empty())) {
    throw WindowStartError(2,
                           "spidarcad: error: --clock virtual: needs --trajectory T.csv and "
                           "--out R.csv (the run's trajectory and its CSV)");
  }
  if (virtual_clock && options.device == "usb") {
    throw WindowStartError(2,
                           "spidarcad: error: --clock virtual: not with --device usb (a real "
                           "board runs in real time); use simulated, ideal or board-sim");
  }
  if (!virtual_clock && !options.out.empty()) {
    throw WindowStartError(2, "spidarcad: error: --out: only with --clock virtual (the run's CSV)");
  }
  if (virtual_clock && !options.set_fields.empty()) {
    throw WindowStartError(2,
                           "spidarcad: error: --set: not with --clock virtual (the run is built "
                           "from the file as saved, as `spidarcad run` builds it)");
  }
  // The recent list and the autosaver; a recovery file newer than the document is recovered
  // (--recover), deleted (--no-recover) or offered in the window (not in --screenshot runs).
  s.recent = std::make_unique<RecentFiles>();
  s.recent->Load();
  ResetAutosaver();
  // On the virtual clock, SCENE means what it means to `spidarcad run`: 'demo' is run's demo
  // fields (the window shows no document then), the file as saved (no recovery offered).
  const std::string source = DefaultSceneFor(options);
  FindRecoveryOffer(source);
  if (virtual_clock) s.recovery_offer.reset();
  std::string load_from = source;
  std::optional<std::string> recovered_original;
  if (s.recovery_offer && options.recover == 1) {
    load_from = s.recovery_offer->path.string();
    recovered_original = s.recovery_offer->original;
    s.recovery_offer.reset();
  } else if (s.recovery_offer && options.recover == 0) {
    std::error_code ec;
    std::filesystem::remove(s.recovery_offer->path, ec);
    s.recovery_offer.reset();
  } else if (s.recovery_offer && !options.screenshot.empty()) {
    s.recovery_offer.reset();  // a screenshot never asks; the file stays for the next start
  }
  s.recovery_popup_requested = s.recovery_offer.has_value();
  // An assembly scene (one with `parts`) keeps X_WD = identity, as `spidarcad run` does, so that
  // one trajectory file works in both.
  // The document is read on a thread of its own while the window opens and shows the
  // "Opening FILE" box; its Cancel starts the window on an empty document instead (a scripted
  // run on the virtual clock, which needs its document, ends). Without a display the document
  // is read first, and the display's error comes after every check of the document and the
  // options, as before.
  s.capture = !options.screenshot.empty();
  bool startup_cancelled = false;
  {
    OpenThread reading(virtual_clock && load_from == kDemoSceneName ? kNoSceneName : load_from);
    OpenWindow();
    if (s.window_open && !WaitForOpen(load_from, reading.work.get())) {
      if (virtual_clock) {
        throw WindowStartError(1, "spidarcad: opening " + load_from + " was cancelled");
      }
      s.cancelled_opens.push_back(std::move(reading.thread));  // ends on its own
      startup_cancelled = true;
    } else {
      reading.thread.join();
    }
    const DeviceToWorld identity;
    try {
      if (startup_cancelled) {
        s.model.Load(kNoSceneName, s.grip->limits());
        load_from = kNoSceneName;
        recovered_original.reset();
        s.workbench.status = "opening " + source + ": cancelled (an empty document instead)";
      } else {
        OpenWork& work = *reading.work;
        if (work.failure) std::rethrow_exception(work.failure);
        const bool assembly = work.prepared.assembly;
        s.model.Adopt(std::move(work.prepared), s.grip->limits(), assembly ? &identity : nullptr);
      }
    } catch (const std::exception& e) {
      throw WindowStartError(2, std::string("spidarcad: error: scene: ") + e.what());
    }
  }
  if (virtual_clock) {
    // The scripted run, on the document just opened (before the window adopts a version 1
    // assembly's parts), with `run`'s options; the view takes its X_WD.
    ScriptedRunOptions run = options.run;
    run.scene = load_from == kNoSceneName ? "" : load_from;
    run.trajectory = options.trajectory;
    run.device = options.device;
    run.seed = options.seed;
    run.geometry = options.geometry;
    run.geometry_given = options.geometry_given;
    run.calibration = options.calibration;
    run.place = options.place;  // the run models by touch; the window shows its ghost
    const bool file = !(run.scene.empty() || run.scene == kDemoSceneName);
    try {
      s.scripted =
          std::make_unique<VirtualClock>(run, file ? &s.model.document() : nullptr, options.out);
    } catch (const InputError& e) {
      throw WindowStartError(2, std::string("spidarcad: error: ") + e.what());
    }
    s.model.set_device_to_world(s.scripted->run().X_WD());
  }
  try {
    AdoptParts(&s.model);
  } catch (const std::exception& e) {
    throw WindowStartError(2, std::string("spidarcad: error: scene: ") + e.what());
  }
  if (recovered_original) {
    s.model.document().MarkRecovered(*recovered_original);
    s.recovered_file = load_from;
    std::cerr << "spidarcad: recovered unsaved work from " << load_from << "\n";
  }
  // The tree panel's controller on the model's Document; the first solid selected, or --select.
  s.tree = std::make_unique<TreeController>(&s.model);
  // Undo and redo wait while the active mode holds a gesture (a carried part, a sculpt stroke).
  s.tree->set_history_hold(
      [this] { return s_->active != nullptr ? s_->active->HistoryHold() : std::string(); });
  if (!options.select.empty() && !startup_cancelled) {
    if (!s.tree->SelectByName(options.select)) {
      throw WindowStartError(2, "spidarcad: error: --select: " + NoSuchNodeText(options.select));
    }
  } else if (!s.model.objects().empty()) {
    s.tree->Select(s.model.objects().front().id);
  }
  if (!startup_cancelled) ApplySetEdits();  // --set edits the document that was asked for
  // Scripted runs leave the start-up document out of the recent list.
  if (options.frames > 0 || !options.screenshot.empty()) {
    s.recorded_path = s.model.document().file_path();
  }
  if (!ParseRuntimeDevice(options.device, &s.runtime_settings.device)) {
    throw WindowStartError(2, "spidarcad: error: --device: '" + options.device +
                                  "' is not a device; use simulated, ideal, board-sim or usb");
  }
  s.runtime_settings.seed = options.seed;
  // The frame: --frame/--pole (recorded in the document, so that saving keeps it), else the
  // start-up document's own ("device"), else the paper's.
  s.runtime_settings.geometry = options.geometry;
  if (options.geometry_given) {
    s.model.document().set_device(options.geometry);
  } else if (s.model.document().device()) {
    s.runtime_settings.geometry = *s.model.document().device();
  }
  s.runtime_settings.calibration_file = options.calibration;
  s.runtime_settings.usb_transport = options.usb_transport;
  if (s.scripted) {
    // The scripted run has the device; the window's runtime only lends the view its geometry
    // and is never started.
    s.runtime_settings.device = RuntimeDevice::kIdeal;
    s.runtime_settings.calibration_file.clear();
  }
  try {
    s.runtime_settings.geometry.Validate();
  } catch (const std::invalid_argument& e) {
    throw WindowStartError(2, std::string("spidarcad: error: --frame/--pole: ") + e.what());
  }

  // The window (opened by OpenWindow while the document was read).
  if (!s.window_open) {
    throw WindowStartError(1,
                           "spidarcad: cannot initialise GLFW (no display?). Run under "
                           "`xvfb-run -a spidarcad` or use the headless subcommands.");
  }

  // The haptic runtime (its own 1 kHz thread, started once the modes have published) and jobs.
  try {
    MakeRuntime();
  } catch (const InputError& e) {  // a bad --calibration file
    throw WindowStartError(2, std::string("spidarcad: error: ") + e.what());
  }
  const haptics::TensionSettings& tension = s.runtime->loop().settings().tension;
  s.jobs = std::make_unique<JobQueue>();
  s.model.StartPreviewJobs(s.jobs.get());

  // VTK in the GLFW context.
  s.view = std::make_unique<DeviceView>(*s.geometry, tension.tau_min, tension.tau_max);
  s.render_window = vtkSmartPointer<vtkGenericOpenGLRenderWindow>::New();
  glfwGetFramebufferSize(s.window, &s.fb_w, &s.fb_h);
  s.render_window->SetSize(s.fb_w, s.fb_h);
  s.make_current->SetCallback(OnMakeCurrent);
  s.make_current->SetClientData(s.window);
  s.render_window->AddObserver(vtkCommand::WindowMakeCurrentEvent, s.make_current);
  s.is_current->SetCallback(OnIsCurrent);
  s.is_current->SetClientData(s.window);
  s.render_window->AddObserver(vtkCommand::WindowIsCurrentEvent, s.is_current);
  if (!s.render_window->InitializeFromCurrentContext()) {
    throw WindowStartError(1,
                           "spidarcad: VTK cannot use the window's OpenGL context (needs "
                           "OpenGL 3.2)");
  }
  s.render_window->SetFrameBlitModeToBlitToCurrent();
  s.render_window->AddRenderer(s.view->renderer());
  s.scene_view = std::make_unique<SceneView>(s.view->renderer());

  try {
    MakeModes();
  } catch (const std::exception& e) {
    throw WindowStartError(2, std::string("spidarcad: error: scene: ") + e.what());
  }

  // The figures strip starts open in windows at least kFiguresOpenHeight tall (the default
  // 1280x800); in smaller ones it starts collapsed so that the viewport keeps its height.
  s.workbench.show_figures = options.height >= kFiguresOpenHeight;

  s.context.model = &s.model;
  s.context.jobs = s.jobs.get();
  s.context.tree = s.tree.get();
  s.context.workbench = &s.workbench;

  // The starting mode: --mode, else the base mode (assembly for a scene with parts, else
  // modelling). Then the first scene, and the loop starts.
  StartScene(options.mode);
  // --place KIND: the ghost of that primitive follows the grip from the first frame. On the
  // virtual clock the scripted run places (ScriptedRunOptions::place); the mode shows its ghost.
  if (s.scripted) {
    s.model_mode->ShowScriptedTouch(s.scripted->run().touch());
  } else if (place) {
    s.model_mode->SetPlacing(*place);
  }

  // --trajectory: played into the hand's target from here on (its own thread, 1 kHz); the main
  // thread takes the target back (the mouse's grip, set to the last sample) once it has ended.
  if (!s.trajectory.empty() && !s.scripted) {
    const double d = s.geometry->d;
    HapticRuntime* runtime = s.runtime.get();
    s.player = std::make_unique<TrajectoryPlayer>(
        s.trajectory, [runtime, d](const haptics::TrajectorySample& sample) {
          runtime->SetTarget(haptics::GripPose::FromFrame(
              sample.p_DT, sample.q_DT.toRotationMatrix(), sample.grasp, d));
        });
    s.player->Start();
  }
  s.player_live = s.player != nullptr;
  // --show open / import: the file browser is up from the first frame.
  const std::string& current = s.model.document().file_path();
  if (options.show == "open") {
    OpenFileBrowser(&s.open_browser, BrowseFilter::kDocuments, "Open", current);
  } else if (options.show == "import") {
    OpenFileBrowser(&s.import_browser, BrowseFilter::kMeshes, "Import", current);
  }
  // --show calibrate: the wizard collects at once, waving the simulated grip itself.
  if (options.show == "calibrate") {
    s.calibration.Open();
    s.calibration.set_auto_wave(true);
    s.calibration.Start();
  }
  s.start_time = glfwGetTime();
  s.last_frame = s.capture ? std::max(kScreenshotFrames, options.frames) : options.frames;
}

AppWindow::~AppWindow() {
  State& s = *s_;
  for (std::thread& t : s.cancelled_opens) t.join();
  s.cancelled_opens.clear();
  if (s.player) s.player->Stop();
  s.player.reset();
  s.calibration.Attach(nullptr);
  if (s.runtime) s.runtime->Stop();
  s.imgui.reset();
  s.modes.clear();
  s.scene_view.reset();
  s.render_window = nullptr;
  s.view.reset();
  s.jobs.reset();
  s.runtime.reset();
  if (s.window != nullptr) glfwDestroyWindow(s.window);
  s.glfw.reset();
}

int AppWindow::Run() {
  State& s = *s_;
  while (Frame()) {
  }
  s.runtime->Stop();
  if (s.scripted && !s.scripted->finished() && s.exit_status == 0) {
    // Closed before the trajectory's end: no CSV (the temporary goes with the run).
    std::cerr << "spidarcad: --clock virtual: the window closed after "
              << s.scripted->run().ticks_done() << " of " << s.scripted->run().ticks() << " ticks; "
              << s.options.out << " not written\n";
    s.exit_status = 1;
    s.print_summary = false;
  }
  // A normal end (Quit answered, or a scripted run's last frame): this session's autosave goes.
  DiscardRecovery();
  if ((s.capture || s.options.frames > 0) && s.print_summary) {
    const haptics::ToolState tool = s.runtime->Latest().tool;
    std::cout << FormatLoopSummary(CollectLoopStats(*s.runtime, s.runtime->Latest()));
    for (auto& m : s.modes) std::cout << m->Summary(tool);
    std::cout << std::flush;
  }
  return s.exit_status;
}

bool AppWindow::Frame() {
  State& s = *s_;
  if (s.done || s.quit) return false;
  glfwPollEvents();                       // files dropped on the window arrive here (OnDrop)
  if (glfwWindowShouldClose(s.window)) {  // the close button: as Quit (asks when unsaved)
    glfwSetWindowShouldClose(s.window, GLFW_FALSE);
    RequestQuit();
  }
  RunPendingAction();  // New, Open, Quit once answered (or with nothing unsaved)
  if (s.quit) return false;
  ++s.frame_index;
  // The scene file changed on disk: read again off this thread (outside an ImGui frame, as
  // the wait draws frames of its own).
  if (s.frame_index % kReloadCheckFrames == 0 && !s.scripted && s.model.SourceChanged()) {
    ReloadSource();
  }
  if (!ReadWindowSize()) {  // minimised
    glfwWaitEvents();
    return true;
  }
  UpdateLayout();
  if (s.fit_pending) {  // the first frame: the viewport's aspect is known now
    s.fit_pending = false;
    Eigen::AlignedBox3d box = SubjectBox(s.model, -1, false, *s.view);
    const Eigen::Vector3d reach = Eigen::Vector3d::Constant(1.2 * s.geometry->d);
    box.extend(s.grip->p0() + reach);
    box.extend(s.grip->p0() - reach);
    s.view->FitBox(box);
  }

  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplGlfw_NewFrame();
  if (s.options.show == "file-menu" && s.frame_index >= 2) {
    // --show file-menu: a click on "File" at the second frame; the pointer stays over the menu.
    ImGuiIO& io = ImGui::GetIO();
    io.MousePos = ImVec2(ImGui::GetStyle().FramePadding.x + 12.0f, 0.5f * s.menu_height);
    io.MouseDown[0] = s.frame_index == 2;
  }
  ImGui::NewFrame();
  s.frame_height = ImGui::GetFrameHeight();

  s.actions = WorkbenchActions{};
  HandleInput();
  if (s.options.estop_frame > 0 && s.frame_index == s.options.estop_frame) {
    s.runtime->EmergencyStop();
    if (s.scripted) s.scripted->EmergencyStop(true);
  }
  FollowTarget();
  s.latest = s.scripted ? s.scripted->run().frame() : s.runtime->Latest();
  s.calibration.Update();
  s.device_frame = MakeDeviceFrame(
      s.latest, *s.geometry,
      s.scripted ? std::string("scripted run (virtual clock)") : s.runtime->description());
  s.view->Update(s.device_frame);
  PollJobs();
  // In model mode a mesh made from a solid, selected in the tree, is drawn in its solid's place.
  ObjectId shown_mesh = 0;
  if (s.active == s.model_mode && s.tree->selection()) {
    const DocObject* o = s.model.document().Find(s.tree->selection()->object);
    const auto* m = o != nullptr ? std::get_if<MeshData>(&o->data) : nullptr;
    if (m != nullptr && m->source != 0) shown_mesh = o->id;
  }
  s.scene_view->SetShownMesh(shown_mesh);
  s.scene_view->Sync(s.model, s.workbench.show_edges ? s.workbench.selected : -1);
  s.scene_view->ShowContacts(s.model.ContactMarkers(), s.latest.tool.time,
                             s.model.device_to_world());

  if (s.frame_index % kReloadCheckFrames == 1 ||
      s.recent_entries.size() != s.recent->paths().size() ||
      (!s.recent_entries.empty() && s.recent_entries[0].path != s.recent->paths()[0])) {
    s.recent_entries = s.recent->Entries();  // a few stat calls: not every frame
  }
  s.menu_height = DrawMenuBar(&s.model, s.jobs.get(), &s.workbench, &s.actions, s.tree.get(),
                              &s.tree_state, &s.recent_entries);
  UpdateModes();
  DrawPanels();
  {  // The calibration wizard over the view's top left (and the panels right of it if need be).
    const float width = std::min(600.0f, static_cast<float>(s.win_w) - 16.0f);
    const float x = std::max(8.0f, std::min(s.layout.viewport.x + 8.0f, s.win_w - width - 8.0f));
    s.calibration.Draw(x, s.layout.viewport.y + 8.0f, width);
  }
  s.calibration_idle = s.calibration.busy() ? 0 : s.calibration_idle + 1;
  if (s.calibration.TakeRepublish()) s.republish = true;  // Use now rebuilt the loop
  // Tree edits, undo and redo: recompile what changed, republish the haptic scene (X_WD stays),
  // re-mesh the previews (coarse first).
  HandleTreeShortcuts(s.tree.get(), &s.tree_state);
  DrawFileDialogs();
  DrawSaveAsDialog(s.tree.get(), &s.tree_state);
  if (s.pending_after_save_as) {  // Save As asked for by the unsaved-changes question
    if (!s.model.document().dirty()) {
      s.pending_after_save_as = false;
      s.pending_ready = true;
    } else if (!s.tree_state.open_save_as && !ImGui::IsPopupOpen("Save As")) {
      s.pending_after_save_as = false;  // cancelled: so is the action
      s.pending_kind = kPendingNone;
    }
  }
  if (s.model.Refresh()) s.republish = true;
  if (s.workbench.contact_changed) {  // the Touch controls (Haptics menu)
    s.workbench.contact_changed = false;
    s.republish = true;
  }
  if (s.republish) PublishScene();
  s.model.UpdatePreviews(s.jobs.get());
  UpdateAutosave();
  // A document saved under a new name (Save As) goes first in the recent list.
  if (const std::string& path = s.model.document().file_path();
      path != s.recorded_path && !s.model.document().dirty()) {
    s.recorded_path = path;
    if (!path.empty()) {
      s.recent->Add(path);
      if (const std::string error = s.recent->Save(); !error.empty()) {
        std::cerr << "spidarcad: " << error << "\n";
      }
    }
  }
  if (const std::string title = s.tree->Title(); title != s.window_title) {
    glfwSetWindowTitle(s.window, title.c_str());
    s.window_title = title;
  }
  if (s.stats.emergency_stop) {
    DrawStopBanner(s.layout.viewport.x, s.layout.viewport.right(), s.layout.viewport.y + 10.0f);
  }
  DrawExportDialog(s.model, &s.workbench);
  ApplyActions();
  ImGui::Render();
  RenderFrame();
  if (s.scripted && s.scripted->done() && !s.scripted->finished()) {
    // The run's last tick is drawn: its CSV and summary, then the screenshot (if any) and exit.
    try {
      s.scripted->Finish(&std::cout);
      std::cout << std::flush;
    } catch (const InputError& e) {
      std::cerr << "spidarcad: error: " << e.what() << "\n";
      s.exit_status = 2;
    }
    s.print_summary = false;
    s.scripted_end_frame = s.frame_index;
    if (!s.capture) s.done = true;
  }
  if (CaptureScreenshot()) return false;
  if (s.done) return false;
  glfwSwapBuffers(s.window);
  // --frames: at least until a trajectory has ended; on the virtual clock the run's end decides.
  const bool trajectory_over = (s.player == nullptr || s.player->finished(0.5)) && !s.scripted;
  if (!s.capture && s.last_frame > 0 && s.frame_index >= s.last_frame && trajectory_over) {
    return false;
  }
  return !s.quit;
}

void AppWindow::HandleInput() {
  State& s = *s_;
  ImGuiIO& io = ImGui::GetIO();
  GripControl& grip = *s.grip;
  DeviceView& view = *s.view;
  const double sx = static_cast<double>(s.fb_w) / s.win_w;
  const double sy = static_cast<double>(s.fb_h) / s.win_h;
  // Mouse in the 3D view (display pixels, origin bottom left).
  const ImVec2 mouse = io.MousePos;
  const double mx = mouse.x * sx, my = s.fb_h - mouse.y * sy;
  const bool in_view = !io.WantCaptureMouse && std::isfinite(mouse.x) &&
                       s.layout.viewport.Contains(mouse.x, mouse.y);
  bool over_grip = false;
  if (in_view) {
    double distance = 0;
    over_grip =
        IntersectRaySphere(view.PickRay(mx, my), grip.p0(), 1.15 * s.geometry->d, &distance);
  }
  if (s.drag == DragMode::kNone && in_view) {
    if (ImGui::IsMouseClicked(ImGuiMouseButton_Left)) {
      if (io.KeyCtrl) {
        s.drag = io.KeyShift ? DragMode::kRollGrip : DragMode::kRotateGrip;
      } else if (over_grip && grip.BeginTranslate(view.PickRay(mx, my), view.ViewDirection())) {
        s.drag = DragMode::kMoveGrip;
      } else {
        s.drag = DragMode::kOrbit;  // a click without travel selects (below)
        s.press = mouse;
        s.press_travel = 0.0;
      }
    } else if (ImGui::IsMouseClicked(ImGuiMouseButton_Right)) {
      s.drag = io.KeyShift ? DragMode::kRollGrip : DragMode::kRotateGrip;
    } else if (ImGui::IsMouseClicked(ImGuiMouseButton_Middle)) {
      s.drag = DragMode::kOrbit;
      s.press_travel = 1e9;  // never a selection click
    }
  }
  const double dx = io.MouseDelta.x, dy = io.MouseDelta.y;  // screen pixels, y down
  const bool moved = std::isfinite(dx) && std::isfinite(dy) && (dx != 0.0 || dy != 0.0);
  if (s.drag != DragMode::kNone && !ImGui::IsMouseDown(ImGuiMouseButton_Left) &&
      !ImGui::IsMouseDown(ImGuiMouseButton_Right) && !ImGui::IsMouseDown(ImGuiMouseButton_Middle)) {
    if (s.drag == DragMode::kOrbit && s.press_travel <= kClickSlop) ClickAt(s.press.x, s.press.y);
    s.drag = DragMode::kNone;
    grip.EndTranslate();
  }
  if (moved) {
    s.press_travel += std::hypot(dx, dy);
    switch (s.drag) {
      case DragMode::kMoveGrip:
        grip.Translate(view.PickRay(mx, my));
        break;
      case DragMode::kRotateGrip:
        // Dragging right turns the near side of the grip right; dragging down turns it down.
        grip.Rotate(view.ViewUp(), kRotateGain * dx);
        grip.Rotate(view.ViewRight(), kRotateGain * dy);
        break;
      case DragMode::kRollGrip:
        grip.Rotate(-view.ViewDirection(), -kRotateGain * dx);
        break;
      case DragMode::kOrbit:
        // A small wobble of a click does not turn the view.
        if (s.press_travel > kClickSlop) view.Orbit(-kOrbitGain * dx, kOrbitGain * dy);
        break;
      case DragMode::kNone:
        break;
    }
  }
  if (in_view && io.MouseWheel != 0.0f) {
    if (io.KeyCtrl) {
      view.Zoom(std::pow(1.1, io.MouseWheel));
    } else {
      grip.AdjustGrasp(kGraspStep * io.MouseWheel);
    }
  }
  if (over_grip || s.drag == DragMode::kMoveGrip) ImGui::SetMouseCursor(ImGuiMouseCursor_Hand);
  s.select_key = false;
  if (!io.WantCaptureKeyboard) {
    if (ImGui::IsKeyPressed(GLFW_KEY_ESCAPE, false) &&
        !ImGui::IsPopupOpen("", ImGuiPopupFlags_AnyPopupId)) {
      RequestQuit();
    }
    if (io.KeyCtrl && ImGui::IsKeyPressed(GLFW_KEY_N, false)) s.actions.file_new = true;
    if (io.KeyCtrl && ImGui::IsKeyPressed(GLFW_KEY_O, false)) s.actions.file_open = true;
    if (io.KeyCtrl && ImGui::IsKeyPressed(GLFW_KEY_I, false)) s.actions.file_import = true;
    if (ImGui::IsKeyPressed(GLFW_KEY_SPACE, false)) {
      s.runtime->EmergencyStop();
      if (s.scripted) s.scripted->EmergencyStop(true);
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_LEFT_BRACKET)) grip.AdjustGrasp(-kGraspStep);
    if (ImGui::IsKeyPressed(GLFW_KEY_RIGHT_BRACKET)) grip.AdjustGrasp(kGraspStep);
    if (ImGui::IsKeyPressed(GLFW_KEY_R, false) && !io.KeyCtrl) grip.Reset();
    if (ImGui::IsKeyPressed(GLFW_KEY_C, false) && !io.KeyCtrl) view.ResetCamera();  // Ctrl+C: copy
    if (ImGui::IsKeyPressed(GLFW_KEY_F, false) && !io.KeyCtrl) s.actions.fit_view = true;
    const int view_keys[4][2] = {{GLFW_KEY_1, GLFW_KEY_KP_1},
                                 {GLFW_KEY_3, GLFW_KEY_KP_3},
                                 {GLFW_KEY_7, GLFW_KEY_KP_7},
                                 {GLFW_KEY_0, GLFW_KEY_KP_0}};
    for (int k = 0; k < 4; ++k) {
      if (ImGui::IsKeyPressed(view_keys[k][0], false) ||
          ImGui::IsKeyPressed(view_keys[k][1], false)) {
        s.actions.standard_view = k;
      }
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_ENTER, false) ||
        ImGui::IsKeyPressed(GLFW_KEY_KP_ENTER, false)) {
      s.select_key = true;
    }
    if (ImGui::IsKeyPressed(GLFW_KEY_P, false) && !io.KeyCtrl) s.place_key = true;
    if (ImGui::IsKeyPressed(GLFW_KEY_G, false) && !io.KeyCtrl) s.grab_key = true;
    if (ImGui::IsKeyPressed(GLFW_KEY_EQUAL) || ImGui::IsKeyPressed(GLFW_KEY_KP_ADD)) view.Zoom(1.1);
    if (ImGui::IsKeyPressed(GLFW_KEY_MINUS) || ImGui::IsKeyPressed(GLFW_KEY_KP_SUBTRACT)) {
      view.Zoom(1.0 / 1.1);
    }
  }
}

void AppWindow::FollowTarget() {
  State& s = *s_;
  if (s.scripted) {
    // The virtual clock: the scripted run's next ticks; the grip is drawn where its hand is.
    if (!s.scripted->done()) {
      try {
        s.scripted->StepFrame();
      } catch (const InputError& e) {
        std::cerr << "spidarcad: error: " << e.what() << "\n";
        s.exit_status = 2;
        s.print_summary = false;
        s.done = true;
      }
    }
    const haptics::GripPose& hand = s.scripted->run().frame().hand_pose;
    s.grip->SetPose(hand.p0, hand.Rotation(), hand.Grasp());
    return;
  }
  // The hand follows the mouse's grip (or the trajectory); the haptic thread's latest tick is
  // what we show.
  const auto wave = s.player_live ? std::nullopt : s.calibration.WaveTarget(s.latest.tool.time);
  if (wave) {  // the calibration wizard waves the simulated grip
    s.grip->SetPose(wave->p_DT, wave->q_DT.toRotationMatrix(), wave->grasp);
    s.runtime->SetTarget(s.grip->Pose());
  } else if (s.player_live) {
    const haptics::TrajectorySample sample = s.player->Current();
    s.grip->SetPose(sample.p_DT, sample.q_DT.toRotationMatrix(), sample.grasp);  // picking, panel
    if (s.player->done()) {
      s.player->Stop();
      s.player_live = false;
    }
  } else {
    s.runtime->SetTarget(s.grip->Pose());
  }
}

void AppWindow::PollJobs() {
  State& s = *s_;
  // Jobs: finishers land their meshes; outcomes go to the status line.
  s.jobs->Poll();
  for (const auto& job : s.jobs->jobs()) {
    switch (job->state()) {
      case Job::State::kSucceeded:
        s.workbench.status = job->title() + ": done";
        s.workbench.status_error = false;
        break;
      case Job::State::kFailed:
        s.workbench.status = job->title() + " failed: " + job->error() + " (nothing changed)";
        s.workbench.status_error = true;
        break;
      case Job::State::kCancelled:
        s.workbench.status = job->title() + ": cancelled (nothing changed)";
        s.workbench.status_error = false;
        break;
      case Job::State::kRunning:
        break;
    }
  }
  s.jobs->Prune();
}

void AppWindow::UpdateModes() {
  State& s = *s_;
  s.context.select_key = s.select_key;
  s.context.place_key = std::exchange(s.place_key, false);
  s.context.grab_key = std::exchange(s.grab_key, false);
  bool changed = false;
  for (auto& m : s.modes) {
    m->Update(s.latest.tool, s.context);
    changed |= m->TakeSceneChanged();
  }
  // A mode's new field may come with its own drawing of the objects it acts on (FE's surface).
  if (changed) {
    s.republish = true;
    ApplyHidden();
  }
  s.select_key = false;
  s.context.select_key = false;
  s.context.place_key = s.context.grab_key = false;
}

void AppWindow::DrawPanels() {
  State& s = *s_;
  const Rect& l = s.layout.left;
  DrawScenePanel(&s.model, s.jobs.get(), &s.workbench, l.x, l.y, l.w, l.h, s.tree.get(),
                 &s.tree_state);
  DrawModePanel();
  DrawFiguresStrip();
}

void AppWindow::DrawModePanel() {
  State& s = *s_;
  const Rect& r = s.layout.right;
  ImGui::SetNextWindowPos(ImVec2(r.x, r.y));
  ImGui::SetNextWindowSize(ImVec2(r.w, r.h));
  const ImGuiWindowFlags flags = ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize |
                                 ImGuiWindowFlags_NoCollapse | ImGuiWindowFlags_NoSavedSettings |
                                 ImGuiWindowFlags_NoTitleBar;
  ImGui::Begin(kModePanel, nullptr, flags);
  // The mode switcher: one radio button per mode this scene offers.
  ImGui::TextUnformatted("Mode");
  Mode* chosen = nullptr;
  const ImGuiStyle& style = ImGui::GetStyle();
  const float right_edge = ImGui::GetWindowPos().x + ImGui::GetWindowContentRegionMax().x;
  for (auto& m : s.modes) {
    if (!m->available()) continue;
    // On the same line while it fits, else on the next.
    const float width =
        ImGui::GetFrameHeight() + style.ItemInnerSpacing.x + ImGui::CalcTextSize(m->name()).x;
    if (ImGui::GetItemRectMax().x + style.ItemSpacing.x + width <= right_edge) ImGui::SameLine();
    if (ImGui::RadioButton(m->name(), m.get() == s.active)) chosen = m.get();
  }
  if (chosen != nullptr && chosen != s.active) SwitchMode(chosen);
  const std::vector<std::string> targets = s.active->Targets(s.model);
  if (!targets.empty()) {
    std::string text = "acts on:";
    for (size_t i = 0; i < targets.size(); ++i) text += (i ? ", '" : " '") + targets[i] + "'";
    ImGui::PushTextWrapPos(0.0f);
    ImGui::TextDisabled("%s", text.c_str());
    ImGui::PopTextWrapPos();
  }
  if (!s.active->live() && s.active != s.model_mode) {
    ImGui::TextDisabled("(no part yet: the scene's solids are felt)");
  }
  ImGui::Separator();
  ImGui::PushItemWidth(0.5f * r.w);  // room for the labels right of the widgets
  s.active->DrawPanel(s.context);
  ImGui::PopItemWidth();
  ImGui::End();
  // A mode asked for another (e.g. sculpt's "Send to FE").
  if (!s.context.switch_to.empty()) {
    Mode* next = FindMode(s.context.switch_to);
    s.context.switch_to.clear();
    if (next != nullptr && next->available() && next != s.active) SwitchMode(next);
  }
}

void AppWindow::DrawFiguresStrip() {
  State& s = *s_;
  const Rect& b = s.layout.bottom;
  ImGui::SetNextWindowPos(ImVec2(b.x, b.y));
  ImGui::SetNextWindowSize(ImVec2(b.w, std::max(b.h, s.frame_height)));
  if (s.figures_applied != s.workbench.show_figures) {  // View menu toggled it
    ImGui::SetNextWindowCollapsed(!s.workbench.show_figures);
  }
  const ImGuiWindowFlags flags = ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize |
                                 ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoScrollbar;
  const bool open = ImGui::Begin(kFiguresPanel, nullptr, flags);
  s.workbench.show_figures = !ImGui::IsWindowCollapsed();
  s.figures_applied = s.workbench.show_figures;
  s.stats = CollectLoopStats(*s.runtime, s.latest);
  if (s.scripted) {  // the virtual clock: the scripted run's loop, not the idle runtime's
    s.stats.ticks = static_cast<std::uint64_t>(s.scripted->run().ticks_done());
    s.stats.events = s.scripted->run().loop().event_counts();
  }
  s.panel_actions = PanelActions{};
  if (open) {
    PanelContext context;
    context.geometry = s.geometry;
    context.tau_min = s.runtime->loop().settings().tension.tau_min;
    context.tau_max = s.runtime->loop().settings().tension.tau_max;
    context.fps = ImGui::GetIO().Framerate;
    context.drag_mode = DragModeText(s.drag);
    context.link = &s.latest.link;
    context.real_hand = s.runtime_settings.device == RuntimeDevice::kUsb;
    context.board_sim = s.runtime_settings.device == RuntimeDevice::kBoardSim;
    // Three columns under the three panels above: strings, device figures, loop figures.
    const float top = ImGui::GetCursorScreenPos().y;
    const float height = b.bottom() - top - 4.0f;
    const Rect columns[3] = {s.layout.left, s.layout.viewport, s.layout.right};
    const char* names[3] = {"strings", "device", "loop"};
    for (int k = 0; k < 3; ++k) {
      ImGui::SetCursorScreenPos(ImVec2(columns[k].x + 6.0f, top));
      const float width = columns[k].w - 12.0f;
      ImGui::BeginChild(names[k], ImVec2(width, height), false);
      if (k == 0) DrawStringFigures(s.device_frame, context, width);
      if (k == 1) s.panel_actions = DrawDeviceFigures(s.device_frame, context);
      if (k == 2) DrawLoopFigures(s.stats, &s.actions);
      ImGui::EndChild();
    }
  }
  ImGui::End();
}

void AppWindow::ApplyActions() {
  State& s = *s_;
  const PanelActions& p = s.panel_actions;
  WorkbenchActions& w = s.actions;
  if (p.field_changed) s.republish = true;
  if (p.reset_grip || w.reset_grip) s.grip->Reset();
  if (p.board_plug != 0) s.runtime->RequestBoardPlugged(p.board_plug > 0);
  if (p.reset_camera || w.reset_camera) s.view->ResetCamera();
  if (w.fit_view) FitView();
  if (w.standard_view >= 0 && w.standard_view < 4) {
    s.view->SetStandardView(static_cast<StandardView>(w.standard_view),
                            SubjectBox(s.model, s.workbench.selected, false, *s.view));
  }
  if (p.quit || w.quit) RequestQuit();
  if (w.file_new) RequestNew();
  const std::string& current = s.model.document().file_path();
  if (w.file_open) {
    OpenFileBrowser(&s.open_browser, BrowseFilter::kDocuments, "Open",
                    current.empty() ? std::filesystem::path() : std::filesystem::path(current));
  }
  if (w.file_import) {
    OpenFileBrowser(&s.import_browser, BrowseFilter::kMeshes, "Import",
                    current.empty() ? std::filesystem::path() : std::filesystem::path(current));
  }
  if (!w.open_recent.empty()) RequestOpen(w.open_recent);
  if (w.clear_recent) {
    for (const std::string& path : std::vector<std::string>(s.recent->paths())) {
      s.recent->Remove(path);
    }
    s.recent->Save();
  }
  if (w.calibrate) s.calibration.Open();
  if (w.emergency_stop) s.runtime->EmergencyStop();
  if (w.rearm) s.runtime->Rearm();
  if (s.scripted && (w.emergency_stop || w.rearm)) s.scripted->EmergencyStop(w.emergency_stop);
  if (s.republish) PublishScene();
}

void AppWindow::PublishScene() {
  State& s = *s_;
  s.republish = false;
  // The active mode's part, when live, stands in for the scene's solids; else the base mode's
  // (the assembly of a scene with parts, else the solids of the modelling mode).
  Mode* source = s.active->live() ? s.active : BaseMode();
  s.runtime->Publish(source->live() ? source->BuildScene(s.context)
                                    : std::make_unique<haptics::HapticScene>());
  ++s.publishes;
}

Mode* AppWindow::BaseMode() const {
  const State& s = *s_;
  // The assembly stands in for the scene's solids when the document has parts and no solids.
  const bool assembly = s.assembly_mode->available() && s.model.objects().empty();
  return assembly ? static_cast<Mode*>(s.assembly_mode) : s.model_mode;
}

void AppWindow::ApplyHidden() {
  State& s = *s_;
  std::vector<std::string> hidden;
  for (auto& m : s.modes) {
    if (!m->draws_targets() || !m->available()) continue;
    for (std::string& name : m->Targets(s.model)) hidden.push_back(std::move(name));
  }
  s.scene_view->SetHidden(std::move(hidden));
}

void AppWindow::FitView() {
  State& s = *s_;
  s.view->FitBox(SubjectBox(s.model, s.workbench.selected, true, *s.view));
}

void AppWindow::RenderFrame() {
  State& s = *s_;
  // VTK draws the scene into its viewport, then ImGui draws the panels around it.
  BindDefaultFramebuffer(s.fb_w, s.fb_h);
  ClearDefaultFramebuffer(0.965f, 0.968f, 0.975f);
  s.render_window->Render();
  BindDefaultFramebuffer(s.fb_w, s.fb_h);
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
}

bool AppWindow::CaptureScreenshot() {
  State& s = *s_;
  if (!s.capture || s.frame_index < s.last_frame) return false;
  // The virtual clock: the run's last frame (its jobs and modes are not what is felt).
  // One frame more, so that the modes show what the run's last strokes left in the document.
  if (s.scripted && (!s.scripted->finished() || s.frame_index <= s.scripted_end_frame))
    return false;
  // A screenshot waits (within kSettleTimeout) for the preview meshes to have landed (a job
  // that ended after this frame's poll has not: JobQueue::pending), for the modes' parts to
  // be live (Mode::Settled) and for the loop to settle: force ramp complete, or the stop's zero
  // force in effect.
  bool modes_settled = true;
  for (auto& m : s.modes) modes_settled = modes_settled && m->Settled();
  const haptics::ToolState& tool = s.latest.tool;
  const bool settled =
      !s.jobs->pending() && modes_settled && s.calibration_idle >= 3 &&
      (s.stats.emergency_stop ? (tool.events & haptics::kEventEmergencyStop) != 0
                              : tool.ramp >= 1.0 ||
                                    // no board: zero force is the settled state
                                    s.latest.link.status == haptics::DeviceStatus::kNotConnected);
  // A calibration session (--show calibrate) may take minutes: it is waited for longer.
  const double timeout = s.calibration.busy() ? kCalibrationTimeout : kSettleTimeout;
  const bool waited_enough = settled || s.scripted || glfwGetTime() - s.start_time > timeout;
  // A trajectory's outcome: the capture waits until it has ended (+0.5 s).
  const bool trajectory_over = s.player == nullptr || s.player->finished(0.5);
  if (!waited_enough || !trajectory_over) return false;
  const std::string error =
      WritePng(s.options.screenshot, ReadBackBuffer(s.fb_w, s.fb_h), s.fb_w, s.fb_h);
  s.done = true;
  if (!error.empty()) {
    std::cerr << "spidarcad: " << error << "\n";
    s.exit_status = 1;
    s.print_summary = false;
    return true;
  }
  std::cout << "spidarcad: wrote " << s.options.screenshot << " (" << s.fb_w << "x" << s.fb_h << ")"
            << (settled ? "" : " before the loop settled") << "\n";
  return true;
}

// ---- the document's lifecycle ----

void AppWindow::MakeRuntime() {
  State& s = *s_;
  s.runtime_settings.loop.X_WD = s.model.device_to_world();
  s.runtime = std::make_unique<HapticRuntime>(s.runtime_settings, s.grip->Pose());
  s.calibration.Attach(s.runtime.get());
  if (!s.runtime->link_at_start().empty()) {  // no board: the window runs at zero force, retrying
    std::cerr << "spidarcad: " << s.runtime->link_at_start()
              << "\nspidarcad: the window runs at zero force and retries the board.\n";
  }
  if (!s.runtime->calibration_note().empty()) {
    std::cerr << "spidarcad: " << s.runtime->calibration_note() << "\n";
  }
  s.geometry = &s.runtime->info().geometry;
  // With solids to touch, the springs would fight the contact: off unless the scene is empty.
  s.springs.enabled = s.model.objects().empty();
}

void AppWindow::MakeModes() {
  State& s = *s_;
  // The modes. Each may contribute force fields, kept across scene rebuilds through SharedField
  // so their state between ticks survives a republish. Modes added with AddMode stay after them.
  std::vector<std::unique_ptr<Mode>> added;
  for (size_t i = std::min<size_t>(kBuiltInModes, s.modes.size()); i < s.modes.size(); ++i) {
    added.push_back(std::move(s.modes[i]));
  }
  s.modes.clear();
  s.model_mode = nullptr;
  s.assembly_mode = nullptr;
  vtkRenderer* renderer = s.view->renderer();
  const DeviceToWorld& X_WD = s.runtime_settings.loop.X_WD;
  auto model_mode = std::make_unique<ModelMode>(renderer, &s.springs, s.geometry->d);
  model_mode->SetWorldToView(X_WD);
  auto fe = std::make_unique<FeWindowMode>(renderer, s.jobs.get());
  fe->fe().SetWorldToView(X_WD);
  auto sculpt = std::make_unique<SculptWindowMode>(renderer, s.jobs.get());
  sculpt->sculpt().SetWorldToView(X_WD);
  sculpt->sculpt().SetGripPoleLength(s.geometry->d);
  // The virtual clock: the scripted run sculpts; the mode draws the clay as the run leaves it.
  sculpt->sculpt().set_strokes_enabled(s.scripted == nullptr);
  // Assembly scenes: the parts are one AssemblyField, drawn by AssemblyMode where the field has
  // them; the SceneView's static actors of the part solids (at their frame origins) are hidden.
  auto assembly = std::make_unique<AssemblyWindowMode>(renderer);
  std::string assembly_error;
  try {
    assembly->assembly().LoadDocument(s.model.document());
  } catch (const std::exception& e) {
    assembly_error = e.what();
  }
  assembly->assembly().SetWorldToView(X_WD);
  s.model_mode = model_mode.get();
  s.assembly_mode = assembly.get();
  s.modes.push_back(std::move(model_mode));
  s.modes.push_back(std::move(fe));
  s.modes.push_back(std::move(sculpt));
  s.modes.push_back(std::move(assembly));
  for (auto& m : added) s.modes.push_back(std::move(m));
  s.model_mode->SetFelt(BaseMode() != s.assembly_mode);
  ApplyHidden();
  if (BaseMode() == s.assembly_mode) {
    s.view->Zoom(1.4);  // the robot is small (C: whole frame)
  } else {
    // A scene with solids opens fitted to them and the grip (C: the whole device).
    s.fit_pending = !s.model.objects().empty();
  }
  if (!assembly_error.empty()) throw std::runtime_error(assembly_error);
}

void AppWindow::StartScene(const std::string& mode_key) {
  State& s = *s_;
  Mode* start = FindMode(mode_key);
  if (start != nullptr && start != s.model_mode) {
    s.active = start;
    // On the virtual clock the run builds what is felt: the mode is entered without its demo
    // set-up (no FE precompute of its own).
    if (s.scripted) {
      start->Enter();
    } else {
      start->Launch();
    }
  } else {
    s.active = BaseMode();
    s.active->Enter();
  }
  for (auto& m : s.modes) m->TakeSceneChanged();
  PublishScene();
  if (!s.scripted) s.runtime->Start();
}

bool AppWindow::ReplaceDocument(const std::string& source, const std::string* recovered_original) {
  State& s = *s_;
  if (s.scripted) {  // the run acts on this document until its last tick
    s.file_error = "a scripted run on the virtual clock uses this document until it ends";
    s.file_error_popup = true;
    return false;
  }
  // Load first, off this thread (the window keeps drawing and can cancel): a file that fails
  // or is cancelled leaves the document, the loop and the modes as they were.
  const std::shared_ptr<OpenWork> work = ReadOffThread(source);
  if (work == nullptr) {
    s.workbench.status = "opening " + source + ": cancelled (the document is unchanged)";
    s.workbench.status_error = false;
    return false;
  }
  try {
    if (work->failure) std::rethrow_exception(work->failure);
    const DeviceToWorld identity;
    const bool assembly = work->prepared.assembly;
    s.model.Adopt(std::move(work->prepared), s.grip->limits(), assembly ? &identity : nullptr);
    AdoptParts(&s.model);
  } catch (const std::exception& e) {
    s.file_error = e.what();
    s.file_error_popup = true;
    s.workbench.status = "could not open " + source + " (the document is unchanged)";
    s.workbench.status_error = true;
    return false;
  }
  if (recovered_original != nullptr) {
    s.model.document().MarkRecovered(*recovered_original);
    s.recovered_file = source;
  }
  // Tear down what belonged to the old document: the trajectory (it drives the old loop), the
  // loop, the jobs (joined: no finisher runs), the modes and the scene's actors.
  if (s.player) s.player->Stop();
  s.player.reset();
  s.player_live = false;
  s.runtime->Stop();
  if (s.active != nullptr) s.active->Leave();  // FE mode may start a job as it leaves
  s.active = nullptr;
  s.jobs.reset();
  s.scene_view.reset();
  // Then the new document's: X_WD, loop, jobs, actors, modes (a fresh camera).
  s.calibration.Attach(nullptr);  // a calibration session on the old loop ends
  s.runtime.reset();
  MakeRuntime();
  s.jobs = std::make_unique<JobQueue>();
  s.context.jobs = s.jobs.get();
  s.scene_view = std::make_unique<SceneView>(s.view->renderer());
  s.view->ResetCamera();
  std::string assembly_error;
  try {
    MakeModes();
  } catch (const std::exception& e) {
    assembly_error = e.what();
  }
  s.tree->ClearSelection();
  if (!s.model.objects().empty()) s.tree->Select(s.model.objects().front().id);
  s.tree_state = TreePanelState{};
  s.workbench.selected = 0;
  s.model.StartPreviewJobs(s.jobs.get());
  StartScene("");
  s.file_error.clear();
  s.workbench.status = (recovered_original != nullptr ? "recovered " : "opened ") +
                       (source == kNoSceneName ? std::string("a new document") : source);
  s.workbench.status_error = false;
  if (!assembly_error.empty()) {
    s.workbench.status += " (assembly not available: " + assembly_error + ")";
    s.workbench.status_error = true;
  }
  // The device keeps the frame it started with; a document made for another one says so.
  if (const auto& g = s.model.document().device(); g && !SameFrame(*g, *s.geometry)) {
    s.workbench.status += " (made for a " + FrameText(*g) + " frame; the device runs a " +
                          FrameText(*s.geometry) + " one: restart with --frame/--pole to use it)";
  }
  return true;
}

void AppWindow::ApplySetEdits() {
  State& s = *s_;
  for (const std::string& text : s.options.set_fields) {
    std::string why;
    try {
      const SetFieldEdit edit = ParseSetField(text);
      const nlohmann::json value = nlohmann::json::parse(edit.value, nullptr, false);
      if (value.is_discarded()) {
        why = "the value '" + edit.value + "' is not JSON (a number, [x, y, z], true, \"text\")";
      } else if (!s.tree->SelectByName(edit.node)) {
        why = NoSuchNodeText(edit.node);
      } else if (!s.tree->SetField(edit.field, value)) {
        why = s.tree->error();
      }
    } catch (const std::exception& e) {
      why = e.what();
    }
    if (!why.empty()) throw WindowStartError(2, "spidarcad: error: --set '" + text + "': " + why);
  }
}

void AppWindow::RequestAction(int kind, const std::string& path) {
  State& s = *s_;
  if (s.ask_discard || s.pending_after_save_as) return;  // a question is already up
  s.pending_kind = kind;
  s.pending_path = path;
  if (s.model.document().dirty()) {
    s.ask_discard = true;
    s.discard_popup_requested = true;
    s.pending_ready = false;
  } else {
    s.pending_ready = true;
  }
}

void AppWindow::RunPendingAction() {
  State& s = *s_;
  if (s.recovery_answer >= 0) {
    const bool recover = s.recovery_answer == 1;
    s.recovery_answer = -1;
    AnswerRecovery(recover);
  }
  if (!s.pending_ready) return;
  const int kind = s.pending_kind;
  const std::string path = s.pending_path;
  s.pending_ready = false;
  s.pending_kind = kPendingNone;
  s.pending_path.clear();
  switch (kind) {
    case kPendingNew:
      NewDocument();  // the old autosave goes: its changes were saved or discarded
      break;
    case kPendingOpen:
      OpenDocument(path);  // a failure leaves the document and says why
      break;
    case kPendingQuit:
      DiscardRecovery();
      s.quit = true;
      break;
    default:
      break;
  }
}

void AppWindow::RequestNew() { RequestAction(kPendingNew, ""); }
void AppWindow::RequestOpen(const std::string& path) { RequestAction(kPendingOpen, path); }
void AppWindow::RequestQuit() { RequestAction(kPendingQuit, ""); }
bool AppWindow::discard_prompt_open() const { return s_->ask_discard; }

void AppWindow::AnswerDiscardPrompt(int answer) {
  State& s = *s_;
  if (!s.ask_discard) return;
  s.ask_discard = false;
  s.discard_popup_requested = false;
  if (answer == 1) {  // Discard
    s.pending_ready = true;
    return;
  }
  if (answer == 0 && s.model.document().file_path().empty()) {  // Save As first, then the action
    s.tree_state.open_save_as = true;
    s.pending_after_save_as = true;
    return;
  }
  if (answer == 0 && s.tree->Save()) {
    s.pending_ready = true;
    return;
  }
  if (answer == 0) {
    s.file_error = s.tree->error() + " (nothing was closed)";
    s.file_error_popup = true;
  }
  s.pending_kind = kPendingNone;  // Cancel, or the save failed
  s.pending_path.clear();
}

void AppWindow::OpenWindow() {
  State& s = *s_;
  const GuiOptions& options = s.options;
  glfwSetErrorCallback(GlfwError);
  s.glfw = std::make_unique<GlfwSession>();
  if (!s.glfw->ok) return;  // no display: the constructor says so after its other checks
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 2);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_DEPTH_BITS, 24);
  s.window =
      glfwCreateWindow(options.width, options.height, "spidarcad — SPIDAR-G", nullptr, nullptr);
  if (s.window == nullptr) {
    throw WindowStartError(1, "spidarcad: cannot create a " + std::to_string(options.width) + "x" +
                                  std::to_string(options.height) + " OpenGL 3.2 window");
  }
  glfwMakeContextCurrent(s.window);
  PinGlDriverForLeakCheck();
  glfwSetWindowUserPointer(s.window, this);
  glfwSetDropCallback(s.window, OnDrop);
  glfwSwapInterval(s.capture || options.frames > 0 || options.clock == "virtual" ? 0 : 1);
  // ImGui on top (up before VTK, so that the "Opening" box can be drawn while the start-up
  // document is read).
  s.imgui = std::make_unique<ImGuiSession>();
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // the panels are docked; there is nothing worth saving
  ApplyPanelStyle();
  LoadFont();
  s.imgui->glfw = ImGui_ImplGlfw_InitForOpenGL(s.window, true);
  s.imgui->gl3 = ImGui_ImplOpenGL3_Init("#version 150");
  if (!s.imgui->glfw || !s.imgui->gl3) {
    throw WindowStartError(1, "spidarcad: cannot initialise the ImGui backends");
  }
  s.window_open = true;
}

void AppWindow::UpdateLayout() {
  State& s = *s_;
  s.render_window->SetSize(s.fb_w, s.fb_h);
  LayoutSizes sizes;
  sizes.menu_height = s.menu_height;
  sizes.collapsed_height = s.frame_height;
  sizes.bottom_collapsed = !s.workbench.show_figures;
  s.layout = ComputeLayout(static_cast<float>(s.win_w), static_cast<float>(s.win_h), sizes);
  // The renderer draws exactly in the viewport rectangle (VTK: normalised, origin bottom left).
  const Rect& v = s.layout.viewport;
  s.view->renderer()->SetViewport(v.x / s.win_w, 1.0 - v.bottom() / s.win_h, v.right() / s.win_w,
                                  1.0 - v.y / s.win_h);
}

bool AppWindow::ReadWindowSize() {
  State& s = *s_;
  glfwGetFramebufferSize(s.window, &s.fb_w, &s.fb_h);
  glfwGetWindowSize(s.window, &s.win_w, &s.win_h);
  return s.fb_w > 0 && s.fb_h > 0 && s.win_w > 0 && s.win_h > 0;
}

std::shared_ptr<OpenWork> AppWindow::ReadOffThread(const std::string& source) {
  State& s = *s_;
  OpenThread reading(source);
  if (!WaitForOpen(source, reading.work.get())) {
    s.cancelled_opens.push_back(std::move(reading.thread));  // ends on its own
    return nullptr;
  }
  reading.thread.join();
  return reading.work;
}

void AppWindow::ReloadSource() {
  State& s = *s_;
  const std::string source = s.model.source();
  const std::shared_ptr<OpenWork> work = ReadOffThread(source);
  if (work == nullptr) {
    s.model.TakeSourceChange();  // not read again until the file changes again
    s.workbench.status = "reloading " + source + ": cancelled (kept the old scene)";
    s.workbench.status_error = false;
    return;
  }
  try {
    if (work->failure) std::rethrow_exception(work->failure);
    s.jobs->CancelAll();
    s.model.Adopt(std::move(work->prepared), s.grip->limits(), &s.model.device_to_world());
    AdoptParts(&s.model);
    s.assembly_mode->assembly().LoadDocument(s.model.document());  // none: it empties
    s.model_mode->SetFelt(BaseMode() != s.assembly_mode);
    if (!s.active->available()) SwitchMode(s.model_mode);
    ApplyHidden();
    s.republish = true;
    s.model.StartPreviewJobs(s.jobs.get());
    s.workbench.status = "reloaded " + s.model.source();
    s.workbench.status_error = false;
  } catch (const std::exception& e) {
    s.model.TakeSourceChange();  // read again at the file's next change, not every half second
    s.workbench.status = std::string("reload failed (kept the old scene): ") + e.what();
    s.workbench.status_error = true;
  }
}

bool AppWindow::WaitForOpen(const std::string& source, OpenWork* work) {
  State& s = *s_;
  s.cancel_open.store(false);  // a cancel of an earlier open does not carry over
  s.opening = true;
  const auto cancelled = [&s] {
    return s.cancel_open.load() ||
           (s.options.cancel_open != nullptr && s.options.cancel_open->load());
  };
  // A quick open (the demo, a small file) draws nothing: no flicker of a box.
  const auto start = std::chrono::steady_clock::now();
  while (!work->done.load() && !cancelled() &&
         std::chrono::steady_clock::now() - start < std::chrono::milliseconds(150))
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  const std::string name = std::filesystem::path(source).filename().string();
  // The window's panels (once it has them: not while the start-up document is read) are drawn
  // as they were, disabled: nothing in them can be used until the document is open.
  const bool panels =
      s.render_window.GetPointer() != nullptr && s.active != nullptr && s.tree != nullptr;
  while (!work->done.load() && !work->cancel.load()) {
    if (cancelled()) break;
    glfwPollEvents();  // a file dropped now is refused (DropFiles: s.opening)
    if (glfwWindowShouldClose(s.window)) {
      glfwSetWindowShouldClose(s.window, GLFW_FALSE);
      break;
    }
    if (!ReadWindowSize()) {  // minimised
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      continue;
    }
    if (panels) UpdateLayout();
    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
    if (panels) {
      ImGui::BeginDisabled();
      s.menu_height = DrawMenuBar(&s.model, s.jobs.get(), &s.workbench, &s.actions, s.tree.get(),
                                  &s.tree_state, &s.recent_entries);
      DrawPanels();
      ImGui::EndDisabled();
      s.actions = WorkbenchActions{};  // nothing drawn disabled acts
    }
    ImGui::SetNextWindowPos(ImVec2(0.5f * s.win_w, 0.5f * s.win_h), ImGuiCond_Always,
                            ImVec2(0.5f, 0.5f));
    ImGui::SetNextWindowFocus();  // over the panels
    ImGui::Begin("##opening", nullptr,
                 ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize |
                     ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoMove);
    ImGui::Text("Opening %s", name.c_str());
    const int total = work->progress.solids_total.load();
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (total == 0) {
      ImGui::TextDisabled("reading the file (%.0f s)", seconds);
    } else {
      ImGui::TextDisabled("compiling and finding the box of solid %d of %d (%.0f s)",
                          std::min(work->progress.solids_done.load() + 1, total), total, seconds);
    }
    const bool cancel = ImGui::Button("Cancel") || ImGui::IsKeyPressed(GLFW_KEY_ESCAPE, false);
    ImGui::End();
    ImGui::Render();
    if (panels) {
      RenderFrame();
    } else {
      BindDefaultFramebuffer(s.fb_w, s.fb_h);
      ClearDefaultFramebuffer(0.965f, 0.968f, 0.975f);
      ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    }
    glfwSwapBuffers(s.window);
    if (cancel) break;
  }
  s.opening = false;
  if (work->done.load()) return true;
  work->cancel.store(true);
  return false;
}

void AppWindow::CancelOpen() { s_->cancel_open.store(true); }

bool AppWindow::opening() const { return s_->opening.load(); }

bool AppWindow::OpenDocument(const std::string& path) {
  State& s = *s_;
  const std::filesystem::path old_recovery = s.autosaver->RecoveryPathFor(s.model.document());
  const bool wrote = s.autosave_wrote;
  const std::string recovered = s.recovered_file;
  if (!ReplaceDocument(path, nullptr)) return false;
  // The old document's autosave goes with it (its changes were saved or discarded).
  std::error_code ec;
  if (wrote) std::filesystem::remove(old_recovery, ec);
  if (!recovered.empty()) std::filesystem::remove(recovered, ec);
  ResetAutosaver();
  s.recent->Add(path);
  const std::string error = s.recent->Save();
  if (!error.empty()) std::cerr << "spidarcad: " << error << "\n";
  s.recorded_path = s.model.document().file_path();
  // A crash may have left an autosave of this file newer than it: offer it.
  FindRecoveryOffer(path);
  s.recovery_popup_requested = s.recovery_offer.has_value();
  return true;
}

void AppWindow::NewDocument() {
  State& s = *s_;
  DiscardRecovery();
  ReplaceDocument(kNoSceneName, nullptr);
  ResetAutosaver();
  s.recorded_path.clear();
}

void AppWindow::ResetAutosaver() {
  State& s = *s_;
  s.autosaver = std::make_unique<Autosaver>(
      DefaultRecoveryDirectory(), std::chrono::duration_cast<Autosaver::Clock::duration>(
                                      std::chrono::duration<double>(s.options.autosave_interval)));
  s.autosave_wrote = false;
  s.recovered_file.clear();
}

bool AppWindow::ImportMesh(const std::string& path) {
  State& s = *s_;
  try {
    Document& doc = s.model.document();
    const std::string stem = std::filesystem::path(path).stem().string();
    doc.Execute(edit::ImportMesh(path, UniqueObjectName(doc, stem.empty() ? "mesh" : stem)));
    const DocObject& o = doc.Get(doc.last_created().at(0));
    const MeshData& m = std::get<MeshData>(o.data);
    s.workbench.status = "imported '" + o.name + "' (" +
                         (m.volume ? std::to_string(m.volume->tets.cols()) + " tetrahedra"
                                   : std::to_string(m.surface->triangles.cols()) + " triangles") +
                         ") from " + path;
    s.workbench.status_error = false;
    s.file_error.clear();
    return true;
  } catch (const std::exception& e) {
    s.file_error = e.what();
    s.file_error_popup = true;
    s.workbench.status = std::string("import failed (nothing changed): ") + e.what();
    s.workbench.status_error = true;
    return false;
  }
}

void AppWindow::DropFiles(const std::vector<std::string>& paths) {
  State& s = *s_;
  if (s.opening) {  // dropped while a document is being read (WaitForOpen polls events)
    s.file_error = "dropped files not used: wait until the document being opened is open";
    s.file_error_popup = true;
    return;
  }
  bool opened = false;
  for (const std::string& path : paths) {
    if (IsMeshFile(path)) {
      ImportMesh(path);
    } else if (MatchesFilter(path, BrowseFilter::kDocuments) && !opened) {
      RequestOpen(path);
      opened = true;  // one document at a time
    } else {
      s.file_error = path + ": dropped file not used: drop a document (.json) to open it or a " +
                     "mesh (.stl .obj .ply .vtu .node) to import it";
      s.file_error_popup = true;
    }
  }
}

const std::string& AppWindow::file_error() const { return s_->file_error; }
RecentFiles& AppWindow::recent() { return *s_->recent; }
Autosaver& AppWindow::autosaver() { return *s_->autosaver; }
bool AppWindow::recovery_prompt_open() const { return s_->recovery_offer.has_value(); }

void AppWindow::AnswerRecovery(bool recover) {
  State& s = *s_;
  if (!s.recovery_offer) return;
  const RecoveryFile offer = *s.recovery_offer;
  s.recovery_offer.reset();
  s.recovery_popup_requested = false;
  if (recover) {
    ReplaceDocument(offer.path.string(), &offer.original);
    return;
  }
  std::error_code ec;
  std::filesystem::remove(offer.path, ec);
}

void AppWindow::FindRecoveryOffer(const std::string& source) {
  State& s = *s_;
  std::string original;  // what a recovery file of this start names ("" untitled)
  if (source != kDemoSceneName && source != kNoSceneName) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(source, ec)) return;  // the load names the problem
    original = NormalisedPath(source);
  }
  for (RecoveryFile& f : ListRecoveryFiles(s.autosaver->directory())) {
    if (f.original != original) continue;
    std::error_code ec;
    if (original.empty()) {
      // An untitled document's autosave: not one of a session still running.
      const long pid = UntitledPid(f.path);
      if (pid > 0 && pid != ::getpid() && ::kill(static_cast<pid_t>(pid), 0) == 0) continue;
    } else {
      const auto saved = std::filesystem::last_write_time(original, ec);
      if (!ec && f.written <= saved) continue;  // older than the file: nothing to recover
    }
    s.recovery_offer = std::move(f);
    return;
  }
}

void AppWindow::DiscardRecovery() {
  State& s = *s_;
  if (s.autosave_wrote) s.autosaver->Discard(s.model.document());
  if (!s.recovered_file.empty()) {
    std::error_code ec;
    std::filesystem::remove(s.recovered_file, ec);
  }
  s.autosave_wrote = false;
  s.recovered_file.clear();
}

void AppWindow::UpdateAutosave() {
  State& s = *s_;
  if (s.recovery_offer) return;  // the question about an older autosave comes first
  const Document& doc = s.model.document();
  if (!doc.dirty()) {
    // Saved (or undone back to the file): the recovery file has nothing the file lacks.
    if (s.autosave_wrote || !s.recovered_file.empty()) DiscardRecovery();
    return;
  }
  if (s.autosaver->Tick(doc)) {
    s.autosave_wrote = true;
    const std::string written = s.autosaver->RecoveryPathFor(doc).string();
    if (!s.recovered_file.empty() && s.recovered_file != written) {
      std::error_code ec;  // superseded by this session's own autosave
      std::filesystem::remove(s.recovered_file, ec);
      s.recovered_file.clear();
    }
    s.autosave_error.clear();
  } else if (!s.autosaver->last_error().empty() && s.autosaver->last_error() != s.autosave_error) {
    s.autosave_error = s.autosaver->last_error();
    s.workbench.status = "autosave failed (retrying): " + s.autosave_error;
    s.workbench.status_error = true;
  }
}

void AppWindow::DrawFileDialogs() {
  State& s = *s_;
  const ImGuiWindowFlags flags = ImGuiWindowFlags_AlwaysAutoResize;
  const float wrap = 520.0f;
  // Save / Discard / Cancel before an action that would drop unsaved changes.
  if (s.discard_popup_requested && s.ask_discard) ImGui::OpenPopup(kDiscardPopup);
  s.discard_popup_requested = false;
  if (ImGui::BeginPopupModal(kDiscardPopup, nullptr, flags)) {
    const Document& doc = s.model.document();
    const std::string name =
        doc.file_path().empty()
            ? std::string("The untitled document")
            : "'" + std::filesystem::path(doc.file_path()).filename().string() + "'";
    std::string before = "quitting";
    if (s.pending_kind == kPendingNew) before = "starting a new document";
    if (s.pending_kind == kPendingOpen) {
      before = "opening " + std::filesystem::path(s.pending_path).filename().string();
    }
    ImGui::PushTextWrapPos(wrap);
    ImGui::Text("%s has unsaved changes.", name.c_str());
    ImGui::Text("Save them before %s?", before.c_str());
    ImGui::PopTextWrapPos();
    int answer = -1;
    if (ImGui::Button(doc.file_path().empty() ? "Save As..." : "Save")) answer = 0;
    ImGui::SameLine();
    if (ImGui::Button("Discard")) answer = 1;
    ImGui::SameLine();
    if (ImGui::Button("Cancel") || ImGui::IsKeyPressed(GLFW_KEY_ESCAPE, false)) answer = 2;
    if (answer >= 0) AnswerDiscardPrompt(answer);
    if (!s.ask_discard) ImGui::CloseCurrentPopup();
    ImGui::EndPopup();
  }
  // The start-up question about an autosave newer than the document.
  if (s.recovery_popup_requested && s.recovery_offer) ImGui::OpenPopup(kRecoveryPopup);
  s.recovery_popup_requested = false;
  if (ImGui::BeginPopupModal(kRecoveryPopup, nullptr, flags)) {
    if (s.recovery_offer) {
      const RecoveryFile& f = *s.recovery_offer;
      ImGui::PushTextWrapPos(wrap);
      ImGui::Text("Recover unsaved work from %s?", FileTimeText(f.written).c_str());
      ImGui::TextDisabled(
          "%s", f.original.empty() ? "an untitled document" : ("of " + f.original).c_str());
      ImGui::TextDisabled("autosave: %s", f.path.string().c_str());
      ImGui::PopTextWrapPos();
      if (ImGui::Button("Recover")) s.recovery_answer = 1;
      ImGui::SameLine();
      if (ImGui::Button("Discard")) s.recovery_answer = 0;
    }
    if (!s.recovery_offer) ImGui::CloseCurrentPopup();
    ImGui::EndPopup();
  }
  // The browsers.
  if (auto path = DrawFileBrowser(&s.open_browser)) RequestOpen(*path);
  if (auto path = DrawFileBrowser(&s.import_browser)) ImportMesh(*path);
  // A file that could not be opened or imported: what and where.
  if (s.file_error_popup) ImGui::OpenPopup(kFileErrorPopup);
  s.file_error_popup = false;
  if (ImGui::BeginPopupModal(kFileErrorPopup, nullptr, flags)) {
    ImGui::PushTextWrapPos(wrap);
    ImGui::TextColored(ImVec4(0.80f, 0.10f, 0.10f, 1.0f), "%s", s.file_error.c_str());
    ImGui::TextDisabled("The document is as it was.");
    ImGui::PopTextWrapPos();
    if (ImGui::Button("OK") || ImGui::IsKeyPressed(GLFW_KEY_ENTER, false))
      ImGui::CloseCurrentPopup();
    ImGui::EndPopup();
  }
}

// ---- for scripted use and tests ----

const WindowLayout& AppWindow::layout() const { return s_->layout; }

Rect AppWindow::DrawnPanel(const std::string& name) const {
  ImGuiWindow* w = ImGui::FindWindowByName(name.c_str());
  if (w == nullptr || !w->Active) return {};  // not begun in the latest frame
  return {w->Pos.x, w->Pos.y, w->Size.x, w->Size.y};
}

void AppWindow::Resize(int width, int height) { glfwSetWindowSize(s_->window, width, height); }

bool AppWindow::ClickAt(double x, double y) {
  State& s = *s_;
  if (!s.layout.viewport.Contains(static_cast<float>(x), static_cast<float>(y))) return false;
  const double sx = static_cast<double>(s.fb_w) / s.win_w;
  const double sy = static_cast<double>(s.fb_h) / s.win_h;
  const ObjectId id = s.scene_view->PickObject(x * sx, s.fb_h - y * sy,
                                               s.assembly_mode->assembly().PickableParts());
  if (id == 0) return false;
  s.tree->Select(id);
  const int index = s.model.IndexOf(id);
  if (index >= 0) s.workbench.selected = index;
  return true;
}

bool AppWindow::SelectTouched() {
  State& s = *s_;
  return s.model_mode->SelectTouched(s.runtime->Latest().tool, s.context, "Enter");
}

std::vector<Mode*> AppWindow::modes() const {
  std::vector<Mode*> out;
  for (const auto& m : s_->modes) out.push_back(m.get());
  return out;
}

Mode* AppWindow::active_mode() const { return s_->active; }

Mode* AppWindow::FindMode(const std::string& key) const {
  for (const auto& m : s_->modes) {
    if (key == m->key()) return m.get();
  }
  return nullptr;
}

void AppWindow::SwitchMode(Mode* mode) {
  State& s = *s_;
  if (mode == nullptr || mode == s.active || !mode->available()) return;
  s.active->Leave();
  s.active = mode;
  s.active->Enter();
  ApplyHidden();
  PublishScene();
}

Mode* AppWindow::AddMode(std::unique_ptr<Mode> mode) {
  s_->modes.push_back(std::move(mode));
  ApplyHidden();
  return s_->modes.back().get();
}

int AppWindow::publish_count() const { return s_->publishes; }
ModelMode& AppWindow::model_mode() { return *s_->model_mode; }
SceneModel& AppWindow::model() { return s_->model; }
TreeController& AppWindow::tree() { return *s_->tree; }
HapticRuntime& AppWindow::runtime() { return *s_->runtime; }
CalibrationWizard& AppWindow::calibration_wizard() { return s_->calibration; }
GripControl& AppWindow::grip() { return *s_->grip; }
DeviceView& AppWindow::view() { return *s_->view; }
SceneView& AppWindow::scene_view() { return *s_->scene_view; }
WorkbenchState& AppWindow::workbench() { return s_->workbench; }
JobQueue& AppWindow::jobs() { return *s_->jobs; }
vtkRenderer* AppWindow::renderer() { return s_->view->renderer(); }

int RunGui(const GuiOptions& options) {
  try {
    AppWindow window(options);
    return window.Run();
  } catch (const WindowStartError& e) {
    std::cerr << e.what() << "\n";
    return e.status();
  }
}

}  // namespace spidarcad::app
