// `spidarcad run`: a headless haptic session. The full haptic loop (HapticLoop) runs on a
// virtual clock at 1 kHz against the simulated SPIDAR-G (strings, encoders and calibration
// error included), gripped by a simulated hand that follows a scripted trajectory and is pushed
// by the device's wrench. One CSV row per tick; a summary on stdout. --device picks the path to
// the device (DeviceRig, scene/device_rig.h, shared with the window): the simulated SPIDAR-G
// directly, the USB driver over the in-process board simulator (board-sim), or the USB driver
// over libusb to a real board (usb, real time).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "cli/run_command.h"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "cli/interrupt_output.h"
#include "scene/scripted_run.h"
#include "scene/scripted_run_options.h"

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
    "  ideal      the simulated SPIDAR-G without encoder errors, noise or stretch (quantisation\n"
    "             and motor lag remain), read through the nominal calibration, held by a rigid\n"
    "             hand: the grip is exactly the trajectory's pose (the window's --device ideal)\n"
    "  board-sim  the same simulated SPIDAR-G behind the controller board's firmware\n"
    "             simulator, driven by the USB driver (UsbSpidarG) over the in-process loopback\n"
    "             transport: the driver's whole path, packets byte for byte (docs/protocol.md),\n"
    "             without hardware. Forces match `simulated` to within a few hundredths of a\n"
    "             newton (tensions travel in mN; the handshake shifts the device's noise by a\n"
    "             sample); the summary adds the link statistics.\n"
    "             Scripted link faults (seeded by --link-seed, default --seed): --link-loss P\n"
    "             and --link-corruption P per packet, --unplug T1 pulls the cable at trajectory\n"
    "             time T1 and --replug T2 puts it back (the board power-cycles, the driver\n"
    "             re-handshakes, forces ramp in again over 0.5 s). With any of them the CSV\n"
    "             adds link_status,plugged,link_lost,link_corrupt (below).\n"
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
    "Sculpt objects: every sculpt object of the document is sculpted by the grip, as in the\n"
    "window's sculpt mode (scene/sculpt_field.h, scene/scripted_run.h). Every 16 ticks of the\n"
    "virtual clock (62.5 Hz, the window's frame) a sculpt session steps on the tool state: the\n"
    "session of the clay under a stroke, else that of the clay nearest the grip centre (nearest\n"
    "vertex within the tool radius; ties: document order). A stroke begins when the grasp\n"
    "closes below 70 deg with the grip centre within the tool radius of that clay, follows the\n"
    "grip, and ends when the grasp opens above 80 deg (a stroke still under way at the last\n"
    "tick ends there); each stroke is recorded in the document. The stroke's resisting wrench\n"
    "is felt through that clay's sculpt tool field (300 N/m).\n"
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
    "--place sphere|box|cylinder (documents of solids, not assemblies): modelling by touch, as\n"
    "the window's model mode with --place (scene/touch_session.h). Every 16 ticks (the window's\n"
    "frame) a ghost of the primitive is put at the measured grip, sized by the grasp (c = s·d·θ,\n"
    "θ clamped to 20..160 deg: the sphere's and cylinder's diameter, the box's edge) and aligned\n"
    "to the document's solids: its centre onto a vertex within s·5 mm, else onto an edge or a\n"
    "round primitive's axis whose line passes within s·4 mm of its centre, else resting on a\n"
    "face its lowest point is within s·6 mm of. A snap field pulls the grip toward where the\n"
    "ghost would align (at most 0.8 N; the faces lifted by c/2 of the grasp once it has held\n"
    "within 2 % for 0.1 s, so a squeeze does not move them). A quick squeeze\n"
    "of the grasp (closed by 10 deg and opened again by 10 deg within 0.4 s) adds the ghost as\n"
    "it was when the squeeze began as a new solid (one command; --save writes it). The solids\n"
    "placed are not felt during the run. The summary lists each place.\n"
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
    "  sculpt_stroke     (documents with sculpt objects only) while a stroke is under way the\n"
    "                    1-based index (document order) of the clay it sculpts, else 0\n"
    "  sculpt_volume     (the same) enclosed volume of the first clay, m^3; sculpt_volume2 ...\n"
    "                    sculpt_volumeN the others'\n"
    "  link_status       (board-sim with scripted faults only) the driver's status after the\n"
    "                    tick: 0 ok, 1 not_connected, 2 comm_error, 3 fault, 4 stopped\n"
    "  plugged           (the same) 1 while the simulated cable is in\n"
    "  link_lost,link_corrupt  (the same) the driver's counts so far of State packets lost\n"
    "                    (sequence gaps) and corrupt (bad CRC, length or magic)\n"
    "  touch_feature     (--place only) what the ghost aligned to at the latest frame: 0 none,\n"
    "                    1 face, 2 edge, 3 axis, 4 vertex\n"
    "  touch_size        (the same) the ghost's size c, m (W)\n"
    "  touch_lift        (the same) the felt faces' lift (c/2 of the latest steady grasp), m\n"
    "                    (W); 0 with no felt field\n"
    "  placed            (the same) solids placed so far\n"
    "\n"
    "The window gives the same CSV with `spidarcad SCENE --clock virtual --trajectory T.csv\n"
    "--out R.csv` and these options (docs/user-guide.md, scripted runs); only tick_us, the\n"
    "wall-clock time, differs.\n"
    "\n"
    "Example:\n"
    "  spidarcad run demo --trajectory assets/trajectories/press.csv --out press_result.csv\n"
    "  spidarcad run assets/scenes/platform.json --trajectory assets/trajectories/press.csv \\\n"
    "      --out platform_press.csv --world-scale 1 --world-origin 0.1,0,0.04\n"
    "  spidarcad run assets/scenes/platform_fe.json --trajectory assets/trajectories/press.csv \\\n"
    "      --out platform_fe_press.csv --world-scale 1 --world-origin 0.1,0,0.04";

// `spidarcad run`'s options: the scripted run's, the output and the progress.
struct RunOptions {
  ScriptedRunOptions run;
  std::string out;
  bool progress = false;  // progress on stderr even when it is not a terminal
};

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

void RunRun(const RunOptions& options) {
  ScriptedRun run(options.run);  // every check and the whole set-up; InputError: exit 2
  // Ctrl+C stops the loop at the next tick (the rig is stopped as on any exit) with status 130;
  // the CSV goes to a hidden temporary renamed over --out when complete, so no half-written
  // file is left (a second Ctrl+C ends at once, removing the temporary).
  InterruptibleOutput output(options.out, "run", InterruptibleOutput::Mode::kFlag);
  std::ofstream out(output.temporary());
  if (!out) throw InputError("--out: cannot write '" + options.out + "'");
  out << run.CsvHeader();
  std::string buffer;
  const long ticks = run.ticks();
  RunProgress progress(options.progress || isatty(STDERR_FILENO) == 1, ticks);
  for (long k = 0; k < ticks; ++k) {
    if (output.interrupted()) output.Stop();
    progress.Tick(k);
    run.Step(&buffer);
    if (buffer.size() > (1 << 16)) {
      out << buffer;
      buffer.clear();
    }
  }
  out << buffer;
  out.close();
  if (!out) throw InputError("--out: failed writing '" + options.out + "'");
  output.Commit();
  run.Finish();
  std::cout << run.Summary();
  std::cout << "wrote " << options.out << " (" << ticks << " rows)\n";
  run.WriteOutputs(&std::cout);
  std::cout << std::flush;
  throw CommandExit{0};
}

}  // namespace

void AddRunCommandOptions(CLI::App* cmd, ScriptedRunOptions* run) {
  cmd->add_option("scene", run->scene, "Scene: omitted (empty), 'demo' or a scene file (.json)");
  cmd->add_option("--trajectory", run->trajectory, "Trajectory CSV (t,x,y,z,qw,qx,qy,qz,grasp)")
      ->required();
  cmd->add_option("--device", run->device,
                  "Device: simulated (default), ideal (no encoder errors, rigid hand), board-sim "
                  "(USB driver over the board simulator) or usb (a real board)");
  cmd->add_option("--seed", run->seed, "Seed of the simulated device's errors (default 1)");
  cmd->add_option("--calibration", run->calibration,
                  "Read the encoders through this calibration file (`spidarcad calibrate --out`; "
                  "it must be this device's and frame's)");
  AddGeometryOptions(*cmd, &run->geometry, &run->geometry_given);
  AddScriptedRunOptions(*cmd, run);
  cmd->add_option("--place", run->place,
                  "Documents of solids: model by touch, placing this primitive (sphere, box or "
                  "cylinder) as the window's model mode does: the snap pull toward vertices, "
                  "faces, edges and axes is felt and each quick squeeze of the grasp adds it as "
                  "a solid")
      ->type_name("KIND");
  cmd->add_option("--save", run->save,
                  "Documents: write the document as it stands at the end of the run to OUT "
                  "(repeatable)")
      ->type_name("OUT")
      ->allow_extra_args(false);
  cmd->add_option("--export", run->exports,
                  "Documents: write one object's final state, NAME=FILE (repeatable); an FE model "
                  "as .vtu with point data displacement and von_mises, a sculpt object's surface "
                  "as .stl, .obj or .ply")
      ->type_name("NAME=FILE")
      ->allow_extra_args(false);
}

void RegisterRunCommand(CLI::App& app) {
  auto options = std::make_shared<RunOptions>();
  CLI::App* cmd = app.add_subcommand("run", "Headless haptic session on a scripted trajectory");
  cmd->footer(kRunHelp);
  AddRunCommandOptions(cmd, &options->run);
  cmd->add_option("--out", options->out, "Result CSV, one row per tick")->required();
  cmd->add_flag("--progress", options->progress,
                "Show progress on stderr even when it is not a terminal");
  cmd->callback([options]() { RunRun(*options); });
}

}  // namespace spidarcad::app
