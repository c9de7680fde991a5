// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Ctrl+C for a command that writes one output file (`spidarcad fem`, `spidarcad run`): the
// output is written to a hidden temporary beside it (.NAME.partial-PID.EXT) and renamed over it
// when complete, so an interrupted run leaves no half-written file and the old file, if any, as
// it was. While an InterruptibleOutput lives, SIGINT either ends the process at once with status
// 130 after removing the temporary (kExitAtOnce: for commands inside library calls that poll
// nothing), or raises a flag the command polls (kFlag: `run`'s tick loop, which then stops the
// device rig cleanly); a second Ctrl+C in kFlag mode ends at once like kExitAtOnce.
#pragma once

#include <string>

namespace spidarcad::app {

class InterruptibleOutput {
 public:
  enum class Mode { kExitAtOnce, kFlag };
  // `out`: the final path; `command` names the command in the message ("fem", "run").
  InterruptibleOutput(const std::string& out, const char* command, Mode mode);
  // Removes the temporary unless committed; restores the previous SIGINT handler.
  ~InterruptibleOutput();
  InterruptibleOutput(const InterruptibleOutput&) = delete;
  InterruptibleOutput& operator=(const InterruptibleOutput&) = delete;

  // Where to write.
  const std::string& temporary() const { return temporary_; }
  // kFlag: true once Ctrl+C was pressed.
  bool interrupted() const;
  // Moves the temporary over the final path; throws InputError naming --out on failure.
  void Commit();
  // Prints "spidarcad COMMAND: interrupted (Ctrl+C): stopped, nothing written" on stderr and
  // throws CommandExit{130} (the destructor removes the temporary).
  [[noreturn]] void Stop() const;

 private:
  std::string out_, temporary_, command_;
  bool committed_ = false;
};

}  // namespace spidarcad::app
