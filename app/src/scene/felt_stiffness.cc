// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/felt_stiffness.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "spidarcad/fem/column_cache.h"
#include "spidarcad/fem/grab.h"

namespace spidarcad::app {
namespace {

Eigen::Vector3d UnitDirection(const Eigen::Vector3d& d, const char* who) {
  const double n = d.norm();
  if (!d.allFinite() || !(n > 0.0)) {
    std::ostringstream msg;
    msg << who << ": the push direction (" << d.x() << ", " << d.y() << ", " << d.z()
        << ") is not a finite non-zero vector";
    throw std::invalid_argument(msg.str());
  }
  return d / n;
}

// Candidate index of each patch node; throws naming a node that is not a free surface node.
std::vector<int> PatchCandidates(const FeModel& model, const std::vector<int>& nodes,
                                 const char* who) {
  if (nodes.empty()) throw std::invalid_argument(std::string(who) + ": the patch is empty");
  std::vector<int> candidates;
  candidates.reserve(nodes.size());
  for (int v : nodes) {
    const int b = model.cache().CandidateOfNode(v);
    if (b < 0 || model.cache().IsFixed(b)) {
      std::ostringstream msg;
      msg << who << ": patch node " << v << " is " << (b < 0 ? "not a surface node" : "clamped");
      throw std::invalid_argument(msg.str());
    }
    candidates.push_back(b);
  }
  return candidates;
}

}  // namespace

std::vector<int> ToolPatchNodes(const FeModel& model, const Eigen::Vector3d& point, double radius,
                                const Eigen::Vector3d& direction) {
  std::vector<int> nodes;
  const fem::ColumnCache& cache = model.cache();
  for (int b = 0; b < cache.num_candidates(); ++b) {
    if (cache.IsFixed(b)) continue;
    const int v = cache.candidate_node(b);
    if ((model.mesh().nodes.row(v).transpose() - point).norm() < radius &&
        model.candidate_normals().row(b).dot(direction) < 0.0)
      nodes.push_back(v);
  }
  std::sort(nodes.begin(), nodes.end());
  return nodes;
}

double ReferencePatchStiffness(const FeModel& model, const std::vector<int>& nodes,
                               const Eigen::Vector3d& direction) {
  const char* who = "reference patch stiffness";
  const Eigen::Vector3d d = UnitDirection(direction, who);
  PatchCandidates(model, nodes, who);
  const fem::GrabPatch patch(model.mesh().nodes, nodes);
  // Linear: one solve at δ = 1 m gives K; the loads' part F(0) only when there are loads.
  const fem::GrabSolution moved = fem::SolveGrab(model.mesh(), model.materials(), model.bcs(),
                                                 patch, d, Eigen::Vector3d::Zero());
  if (!moved.status.converged)
    throw std::runtime_error(std::string(who) + ": the solve failed: " + moved.status.message);
  Eigen::Vector3d force = moved.wrench.force;
  if (!model.load_nodes().empty()) {
    const fem::GrabSolution held =
        fem::SolveGrab(model.mesh(), model.materials(), model.bcs(), patch, Eigen::Vector3d::Zero(),
                       Eigen::Vector3d::Zero());
    if (!held.status.converged)
      throw std::runtime_error(std::string(who) + ": the solve failed: " + held.status.message);
    force -= held.wrench.force;
  }
  return d.dot(force);
}

double CachedPatchStiffness(FeModel* model, const std::vector<int>& nodes,
                            const Eigen::Vector3d& direction) {
  const char* who = "cached patch stiffness";
  const Eigen::Vector3d d = UnitDirection(direction, who);
  const std::vector<int> candidates = PatchCandidates(*model, nodes, who);
  fem::ColumnCache& cache = model->cache();
  cache.ComputeNodes(candidates);
  const int n = static_cast<int>(candidates.size());
  fem::CachedContactSolver solver(&cache, n);
  for (int b : candidates) {
    if (!cache.IsReady(b))
      throw std::runtime_error(std::string(who) + ": no column for candidate " + std::to_string(b));
    const fem::CachedContactStatus status = solver.Add(b);
    if (status != fem::CachedContactStatus::kOk)
      throw std::runtime_error(std::string(who) + ": candidate " + std::to_string(b) +
                               " could not be added (contact block not positive definite)");
  }
  std::vector<double> held(3 * n), moved(3 * n), f_held(3 * n), f_moved(3 * n);
  for (int s = 0; s < n; ++s) {
    const int row = 3 * cache.OutputIndexOfCandidate(solver.contact(s));
    for (int i = 0; i < 3; ++i) {
      held[3 * s + i] = cache.baseline()(row + i);
      moved[3 * s + i] = held[3 * s + i] + d(i);
    }
  }
  if (!solver.Solve(moved.data(), f_moved.data()) || !solver.Solve(held.data(), f_held.data()))
    throw std::runtime_error(std::string(who) + ": the contact solve failed");
  double k = 0.0;
  for (int s = 0; s < n; ++s)
    for (int i = 0; i < 3; ++i) k += d(i) * (f_moved[3 * s + i] - f_held[3 * s + i]);
  return k;
}

double FeltStiffness(double part_stiffness, double coupling_stiffness, double force_scale) {
  const double sk = force_scale * part_stiffness;
  if (!(sk > 0.0)) return 0.0;
  if (!(coupling_stiffness > 0.0)) return sk;
  return 1.0 / (1.0 / coupling_stiffness + 1.0 / sk);
}

std::vector<FeltProbe> PlatformFeltProbes() {
  return {{"corner", Eigen::Vector3d(0.29, 0.09, 0.01), -Eigen::Vector3d::UnitZ()},
          {"gusset", Eigen::Vector3d(0.10, 0.0, 0.01), -Eigen::Vector3d::UnitZ()}};
}

std::vector<FeltSample> MeasureFeltStiffness(
    const FeltSweepSettings& settings, const std::function<void(const FeltSample&)>& progress) {
  if (settings.cells.empty()) throw std::invalid_argument("felt stiffness: no cell size given");
  for (double h : settings.cells)
    if (!(h > 0.0) || !std::isfinite(h))
      throw std::invalid_argument("felt stiffness: cell size " + std::to_string(h) +
                                  " must be a finite length > 0 m");
  for (int order : settings.orders)
    if (order != 1 && order != 2)
      throw std::invalid_argument("felt stiffness: element order " + std::to_string(order) +
                                  " (must be 1 or 2)");
  if (!(settings.tool_radius > 0.0) || !std::isfinite(settings.tool_radius))
    throw std::invalid_argument("felt stiffness: tool radius " +
                                std::to_string(settings.tool_radius) + " must be > 0 m");
  const std::vector<FeltProbe> probes =
      settings.probes.empty() ? PlatformFeltProbes() : settings.probes;
  const std::string scene = settings.scene_path.empty() ? PlatformScenePath() : settings.scene_path;
  std::vector<FeltSample> samples;
  for (double h : settings.cells) {
    const fem::TetMesh mesh = MeshSceneSolidForFe(scene, settings.solid, h, nullptr, {},
                                                  settings.lattice, settings.flat_cells);
    for (int order : settings.orders) {
      FeModelSettings ms;
      ms.order = order;
      ms.use_disk_cache = false;
      ms.cache.start_worker = false;
      const std::unique_ptr<FeModel> model = FeModel::Build(mesh, ms);
      for (const FeltProbe& probe : probes) {
        const std::vector<int> patch =
            ToolPatchNodes(*model, probe.point, settings.tool_radius, probe.direction);
        if (patch.empty())
          throw std::invalid_argument("felt stiffness: probe '" + probe.name +
                                      "': no free surface node within the tool radius");
        FeltSample s;
        s.probe = probe.name;
        s.cell = h;
        s.order = order;
        s.nodes = model->mesh().num_nodes();
        s.patch_nodes = static_cast<int>(patch.size());
        s.stiffness = ReferencePatchStiffness(*model, patch, probe.direction);
        s.felt = FeltStiffness(s.stiffness, settings.coupling_stiffness, settings.force_scale);
        if (progress) progress(s);
        samples.push_back(s);
      }
    }
  }
  return samples;
}

double RichardsonExtrapolate(double h1, double v1, double h2, double v2, double p) {
  return v2 + (v2 - v1) / (std::pow(h1 / h2, p) - 1.0);
}

}  // namespace spidarcad::app
