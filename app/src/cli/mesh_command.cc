// `spidarcad mesh`: an implicit solid of a scene file -> a surface mesh (STL, OBJ, PLY) or, with
// --tets tetgen|cgal, a tetrahedral mesh (VTU for ParaView, TetGen .node/.ele), with figures.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "scene/document_file.h"
#include "scene/scene_solid.h"
#include "spidarcad/modeling/cgal_mesher.h"
#include "spidarcad/modeling/feature_sharpening.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/mesh_repair.h"
#include "spidarcad/modeling/scene_io.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/tet_smoothing.h"
#include "spidarcad/modeling/tetgen_mesher.h"
#include "spidarcad/modeling/triangle_mesh_io.h"

namespace spidarcad::app {

namespace {

using namespace spidarcad::modeling;

// Options of `spidarcad mesh`.
struct MeshOptions {
  std::string scene;
  std::string out;
  std::string solid;
  std::string object;        // --object, the same as --solid under the name documents use
  double resolution = 0.0;   // m; 0: from the solid's size
  std::string tets;          // "", "tetgen" or "cgal"
  double quality = 2.0;      // radius-edge bound, 0: no refinement
  double max_volume = 0.0;   // m³, 0: unbounded
  double smooth_tets = 0.0;  // --smooth-tets (degrees; 0: off)
  bool raw_surface = false;
  bool sharp = false;
  // --sliver-angle (degrees; 0: off), used with --sharp.
  double sliver_angle = kProductSliverAngleDeg;
  bool sliver_angle_given = false;  // on the command line
  // --snap-cells (fraction of the cell; 0: off): the clean-up's snap band.
  double snap_cells = kProductSnapCells;
  bool snap_cells_given = false;  // on the command line
  // --flat-cells (fraction of the cell; 0: off): the clean-up's flat-fan coarsening.
  double flat_cells = 0.0;
  bool flat_cells_given = false;  // on the command line
  // --mesher: "lattice", "tetrahedra", or "" (lattice unless an option of the other route is
  // given: --sharp, --raw-surface, --snap-cells).
  std::string mesher;
  double lattice_snap = SurfaceMeshSettings{}.lattice_snap;  // --lattice-snap
  bool lattice_snap_given = false;
  double max_cells = 0.0;   // grid cells allowed; set from kDefaultMeshMaxCells
  double max_memory = 0.0;  // estimated peak bytes allowed
  double max_work = 0.0;    // estimated tape instructions allowed
  bool progress = false;    // progress on stderr even when it is not a terminal
  double weld = 1e-9;       // mesh-file input: weld tolerance, fraction of the box diagonal
};

// Whether an option that only the marching-tetrahedra route has is given (--raw-surface,
// --snap-cells, --flat-cells).
bool TetrahedraOptionsGiven(const MeshOptions& o) {
  return o.raw_surface || o.snap_cells_given || o.flat_cells_given;
}
// Whether the surface is meshed by the lattice route: --mesher lattice, or no --mesher, no
// option of the other route and no --sharp (which sharpens the marching-tetrahedra surface
// unless --mesher lattice asks for the lattice one).
bool LatticeRoute(const MeshOptions& o) {
  return o.mesher == "lattice" || (o.mesher.empty() && !o.sharp && !TetrahedraOptionsGiven(o));
}

// Default budget of `spidarcad mesh` (docs/limits.md): 2^27 grid cells (512^3), 2 GiB of
// estimated memory, 2e11 estimated tape instructions (about a minute on one core).
constexpr double kDefaultMeshMaxCells = 134217728.0;
constexpr double kDefaultMeshMaxMemory = 2147483648.0;
constexpr double kDefaultMeshMaxWork = 2e11;
// MeshSurface's own ceiling on the grid: --max-cells cannot go past it.
constexpr double kMeshMaxCellsCeiling = 1073741824.0;

// Raised by SIGINT (Ctrl+C) while `mesh` runs; the meshers poll it.
std::atomic<bool> g_interrupted{false};
static_assert(std::atomic<bool>::is_always_lock_free, "the SIGINT handler stores to g_interrupted");
// Set while the main thread is inside TetGen or CGAL Mesh_3 (UninterruptibleScope), which look
// at the flag only between their stages or not at all.
std::atomic<bool> g_at_once{false};

// What a Ctrl+C prints (as Interrupted() below).
constexpr char kInterruptedMessage[] =
    "\nspidarcad mesh: interrupted (Ctrl+C): stopped, nothing written\n";

void OnMeshInterrupt(int) {
  if (g_at_once.load()) {
    // Inside TetGen or CGAL: end now (async-signal-safe calls only). No output exists yet: the
    // outputs are written after these calls, through temporaries (WriteThrough).
    const ssize_t ignored =
        write(STDERR_FILENO, kInterruptedMessage, sizeof kInterruptedMessage - 1);
    (void)ignored;
    _exit(130);
  }
  if (g_interrupted.load()) {
    // A second Ctrl+C: stop now, the default way.
    signal(SIGINT, SIG_DFL);
    raise(SIGINT);
    return;
  }
  g_interrupted.store(true);
}

// Installs OnMeshInterrupt for its lifetime (even where the shell ignored SIGINT for a
// background job: the flag only asks the meshers to stop).
class InterruptScope {
 public:
  InterruptScope() {
    g_interrupted.store(false);
    struct sigaction action = {};
    action.sa_handler = OnMeshInterrupt;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &previous_);
  }
  ~InterruptScope() { sigaction(SIGINT, &previous_, nullptr); }
  InterruptScope(const InterruptScope&) = delete;
  InterruptScope& operator=(const InterruptScope&) = delete;

 private:
  struct sigaction previous_ = {};
};

// Thrown between stages when Ctrl+C was pressed.
struct MeshInterrupted {};

// For its lifetime the first Ctrl+C ends the process at once with status 130 (OnMeshInterrupt):
// around TetGen and CGAL calls, which would otherwise finish first (seconds to minutes). What
// was printed so far is flushed first (_exit drops stdio buffers). Not nested.
class UninterruptibleScope {
 public:
  UninterruptibleScope() {
    std::cout.flush();
    std::fflush(stdout);
    g_at_once.store(true);
    // A Ctrl+C that came just before: end now as well.
    if (g_interrupted.load()) raise(SIGINT);
  }
  ~UninterruptibleScope() { g_at_once.store(false); }
  UninterruptibleScope(const UninterruptibleScope&) = delete;
  UninterruptibleScope& operator=(const UninterruptibleScope&) = delete;
};

// fn() inside an UninterruptibleScope.
template <typename F>
auto AtOnceOnCtrlC(F&& fn) {
  const UninterruptibleScope scope;
  return fn();
}

void CheckInterrupted() {
  if (g_interrupted.load()) throw MeshInterrupted{};
}

// Progress of the long stages on stderr: one line redrawn at most 5 times a second.
class Progress {
 public:
  explicit Progress(bool enabled) : enabled_(enabled) {}
  ~Progress() { Finish(); }

  // A callback for the meshers' `progress` that shows `stage` with its fraction done.
  std::function<void(double)> Stage(const std::string& stage) {
    if (!enabled_) return {};
    return [this, stage](double fraction) { Show(stage, fraction); };
  }
  // A line of its own (the estimate), between the bars.
  void Note(const std::string& line) {
    if (!enabled_) return;
    Finish();
    std::cerr << "spidarcad mesh: " << line << "\n" << std::flush;
  }
  void Finish() {
    if (open_) std::cerr << "\n" << std::flush;
    open_ = false;
  }

 private:
  void Show(const std::string& stage, double fraction) {
    const auto now = std::chrono::steady_clock::now();
    if (open_ && stage == stage_ && fraction < 1.0 && now - last_ < std::chrono::milliseconds(200))
      return;
    if (open_ && stage != stage_) Finish();
    last_ = now;
    stage_ = stage;
    open_ = true;
    char line[96];
    std::snprintf(line, sizeof line, "\rspidarcad mesh: %s %5.1f %%", stage.c_str(),
                  100.0 * std::clamp(fraction, 0.0, 1.0));
    std::cerr << line << std::flush;
  }

  bool enabled_;
  bool open_ = false;
  std::string stage_;
  std::chrono::steady_clock::time_point last_;
};

// Where an output goes while it is written: a hidden file beside it with the same extension,
// renamed over it when complete, so an interrupted or failed run leaves no half-written file.
std::string TemporaryPath(const std::string& out, const std::string& ext) {
  const std::filesystem::path path(out);
  const std::string stem =
      path.filename().string().substr(0, path.filename().string().size() - ext.size());
  return (path.parent_path() / ("." + stem + ".partial-" + std::to_string(getpid()) + ext))
      .string();
}

// Writes files through temporaries: write(temporaries) fills each of temporaries, then, unless
// Ctrl+C came meanwhile, each is renamed over its final path. On any failure the temporaries
// are removed and the final paths left as they were.
void WriteThrough(const std::vector<std::string>& temporaries,
                  const std::vector<std::string>& finals, const std::function<void()>& write) {
  auto remove_all = [&]() {
    std::error_code ec;
    for (const std::string& t : temporaries) std::filesystem::remove(t, ec);
  };
  try {
    write();
    CheckInterrupted();
  } catch (...) {
    remove_all();
    throw;
  }
  for (size_t i = 0; i < temporaries.size(); ++i) {
    std::error_code ec;
    std::filesystem::rename(temporaries[i], finals[i], ec);
    if (ec) {
      remove_all();
      throw InputError("--out '" + finals[i] + "': cannot move the finished file into place (" +
                       ec.message() + ")");
    }
  }
}

// The budget check of one figure: throws InputError with the estimate and the option.
void CheckBudget(double value, double limit, const char* what, const char* option,
                 const SurfaceMeshEstimate& estimate, const std::string& unit) {
  if (value <= limit) return;
  char text[256];
  std::snprintf(text, sizeof text, "estimated %s %.3g%s is over %s %.6g%s", what, value,
                unit.c_str(), option, limit, unit.c_str());
  char raised[64];
  std::snprintf(raised, sizeof raised, "%.3g", std::ceil(value * 1.1));
  throw InputError(std::string("mesh: ") + text + " (estimate: " + estimate.Describe() +
                   "; docs/limits.md): use a coarser --resolution, or raise the limit with " +
                   option + " " + raised);
}

// Cells along the largest side of the solid's box for the default resolution.
constexpr double kDefaultCellsAcross = 80.0;

constexpr const char* kMeshHelp =
    "Meshes an implicit solid of a scene file or document (docs/scene-format.md): the solid\n"
    "--object NAME (or --solid NAME), else the first solid; a document's other objects (meshes,\n"
    "FE models, sculpts, parts) are not meshed, and naming one is an error that lists the solids.\n"
    "Surface (--mesher lattice, the default): marching tetrahedra on the body-centred cubic\n"
    "lattice of the grid's corners and cell centres (cell R metres), where each lattice vertex\n"
    "whose nearest crossing lies within --lattice-snap F of its edge (default 0.35) is first\n"
    "moved onto the surface, so no needle is ever made and no clean-up is needed; regions the\n"
    "interval bounds place away from the surface are not sampled. Closed and manifold; smooth\n"
    "surfaces keep every angle above about 15 deg; sharp edges are cut off by up to about R/2.\n"
    "Surface (--mesher tetrahedra, the default with --sharp, --raw-surface, --snap-cells or\n"
    "--flat-cells):\n"
    "marching tetrahedra on the grid's cubes, then a clean-up pass (edge collapses and flips);\n"
    "it snaps grid values within --snap-cells S cells of zero (default 0.2) to zero, so smooth\n"
    "surfaces get no triangle under about 10 deg; --snap-cells 0 gives the mesh of before\n"
    "2026-12-05. --flat-cells F (default 0: off) then collapses edges under F cells in flat\n"
    "fans, so a flat face has as few triangles wherever the grid crosses it (fewer tets for\n"
    "TetGen; `spidarcad fem` takes it too). --sharp then moves vertices onto creases and corners,\n"
    "and where a part about a cell thick keeps a triangle under --sliver-angle it sharpens again\n"
    "on the grid moved by a fraction of a cell.\n"
    "Every route: where the surface holds over 5 % more or less volume than the solid (sampled\n"
    "from its function; a wall about a cell thick fallen between grid planes), the solid is\n"
    "meshed again on the grid moved by 1/4, 1/8, 3/8 of a cell along each axis and the best\n"
    "placement is kept (the line 'grid placement'); a warning says when none keeps it.\n"
    "--mesher lattice --sharp sharpens the lattice surface instead, putting a new vertex on each\n"
    "corner no vertex could reach: on boxes and holes it halves the error of the other route in\n"
    "less time, but it leaves concave creases at general angles cut by up to R/2 (docs/cli.md).\n"
    "Volume (--tets tetgen): TetGen 1.5 tetrahedralizes that surface; --quality Q bounds the\n"
    "radius-edge ratio (TetGen's q switch, > 1; 0 turns refinement off), --max-volume V bounds\n"
    "the tet volume in m^3 (TetGen's a switch). --smooth-tets D then moves the vertices inside\n"
    "the mesh of the tets with a dihedral angle under D degrees to where the smallest angle of\n"
    "the tets around them is largest; the surface, the tets and the volume stay (the platform at\n"
    "its default cell with D = 10: 723 -> 514 tets under 10 deg, the smallest 2.84 -> 4.05 deg).\n"
    "Volume (--tets cgal): CGAL Mesh_3 straight from the implicit function (no surface mesh):\n"
    "facet and cell size R (the resolution), facet distance R/10, facet angle 25 deg, then sliver\n"
    "perturbation and exudation; --quality Q is the cell radius-edge bound (> 1; 0: 3), and\n"
    "--max-volume V lowers the cell size to the circumradius of a regular tet of volume V.\n"
    "Boundary nodes lie on the surface; sharp edges are cut off by up to about R/10.\n"
    "Output by extension: .stl (binary), .obj, .ply (binary) for the surface; .vtu (ParaView,\n"
    "cell data region/volume/min_dihedral_deg) or .node (+ .ele beside it) with --tets.\n"
    "Prints counts, times, the smallest triangle angle, the surface error (max |f| sampled at\n"
    "vertices, edge midpoints and centroids: the distance to the true surface for exact\n"
    "distance fields), the volume against the solid's (estimated from its function at 2^16\n"
    "quasi-random points; a warning past 5 %: a wall about a cell thick can fall between the\n"
    "grid's planes) and the tets' worst dihedral angles. Bad input exits with status 2.\n"
    "\n"
    "Budget (docs/limits.md): before meshing, the cost is estimated from the box and the\n"
    "resolution (grid cells, surface cells, triangles, field evaluations, memory); past a limit\n"
    "the command refuses (status 2) with the estimate: --max-cells (grid cells, default 2^27,\n"
    "at most 2^30), --max-memory (bytes, default 2 GiB), --max-work (tape instructions, default\n"
    "2e11, about a minute). Progress goes to stderr when it is a terminal or with --progress.\n"
    "Ctrl+C stops cleanly: exit status 130 and no output file (outputs are written to a hidden\n"
    "file beside --out and renamed when complete), at once also inside TetGen and CGAL.\n"
    "\n"
    "Mesh-file input (.stl, .obj, .ply instead of a scene): the surface is repaired where that\n"
    "is safe (vertices within --weld welded, zero-area, repeated and back-to-back triangles\n"
    "dropped, the orientation made consistent and outward), each change reported, or refused\n"
    "with status 2 naming the file, the defect (open, non-manifold edge, self-intersection) and\n"
    "the first offending triangle. Then --out .stl/.obj/.ply writes the repaired surface and\n"
    "--tets tetgen tetrahedralizes it (--quality, --max-volume as above).\n"
    "\n"
    "Examples:\n"
    "  spidarcad mesh assets/scenes/platform.json --out platform.stl\n"
    "  spidarcad mesh assets/scenes/platform.json --out platform.obj --resolution 0.002\n"
    "  spidarcad mesh assets/scenes/platform.json --out platform.vtu --tets tetgen\n"
    "  spidarcad mesh assets/scenes/platform.json --out platform.vtu --tets tetgen \\\n"
    "      --resolution 0.003 --quality 1.5 --max-volume 1e-7\n"
    "  spidarcad mesh assets/scenes/platform.json --out platform.node --tets tetgen\n"
    "      (writes platform.node and platform.ele)\n"
    "  spidarcad mesh assets/scenes/platform.json --out platform.vtu --tets cgal --resolution "
    "0.004\n"
    "  spidarcad mesh platform.stl --out part_fixed.stl  (a surface file, here the first\n"
    "      example's: repair report, repaired copy)\n"
    "  spidarcad mesh platform.stl --out part.vtu --tets tetgen\n";

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string Extension(const std::string& path) {
  const auto slash = path.find_last_of('/');
  const auto dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  return Lower(path.substr(dot));
}

std::string Fmt(double v, int digits = 4) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*g", digits, v);
  return buffer;
}

// --smooth-tets DEG: the interior vertices of the tets under DEG moved (SmoothSlivers), a line
// saying what it did; the tets' quality measured again.
TetQuality SmoothTets(TetMesh* tets, double target_deg, const TetQuality& quality) {
  if (!(target_deg > 0.0)) return quality;
  TetSmoothingSettings settings;
  settings.target_dihedral_deg = target_deg;
  const TetSmoothingStats s = SmoothSlivers(tets, settings);
  std::cout << "smooth: " << s.moved << " interior vertices moved in " << s.sweeps
            << " passes; tets under " << Fmt(target_deg) << " deg " << s.under_target_before
            << " -> " << s.under_target_after << ", smallest dihedral angle "
            << Fmt(s.min_dihedral_before_deg, 3) << " -> " << Fmt(s.min_dihedral_after_deg, 3)
            << " deg, " << Fmt(s.seconds, 3) << " s\n";
  return MeasureTetQuality(*tets);
}

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Writes tets to o.out (.vtu, or .node with .ele beside it) and says so.
void WriteTets(const TetMesh& tets, const std::string& out, const std::string& ext) {
  const auto start = std::chrono::steady_clock::now();
  const std::string temporary = TemporaryPath(out, ext);
  if (ext == ".vtu") {
    WriteThrough({temporary}, {out}, [&]() { WriteVtu(tets, temporary); });
    std::cout << "wrote " << out;
  } else {
    const std::string base = out.substr(0, out.size() - ext.size());
    const std::string temporary_base = temporary.substr(0, temporary.size() - ext.size());
    WriteThrough({temporary_base + ".node", temporary_base + ".ele"},
                 {base + ".node", base + ".ele"},
                 [&]() { WriteTetgenFiles(tets, temporary_base); });
    std::cout << "wrote " << base << ".node and " << base << ".ele";
  }
  std::cout << " (" << Fmt(Seconds(start), 3) << " s)\n";
}

// --tets cgal: CGAL Mesh_3 from the implicit function on the grid's box, sizes from its cell.
void RunCgal(const MeshOptions& o, const SceneSolidGrid& grid, const std::string& ext,
             Progress* progress) {
  CgalMeshSettings settings = CgalMeshSettings::ForSize(grid.cell);
  settings.cancel = &g_interrupted;
  settings.progress = progress->Stage("cgal mesh_3");
  settings.cell_radius_edge_ratio = o.quality > 0.0 ? o.quality : 3.0;
  if (o.max_volume > 0.0) {
    // Circumradius of the regular tet of volume V: edge a = (6 sqrt(2) V)^(1/3), R = sqrt(6)/4 a.
    const double edge = std::cbrt(6.0 * std::sqrt(2.0) * o.max_volume);
    settings.cell_size = std::min(settings.cell_size, std::sqrt(6.0) / 4.0 * edge);
  }
  CgalMeshStats stats;
  const TetMesh tets = AtOnceOnCtrlC(
      [&] { return MeshImplicitWithCgal(grid.compiled, grid.bounds, settings, &stats); });
  progress->Finish();
  CheckInterrupted();
  const TriangleMesh boundary = BoundarySurface(tets);
  const TriangleAngleStats angles = MeasureTriangleAngles(boundary, 5.0);
  const SurfaceError error = MeasureSurfaceError(grid.compiled, boundary);
  const TetQuality& q = stats.quality;
  std::cout << "scene " << o.scene << ", solid '" << grid.solid_name << "'\n";
  std::cout << "cgal mesh_3: facet size " << Fmt(settings.facet_size) << " m, facet distance "
            << Fmt(settings.facet_distance) << " m, cell size " << Fmt(settings.cell_size)
            << " m, radius-edge " << Fmt(settings.cell_radius_edge_ratio) << ", box "
            << Fmt(grid.bounds.sizes().x()) << " x " << Fmt(grid.bounds.sizes().y()) << " x "
            << Fmt(grid.bounds.sizes().z()) << " m\n";
  std::cout << "cgal: " << tets.nodes.cols() << " nodes, " << tets.tets.cols() << " tets, "
            << stats.seed_points << " seeds, refine " << Fmt(stats.refine_seconds, 3)
            << " s, optimize " << Fmt(stats.optimize_seconds, 3) << " s, total "
            << Fmt(stats.seconds, 3) << " s\n";
  std::cout << "boundary: " << boundary.vertices.cols() << " vertices, "
            << boundary.triangles.cols() << " triangles, min triangle angle "
            << Fmt(angles.min_angle_deg, 3) << " deg; error max " << Fmt(error.max, 3) << " m, rms "
            << Fmt(error.rms, 3) << " m\n";
  std::cout << "tet quality: dihedral angles " << Fmt(q.min_dihedral_deg, 3) << " .. "
            << Fmt(q.max_dihedral_deg, 4) << " deg, max radius-edge " << Fmt(q.max_radius_edge, 3)
            << ", volume " << Fmt(q.total_volume * 1e6, 6) << " cm^3\n";
  WriteTets(tets, o.out, ext);
}

// Whether path names a triangle mesh file (.stl, .obj, .ply, any case).
bool IsTriangleMeshFile(const std::string& path) {
  const std::string ext = Extension(path);
  return ext == ".stl" || ext == ".obj" || ext == ".ply";
}

// A triangle mesh file as input: repaired (or refused) by modeling::ImportSolidMesh, with the
// repair report on stdout, then written as a surface (a repaired copy) or tetrahedralized by
// TetGen.
void RunMeshFile(const MeshOptions& o, const std::string& ext, Progress* progress) {
  if (o.tets == "cgal") {
    throw InputError("--tets cgal meshes an implicit solid from its function; the mesh file '" +
                     o.scene + "' can be tetrahedralized with --tets tetgen");
  }
  if (o.resolution != 0.0 || o.sharp || TetrahedraOptionsGiven(o) || !o.solid.empty() ||
      !o.mesher.empty() || o.lattice_snap_given) {
    throw InputError(
        "--resolution, --mesher, --sharp, --raw-surface, --snap-cells, --flat-cells, "
        "--lattice-snap and --solid apply to scene files; the mesh file '" +
        o.scene + "' is used as it is (drop them)");
  }
  if (!(o.weld >= 0.0 && o.weld < 0.1)) {
    throw InputError("--weld: a fraction of the bounding-box diagonal in [0, 0.1), got " +
                     Fmt(o.weld));
  }
  MeshRepairSettings settings;
  settings.weld_tolerance = o.weld;
  MeshRepairReport report;
  TriangleMesh surface;
  try {
    surface = ImportSolidMesh(o.scene, settings, &report);
  } catch (const MeshDefectError& e) {
    throw InputError(e.what());
  }
  std::cout << "mesh file " << o.scene << ": " << report.input_vertices << " vertices, "
            << report.input_triangles << " triangles\n";
  for (const std::string& line : report.Lines()) std::cout << "repair: " << line << "\n";
  const Eigen::AlignedBox3d box(surface.vertices.rowwise().minCoeff(),
                                surface.vertices.rowwise().maxCoeff());
  std::cout << "surface: " << surface.vertices.cols() << " vertices, " << surface.triangles.cols()
            << " triangles, box " << Fmt(box.sizes().x()) << " x " << Fmt(box.sizes().y()) << " x "
            << Fmt(box.sizes().z()) << ", volume " << Fmt(MeshVolume(surface), 6)
            << " (file units cubed); closed, manifold, no self-intersection (checked in "
            << Fmt(report.seconds, 3) << " s)\n";
  if (o.tets.empty()) {
    const std::string temporary = TemporaryPath(o.out, ext);
    WriteThrough({temporary}, {o.out}, [&]() { WriteTriangleMesh(surface, temporary); });
    std::cout << "wrote " << o.out << "\n";
    return;
  }
  TetMeshSettings tet_settings;
  tet_settings.max_radius_edge = o.quality;
  tet_settings.max_volume = o.max_volume;
  tet_settings.cancel = &g_interrupted;
  tet_settings.progress = progress->Stage("tetgen");
  TetMeshStats tet_stats;
  TetMesh tets =
      AtOnceOnCtrlC([&] { return TetrahedralizeSurface(surface, tet_settings, &tet_stats); });
  progress->Finish();
  CheckInterrupted();
  std::cout << "tetgen -" << tet_stats.switches << ": " << tets.nodes.cols() << " nodes, "
            << tets.tets.cols() << " tets, tetgen " << Fmt(tet_stats.tetgen_seconds, 3) << " s\n";
  const TetQuality q = SmoothTets(&tets, o.smooth_tets, tet_stats.quality);
  std::cout << "tet quality: dihedral angles " << Fmt(q.min_dihedral_deg, 3) << " .. "
            << Fmt(q.max_dihedral_deg, 4) << " deg, max radius-edge " << Fmt(q.max_radius_edge, 3)
            << ", volume " << Fmt(q.total_volume, 6) << "\n";
  WriteTets(tets, o.out, ext);
}

void RunMesh(const MeshOptions& o) {
  const std::string ext = Extension(o.out);
  const bool surface_ext = ext == ".stl" || ext == ".obj" || ext == ".ply";
  const bool volume_ext = ext == ".vtu" || ext == ".node";
  if (!surface_ext && !volume_ext) {
    throw InputError(
        "--out '" + o.out + "': unknown extension '" + ext +
        "' (use .stl, .obj, .ply for a surface; .vtu or .node with --tets tetgen|cgal)");
  }
  if (!o.tets.empty() && o.tets != "tetgen" && o.tets != "cgal") {
    throw InputError("--tets '" + o.tets + "': expected tetgen or cgal");
  }
  if (volume_ext && o.tets.empty()) {
    throw InputError("--out '" + o.out + "': " + ext +
                     " holds tetrahedra; add --tets tetgen or --tets cgal");
  }
  if (surface_ext && !o.tets.empty()) {
    throw InputError("--out '" + o.out + "': with --tets the output is .vtu or .node, not " + ext);
  }
  if (o.sliver_angle_given && !o.sharp)
    throw InputError("--sliver-angle repairs what --sharp leaves: add --sharp");
  if (!(o.sliver_angle >= 0.0 && o.sliver_angle < 60.0))
    throw InputError("--sliver-angle " + Fmt(o.sliver_angle) +
                     ": give degrees in [0, 60) (default 10; 0 turns it off)");
  if (!(o.snap_cells >= 0.0 && o.snap_cells <= 0.25))
    throw InputError("--snap-cells " + Fmt(o.snap_cells) +
                     ": give a fraction of the cell in [0, 0.25] (default " +
                     Fmt(kProductSnapCells) + "; 0 turns snapping off)");
  if (o.snap_cells_given && o.raw_surface)
    throw InputError("--snap-cells is part of the clean-up pass: drop --raw-surface");
  CheckFlatCellsOption(o.flat_cells, o.mesher == "lattice");
  if (o.flat_cells_given && o.raw_surface)
    throw InputError("--flat-cells is part of the clean-up pass: drop --raw-surface");
  if (o.flat_cells_given && o.tets == "cgal")
    throw InputError(
        "--flat-cells applies to the marching-tetrahedra surface; --tets cgal does not use one");
  if (o.snap_cells_given && o.tets == "cgal")
    throw InputError(
        "--snap-cells applies to the marching-tetrahedra surface; --tets cgal does "
        "not use one");
  LatticeMesherOption(o.mesher, "lattice");
  if (o.mesher == "lattice" && TetrahedraOptionsGiven(o)) {
    throw InputError(
        "--raw-surface, --snap-cells and --flat-cells belong to --mesher tetrahedra (the lattice "
        "surface has no clean-up pass): drop them or use --mesher tetrahedra");
  }
  if (o.lattice_snap_given && !LatticeRoute(o))
    throw InputError("--lattice-snap applies to --mesher lattice");
  if (!(o.lattice_snap >= 0.0 && o.lattice_snap <= kMaxLatticeSnap))
    throw InputError("--lattice-snap " + Fmt(o.lattice_snap) +
                     ": give a fraction of the lattice edge in [0, " + Fmt(kMaxLatticeSnap) +
                     "] (default " + Fmt(SurfaceMeshSettings{}.lattice_snap) +
                     "; 0: no vertex moves)");
  if (!(o.resolution >= 0.0) || !std::isfinite(o.resolution)) {
    throw InputError("--resolution: must be > 0 m, got " + Fmt(o.resolution));
  }
  if (!(o.quality == 0.0 || o.quality > 1.0) || !std::isfinite(o.quality)) {
    throw InputError("--quality: radius-edge bound must be > 1 (or 0 for no refinement), got " +
                     Fmt(o.quality));
  }
  if (!(o.max_volume >= 0.0) || !std::isfinite(o.max_volume)) {
    throw InputError("--max-volume: must be >= 0 m^3, got " + Fmt(o.max_volume));
  }
  if (!(o.smooth_tets >= 0.0 && o.smooth_tets < 60.0)) {
    throw InputError("--smooth-tets: must be a dihedral angle in [0, 60) degrees (0: off), got " +
                     Fmt(o.smooth_tets));
  }
  if (o.smooth_tets > 0.0 && o.tets != "tetgen") {
    throw InputError("--smooth-tets smooths TetGen's tets: give it with --tets tetgen");
  }
  if (!(o.max_cells >= 1.0 && o.max_cells <= kMeshMaxCellsCeiling)) {
    throw InputError(
        "--max-cells: must be in [1, 2^30 = 1073741824] (the mesher's grid ceiling), got " +
        Fmt(o.max_cells, 6));
  }
  if (!(o.max_memory > 0.0) || !std::isfinite(o.max_memory)) {
    throw InputError("--max-memory: must be a number of bytes > 0 (e.g. 4e9), got " +
                     Fmt(o.max_memory, 6));
  }
  if (!(o.max_work > 0.0) || !std::isfinite(o.max_work)) {
    throw InputError("--max-work: must be a number of tape instructions > 0 (e.g. 1e12), got " +
                     Fmt(o.max_work, 6));
  }

  // The output's directory must take the file (checked now, not after the meshing).
  {
    const std::filesystem::path parent = std::filesystem::path(o.out).parent_path();
    const std::string directory = parent.empty() ? std::string(".") : parent.string();
    std::error_code ec;
    if (!std::filesystem::is_directory(directory, ec) ||
        access(directory.c_str(), W_OK | X_OK) != 0) {
      throw InputError("--out '" + o.out + "': cannot write into '" + directory +
                       "' (no such directory, or no permission); create it or pick another path");
    }
  }

  if (!o.solid.empty() && !o.object.empty())
    throw InputError("--solid and --object name the same thing: give one");
  const std::string option = o.object.empty() ? "--solid" : "--object";
  const std::string name = o.object.empty() ? o.solid : o.object;

  const InterruptScope interrupt_scope;
  Progress progress(o.progress || isatty(STDERR_FILENO) == 1);
  if (IsTriangleMeshFile(o.scene)) {
    RunMeshFile(o, ext, &progress);
    return;
  }
  const OpenedDocument opened = OpenDocumentFile(o.scene);
  // The box search (seconds for a union of 100,000 primitives) writes nothing: a Ctrl+C there
  // ends the process at once.
  progress.Note("box: finding where the solid lies");
  const SceneSolidGrid grid = AtOnceOnCtrlC([&] {
    return PrepareDocumentSolid(opened, name, option, o.resolution, kDefaultCellsAcross,
                                o.max_cells, "--max-cells");
  });
  const CompiledSolid& compiled = grid.compiled;
  const Eigen::AlignedBox3d& bounds = grid.bounds;
  const double cell = grid.cell;

  if (o.sharp && o.raw_surface)
    throw InputError("--sharp needs the clean-up pass: drop --raw-surface");
  if (o.sharp && o.tets == "cgal") {
    throw InputError(
        "--sharp sharpens the marching-tetrahedra surface; --tets cgal does not use one");
  }
  if (o.tets == "cgal") {
    RunCgal(o, grid, ext, &progress);
    return;
  }

  SurfaceMeshSettings settings;
  settings.bounds = bounds;
  settings.cell_size = cell;
  settings.clean = !o.raw_surface;
  settings.snap_cells = o.snap_cells;  // without the clean-up (--raw-surface) nothing is snapped
  settings.flat_coarsen_cells = o.flat_cells;
  const bool lattice = LatticeRoute(o);
  if (lattice) {
    settings.mesher = SurfaceMesher::kLattice;
    settings.lattice_snap = o.lattice_snap;
  }
  settings.cancel = &g_interrupted;
  settings.progress = progress.Stage("surface");
  SurfaceMeshStats stats;
  TriangleMesh surface;
  FeatureSettings features;
  features.cell_size = cell;
  features.cancel = &g_interrupted;
  features.sliver_angle_deg = o.sliver_angle;
  features.sliver_fallback_deviation_cells = kProductSliverFallbackCells;
  // The lattice leaves no vertex near a box corner to move onto it: insert one there.
  features.insert_corners = lattice;
  FeatureStats feature_stats;
  SharpSurface placed;  // the grid placement kept, and the first's figures
  try {
    const SurfaceMeshEstimate estimate = EstimateSurfaceMesh(compiled, settings);
    progress.Note("estimate: " + estimate.Describe());
    CheckBudget(estimate.grid_cells, o.max_cells, "grid cells", "--max-cells", estimate, "");
    CheckBudget(estimate.bytes, o.max_memory, "memory", "--max-memory", estimate, " bytes");
    CheckBudget(estimate.work, o.max_work, "work", "--max-work", estimate, " tape instructions");
    if (o.sharp) {
      // Sharpened, on another grid placement where the first leaves triangles under the sliver
      // angle (a part about a cell thick).
      placed = MeshSharpSurface(compiled, settings, features);
      feature_stats = placed.features;
    } else {
      // On another grid placement where a wall about a cell thick falls between grid planes.
      placed = MeshSurfaceKeepingVolume(compiled, settings);
    }
    surface = std::move(placed.mesh);
    stats = placed.surface;
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--resolution ") + Fmt(cell) + ": " + e.what());
  }
  progress.Finish();
  CheckInterrupted();
  if (surface.triangles.cols() == 0)
    throw InputError("solid '" + grid.solid_name + "': the surface mesh is empty at cell " +
                     Fmt(cell) + " m");
  const TriangleAngleStats angles = MeasureTriangleAngles(surface, 5.0);
  const SurfaceError error = MeasureSurfaceError(compiled, surface);
  std::cout << "scene " << o.scene << ", solid '" << grid.solid_name << "'\n";
  std::cout << "surface: cell " << Fmt(cell) << " m, box " << Fmt(bounds.sizes().x()) << " x "
            << Fmt(bounds.sizes().y()) << " x " << Fmt(bounds.sizes().z()) << " m, "
            << surface.vertices.cols() << " vertices, " << surface.triangles.cols()
            << " triangles, " << Fmt(stats.seconds, 3) << " s"
            << (o.raw_surface ? " (raw, no clean-up)" : "")
            << (lattice ? " (lattice)" : " (marching tetrahedra)") << "\n";
  if (lattice) {
    std::cout << "lattice: " << stats.snapped_vertices << " lattice vertices snapped onto the "
              << "surface (within " << Fmt(settings.lattice_snap) << " of an edge), "
              << stats.field_evaluations << " field evaluations\n";
  } else if (!o.raw_surface) {
    std::cout << "clean-up: " << stats.collapsed_edges << " edge collapses, " << stats.flipped_edges
              << " flips, snap " << Fmt(settings.snap_cells) << " cells";
    if (o.flat_cells > 0.0)
      std::cout << ", " << stats.flat_collapses << " collapses in flat fans (edges under "
                << Fmt(o.flat_cells) << " cells)";
    std::cout << "\n";
  }
  if (o.sharp) {
    std::cout << "sharpen: " << feature_stats.feature_vertices << " feature vertices ("
              << feature_stats.corner_vertices << " corners), " << feature_stats.vertices_moved
              << " moved, " << feature_stats.edges_flipped << " flips";
    if (lattice) std::cout << ", " << feature_stats.corners_inserted << " corners inserted";
    if (o.sliver_angle > 0.0)
      std::cout << "; slivers under " << Fmt(o.sliver_angle)
                << " deg: " << feature_stats.sliver_collapses << " collapses, "
                << feature_stats.sliver_snaps << " snaps, " << feature_stats.sliver_flips
                << " flips, " << feature_stats.sliver_moves << " moves";
    std::cout << ", " << Fmt(feature_stats.seconds, 3) << " s\n";
  }
  const double volume = MeshVolume(surface);
  // The volume against the solid's (EstimateSolidVolume): a wall about a cell thick can fall
  // between grid planes and be lost without any other figure showing it.
  const double volume_off = placed.solid_volume > 0.0 ? volume / placed.solid_volume - 1.0 : 0.0;
  if (placed.placements > 1) {
    // A relative volume error in percent, signed.
    auto off = [&](double error) { return Fmt(100.0 * error, 3) + " %"; };
    std::cout << "grid placement: the first";
    if (o.sharp)
      std::cout << " left " << placed.first_under << " triangle"
                << (placed.first_under == 1 ? "" : "s") << " under " << Fmt(o.sliver_angle)
                << " deg (min " << Fmt(placed.first_min_angle_deg, 4) << " deg),";
    std::cout << " volume " << off(placed.first_volume_error) << " from the solid's; "
              << placed.placements << " placements meshed" << (o.sharp ? " and sharpened" : "")
              << ", kept ";
    if (placed.grid_shift == 0.0)
      std::cout << "the first";
    else
      std::cout << "the grid moved by " << Fmt(placed.grid_shift) << " cell along each axis";
    std::cout << " (volume " << off(volume_off) << "), " << Fmt(placed.seconds, 3) << " s in all\n";
  }
  // Four digits, so that an angle a hair under 10° does not print as 10.
  const long under_10 = MeasureTriangleAngles(surface, 10.0).small_angle;
  std::cout << "surface quality: min triangle angle " << Fmt(angles.min_angle_deg, 4) << " deg, "
            << under_10 << (under_10 == 1 ? " triangle" : " triangles") << " under 10 deg, "
            << angles.small_angle << " under 5 deg, " << angles.zero_area
            << " zero-area; error max " << Fmt(error.max, 3) << " m, rms " << Fmt(error.rms, 3)
            << " m; volume " << Fmt(volume * 1e6, 6) << " cm^3";
  if (placed.solid_volume > 0.0)
    std::cout << " (" << (volume_off >= 0.0 ? "+" : "") << Fmt(100.0 * volume_off, 2)
              << " % from the solid's, sampled from its function)";
  std::cout << "\n";
  std::cerr << VolumeOffWarning(volume_off, cell,
                                "no grid placement tried keeps it; a finer --resolution does");

  if (o.tets.empty()) {
    const auto start = std::chrono::steady_clock::now();
    const std::string temporary = TemporaryPath(o.out, ext);
    WriteThrough({temporary}, {o.out}, [&]() { WriteTriangleMesh(surface, temporary); });
    std::cout << "wrote " << o.out << " (" << Fmt(Seconds(start), 3) << " s)\n";
    return;
  }

  TetMeshSettings tet_settings;
  tet_settings.max_radius_edge = o.quality;
  tet_settings.max_volume = o.max_volume;
  tet_settings.cancel = &g_interrupted;
  tet_settings.progress = progress.Stage("tetgen");
  TetMeshStats tet_stats;
  TetMesh tets =
      AtOnceOnCtrlC([&] { return TetrahedralizeSurface(surface, tet_settings, &tet_stats); });
  progress.Finish();
  CheckInterrupted();
  std::cout << "tetgen -" << tet_stats.switches << ": " << tets.nodes.cols() << " nodes, "
            << tets.tets.cols() << " tets, check " << Fmt(tet_stats.check_seconds, 3)
            << " s, tetgen " << Fmt(tet_stats.tetgen_seconds, 3) << " s";
  if (tet_stats.welded_vertices > 0 || tet_stats.dropped_triangles > 0) {
    std::cout << " (repair welded " << tet_stats.welded_vertices << " vertices, dropped "
              << tet_stats.dropped_triangles << " triangles)";
  }
  std::cout << "\n";
  const TetQuality q = SmoothTets(&tets, o.smooth_tets, tet_stats.quality);
  std::cout << "tet quality: dihedral angles " << Fmt(q.min_dihedral_deg, 3) << " .. "
            << Fmt(q.max_dihedral_deg, 4) << " deg, max radius-edge " << Fmt(q.max_radius_edge, 3)
            << ", volume " << Fmt(q.total_volume * 1e6, 6) << " cm^3\n";
  WriteTets(tets, o.out, ext);
}

// Ctrl+C: say so and end with status 130 (128 + SIGINT), as a shell does for a killed job.
[[noreturn]] void Interrupted() {
  std::cout.flush();
  std::cerr << kInterruptedMessage << std::flush;
  throw CommandExit{130};
}

}  // namespace

void RegisterMeshCommand(CLI::App& app) {
  auto options = std::make_shared<MeshOptions>();
  options->max_cells = kDefaultMeshMaxCells;
  options->max_memory = kDefaultMeshMaxMemory;
  options->max_work = kDefaultMeshMaxWork;
  CLI::App* cmd = app.add_subcommand(
      "mesh", "Mesh an implicit solid of a scene: surface (STL/OBJ/PLY) or tets (VTU, .node)");
  cmd->footer(kMeshHelp);
  cmd->add_option("scene", options->scene,
                  "Scene file or document (JSON, version 1 or 2, docs/scene-format.md), or a "
                  "closed triangle mesh (.stl, .obj, .ply) to repair or tetrahedralize")
      ->required();
  cmd->add_option("--weld", options->weld,
                  "Mesh-file input: weld vertices closer than this fraction of the bounding-box "
                  "diagonal (default 1e-9)");
  cmd->add_option("--out", options->out,
                  "Output file: .stl .obj .ply (surface) or .vtu .node (with --tets)")
      ->required();
  cmd->add_option("--solid", options->solid, "Name of the solid to mesh (default: the first)");
  cmd->add_option("--object", options->object,
                  "Name of the solid object to mesh (as --solid; default: the first solid)");
  cmd->add_option("--resolution", options->resolution,
                  "Grid cell edge [m] (default: the solid's largest side / 80; platform: 3.9 mm)");
  cmd->add_option(
      "--tets", options->tets,
      "Tetrahedralize: tetgen (of the surface mesh) or cgal (Mesh_3 from the function)");
  cmd->add_option("--quality", options->quality,
                  "Radius-edge bound for --tets (default 2; > 1; 0: none for tetgen, 3 for cgal)");
  cmd->add_option("--max-volume", options->max_volume,
                  "Largest tet volume [m^3] for --tets (default 0: unbounded)");
  cmd->add_option("--smooth-tets", options->smooth_tets,
                  "With --tets tetgen: move the interior vertices of the tets with a dihedral "
                  "angle under this [deg] to where the smallest dihedral angle around them is "
                  "largest; the surface and the tets' count stay (default 0: off)");
  cmd->add_flag("--sharp", options->sharp,
                "Sharpen features: move vertices onto the solid's creases and corners and flip "
                "edges along them (on the tetrahedra route, or on the lattice with --mesher "
                "lattice, which also inserts a vertex at each corner)");
  cmd->add_option("--sliver-angle", options->sliver_angle,
                  "With --sharp: repair the triangles under this angle [deg] that sharpening "
                  "leaves along creases, by collapses, flips and moves that keep the creases, "
                  "then those left by the same allowing up to 0.2 cells of distance to the "
                  "surface (default 10; 0: off)");
  cmd->add_option("--snap-cells", options->snap_cells,
                  "Clean-up: grid values within this fraction of a cell of zero count as zero, "
                  "so no triangle of a smooth surface is sharper than about 10 deg (in [0, 0.25]; "
                  "default 0.2; 0: off, the mesh of before 2026-12-05)");
  cmd->add_option("--flat-cells", options->flat_cells,
                  "Clean-up, last: collapse the edges shorter than this fraction of a cell whose "
                  "vertex lies in a flat fan, so flat faces get as few triangles wherever the "
                  "grid crosses them (in [0, 1]; default 0: off; 0.5 evens the platform's triangle "
                  "counts across cells)");
  cmd->add_option("--mesher", options->mesher,
                  "Surface route: lattice (default; no clean-up, fast) or tetrahedra (marching "
                  "tetrahedra and a clean-up pass; the default with --sharp, --raw-surface, "
                  "--snap-cells or --flat-cells)");
  cmd->add_option("--lattice-snap", options->lattice_snap,
                  "Lattice: a lattice vertex whose nearest crossing lies within this fraction of "
                  "its edge moves onto the surface (in [0, 0.45]; default 0.35; 0: none moves)");
  cmd->add_flag("--raw-surface", options->raw_surface,
                "Skip the surface clean-up pass (raw marching tetrahedra, for comparison)");
  cmd->add_option("--max-cells", options->max_cells,
                  "Largest meshing grid, cells (default 134217728 = 2^27; at most 2^30)");
  cmd->add_option(
      "--max-memory", options->max_memory,
      "Largest estimated peak memory of the surface meshing, bytes (default 2147483648 = 2 GiB)");
  cmd->add_option("--max-work", options->max_work,
                  "Largest estimated work of the surface meshing, tape instructions (default 2e11, "
                  "about a minute)");
  cmd->add_flag("--progress", options->progress,
                "Show progress on stderr even when it is not a terminal");
  cmd->callback([options, cmd]() {
    options->sliver_angle_given = cmd->count("--sliver-angle") > 0;
    options->snap_cells_given = cmd->count("--snap-cells") > 0;
    options->flat_cells_given = cmd->count("--flat-cells") > 0;
    options->lattice_snap_given = cmd->count("--lattice-snap") > 0;
    try {
      RunMesh(*options);
    } catch (const InputError&) {
      throw;
    } catch (const MeshInterrupted&) {
      Interrupted();
    } catch (const MeshingCancelled&) {
      Interrupted();
    } catch (const TetMeshingCancelled&) {
      Interrupted();
    } catch (const CgalMeshCancelled&) {
      Interrupted();
    } catch (const SurfaceDefectError& e) {
      std::cout.flush();
      throw InputError(std::string("the surface cannot be tetrahedralized: ") + e.what() +
                       " (try another --resolution)");
    } catch (const TetgenError& e) {
      std::cout.flush();
      throw InputError(std::string("TetGen failed: ") + e.what() +
                       " (try another --resolution or --quality)");
    } catch (const CgalMeshError& e) {
      std::cout.flush();
      throw InputError(std::string("CGAL meshing failed: ") + e.what() +
                       " (try another --resolution or --quality)");
    } catch (const MeshFileError& e) {
      std::cout.flush();
      throw InputError(e.what());
    } catch (const std::invalid_argument& e) {
      std::cout.flush();
      throw InputError(e.what());
    } catch (const std::runtime_error& e) {
      std::cout.flush();
      throw InputError(e.what());
    }
  });
}

}  // namespace spidarcad::app
