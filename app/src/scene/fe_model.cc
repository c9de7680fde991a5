// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/fe_model.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <future>
#include <sstream>
#include <system_error>
#include <variant>

#include "doc/assets.h"
#include "scene/scene_solid.h"
#include "scene/vtu_io.h"
#include "scene/worker_process.h"
#include "spidarcad/fem/cache_file.h"
#include "spidarcad/fem/stiffness.h"
#include "spidarcad/modeling/feature_sharpening.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::app {
namespace {

void CheckCancel(const FeModelSettings& s) {
  if (s.cancel != nullptr && s.cancel->load(std::memory_order_relaxed)) throw FeModelCancelled();
}

void Progress(const FeModelSettings& s, double fraction, const char* phase) {
  if (s.phase && phase != nullptr) s.phase(phase);
  if (s.progress) s.progress(fraction);
}

}  // namespace

const fem::SolveStatus& FeModel::factor_status() const {
  return solver_ ? solver_->factor_status() : substructured_->factor_status();
}

std::unique_ptr<FeModel> FeModel::Build(fem::TetMesh mesh, const FeModelSettings& settings) {
  const auto t0 = std::chrono::steady_clock::now();
  if (settings.order != 1 && settings.order != 2) {
    std::ostringstream msg;
    msg << "FE model: element order must be 1 or 2, got " << settings.order;
    throw std::invalid_argument(msg.str());
  }
  settings.material.Validate();
  Progress(settings, 0.0, "check mesh");
  mesh.Validate();
  if (mesh.Order() != 1 && settings.order == 1)
    throw std::invalid_argument("FE model: the mesh is quadratic (10-node) but order 1 was asked");
  CheckCancel(settings);

  std::unique_ptr<FeModel> m(new FeModel());
  m->material_ = settings.material;
  m->mesh_ =
      (settings.order == 2 && mesh.Order() == 1) ? fem::MakeQuadratic(mesh) : std::move(mesh);
  if (settings.region_materials.empty()) m->mesh_.regions.setZero(m->mesh_.num_elements());
  m->materials_ = std::make_unique<fem::MaterialTable>(
      MakeMaterialTable(settings.material, settings.region_materials));
  const fem::TetMesh& tm = m->mesh_;
  const int nv = tm.num_nodes();
  // What needs the surface and not the factor (surface, output nodes, stress operators,
  // normals) is made on a thread of its own while the model is factored: 0.1 s of a 130k-tet
  // edit's precompute. It reads the mesh, the materials and the design; it reports no progress.
  std::future<void> surface_side = std::async(std::launch::async, [&m, &settings] {
    FeModel* const model = m.get();
    const fem::TetMesh& tm = model->mesh_;
    const int nv = tm.num_nodes();
    model->surface_ = fem::ExtractSurface(model->mesh_);

    // Mean boundary edge length (corner edges of the faces).
    double edge_sum = 0.0;
    const int nf = static_cast<int>(model->surface_.faces.rows());
    for (int f = 0; f < nf; ++f)
      for (int i = 0; i < 3; ++i) {
        const int a = model->surface_.faces(f, i), b = model->surface_.faces(f, (i + 1) % 3);
        edge_sum += (tm.nodes.row(a) - tm.nodes.row(b)).norm();
      }
    model->mean_edge_ = nf > 0 ? edge_sum / (3.0 * nf) : 0.0;
    CheckCancel(settings);

    // Surface elements, output nodes (every node of a surface element), stress operators.
    model->surface_elements_.assign(
        model->surface_.face_element.data(),
        model->surface_.face_element.data() + model->surface_.face_element.size());
    std::sort(model->surface_elements_.begin(), model->surface_elements_.end());
    model->surface_elements_.erase(
        std::unique(model->surface_elements_.begin(), model->surface_elements_.end()),
        model->surface_elements_.end());
    model->output_index_.assign(nv, -1);
    for (int e : model->surface_elements_)
      for (int j = 0; j < tm.NodesPerElement(); ++j) model->output_index_[tm.elements(e, j)] = 0;
    for (int v : model->surface_.nodes) model->output_index_[v] = 0;
    for (int v = 0; v < nv; ++v)
      if (model->output_index_[v] == 0) {
        model->output_index_[v] = static_cast<int>(model->output_nodes_.size());
        model->output_nodes_.push_back(v);
      }
    model->stress_ops_.reserve(model->surface_elements_.size());
    model->element_volume_.reserve(model->surface_elements_.size());
    for (std::size_t i = 0; i < model->surface_elements_.size(); ++i) {
      const int e = model->surface_elements_[i];
      const Eigen::MatrixXd b =
          fem::StrainDisplacement(fem::GetElementNodes(tm, e), Eigen::Vector4d::Constant(0.25));
      model->stress_ops_.push_back(model->materials_->Get(tm.regions(e)).ElasticityMatrix() * b);
      model->element_volume_.push_back(std::abs(tm.CornerVolume(e)));
      if ((i & 1023) == 0) CheckCancel(settings);
    }

    // Outward normals of the surface nodes (candidates), area weighted.
    const std::vector<int>& candidates = model->surface_.nodes;
    std::vector<int> cand_of(nv, -1);
    for (std::size_t b = 0; b < candidates.size(); ++b)
      cand_of[candidates[b]] = static_cast<int>(b);
    model->normals_.setZero(static_cast<Eigen::Index>(candidates.size()), 3);
    for (int f = 0; f < nf; ++f) {
      const Eigen::Vector3d p0 = tm.nodes.row(model->surface_.faces(f, 0)),
                            p1 = tm.nodes.row(model->surface_.faces(f, 1)),
                            p2 = tm.nodes.row(model->surface_.faces(f, 2));
      const Eigen::RowVector3d n = (p1 - p0).cross(p2 - p0).transpose();  // 2·area·normal
      for (int i = 0; i < 3; ++i) model->normals_.row(cand_of[model->surface_.faces(f, i)]) += n;
      if (model->surface_.faces6.rows() == nf)
        for (int i = 3; i < 6; ++i) model->normals_.row(cand_of[model->surface_.faces6(f, i)]) += n;
    }
    for (Eigen::Index b = 0; b < model->normals_.rows(); ++b) {
      const double len = model->normals_.row(b).norm();
      if (len > 0.0) model->normals_.row(b) /= len;
    }
    // The design's normals where the design is known and agrees with the mesh.
    model->design_normals_ = model->normals_;
    if (settings.design) {
      for (Eigen::Index b = 0; b < model->normals_.rows(); ++b) {
        Eigen::Vector3d gradient;
        settings.design->ValueAndGradient(tm.nodes.row(candidates[b]).transpose(), &gradient);
        const double len = gradient.norm();
        if (!(len > 0.0) || !gradient.allFinite()) continue;
        const Eigen::Vector3d n = gradient / len;
        if (!(n.dot(model->normals_.row(b)) >= kDesignNormalAgreement)) continue;
        model->design_normals_.row(b) = n.transpose();
        ++model->num_design_normals_;
      }
    }
    CheckCancel(settings);
  });

  // Clamps.
  Progress(settings, 0.05, "constraints");
  m->bcs_ = std::make_unique<fem::BoundaryConditions>(nv);
  if (settings.fixed_boxes.empty()) {
    const std::vector<int> face = MinXFaceNodes(tm, settings.min_x_tolerance);
    m->bcs_->FixNodes(face);
    m->num_fixed_nodes_ = static_cast<int>(face.size());
  } else {
    std::vector<char> fixed(nv, 0);
    for (std::size_t i = 0; i < settings.fixed_boxes.size(); ++i) {
      const Eigen::AlignedBox3d& box = settings.fixed_boxes[i];
      if (box.isEmpty()) {
        std::ostringstream msg;
        msg << "FE model: fixed box " << i << " is empty (min must not exceed max)";
        throw std::invalid_argument(msg.str());
      }
      for (int v : fem::NodesInBox(tm, box.min(), box.max())) fixed[v] = 1;
    }
    for (int v = 0; v < nv; ++v)
      if (fixed[v]) {
        m->bcs_->FixNode(v);
        ++m->num_fixed_nodes_;
      }
  }
  if (m->num_fixed_nodes_ == 0)
    throw std::invalid_argument("FE model: no node lies in the fixed region: the part would float");
  m->load_nodes_ = AddBoxLoads(tm, settings.loads, m->bcs_.get());
  CheckCancel(settings);

  // The disk cache's directory: slab factors (below) and columns (after the factorisation).
  m->cache_directory_ =
      settings.cache_directory.empty() ? fem::DefaultCacheDirectory() : settings.cache_directory;

  // Assembly and factorisation. With a cancel flag and a worker program (the window), CHOLMOD
  // runs in a child process that Cancel kills (scene/worker_process.h).
  Progress(settings, 0.1, "assemble");
  if (settings.element_block.size() > 0) {
    if (settings.element_block.size() != tm.num_elements()) {
      std::ostringstream msg;
      msg << "FE model: " << settings.element_block.size() << " slab labels for "
          << tm.num_elements() << " elements";
      throw std::invalid_argument(msg.str());
    }
    Progress(settings, 0.15, "factor slabs");
    const fem::SubstructuredSolver* reuse =
        settings.reuse ? settings.reuse->substructured() : nullptr;
    std::filesystem::path blocks;
    if (settings.use_disk_cache) {
      blocks = m->cache_directory_;
      // What this model reads or writes is newer than this, so it is kept.
      fem::PruneCacheDirectory(blocks, settings.cache_max_bytes, {".block", ".plane", ".slab"},
                               std::filesystem::file_time_type::clock::now());
    }
    try {
      m->substructured_ = std::make_unique<fem::SubstructuredSolver>(
          tm, *m->materials_, *m->bcs_, settings.element_block, reuse, blocks, settings.cancel,
          settings.block_place);
    } catch (const fem::SubstructureCancelled&) {
      throw FeModelCancelled();
    }
  } else {
    const fem::StaticSolver::Factorizer factorize = [&settings](const fem::SparseMatrixd& k_ff) {
      CheckCancel(settings);
      Progress(settings, 0.15, "factor");
      return FactorizeCancellable(k_ff, settings.cancel);
    };
    try {
      m->solver_ = std::make_unique<fem::StaticSolver>(tm, *m->materials_, *m->bcs_, factorize);
    } catch (const FactorizationCancelled&) {
      throw FeModelCancelled();
    }
  }
  if (!m->factor_status().converged)
    throw std::runtime_error("FE model: factorisation failed: " + m->factor_status().message);
  CheckCancel(settings);

  Progress(settings, 0.7, "stress operators");
  surface_side.get();  // rethrows what the surface side threw (a cancel, a bad mesh)
  const std::vector<int>& candidates = m->surface_.nodes;

  // Column cache (baseline solve), disk cache import.
  Progress(settings, 0.8, "columns");
  fem::ColumnCacheSettings cs = settings.cache;
  cs.start_worker = false;
  cs.neighbours_on_worker = true;  // the first columns need none: the model is ready sooner
  cs.near_rows_first = true;       // in slabs: a contact's rows before the whole column
  auto cache = m->solver_ ? std::make_unique<fem::ColumnCache>(*m->solver_, tm.nodes,
                                                               m->output_nodes_, candidates, cs)
                          : std::make_unique<fem::ColumnCache>(*m->substructured_, tm.nodes,
                                                               m->output_nodes_, candidates, cs);
  m->use_disk_cache_ = settings.use_disk_cache;
  m->key_ = fem::PrecomputeKey(tm, *m->materials_, *m->bcs_, m->output_nodes_, cs.precision);
  if (m->use_disk_cache_) {
    Progress(settings, 0.9, "disk cache");
    const fem::PrecomputeCache disk(m->cache_directory_);
    if (std::optional<fem::ColumnSet> set = disk.Load(m->key_))
      m->imported_nodes_ = cache->Import(*set);
  }
  CheckCancel(settings);
  m->cache_ = std::move(cache);
  if (settings.cache.start_worker) m->cache_->Start();
  m->built_at_ = std::chrono::steady_clock::now();
  m->build_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  Progress(settings, 1.0, "ready");
  return m;
}

void FeModel::PrepareReuseInBackground() {
  if (!substructured_ || prepare_reuse_.joinable()) return;
  try {
    prepare_reuse_ = std::thread([s = substructured_.get()] {
      try {
        s->PrepareReuse();
      } catch (const std::exception&) {
        // Out of memory, most likely: the next edit's model tries again (PrepareReuse runs again
        // after a throw) or factors the planes it needs itself.
      }
    });
  } catch (const std::system_error&) {
    // No thread to be had: the next edit's model runs it (SubstructuredSolver's constructor).
  }
}

void FeModel::WaitReusePrepared() {
  if (prepare_reuse_.joinable()) substructured_->PrepareReuse();  // waits for the thread's run
}

double FeModel::age_seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - built_at_).count();
}

FeModel::~FeModel() {
  if (prepare_reuse_.joinable()) prepare_reuse_.join();
  if (cache_) cache_->Stop();
}

Eigen::VectorXd FeModel::SurfaceElementVonMises(const Eigen::VectorXd& u_out) const {
  const int npe = mesh_.NodesPerElement();
  Eigen::VectorXd vm(static_cast<Eigen::Index>(surface_elements_.size()));
  Eigen::VectorXd ue(3 * npe);
  for (std::size_t i = 0; i < surface_elements_.size(); ++i) {
    const int e = surface_elements_[i];
    for (int j = 0; j < npe; ++j)
      ue.segment<3>(3 * j) = u_out.segment<3>(3 * output_index_[mesh_.elements(e, j)]);
    const Eigen::Matrix<double, 6, 1> s = stress_ops_[i] * ue;
    vm(static_cast<Eigen::Index>(i)) = fem::VonMises(s);
  }
  return vm;
}

Eigen::VectorXd FeModel::NodalVonMises(const Eigen::VectorXd& u_out) const {
  const Eigen::VectorXd vm = SurfaceElementVonMises(u_out);
  const int nv = mesh_.num_nodes(), npe = mesh_.NodesPerElement();
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(nv), weight = Eigen::VectorXd::Zero(nv);
  for (std::size_t i = 0; i < surface_elements_.size(); ++i)
    for (int j = 0; j < npe; ++j) {
      const int v = mesh_.elements(surface_elements_[i], j);
      sum(v) += element_volume_[i] * vm(static_cast<Eigen::Index>(i));
      weight(v) += element_volume_[i];
    }
  for (int v = 0; v < nv; ++v) sum(v) = weight(v) > 0.0 ? sum(v) / weight(v) : 0.0;
  return sum;
}

Eigen::MatrixX3d FeModel::FullDisplacement(const Eigen::VectorXd& u_out) const {
  Eigen::MatrixX3d u = Eigen::MatrixX3d::Zero(mesh_.num_nodes(), 3);
  for (std::size_t a = 0; a < output_nodes_.size(); ++a)
    u.row(output_nodes_[a]) = u_out.segment<3>(3 * static_cast<Eigen::Index>(a)).transpose();
  return u;
}

bool FeModel::SaveColumns(std::string* error) {
  if (!use_disk_cache_) {
    if (error) *error = "the disk cache is off for this model";
    return false;
  }
  const bool was_running = cache_->running();
  cache_->Stop();
  const fem::ColumnSet set = cache_->Export(key_);
  if (was_running) cache_->Start();
  if (set.nodes.empty()) {
    if (error) *error = "no column is ready: nothing to save";
    return false;
  }
  return fem::PrecomputeCache(cache_directory_).Save(set, error);
}

FeModelSettings ApplyFeModelData(const FeModelData& data, FeModelSettings base) {
  base.material = data.material;
  base.region_materials = data.region_materials;
  base.fixed_boxes = data.fixed_boxes;
  base.loads = data.loads;
  base.order = data.element_order;
  return base;
}

fem::TetMesh FeMeshOf(const Document& doc, const FeModelData& data) {
  const DocObject* object = doc.Find(data.tet_mesh);
  const auto* mesh = object != nullptr ? std::get_if<MeshData>(&object->data) : nullptr;
  if (mesh == nullptr || !mesh->volume) {
    throw DocumentError("FE model: its mesh object " + std::to_string(data.tet_mesh) +
                        " is missing or holds no tetrahedral mesh");
  }
  return ToFemMesh(*mesh->volume);
}

fem::MaterialTable MakeMaterialTable(const fem::Material& material,
                                     const std::vector<RegionMaterial>& regions) {
  fem::MaterialTable table(material);
  std::vector<int> seen;
  for (const RegionMaterial& r : regions) {
    if (std::find(seen.begin(), seen.end(), r.region) != seen.end()) {
      throw std::invalid_argument("FE model: region " + std::to_string(r.region) +
                                  " has two materials");
    }
    seen.push_back(r.region);
    table.Set(r.region, r.material);
  }
  return table;
}

std::vector<std::vector<int>> AddBoxLoads(const fem::TetMesh& mesh,
                                          const std::vector<FeLoad>& loads,
                                          fem::BoundaryConditions* bcs) {
  std::vector<std::vector<int>> nodes;
  for (std::size_t i = 0; i < loads.size(); ++i) {
    const FeLoad& load = loads[i];
    const auto where = [&] {
      const Eigen::Vector3d& a = load.box.min();
      const Eigen::Vector3d& b = load.box.max();
      std::ostringstream msg;
      msg << "FE model: load " << i << " (box " << a.x() << "," << a.y() << "," << a.z() << " .. "
          << b.x() << "," << b.y() << "," << b.z() << " m): ";
      return msg.str();
    };
    if (load.box.isEmpty()) throw std::invalid_argument(where() + "min must not exceed max");
    if (!load.force.allFinite()) throw std::invalid_argument(where() + "the force is not finite");
    std::vector<int> in = fem::NodesInBox(mesh, load.box.min(), load.box.max());
    if (in.empty()) {
      throw std::invalid_argument(where() +
                                  "the box holds no node of the mesh; enlarge it or move it "
                                  "onto the part");
    }
    const Eigen::Vector3d share = load.force / static_cast<double>(in.size());
    for (int v : in) bcs->AddPointLoad(v, share);
    nodes.push_back(std::move(in));
  }
  return nodes;
}

std::vector<int> MinXFaceNodes(const fem::TetMesh& mesh, double tolerance) {
  if (mesh.num_nodes() == 0) return {};
  const Eigen::RowVector3d lo = mesh.nodes.colwise().minCoeff();
  const Eigen::RowVector3d hi = mesh.nodes.colwise().maxCoeff();
  // The layer's default thickness is a fraction of the part's size, not of its mesh: a tolerance
  // tied to the element size (it was a quarter of the mean boundary edge) shrinks as the mesh is
  // refined, so on a face that is not exactly flat (the platform's weld lip, 1 mm proud of its
  // wall face) a fine mesh clamped only the lip's crest (docs/fem.md, section 5).
  const double tol = tolerance >= 0.0 ? tolerance : kMinXFaceLayer * (hi - lo).maxCoeff();
  return fem::NodesInBox(mesh, Eigen::Vector3d(lo.x() - 1.0, -1e30, -1e30),
                         Eigen::Vector3d(lo.x() + tol, 1e30, 1e30));
}

fem::TetMesh MeshSceneSolidForFe(const std::string& scene_path, const std::string& solid_name,
                                 double resolution, const std::atomic<bool>* cancel,
                                 const std::function<void(double)>& progress, bool lattice,
                                 double flat_cells) {
  const auto check = [&] {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) throw FeModelCancelled();
  };
  if (progress) progress(0.0);
  const SceneSolidGrid grid = PrepareSceneSolid(scene_path, solid_name, resolution);
  check();
  modeling::SurfaceMeshSettings ss;
  ss.bounds = grid.bounds;
  ss.cell_size = grid.cell;
  ss.flat_coarsen_cells = flat_cells;
  if (lattice) ss.mesher = modeling::SurfaceMesher::kLattice;
  // On another grid placement where a wall about a cell thick falls between grid planes.
  const modeling::TriangleMesh surface = modeling::MeshSurfaceKeepingVolume(grid.compiled, ss).mesh;
  if (progress) progress(0.3);
  check();
  modeling::TetMeshSettings ts;
  ts.max_radius_edge = 2.0;
  ts.cancel = cancel;
  if (progress) ts.progress = [&](double f) { progress(0.3 + 0.7 * f); };
  modeling::TetMesh tets;
  try {
    tets = TetrahedralizeCancellable(surface, ts);  // a child process Cancel kills
  } catch (const modeling::TetMeshingCancelled&) {
    throw FeModelCancelled();
  }
  check();
  return ToFemMesh(tets);
}

std::string PlatformScenePath() {
  namespace fs = std::filesystem;
  if (const char* p = std::getenv("SPIDARCAD_PLATFORM_SCENE"); p != nullptr && *p != 0) return p;
  return AssetPath("scenes/platform.json");
}

int AddSlotForcesDisplacement(fem::ColumnCache* cache, int n, const int* candidate,
                              const int* substitute, const double* force, double* u) {
  int skipped = 0;
  for (int s = 0; s < n; ++s) {
    const int b = candidate[s], r = substitute[s];
    if (r < 0 || !cache->Pin(r)) {
      ++skipped;
      continue;
    }
    if (!cache->IsReady(r)) {  // the near rows only, so far: the shape would tear at a slab
      cache->Unpin(r);
      ++skipped;
      continue;
    }
    const int rb = 3 * cache->OutputIndexOfCandidate(b), rr = 3 * cache->OutputIndexOfCandidate(r);
    for (int j = 0; j < 3; ++j) {
      const double f = force[3 * s + j];
      cache->AddColumn(r, j, f, u);
      if (r == b) continue;
      for (int i = 0; i < 3; ++i) {  // shift: swap the row blocks of b and r in r's column
        const double g_rr = cache->Value(rr + i, r, j), g_br = cache->Value(rb + i, r, j);
        u[rb + i] += f * (g_rr - g_br);
        u[rr + i] += f * (g_br - g_rr);
      }
    }
    cache->Unpin(r);
  }
  return skipped;
}

}  // namespace spidarcad::app
