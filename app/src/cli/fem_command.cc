// `spidarcad fem`: static linear-elastic solve of a tetrahedral mesh (.vtu) or of a scene's
// solid meshed on the fly, with clamped boxes, pushed surface nodes and point loads. Writes the
// displacement and von Mises stress to a .vtu and a JSON summary to stdout.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <variant>
#include <vector>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "cli/interrupt_output.h"
#include "doc/document.h"
#include "scene/document_file.h"
#include "scene/fe_model.h"
#include "scene/fe_setup.h"
#include "scene/scene_solid.h"
#include "scene/slab_fe_mesh.h"
#include "scene/vtu_io.h"
#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/cache_file.h"
#include "spidarcad/fem/free_dof_solver.h"
#include "spidarcad/fem/grab.h"
#include "spidarcad/fem/material.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/fem/static_solver.h"
#include "spidarcad/fem/stiffness.h"
#include "spidarcad/fem/substructure.h"
#include "spidarcad/modeling/feature_sharpening.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/mesh_repair.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tetgen_mesher.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::app {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

struct FemOptions {
  std::string input;
  std::string out;
  double youngs_modulus = 200e9;
  double poisson_ratio = 0.3;
  std::vector<std::string> fix;
  std::vector<std::string> push, disp;
  std::vector<std::string> load, force;
  std::string grab, move, rotate;  // --grab BOX, --move DX,DY,DZ, --rotate RX,RY,RZ
  int order = 0;                   // 0: keep the input's order
  bool incompressible = false;
  double resolution = 0.004;
  double max_radius_edge = 2.0;
  std::string solid;
  std::string object;    // --object: any object of a document (solid, mesh, sculpt, fe_model)
  int slabs = 0;         // --slabs: 0 one piece (not given: 4 with --cache-dir, else 0)
  std::string mesher;    // --mesher: a scene solid's surface, "lattice" or "tetrahedra" ("")
  bool lattice = false;  // --mesher lattice (checked and set before RunFem)
  // --flat-cells: SurfaceMeshSettings::flat_coarsen_cells; not given: kQuadraticFlatCells for
  // quadratic elements on a scene solid's marching-tetrahedra surface (as FE mode), else 0.
  double flat_cells = 0.0;
  bool flat_cells_given = false;
  std::string cache_dir;      // --cache-dir: slab meshes and block factors kept between runs
  double cache_max_gb = 4.0;  // --cache-max-gb: the directory's bound (least recently used out)
  // Which options were given (a document's FE model supplies the others).
  bool given_e = false, given_nu = false;
};

// Parses "a,b,c,..." into exactly n finite numbers; errors name the option, its occurrence and
// the text.
std::vector<double> ParseList(const std::string& text, int n, const std::string& option,
                              int occurrence) {
  std::vector<double> values;
  std::stringstream fields(text);
  std::string field;
  // occurrence < 0: an option given at most once, named without a number.
  const std::string where =
      option + (occurrence >= 0 ? " #" + std::to_string(occurrence + 1) : "") + " '" + text + "': ";
  while (std::getline(fields, field, ',')) {
    size_t used = 0;
    double value = 0.0;
    try {
      value = std::stod(field, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    while (used < field.size() && std::isspace(static_cast<unsigned char>(field[used]))) ++used;
    if (field.empty() || used != field.size() || !std::isfinite(value)) {
      throw InputError(where + "'" + field + "' is not a finite number");
    }
    values.push_back(value);
  }
  if (!text.empty() && text.back() == ',') {
    throw InputError(where + "trailing comma");
  }
  if (static_cast<int>(values.size()) != n) {
    throw InputError(where + "expected " + std::to_string(n) + " comma-separated numbers, got " +
                     std::to_string(values.size()));
  }
  return values;
}

Eigen::Vector3d ParseVector(const std::string& text, const std::string& option, int occurrence) {
  const std::vector<double> v = ParseList(text, 3, option, occurrence);
  return Eigen::Vector3d(v[0], v[1], v[2]);
}

bool EndsWith(const std::string& text, const std::string& suffix) {
  if (text.size() < suffix.size()) return false;
  std::string tail = text.substr(text.size() - suffix.size());
  for (char& c : tail) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return tail == suffix;
}

// The tets' volume against the solid's (`solid`, m³: modeling::EstimateSolidVolume over the
// grid's bounds) under report["meshing"], and the warning on stderr past
// modeling::kSharpVolumeRetry: a wall about a cell thick can fall between the grid's planes, and
// its stiffness with it.
void CheckMeshVolume(const SceneSolidGrid& grid, double solid, const modeling::TetMesh& tets,
                     nlohmann::ordered_json* report) {
  const double volume = modeling::MeasureTetQuality(tets).total_volume;
  const double off = solid > 0.0 ? volume / solid - 1.0 : 0.0;
  (*report)["meshing"]["volume_m3"] = volume;
  (*report)["meshing"]["solid_volume_m3"] = solid;
  (*report)["meshing"]["volume_off"] = off;
  std::cerr << VolumeOffWarning(off, grid.cell,
                                "the part's stiffness is missing with it; a finer --resolution "
                                "keeps it");
}

// Meshes one solid of a scene in slabs (scene/slab_fe_mesh.h), with the slab of each element in
// *slab; slab meshes come from and go to the cache directory when one is given.
fem::TetMesh MeshSceneInSlabs(const FemOptions& options, const SceneSolidGrid& grid,
                              Eigen::VectorXi* slab, nlohmann::ordered_json* report) {
  const double cell = grid.cell;
  SlabFeMesh slabs;
  try {
    SlabMeshOptions slab_options;
    slab_options.max_radius_edge = options.max_radius_edge;
    slab_options.cache_directory = options.cache_dir;
    slab_options.lattice = options.lattice;
    slab_options.flat_coarsen_cells = options.flat_cells;
    slabs =
        MeshSolidInSlabs(grid.compiled, grid.bounds, cell,
                         SlabPlanes(grid.bounds, cell, options.slabs, slab_options), slab_options);
  } catch (const std::exception& e) {
    throw InputError(options.input + ": solid '" + grid.solid_name + "' at --resolution " +
                     FormatNumber(cell) + " m in " + std::to_string(options.slabs) +
                     " slabs cannot be meshed: " + e.what() +
                     " (try another --resolution or --slabs)");
  }
  nlohmann::ordered_json per_slab = nlohmann::ordered_json::array();
  Eigen::VectorXi tets_per_slab = Eigen::VectorXi::Zero(static_cast<int>(slabs.slab_tets.size()));
  for (int e = 0; e < slabs.slab.size(); ++e) ++tets_per_slab(slabs.slab(e));
  for (std::size_t k = 0; k < slabs.slab_tets.size(); ++k) {
    per_slab.push_back({{"slab", k},
                        {"tets", tets_per_slab(static_cast<int>(k))},
                        {"mesh", slabs.loaded[k] ? "cache" : "tetgen"}});
  }
  double min_dihedral = 180.0;  // the joined mesh's tets are the slabs' tets
  for (const modeling::TetMesh& tets : slabs.slab_tets)
    min_dihedral = std::min(min_dihedral, modeling::MeasureTetQuality(tets).min_dihedral_deg);
  (*report)["meshing"] = {{"solid", grid.solid_name},
                          {"resolution_m", cell},
                          {"surface_mesher", options.lattice ? "lattice" : "tetrahedra"},
                          {"slabs", static_cast<int>(slabs.slab_tets.size())},
                          {"planes_x_m", slabs.planes},
                          {"surface_seconds", slabs.surface_seconds},
                          {"cut_seconds", slabs.cut_seconds},
                          {"tetgen_seconds", slabs.tetgen_seconds},
                          {"join_seconds", slabs.join_seconds},
                          {"cache_read_seconds", slabs.cache_read_seconds},
                          {"cache_write_seconds", slabs.cache_write_seconds},
                          {"min_dihedral_deg", min_dihedral},
                          {"grid_placements", slabs.grid_placements},
                          {"grid_shift_cells", slabs.grid_shift_cells},
                          {"per_slab", per_slab}};
  if (!slabs.cache_notes.empty()) (*report)["meshing"]["cache_notes"] = slabs.cache_notes;
  if (options.flat_cells > 0.0) (*report)["meshing"]["flat_cells"] = options.flat_cells;
  CheckMeshVolume(grid, slabs.solid_volume, *slabs.volume, report);  // estimated over grid.bounds
  *slab = slabs.slab;
  return std::move(slabs.mesh);
}

// Meshes one solid of a scene: surface on a grid of `resolution`, then TetGen (in one piece, or
// in slabs when options.slabs > 0, filling *slab).
fem::TetMesh MeshScene(const FemOptions& options, const OpenedDocument& opened,
                       const std::string& name, const std::string& option, Eigen::VectorXi* slab,
                       nlohmann::ordered_json* report) {
  const SceneSolidGrid grid = PrepareDocumentSolid(opened, name, option, options.resolution);
  if (options.slabs > 0) return MeshSceneInSlabs(options, grid, slab, report);
  const double cell = grid.cell;
  modeling::SurfaceMeshSettings surface_settings;
  surface_settings.bounds = grid.bounds;
  surface_settings.cell_size = cell;
  surface_settings.flat_coarsen_cells = options.flat_cells;
  if (options.lattice) surface_settings.mesher = modeling::SurfaceMesher::kLattice;
  // On another grid placement where a wall about a cell thick falls between grid planes.
  modeling::SharpSurface placed =
      modeling::MeshSurfaceKeepingVolume(grid.compiled, surface_settings);
  const modeling::TriangleMesh surface = std::move(placed.mesh);
  const modeling::SurfaceMeshStats& surface_stats = placed.surface;
  modeling::TetMeshSettings tet_settings;
  tet_settings.max_radius_edge = options.max_radius_edge;
  modeling::TetMeshStats tet_stats;
  modeling::TetMesh tets;
  try {
    tets = modeling::TetrahedralizeSurface(surface, tet_settings, &tet_stats);
  } catch (const std::exception& e) {
    throw InputError(options.input + ": solid '" + grid.solid_name + "' at --resolution " +
                     FormatNumber(cell) + " m cannot be tetrahedralized: " + e.what() +
                     " (try another --resolution)");
  }
  (*report)["meshing"] = {{"solid", grid.solid_name},
                          {"resolution_m", cell},
                          {"surface_triangles", surface.triangles.cols()},
                          {"surface_seconds", placed.seconds},
                          {"tetgen_seconds", tet_stats.tetgen_seconds},
                          {"tetgen_switches", tet_stats.switches},
                          {"min_dihedral_deg", tet_stats.quality.min_dihedral_deg},
                          {"grid_placements", placed.placements},
                          {"grid_shift_cells", placed.grid_shift}};
  if (options.flat_cells > 0.0) {
    (*report)["meshing"]["flat_cells"] = options.flat_cells;
    (*report)["meshing"]["flat_collapses"] = surface_stats.flat_collapses;
  }
  CheckMeshVolume(grid, placed.solid_volume, tets, report);  // estimated over grid.bounds
  return ToFemMesh(tets);
}

// Whether path names a triangle mesh file (.stl, .obj, .ply, any case).
bool IsTriangleMeshFile(const std::string& path) {
  std::string lower = path;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return EndsWith(lower, ".stl") || EndsWith(lower, ".obj") || EndsWith(lower, ".ply");
}

// TetGen tets of a closed surface, with its figures under report["meshing"] (plus `extra`).
// `what` names the surface in an error ("the repaired surface", "object 'clay'"), `hint` says
// what to try.
fem::TetMesh TetrahedralizeForFem(const FemOptions& options, const modeling::TriangleMesh& surface,
                                  const std::string& what, const std::string& hint,
                                  nlohmann::ordered_json extra, nlohmann::ordered_json* report) {
  modeling::TetMeshSettings tet_settings;
  tet_settings.max_radius_edge = options.max_radius_edge;
  modeling::TetMeshStats tet_stats;
  modeling::TetMesh tets;
  try {
    tets = modeling::TetrahedralizeSurface(surface, tet_settings, &tet_stats);
  } catch (const std::exception& e) {
    throw InputError(options.input + ": " + what + " cannot be tetrahedralized: " + e.what() +
                     " (" + hint + ")");
  }
  extra["surface_triangles"] = surface.triangles.cols();
  extra["tetgen_seconds"] = tet_stats.tetgen_seconds;
  extra["tetgen_switches"] = tet_stats.switches;
  extra["min_dihedral_deg"] = tet_stats.quality.min_dihedral_deg;
  (*report)["meshing"] = std::move(extra);
  return ToFemMesh(tets);
}

// A closed triangle mesh file -> repaired surface (modeling::ImportSolidMesh) -> TetGen tets.
// The repair report goes into the JSON report; a mesh that cannot be repaired is an InputError
// naming the file, the defect and the first offending triangle.
fem::TetMesh MeshTriangleFile(const FemOptions& options, nlohmann::ordered_json* report) {
  modeling::MeshRepairReport repair;
  modeling::TriangleMesh surface;
  try {
    surface = modeling::ImportSolidMesh(options.input, {}, &repair);
  } catch (const modeling::MeshFileError& e) {
    throw InputError(e.what());
  } catch (const modeling::MeshDefectError& e) {
    throw InputError(std::string(e.what()) + " (the mesh cannot be tetrahedralized as it is)");
  }
  nlohmann::ordered_json extra = {{"input_triangles", repair.input_triangles},
                                  {"repair", repair.Lines()}};
  return TetrahedralizeForFem(options, surface, "the repaired surface", "try another --quality",
                              std::move(extra), report);
}

// Tetrahedralizes a closed surface of a document object (a mesh without a volume, a sculpt).
fem::TetMesh MeshSurfaceObject(const FemOptions& options, const std::string& name,
                               const modeling::TriangleMesh& surface,
                               nlohmann::ordered_json* report) {
  return TetrahedralizeForFem(options, surface, "object '" + name + "': its surface",
                              "it must be closed and free of self-intersections",
                              {{"object", name}}, report);
}

// The object `fem` solves in a document: the one named (any kind but a rigid part), else the
// first FE model, else the first solid, mesh or sculpt. A version 1 scene: its solids only, with
// the messages `fem` always gave.
const DocObject& PickFemObject(const OpenedDocument& opened, const std::string& name,
                               const std::string& option) {
  const Document& doc = *opened.doc;
  if (opened.version == 1) return PickSolid(opened, name, option);
  std::string all;
  for (const DocObject& o : doc.objects())
    all += (all.empty() ? "" : ", ") + std::string(ObjectKindName(o.data)) + " '" + o.name + "'";
  if (all.empty()) all = "no object";
  if (!name.empty()) {
    const DocObject* o = doc.FindByName(name);
    if (o == nullptr) {
      throw InputError(option + " '" + name + "': no such object in " + opened.path + " (it has " +
                       all + ")");
    }
    if (std::holds_alternative<RigidPartData>(o->data)) {
      throw InputError(option + " '" + name + "': a rigid part; fem solves an fe_model, solid, " +
                       "mesh or sculpt object (" + opened.path + " has " + all + ")");
    }
    return *o;
  }
  for (const char* kind : {"fe_model", "solid", "mesh", "sculpt"})
    for (const DocObject& o : doc.objects())
      if (std::string(ObjectKindName(o.data)) == kind) return o;
  throw InputError(opened.path + ": nothing to solve: the document has " + all +
                   "; fem needs an fe_model, solid, mesh or sculpt object");
}

nlohmann::ordered_json JsonVector(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// "(x, y, z)" for a message.
std::string FormatPoint(const Eigen::Vector3d& p) {
  return "(" + FormatNumber(p.x()) + ", " + FormatNumber(p.y()) + ", " + FormatNumber(p.z()) + ")";
}

nlohmann::ordered_json JsonBox(const Eigen::AlignedBox3d& box) {
  return {{"min", JsonVector(box.min())}, {"max", JsonVector(box.max())}};
}

// Index (into mesh nodes) of the surface node nearest p.
int NearestNode(const fem::TetMesh& mesh, const std::vector<int>& candidates,
                const Eigen::Vector3d& p) {
  int best = -1;
  double best_d2 = std::numeric_limits<double>::infinity();
  for (int v : candidates) {
    const double d2 = (mesh.nodes.row(v).transpose() - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = v;
    }
  }
  return best;
}

// The JSON "substructure" object of a slab solve: blocks, interface and where each factor came
// from.
nlohmann::ordered_json SubstructureReport(const fem::SubstructuredSolver& solver) {
  const fem::SubstructureStats& stats = solver.stats();
  nlohmann::ordered_json blocks = nlohmann::ordered_json::array();
  for (int b = 0; b < solver.num_blocks(); ++b) {
    const fem::BlockStats& s = solver.block_stats(b);
    blocks.push_back(
        {{"block", b},
         {"elements", s.num_elements},
         {"interior_dofs", s.num_interior_dofs},
         {"interface_dofs", s.num_interface_dofs},
         {"factor_nonzeros", s.factor_nonzeros},
         {"factor", s.loaded ? "cache" : "computed"},
         {"seconds",
          s.loaded ? s.load_seconds : s.assembly_seconds + s.factor_seconds + s.schur_seconds}});
  }
  nlohmann::ordered_json out = {{"blocks", blocks},
                                {"interface_dofs", stats.num_interface_dofs},
                                {"interface_planes", stats.interface_groups},
                                {"interface_seconds", stats.interface_seconds},
                                {"cache_read_seconds", stats.cache_read_seconds},
                                {"cache_write_seconds", stats.cache_write_seconds}};
  if (!stats.cache_notes.empty()) out["cache_notes"] = stats.cache_notes;
  return out;
}

// The JSON "cache" object: what this run took from --cache-dir and what it computed (and left
// there for the next run).
nlohmann::ordered_json CacheReport(const std::string& directory,
                                   const nlohmann::ordered_json& meshing,
                                   const fem::SubstructuredSolver& solver) {
  nlohmann::ordered_json reused = nlohmann::ordered_json::array();
  nlohmann::ordered_json recomputed = nlohmann::ordered_json::array();
  if (meshing.contains("per_slab")) {
    recomputed.push_back("surface");
    for (const auto& slab : meshing["per_slab"]) {
      const std::string what = "slab " + std::to_string(slab["slab"].get<int>()) + " mesh";
      (slab["mesh"] == "cache" ? reused : recomputed).push_back(what);
    }
  }
  for (int b = 0; b < solver.num_blocks(); ++b) {
    const std::string what = "block " + std::to_string(b) + " factor";
    (solver.block_stats(b).loaded ? reused : recomputed).push_back(what);
  }
  const fem::SubstructureStats& stats = solver.stats();
  for (std::size_t g = 0; g < stats.interface_group_loaded.size(); ++g) {
    const std::string what = "interface plane " + std::to_string(g) + " factor";
    (stats.interface_group_loaded[g] ? reused : recomputed).push_back(what);
  }
  // An interface that is no chain of planes is factored by CHOLMOD, whole, every time.
  if (stats.interface_groups == 0 && stats.num_interface_dofs > 0)
    recomputed.push_back("interface factor");
  nlohmann::ordered_json notes = nlohmann::ordered_json::array();
  if (meshing.contains("cache_notes"))
    for (const auto& n : meshing["cache_notes"]) notes.push_back(n);
  for (const std::string& n : stats.cache_notes) notes.push_back(n);
  return {
      {"directory", directory}, {"reused", reused}, {"recomputed", recomputed}, {"notes", notes}};
}

void RunFem(const FemOptions& options) {
  const Clock::time_point start = Clock::now();
  // Cache files this run reads or writes are stamped from now on, and are never pruned by it.
  // (File times come from the kernel's coarse clock, up to a tick of 1-10 ms behind: hence the
  // margin.)
  const auto cache_protect_since =
      std::filesystem::file_time_type::clock::now() - std::chrono::milliseconds(100);
  // Ctrl+C ends at once with status 130 (TetGen and CHOLMOD poll nothing); the result goes to a
  // hidden temporary renamed over --out when complete, so no half-written file is left.
  InterruptibleOutput output(options.out, "fem", InterruptibleOutput::Mode::kExitAtOnce);
  nlohmann::ordered_json report;
  report["input"] = options.input;

  // Options that do not need the mesh first.
  fem::Material material;
  material.youngs_modulus = options.youngs_modulus;
  material.poisson_ratio = options.poisson_ratio;
  if (options.incompressible) {
    if (options.order == 1) {
      throw InputError(
          "--incompressible needs quadratic (10-node) elements: linear tetrahedra lock whatever "
          "their volumetric integration; drop --order 1 (a linear mesh is then upgraded) or use "
          "--order 2");
    }
    material.formulation = fem::Formulation::kMeanDilatation;
  }
  try {
    material.Validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--E/--nu: ") + e.what());
  }
  if (options.push.size() != options.disp.size()) {
    throw InputError("--push and --disp come in pairs: got " + std::to_string(options.push.size()) +
                     " --push and " + std::to_string(options.disp.size()) + " --disp");
  }
  if (options.load.size() != options.force.size()) {
    throw InputError("--load and --force come in pairs: got " +
                     std::to_string(options.load.size()) + " --load and " +
                     std::to_string(options.force.size()) + " --force");
  }
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> fix_boxes;
  for (size_t i = 0; i < options.fix.size(); ++i) {
    const std::vector<double> b = ParseList(options.fix[i], 6, "--fix", static_cast<int>(i));
    const Eigen::Vector3d lower(b[0], b[1], b[2]), upper(b[3], b[4], b[5]);
    if ((lower.array() > upper.array()).any()) {
      throw InputError("--fix #" + std::to_string(i + 1) + " '" + options.fix[i] +
                       "': XMIN,YMIN,ZMIN must not exceed XMAX,YMAX,ZMAX");
    }
    fix_boxes.emplace_back(lower, upper);
  }
  if (options.grab.empty() && (!options.move.empty() || !options.rotate.empty())) {
    throw InputError(std::string(options.move.empty() ? "--rotate" : "--move") +
                     " moves the grabbed nodes: give --grab XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX too");
  }
  Eigen::Vector3d grab_lower = Eigen::Vector3d::Zero(), grab_upper = Eigen::Vector3d::Zero();
  Eigen::Vector3d grab_move = Eigen::Vector3d::Zero(), grab_rotate = Eigen::Vector3d::Zero();
  if (!options.grab.empty()) {
    const std::vector<double> b = ParseList(options.grab, 6, "--grab", -1);
    grab_lower = Eigen::Vector3d(b[0], b[1], b[2]);
    grab_upper = Eigen::Vector3d(b[3], b[4], b[5]);
    if ((grab_lower.array() > grab_upper.array()).any()) {
      throw InputError("--grab '" + options.grab +
                       "': XMIN,YMIN,ZMIN must not exceed XMAX,YMAX,ZMAX");
    }
    if (!options.move.empty()) grab_move = ParseVector(options.move, "--move", -1);
    if (!options.rotate.empty()) grab_rotate = ParseVector(options.rotate, "--rotate", -1);
  }
  std::vector<Eigen::Vector3d> push_points, push_disps, load_points, load_forces;
  for (size_t i = 0; i < options.push.size(); ++i) {
    push_points.push_back(ParseVector(options.push[i], "--push", static_cast<int>(i)));
    push_disps.push_back(ParseVector(options.disp[i], "--disp", static_cast<int>(i)));
  }
  for (size_t i = 0; i < options.load.size(); ++i) {
    load_points.push_back(ParseVector(options.load[i], "--load", static_cast<int>(i)));
    load_forces.push_back(ParseVector(options.force[i], "--force", static_cast<int>(i)));
  }
  if (options.slabs < 0 || options.slabs > 64) {
    throw InputError("--slabs " + std::to_string(options.slabs) +
                     ": the number of slabs must be 1 to 64 (0: solve in one piece)");
  }
  if (!(options.cache_max_gb >= 0.0) || !std::isfinite(options.cache_max_gb)) {
    throw InputError("--cache-max-gb: must be a size >= 0 in GiB, got " +
                     FormatNumber(options.cache_max_gb));
  }
  if (!options.cache_dir.empty() && options.slabs == 0) {
    throw InputError(
        "--cache-dir keeps slab meshes and slab factors between runs: it needs "
        "--slabs N (N >= 1; without --slabs it is 4), not --slabs 0");
  }
  // --mesher and --flat-cells shape the surface of a scene solid, and nothing else.
  const bool surface_option_given =
      !options.mesher.empty() || (options.flat_cells_given && options.flat_cells > 0.0);
  const std::string surface_option = !options.mesher.empty() ? "--mesher" : "--flat-cells";
  if (surface_option_given && EndsWith(options.input, ".vtu"))
    throw InputError(surface_option + " shapes the surface of a scene solid; " + options.input +
                     " holds tetrahedra already: drop " + surface_option);
  if (!(options.resolution > 0.0) || !std::isfinite(options.resolution)) {
    throw InputError("--resolution: must be a finite length > 0 m, got " +
                     FormatNumber(options.resolution));
  }

  // The mesh.
  Clock::time_point t = Clock::now();
  fem::TetMesh mesh;
  Eigen::VectorXi element_slab;  // slab of each element (meshed in slabs; else filled below)
  OpenedDocument opened;
  const FeModelData* fe = nullptr;  // a document's FE model, when that is what is solved
  std::string fe_name;              // its name
  if (!options.solid.empty() && !options.object.empty())
    throw InputError("--solid and --object name the same thing: give one");
  const std::string option = options.object.empty() ? "--solid" : "--object";
  const std::string name = options.object.empty() ? options.solid : options.object;
  if (EndsWith(options.input, ".vtu")) {
    VtuReadInfo info;
    mesh = ReadTetVtu(options.input, &info);
    if (info.flipped_elements > 0) report["flipped_elements"] = info.flipped_elements;
  } else if (EndsWith(options.input, ".json")) {
    opened = OpenDocumentFile(options.input);
    const DocObject& object = PickFemObject(opened, name, option);
    if (opened.version == 2)
      report["object"] = {{"name", object.name}, {"kind", ObjectKindName(object.data)}};
    if (std::holds_alternative<SolidData>(object.data)) {
      mesh = MeshScene(options, opened, object.name, option, &element_slab, &report);
    } else if (surface_option_given) {
      throw InputError(surface_option + " shapes the surface of a solid; " + object.name + " in " +
                       options.input + " is " + ObjectKindName(object.data) + ": drop " +
                       surface_option);
    } else if (const auto* f = std::get_if<FeModelData>(&object.data)) {
      fe = f;
      fe_name = object.name;
      mesh = FeMeshOf(*opened.doc, *f);
    } else if (const auto* m = std::get_if<MeshData>(&object.data)) {
      if (m->volume) {
        mesh = ToFemMesh(*m->volume);
      } else {
        mesh = MeshSurfaceObject(options, object.name, *m->surface, &report);
      }
    } else {
      mesh =
          MeshSurfaceObject(options, object.name, *std::get<SculptData>(object.data).mesh, &report);
    }
  } else if (surface_option_given) {
    throw InputError(surface_option + " shapes the surface of a scene solid; " + options.input +
                     " is a mesh file: drop " + surface_option);
  } else if (IsTriangleMeshFile(options.input)) {
    mesh = MeshTriangleFile(options, &report);
  } else {
    throw InputError(options.input +
                     ": unknown input kind (expected a .vtu mesh, a closed .stl/.obj/.ply "
                     "surface or a .json scene)");
  }
  // A document's FE model: its material, region materials, clamps, loads and order, unless an
  // option says otherwise (listed under "overridden").
  std::vector<RegionMaterial> region_materials;
  nlohmann::ordered_json fe_report;
  nlohmann::ordered_json from_document = nlohmann::ordered_json::array();
  nlohmann::ordered_json overridden = nlohmann::ordered_json::array();
  int order = options.order;
  if (fe != nullptr) {
    const std::string where = options.input + ": fe_model '" + fe_name + "': ";
    if (options.given_e || options.given_nu) {
      if (!options.given_e) material.youngs_modulus = fe->material.youngs_modulus;
      if (!options.given_nu) material.poisson_ratio = fe->material.poisson_ratio;
      overridden.push_back("material (--E/--nu; region materials not used)");
    } else {
      material.youngs_modulus = fe->material.youngs_modulus;
      material.poisson_ratio = fe->material.poisson_ratio;
      region_materials = fe->region_materials;
      from_document.push_back("material");
      if (!region_materials.empty()) from_document.push_back("region_materials");
    }
    for (RegionMaterial& r : region_materials) r.material.formulation = material.formulation;
    try {
      material.Validate();
      for (const RegionMaterial& r : region_materials) r.material.Validate();
    } catch (const std::invalid_argument& e) {
      throw InputError(where + "material: " + e.what());
    }
    if (options.order != 0) {
      overridden.push_back("element_order (--order)");
    } else if (options.incompressible && fe->element_order == 1) {
      overridden.push_back("element_order (--incompressible needs quadratic elements)");
    } else {
      order = fe->element_order;
      from_document.push_back("element_order");
    }
    if (options.fix.empty()) {
      for (std::size_t i = 0; i < fe->fixed_boxes.size(); ++i) {
        fix_boxes.emplace_back(fe->fixed_boxes[i].min(), fe->fixed_boxes[i].max());
      }
      from_document.push_back("fixed_boxes");
    } else {
      overridden.push_back("fixed_boxes (--fix)");
    }
    if (options.load.empty()) {
      from_document.push_back("loads");
    } else {
      overridden.push_back("loads (--load/--force)");
    }
  }
  const int input_order = mesh.Order();
  const int input_nodes = mesh.num_nodes();
  if ((order == 2 || options.incompressible) && input_order == 1) {
    mesh = fem::MakeQuadratic(mesh);
  } else if (order == 1 && input_order == 2) {
    throw InputError("--order 1: the mesh " + options.input +
                     " has quadratic (10-node) tetrahedra; use --order 2 or a linear mesh");
  }
  const double mesh_seconds = SecondsSince(t);

  const fem::Surface surface = fem::ExtractSurface(mesh);
  fem::BoundaryConditions bcs(mesh.num_nodes());
  std::vector<char> clamped(mesh.num_nodes(), 0);
  int num_fixed = 0;
  for (size_t i = 0; i < fix_boxes.size(); ++i) {
    const std::vector<int> nodes = fem::NodesInBox(mesh, fix_boxes[i].first, fix_boxes[i].second);
    if (nodes.empty() && i >= options.fix.size()) {
      throw InputError(options.input + ": fe_model '" + fe_name + "': fixed box " +
                       std::to_string(i) +
                       " contains no node of the mesh; correct it in the document or give --fix");
    }
    if (nodes.empty()) {
      throw InputError("--fix #" + std::to_string(i + 1) + " '" + options.fix[i] +
                       "': the box contains no node of the mesh");
    }
    for (int v : nodes) {
      if (!clamped[v]) ++num_fixed;
      clamped[v] = 1;
    }
    bcs.FixNodes(nodes);
  }
  if (num_fixed == mesh.num_nodes()) {
    throw InputError("--fix: the box(es) clamp all " + std::to_string(num_fixed) +
                     " nodes of the mesh, so nothing is left to solve; make the --fix box cover "
                     "only the supported part (e.g. the nodes at one end)");
  }
  // The grabbed nodes: every node in the --grab box, none of them clamped.
  std::vector<char> grabbed(mesh.num_nodes(), 0);
  std::unique_ptr<fem::GrabPatch> grab;
  if (!options.grab.empty()) {
    const std::string where = "--grab '" + options.grab + "': ";
    const std::vector<int> nodes = fem::NodesInBox(mesh, grab_lower, grab_upper);
    if (nodes.empty()) {
      throw InputError(where + "the box contains no node of the mesh (the mesh spans " +
                       FormatPoint(mesh.nodes.colwise().minCoeff().transpose()) + " to " +
                       FormatPoint(mesh.nodes.colwise().maxCoeff().transpose()) + ")");
    }
    int overlap = 0, first = -1;
    for (int v : nodes) {
      if (!clamped[v]) continue;
      if (first < 0) first = v;
      ++overlap;
    }
    if (overlap > 0) {
      throw InputError(
          where + std::to_string(overlap) + " of its " + std::to_string(nodes.size()) +
          " nodes are also clamped (" +
          (options.fix.empty() && fe != nullptr ? "the fe_model's fixed boxes" : "--fix") +
          "), e.g. node " + std::to_string(first) + " at " +
          FormatPoint(mesh.nodes.row(first).transpose()) +
          "; a node cannot be both clamped and grabbed: make the boxes disjoint");
    }
    for (int v : nodes) grabbed[v] = 1;
    grab = std::make_unique<fem::GrabPatch>(mesh.nodes, nodes);
  }
  std::vector<char> used(mesh.num_nodes(), 0);
  std::vector<int> push_nodes, load_nodes;
  for (size_t i = 0; i < push_points.size(); ++i) {
    const int v = NearestNode(mesh, surface.nodes, push_points[i]);
    const std::string where = "--push #" + std::to_string(i + 1) + " '" + options.push[i] + "': ";
    if (clamped[v]) {
      throw InputError(where + "the nearest surface node " + std::to_string(v) +
                       " is clamped by a --fix box");
    }
    if (used[v]) {
      throw InputError(where + "the nearest surface node " + std::to_string(v) +
                       " is already pushed by an earlier --push");
    }
    if (grabbed[v]) {
      throw InputError(where + "the nearest surface node " + std::to_string(v) +
                       " is grabbed by --grab");
    }
    used[v] = 1;
    bcs.PrescribeNode(v, push_disps[i]);
    push_nodes.push_back(v);
  }
  for (size_t i = 0; i < load_points.size(); ++i) {
    const int v = NearestNode(mesh, surface.nodes, load_points[i]);
    if (clamped[v] || used[v] || grabbed[v]) {
      throw InputError("--load #" + std::to_string(i + 1) + " '" + options.load[i] +
                       "': the nearest surface node " + std::to_string(v) +
                       " has a prescribed displacement (--fix, --push or --grab), a force there "
                       "does nothing");
    }
    bcs.AddPointLoad(v, load_forces[i]);
    load_nodes.push_back(v);
  }
  std::vector<std::vector<int>> box_load_nodes;
  if (fe != nullptr && options.load.empty()) {
    try {
      box_load_nodes = AddBoxLoads(mesh, fe->loads, &bcs);
    } catch (const std::invalid_argument& e) {
      throw InputError(options.input + ": fe_model '" + fe_name + "': " + e.what());
    }
  }

  if (grab) {
    try {
      grab->Prescribe(grab_move, grab_rotate, &bcs);
    } catch (const std::invalid_argument& e) {
      throw InputError("--grab '" + options.grab + "': " + e.what() +
                       " (check --move and --rotate)");
    }
  }

  // Solve.
  fem::MaterialTable materials(material);
  try {
    materials = MakeMaterialTable(material, region_materials);
  } catch (const std::invalid_argument& e) {
    throw InputError(options.input + ": fe_model '" + fe_name + "': " + e.what());
  }
  // One sparse Cholesky factor of the whole model, or one per slab and the interface system
  // (--slabs; blocks from and to --cache-dir).
  std::unique_ptr<fem::StaticSolver> static_solver;
  std::unique_ptr<fem::StaticSolverView> static_view;
  std::unique_ptr<fem::SubstructuredSolver> slab_solver;
  const fem::FreeDofSolver* solver = nullptr;
  try {
    if (options.slabs > 0) {
      if (element_slab.size() != mesh.num_elements())
        element_slab = fem::SlabBlocks(mesh, 0, fem::EvenPlanes(mesh, 0, options.slabs));
      slab_solver = std::make_unique<fem::SubstructuredSolver>(mesh, materials, bcs, element_slab,
                                                               nullptr, options.cache_dir);
      solver = slab_solver.get();
    } else {
      static_solver = std::make_unique<fem::StaticSolver>(mesh, materials, bcs);
      static_view = std::make_unique<fem::StaticSolverView>(*static_solver);
      solver = static_view.get();
    }
  } catch (const std::invalid_argument& e) {
    throw InputError(options.input + ": " + e.what());
  }
  if (!solver->factor_status().converged) {
    throw InputError(options.input +
                     ": the stiffness could not be factored: " + solver->factor_status().message);
  }
  t = Clock::now();
  const fem::StaticSolution solution = solver->Solve();
  const double solve_seconds = SecondsSince(t);
  t = Clock::now();
  const Eigen::VectorXd element_vm = fem::ElementVonMises(mesh, materials, solution.displacement);
  const Eigen::VectorXd node_vm = fem::AverageToNodes(mesh, element_vm);
  const double stress_seconds = SecondsSince(t);

  // A result that overflowed is refused before anything is written: name the largest input.
  if (!solution.displacement.allFinite() || !solution.reaction.allFinite() ||
      !element_vm.allFinite() || !std::isfinite(solution.status.residual)) {
    // The largest prescribed displacement, the largest force and the grab's motion.
    std::vector<std::string> culprits;
    double largest = -1.0;
    std::string disp_culprit;
    for (size_t i = 0; i < push_disps.size(); ++i) {
      if (push_disps[i].norm() > largest) {
        largest = push_disps[i].norm();
        disp_culprit = "--disp #" + std::to_string(i + 1) + " '" + options.disp[i] + "'";
      }
    }
    if (!disp_culprit.empty()) culprits.push_back(disp_culprit);
    double largest_force = -1.0;
    std::string force_culprit;
    for (size_t i = 0; i < load_forces.size(); ++i) {
      if (load_forces[i].norm() > largest_force) {
        largest_force = load_forces[i].norm();
        force_culprit = "--force #" + std::to_string(i + 1) + " '" + options.force[i] + "'";
      }
    }
    if (!force_culprit.empty()) culprits.push_back(force_culprit);
    if (grab && !options.move.empty()) culprits.push_back("--move '" + options.move + "'");
    if (grab && !options.rotate.empty()) culprits.push_back("--rotate '" + options.rotate + "'");
    std::string culprit;
    for (const std::string& c : culprits) culprit += (culprit.empty() ? "" : " or ") + c;
    if (culprit.empty()) culprit = "--E/--nu";
    throw InputError(options.input +
                     ": the solution is not finite (it overflows double "
                     "precision): an input is out of range: " +
                     culprit +
                     "; use displacements of the order of the model size and forces and moduli "
                     "of physical magnitude");
  }

  t = Clock::now();
  modeling::VtuArrays point_data, cell_data;
  // k by N arrays: the displacement vector (3·#V, node-major) is already 3 by #V column-major.
  point_data["displacement"] =
      Eigen::Map<const Eigen::Matrix3Xd>(solution.displacement.data(), 3, mesh.num_nodes());
  point_data["von_mises"] = node_vm.transpose();
  cell_data["von_mises"] = element_vm.transpose();
  try {
    WriteTetVtu(mesh, output.temporary(), point_data, cell_data);
  } catch (const std::exception& e) {
    std::string what = e.what();
    for (std::size_t at; (at = what.find(output.temporary())) != std::string::npos;)
      what.replace(at, output.temporary().size(), options.out);
    throw InputError("--out: " + what);
  }
  output.Commit();
  const double write_seconds = SecondsSince(t);

  // Report.
  report["output"] = options.out;
  report["material"] = {{"youngs_modulus_pa", material.youngs_modulus},
                        {"poisson_ratio", material.poisson_ratio}};
  report["formulation"] = options.incompressible ? "mean_dilatation" : "displacement";
  report["order"] = mesh.Order();
  report["nodes"] = mesh.num_nodes();
  report["input_nodes"] = input_nodes;
  report["elements"] = mesh.num_elements();
  report["surface_nodes"] = surface.nodes.size();
  report["fixed_nodes"] = num_fixed;
  report["unknowns"] = solver->num_free();
  nlohmann::ordered_json pushes = nlohmann::ordered_json::array();
  for (size_t i = 0; i < push_nodes.size(); ++i) {
    const int v = push_nodes[i];
    pushes.push_back({{"node", v},
                      {"position", JsonVector(mesh.nodes.row(v).transpose())},
                      {"displacement", JsonVector(push_disps[i])},
                      {"reaction_force", JsonVector(solution.reaction.segment<3>(3 * v))}});
  }
  report["pushes"] = pushes;
  nlohmann::ordered_json loads = nlohmann::ordered_json::array();
  for (size_t i = 0; i < load_nodes.size(); ++i) {
    const int v = load_nodes[i];
    loads.push_back({{"node", v},
                     {"position", JsonVector(mesh.nodes.row(v).transpose())},
                     {"force", JsonVector(load_forces[i])},
                     {"displacement", JsonVector(solution.displacement.segment<3>(3 * v))}});
  }
  report["loads"] = loads;
  if (grab) {
    // The wrench applied ON the part at the grabbed nodes to hold them there: force (N) and
    // moment about the centroid of their rest positions (N·m).
    const fem::GrabWrench wrench = grab->WrenchOfReaction(solution.reaction);
    report["grab"] = {{"nodes", grab->size()},
                      {"centroid", JsonVector(grab->centroid())},
                      {"force", JsonVector(wrench.force)},
                      {"moment", JsonVector(wrench.moment)}};
  }
  if (fe != nullptr) {
    nlohmann::ordered_json box_loads = nlohmann::ordered_json::array();
    for (std::size_t i = 0; i < box_load_nodes.size(); ++i) {
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (int v : box_load_nodes[i]) mean += solution.displacement.segment<3>(3 * v);
      mean /= static_cast<double>(box_load_nodes[i].size());
      nlohmann::ordered_json entry = JsonBox(fe->loads[i].box);
      entry["force"] = JsonVector(fe->loads[i].force);
      entry["nodes"] = box_load_nodes[i].size();
      entry["mean_displacement"] = JsonVector(mean);
      box_loads.push_back(entry);
    }
    report["box_loads"] = box_loads;
    nlohmann::ordered_json regions = nlohmann::ordered_json::array();
    for (const RegionMaterial& r : region_materials) {
      regions.push_back({{"region", r.region},
                         {"youngs_modulus_pa", r.material.youngs_modulus},
                         {"poisson_ratio", r.material.poisson_ratio}});
    }
    const DocObject* tet_mesh = opened.doc->Find(fe->tet_mesh);
    fe_report["name"] = fe_name;
    fe_report["tet_mesh"] = tet_mesh != nullptr ? tet_mesh->name : std::string();
    fe_report["region_materials"] = regions;
    fe_report["from_document"] = from_document;
    fe_report["overridden"] = overridden;
    report["fe_model"] = fe_report;
  }
  Eigen::Vector3d support = Eigen::Vector3d::Zero();
  for (int v = 0; v < mesh.num_nodes(); ++v) {
    if (clamped[v]) support += solution.reaction.segment<3>(3 * v);
  }
  report["fixed_reaction_force"] = JsonVector(support);
  double max_disp = 0.0;
  for (int v = 0; v < mesh.num_nodes(); ++v) {
    max_disp = std::max(max_disp, solution.displacement.segment<3>(3 * v).norm());
  }
  report["max_displacement_m"] = max_disp;
  report["max_von_mises_pa"] = element_vm.size() ? element_vm.maxCoeff() : 0.0;
  // residual is the normwise backward error ||K u - f|| / (||K|| ||u|| + ||f||) of the free
  // dofs (kept under its old name); backward_error says the same under its proper name.
  report["status"] = {{"converged", solution.status.converged},
                      {"residual", solution.status.residual},
                      {"backward_error", solution.status.residual},
                      {"message", solution.status.message}};
  double assembly_seconds = 0.0, factor_seconds = 0.0;
  if (static_solver) {
    const fem::FactorStats& stats = static_solver->stats();
    assembly_seconds = stats.assembly_seconds;
    factor_seconds = stats.factor_seconds;
    report["factor_peak_bytes"] = stats.factor_peak_bytes;
  } else {
    // factor: everything but the blocks' assembly (their factors, S_b, reading the cache, S);
    // the block files are written in the background, waited for here.
    const Clock::time_point t_wait = Clock::now();
    const fem::SubstructureStats& stats = slab_solver->FinishCacheWrites();
    const double wait_seconds = SecondsSince(t_wait);
    assembly_seconds = stats.block_assembly_seconds;
    factor_seconds = stats.wall_seconds - stats.block_assembly_seconds;
    report["substructure"] = SubstructureReport(*slab_solver);
    report["substructure"]["cache_write_wait_seconds"] = wait_seconds;
    if (!options.cache_dir.empty()) {
      report["cache"] = CacheReport(options.cache_dir, report["meshing"], *slab_solver);
      const fem::PruneStats pruned = fem::PruneCacheDirectory(
          options.cache_dir,
          static_cast<std::uintmax_t>(options.cache_max_gb * 1024.0 * 1024.0 * 1024.0),
          {".block", ".plane", ".slab"}, cache_protect_since);
      report["cache"]["size_bytes"] = pruned.kept_bytes;
      report["cache"]["pruned_files"] = pruned.removed_files;
      report["cache"]["pruned_bytes"] = pruned.removed_bytes;
    }
  }
  report["timing_s"] = {{"mesh", mesh_seconds},        {"assembly", assembly_seconds},
                        {"factor", factor_seconds},    {"solve", solve_seconds},
                        {"stress", stress_seconds},    {"write", write_seconds},
                        {"total", SecondsSince(start)}};
  std::cout << report.dump(2) << "\n";
  std::cout.flush();
  if (!solution.status.converged) {
    std::cerr << "spidarcad: error: the solve did not converge (residual "
              << solution.status.residual << "): " << solution.status.message << "\n";
    throw CommandExit{1};
  }
}

}  // namespace

void RegisterFemCommand(CLI::App& app) {
  auto options = std::make_shared<FemOptions>();
  CLI::App* cmd = app.add_subcommand(
      "fem", "Static linear-elastic FE solve of a tetrahedral mesh or a scene solid (VTU out)");
  cmd->footer(
      "Input: a .vtu with VTK_TETRA or VTK_QUADRATIC_TETRA cells, or a .json scene whose solid\n"
      "(the first, or --solid NAME) is meshed first (surface grid of --resolution, then TetGen;\n"
      "a surface over 5 % off the solid's volume, a wall about a cell thick fallen between grid\n"
      "planes, is meshed again on the grid moved by a fraction of a cell: meshing.grid_*),\n"
      "or a .json document (version 2) and its object --object NAME (default: the first\n"
      "fe_model, else the first solid, mesh or sculpt). An fe_model brings its tet mesh,\n"
      "material, region materials, fixed boxes, loads (each box's force spread evenly over its\n"
      "nodes) and element order; --E/--nu, --fix, --load/--force and --order replace the\n"
      "document's value, and the JSON lists which under fe_model.overridden. A mesh object is\n"
      "used as it is (its tets) or tetrahedralized (a surface), as is a sculpt's surface;\n"
      "or a closed triangle surface (.stl, .obj, .ply), repaired where that is safe (vertices\n"
      "welded, zero-area, repeated and back-to-back triangles dropped, orientation fixed; the\n"
      "JSON's meshing.repair lists the changes) or refused naming the defect and the first\n"
      "offending triangle (open, non-manifold, self-intersecting), then meshed by TetGen.\n"
      "Nodes inside a --fix box are clamped; --push prescribes the displacement (all three\n"
      "components) of the surface node nearest the point; --load applies a point force at the\n"
      "surface node nearest the point. Material defaults to steel (E = 200 GPa, nu = 0.3).\n"
      "Writes OUT.vtu (point data displacement [m], von_mises [Pa, volume-weighted average of\n"
      "the elements]; cell data von_mises [Pa, at the element centroid], region) and prints JSON:\n"
      "for each pushed node its index, position and reaction_force (N, the force the push\n"
      "applies ON the body), for each load its node and force, counts, status (converged,\n"
      "backward_error ||K u - f|| / (||K|| ||u|| + ||f||)) and timings.\n"
      "--grab BOX holds every node inside the box (as --fix: XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX) and\n"
      "moves it rigidly: u = (R - I)(x - c) + t, with t = --move DX,DY,DZ [m], R = exp([r]x) for\n"
      "the rotation vector r = --rotate RX,RY,RZ [rad] and c the centroid of the grabbed nodes'\n"
      "rest positions. The JSON's grab object gives nodes, centroid and the wrench applied ON\n"
      "the part to hold them there (sum over the grabbed nodes): force [N] and moment about c\n"
      "[N m]. A grab box that holds no node, or one of whose nodes is clamped, is an error.\n"
      "--incompressible (for nu near 0.5, e.g. rubber or soft tissue): quadratic elements with\n"
      "the volumetric term on the element-mean dilatation (P2-P0, locking-free); a linear mesh\n"
      "is upgraded to 10-node elements, and --order 1 with it is an error.\n"
      "--slabs N solves in N slabs across x: each slab's stiffness is factored on its own and\n"
      "condensed onto the planes between slabs (on a given mesh, the one-piece answer to\n"
      "rounding); a scene solid is then meshed slab by slab, conforming across the planes\n"
      "(moved with the grid when the grid moves). --cache-dir DIR (implies\n"
      "--slabs 4) keeps every slab's mesh and factor, and the factor of every plane between\n"
      "slabs, in DIR; a later run reads those whose input is unchanged, so after a local edit\n"
      "(a hole moved) only the slabs the edit reached, and the planes from the first of them\n"
      "on, are meshed and factored again. The JSON's cache.reused and cache.recomputed list what "
      "was\n"
      "read and what was computed; substructure.blocks gives each slab's figures and timings.\n"
      "A damaged or stale file is never trusted: it is recomputed, and cache.notes says why.\n"
      "After the run the directory is cut back to --cache-max-gb (default 4 GiB), least\n"
      "recently used files first; the files this run used stay.\n"
      "\n"
      "Example (a 1 x 0.1 x 0.1 m steel beam clamped at x = 0, tip pushed 1 mm down):\n"
      "  spidarcad fem beam.vtu --fix=-1,-1,-1,1e-9,1,1 --push 1,0.05,0.05 --disp 0,0,-0.001 \\\n"
      "    --order 2 --out result.vtu\n"
      "(write a value that starts with '-' as --fix=-1,...: otherwise it reads as an option)\n"
      "Example (the platform, quadratic, slab meshes and factors kept for the next run):\n"
      "  spidarcad fem assets/scenes/platform.json --order 2 --resolution 0.01 \\\n"
      "    --fix=-1,-1,-1,0.0005,1,1 --cache-dir /tmp/spidarcad-fem --out platform.vtu");
  cmd->add_option("input", options->input,
                  "Mesh (.vtu), closed surface (.stl, .obj, .ply), scene or document (.json)")
      ->required();
  cmd->add_option("--out", options->out, "Result .vtu to write")->required();
  cmd->add_option("--E", options->youngs_modulus, "Young's modulus [Pa] (default 200e9, steel)");
  cmd->add_option("--nu", options->poisson_ratio, "Poisson's ratio (default 0.3, steel)");
  cmd->add_option("--fix", options->fix, "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX [m]: clamp nodes in box")
      ->allow_extra_args(false);
  cmd->add_option("--push", options->push, "X,Y,Z [m]: push the surface node nearest here")
      ->allow_extra_args(false);
  cmd->add_option("--disp", options->disp, "DX,DY,DZ [m]: displacement of the matching --push")
      ->allow_extra_args(false);
  cmd->add_option("--load", options->load,
                  "X,Y,Z [m]: point force at the surface node nearest here")
      ->allow_extra_args(false);
  cmd->add_option("--force", options->force, "FX,FY,FZ [N]: force of the matching --load")
      ->allow_extra_args(false);
  cmd->add_option("--grab", options->grab,
                  "XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX [m]: grab the nodes in box, move them rigidly "
                  "(--move, --rotate); JSON grab: their wrench");
  cmd->add_option("--move", options->move,
                  "DX,DY,DZ [m]: translation of the grabbed nodes (with --grab; default 0)");
  cmd->add_option("--rotate", options->rotate,
                  "RX,RY,RZ [rad]: rotation vector of the grabbed nodes about their centroid "
                  "(with --grab; default 0)");
  cmd->add_option("--order", options->order,
                  "Element order: 1 (4-node) or 2 (10-node; a linear mesh gets midside nodes). "
                  "Default: the input's")
      ->check(CLI::IsMember({1, 2}));
  cmd->add_flag("--incompressible", options->incompressible,
                "Locking-free near-incompressible elements (quadratic, mean dilatation)");
  cmd->add_option("--resolution", options->resolution,
                  "Scene input: surface grid cell [m] (default 0.004)");
  cmd->add_option("--quality", options->max_radius_edge,
                  "Scene input: TetGen radius-edge bound (default 2; 0 = no refinement)");
  cmd->add_option("--solid", options->solid, "Scene input: name of the solid (default: the first)");
  cmd->add_option("--object", options->object,
                  "Document input: the object to solve (default: the first fe_model, else the "
                  "first solid, mesh or sculpt)");
  cmd->add_option("--mesher", options->mesher,
                  "Scene solid: surface route, tetrahedra (the default: marching tetrahedra on the "
                  "grid) or lattice (better-shaped triangles; on the platform at 10 mm fewer tets "
                  "and faster edits, at most other cells more tets)");
  cmd->add_option("--flat-cells", options->flat_cells,
                  "Scene solid, marching tetrahedra: collapse the surface's edges shorter than "
                  "this fraction of a cell in flat fans before TetGen, so flat faces get as few "
                  "triangles wherever the grid crosses them (in [0, 1]; default: 0.5 with "
                  "--order 2 or --incompressible, as FE mode meshes for quadratic elements, "
                  "which keep their accuracy on about half the nodes; else 0, since linear "
                  "elements lock more in bending on the coarser faces)")
      ->type_name("F");
  cmd->add_option("--slabs", options->slabs,
                  "Solve in N slabs across x: each factored on its own and condensed onto the "
                  "planes between them (a scene solid is meshed slab by slab). Default 0 (one "
                  "piece), 4 with --cache-dir")
      ->type_name("N");
  cmd->add_option("--cache-dir", options->cache_dir,
                  "Keep slab meshes and slab factors in DIR: a later run whose slab is unchanged "
                  "(e.g. after an edit elsewhere) reads it instead of recomputing it")
      ->type_name("DIR");
  cmd->add_option("--cache-max-gb", options->cache_max_gb,
                  "Bound of --cache-dir in GiB (default 4): the least recently used files are "
                  "removed after the run, never those the run used")
      ->type_name("GB");
  cmd->callback([options, cmd]() {
    options->given_e = cmd->count("--E") > 0;
    options->given_nu = cmd->count("--nu") > 0;
    FemOptions resolved = *options;
    if (cmd->count("--slabs") == 0) resolved.slabs = resolved.cache_dir.empty() ? 0 : 4;
    resolved.lattice = LatticeMesherOption(resolved.mesher, "tetrahedra");
    resolved.flat_cells_given = cmd->count("--flat-cells") > 0;
    if (!resolved.flat_cells_given) {  // FE mode's rule for a solid meshed by TetGen
      MeshSettings surface;
      if (resolved.lattice) surface.surface_mesher = "lattice";
      const int order = resolved.order == 2 || resolved.incompressible ? 2 : 1;
      resolved.flat_cells = FlatCellsForOrder(FeSourceKind::kSolid, surface, order);
    }
    CheckFlatCellsOption(resolved.flat_cells, resolved.lattice);
    RunFem(resolved);
  });
}

}  // namespace spidarcad::app
