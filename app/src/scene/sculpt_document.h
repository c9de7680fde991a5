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

}  // namespace spidarcad::app
