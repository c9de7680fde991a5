// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The felt stiffness of an FE part: a definition that converges as the mesh is refined, its
// reference computation (a full sparse solve) and the same number through the haptic path's
// cached columns (docs/fem.md, "Felt stiffness").
//
// Why not a node. Pushing one node is a point load: in 3D its displacement is unbounded (the
// elastic half-space's u = F(1 − ν²)/(π E ρ) at distance ρ), so the stiffness of one FE node
// falls like the cell size h (K ≈ E·h) as the mesh is refined and has no limit but zero.
//
// Definition. The tool has a physical size: a sphere of radius r (FeTouchSettings::tool_radius).
// Its patch at a surface point p is every free (unclamped) surface node within r of p that faces
// the tool (outward normal against the push direction d). The patch
// stiffness K(p, d) is the force per metre, along the push direction d (unit), needed to move
// that patch rigidly by δ d (sticking: every patch node moves by the same vector), the rest of the
// part free apart from its clamps:
//   K = d · (F(δ d) − F(0)) / δ,   F = Σ_patch reactions ON the body (N),
// which is what fem::SolveGrab computes for the patch. As h → 0 the patch tends to the part of
// the surface inside the tool's sphere and K to the stiffness of a rigid punch of radius r on the
// part (the flat punch on a half-space: 2 E r/(1 − ν²)), which is finite. The felt stiffness is
// K seen through FE mode's virtual coupling k_c and force scale σ: the two in series,
//   k_felt = 1 / (1/k_c + 1/(σ K)).
//
// Units: m, N, N/m; positions and directions in the part's frame W.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "scene/fe_model.h"

namespace spidarcad::app {

// The free surface nodes within `radius` (m, > 0) of `point` (W) that face the tool (outward
// normal n with n·direction < 0, `direction` the push direction): the patch a tool of that radius
// covers there (a plate as thin as the tool's radius keeps its far face out). Mesh node
// indices, ascending. Empty when none.
std::vector<int> ToolPatchNodes(const FeModel& model, const Eigen::Vector3d& point, double radius,
                                const Eigen::Vector3d& direction);

// Reference patch stiffness K (N/m) along unit `direction` of the patch `nodes` (mesh node
// indices, free, no repeats), from full sparse solves (fem::SolveGrab) on the model's mesh,
// materials and constraints. Throws std::invalid_argument naming what is wrong (an empty patch,
// a clamped node, a direction that is not a finite non-zero vector) and std::runtime_error when
// the solve fails.
double ReferencePatchStiffness(const FeModel& model, const std::vector<int>& nodes,
                               const Eigen::Vector3d& direction);

// The same stiffness through the haptic path: the model's column cache (columns computed for the
// patch now; the cache worker must be stopped) and a fem::CachedContactSolver holding the patch,
// its forces for targets u0 + d and u0 summed along d. Throws as ReferencePatchStiffness, and
// std::runtime_error when a column cannot be computed or the contact block is not positive
// definite.
double CachedPatchStiffness(FeModel* model, const std::vector<int>& nodes,
                            const Eigen::Vector3d& direction);

// Felt stiffness of part stiffness K (N/m) through a coupling k_c (N/m) with force scale σ:
// 1 / (1/k_c + 1/(σK)); σK when k_c <= 0; 0 when σK <= 0.
double FeltStiffness(double part_stiffness, double coupling_stiffness, double force_scale);

// A point where the felt stiffness is measured.
struct FeltProbe {
  std::string name;                                       // e.g. "corner"
  Eigen::Vector3d point = Eigen::Vector3d::Zero();        // tool centre's touch point, W, m
  Eigen::Vector3d direction = -Eigen::Vector3d::UnitZ();  // push direction, W (unit)
};

// The platform's probes (assets/scenes/platform.json): its free corner, the plate top 1 cm in
// from both free edges, (0.29, 0.09, 0.01); the plate top over the gusset, (0.10, 0, 0.01); both
// pushed down (−z).
std::vector<FeltProbe> PlatformFeltProbes();

// One measurement: a probe on a mesh of one cell size and element order.
struct FeltSample {
  std::string probe;
  double cell = 0.0;       // surface grid cell of the mesh, m
  int order = 1;           // element order
  int nodes = 0;           // mesh nodes (after the order upgrade)
  int patch_nodes = 0;     // nodes in the tool's patch
  double stiffness = 0.0;  // K, N/m
  double felt = 0.0;       // FeltStiffness(K, k_c, σ), N/m
};

// Settings of MeasureFeltStiffness.
struct FeltSweepSettings {
  std::string scene_path;              // scene file (empty: PlatformScenePath())
  std::string solid;                   // solid name (empty: the first)
  std::vector<double> cells;           // surface grid cells, m (each > 0)
  std::vector<int> orders = {1, 2};    // element orders (1, 2)
  std::vector<FeltProbe> probes;       // empty: PlatformFeltProbes()
  double tool_radius = 0.01;           // m (> 0)
  double coupling_stiffness = 1500.0;  // k_c, N/m (kDefaultFeCoupling)
  double force_scale = 1e-4;           // σ (kDefaultFeForceScale)
  bool lattice = false;                // surfaces by the lattice route (else marching tetrahedra)
  double flat_cells = 0.0;             // SurfaceMeshSettings::flat_coarsen_cells (not lattice)
};

// Meshes the solid at each cell size (MeshSceneSolidForFe), builds a steel FE model of each
// order clamped at its minimum-x face as FE mode does (FeModel::Build, no disk cache, no
// worker) and measures every probe with ReferencePatchStiffness. Samples in the order cell,
// order, probe. `progress` (may be empty) gets each sample as it is done. Throws
// std::invalid_argument for a bad setting and what the meshing and solves throw.
std::vector<FeltSample> MeasureFeltStiffness(
    const FeltSweepSettings& settings, const std::function<void(const FeltSample&)>& progress = {});

// Richardson extrapolation to h = 0 of values v1 at cell h1 and v2 at cell h2 < h1 converging
// like h^p: v2 + (v2 − v1)/((h1/h2)^p − 1).
double RichardsonExtrapolate(double h1, double v1, double h2, double v2, double p);

}  // namespace spidarcad::app
