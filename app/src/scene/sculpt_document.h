// Sculpt mode and the Document (issue 12, "one workbench, one document"): what a sculpt session
// needs to act on a sculpt object of the Document instead of a clay of its own.
//
// - Which objects can be sculpted: the Document's sculpt objects directly; a copy of an implicit
//   solid (meshed first) or of a mesh object whose surface is closed.
// - A finished stroke as one command (doc/command.h): SculptStroke with the moved vertices when
//   the stroke kept the topology, ReplaceSculptMesh with the whole mesh when refinement split
//   edges; titled "Sculpt stroke (TOOL) on NAME".
//
// Main thread only. Units: m (W).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <memory>
#include <string>

#include "doc/command.h"
#include "doc/document.h"
#include "scene/sculpt_field.h"
#include "spidarcad/modeling/sculpt.h"
#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::app {

// The closed surface a sculpt copy of `object` starts from: a mesh object's surface when it is
// closed (at least 4 vertices and 4 triangles, indices in range and distinct per triangle, every
// directed edge exactly once and its reverse exactly once: closed, edge-manifold, consistently
// oriented, what modeling::SculptMesh accepts), else null (solids are meshed by a Job; other
// kinds have none).
std::shared_ptr<const modeling::TriangleMesh> SculptableSurface(const DocObject& object);

// True for the objects a sculpt copy can be made of: implicit solids and mesh objects with a
// closed surface.
bool CanSculptCopyOf(const DocObject& object);

// The Edit-menu text of a stroke: "Sculpt stroke (grab) on clay".
std::string SculptStrokeTitle(modeling::SculptTool tool, const std::string& object_name);

// The command recording a stroke that `mesh` has just ended (`edit`, from SculptMesh::EndStroke)
// on sculpt object `id` named `name`: ReplaceSculptMesh with mesh.ToTriangleMesh() when
// refinement changed the topology, else SculptStroke with the vertices whose position changed
// and their new positions. Null when the stroke moved nothing (nothing to record).
std::unique_ptr<Command> MakeStrokeCommand(ObjectId id, const std::string& name,
                                           modeling::SculptTool tool,
                                           const modeling::SculptEdit& edit,
                                           const modeling::SculptMesh& mesh);

// A sculpt object of a Document sculpted without a window (`spidarcad run`): a SculptSession
// loaded from the object's mesh, stepped once a frame from the tool state, each stroke that ends
// recorded in the Document as one MakeStrokeCommand (as the window's sculpt mode records it), so
// that the Document holds the sculpted clay. The Document must outlive this binding and change
// only through it meanwhile. Main thread only.
class DocumentSculpt {
 public:
  // Loads sculpt object `id` of *doc with `settings` (validated; the spatial grid's cell is a
  // third of the tool radius). Throws std::invalid_argument naming the object when it is not a
  // sculpt object, its mesh is not closed, or a setting is out of range.
  DocumentSculpt(Document* doc, ObjectId id, const SculptModeSettings& settings);
  // One frame: SculptSession::Step (no key: the grasp alone triggers strokes); a stroke that
  // ended is recorded in the Document.
  SculptFrameEvent Step(const haptics::ToolKinematics& tool);
  // Ends a stroke still under way (as if the grasp opened at `tool`) and records it; no-op
  // without one.
  void Finish(const haptics::ToolKinematics& tool);
  SculptSession& session() { return session_; }
  const SculptSession& session() const { return session_; }
  ObjectId id() const { return id_; }
  const std::string& name() const { return name_; }
  // Strokes ended so far (each a command in the Document, unless it moved nothing).
  int strokes() const { return strokes_; }
  // Enclosed volume of the clay when loaded (m³).
  double start_volume() const { return start_volume_; }
  // Thread CPU time (s) of the clay width's grid built when loaded.
  double start_grid_seconds() const { return start_grid_seconds_; }

 private:
  void Record();
  Document* doc_;
  ObjectId id_;
  std::string name_;
  SculptSession session_;
  int strokes_ = 0;
  double start_volume_ = 0.0;
  double start_grid_seconds_ = 0.0;
};

}  // namespace spidarcad::app
