// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/fe_setup.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>
#include <variant>
#include <vector>

#include "scene/worker_process.h"
#include "spidarcad/modeling/cgal_mesher.h"
#include "spidarcad/modeling/feature_sharpening.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::app {
namespace {

// Half-side of the box searched for a solid, m (as `spidarcad mesh`): reaching it = unbounded.
constexpr double kSearchHalfSide = 10.0;
// `spidarcad mesh`'s default budget (app/src/cli/mesh_command.cc, docs/limits.md).
constexpr double kBudgetCells = 134217728.0;
constexpr double kBudgetBytes = 2147483648.0;
constexpr double kBudgetWork = 2e11;
// TetGen's radius-edge bound when the settings leave it at 0 (as MeshSceneSolidForFe).
constexpr double kDefaultRadiusEdge = 2.0;

std::string Quoted(const DocObject& o) {
  return std::string(ObjectKindName(o.data)) + " '" + o.name + "'";
}

// `what` starts the error messages ("set up FE for", "mesh").
void CheckSettings(const DocObject& o, const MeshSettings& s, FeSourceKind kind,
                   const std::string& what) {
  if (!(s.cell_size >= 0.0) || !(s.max_tet_volume >= 0.0) || !(s.max_radius_edge >= 0.0) ||
      !std::isfinite(s.cell_size + s.max_tet_volume + s.max_radius_edge)) {
    throw DocumentError(what + " " + Quoted(o) +
                        ": cell size, tet volume and radius-edge bound must be finite and >= 0");
  }
  if (s.max_radius_edge != 0.0 && s.max_radius_edge < 1.0) {
    throw DocumentError(what + " " + Quoted(o) + ": radius-edge bound " +
                        std::to_string(s.max_radius_edge) + " must be 0 (default) or >= 1");
  }
  if (!s.mesher.empty() && s.mesher != "tetgen" && s.mesher != "cgal") {
    throw DocumentError(what + " " + Quoted(o) + ": mesher '" + s.mesher +
                        "' (expected tetgen or cgal)");
  }
  if (kind != FeSourceKind::kSolid && (s.mesher == "cgal" || s.sharp_edges)) {
    throw DocumentError(what + " " + Quoted(o) +
                        ": CGAL and sharp edges mesh an implicit solid; a surface is meshed by "
                        "TetGen as it is (choose tetgen, no sharp edges)");
  }
  if (!s.surface_mesher.empty() && s.surface_mesher != "lattice") {
    throw DocumentError(what + " " + Quoted(o) + ": surface mesher '" + s.surface_mesher +
                        "' (expected lattice, or none for marching tetrahedra)");
  }
  if (!s.surface_mesher.empty() && (kind != FeSourceKind::kSolid || s.mesher == "cgal")) {
    throw DocumentError(what + " " + Quoted(o) +
                        ": the lattice surface is meshed from an implicit solid for TetGen; " +
                        (kind != FeSourceKind::kSolid ? "this source is a surface already"
                                                      : "CGAL does not use a surface") +
                        " (drop the lattice surface)");
  }
  if (!(s.flat_cells >= 0.0 && s.flat_cells <= 1.0)) {
    throw DocumentError(what + " " + Quoted(o) + ": flat faces coarsened below " +
                        std::to_string(s.flat_cells) + " cells; expected [0, 1] (0: off)");
  }
  if (s.flat_cells > 0.0 &&
      (kind != FeSourceKind::kSolid || s.mesher == "cgal" || !s.surface_mesher.empty())) {
    throw DocumentError(what + " " + Quoted(o) +
                        ": flat faces are coarsened on an implicit solid's marching-tetrahedra "
                        "surface for TetGen (set flat cells to 0 for a surface, CGAL or the "
                        "lattice)");
  }
  if (s.mesher == "cgal" && s.sharp_edges) {
    throw DocumentError(
        what + " " + Quoted(o) +
        ": sharp edges sharpen the grid surface TetGen uses; CGAL does not use one");
  }
}

// The copy-on-main-thread part shared by PrepareFeMesh and PrepareFeRemesh.
FeMeshInput Prepare(const DocObject& o, const MeshSettings& settings,
                    const std::string& what = "set up FE for") {
  FeMeshInput in;
  in.source = o.id;
  in.source_revision = o.revision;
  in.source_name = o.name;
  in.settings = settings;
  if (const auto* s = std::get_if<SolidData>(&o.data)) {
    in.kind = FeSourceKind::kSolid;
    in.root = s->root;
  } else if (const auto* s = std::get_if<SculptData>(&o.data)) {
    in.kind = FeSourceKind::kSculpt;
    if (!s->mesh || !IsClosedSurface(*s->mesh))
      throw DocumentError(what + " " + Quoted(o) +
                          ": its mesh is not a closed surface (TetGen needs one)");
    // A copy: strokes may change a sculpt mesh in place.
    in.surface = std::make_shared<const modeling::TriangleMesh>(*s->mesh);
  } else if (const auto* m = std::get_if<MeshData>(&o.data)) {
    if (m->volume) throw DocumentError(what + " " + Quoted(o) + ": it already holds tets");
    if (!m->surface || !IsClosedSurface(*m->surface))
      throw DocumentError(what + " " + Quoted(o) +
                          ": its surface is not closed (TetGen needs a closed surface)");
    in.kind = FeSourceKind::kSurfaceMesh;
    in.surface = m->surface;  // immutable
  } else {
    throw DocumentError(what + " " + Quoted(o) +
                        ": only a solid, a sculpt or a closed surface mesh can be meshed");
  }
  CheckSettings(o, settings, in.kind, what);
  return in;
}

void Report(const std::function<void(double)>& progress, double f) {
  if (progress) progress(f);
}

modeling::TetMesh Tetgen(const modeling::TriangleMesh& surface, const MeshSettings& s,
                         const std::atomic<bool>* cancel,
                         const std::function<void(double)>& progress, double from) {
  modeling::TetMeshSettings ts;
  ts.max_radius_edge = s.max_radius_edge > 0.0 ? s.max_radius_edge : kDefaultRadiusEdge;
  ts.max_volume = s.max_tet_volume;
  ts.cancel = cancel;
  if (progress) ts.progress = [&progress, from](double f) { progress(from + (1.0 - from) * f); };
  // With a cancel flag, in a child process that Cancel kills (scene/worker_process.h).
  return TetrahedralizeCancellable(surface, ts);
}

}  // namespace

FeSourceKind ClassifyFeSource(const Document& doc, ObjectId id) {
  const DocObject* o = doc.Find(id);
  if (o == nullptr) return FeSourceKind::kNone;
  if (std::holds_alternative<FeModelData>(o->data)) return FeSourceKind::kFeModel;
  if (std::holds_alternative<SolidData>(o->data)) return FeSourceKind::kSolid;
  if (const auto* s = std::get_if<SculptData>(&o->data)) {
    return s->mesh && IsClosedSurface(*s->mesh) ? FeSourceKind::kSculpt : FeSourceKind::kNone;
  }
  if (const auto* m = std::get_if<MeshData>(&o->data)) {
    if (m->volume && m->volume->tets.cols() > 0) return FeSourceKind::kVolumeMesh;
    if (m->surface && IsClosedSurface(*m->surface)) return FeSourceKind::kSurfaceMesh;
  }
  return FeSourceKind::kNone;
}

const char* FeSourceKindText(FeSourceKind kind) {
  switch (kind) {
    case FeSourceKind::kFeModel:
      return "FE model";
    case FeSourceKind::kVolumeMesh:
      return "volume mesh";
    case FeSourceKind::kSurfaceMesh:
      return "surface mesh";
    case FeSourceKind::kSolid:
      return "solid";
    case FeSourceKind::kSculpt:
      return "sculpt";
    case FeSourceKind::kNone:
      break;
  }
  return "";
}

bool IsClosedSurface(const modeling::TriangleMesh& mesh) {
  const Eigen::Index nt = mesh.triangles.cols();
  const Eigen::Index nv = mesh.vertices.cols();
  if (nt < 4 || nv < 4) return false;  // the fewest a closed solid needs (a tetrahedron)
  // Directed edges as (a << 32 | b): each must appear once, and its reverse once.
  std::vector<std::uint64_t> directed;
  directed.reserve(3 * nt);
  for (Eigen::Index t = 0; t < nt; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.triangles(k, t), b = mesh.triangles((k + 1) % 3, t);
      if (a < 0 || b < 0 || a >= nv || b >= nv || a == b) return false;
      directed.push_back(static_cast<std::uint64_t>(a) << 32 | static_cast<std::uint32_t>(b));
    }
  }
  std::sort(directed.begin(), directed.end());
  if (std::adjacent_find(directed.begin(), directed.end()) != directed.end()) return false;
  for (const std::uint64_t e : directed) {
    const std::uint64_t reverse = (e & 0xffffffffu) << 32 | e >> 32;
    if (!std::binary_search(directed.begin(), directed.end(), reverse)) return false;
  }
  return true;
}

ObjectId FeModelFor(const Document& doc, ObjectId id) {
  const DocObject* o = doc.Find(id);
  if (o == nullptr) return 0;
  if (std::holds_alternative<FeModelData>(o->data)) return id;
  const bool is_mesh = std::holds_alternative<MeshData>(o->data);
  for (const DocObject& f : doc.objects()) {
    const auto* fe = std::get_if<FeModelData>(&f.data);
    if (fe == nullptr) continue;
    if (is_mesh && fe->tet_mesh == id) return f.id;
    const DocObject* mesh = doc.Find(fe->tet_mesh);
    const auto* md = mesh != nullptr ? std::get_if<MeshData>(&mesh->data) : nullptr;
    if (md != nullptr && md->source == id && md->source != 0) return f.id;
  }
  return 0;
}

double FlatCellsForOrder(FeSourceKind kind, const MeshSettings& settings, int order) {
  const bool plain_tetgen_surface = kind == FeSourceKind::kSolid && settings.mesher != "cgal" &&
                                    settings.surface_mesher.empty() && !settings.sharp_edges;
  return order == 2 && plain_tetgen_surface ? kQuadraticFlatCells : 0.0;
}

FeMeshInput PrepareFeMesh(const Document& doc, ObjectId source, const MeshSettings& settings) {
  const DocObject* o = doc.Find(source);
  if (o == nullptr)
    throw DocumentError("set up FE: no object with id " + std::to_string(source) +
                        " in the document");
  return Prepare(*o, settings);
}

FeMeshInput PrepareFeRemesh(const Document& doc, ObjectId mesh) {
  const DocObject& o = doc.Get(mesh);
  const auto* m = std::get_if<MeshData>(&o.data);
  if (m == nullptr) throw DocumentError("refresh " + Quoted(o) + ": not a mesh object");
  if (m->source == 0)
    throw DocumentError("refresh " + Quoted(o) + ": it was not made from another object");
  const DocObject* src = doc.Find(m->source);
  if (src == nullptr)
    throw DocumentError("refresh " + Quoted(o) + ": its source (object " +
                        std::to_string(m->source) + ") was deleted");
  FeMeshInput in = Prepare(*src, m->settings, "refresh");
  in.volume = m->volume != nullptr;
  return in;
}

FeMeshInput PrepareSolidMesh(const Document& doc, ObjectId source, const MeshSettings& settings,
                             bool volume) {
  const DocObject* o = doc.Find(source);
  if (o == nullptr)
    throw DocumentError("mesh: no object with id " + std::to_string(source) + " in the document");
  if (!std::holds_alternative<SolidData>(o->data))
    throw DocumentError("mesh " + Quoted(*o) + ": only an implicit solid is meshed here");
  FeMeshInput in = Prepare(*o, settings, "mesh");
  if (!volume && settings.mesher == "cgal")
    throw DocumentError("mesh " + Quoted(*o) +
                        ": CGAL makes tetrahedra; a surface is meshed on the grid (no mesher)");
  in.volume = volume;
  return in;
}

namespace {

// FeSolidBounds; `fine` = false stops at the coarse search (a box that holds the solid, found at
// a cost that does not grow with the cell count: what an estimate may spend).
Eigen::AlignedBox3d SolidBox(const modeling::ImplicitNode& root, const std::string& name,
                             double* cell, modeling::CompiledSolid* compiled, bool fine,
                             const std::atomic<bool>* cancel) {
  try {
    *compiled = modeling::CompiledSolid::Compile(root);
  } catch (const std::exception& e) {
    throw std::invalid_argument("solid '" + name + "': " + e.what());
  }
  const Eigen::AlignedBox3d search(Eigen::Vector3d::Constant(-kSearchHalfSide),
                                   Eigen::Vector3d::Constant(kSearchHalfSide));
  const double coarse = *cell > 0.0 ? std::max(*cell, 0.005) : 0.01;
  const Eigen::AlignedBox3d rough = modeling::FindBounds(*compiled, search, coarse, cancel);
  if (rough.isEmpty()) throw std::invalid_argument("solid '" + name + "' is empty");
  for (int a = 0; a < 3; ++a) {
    if (rough.min()[a] <= -kSearchHalfSide + coarse || rough.max()[a] >= kSearchHalfSide - coarse)
      throw std::invalid_argument("solid '" + name +
                                  "' reaches 10 m from the origin (unbounded, e.g. a bare "
                                  "half-space): intersect it with a box");
  }
  if (!(*cell > 0.0)) *cell = rough.sizes().maxCoeff() / kFeCellsAcross;
  Eigen::AlignedBox3d box = fine ? modeling::FindBounds(*compiled, rough, *cell, cancel) : rough;
  box.min().array() -= 2.0 * *cell;
  box.max().array() += 2.0 * *cell;
  return box;
}

}  // namespace

Eigen::AlignedBox3d FeSolidBounds(const modeling::ImplicitNode& root, const std::string& name,
                                  double* cell, modeling::CompiledSolid* compiled,
                                  const std::atomic<bool>* cancel) {
  return SolidBox(root, name, cell, compiled, true, cancel);
}

std::optional<modeling::SurfaceMeshEstimate> EstimateFeMesh(const FeMeshInput& input,
                                                            const std::atomic<bool>* cancel) {
  if (input.kind != FeSourceKind::kSolid || input.settings.mesher == "cgal") return std::nullopt;
  double cell = input.settings.cell_size;
  modeling::CompiledSolid compiled;
  modeling::SurfaceMeshSettings ss;
  ss.bounds = SolidBox(input.root, input.source_name, &cell, &compiled, false, cancel);
  ss.cell_size = cell;
  return modeling::EstimateSurfaceMesh(compiled, ss);
}

std::string FeMeshOverBudget(const modeling::SurfaceMeshEstimate& estimate) {
  const struct {
    double value, limit;
    const char* what;
  } figures[] = {{estimate.grid_cells, kBudgetCells, "grid cells"},
                 {estimate.bytes, kBudgetBytes, "memory (bytes)"},
                 {estimate.work, kBudgetWork, "work (tape instructions)"}};
  std::string text;
  for (const auto& f : figures) {
    if (f.value <= f.limit) continue;
    char line[160];
    std::snprintf(line, sizeof line, "%sestimated %s %.3g is over %.3g", text.empty() ? "" : "; ",
                  f.what, f.value, f.limit);
    text += line;
  }
  return text;
}

std::string LargeMeshQuestion(const std::string& name, const FeMeshInput& input,
                              const std::atomic<bool>* cancel) {
  const auto estimate = EstimateFeMesh(input, cancel);
  if (!estimate) return "";
  const std::string over = FeMeshOverBudget(*estimate);
  if (over.empty()) return "";
  return "Meshing '" + name + "' is large: " + over + " (" + estimate->Describe() +
         "; the limits of spidarcad mesh, docs/limits.md).";
}

namespace {

// True when `input` asks for tetrahedra in slabs that can be made so (FeMeshInput::slabs).
bool InSlabs(const FeMeshInput& input) {
  return input.slabs > 0 && input.volume && !input.settings.sharp_edges &&
         input.settings.max_tet_volume == 0.0 && input.settings.mesher != "cgal";
}

using SlabMesher = std::function<SlabFeMesh(const Eigen::AlignedBox3d&, double,
                                            const std::vector<double>&, const SlabMeshOptions&)>;

// Meshes in input.slabs slabs with `mesh`, trying the planes of `previous` (its box and spacing;
// may be null) and then `fresh` planes on (box, spacing), shifted by 0 and a quarter of the
// spacing to either side (a plane may meet a face of the surface: the cut refuses a triangle in a
// plane).
// On success fills `result` (tetrahedra, their boundary, the slabs and their planes) and returns
// true; when every try failed, notes the first failure in result->slab_note and returns false
// (the caller meshes in one piece). A cancel is rethrown.
bool MeshInSlabs(const FeMeshInput& input, const Eigen::AlignedBox3d& box, double spacing,
                 const SlabFeMesh* previous,
                 const std::function<std::vector<double>(const Eigen::AlignedBox3d&)>& fresh,
                 const SlabMesher& mesh, const std::atomic<bool>* cancel,
                 const std::function<void(double)>& progress, FeMeshResult* result) {
  SlabMeshOptions so;
  so.max_radius_edge =
      input.settings.max_radius_edge > 0.0 ? input.settings.max_radius_edge : kDefaultRadiusEdge;
  so.cancel = cancel;
  so.progress = progress;
  so.cache_directory = input.cache_directory;
  // Strips for a solid only (a sculpt's planes are moved off its triangles; strip planes are not).
  so.strips = input.kind == FeSourceKind::kSolid ? input.strips : 0;
  so.strip_min_triangles = input.strip_min_triangles;
  struct Try {
    Eigen::AlignedBox3d box;
    double spacing;
    std::vector<double> planes;
    bool strips = true;  // with so.strips (and the previous mesh's), or none
  };
  std::vector<Try> tries;
  if (previous != nullptr && static_cast<int>(previous->planes.size()) + 1 == input.slabs)
    tries.push_back({previous->grid_bounds, previous->cell, previous->planes});
  for (double shift : {0.0, 0.25, -0.25}) {
    Eigen::AlignedBox3d shifted = box;  // moves the planes by the shift
    shifted.min().x() += shift * spacing;
    shifted.max().x() += shift * spacing;
    tries.push_back({box, spacing, fresh(shifted)});
  }
  // Last, without strips: a strip plane may meet a face of the solid, or the earlier mesh's
  // strips may no longer suit it.
  if (so.strips > 1) tries.push_back({box, spacing, fresh(box), false});
  std::string why;
  for (const Try& t : tries) {
    try {
      SlabMeshOptions o = so;
      // The previous mesh is ignored by the mesher for another box, spacing or planes.
      o.previous = t.strips ? previous : nullptr;
      if (!t.strips) o.strips = 0;
      auto slabs = std::make_shared<const SlabFeMesh>(mesh(t.box, t.spacing, t.planes, o));
      if (slabs->volume->tets.cols() == 0) throw std::runtime_error("no tetrahedra");
      result->settings.slab_planes = slabs->planes;
      result->settings.slab_strip_axis = slabs->strip_axis;
      result->settings.slab_strips = slabs->strip_planes;
      result->volume = slabs->volume;
      result->surface =
          std::make_shared<const modeling::TriangleMesh>(modeling::BoundarySurface(*slabs->volume));
      result->slabs = std::move(slabs);
      Report(progress, 1.0);
      return true;
    } catch (const modeling::MeshingCancelled&) {
      throw;
    } catch (const modeling::TetMeshingCancelled&) {
      throw;
    } catch (const std::exception& e) {
      if (why.empty()) why = e.what();
    }
  }
  result->slab_note = std::string("meshed in one piece: in ") + std::to_string(input.slabs) +
                      " slabs it failed (" + why + ")";
  return false;
}

}  // namespace

FeMeshResult MeshFeSource(const FeMeshInput& input, const std::atomic<bool>* cancel,
                          const std::function<void(double)>& progress) {
  FeMeshResult result;
  result.settings = input.settings;
  result.settings.slab_planes.clear();  // set below when the tetrahedra are made in slabs
  result.settings.slab_strips.clear();
  Report(progress, 0.0);
  if (input.kind == FeSourceKind::kSculpt || input.kind == FeSourceKind::kSurfaceMesh) {
    if (!input.surface) throw std::invalid_argument("set up FE: no surface to mesh");
    result.settings.cell_size = 0.0;
    if (input.kind == FeSourceKind::kSculpt && InSlabs(input)) {
      // In slabs across x, spaced by SurfaceSlabSpacing, on the earlier mesh's box,
      // spacing and planes while its box holds the surface's (a stroke moves only the vertices
      // under the tool, so the slabs it did not reach come back as they were).
      const modeling::TriangleMesh& surface = *input.surface;
      const SlabFeMesh* previous = input.previous_slabs.get();
      Eigen::AlignedBox3d box(surface.vertices.rowwise().minCoeff(),
                              surface.vertices.rowwise().maxCoeff());
      if (previous != nullptr && !previous->grid_bounds.contains(box)) previous = nullptr;
      const double spacing = SurfaceSlabSpacing(surface);
      box.min().array() -= 2.0 * spacing;
      box.max().array() += 2.0 * spacing;
      if (MeshInSlabs(
              input, box, spacing, previous,
              [&](const Eigen::AlignedBox3d& b) {
                return SurfaceSlabPlanes(surface, b, spacing, input.slabs);
              },
              [&](const Eigen::AlignedBox3d& b, double h, const std::vector<double>& planes,
                  const SlabMeshOptions& so) {
                return MeshSurfaceInSlabs(surface, b, h, planes, so);
              },
              cancel, progress, &result))
        return result;
    }
    result.surface = input.surface;
    if (input.volume) {
      result.volume = std::make_shared<const modeling::TetMesh>(
          Tetgen(*input.surface, input.settings, cancel, progress, 0.0));
    }
    Report(progress, 1.0);
    return result;
  }
  if (input.kind != FeSourceKind::kSolid)
    throw std::invalid_argument("set up FE: '" + input.source_name + "' cannot be meshed");
  double cell = input.settings.cell_size;
  modeling::CompiledSolid compiled;
  const Eigen::AlignedBox3d bounds =
      FeSolidBounds(input.root, input.source_name, &cell, &compiled, cancel);
  result.settings.cell_size = cell;
  const bool lattice = input.settings.surface_mesher == "lattice";
  if (input.settings.mesher == "cgal") {
    if (!input.volume)
      throw std::invalid_argument("solid '" + input.source_name +
                                  "': CGAL makes tetrahedra, not a surface alone");
    modeling::CgalMeshSettings cs = modeling::CgalMeshSettings::ForSize(cell);
    cs.cancel = cancel;
    cs.progress = progress;
    if (input.settings.max_radius_edge > 0.0)
      cs.cell_radius_edge_ratio = input.settings.max_radius_edge;
    // With a cancel flag, in a child process that Cancel kills (scene/worker_process.h).
    auto volume = std::make_shared<const modeling::TetMesh>(
        MeshWithCgalCancellable(input.root, compiled, bounds, cs));
    result.surface =
        std::make_shared<const modeling::TriangleMesh>(modeling::BoundarySurface(*volume));
    result.volume = std::move(volume);
    Report(progress, 1.0);
    return result;
  }
  if (InSlabs(input)) {
    // In slabs across x, on the earlier mesh's grid and planes when it was made at this cell size
    // in as many slabs and its grid holds the solid's box (then the slabs the edit did not reach
    // come back as they were).
    const SlabFeMesh* previous = input.previous_slabs.get();
    if (previous != nullptr && !(previous->cell == cell && previous->grid_bounds.contains(bounds)))
      previous = nullptr;
    if (MeshInSlabs(
            input, bounds, cell, previous,
            [&](const Eigen::AlignedBox3d& box) {
              SlabMeshOptions surface;
              surface.lattice = lattice;
              return SlabPlanes(box, cell, input.slabs, surface);
            },
            [&](const Eigen::AlignedBox3d& box, double h, const std::vector<double>& planes,
                const SlabMeshOptions& so) {
              SlabMeshOptions snapped = so;
              snapped.snap_cells = modeling::kProductSnapCells;
              snapped.lattice = lattice;
              snapped.flat_coarsen_cells = input.settings.flat_cells;
              return MeshSolidInSlabs(compiled, box, h, planes, snapped);
            },
            cancel, progress, &result))
      return result;
  }
  modeling::SurfaceMeshSettings ss;
  ss.bounds = bounds;
  ss.cell_size = cell;
  // Snapped as `spidarcad mesh` does (no triangle of a smooth surface under about 10°).
  ss.snap_cells = modeling::kProductSnapCells;
  if (lattice) ss.mesher = modeling::SurfaceMesher::kLattice;
  ss.flat_coarsen_cells = input.settings.flat_cells;
  ss.cancel = cancel;
  const double surface_share = input.volume ? 0.3 : 0.9;
  if (progress) ss.progress = [&progress, surface_share](double f) { progress(surface_share * f); };
  modeling::TriangleMesh surface;
  if (input.settings.sharp_edges) {
    modeling::FeatureSettings fs;
    fs.cell_size = cell;
    fs.cancel = cancel;
    // The slivers sharpening leaves along creases repaired, as `spidarcad mesh --sharp` does:
    // TetGen's worst dihedral and tet count depend on them (feature_sharpening.h, step 4b).
    fs.sliver_angle_deg = modeling::kProductSliverAngleDeg;
    fs.sliver_fallback_deviation_cells = modeling::kProductSliverFallbackCells;
    // The lattice leaves no vertex near a box corner to move there (`spidarcad mesh --mesher
    // lattice --sharp`).
    fs.insert_corners = lattice;
    // On another grid placement where a part about a cell thick loses volume or keeps slivers.
    surface = modeling::MeshSharpSurface(compiled, ss, fs).mesh;
  } else {
    // On another grid placement where a wall about a cell thick falls between grid planes.
    surface = modeling::MeshSurfaceKeepingVolume(compiled, ss).mesh;
  }
  if (surface.triangles.cols() == 0)
    throw std::invalid_argument("solid '" + input.source_name + "': the surface mesh is empty at " +
                                std::to_string(cell) + " m cells");
  Report(progress, input.volume ? 0.35 : 1.0);
  if (input.volume) {
    result.volume = std::make_shared<const modeling::TetMesh>(
        Tetgen(surface, input.settings, cancel, progress, 0.35));
  }
  result.surface = std::make_shared<const modeling::TriangleMesh>(std::move(surface));
  Report(progress, 1.0);
  return result;
}

namespace {

// Throws when the source is gone or no longer at the revision that was meshed.
void CheckSourceUnchanged(const Document& doc, const FeMeshInput& in, const std::string& what) {
  const DocObject* src = doc.Find(in.source);
  if (src == nullptr)
    throw DocumentError(what + ": '" + in.source_name + "' was deleted while it was meshed");
  if (src->revision != in.source_revision)
    throw DocumentError(what + ": '" + in.source_name +
                        "' changed while it was meshed; the mesh is of the old shape");
}

// Builds its commands at the first Do (they need the ids the first ones get) and then replays
// them: one undo step.
class LazyMacroCommand : public Command {
 public:
  using Step = std::function<std::unique_ptr<Command>(const Document&)>;
  LazyMacroCommand(std::string description, std::vector<Step> steps)
      : description_(std::move(description)), steps_(std::move(steps)) {}

  void Do(Document& doc) override {
    if (!done_) {
      try {
        for (Step& step : steps_) {
          commands_.push_back(step(doc));
          commands_.back()->Do(doc);
        }
      } catch (...) {
        // The last command threw before committing anything; undo the ones done before it.
        if (!commands_.empty()) commands_.pop_back();
        for (std::size_t i = commands_.size(); i > 0; --i) commands_[i - 1]->Undo(doc);
        commands_.clear();
        throw;
      }
      done_ = true;
      steps_.clear();
      return;
    }
    for (auto& c : commands_) c->Do(doc);
  }
  void Undo(Document& doc) override {
    for (std::size_t i = commands_.size(); i > 0; --i) commands_[i - 1]->Undo(doc);
  }
  std::string Description() const override { return description_; }

 private:
  std::string description_;
  std::vector<Step> steps_;
  std::vector<std::unique_ptr<Command>> commands_;
  bool done_ = false;
};

const fem::Material kSteel = {200.0e9, 0.30};

// The step that adds the mesh object of `mesh` made from input's source ("NAME tets" or "NAME
// surface"), checking first that the source is unchanged (`what` starts the error).
LazyMacroCommand::Step AddMeshStep(const FeMeshInput& input, const FeMeshResult& mesh,
                                   const std::string& what) {
  return [input, mesh, what](const Document& doc) {
    CheckSourceUnchanged(doc, input, what);
    MeshData data;
    data.source = input.source;
    data.source_revision = input.source_revision;
    data.surface = mesh.surface;
    data.volume = mesh.volume;
    data.settings = mesh.settings;
    const std::string suffix = mesh.volume ? " tets" : " surface";
    return edit::AddObject(UniqueObjectName(doc, input.source_name + suffix), std::move(data));
  };
}

}  // namespace

std::unique_ptr<Command> AddMeshOf(const FeMeshInput& input, FeMeshResult mesh) {
  if (input.volume && !mesh.volume) throw std::invalid_argument("mesh: the mesh has no tetrahedra");
  if (!input.volume) mesh.volume = nullptr;  // what was asked for: the surface alone
  if (!mesh.surface && !mesh.volume) throw std::invalid_argument("mesh: the mesh is empty");
  std::vector<LazyMacroCommand::Step> steps;
  steps.push_back(AddMeshStep(input, mesh, "mesh"));
  return std::make_unique<LazyMacroCommand>(
      "Mesh " + input.source_name + (input.volume ? " (tetrahedra)" : " (surface)"),
      std::move(steps));
}

std::unique_ptr<Command> SetUpFe(const FeMeshInput& input, FeMeshResult mesh) {
  if (!mesh.volume) throw std::invalid_argument("set up FE: the mesh has no tetrahedra");
  std::vector<LazyMacroCommand::Step> steps;
  steps.push_back(AddMeshStep(input, mesh, "set up FE"));
  steps.push_back([input](const Document& doc) {
    const ObjectId tets = doc.last_created().back();
    return edit::AddFeModel(UniqueObjectName(doc, input.source_name + " FE"), tets, kSteel, {},
                            input.element_order);
  });
  return std::make_unique<LazyMacroCommand>("Set up FE for " + input.source_name, std::move(steps));
}

std::unique_ptr<Command> SetUpFeOnMesh(const Document& doc, ObjectId mesh, int element_order) {
  const DocObject& o = doc.Get(mesh);
  const auto* m = std::get_if<MeshData>(&o.data);
  if (m == nullptr || !m->volume)
    throw DocumentError("set up FE on " + Quoted(o) + ": it holds no tetrahedra");
  std::vector<std::unique_ptr<Command>> commands;
  commands.push_back(
      edit::AddFeModel(UniqueObjectName(doc, o.name + " FE"), mesh, kSteel, {}, element_order));
  return std::make_unique<MacroCommand>("Set up FE for " + o.name, std::move(commands));
}

std::unique_ptr<Command> RefreshFeMesh(ObjectId mesh, const FeMeshInput& input,
                                       FeMeshResult result) {
  if (input.volume && !result.volume)
    throw std::invalid_argument("refresh: the mesh has no tetrahedra");
  if (!input.volume) result.volume = nullptr;
  std::vector<LazyMacroCommand::Step> steps;
  steps.push_back([mesh, input, result](const Document& doc) {
    CheckSourceUnchanged(doc, input, "refresh");
    const DocObject& o = doc.Get(mesh);
    const auto* old = std::get_if<MeshData>(&o.data);
    if (old == nullptr || old->source != input.source)
      throw DocumentError("refresh: object '" + o.name + "' is no longer a mesh of '" +
                          input.source_name + "'");
    MeshData data = *old;
    data.source_revision = input.source_revision;
    data.surface = result.surface;
    data.volume = result.volume;
    data.settings = result.settings;
    std::vector<std::unique_ptr<Command>> commands;
    commands.push_back(edit::SetObjectData(mesh, std::move(data)));
    for (const DocObject& f : doc.objects()) {
      const auto* fe = std::get_if<FeModelData>(&f.data);
      if (fe != nullptr && fe->tet_mesh == mesh && fe->precompute_key != 0)
        commands.push_back(edit::SetPrecomputeKey(f.id, 0));
    }
    return std::make_unique<MacroCommand>("", std::move(commands));
  });
  return std::make_unique<LazyMacroCommand>("Refresh " + input.source_name + " mesh",
                                            std::move(steps));
}

}  // namespace spidarcad::app
