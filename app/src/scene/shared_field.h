// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// A force field shared between successive HapticScenes. The window rebuilds and republishes its
// HapticScene whenever something changes (a solid edited, a setting moved), but a mode's field
// (FE contact, sculpt stroke) keeps state between ticks and should survive the swap. The window
// keeps the mode's field in a shared_ptr and adds a SharedField forwarding to it into every scene
// it builds. Reference counts change on the main thread only (scene construction and the deletion
// of retired scenes, see haptic_loop.h); the haptic thread only calls Evaluate through the
// pointer, so the field outlives every scene that still refers to it.
#pragma once

#include <memory>
#include <utility>

#include "spidarcad/haptics/force_field.h"

namespace spidarcad::app {

// Forwards Evaluate and name to a shared field (real-time safe when the target is).
class SharedField final : public haptics::ForceField {
 public:
  // `target` must not be null.
  explicit SharedField(std::shared_ptr<haptics::ForceField> target) : target_(std::move(target)) {}
  haptics::ToolWrench Evaluate(const haptics::ToolKinematics& tool) noexcept override {
    return target_->Evaluate(tool);
  }
  const char* name() const noexcept override { return target_->name(); }

 private:
  std::shared_ptr<haptics::ForceField> target_;
};

}  // namespace spidarcad::app
