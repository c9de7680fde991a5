// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/scene_view.h"

#include <vtkActor.h>
#include <vtkCellArray.h>
#include <vtkCellPicker.h>
#include <vtkNew.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkPolyDataNormals.h>
#include <vtkProperty.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>
#include <vtkSphereSource.h>

#include <algorithm>
#include <cstdint>
#include <variant>

#include "spidarcad/modeling/cgal_mesher.h"

namespace spidarcad::app {

struct SceneView::Entry {
  vtkNew<vtkPolyData> poly;
  vtkNew<vtkPolyDataNormals> normals;
  vtkNew<vtkPolyDataMapper> mapper;
  vtkNew<vtkActor> actor;
  int revision = -1;
  ObjectId id = 0;
  std::uint64_t doc_revision = 0;  // imported meshes: the object revision drawn
};

// A contact marker's sphere.
struct SceneView::Marker {
  vtkNew<vtkSphereSource> sphere;
  vtkNew<vtkPolyDataMapper> mapper;
  vtkNew<vtkActor> actor;
};

SceneView::SceneView(vtkRenderer* renderer) : renderer_(renderer) {}

SceneView::~SceneView() {
  for (auto& e : entries_) renderer_->RemoveActor(e->actor);
  for (auto& e : mesh_entries_) renderer_->RemoveActor(e->actor);
  for (auto& m : markers_) renderer_->RemoveActor(m->actor);
}

int SceneView::ShowContacts(const std::vector<ContactMarker>& markers, double now,
                            const DeviceToWorld& x_wd) {
  const double inv = 1.0 / x_wd.world_scale;
  int shown = 0;
  for (const ContactMarker& m : markers) {
    const Eigen::Vector3d p_D = x_wd.PointToDevice(m.p_W);
    const bool visible = m.contact && m.time >= 0.0 && now - m.time <= kMarkerMaxAge &&
                         p_D.allFinite() && inv * (m.p_W - m.tool_W).norm() > kMarkerMinOffset;
    if (!visible) continue;
    if (shown == static_cast<int>(markers_.size())) {
      auto marker = std::make_unique<Marker>();
      marker->sphere->SetRadius(kMarkerRadius);
      marker->sphere->SetThetaResolution(16);
      marker->sphere->SetPhiResolution(12);
      marker->mapper->SetInputConnection(marker->sphere->GetOutputPort());
      marker->actor->SetMapper(marker->mapper);
      marker->actor->GetProperty()->SetColor(0.85, 0.08, 0.35);  // crimson: the god-object
      marker->actor->GetProperty()->SetAmbient(0.4);
      marker->actor->PickableOff();
      renderer_->AddActor(marker->actor);
      markers_.push_back(std::move(marker));
    }
    Marker& marker = *markers_[shown++];
    marker.actor->SetPosition(p_D.x(), p_D.y(), p_D.z());
    marker.actor->VisibilityOn();
  }
  for (std::size_t i = shown; i < markers_.size(); ++i) markers_[i]->actor->VisibilityOff();
  return shown;
}

void FillPolyData(const modeling::TriangleMesh& mesh, vtkPolyData* poly) {
  vtkNew<vtkPoints> points;
  points->SetNumberOfPoints(mesh.vertices.cols());
  for (Eigen::Index i = 0; i < mesh.vertices.cols(); ++i) {
    points->SetPoint(i, mesh.vertices(0, i), mesh.vertices(1, i), mesh.vertices(2, i));
  }
  vtkNew<vtkCellArray> cells;
  cells->AllocateExact(mesh.triangles.cols(), 3 * mesh.triangles.cols());
  for (Eigen::Index t = 0; t < mesh.triangles.cols(); ++t) {
    const vtkIdType ids[3] = {mesh.triangles(0, t), mesh.triangles(1, t), mesh.triangles(2, t)};
    cells->InsertNextCell(3, ids);
  }
  poly->Initialize();
  poly->SetPoints(points);
  poly->SetPolys(cells);
  poly->Modified();
}

modeling::TriangleMesh DrawnSurface(const MeshData& mesh) {
  if (mesh.surface != nullptr) return *mesh.surface;
  if (mesh.volume != nullptr && mesh.volume->tets.cols() > 0) {
    return modeling::BoundarySurface(*mesh.volume);
  }
  return {};
}

namespace {

// A new entry's VTK pipeline: polydata → normals → mapper → actor (hidden until filled).
template <typename Entry>
void SetUpEntry(Entry* e) {
  e->normals->SetInputData(e->poly);
  e->normals->SetFeatureAngle(35.0);
  e->normals->SplittingOn();
  e->normals->ConsistencyOff();
  e->mapper->SetInputConnection(e->normals->GetOutputPort());
  e->mapper->ScalarVisibilityOff();
  e->actor->SetMapper(e->mapper);
  e->actor->GetProperty()->SetAmbient(0.25);
  e->actor->GetProperty()->SetDiffuse(0.75);
  e->actor->GetProperty()->SetSpecular(0.1);
  e->actor->VisibilityOff();
}

}  // namespace

void SceneView::SyncMeshes(const Document& doc, const DeviceToWorld& x) {
  std::vector<const DocObject*> imported;
  for (const DocObject& o : doc.objects()) {
    const auto* m = std::get_if<MeshData>(&o.data);
    if (m != nullptr && (m->source == 0 || o.id == shown_mesh_)) imported.push_back(&o);
  }
  std::vector<std::unique_ptr<Entry>> next;
  for (const DocObject* o : imported) {
    std::unique_ptr<Entry> e;
    for (auto& old : mesh_entries_) {
      if (old != nullptr && old->id == o->id) e = std::move(old);
    }
    if (e == nullptr) {
      e = std::make_unique<Entry>();
      e->id = o->id;
      SetUpEntry(e.get());
      e->actor->GetProperty()->SetColor(kImportedMeshColour[0], kImportedMeshColour[1],
                                        kImportedMeshColour[2]);
      renderer_->AddActor(e->actor);
    }
    if (e->doc_revision != o->revision) {
      const modeling::TriangleMesh surface = DrawnSurface(std::get<MeshData>(o->data));
      FillPolyData(surface, e->poly);
      e->doc_revision = o->revision;
      e->actor->SetVisibility(surface.triangles.cols() > 0);
    }
    const double inv = 1.0 / x.world_scale;
    e->actor->SetScale(inv, inv, inv);
    e->actor->SetPosition(-inv * x.p_WDo.x(), -inv * x.p_WDo.y(), -inv * x.p_WDo.z());
    // A mesh made from a solid shows its cells: it stands where its solid would be drawn.
    e->actor->GetProperty()->SetEdgeVisibility(o->id == shown_mesh_ &&
                                               std::get<MeshData>(o->data).source != 0);
    e->actor->GetProperty()->SetEdgeColor(0.2, 0.25, 0.35);
    next.push_back(std::move(e));
  }
  for (auto& old : mesh_entries_) {
    if (old != nullptr) renderer_->RemoveActor(old->actor);  // deleted (or undone) imports
  }
  mesh_entries_ = std::move(next);
}

void SceneView::Sync(const SceneModel& model, int highlight) {
  const auto& objects = model.objects();
  bool same_ids = entries_.size() == objects.size();
  for (size_t i = 0; same_ids && i < objects.size(); ++i)
    same_ids = entries_[i]->id == objects[i].id;
  if (model.generation() != generation_ || !same_ids) {
    for (auto& e : entries_) renderer_->RemoveActor(e->actor);
    entries_.clear();
    for (size_t i = 0; i < objects.size(); ++i) {
      auto e = std::make_unique<Entry>();
      e->id = objects[i].id;
      SetUpEntry(e.get());
      renderer_->AddActor(e->actor);
      entries_.push_back(std::move(e));
    }
    generation_ = model.generation();
  }
  const DeviceToWorld& x = model.device_to_world();
  const double inv = 1.0 / x.world_scale;
  // The solid the shown mesh was made from: the mesh is drawn in its place.
  ObjectId replaced = 0;
  if (const DocObject* shown = model.document().Find(shown_mesh_)) {
    if (const auto* m = std::get_if<MeshData>(&shown->data)) replaced = m->source;
  }
  for (size_t i = 0; i < objects.size(); ++i) {
    Entry& e = *entries_[i];
    const SceneObject& o = objects[i];
    if (o.revision != e.revision) {
      FillPolyData(o.preview, e.poly);
      e.revision = o.revision;
    }
    const bool hidden =
        std::find(hidden_.begin(), hidden_.end(), o.name) != hidden_.end() || o.id == replaced;
    e.actor->SetVisibility(o.preview.triangles.cols() > 0 && !hidden);
    const auto& c = o.colour;
    if (o.error.empty()) {
      e.actor->GetProperty()->SetColor(c[0], c[1], c[2]);
    } else {
      e.actor->GetProperty()->SetColor(0.5 * c[0] + 0.45, 0.5 * c[1], 0.5 * c[2]);
    }
    // p_D = p_W / s − p_WDo / s.
    e.actor->SetScale(inv, inv, inv);
    e.actor->SetPosition(-inv * x.p_WDo.x(), -inv * x.p_WDo.y(), -inv * x.p_WDo.z());
    e.actor->GetProperty()->SetEdgeVisibility(static_cast<int>(i) == highlight);
    e.actor->GetProperty()->SetEdgeColor(0.35, 0.3, 0.25);
  }
  SyncMeshes(model.document(), x);
}

ObjectId SceneView::PickObject(double x, double y,
                               const std::vector<std::pair<vtkActor*, ObjectId>>& extra) const {
  vtkNew<vtkCellPicker> picker;
  picker->SetTolerance(0.0005);
  picker->PickFromListOn();
  for (const auto* list : {&entries_, &mesh_entries_}) {
    for (const auto& e : *list) {
      if (e->actor->GetVisibility()) picker->AddPickList(e->actor);
    }
  }
  for (const auto& [actor, id] : extra) {
    if (actor != nullptr && actor->GetVisibility()) picker->AddPickList(actor);
  }
  if (picker->Pick(x, y, 0.0, renderer_) == 0) return 0;
  vtkActor* hit = picker->GetActor();
  for (const auto& [actor, id] : extra) {
    if (actor == hit) return id;
  }
  for (const auto* list : {&entries_, &mesh_entries_}) {
    for (const auto& e : *list) {
      if (e->actor.GetPointer() == hit) return e->id;
    }
  }
  return 0;
}

vtkActor* SceneView::ActorOf(ObjectId id) const {
  for (const auto* list : {&entries_, &mesh_entries_}) {
    for (const auto& e : *list) {
      if (e->id == id) return e->actor;
    }
  }
  return nullptr;
}

}  // namespace spidarcad::app
