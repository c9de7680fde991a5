// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// MeshSharpSurface and MeshSurfaceKeepingVolume: a surface, sharpened or not, on another grid
// placement where the first loses volume or leaves triangles under the sliver angle
// (feature_sharpening.h).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>

#include "spidarcad/modeling/feature_sharpening.h"

namespace spidarcad::modeling {

namespace {

// The radical inverse of i in `base`: the Halton sequence's coordinate.
double RadicalInverse(int i, int base) {
  double f = 1.0, r = 0.0;
  for (; i > 0; i /= base) {
    f /= base;
    r += f * (i % base);
  }
  return r;
}

}  // namespace

double EstimateSolidVolume(const CompiledSolid& solid, const Eigen::AlignedBox3d& box, int points) {
  if (points <= 0 || box.isEmpty()) return 0.0;
  Eigen::Matrix3Xd p(3, points);
  const Eigen::Vector3d size = box.sizes();
  for (int i = 0; i < points; ++i)
    p.col(i) = box.min() +
               size.cwiseProduct(Eigen::Vector3d(RadicalInverse(i + 1, 2), RadicalInverse(i + 1, 3),
                                                 RadicalInverse(i + 1, 5)));
  Eigen::VectorXd values(points);
  solid.Values(p, values);
  const long inside = (values.array() < 0.0).count();
  return box.volume() * static_cast<double>(inside) / points;
}

SurfaceMeshSettings SharpGridPlacement(const SurfaceMeshSettings& settings, double shift) {
  SurfaceMeshSettings moved = settings;
  if (shift != 0.0) {
    const double h = settings.cell_size;
    moved.bounds.min().array() += shift * h - h;
    moved.bounds.max().array() += shift * h + h;
  }
  return moved;
}

namespace {

// The placement search of MeshSharpSurface and MeshSurfaceKeepingVolume: `mesh_one(settings,
// run)` fills run->mesh (and its stats) for one grid placement; triangles under `sliver_angle`
// degrees (0: none counted) and the volume against the solid's rank the placements.
SharpSurface SearchPlacements(
    const CompiledSolid& solid, const SurfaceMeshSettings& surface_settings, double sliver_angle,
    const std::function<void(const SurfaceMeshSettings&, SharpSurface*)>& mesh_one) {
  // How good a placement is: its volume error (m³, against the estimate), whether that is past
  // the retry bound, its triangles under the sliver angle and its smallest angle.
  struct Score {
    double error = 0.0;
    bool far = false;
    long under = 0;
    double min_angle = 0.0;
  };
  double tolerance = 0.0, retry = 0.0;
  // Whether a beats b: a volume within the retry bound first; then, between two within it, the
  // fewer triangles under the angle, and between two past it the closer volume; then the closer
  // volume (beyond the tolerance), the fewer triangles under the angle, the larger smallest
  // angle.
  auto better = [&](const Score& a, const Score& b) {
    if (a.far != b.far) return !a.far;
    if (a.far && std::abs(a.error - b.error) > tolerance) return a.error < b.error;
    if (a.under != b.under) return a.under < b.under;
    if (std::abs(a.error - b.error) > tolerance) return a.error < b.error;
    return a.min_angle > b.min_angle;
  };
  const auto start = std::chrono::steady_clock::now();
  SharpSurface best;
  Score best_score, first_score;
  for (double shift : kSharpGridShifts) {
    SharpSurface run;
    mesh_one(SharpGridPlacement(surface_settings, shift), &run);
    const TriangleAngleStats angles = MeasureTriangleAngles(run.mesh, std::max(sliver_angle, 0.0));
    Score score;
    score.under = sliver_angle > 0.0 ? angles.small_angle : 0;
    score.min_angle = angles.min_angle_deg;
    ++best.placements;
    if (best.placements == 1) {
      const double volume = EstimateSolidVolume(solid, surface_settings.bounds, kSharpVolumePoints);
      const double signed_error = MeshVolume(run.mesh) - volume;
      tolerance = kSharpVolumeTolerance * volume;
      retry = kSharpVolumeRetry * volume;
      score.error = std::abs(signed_error);
      score.far = score.error > retry;
      best = std::move(run);
      best.placements = 1;
      best.first_under = score.under;
      best.first_min_angle_deg = score.min_angle;
      best.solid_volume = volume;
      best.first_volume_error = volume > 0.0 ? signed_error / volume : 0.0;
      best_score = first_score = score;
      if (best.mesh.triangles.cols() == 0) break;  // nothing to mesh: the caller says so
    } else {
      score.error = std::abs(MeshVolume(run.mesh) - best.solid_volume);
      score.far = score.error > retry;
      // Never at the cost of the solid's volume: within the first placement's volume error or
      // the tolerance.
      if (score.error <= std::max(first_score.error, tolerance) && better(score, best_score)) {
        SharpSurface kept = std::move(run);
        kept.placements = best.placements;
        kept.grid_shift = shift;
        kept.first_under = best.first_under;
        kept.first_min_angle_deg = best.first_min_angle_deg;
        kept.first_volume_error = best.first_volume_error;
        kept.solid_volume = best.solid_volume;
        best = std::move(kept);
        best_score = score;
      }
    }
    if (best_score.under == 0 && !best_score.far) break;
  }
  best.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return best;
}

}  // namespace

SharpSurface MeshSharpSurface(const CompiledSolid& solid,
                              const SurfaceMeshSettings& surface_settings,
                              const FeatureSettings& features) {
  return SearchPlacements(solid, surface_settings, features.sliver_angle_deg,
                          [&](const SurfaceMeshSettings& placed, SharpSurface* run) {
                            run->mesh =
                                SharpenFeatures(solid, MeshSurface(solid, placed, &run->surface),
                                                features, &run->features);
                          });
}

SharpSurface MeshSurfaceKeepingVolume(const CompiledSolid& solid,
                                      const SurfaceMeshSettings& surface_settings) {
  return SearchPlacements(solid, surface_settings, 0.0,
                          [&](const SurfaceMeshSettings& placed, SharpSurface* run) {
                            run->mesh = MeshSurface(solid, placed, &run->surface);
                          });
}

}  // namespace spidarcad::modeling
