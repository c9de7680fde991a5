// Rendering side of the window: the VTK scene of the SPIDAR-G (frame, corner pulleys, strings
// coloured by tension, cross grip with its two poles and sphere, floor grid, axes) and the
// camera. Update() copies a DeviceFrame into the actors; it computes nothing about the device.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>

#include "scene/device_session.h"
#include "scene/grip_control.h"
#include "spidarcad/haptics/geometry.h"

class vtkRenderer;

namespace spidarcad::app {

// Colours of the two poles (RGB in [0, 1]), shared by the scene and the panel.
inline constexpr double kPole1Colour[3] = {0.58, 0.28, 0.82};  // purple
inline constexpr double kPole2Colour[3] = {0.15, 0.55, 0.25};  // green

// The standard views of the View menu (keys 1, 3, 7, 0): the camera looks along +y (front),
// along −x (right), down −z (top, +y up on screen) or along the 3/4 direction of ResetCamera.
enum class StandardView { kFront, kRight, kTop, kIso };

// The 3D scene and its camera.
class DeviceView {
 public:
  // tau_min, tau_max (N): ends of the tension colour map.
  DeviceView(const haptics::SpidarGeometry& geometry, double tau_min, double tau_max);
  ~DeviceView();
  DeviceView(const DeviceView&) = delete;
  DeviceView& operator=(const DeviceView&) = delete;

  // The renderer to add to a render window.
  vtkRenderer* renderer();

  // Shows `frame`: strings to the measured pose coloured by tension, the grip at the measured
  // pose, a ghost of the true pose, and the force arrow.
  void Update(const DeviceFrame& frame);

  // Camera: the 3/4 view of the whole device.
  void ResetCamera();
  // Orbits about the focal point: azimuth and elevation in degrees (elevation kept in ±85°).
  void Orbit(double azimuth_deg, double elevation_deg);
  // Moves the camera toward the focal point by `factor` (> 1 closer).
  void Zoom(double factor);
  // Keeps the view direction and moves the camera so that `box_D` (in D, m; not empty) fills the
  // viewport: focal point at the box centre, distance such that the box's bounding sphere fits
  // both the vertical view angle and the horizontal one at the renderer's viewport aspect.
  void FitBox(const Eigen::AlignedBox3d& box_D);
  // Turns the camera to a standard view and fits `box_D` (FitBox).
  void SetStandardView(StandardView view, const Eigen::AlignedBox3d& box_D);
  // The box of the whole device frame in D (the camera's default subject).
  Eigen::AlignedBox3d FrameBox() const;
  // Display pixel (x, y, origin bottom left) of the point p_D of the view; z: depth in [0, 1].
  Eigen::Vector3d WorldToDisplay(const Eigen::Vector3d& p_D) const;

  // The ray through display pixel (x, y) of the render window (origin bottom left).
  Ray PickRay(double x, double y) const;
  // Unit view direction (from the camera toward the focal point), up and right vectors, in D.
  Eigen::Vector3d ViewDirection() const;
  Eigen::Vector3d ViewUp() const;
  Eigen::Vector3d ViewRight() const;

 private:
  struct Actors;
  std::unique_ptr<Actors> actors_;
  haptics::SpidarGeometry geometry_;
  double tau_min_;
  double tau_max_;
};

}  // namespace spidarcad::app
