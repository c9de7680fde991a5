// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Internal to modeling/: MeshSurface's lattice route (SurfaceMesher::kLattice), see
// surface_mesher.h and lattice_mesher.cc.
#pragma once

#include "spidarcad/modeling/surface_mesher.h"

namespace spidarcad::modeling::internal {

// The zero set of solid, clipped to settings.bounds, by marching tetrahedra on a body-centred
// cubic lattice whose vertices near the surface are moved onto it. Settings already checked by
// MeshSurface.
TriangleMesh MeshSurfaceLattice(const CompiledSolid& solid, const SurfaceMeshSettings& settings,
                                SurfaceMeshStats* stats);

}  // namespace spidarcad::modeling::internal
