// Rendering side of the scene: one VTK actor per scene object showing its preview surface, and
// one per imported mesh object of the Document (a MeshData without a source: its surface, or the
// boundary of its tetrahedra), placed in the device frame D of the view by the inverse of X_WD
// (p_D = (p_W − p_WDo) / s). A mesh made from a solid stands where the solid is, so it is drawn
// only when asked for (SetShownMesh: the tree's selection in model mode), with its edges and in
// place of its source (whose actor is hidden meanwhile: the two would z-fight). No meshing here:
// it copies what SceneModel and the Document have.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <array>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "scene/scene_model.h"

class vtkActor;
class vtkPolyData;
class vtkRenderer;

namespace spidarcad::app {

// Replaces `poly`'s points and polygons with `mesh`'s vertices and triangles (coordinates as
// they are) and marks it modified.
void FillPolyData(const modeling::TriangleMesh& mesh, vtkPolyData* poly);

// Colour of imported meshes (RGB in [0, 1]): a steel grey-blue, unlike the solids' colours.
inline constexpr std::array<double, 3> kImportedMeshColour = {0.58, 0.66, 0.78};

// The surface SceneView draws for a mesh object: its surface, else the boundary of its
// tetrahedra (modeling::BoundarySurface); empty when it has neither.
modeling::TriangleMesh DrawnSurface(const MeshData& mesh);

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

  // The contact markers (SceneModel::ContactMarkers): a small sphere (radius kMarkerRadius in
  // D) at each marker's proxy / virtual tool centre that is in contact, was written at most
  // kMarkerMaxAge before `now` (the loop time of the latest ToolState; an older one belongs to
  // a scene no longer felt) and lies more than kMarkerMinOffset (in D) from the tool point, in
  // the view's frame D through the inverse of `x_wd`; every other marker hidden. Returns the
  // number shown.
  int ShowContacts(const std::vector<ContactMarker>& markers, double now,
                   const DeviceToWorld& x_wd);
  static constexpr double kMarkerRadius = 0.005;    // m in D
  static constexpr double kMarkerMaxAge = 0.1;      // s
  static constexpr double kMarkerMinOffset = 3e-4;  // m in D
  // The mesh object made from a source to draw (with its edges, its source's actor hidden), or 0
  // for none. Imported meshes are drawn whatever this is.
  void SetShownMesh(ObjectId mesh) { shown_mesh_ = mesh; }
  ObjectId shown_mesh() const { return shown_mesh_; }
  // Solids (by name) whose actors stay hidden: an assembly's part solids, which AssemblyMode
  // draws where the parts are (the solids themselves sit at their own frame origins).
  void SetHidden(std::vector<std::string> names) { hidden_ = std::move(names); }
  // The Document object whose actor is nearest the eye under display pixel (x, y) of the
  // renderer's window (origin bottom left): a VTK cell picker on the visible scene actors and
  // imported-mesh actors only (the device, the grip and the markers are not picked). 0 when
  // none is there. `extra` adds actors of other objects to pick from (an assembly's parts, drawn
  // by AssemblyMode); the nearest hit wins either way.
  ObjectId PickObject(double x, double y,
                      const std::vector<std::pair<vtkActor*, ObjectId>>& extra = {}) const;
  // The actor of Document object `id`, a solid, an imported mesh or the shown mesh (null when it
  // has none).
  vtkActor* ActorOf(ObjectId id) const;

 private:
  struct Entry;
  // Brings the imported meshes' and the shown mesh's actors in line with the Document (by id and
  // revision).
  void SyncMeshes(const Document& doc, const DeviceToWorld& x);
  vtkRenderer* renderer_;
  std::vector<std::unique_ptr<Entry>> entries_;
  std::vector<std::unique_ptr<Entry>> mesh_entries_;  // drawn mesh objects, document order
  int generation_ = -1;
  struct Marker;
  std::vector<std::unique_ptr<Marker>> markers_;  // sphere actors, grown on demand
  std::vector<std::string> hidden_;
  ObjectId shown_mesh_ = 0;
};

}  // namespace spidarcad::app
