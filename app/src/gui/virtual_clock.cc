// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/virtual_clock.h"

#include <unistd.h>

#include <filesystem>

#include "doc/input_error.h"

namespace spidarcad::app {

VirtualClock::VirtualClock(const ScriptedRunOptions& options, Document* doc, const std::string& out)
    : run_(std::make_unique<ScriptedRun>(options, doc)), out_(out) {
  const std::filesystem::path path(out);
  temporary_ = (path.parent_path() / ("." + path.filename().string() + ".part-" +
                                      std::to_string(static_cast<long>(getpid()))))
                   .string();
  file_.open(temporary_);
  if (!file_) throw InputError("--out: cannot write '" + out + "'");
  file_ << run_->CsvHeader();
}

VirtualClock::~VirtualClock() {
  if (finished_) return;
  file_.close();
  std::error_code ec;
  std::filesystem::remove(temporary_, ec);
}

void VirtualClock::StepFrame() {
  for (long i = 0; i < kSculptFrameTicks && !run_->done(); ++i) run_->Step(&buffer_);
  if (buffer_.size() > (1 << 16)) {
    file_ << buffer_;
    buffer_.clear();
  }
}

void VirtualClock::Finish(std::ostream* summary) {
  if (finished_) return;
  file_ << buffer_;
  buffer_.clear();
  file_.close();
  if (!file_) throw InputError("--out: failed writing '" + out_ + "'");
  std::error_code ec;
  std::filesystem::rename(temporary_, out_, ec);
  if (ec) throw InputError("--out: cannot write '" + out_ + "': " + ec.message());
  finished_ = true;
  run_->Finish();
  *summary << run_->Summary() << "wrote " << out_ << " (" << run_->ticks() << " rows)\n";
}

}  // namespace spidarcad::app
