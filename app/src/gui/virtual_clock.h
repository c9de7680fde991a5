// The window's virtual clock (`spidarcad SCENE --clock virtual --trajectory T.csv --out R.csv`):
// the scripted run of `spidarcad run` (scene/scripted_run.h) stepped kSculptFrameTicks ticks
// per frame in the window's process, its CSV rows written to a hidden temporary next to --out
// and renamed over it when the run is complete (a window closed earlier leaves no file).
// Main thread only.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <fstream>
#include <memory>
#include <ostream>
#include <string>

#include "doc/document.h"
#include "scene/scripted_run.h"

namespace spidarcad::app {

class VirtualClock {
 public:
  // Builds the run (ScriptedRun on `doc`, or on its own document when null) and opens the
  // temporary of `out`. Throws InputError naming the option or file.
  VirtualClock(const ScriptedRunOptions& options, Document* doc, const std::string& out);
  // Removes the temporary unless Finish renamed it.
  ~VirtualClock();
  VirtualClock(const VirtualClock&) = delete;
  VirtualClock& operator=(const VirtualClock&) = delete;

  // One frame: the next kSculptFrameTicks ticks (fewer at the end). Throws InputError when a
  // sculpt step fails.
  void StepFrame();
  bool done() const { return run_->done(); }
  // Once done: ends the strokes under way, writes the rest of the CSV, renames it over --out
  // and writes the run's summary and "wrote R.csv (N rows)" to *summary. Throws InputError
  // when the file cannot be written.
  void Finish(std::ostream* summary);
  bool finished() const { return finished_; }
  const ScriptedRun& run() const { return *run_; }
  // The window's emergency stop (Space, the panel's button) and its release, on the run's loop.
  void EmergencyStop(bool stop) { run_->EmergencyStop(stop); }

 private:
  std::unique_ptr<ScriptedRun> run_;
  std::string out_, temporary_;
  std::ofstream file_;
  std::string buffer_;
  bool finished_ = false;
};

}  // namespace spidarcad::app
