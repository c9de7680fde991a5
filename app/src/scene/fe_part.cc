// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/fe_part.h"

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <utility>
#include <variant>

#include "scene/vtu_io.h"
#include "spidarcad/fem/stiffness.h"

namespace spidarcad::app {

FeTouchSettings DefaultFeTouchSettings() {
  FeTouchSettings s;
  s.tool_radius = kDefaultFeToolRadius;
  s.patch_contact = true;
  s.frictionless = false;
  s.force_scale = kDefaultFeForceScale;
  s.max_force = 8.0;
  s.coupling_stiffness = kDefaultFeCoupling;
  return s;
}

FeTouchSettings FieldTouchSettings(const FeTouchSettings& panel, double world_scale) {
  FeTouchSettings ts = panel;
  if (!(ts.tool_radius > 0.0)) ts.tool_radius = kDefaultFeToolRadius;
  if (world_scale > 0.0) {
    ts.force_scale = panel.force_scale / world_scale;
    ts.coupling_stiffness = panel.coupling_stiffness / world_scale;
  }
  return ts;
}

FeTouchSettings ResolvedFieldSettings(const FeModel& /*model*/, const FeTouchSettings& panel,
                                      double world_scale) {
  return FieldTouchSettings(panel, world_scale);
}

FeGrabSettings DefaultFeGrabSettings() {
  FeGrabSettings s;
  s.tool_radius = kDefaultFeToolRadius;
  s.force_scale = kDefaultFeForceScale;
  s.max_force = 8.0;
  s.max_torque = 0.5;
  s.coupling_stiffness = kDefaultFeCoupling;
  s.coupling_rot_stiffness = kDefaultFeGrabRotCoupling;
  return s;
}

FeGrabSettings ResolvedGrabSettings(const FeModel& /*model*/, const FeGrabSettings& panel,
                                    double world_scale) {
  FeGrabSettings gs = panel;
  if (!(gs.tool_radius > 0.0)) gs.tool_radius = kDefaultFeToolRadius;
  if (world_scale > 0.0) {
    gs.force_scale = panel.force_scale / world_scale;
    gs.coupling_stiffness = panel.coupling_stiffness / world_scale;
  }
  return gs;
}

FePushGrabField::FePushGrabField(std::unique_ptr<FeTouchField> touch,
                                 std::unique_ptr<FeGrabField> grab)
    : touch_(std::move(touch)), grab_(std::move(grab)) {
  if (!touch_ || !grab_) throw std::invalid_argument("FE push-grab field: a field is missing");
}

haptics::ToolWrench FePushGrabField::Evaluate(const haptics::ToolKinematics& tool) noexcept {
  const haptics::ToolWrench w = grab_->Evaluate(tool);
  if (grab_->last_state().held) return w;
  return touch_->Evaluate(tool);
}

std::vector<ObjectId> FeModelsOf(const Document& doc) {
  std::vector<ObjectId> ids;
  for (const DocObject& o : doc.objects())
    if (std::holds_alternative<FeModelData>(o.data)) ids.push_back(o.id);
  return ids;
}

ObjectId FeModelSource(const Document& doc, ObjectId fe) {
  const DocObject* o = doc.Find(fe);
  const auto* data = o != nullptr ? std::get_if<FeModelData>(&o->data) : nullptr;
  if (data == nullptr) return 0;
  const DocObject* mesh = doc.Find(data->tet_mesh);
  const auto* mesh_data = mesh != nullptr ? std::get_if<MeshData>(&mesh->data) : nullptr;
  if (mesh_data == nullptr || doc.Find(mesh_data->source) == nullptr) return 0;
  return mesh_data->source;
}

std::shared_ptr<const modeling::CompiledSolid> FeDesignOf(const Document& doc, ObjectId mesh) {
  const DocObject* o = doc.Find(mesh);
  const auto* data = o != nullptr ? std::get_if<MeshData>(&o->data) : nullptr;
  if (data == nullptr || data->source == 0 || doc.IsMeshOutOfDate(mesh)) return nullptr;
  const DocObject* source = doc.Find(data->source);
  const auto* solid = source != nullptr ? std::get_if<SolidData>(&source->data) : nullptr;
  if (solid == nullptr) return nullptr;
  try {
    return std::make_shared<const modeling::CompiledSolid>(
        modeling::CompiledSolid::Compile(solid->root));
  } catch (const std::exception&) {
    return nullptr;  // a tree that does not compile: the mesh's normals
  }
}

FePart BuildFePart(const Document& doc, ObjectId fe, const FePartOptions& options) {
  const DocObject* o = doc.Find(fe);
  const auto* data = o != nullptr ? std::get_if<FeModelData>(&o->data) : nullptr;
  if (data == nullptr) {
    throw DocumentError("object " + std::to_string(fe) + " is not an FE model");
  }
  FePart part;
  part.fe = fe;
  part.mesh = data->tet_mesh;
  part.source = FeModelSource(doc, fe);
  part.name = o->name;
  FeModelSettings model_settings = ApplyFeModelData(*data, options.model);
  if (!model_settings.design) model_settings.design = FeDesignOf(doc, data->tet_mesh);
  part.model = FeModel::Build(FeMeshOf(doc, *data), model_settings);
  part.channel = std::make_shared<FeContactChannel>();
  part.field = std::make_unique<FeTouchField>(
      part.model, ResolvedFieldSettings(*part.model, options.touch, options.world_scale),
      part.channel);
  if (options.grab) {
    part.grab_channel = std::make_shared<FeGrabChannel>();
    part.grab_field = std::make_unique<FeGrabField>(
        part.model, ResolvedGrabSettings(*part.model, options.grab_settings, options.world_scale),
        part.grab_channel);
  }
  return part;
}

std::vector<int> CandidatesNearPath(const FeModel& model,
                                    const std::vector<Eigen::Vector3d>& path_W, double radius) {
  std::vector<int> out;
  if (path_W.empty()) return out;
  const fem::ColumnCache& cache = model.cache();
  const fem::TetMesh& mesh = model.mesh();
  // The path's box grown by the radius rules most nodes out at once.
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3d& p : path_W) box.extend(p);
  box.min().array() -= radius;
  box.max().array() += radius;
  const double r2 = radius * radius;
  std::vector<std::pair<double, int>> found;  // (squared distance to the path, candidate)
  for (int b = 0; b < cache.num_candidates(); ++b) {
    if (cache.IsFixed(b)) continue;
    const Eigen::Vector3d x = mesh.nodes.row(cache.candidate_node(b)).transpose();
    if (!box.contains(x)) continue;
    double best = (x - path_W[0]).squaredNorm();
    for (std::size_t i = 1; i < path_W.size(); ++i) {
      const Eigen::Vector3d a = path_W[i - 1], d = path_W[i] - a;
      const double len2 = d.squaredNorm();
      const double t = len2 > 0.0 ? std::clamp((x - a).dot(d) / len2, 0.0, 1.0) : 0.0;
      best = std::min(best, (x - a - t * d).squaredNorm());
    }
    if (best <= r2) found.emplace_back(best, b);
  }
  std::sort(found.begin(), found.end());
  for (const auto& [d2, b] : found) out.push_back(b);
  return out;
}

FeColumnPlan PrepareColumns(FeModel* model, const std::vector<int>& candidates, bool save,
                            const std::filesystem::path& cache_directory) {
  fem::ColumnCache& cache = model->cache();
  if (cache.running()) {
    throw std::logic_error("PrepareColumns: the column worker must be stopped");
  }
  const auto t0 = std::chrono::steady_clock::now();
  FeColumnPlan plan;
  // The candidates in the order given, once each; `sorted` for look-ups.
  std::vector<int> wanted, sorted;
  for (int b : candidates) {
    if (b < 0 || b >= cache.num_candidates() || cache.IsFixed(b)) continue;
    const auto at = std::lower_bound(sorted.begin(), sorted.end(), b);
    if (at != sorted.end() && *at == b) continue;
    sorted.insert(at, b);
    wanted.push_back(b);
  }
  plan.requested = static_cast<int>(wanted.size());

  // What the disk cache gave (everything ready now), then only the wanted part of it back.
  const fem::ColumnSet held = cache.Export(model->cache_key());
  cache.EvictAll();
  fem::ColumnSet keep;
  keep.key = held.key;
  keep.precision = held.precision;
  keep.output_nodes = held.output_nodes;
  keep.baseline = held.baseline;
  std::vector<Eigen::Index> kept_blocks;
  for (std::size_t k = 0; k < held.nodes.size(); ++k) {
    const int b = cache.CandidateOfNode(held.nodes[k]);
    if (b >= 0 && std::binary_search(sorted.begin(), sorted.end(), b)) {
      keep.nodes.push_back(held.nodes[k]);
      kept_blocks.push_back(static_cast<Eigen::Index>(k));
    }
  }
  keep.columns.resize(held.columns.rows(), 3 * static_cast<Eigen::Index>(kept_blocks.size()));
  for (std::size_t i = 0; i < kept_blocks.size(); ++i)
    keep.columns.middleCols(3 * static_cast<Eigen::Index>(i), 3) =
        held.columns.middleCols(3 * kept_blocks[i], 3);
  plan.from_disk = keep.nodes.empty() ? 0 : cache.Import(keep);
  plan.computed = cache.ComputeNodes(wanted);
  for (int b : wanted) plan.ready += cache.IsReady(b) ? 1 : 0;

  if (save && plan.computed > 0) {
    // The file keeps what it held and gains the new columns.
    const fem::ColumnSet now = cache.Export(model->cache_key());
    fem::ColumnSet merged = held;
    std::vector<Eigen::Index> added;
    for (std::size_t k = 0; k < now.nodes.size(); ++k)
      if (std::find(held.nodes.begin(), held.nodes.end(), now.nodes[k]) == held.nodes.end())
        added.push_back(static_cast<Eigen::Index>(k));
    const Eigen::Index old_cols = merged.columns.cols();
    merged.columns.conservativeResize(Eigen::NoChange,
                                      old_cols + 3 * static_cast<Eigen::Index>(added.size()));
    for (std::size_t i = 0; i < added.size(); ++i) {
      merged.nodes.push_back(now.nodes[added[i]]);
      merged.columns.middleCols(old_cols + 3 * static_cast<Eigen::Index>(i), 3) =
          now.columns.middleCols(3 * added[i], 3);
    }
    std::string error;
    plan.saved = fem::PrecomputeCache(cache_directory.empty() ? fem::DefaultCacheDirectory()
                                                              : cache_directory)
                     .Save(merged, &error);
  }
  plan.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return plan;
}

std::vector<Eigen::Vector3d> TrajectoryPathW(const haptics::Trajectory& trajectory,
                                             const haptics::DeviceToWorld& X_WD, double spacing) {
  std::vector<Eigen::Vector3d> path;
  const auto& samples = trajectory.samples();
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const Eigen::Vector3d p = X_WD.PointToWorld(samples[i].p_DT);
    if (!path.empty() && i + 1 < samples.size() && (p - path.back()).norm() < spacing) continue;
    path.push_back(p);
  }
  return path;
}

FeColumnPlan PrepareTrajectoryColumns(FePart* part, const haptics::Trajectory& trajectory,
                                      const haptics::DeviceToWorld& X_WD, bool save,
                                      const std::filesystem::path& cache_directory) {
  const FeTouchSettings& ts = part->field->settings();
  double radius = ts.tool_radius, pole = ts.grasp ? ts.pole_length : 0.0;
  if (part->grab_field) {
    const FeGrabSettings& gs = part->grab_field->settings();
    radius = std::max(radius, gs.tool_radius);
    if (gs.grasp) pole = std::max(pole, gs.pole_length);
  }
  const double reach = radius + X_WD.world_scale * kFeTrajectoryMargin + pole;
  const std::vector<Eigen::Vector3d> path =
      TrajectoryPathW(trajectory, X_WD, 0.25 * ts.tool_radius);
  return PrepareColumns(part->model.get(), CandidatesNearPath(*part->model, path, reach), save,
                        cache_directory);
}

namespace {

// The model solved in full with nodes candidate[i] (i < n) prescribed to target[3i..3i+2].
FeSolvedState SolvePrescribed(const FeModel& model, int n, const int* candidate,
                              const double* target) {
  fem::BoundaryConditions bcs = model.bcs();
  for (int s = 0; s < n; ++s) {
    bcs.PrescribeNode(model.cache().candidate_node(candidate[s]),
                      Eigen::Vector3d(target[3 * s], target[3 * s + 1], target[3 * s + 2]));
  }
  const fem::StaticSolver solver(model.mesh(), model.materials(), bcs);
  if (!solver.factor_status().converged) {
    throw std::runtime_error("FE state: the stiffness could not be factored: " +
                             solver.factor_status().message);
  }
  fem::StaticSolution solution = solver.Solve();
  if (!solution.status.converged) {
    throw std::runtime_error("FE state: the solve did not converge: " + solution.status.message);
  }
  FeSolvedState out;
  out.displacement = std::move(solution.displacement);
  out.element_von_mises = fem::ElementVonMises(model.mesh(), model.materials(), out.displacement);
  out.von_mises = fem::AverageToNodes(model.mesh(), out.element_von_mises);
  return out;
}

}  // namespace

FeSolvedState SolveFeState(const FeModel& model, const FeContactState& state) {
  return SolvePrescribed(model, state.num_contacts, state.candidate.data(), state.target.data());
}

FeSolvedState SolveFeGrabState(const FeModel& model, const FeGrabState& state) {
  return SolvePrescribed(model, state.ready ? state.num_nodes : 0, state.candidate.data(),
                         state.target.data());
}

void WriteFeStateVtu(const FeModel& model, const FeSolvedState& solved, const std::string& path) {
  const fem::TetMesh& mesh = model.mesh();
  modeling::VtuArrays point_data, cell_data;
  point_data["displacement"] =
      Eigen::Map<const Eigen::Matrix3Xd>(solved.displacement.data(), 3, mesh.num_nodes());
  point_data["von_mises"] = solved.von_mises.transpose();
  cell_data["von_mises"] = solved.element_von_mises.transpose();
  WriteTetVtu(mesh, path, point_data, cell_data);
}

}  // namespace spidarcad::app
