// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The window loop: GLFW events → grip control → target of the simulated hand → (haptic thread:
// hand, device, HapticLoop at 1 kHz) → latest ToolState → VTK scene + ImGui panels; scene
// meshing in background Jobs.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>
#include <vtkCallbackCommand.h>
#include <vtkCommand.h>
#include <vtkGenericOpenGLRenderWindow.h>
#include <vtkNew.h>
#include <vtkRenderer.h>

#include <Eigen/Geometry>

#include "scene/vtu_io.h"
#include "doc/job.h"
#include "gui/assembly_mode.h"
#include "scene/device_session.h"
#include "gui/device_view.h"
#include "gui/fe_mode.h"
#include "gui/gl_capture.h"
#include "scene/grip_control.h"
#include "gui/gui.h"

#include "doc/assets.h"
#include "scene/haptic_runtime.h"
#include "gui/panels.h"
#include "scene/scene_model.h"
#include "gui/scene_view.h"
#include "gui/sculpt_mode.h"
#include "scene/trajectory_player.h"
#include "gui/tree_panel.h"
#include "gui/workbench_panels.h"
#include "scene/fe_model.h"
#include "scene/shared_field.h"
#include "spidarcad/haptics/trajectory.h"

namespace spidarcad::app {

namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
constexpr double kGraspStep = 5.0 * kDegToRad;    // per wheel notch or key press
constexpr double kRotateGain = 0.008;              // rad per pixel of right-drag
constexpr double kOrbitGain = 0.3;                 // deg per pixel
constexpr int kScreenshotFrames = 6;               // frames rendered before the capture
constexpr double kSettleTimeout = 90.0;            // s a screenshot waits for ramp and jobs
constexpr float kScenePanelWidth = 330.0f;         // pixels
constexpr int kReloadCheckFrames = 30;             // frames between scene-file mtime checks
constexpr char kFontPath[] = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

void GlfwError(int code, const char* text) {
  std::cerr << "spidarcad: GLFW error " << code << ": " << text << "\n";
}

// Mouse action in progress in the 3D view.
enum class DragMode { kNone, kMoveGrip, kRotateGrip, kRollGrip, kOrbit };

const char* DragModeText(DragMode mode) {
  switch (mode) {
    case DragMode::kMoveGrip: return "moving grip";
    case DragMode::kRotateGrip: return "rotating grip";
    case DragMode::kRollGrip: return "rolling grip";
    case DragMode::kOrbit: return "orbit";
    case DragMode::kNone: break;
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
  static const ImWchar kRanges[] = {0x0020, 0x00FF, 0x0370, 0x03FF, 0x2010, 0x2044,
                                    0x2070, 0x209F, 0x2190, 0x21FF, 0x2200, 0x22FF,
                                    0x25A0, 0x25FF, 0};
  std::error_code ec;
  if (std::filesystem::exists(kFontPath, ec)) {
    if (io.Fonts->AddFontFromFileTTF(kFontPath, 14.5f, nullptr, kRanges) != nullptr) return;
  }
  io.Fonts->AddFontDefault();
}

}  // namespace

bool DisplayAvailable() {
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || display[0] == '\0') return false;
  // glfwInit connects to the X server and fails cleanly when it cannot. The connection is
  // kept (RunGui's glfwInit is then a no-op): closing it would let an Xvfb with no other
  // client reset, and a connection opened during the reset fails.
  glfwSetErrorCallback(nullptr);
  return glfwInit() == GLFW_TRUE;
}

void ParseWindowSize(const std::string& text, int* width, int* height) {
  int w = 0, h = 0;
  char x = 0;
  std::istringstream in(text);
  if (!(in >> w >> x >> h) || (x != 'x' && x != 'X') || !(in >> std::ws).eof() || w < 200 ||
      h < 200 || w > 8192 || h > 8192) {
    throw CLI::ValidationError("--size", "expected WxH with both in [200, 8192] pixels, got '" +
                                             text + "'");
  }
  *width = w;
  *height = h;
}

void ParseGripPose(const std::string& text, std::array<double, 7>* grip) {
  static const char* kFields[7] = {"x [mm]",   "y [mm]",   "z [mm]",    "roll [deg]",
                                   "pitch [deg]", "yaw [deg]", "grasp [deg]"};
  std::array<double, 7> out = *grip;
  std::stringstream in(text);
  std::string field;
  int k = 0;
  while (std::getline(in, field, ',')) {
    if (k >= 7) {
      throw CLI::ValidationError("--grip", "at most 7 fields (x,y,z,roll,pitch,yaw,grasp), got '" +
                                               text + "'");
    }
    try {
      size_t used = 0;
      out[k] = std::stod(field, &used);
      if (used != field.size() || !std::isfinite(out[k])) throw std::invalid_argument(field);
    } catch (const std::exception&) {
      throw CLI::ValidationError("--grip", std::string("field ") + std::to_string(k + 1) + " (" +
                                               kFields[k] + ") is not a number: '" + field +
                                               "'");
    }
    ++k;
  }
  if (k != 3 && k != 6 && k != 7) {
    throw CLI::ValidationError("--grip", "expected 3, 6 or 7 comma-separated fields "
                                         "(x,y,z[,roll,pitch,yaw[,grasp]]), got '" + text + "'");
  }
  *grip = out;
}

void AddGuiOptions(CLI::App& app, GuiOptions* options) {
  app.add_option("--select", options->select,
                 "Select this solid or node in the tree panel at start, showing its parameters: a "
                 "solid's name, a node's name or id, or SOLID/i/j for child j of child i of the "
                 "solid's root (default: the first solid). Not in the scene: exit status 2")
      ->type_name("NAME");
  app.add_option("scene", options->scene,
                 "Scene to open: a scene file (JSON, e.g. assets/scenes/platform.json), 'demo' "
                 "(built-in, the default) or 'none'; with --mode fe the default is "
                 "assets/scenes/platform.json, with --mode sculpt assets/scenes/clay.json. The "
                 "file is re-read when it changes on disk.");
  app.add_option("--mode", options->mode,
                 "Start in a mode: 'fe' meshes assets/scenes/platform.json (TetGen, 12 mm), "
                 "precomputes it (steel, clamped at the wall face) and lets the grip push it; "
                 "'sculpt' meshes assets/scenes/clay.json and lets the grip sculpt it (close the "
                 "grasp or hold G). Both are also in the 'Modes' window. While a mode's part "
                 "is live, it alone is felt: the scene's solids are shown but not touched.")
      ->check(CLI::IsMember({"fe", "sculpt"}));
  app.add_option("--estop-frame", options->estop_frame,
                 "Press the emergency stop (Space) at this frame (scripted runs and tests)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--trajectory", options->trajectory,
                 "Scripted grip: the simulated hand's target follows this trajectory CSV "
                 "(t,x,y,z,qw,qx,qy,qz,grasp in D, as `spidarcad run --trajectory`) in wall-clock "
                 "time from the first frame, then holds its last sample and the mouse takes over; "
                 "the grip starts at its first sample. --screenshot waits until it has ended "
                 "(+0.5 s), --frames runs at least that long.");
  app.add_option("--screenshot", options->screenshot,
                 "Render a few frames, write the window (scene and panel) to this PNG and exit");
  app.add_option("--frames", options->frames, "Exit after this many frames (0: run until closed)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--device", options->device,
                 "The device the 1 kHz haptic loop drives: 'simulated' (default: the simulated "
                 "SPIDAR-G with encoder errors, calibrated at start-up, held by a simulated hand "
                 "that follows the mouse); 'ideal' (no encoder errors, the grip exactly where the "
                 "mouse puts it); 'board-sim' (the same simulated SPIDAR-G behind the controller "
                 "board's firmware simulator, driven by the USB driver byte for byte, no "
                 "hardware; the panel can unplug it); 'usb' (a real controller board over libusb: "
                 "your hand moves the grip, the mouse does not; without a board the window runs "
                 "at zero force, says 'not connected' and retries every 0.2 s: see `spidarcad "
                 "device list` and assets/udev/99-spidarcad.rules)")
      ->check(CLI::Validator(
          [](std::string& name) -> std::string {
            RuntimeDevice device;
            if (ParseRuntimeDevice(name, &device)) return {};
            return "'" + name + "' is not a device; use simulated, ideal, board-sim or usb";
          },
          "DEVICE"));
  app.add_option_function<std::string>(
         "--size", [options](const std::string& s) {
           ParseWindowSize(s, &options->width, &options->height);
         },
         "Window size WxH in pixels (default 1280x800)")
      ->type_name("WxH");
  app.add_option_function<std::string>(
         "--grip", [options](const std::string& s) { ParseGripPose(s, &options->grip); },
         "Starting hand pose in the device frame: x,y,z[,roll,pitch,yaw[,grasp]] "
         "(mm and degrees; grasp 20..160, default 90)")
      ->type_name("X,Y,Z[,R,P,Y[,G]]");
}

// The scene the window opens: the positional argument, else the mode's part, else the demo.
static std::string DefaultSceneFor(const GuiOptions& options) {
  if (!options.scene.empty()) return options.scene;
  if (options.mode == "fe") return PlatformScenePath();
  if (options.mode == "sculpt") return AssetPath("scenes/clay.json");
  return kDemoSceneName;
}

int RunGui(const GuiOptions& options) {
  // The scene first: a bad file fails before any window opens.
  GripControl grip(haptics::SpidarGeometry{});
  const auto& g0 = options.grip;
  const Eigen::Matrix3d R0 = (Eigen::AngleAxisd(g0[5] * kDegToRad, Eigen::Vector3d::UnitZ()) *
                              Eigen::AngleAxisd(g0[4] * kDegToRad, Eigen::Vector3d::UnitY()) *
                              Eigen::AngleAxisd(g0[3] * kDegToRad, Eigen::Vector3d::UnitX()))
                                 .toRotationMatrix();
  grip.SetPose(Eigen::Vector3d(g0[0], g0[1], g0[2]) * 1e-3, R0, g0[6] * kDegToRad);
  // --trajectory: read before any window opens; the grip starts at its first sample.
  haptics::Trajectory trajectory;
  if (!options.trajectory.empty()) {
    try {
      trajectory = haptics::Trajectory::Load(options.trajectory);
    } catch (const std::exception& e) {
      std::cerr << "spidarcad: error: --trajectory: " << e.what() << "\n";
      return 2;
    }
    const haptics::TrajectorySample first = trajectory.Sample(trajectory.start_time());
    grip.SetPose(first.p_DT, first.q_DT.toRotationMatrix(), first.grasp);
  }
  SceneModel model;
  // An assembly scene (one with `parts`) keeps X_WD = identity, as `spidarcad run` does, so that
  // one trajectory file works in both.
  modeling::Scene assembly_scene;
  const bool assembly = LoadAssemblyScene(DefaultSceneFor(options), &assembly_scene);
  try {
    const DeviceToWorld identity;
    model.Load(DefaultSceneFor(options), grip.limits(), assembly ? &identity : nullptr);
  } catch (const std::exception& e) {
    std::cerr << "spidarcad: error: scene: " << e.what() << "\n";
    return 2;
  }
  // The tree panel's controller on the model's Document; the first solid selected, or --select.
  TreeController tree(&model);
  TreePanelState tree_state;
  if (!options.select.empty()) {
    if (!tree.SelectByName(options.select)) {
      std::cerr << "spidarcad: error: --select: no solid or node named '" << options.select
                << "' in the scene\n";
      return 2;
    }
  } else if (!model.objects().empty()) {
    tree.Select(model.objects().front().id);
  }
  std::string window_title;
  glfwSetErrorCallback(GlfwError);
  GlfwSession glfw;
  if (!glfw.ok) {
    std::cerr << "spidarcad: cannot initialise GLFW (no display?). Run under "
                 "`xvfb-run -a spidarcad` or use the headless subcommands.\n";
    return 1;
  }
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 2);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_DEPTH_BITS, 24);
  GLFWwindow* window = glfwCreateWindow(options.width, options.height,
                                        "spidarcad — SPIDAR-G", nullptr, nullptr);
  if (window == nullptr) {
    std::cerr << "spidarcad: cannot create a " << options.width << "x" << options.height
              << " OpenGL 3.2 window\n";
    return 1;
  }
  struct WindowGuard {
    GLFWwindow* w;
    ~WindowGuard() { glfwDestroyWindow(w); }
  } window_guard{window};
  glfwMakeContextCurrent(window);
  const bool capture = !options.screenshot.empty();
  glfwSwapInterval(capture || options.frames > 0 ? 0 : 1);

  // The haptic runtime (its own 1 kHz thread) and the jobs.
  RuntimeSettings runtime_settings;
  if (!ParseRuntimeDevice(options.device, &runtime_settings.device)) {
    std::cerr << "spidarcad: error: --device: '" << options.device
              << "' is not a device; use simulated, ideal, board-sim or usb\n";
    return 2;
  }
  runtime_settings.loop.world_scale = model.device_to_world().world_scale;
  runtime_settings.loop.p_WDo = model.device_to_world().p_WDo;
  HapticRuntime runtime(runtime_settings, grip.Pose());
  if (!runtime.link_at_start().empty()) {  // no board: the window runs at zero force, retrying
    std::cerr << "spidarcad: " << runtime.link_at_start()
              << "\nspidarcad: the window runs at zero force and retries the board.\n";
  }
  const haptics::SpidarGeometry& geometry = runtime.info().geometry;
  const haptics::TensionSettings& tension_settings = runtime.loop().settings().tension;
  DemoFieldSettings field;
  // With solids to touch, the springs would fight the contact: off unless the scene is empty.
  field.enabled = model.objects().empty();
  // An assembly's part solids sit at their frame origins until the assembly field (below) places
  // them: nothing is felt until it is published.
  runtime.Publish(assembly ? std::make_unique<haptics::HapticScene>() : model.BuildHapticScene(field));
  runtime.Start();
  struct RuntimeGuard {
    HapticRuntime* r;
    ~RuntimeGuard() { r->Stop(); }
  } runtime_guard{&runtime};
  JobQueue jobs;  // after model: its destructor joins the workers before model goes
  model.StartPreviewJobs(&jobs);
  WorkbenchState workbench;

  // VTK in the GLFW context.
  DeviceView view(geometry, tension_settings.tau_min, tension_settings.tau_max);
  vtkNew<vtkGenericOpenGLRenderWindow> render_window;
  int fb_w = 0, fb_h = 0;
  glfwGetFramebufferSize(window, &fb_w, &fb_h);
  render_window->SetSize(fb_w, fb_h);
  vtkNew<vtkCallbackCommand> make_current;
  make_current->SetCallback(OnMakeCurrent);
  make_current->SetClientData(window);
  render_window->AddObserver(vtkCommand::WindowMakeCurrentEvent, make_current);
  vtkNew<vtkCallbackCommand> is_current;
  is_current->SetCallback(OnIsCurrent);
  is_current->SetClientData(window);
  render_window->AddObserver(vtkCommand::WindowIsCurrentEvent, is_current);
  if (!render_window->InitializeFromCurrentContext()) {
    std::cerr << "spidarcad: VTK cannot use the window's OpenGL context (needs OpenGL 3.2)\n";
    return 1;
  }
  render_window->SetFrameBlitModeToBlitToCurrent();
  render_window->AddRenderer(view.renderer());
  SceneView scene_view(view.renderer());

  // The modes (FE push, sculpt): each may contribute one force field, kept across scene rebuilds
  // through SharedField so its state between ticks survives a republish.
  FeMode fe_mode(view.renderer(), &jobs);
  SculptMode sculpt_mode(view.renderer(), &jobs);
  fe_mode.SetWorldToView(runtime_settings.loop.world_scale, runtime_settings.loop.p_WDo);
  sculpt_mode.SetWorldToView(runtime_settings.loop.world_scale, runtime_settings.loop.p_WDo);
  std::shared_ptr<haptics::ForceField> fe_field, sculpt_field;
  bool fe_precompute_started = false;
  if (options.mode == "fe") {
    fe_mode.SetActive(true);
    fe_mode.MeshPlatform();
  } else if (options.mode == "sculpt") {
    sculpt_mode.SetActive(true);
  }
  // Assembly scenes: the parts are one AssemblyField, drawn by AssemblyMode where the field has
  // them; the SceneView's static actors of the part solids (at their frame origins) are hidden.
  AssemblyMode assembly_mode(view.renderer());
  if (assembly) {
    try {
      assembly_mode.Load(assembly_scene);
    } catch (const std::exception& e) {
      std::cerr << "spidarcad: error: scene: " << e.what() << "\n";
      return 2;
    }
  }
  assembly_mode.SetWorldToView(runtime_settings.loop.world_scale, runtime_settings.loop.p_WDo);
  scene_view.SetHidden(assembly_mode.part_solids());
  if (assembly_mode.has_parts()) view.Zoom(1.7);  // the robot is small in the frame (C: whole frame)
  const auto publish_scene = [&] {
    // A live mode part stands in for the scene's solids: the FE part and the clay usually sit
    // where a solid of the scene is (they are meshed from it), and the solid's contact would
    // hold the tool off the part.
    const bool fe_live = fe_field && fe_mode.active();
    const bool sculpt_live = sculpt_field && sculpt_mode.active();
    // An assembly's field stands in for the part solids (when no mode part is live).
    const bool assembly_live = assembly_mode.has_parts() && !fe_live && !sculpt_live;
    std::unique_ptr<haptics::HapticScene> scene =
        fe_live || sculpt_live || assembly_live ? std::make_unique<haptics::HapticScene>()
                                                : model.BuildHapticScene(field, workbench.contact);
    if (fe_live) scene->Add(std::make_unique<SharedField>(fe_field));
    if (sculpt_live) scene->Add(std::make_unique<SharedField>(sculpt_field));
    if (assembly_live) scene->Add(std::make_unique<SharedField>(assembly_mode.field()));
    runtime.Publish(std::move(scene));
  };

  // ImGui on top.
  ImGuiSession imgui;
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // the panel is docked; there is nothing worth saving
  ApplyPanelStyle();
  LoadFont();
  imgui.glfw = ImGui_ImplGlfw_InitForOpenGL(window, true);
  imgui.gl3 = ImGui_ImplOpenGL3_Init("#version 150");
  if (!imgui.glfw || !imgui.gl3) {
    std::cerr << "spidarcad: cannot initialise the ImGui backends\n";
    return 1;
  }

  if (assembly_mode.TakeFieldChanged()) publish_scene();
  // --trajectory: played into the hand's target from here on (its own thread, 1 kHz); the main
  // thread takes the target back (the mouse's grip, set to the last sample) once it has ended.
  std::unique_ptr<TrajectoryPlayer> player;
  if (!trajectory.empty()) {
    const double d = geometry.d;
    player = std::make_unique<TrajectoryPlayer>(trajectory, [&runtime, d](const haptics::TrajectorySample& s) {
      runtime.SetTarget(haptics::GripPose::FromFrame(s.p_DT, s.q_DT.toRotationMatrix(), s.grasp, d));
    });
    player->Start();
  }
  bool player_live = player != nullptr;

  DragMode drag = DragMode::kNone;
  bool quit = false;
  const double start_time = glfwGetTime();
  int exit_status = 0;
  const int last_frame = capture ? std::max(kScreenshotFrames, options.frames) : options.frames;
  for (int frame_index = 1; !quit && !glfwWindowShouldClose(window); ++frame_index) {
    glfwPollEvents();
    glfwGetFramebufferSize(window, &fb_w, &fb_h);
    int win_w = 0, win_h = 0;
    glfwGetWindowSize(window, &win_w, &win_h);
    if (fb_w <= 0 || fb_h <= 0 || win_w <= 0 || win_h <= 0) {  // minimised
      glfwWaitEvents();
      continue;
    }
    const double sx = static_cast<double>(fb_w) / win_w, sy = static_cast<double>(fb_h) / win_h;
    render_window->SetSize(fb_w, fb_h);
    const double panel_fb = std::min(kPanelWidth * sx, 0.6 * fb_w);
    view.renderer()->SetViewport(panel_fb / fb_w, 0.0, 1.0, 1.0);

    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();

    // Mouse in the 3D view (display pixels, origin bottom left).
    const ImVec2 mouse = io.MousePos;
    const double mx = mouse.x * sx, my = fb_h - mouse.y * sy;
    const bool in_view = !io.WantCaptureMouse && mouse.x >= kPanelWidth && mouse.x >= 0 &&
                         std::isfinite(mouse.x);
    bool over_grip = false;
    if (in_view) {
      double distance = 0;
      over_grip = IntersectRaySphere(view.PickRay(mx, my), grip.p0(), 1.15 * geometry.d,
                                     &distance);
    }
    if (drag == DragMode::kNone && in_view) {
      if (ImGui::IsMouseClicked(ImGuiMouseButton_Left)) {
        if (io.KeyCtrl) {
          drag = io.KeyShift ? DragMode::kRollGrip : DragMode::kRotateGrip;
        } else if (over_grip && grip.BeginTranslate(view.PickRay(mx, my), view.ViewDirection())) {
          drag = DragMode::kMoveGrip;
        } else {
          drag = DragMode::kOrbit;
        }
      } else if (ImGui::IsMouseClicked(ImGuiMouseButton_Right)) {
        drag = io.KeyShift ? DragMode::kRollGrip : DragMode::kRotateGrip;
      } else if (ImGui::IsMouseClicked(ImGuiMouseButton_Middle)) {
        drag = DragMode::kOrbit;
      }
    }
    if (drag != DragMode::kNone && !ImGui::IsMouseDown(ImGuiMouseButton_Left) &&
        !ImGui::IsMouseDown(ImGuiMouseButton_Right) &&
        !ImGui::IsMouseDown(ImGuiMouseButton_Middle)) {
      drag = DragMode::kNone;
      grip.EndTranslate();
    }
    const double dx = io.MouseDelta.x, dy = io.MouseDelta.y;  // screen pixels, y down
    const bool moved = std::isfinite(dx) && std::isfinite(dy) && (dx != 0.0 || dy != 0.0);
    if (moved) {
      switch (drag) {
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
          view.Orbit(-kOrbitGain * dx, kOrbitGain * dy);
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
    if (over_grip || drag == DragMode::kMoveGrip) ImGui::SetMouseCursor(ImGuiMouseCursor_Hand);
    if (!io.WantCaptureKeyboard) {
      if (ImGui::IsKeyPressed(GLFW_KEY_ESCAPE)) quit = true;
      if (ImGui::IsKeyPressed(GLFW_KEY_SPACE, false)) runtime.EmergencyStop();
      if (ImGui::IsKeyPressed(GLFW_KEY_LEFT_BRACKET)) grip.AdjustGrasp(-kGraspStep);
      if (ImGui::IsKeyPressed(GLFW_KEY_RIGHT_BRACKET)) grip.AdjustGrasp(kGraspStep);
      if (ImGui::IsKeyPressed(GLFW_KEY_R, false) && !io.KeyCtrl) grip.Reset();
      if (ImGui::IsKeyPressed(GLFW_KEY_C, false) && !io.KeyCtrl) view.ResetCamera();  // Ctrl+C: copy
      if (ImGui::IsKeyPressed(GLFW_KEY_EQUAL) || ImGui::IsKeyPressed(GLFW_KEY_KP_ADD)) {
        view.Zoom(1.1);
      }
      if (ImGui::IsKeyPressed(GLFW_KEY_MINUS) || ImGui::IsKeyPressed(GLFW_KEY_KP_SUBTRACT)) {
        view.Zoom(1.0 / 1.1);
      }
    }

    if (options.estop_frame > 0 && frame_index == options.estop_frame) runtime.EmergencyStop();

    // The hand follows the mouse's grip (or the trajectory); the haptic thread's latest tick is
    // what we show.
    if (player_live) {
      const haptics::TrajectorySample s = player->Current();
      grip.SetPose(s.p_DT, s.q_DT.toRotationMatrix(), s.grasp);  // picking and the panel follow
      if (player->done()) {
        player->Stop();
        player_live = false;
      }
    } else {
      runtime.SetTarget(grip.Pose());
    }
    const RuntimeFrame& latest = runtime.Latest();
    const DeviceFrame state = MakeDeviceFrame(latest, geometry, runtime.description());
    view.Update(state);

    // Jobs: finishers land their meshes; outcomes go to the status line.
    jobs.Poll();
    for (const auto& job : jobs.jobs()) {
      switch (job->state()) {
        case Job::State::kSucceeded:
          workbench.status = job->title() + ": done";
          workbench.status_error = false;
          break;
        case Job::State::kFailed:
          workbench.status = job->title() + " failed: " + job->error() + " (nothing changed)";
          workbench.status_error = true;
          break;
        case Job::State::kCancelled:
          workbench.status = job->title() + ": cancelled (nothing changed)";
          workbench.status_error = false;
          break;
        case Job::State::kRunning:
          break;
      }
    }
    jobs.Prune();
    if (frame_index % kReloadCheckFrames == 0 && model.SourceChanged()) {
      try {
        jobs.CancelAll();
        model.Load(model.source(), grip.limits(), &model.device_to_world());
        modeling::Scene reloaded;  // no parts (any more): the assembly empties
        if (LoadAssemblyScene(model.source(), &reloaded) || assembly_mode.has_parts()) {
          assembly_mode.Load(reloaded);
          scene_view.SetHidden(assembly_mode.part_solids());
        }
        publish_scene();
        model.StartPreviewJobs(&jobs);
        workbench.status = "reloaded " + model.source();
        workbench.status_error = false;
      } catch (const std::exception& e) {
        workbench.status = std::string("reload failed (kept the old scene): ") + e.what();
        workbench.status_error = true;
      }
    }
    scene_view.Sync(model, workbench.show_edges ? workbench.selected : -1);
    scene_view.ShowContacts(model.ContactMarkers(), latest.tool.time, model.device_to_world());

    WorkbenchActions wb;
    const float menu_height = DrawMenuBar(&model, &jobs, &workbench, &wb, &tree, &tree_state);
    PanelContext context;
    context.geometry = &geometry;
    context.tau_min = tension_settings.tau_min;
    context.tau_max = tension_settings.tau_max;
    context.fps = io.Framerate;
    context.drag_mode = DragModeText(drag);
    context.top = menu_height;
    context.link = &latest.link;
    context.real_hand = runtime_settings.device == RuntimeDevice::kUsb;
    context.board_sim = runtime_settings.device == RuntimeDevice::kBoardSim;
    const PanelActions actions =
        DrawDevicePanel(state, context, &field, static_cast<float>(win_h));
    bool republish = actions.field_changed;
    {
      // Modes: a small window of collapsing headers (collapsed at start, so it never hides the
      // view); each mode's own panel inside.
      ImGui::SetNextWindowPos(ImVec2(kPanelWidth + 8.0f, menu_height + 8.0f), ImGuiCond_FirstUseEver);
      ImGui::SetNextWindowSize(ImVec2(380.0f, 0.0f), ImGuiCond_FirstUseEver);
      ImGui::SetNextWindowCollapsed(options.mode.empty() && !assembly_mode.has_parts(), ImGuiCond_FirstUseEver);
      if (ImGui::Begin("Modes: FE push, sculpt")) {
        ImGui::SetNextItemOpen(options.mode == "fe", ImGuiCond_FirstUseEver);
        if (ImGui::CollapsingHeader("FE mode: push a part, feel its stiffness")) {
          bool on = fe_mode.active();
          if (ImGui::Checkbox("FE mode on", &on)) {
            fe_mode.SetActive(on);
            republish = true;
          }
          // "Pick a meshed object": the selected scene object's tetrahedra (Mesh → Tetrahedra).
          const bool has_tets = workbench.selected >= 0 &&
                                workbench.selected < static_cast<int>(model.objects().size()) &&
                                model.objects()[workbench.selected].tets.tets.cols() > 0;
          if (!has_tets) ImGui::BeginDisabled();
          if (ImGui::Button("Use the selected object's tetrahedra")) {
            const SceneObject& object = model.objects()[workbench.selected];
            fe_mode.SetMesh(ToFemMesh(object.tets), object.name);
          }
          if (!has_tets) {
            ImGui::EndDisabled();
            ImGui::SameLine();
            ImGui::TextDisabled("(select an object, Mesh > Tetrahedra first)");
          }
          fe_mode.DrawPanel();
        }
        ImGui::SetNextItemOpen(options.mode == "sculpt", ImGuiCond_FirstUseEver);
        if (ImGui::CollapsingHeader("Sculpt mode: shape the clay with the grip")) {
          bool on = sculpt_mode.active();
          if (ImGui::Checkbox("Sculpt mode on", &on)) {
            sculpt_mode.SetActive(on);
            republish = true;
          }
          sculpt_mode.DrawPanel();
        }
        if (assembly_mode.has_parts()) {
          ImGui::SetNextItemOpen(true, ImGuiCond_FirstUseEver);
          if (ImGui::CollapsingHeader("Assembly: pick, carry and seat the parts")) {
            assembly_mode.DrawPanel();
          }
        }
      }
      ImGui::End();
    }
    if (options.mode == "fe" && !fe_precompute_started && !jobs.busy()) {
      fe_mode.Precompute();  // the platform mesh has landed (or failed: the panel says so)
      fe_precompute_started = true;
    }
    fe_mode.OnFrame(latest.tool);
    sculpt_mode.OnFrame(latest.tool);
    assembly_mode.OnFrame();
    if (assembly_mode.TakeFieldChanged()) republish = true;  // Reset parts
    if (auto f = fe_mode.TakeField()) {
      fe_field = std::shared_ptr<haptics::ForceField>(std::move(f));
      republish = true;
    }
    if (auto f = sculpt_mode.TakeField()) {
      sculpt_field = std::shared_ptr<haptics::ForceField>(std::move(f));
      republish = true;
    }
    if (republish) publish_scene();
    DrawScenePanel(&model, &jobs, &workbench, static_cast<float>(win_w) - kScenePanelWidth - 8.0f,
                   menu_height + 8.0f, kScenePanelWidth, &tree, &tree_state,
                   static_cast<float>(win_h) - menu_height - 300.0f);  // above the loop panel
    // Tree edits, undo and redo: recompile what changed, republish the haptic scene (X_WD
    // stays), re-mesh the previews (coarse first).
    HandleTreeShortcuts(&tree, &tree_state);
    DrawSaveAsDialog(&tree, &tree_state);
    if (model.Refresh()) publish_scene();
    if (workbench.contact_changed) {  // the Touch controls (Haptics menu)
      workbench.contact_changed = false;
      publish_scene();
    }
    model.UpdatePreviews(&jobs);
    if (const std::string title = tree.Title(); title != window_title) {
      glfwSetWindowTitle(window, title.c_str());
      window_title = title;
    }
    const LoopStats stats = CollectLoopStats(runtime, latest);
    DrawLoopPanel(stats, static_cast<float>(win_w) - 8.0f, static_cast<float>(win_h) - 8.0f, &wb);
    if (stats.emergency_stop) {
      DrawStopBanner(kPanelWidth, kPanelWidth + 0.5f * (win_w - kPanelWidth - kScenePanelWidth),
                     menu_height + 10.0f);
    }
    DrawExportDialog(model, &workbench);
    if (actions.reset_grip || wb.reset_grip) grip.Reset();
    if (actions.board_plug != 0) runtime.RequestBoardPlugged(actions.board_plug > 0);
    if (actions.reset_camera || wb.reset_camera) view.ResetCamera();
    if (actions.quit || wb.quit) quit = true;
    if (wb.emergency_stop) runtime.EmergencyStop();
    if (wb.rearm) runtime.Rearm();
    ImGui::Render();

    // VTK draws the scene into the window, then ImGui draws the panel over it.
    BindDefaultFramebuffer(fb_w, fb_h);
    ClearDefaultFramebuffer(0.965f, 0.968f, 0.975f);
    render_window->Render();
    BindDefaultFramebuffer(fb_w, fb_h);
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());

    // A screenshot waits (within kSettleTimeout) for the preview meshes, for FE mode's part to
    // be live (FeMode::Settled) and for the loop to settle: force ramp complete, or the stop's
    // zero force in effect.
    const bool settled =
        !jobs.busy() && fe_mode.Settled() && (stats.emergency_stop ? (latest.tool.events & haptics::kEventEmergencyStop) != 0
                                              : latest.tool.ramp >= 1.0 ||
                                                    // no board: zero force is the settled state
                                                    latest.link.status == haptics::DeviceStatus::kNotConnected);
    const bool waited_enough = settled || glfwGetTime() - start_time > kSettleTimeout;
    // A trajectory's outcome: the capture waits until it has ended (+0.5 s), --frames runs on.
    const bool trajectory_over = player == nullptr || player->finished(0.5);
    if (capture && frame_index >= last_frame && waited_enough && trajectory_over) {
      const std::string error =
          WritePng(options.screenshot, ReadBackBuffer(fb_w, fb_h), fb_w, fb_h);
      if (!error.empty()) {
        std::cerr << "spidarcad: " << error << "\n";
        return 1;
      }
      std::cout << "spidarcad: wrote " << options.screenshot << " (" << fb_w << "x" << fb_h
                << ")" << (settled ? "" : " before the loop settled") << "\n";
      break;
    }
    glfwSwapBuffers(window);
    if (!capture && last_frame > 0 && frame_index >= last_frame && trajectory_over) break;
  }
  runtime.Stop();
  if (capture || options.frames > 0) {
    std::cout << FormatLoopSummary(CollectLoopStats(runtime, runtime.Latest()));
    if (fe_mode.active()) std::cout << FormatFeSummary(fe_mode, runtime.Latest().tool);
    if (assembly_mode.has_parts()) {
      assembly_mode.OnFrame();  // the field's last tick
      std::cout << FormatAssemblySummary(assembly_mode);
    }
    std::cout << std::flush;
  }
  return exit_status;
}

}  // namespace spidarcad::app
