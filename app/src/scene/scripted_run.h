// A scripted haptic session on a virtual clock: what `spidarcad run` does, as one piece that the
// window (`--clock virtual`) uses too, so that both give the same CSV for the same options.
//
// Document -> fields: the scene (empty, run's demo, or a scene file or document) becomes one
// HapticScene with the builders the window's modes use (scene_haptics.h for solids, fe_part.h
// for FE models, assembly_scene.h for rigid parts, sculpt_document.h for every sculpt object,
// snap). Device: the rig of --device (device_rig.h: simulated, ideal, board-sim with scripted
// link faults, usb) gripped by a simulated hand that follows the trajectory. Stepping: one
// HapticLoop::Step per tick of 1 ms; every kSculptFrameTicks ticks the sculpt sessions step on
// the tick's tool state (as the window steps its sculpt mode once a frame). CSV rows: one per
// tick, the columns of CsvHeader() (docs/cli.md, run).
//
// Modelling by touch (--place KIND): a TouchSession (scene/touch_session.h) on the document steps
// every kSculptFrameTicks ticks on the tick's tool state, as model mode does once a frame: the
// ghost follows the measured grip, a squeeze (SqueezeDetector) places it as one command, and its
// felt snap field, in the scene from the first tick (TouchSnapSlotField), pulls from the next
// tick on. The solids placed are not felt during the run (its fields are built before the first
// tick); --save writes them.
//
// Sculpt objects (every one of the document): each is a DocumentSculpt session felt through its
// own sculpt tool field. The rule for which clay a stroke sculpts: while a stroke is under way
// on one clay, only that clay's session steps; otherwise only the session of the clay nearest
// the grip centre (nearest vertex within the stroke's snap distance; ties: document order)
// steps, so one closing of the grasp begins at most one stroke, on the clay the grip touches.
//
// Main thread only (a real board's run sleeps in Step to keep 1 kHz). Frames and units: the
// trajectory and the CSV's pose and wrench columns in D; FE and sculpt columns in W; SI.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include "doc/document.h"
#include "scene/haptic_runtime.h"
#include "spidarcad/haptics/device_to_world.h"
#include "spidarcad/haptics/geometry.h"
#include "spidarcad/haptics/haptic_loop.h"

namespace spidarcad::app {

class TouchSession;

// The sculpt sessions step every this many ticks of the virtual clock (62.5 Hz), as the window
// steps its sculpt mode once a frame; the window on the virtual clock renders one frame per as
// many ticks.
inline constexpr long kSculptFrameTicks = 16;

// Options of a scripted run (the options of `spidarcad run`, docs/cli.md). Checked by
// ScriptedRun's constructor; every problem is an InputError naming the option.
struct ScriptedRunOptions {
  std::string scene;                 // "" or "none" (empty), "demo" (run's demo fields) or a file
  std::string trajectory;            // trajectory CSV (t,x,y,z,qw,qx,qy,qz,grasp; D)
  std::string device = "simulated";  // simulated, ideal, board-sim or usb
  std::vector<double> hand;          // --hand stiffness,damping (empty: 300, 20)
  std::uint64_t seed = 1;            // the simulated device's errors and noise
  std::string tool = "proxy";        // solids: proxy or shell
  double stiffness = 1500.0;         // N/m at the grip
  double damping = 1.0;              // N·s/m at the grip
  std::vector<double> friction;      // static,dynamic (empty: 0.3, 0.2)
  double world_scale = 0.0;          // 0: fitted
  std::vector<double> world_origin;  // x,y,z, m (empty: fitted)
  bool calibrate = false;            // line-fit calibration of the simulated device first
  std::string calibration;           // calibration file to read the encoders through
  haptics::SpidarGeometry geometry;  // the device's frame and pole (--frame, --pole)
  bool geometry_given = false;       // --frame or --pole given: it overrides the document's
  double max_duration = 3600.0;      // s: longest run accepted (docs/limits.md)
  bool fe_grab = false;              // FE parts: grabbed by the closing grasp instead of pushed
  bool fe_grasp = false;             // FE parts: two-point grasp contact instead of the sphere
  double fe_tool_radius = 0.01;      // FE parts: the tool's physical radius, m on the part (W)
  std::vector<std::string> save;     // --save OUT: the document at the end of the run
  std::vector<std::string> exports;  // --export NAME=FILE: one object's final state
  std::string sculpt_tool = "grab";  // sculpt objects: the tool of every stroke
  double sculpt_radius = 0.02;       // sculpt objects: falloff radius R, m (W)
  bool conserve_volume = false;      // sculpt objects: keep each stroke's enclosed volume
  // Modelling by touch (--place sphere|box|cylinder; "" off): the grip places that primitive as
  // model mode does (scene/touch_session.h): its ghost aligns to the document's faces, edges and
  // axes, their snap pull is felt, and each quick squeeze of the grasp adds it as a solid.
  std::string place;
  // board-sim link faults (haptics::usb::LinkFaults), seeded by link_seed (0: --seed):
  double link_loss = 0.0;        // probability that a packet (either direction) vanishes
  double link_corruption = 0.0;  // probability that a packet arrives with 1..3 bits flipped
  std::uint64_t link_seed = 0;
  // board-sim: the cable is pulled at trajectory time unplug_at and put back at replug_at (s;
  // NaN: never).
  double unplug_at = std::numeric_limits<double>::quiet_NaN();
  double replug_at = std::numeric_limits<double>::quiet_NaN();
};

// One scripted session (see the file comment). Construct (all the set-up: document, fields,
// device, calibration, FE columns along the path), then Step ticks() times, then Finish.
class ScriptedRun {
 public:
  // Checks `options` and builds the session. `doc`: null to open options.scene as `run` does
  // (OpenDocumentFile); else the caller's document of options.scene (not "demo" or empty),
  // opened from that file and not edited since, which the run then acts on (sculpt strokes
  // are recorded in it) and which must outlive it. Throws InputError naming the option, file,
  // line and field.
  explicit ScriptedRun(const ScriptedRunOptions& options, Document* doc = nullptr);
  ~ScriptedRun();
  ScriptedRun(const ScriptedRun&) = delete;
  ScriptedRun& operator=(const ScriptedRun&) = delete;

  // Ticks of the run: from the trajectory's first sample to its last, 1 ms apart.
  long ticks() const;
  // Ticks stepped so far.
  long ticks_done() const;
  bool done() const { return ticks_done() >= ticks(); }
  // The CSV's header line (with its newline): today's columns, then the FE, sculpt and link
  // columns this run has.
  const std::string& CsvHeader() const;
  // Names of the CSV columns that hold wall-clock timing, not physics ("tick_us"): two runs
  // with the same options differ only there.
  static std::vector<std::string> TimingColumns();
  // Runs the next tick and appends its CSV row (with its newline) to *csv (not null). Throws
  // InputError when a sculpt step fails. Not after done().
  void Step(std::string* csv);
  // After the last tick: ends every stroke still under way (as if the grasp opened there).
  void Finish();
  // Calls `before` right before and `after` right after each tick's HapticLoop::Step (on the
  // thread that calls Step; either may be empty), so that a caller can time exactly the loop's
  // ticks of the run (the tick table's golden rows, cli/report_tick.h).
  void SetStepHooks(std::function<void()> before, std::function<void()> after);
  // Latches (true) or releases (false) the loop's emergency stop: zero force from the next tick
  // (HapticLoop::RequestEmergencyStop), forces back through the ramp after the release.
  void EmergencyStop(bool stop);

  // The summary printed by `run` after the ticks: the "run: N ticks ..." line, link,
  // calibration, fields, FE, sculpt, frame, X_WD, tick time, safety events, the largest force
  // and the assembly.
  std::string Summary() const;
  // Writes --export and --save (each with its "wrote ..." line on *out). Throws InputError.
  void WriteOutputs(std::ostream* out) const;

  // ---- the latest tick, for the window ----
  // The loop's output of the latest tick, the true grip pose (the hand's; usb: measured), the
  // calibrated string lengths, the tick's compute time and the rig's link, as the window's
  // haptic runtime publishes them.
  const RuntimeFrame& frame() const;
  // The map from D to W of the run (fitted or given).
  const haptics::DeviceToWorld& X_WD() const;
  // The device (geometry, encoder, tension range).
  const haptics::DeviceInfo& info() const;
  const haptics::HapticLoop& loop() const;
  // Sculpt strokes ended so far, over all sculpt objects.
  int sculpt_strokes() const;
  // With --place: the run's modelling by touch (the window shows its ghost); else null.
  const TouchSession* touch() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace spidarcad::app
