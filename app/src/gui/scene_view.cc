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

namespace spidarcad::app {

struct SceneView::Entry {
  vtkNew<vtkPolyData> poly;
  vtkNew<vtkPolyDataNormals> normals;
  vtkNew<vtkPolyDataMapper> mapper;
  vtkNew<vtkActor> actor;
  int revision = -1;
  ObjectId id = 0;
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
      renderer_->AddActor(e->actor);
      entries_.push_back(std::move(e));
    }
    generation_ = model.generation();
  }
  const DeviceToWorld& x = model.device_to_world();
  const double inv = 1.0 / x.world_scale;
  for (size_t i = 0; i < objects.size(); ++i) {
    Entry& e = *entries_[i];
    const SceneObject& o = objects[i];
    if (o.revision != e.revision) {
      FillPolyData(o.shown(), e.poly);
      e.revision = o.revision;
    }
    const bool hidden = std::find(hidden_.begin(), hidden_.end(), o.name) != hidden_.end();
    e.actor->SetVisibility(o.shown().triangles.cols() > 0 && !hidden);
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
}

ObjectId SceneView::PickObject(double x, double y) const {
  vtkNew<vtkCellPicker> picker;
  picker->SetTolerance(0.0005);
  picker->PickFromListOn();
  for (const auto& e : entries_) {
    if (e->actor->GetVisibility()) picker->AddPickList(e->actor);
  }
  if (picker->Pick(x, y, 0.0, renderer_) == 0) return 0;
  vtkActor* hit = picker->GetActor();
  for (const auto& e : entries_) {
    if (e->actor.GetPointer() == hit) return e->id;
  }
  return 0;
}

vtkActor* SceneView::ActorOf(ObjectId id) const {
  for (const auto& e : entries_) {
    if (e->id == id) return e->actor;
  }
  return nullptr;
}

}  // namespace spidarcad::app
