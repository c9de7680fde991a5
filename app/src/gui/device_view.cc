// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "gui/device_view.h"

#include <vtkActor.h>
#include <vtkArrowSource.h>
#include <vtkAxesActor.h>
#include <vtkBillboardTextActor3D.h>
#include <vtkCamera.h>
#include <vtkCaptionActor2D.h>
#include <vtkCellArray.h>
#include <vtkCylinderSource.h>
#include <vtkGlyph3D.h>
#include <vtkMatrix4x4.h>
#include <vtkNew.h>
#include <vtkPlaneSource.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>
#include <vtkSphereSource.h>
#include <vtkTextActor.h>
#include <vtkTextProperty.h>
#include <vtkTransform.h>
#include <vtkTubeFilter.h>
#include <vtkUnsignedCharArray.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "gui/colour_map.h"

namespace spidarcad::app {

using haptics::kNumStrings;

struct DeviceView::Actors {
  vtkNew<vtkRenderer> renderer;
  // Strings: 16 points (2 per string, unshared so each string has its own colour), 8 lines.
  vtkNew<vtkPolyData> strings;
  vtkNew<vtkPoints> string_points;
  vtkNew<vtkUnsignedCharArray> string_colours;
  // Grip.
  std::array<vtkNew<vtkActor>, 2> poles;
  std::array<vtkNew<vtkPoints>, 2> pole_end_points;
  std::array<vtkNew<vtkPolyData>, 2> pole_ends;
  vtkNew<vtkActor> grip_sphere;
  vtkNew<vtkActor> grip_centre;
  // Ghost of the true (hand) pose: two thin lines.
  vtkNew<vtkPolyData> ghost;
  vtkNew<vtkPoints> ghost_points;
  vtkNew<vtkActor> ghost_actor;
  // Commanded force arrow.
  vtkNew<vtkActor> force_arrow;
};

namespace {

vtkSmartPointer<vtkActor> MakeActor(vtkAlgorithmOutput* port, const double rgb[3]) {
  vtkNew<vtkPolyDataMapper> mapper;
  mapper->SetInputConnection(port);
  mapper->ScalarVisibilityOff();
  auto actor = vtkSmartPointer<vtkActor>::New();
  actor->SetMapper(mapper);
  actor->GetProperty()->SetColor(rgb[0], rgb[1], rgb[2]);
  return actor;
}

// Matrix that maps the y axis of a source centred at the origin onto `axis` (scaled by its
// length relative to `unit`), placed at `origin`.
void SetAxisMatrix(vtkActor* actor, const Eigen::Vector3d& origin, const Eigen::Vector3d& axis,
                   double scale_along) {
  const Eigen::Vector3d y = axis.normalized();
  Eigen::Vector3d helper =
      std::abs(y.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
  const Eigen::Vector3d x = y.cross(helper).normalized();
  const Eigen::Vector3d z = x.cross(y);
  vtkNew<vtkMatrix4x4> m;
  for (int r = 0; r < 3; ++r) {
    m->SetElement(r, 0, x[r]);
    m->SetElement(r, 1, y[r] * scale_along);
    m->SetElement(r, 2, z[r]);
    m->SetElement(r, 3, origin[r]);
  }
  actor->SetUserMatrix(m);
}

}  // namespace

DeviceView::DeviceView(const haptics::SpidarGeometry& geometry, double tau_min, double tau_max)
    : actors_(std::make_unique<Actors>()),
      geometry_(geometry),
      tau_min_(tau_min),
      tau_max_(tau_max) {
  vtkRenderer* ren = actors_->renderer;
  ren->GradientBackgroundOn();
  ren->SetBackground(0.80, 0.83, 0.88);   // bottom
  ren->SetBackground2(0.97, 0.97, 0.98);  // top
  // No FXAA: in a vtkGenericOpenGLRenderWindow blitting to the GLFW context it left the scene
  // black (VTK 9.1, Mesa llvmpipe).
  ren->SetTwoSidedLighting(true);
  const double a = geometry.a, b = geometry.b, c = geometry.c, d = geometry.d;

  // Frame: 12 edges of the box between the corners.
  {
    vtkNew<vtkPoints> pts;
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d q = geometry.Corner(i);
      pts->InsertNextPoint(q.x(), q.y(), q.z());
    }
    vtkNew<vtkCellArray> lines;
    for (int i = 0; i < 8; ++i) {
      for (int j = i + 1; j < 8; ++j) {
        // Corners differing in exactly one coordinate sign share an edge.
        const Eigen::Vector3d diff = geometry.Corner(i) - geometry.Corner(j);
        const int differing =
            (std::abs(diff.x()) > 0) + (std::abs(diff.y()) > 0) + (std::abs(diff.z()) > 0);
        if (differing == 1) {
          const vtkIdType ids[2] = {i, j};
          lines->InsertNextCell(2, ids);
        }
      }
    }
    vtkNew<vtkPolyData> edges;
    edges->SetPoints(pts);
    edges->SetLines(lines);
    vtkNew<vtkTubeFilter> tube;
    tube->SetInputData(edges);
    tube->SetRadius(0.0045);
    tube->SetNumberOfSides(12);
    tube->CappingOn();
    const double grey[3] = {0.50, 0.53, 0.58};
    auto actor = MakeActor(tube->GetOutputPort(), grey);
    actor->GetProperty()->SetSpecular(0.4);
    actor->GetProperty()->SetSpecularPower(30);
    ren->AddActor(actor);

    // Corner pulleys: a dark disc glyph at each corner.
    vtkNew<vtkPolyData> corner_pd;
    corner_pd->SetPoints(pts);
    vtkNew<vtkSphereSource> pulley;
    pulley->SetRadius(0.011);
    pulley->SetThetaResolution(20);
    pulley->SetPhiResolution(14);
    vtkNew<vtkGlyph3D> glyph;
    glyph->SetInputData(corner_pd);
    glyph->SetSourceConnection(pulley->GetOutputPort());
    glyph->ScalingOff();
    const double dark[3] = {0.18, 0.19, 0.22};
    auto pulleys = MakeActor(glyph->GetOutputPort(), dark);
    pulleys->GetProperty()->SetSpecular(0.5);
    ren->AddActor(pulleys);

    // String numbers beside their corners (string i ends at corner Q_i).
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d q = geometry.Corner(i);
      // Beside the corner, outward in the horizontal plane and a little up (the labels of
      // the bottom corners would otherwise sink into the floor).
      const Eigen::Vector3d at =
          q + 0.045 * Eigen::Vector3d(q.x(), q.y(), 0.0).normalized() + Eigen::Vector3d(0, 0, 0.02);
      vtkNew<vtkBillboardTextActor3D> label;
      label->SetInput(("Q" + std::to_string(i + 1)).c_str());
      label->SetPosition(at.x(), at.y(), at.z());
      label->GetTextProperty()->SetFontSize(15);
      label->GetTextProperty()->SetColor(0.15, 0.15, 0.2);
      label->GetTextProperty()->BoldOn();
      label->GetTextProperty()->SetJustificationToCentered();
      label->GetTextProperty()->SetVerticalJustificationToCentered();
      ren->AddActor(label);
    }
  }

  // Floor: a light plate with a 4 cm grid, just below the frame.
  {
    const double z = -c - 0.02;
    const double ex = a + 0.12, ey = b + 0.12;
    vtkNew<vtkPlaneSource> plate;
    plate->SetOrigin(-ex, -ey, z - 0.001);
    plate->SetPoint1(ex, -ey, z - 0.001);
    plate->SetPoint2(-ex, ey, z - 0.001);
    const double plate_rgb[3] = {0.90, 0.91, 0.93};
    auto plate_actor = MakeActor(plate->GetOutputPort(), plate_rgb);
    plate_actor->GetProperty()->SetAmbient(0.5);
    plate_actor->GetProperty()->SetDiffuse(0.5);
    ren->AddActor(plate_actor);
    vtkNew<vtkPlaneSource> grid;
    grid->SetOrigin(-ex, -ey, z);
    grid->SetPoint1(ex, -ey, z);
    grid->SetPoint2(-ex, ey, z);
    grid->SetResolution(static_cast<int>(std::lround(2 * ex / 0.04)),
                        static_cast<int>(std::lround(2 * ey / 0.04)));
    const double grid_rgb[3] = {0.66, 0.69, 0.74};
    auto grid_actor = MakeActor(grid->GetOutputPort(), grid_rgb);
    grid_actor->GetProperty()->SetRepresentationToWireframe();
    grid_actor->GetProperty()->LightingOff();
    ren->AddActor(grid_actor);

    // Axes of D (x red, y green, z blue) at a floor corner, 8 cm long.
    vtkNew<vtkAxesActor> axes;
    vtkNew<vtkTransform> at;
    at->Translate(-ex + 0.03, -ey + 0.03, z);
    axes->SetUserTransform(at);
    axes->SetTotalLength(0.08, 0.08, 0.08);
    axes->SetShaftTypeToCylinder();
    axes->SetCylinderRadius(0.03);
    axes->SetConeRadius(0.25);
    for (vtkCaptionActor2D* cap : {axes->GetXAxisCaptionActor2D(), axes->GetYAxisCaptionActor2D(),
                                   axes->GetZAxisCaptionActor2D()}) {
      cap->GetCaptionTextProperty()->SetFontSize(13);
      cap->GetCaptionTextProperty()->ShadowOff();
      cap->GetCaptionTextProperty()->ItalicOff();
      cap->GetCaptionTextProperty()->SetColor(0.15, 0.15, 0.2);
      cap->GetTextActor()->SetTextScaleModeToNone();
    }
    ren->AddActor(axes);
  }

  // Strings: tubes with per-point colours.
  {
    Actors& s = *actors_;
    s.string_points->SetNumberOfPoints(2 * kNumStrings);
    s.string_colours->SetNumberOfComponents(3);
    s.string_colours->SetNumberOfTuples(2 * kNumStrings);
    s.string_colours->SetName("tension_colour");
    vtkNew<vtkCellArray> lines;
    for (int i = 0; i < kNumStrings; ++i) {
      const vtkIdType ids[2] = {2 * i, 2 * i + 1};
      lines->InsertNextCell(2, ids);
      s.string_points->SetPoint(2 * i, 0, 0, 0);
      s.string_points->SetPoint(2 * i + 1, 0, 0, 0);
    }
    s.strings->SetPoints(s.string_points);
    s.strings->SetLines(lines);
    s.strings->GetPointData()->SetScalars(s.string_colours);
    vtkNew<vtkTubeFilter> tube;
    tube->SetInputData(s.strings);
    tube->SetRadius(0.0022);
    tube->SetNumberOfSides(10);
    vtkNew<vtkPolyDataMapper> mapper;
    mapper->SetInputConnection(tube->GetOutputPort());
    mapper->SetColorModeToDirectScalars();
    mapper->SetScalarModeToUsePointData();
    mapper->ScalarVisibilityOn();
    vtkNew<vtkActor> actor;
    actor->SetMapper(mapper);
    actor->GetProperty()->SetAmbient(0.45);
    actor->GetProperty()->SetDiffuse(0.6);
    ren->AddActor(actor);
  }

  // Grip: two poles of length 2d with knobs at their ends, a centre bead, a glass sphere.
  {
    Actors& s = *actors_;
    vtkNew<vtkCylinderSource> cylinder;
    cylinder->SetHeight(2.0 * d);
    cylinder->SetRadius(0.0045);
    cylinder->SetResolution(24);
    vtkNew<vtkSphereSource> knob;
    knob->SetRadius(0.0058);
    knob->SetThetaResolution(16);
    knob->SetPhiResolution(12);
    const double* colours[2] = {kPole1Colour, kPole2Colour};
    for (int k = 0; k < 2; ++k) {
      vtkNew<vtkPolyDataMapper> mapper;
      mapper->SetInputConnection(cylinder->GetOutputPort());
      s.poles[k]->SetMapper(mapper);
      s.poles[k]->GetProperty()->SetColor(colours[k][0], colours[k][1], colours[k][2]);
      s.poles[k]->GetProperty()->SetSpecular(0.5);
      s.poles[k]->GetProperty()->SetSpecularPower(40);
      ren->AddActor(s.poles[k]);
      s.pole_end_points[k]->SetNumberOfPoints(2);
      s.pole_ends[k]->SetPoints(s.pole_end_points[k]);
      vtkNew<vtkGlyph3D> glyph;
      glyph->SetInputData(s.pole_ends[k]);
      glyph->SetSourceConnection(knob->GetOutputPort());
      glyph->ScalingOff();
      auto ends = MakeActor(glyph->GetOutputPort(), colours[k]);
      ends->GetProperty()->SetSpecular(0.5);
      ren->AddActor(ends);
    }
    vtkNew<vtkSphereSource> bead;
    bead->SetRadius(0.006);
    bead->SetThetaResolution(16);
    bead->SetPhiResolution(12);
    const double bead_rgb[3] = {0.25, 0.25, 0.28};
    vtkNew<vtkPolyDataMapper> bead_mapper;
    bead_mapper->SetInputConnection(bead->GetOutputPort());
    s.grip_centre->SetMapper(bead_mapper);
    s.grip_centre->GetProperty()->SetColor(bead_rgb[0], bead_rgb[1], bead_rgb[2]);
    ren->AddActor(s.grip_centre);

    vtkNew<vtkSphereSource> sphere;
    sphere->SetRadius(d);
    sphere->SetThetaResolution(48);
    sphere->SetPhiResolution(32);
    vtkNew<vtkPolyDataMapper> sphere_mapper;
    sphere_mapper->SetInputConnection(sphere->GetOutputPort());
    s.grip_sphere->SetMapper(sphere_mapper);
    s.grip_sphere->GetProperty()->SetColor(0.55, 0.70, 0.92);
    s.grip_sphere->GetProperty()->SetOpacity(0.18);
    s.grip_sphere->GetProperty()->SetSpecular(0.6);
    s.grip_sphere->GetProperty()->SetSpecularPower(60);
    ren->AddActor(s.grip_sphere);

    // Ghost of the hand pose.
    s.ghost_points->SetNumberOfPoints(4);
    vtkNew<vtkCellArray> ghost_lines;
    const vtkIdType l0[2] = {0, 1}, l1[2] = {2, 3};
    ghost_lines->InsertNextCell(2, l0);
    ghost_lines->InsertNextCell(2, l1);
    s.ghost->SetPoints(s.ghost_points);
    s.ghost->SetLines(ghost_lines);
    vtkNew<vtkPolyDataMapper> ghost_mapper;
    ghost_mapper->SetInputData(s.ghost);
    s.ghost_actor->SetMapper(ghost_mapper);
    s.ghost_actor->GetProperty()->SetColor(0.1, 0.1, 0.1);
    s.ghost_actor->GetProperty()->SetLineWidth(1.5);
    s.ghost_actor->GetProperty()->SetOpacity(0.5);
    s.ghost_actor->GetProperty()->LightingOff();
    ren->AddActor(s.ghost_actor);

    // Force arrow (vtkArrowSource points along x; Update() maps x onto the force).
    vtkNew<vtkArrowSource> arrow;
    arrow->SetTipResolution(24);
    arrow->SetShaftResolution(16);
    arrow->SetShaftRadius(0.035);
    arrow->SetTipRadius(0.09);
    arrow->SetTipLength(0.25);
    vtkNew<vtkPolyDataMapper> arrow_mapper;
    arrow_mapper->SetInputConnection(arrow->GetOutputPort());
    s.force_arrow->SetMapper(arrow_mapper);
    s.force_arrow->GetProperty()->SetColor(1.0, 0.55, 0.0);
    s.force_arrow->GetProperty()->SetAmbient(0.3);
    ren->AddActor(s.force_arrow);
  }
  ResetCamera();
}

DeviceView::~DeviceView() = default;

vtkRenderer* DeviceView::renderer() { return actors_->renderer; }

void DeviceView::Update(const DeviceFrame& frame) {
  Actors& s = *actors_;
  const haptics::GripPose& pose = frame.measured_pose;
  for (int i = 0; i < kNumStrings; ++i) {
    const Eigen::Vector3d p = pose.Attachment(i);
    const Eigen::Vector3d q = geometry_.Corner(i);
    s.string_points->SetPoint(2 * i, p.x(), p.y(), p.z());
    s.string_points->SetPoint(2 * i + 1, q.x(), q.y(), q.z());
    const Rgb rgb = TensionColour(frame.tensions[i], tau_min_, tau_max_);
    unsigned char bytes[3];
    for (int k = 0; k < 3; ++k) {
      bytes[k] = static_cast<unsigned char>(std::lround(255.0 * std::clamp(rgb[k], 0.0, 1.0)));
    }
    s.string_colours->SetTypedTuple(2 * i, bytes);
    s.string_colours->SetTypedTuple(2 * i + 1, bytes);
  }
  s.string_points->Modified();
  s.string_colours->Modified();
  s.strings->Modified();

  const Eigen::Vector3d* poles[2] = {&pose.p1, &pose.p2};
  for (int k = 0; k < 2; ++k) {
    SetAxisMatrix(s.poles[k], pose.p0, *poles[k], 1.0);
    const Eigen::Vector3d plus = pose.p0 + *poles[k], minus = pose.p0 - *poles[k];
    s.pole_end_points[k]->SetPoint(0, plus.x(), plus.y(), plus.z());
    s.pole_end_points[k]->SetPoint(1, minus.x(), minus.y(), minus.z());
    s.pole_end_points[k]->Modified();
    s.pole_ends[k]->Modified();
  }
  s.grip_sphere->SetPosition(pose.p0.x(), pose.p0.y(), pose.p0.z());
  s.grip_centre->SetPosition(pose.p0.x(), pose.p0.y(), pose.p0.z());

  const haptics::GripPose& hand = frame.true_pose;
  const Eigen::Vector3d ends[4] = {hand.p0 + hand.p1, hand.p0 - hand.p1, hand.p0 + hand.p2,
                                   hand.p0 - hand.p2};
  for (int k = 0; k < 4; ++k) s.ghost_points->SetPoint(k, ends[k].x(), ends[k].y(), ends[k].z());
  s.ghost_points->Modified();
  s.ghost->Modified();
  const bool apart = (hand.p0 - pose.p0).norm() > 5e-4 || (hand.p1 - pose.p1).norm() > 5e-4 ||
                     (hand.p2 - pose.p2).norm() > 5e-4;
  s.ghost_actor->SetVisibility(apart);

  // Arrow of the displayed force: 1 cm per newton, starting at the sphere's surface.
  const Eigen::Vector3d f = frame.achieved.head<3>();
  const double fn = f.norm();
  if (fn > 0.05 && std::isfinite(fn)) {
    const Eigen::Vector3d u = f / fn;
    const double length = 0.01 * fn;
    // vtkArrowSource spans x in [0, 1]; map x to the force direction.
    Eigen::Vector3d helper =
        std::abs(u.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
    const Eigen::Vector3d y = u.cross(helper).normalized();
    const Eigen::Vector3d z = u.cross(y);
    const Eigen::Vector3d origin = pose.p0 + u * (geometry_.d + 0.004);
    const double thick = 0.09;  // arrow shaft and tip scale (m per unit of the source)
    vtkNew<vtkMatrix4x4> m;
    for (int r = 0; r < 3; ++r) {
      m->SetElement(r, 0, u[r] * length);
      m->SetElement(r, 1, y[r] * thick);
      m->SetElement(r, 2, z[r] * thick);
      m->SetElement(r, 3, origin[r]);
    }
    s.force_arrow->SetUserMatrix(m);
    s.force_arrow->VisibilityOn();
  } else {
    s.force_arrow->VisibilityOff();
  }
  s.renderer->ResetCameraClippingRange();
}

void DeviceView::ResetCamera() {
  vtkCamera* cam = actors_->renderer->GetActiveCamera();
  const Eigen::Vector3d focal(0.0, 0.0, -0.05);
  const Eigen::Vector3d dir = Eigen::Vector3d(0.62, -1.0, 0.52).normalized();
  const double size = std::max({geometry_.a, geometry_.b, geometry_.c});
  const Eigen::Vector3d pos = focal + dir * (7.4 * size);
  cam->SetFocalPoint(focal.x(), focal.y(), focal.z());
  cam->SetPosition(pos.x(), pos.y(), pos.z());
  cam->SetViewUp(0, 0, 1);
  cam->SetViewAngle(30.0);
  cam->OrthogonalizeViewUp();
  actors_->renderer->ResetCameraClippingRange();
}

void DeviceView::Orbit(double azimuth_deg, double elevation_deg) {
  vtkCamera* cam = actors_->renderer->GetActiveCamera();
  cam->Azimuth(azimuth_deg);
  const Eigen::Vector3d dop = -ViewDirection();  // focal point to camera
  const double current = std::asin(std::clamp(dop.z(), -1.0, 1.0)) * 180.0 / 3.14159265358979;
  const double target = std::clamp(current + elevation_deg, -85.0, 85.0);
  cam->Elevation(target - current);
  cam->SetViewUp(0, 0, 1);
  cam->OrthogonalizeViewUp();
  actors_->renderer->ResetCameraClippingRange();
}

void DeviceView::Zoom(double factor) {
  vtkCamera* cam = actors_->renderer->GetActiveCamera();
  const double distance = cam->GetDistance();
  const double target = std::clamp(distance / factor, 0.25, 8.0);
  cam->Dolly(distance / target);
  actors_->renderer->ResetCameraClippingRange();
}

Ray DeviceView::PickRay(double x, double y) const {
  vtkRenderer* ren = actors_->renderer;
  double near_w[4], far_w[4];
  ren->SetDisplayPoint(x, y, 0.0);
  ren->DisplayToWorld();
  ren->GetWorldPoint(near_w);
  ren->SetDisplayPoint(x, y, 1.0);
  ren->DisplayToWorld();
  ren->GetWorldPoint(far_w);
  Ray ray;
  for (int k = 0; k < 3; ++k) {
    ray.origin[k] = near_w[k] / near_w[3];
    ray.direction[k] = far_w[k] / far_w[3] - ray.origin[k];
  }
  return ray;
}

Eigen::Vector3d DeviceView::ViewDirection() const {
  vtkCamera* cam = actors_->renderer->GetActiveCamera();
  double v[3];
  cam->GetDirectionOfProjection(v);
  return Eigen::Vector3d(v[0], v[1], v[2]).normalized();
}

Eigen::Vector3d DeviceView::ViewUp() const {
  vtkCamera* cam = actors_->renderer->GetActiveCamera();
  double v[3];
  cam->GetViewUp(v);
  return Eigen::Vector3d(v[0], v[1], v[2]).normalized();
}

Eigen::Vector3d DeviceView::ViewRight() const {
  return ViewDirection().cross(ViewUp()).normalized();
}

void DeviceView::FitBox(const Eigen::AlignedBox3d& box_D) {
  if (box_D.isEmpty() || !box_D.min().allFinite() || !box_D.max().allFinite()) return;
  vtkRenderer* ren = actors_->renderer;
  vtkCamera* cam = ren->GetActiveCamera();
  const Eigen::Vector3d centre = box_D.center();
  const double radius = std::max(0.5 * box_D.diagonal().norm(), 1e-3);
  // The narrower of the two view angles (VTK's view angle is the vertical one).
  double aspect = 1.0;
  if (ren->GetRenderWindow() != nullptr) {
    const double* vp = ren->GetViewport();
    const double vx0 = vp[0], vy0 = vp[1], vx1 = vp[2], vy1 = vp[3];
    const int* size = ren->GetRenderWindow()->GetSize();
    const double w = (vx1 - vx0) * size[0], h = (vy1 - vy0) * size[1];
    if (w > 0.0 && h > 0.0) aspect = w / h;
  }
  const double half_v = 0.5 * cam->GetViewAngle() * 3.14159265358979323846 / 180.0;
  const double half_h = std::atan(std::tan(half_v) * aspect);
  const double distance = 1.05 * radius / std::sin(std::min(half_v, half_h));
  const Eigen::Vector3d dir = ViewDirection();
  const Eigen::Vector3d pos = centre - distance * dir;
  cam->SetFocalPoint(centre.x(), centre.y(), centre.z());
  cam->SetPosition(pos.x(), pos.y(), pos.z());
  cam->OrthogonalizeViewUp();
  ren->ResetCameraClippingRange();
}

void DeviceView::SetStandardView(StandardView view, const Eigen::AlignedBox3d& box_D) {
  vtkCamera* cam = actors_->renderer->GetActiveCamera();
  // From the camera toward the subject (front until the switch picks the view).
  Eigen::Vector3d dir(0, 1, 0);
  Eigen::Vector3d up(0, 0, 1);
  switch (view) {
    case StandardView::kFront:
      dir = Eigen::Vector3d(0, 1, 0);
      break;
    case StandardView::kRight:
      dir = Eigen::Vector3d(-1, 0, 0);
      break;
    case StandardView::kTop:
      dir = Eigen::Vector3d(0, 0, -1);
      up = Eigen::Vector3d(0, 1, 0);
      break;
    case StandardView::kIso:
      dir = -Eigen::Vector3d(0.62, -1.0, 0.52).normalized();
      break;
  }
  double focal[3];
  cam->GetFocalPoint(focal);
  const Eigen::Vector3d f(focal[0], focal[1], focal[2]);
  const Eigen::Vector3d pos = f - cam->GetDistance() * dir;
  cam->SetPosition(pos.x(), pos.y(), pos.z());
  cam->SetViewUp(up.x(), up.y(), up.z());
  cam->OrthogonalizeViewUp();
  FitBox(box_D);
}

Eigen::AlignedBox3d DeviceView::FrameBox() const {
  const Eigen::Vector3d half(geometry_.a, geometry_.b, geometry_.c);
  return Eigen::AlignedBox3d(-half, half);
}

Eigen::Vector3d DeviceView::WorldToDisplay(const Eigen::Vector3d& p_D) const {
  vtkRenderer* ren = actors_->renderer;
  ren->SetWorldPoint(p_D.x(), p_D.y(), p_D.z(), 1.0);
  ren->WorldToDisplay();
  double d[3];
  ren->GetDisplayPoint(d);
  return Eigen::Vector3d(d[0], d[1], d[2]);
}

}  // namespace spidarcad::app
