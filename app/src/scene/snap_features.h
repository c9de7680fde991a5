// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The vertices, edges and faces of a scene's implicit solids, for snap forces
// (haptics::SnapField).
//
// Implicit solids have no explicit boundary representation, so the features come from the
// primitives that have sharp ones, placed by the transforms above them, and are kept only where
// they lie on the final surface of the scene:
//  - box: 8 corners, 12 edges, 6 rectangular faces; rounded_box: the same (its rounded corners
//    and edges fail the surface test unless the rounding is below the tolerance);
//  - extrusion: 2n vertices, 3n edges, n side quads and the two profile caps (n-gons);
//  - cylinder: the two rims as kCylinderSegments chords each (edges) and the two caps as
//    kCylinderSegments-gons (faces); no vertices;
//  - half_space: its whole plane (an unbounded face).
// Spheres, capsules, cones and tori contribute no vertex, edge or face (their axes:
// ExtractSnapAxes). Transforms (translate, rotate, scale — also non-uniform —, mirror with or
// without the original, linear and polar arrays) map the features; booleans, blends, offsets and
// shells pass their children's features up unchanged (the children of a difference too: a pocket's
// corners are features of the result).
//
// Surface test: a vertex is kept when the scene value (the minimum over all solids of
// modeling::EvaluateTree) has |value| <= tolerance there; an edge when its end points and three
// inner points pass; a face when its centroid and the points 50 % and 90 % of the way from the
// centroid to each of its vertices pass (an unbounded plane: the point of it nearest the
// origin). So a face or edge
// cut by a hole or buried in another solid, or moved by an offset or blend, is dropped as a
// whole. Duplicates (within the tolerance: a mirror keeping a feature on its plane, arrays that
// overlap) are kept once, so that a feature never pulls twice.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "spidarcad/haptics/snap_field.h"
#include "spidarcad/modeling/scene_io.h"

namespace spidarcad::app {

// Chords per cylinder rim (and sides of its cap polygons).
inline constexpr int kCylinderSegments = 24;

// Feature counts, for summaries.
struct SnapFeatureCounts {
  int vertices = 0;
  int edges = 0;
  int faces = 0;
  // "8 vertices, 12 edges, 6 faces".
  std::string ToString() const;
};

// The snap features (W, m) of every solid of `scene` on the scene's surface within
// `tolerance` m (> 0). Throws std::invalid_argument for a non-positive tolerance.
haptics::SnapFeatures ExtractSnapFeatures(const modeling::Scene& scene, double tolerance = 1e-5);

// The axes of the scene's round primitives as segments (W, m), placed by the transforms above
// them, each once (duplicates within `tolerance` dropped), buried or not: a cylinder's and a
// cone's from −height/2 to +height/2 along its z, a capsule's from a to b, a torus's across its
// tube (±minor_radius along its z). Throws std::invalid_argument as ExtractSnapFeatures does for
// too many candidates.
std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> ExtractSnapAxes(
    const modeling::Scene& scene, double tolerance = 1e-5);

// The counts of `features`.
SnapFeatureCounts CountSnapFeatures(const haptics::SnapFeatures& features);

}  // namespace spidarcad::app
