// FE workload: the steel cantilever whose tip deflection has a closed form (Timoshenko), meshed
// as a box of linear or quadratic tets, clamped at x = 0 and sheared at the free end, with its
// compliance condensed onto the top-face nodes nearest the tip. Shared by bench/fem_bench.cc and
// the report's FE section. Uses spidarcad::fem.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <vector>

#include "spidarcad/fem/column_cache.h"
#include "spidarcad/fem/condensation.h"

namespace spidarcad::workloads {

// The beam: length along x, square section, tip shear force along −z, steel.
inline constexpr double kCantileverLength = 1.0;           // m
inline constexpr double kCantileverSide = 0.1;             // m
inline constexpr double kCantileverForce = 1000.0;         // N
inline const fem::Material kCantileverSteel{2.0e11, 0.3};  // E [Pa], ν

// Timoshenko tip deflection of the beam (bending + shear, the square section's shear
// coefficient), m, positive downwards.
inline double CantileverTimoshenkoTip() {
  const double side = kCantileverSide, length = kCantileverLength;
  const fem::Material& steel = kCantileverSteel;
  const double i = side * std::pow(side, 3) / 12.0;
  const double nu = steel.poisson_ratio;
  const double kappa = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu);
  return kCantileverForce * std::pow(length, 3) / (3.0 * steel.youngs_modulus * i) +
         kCantileverForce * length / (kappa * steel.Mu() * side * side);
}

// A built cantilever: mesh, clamps and load, the factorised solver and the condensed compliance.
struct CantileverModel {
  int order = 1, r = 1;  // element order; cells across the section (10 r along the length)
  fem::TetMesh mesh;
  fem::MaterialTable materials{kCantileverSteel};
  std::unique_ptr<fem::BoundaryConditions> bcs;
  std::unique_ptr<fem::StaticSolver> solver;
  std::unique_ptr<fem::Compliance> compliance;
  double precompute_seconds = NAN;  // mesh, assembly, factorisation and the condensed columns, s
  double tip_ratio = NAN;           // FE tip deflection / CantileverTimoshenkoTip()
};

// Top-face nodes (z = side) of the cantilever's mesh.
inline std::vector<int> CantileverTopFace(const fem::TetMesh& mesh) {
  return fem::NodesInBox(mesh, Eigen::Vector3d(-1, -1, kCantileverSide), Eigen::Vector3d(2, 2, 2));
}

// Builds the cantilever with `order` elements and r cells across, condensing the compliance
// onto the `condensed_nodes` top-face nodes of the outer half nearest the middle of the tip's
// top edge. The tip deflection (the mean z displacement of the end face, from a static solve)
// is measured after the precompute time is taken.
inline std::unique_ptr<CantileverModel> BuildCantilever(
    int order, int r, int condensed_nodes, const fem::CondensationSettings& condensation = {}) {
  using fem::NodesInBox;
  const double length = kCantileverLength, side = kCantileverSide;
  auto m = std::make_unique<CantileverModel>();
  m->order = order;
  m->r = r;
  const auto start = std::chrono::steady_clock::now();
  fem::BoxMeshSettings s;
  s.upper = Eigen::Vector3d(length, side, side);
  s.nx = 10 * r;
  s.ny = s.nz = r;
  s.order = order;
  m->mesh = fem::MakeBoxMesh(s);
  m->bcs = std::make_unique<fem::BoundaryConditions>(m->mesh.num_nodes());
  fem::FixNodesInBox(m->mesh, Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1e-9, 1, 1),
                     m->bcs.get());
  const fem::Surface surface = fem::ExtractSurface(m->mesh);
  fem::AddTractionInBox(m->mesh, surface, Eigen::Vector3d(length - 1e-9, -1, -1),
                        Eigen::Vector3d(2, 2, 2),
                        Eigen::Vector3d(0, 0, -kCantileverForce / (side * side)), m->bcs.get());
  m->solver = std::make_unique<fem::StaticSolver>(m->mesh, m->materials, *m->bcs);
  std::vector<int> top =
      NodesInBox(m->mesh, Eigen::Vector3d(0.5, -1, side), Eigen::Vector3d(2, 2, 2));
  const Eigen::Vector3d tip(length, side / 2, side);
  std::sort(top.begin(), top.end(), [&](int a, int b) {
    return (m->mesh.nodes.row(a).transpose() - tip).norm() <
           (m->mesh.nodes.row(b).transpose() - tip).norm();
  });
  top.resize(std::min<size_t>(top.size(), condensed_nodes));
  m->compliance = std::make_unique<fem::Compliance>(*m->solver, surface.nodes, top, condensation);
  m->precompute_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto end_face =
      NodesInBox(m->mesh, Eigen::Vector3d(length - 1e-9, -1, -1), Eigen::Vector3d(2, 2, 2));
  const fem::StaticSolution solution = m->solver->Solve();
  double sum = 0.0;
  for (int v : end_face) sum += solution.displacement(3 * v + 2);
  m->tip_ratio = -sum / end_face.size() / CantileverTimoshenkoTip();
  return m;
}

// Relative force error of a single 0.1 mm push at the middle of the top face when the column of
// the node `cells` cells further along x stands in for the pushed node's, for cells = 1..4
// (the column cache's borrowed-column fallback). Each call builds its own cache.
inline std::vector<double> BorrowedColumnErrors(const CantileverModel& m) {
  using fem::NodesInBox;
  const double side = kCantileverSide, middle = kCantileverLength / 2;
  const std::vector<int> top = CantileverTopFace(m.mesh);
  const double cell = side / m.r;
  auto node_at = [&](double x) {
    const Eigen::Vector3d p(x, side / 2, side), tol = Eigen::Vector3d::Constant(1e-9);
    return NodesInBox(m.mesh, p - tol, p + tol).at(0);
  };
  fem::ColumnCacheSettings settings;
  settings.start_worker = false;
  fem::ColumnCache cache(*m.solver, m.mesh.nodes, m.compliance->output_nodes(), top, settings);
  const int b = cache.CandidateOfNode(node_at(middle));
  cache.ComputeNodes({b});
  const Eigen::Vector3d d = cache.baseline().segment<3>(3 * cache.OutputIndexOfCandidate(b)) -
                            Eigen::Vector3d(0, 0, 1e-4);
  double exact[3];
  {
    fem::CachedContactSolver solver(&cache, 1);
    solver.Add(b);
    solver.Solve(d.data(), exact);
  }
  const Eigen::Vector3d fe(exact[0], exact[1], exact[2]);
  std::vector<double> errors;
  for (int cells = 1; cells <= 4; ++cells) {
    cache.EvictAll();
    cache.ComputeNodes({cache.CandidateOfNode(node_at(middle + cells * cell))});
    fem::CachedContactSolver approx(&cache, 1);
    approx.Add(b);
    double f[3];
    approx.Solve(d.data(), f);
    errors.push_back((Eigen::Vector3d(f[0], f[1], f[2]) - fe).norm() / fe.norm());
  }
  return errors;
}

}  // namespace spidarcad::workloads
