// Rendering side of the scene: one VTK actor per scene object showing its current mesh (the
// preview surface, then the Mesh action's result), placed in the device frame D of the view by
// the inverse of X_WD (p_D = (p_W − p_WDo) / s). No meshing here: it copies what SceneModel has.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <memory>
#include <vector>

#include "gui/scene_model.h"

class vtkRenderer;

namespace spidarcad::app {

// The scene objects' actors in a renderer.
class SceneView {
 public:
  // Adds its actors to `renderer` (which must outlive this view).
  explicit SceneView(vtkRenderer* renderer);
  ~SceneView();
  SceneView(const SceneView&) = delete;
  SceneView& operator=(const SceneView&) = delete;

  // Brings the actors in line with `model`: one actor per scene object, matched by Document
  // object id (objects added, deleted or reordered by edits get their own actors); rebuilds an
  // object's polydata when its revision, its id or the scene's generation changed, colours it
  // (a solid whose latest edit did not compile is tinted red while it shows its last good
  // mesh) and places every actor by the inverse of X_WD. `highlight` (an object index, or −1)
  // is drawn with its mesh edges.
  void Sync(const SceneModel& model, int highlight = -1);

 private:
  struct Entry;
  vtkRenderer* renderer_;
  std::vector<std::unique_ptr<Entry>> entries_;
  int generation_ = -1;
};

}  // namespace spidarcad::app
