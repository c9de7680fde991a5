// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// `spidarcad report`, section "edit": edit to first correct felt force on the platform through
// slab re-meshing and the substructured solver, against a full recompute (cli/edit_to_force.h;
// the same measurement as build/bench/app_fem_substructure_bench).
#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "cli/edit_to_force.h"
#include "cli/report_sections.h"
#include "doc/assets.h"
#include "scene/fe_setup.h"

namespace spidarcad::app {

void ReportEditToForce(ReportContext& ctx) {
  const std::string scene = AssetPath("scenes/platform.json");
  struct Case {
    int order;
    double cell;
    int edits;
    EditToForceMeshing meshing;
  };
  // P1 at 6 mm with every edit; P2 at 10 mm (the case) with the two local ones; each
  // also with the lattice route's surfaces; P1 at 5 mm (the 100k-tet linear part) as FE
  // mode meshes it (snapped surfaces, the bracket slab in kFeStrips strips); and P2 at 10 mm with
  // its flat faces coarsened as FE mode meshes a solid for quadratic elements
  // (kQuadraticFlatCells). The last two give the headline.
  EditToForceMeshing lattice, fe_mode_p1, fe_mode_p2;
  lattice.lattice = true;
  fe_mode_p1.strips = kFeStrips;
  fe_mode_p1.snap_cells = modeling::kProductSnapCells;
  fe_mode_p2.flat_cells = kQuadraticFlatCells;
  const std::vector<Case> plan =
      ctx.quick() ? std::vector<Case>{{1, 0.006, 2, {}}, {1, 0.006, 2, lattice}}
                  : std::vector<Case>{{1, 0.006, 4, {}},         {2, 0.01, 2, {}},
                                      {1, 0.006, 4, lattice},    {2, 0.01, 2, lattice},
                                      {1, 0.005, 2, fe_mode_p1}, {2, 0.01, 2, fe_mode_p2}};
  std::vector<EditToForceCase> cases;
  for (std::size_t k = 0; k < plan.size(); ++k) {
    cases.push_back(
        MeasureEditToForce(scene, plan[k].order, plan[k].cell, 4, plan[k].edits, plan[k].meshing));
    ctx.Progress(double(k + 1) / plan.size());
  }
  ctx.md() << "After an edit of assets/scenes/platform.json, the time to the first correct felt "
              "force: the part is meshed in four slabs across x (a slab whose input did not "
              "change keeps its tets), each slab's interior is factored and condensed onto the "
              "planes between slabs (an unchanged slab keeps its factor), the planes' system is "
              "factored plane by plane from both ends and twisted at the edit (the planes on "
              "either side of the changed ones are kept; \"S from both ends\" is the completion "
              "of the fresh model's factor that allows it, done before the edits, as FE mode does "
              "in the background), and "
              "the felt patch's compliance (8 nodes, 24 columns) is solved from its slab and the "
              "planes. \"Full recompute\" is what FE mode does today: surface, one-piece TetGen, "
              "one sparse Cholesky factor, the same columns. The error is the patch block's "
              "relative difference from that monolithic solve of the same new mesh. Edits: the "
              "load holes widened (in the last slab, beside the patch), the bolt holes widened "
              "(the first slab, at the wall), the gusset shortened (three slabs), the plate "
              "thickened (every slab). Times in s, wall clock (CPU: the process's, both cores). "
              "During each update a 1 kHz contact tick runs on the old model, as FE mode keeps "
              "it until the new one is ready. Cases named \"lattice\" make every surface (the "
              "full recompute's too) by the lattice route instead of marching tetrahedra "
              "(SlabMeshOptions::lattice, `spidarcad fem --mesher lattice`). The case named "
              "\"flat 0.5\" makes them by marching tetrahedra with the flat fans coarsened "
              "(edges under half a cell collapsed where the surface is planar, `spidarcad fem "
              "--flat-cells 0.5`), as FE mode meshes a solid for quadratic elements (there on "
              "the snapped surface): at 10 mm the grid cuts the platform's plate faces without "
              "making needles, so the clean-up collapses nothing there and they keep about "
              "three times the triangles they get at 10.2 mm, and TetGen twice the tets; at 10 "
              "mm the lattice route's many vertices snapped onto those faces give it fewer "
              "tets (docs/design/2026-12-06-flat-faces.md, "
              "docs/design/2026-12-06-quadratic-flat-faces.md). The case named \"3 strips, snap "
              "0.2\" meshes as FE mode meshes a solid for linear elements: every surface snapped "
              "(modeling::kProductSnapCells) and the bracket's slab, about twice the mean share "
              "of the surface, cut into three strips across y, each a block of the solver, so an "
              "edit of the bolt holes re-meshes and refactors the strips that hold them, not the "
              "whole slab (docs/design/2026-12-07-bracket-strips.md); at 5 mm it is the issue's "
              "100k-tet linear part.\n\n"
           << EditToForceTables(cases) << "\n";
  std::vector<std::vector<std::string>> csv;
  Chart chart{"Edit to first correct felt force", "tets re-meshed", "time [s]", false, true, {}};
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const EditToForceCase& c = cases[k];
    ChartSeries route{c.name + ": slabs", {}, {}, static_cast<int>(k), true, false, 0};
    ChartSeries full{c.name + ": full recompute", {}, {}, static_cast<int>(k), true, true, 0};
    double lo = std::numeric_limits<double>::infinity(), hi = 0;
    for (const EditToForceRow& e : c.edits) {
      csv.push_back({std::to_string(c.order), Sig(1e3 * c.cell, 3), std::to_string(c.num_slabs),
                     c.lattice            ? "lattice"
                     : c.flat_cells > 0.0 ? "tetrahedra flat"
                     : c.snap_cells > 0.0 ? "tetrahedra snapped"
                                          : "tetrahedra",
                     e.edit, std::to_string(c.strips), std::to_string(e.remeshed_tets),
                     std::to_string(e.remeshed), std::to_string(e.planes_refactored),
                     Sig(e.total_wall, 4), Sig(e.total_cpu, 4), Sig(c.full_wall(), 4),
                     Sig(e.error, 3), Sig(e.tick_cpu_p999, 3), Sig(e.tick_late_p999, 4)});
      route.x.push_back(double(e.remeshed_tets));
      route.y.push_back(e.total_wall);
      lo = std::min(lo, double(e.remeshed_tets));
      hi = std::max(hi, double(e.remeshed_tets));
    }
    full.x = {lo, hi};
    full.y = {c.full_wall(), c.full_wall()};
    chart.series.push_back(route);
    chart.series.push_back(full);
  }
  ctx.Csv("edit",
          {"order", "cell_mm", "slabs", "surface", "edit", "strips", "tets_remeshed",
           "slabs_remeshed", "planes_refactored", "edit_to_force_s", "edit_to_force_cpu_s",
           "full_recompute_s", "relative_difference", "tick_cpu_p999_us", "tick_late_p999_us"},
          csv);
  ctx.Figure("edit_to_force", {chart},
             "Time from the edited scene to the first correct felt force against the tets the "
             "edit re-meshed (solid), and a full recompute (dashed), per case.",
             900, 560);
  // Headline: the local edit beside the patch in the last case (P2 at 10 mm in the full run).
  const EditToForceCase& last = cases.back();
  double worst_error = 0;
  for (const EditToForceCase& c : cases)
    for (const EditToForceRow& e : c.edits) worst_error = std::max(worst_error, e.error);
  if (!last.edits.empty()) {
    const EditToForceRow& local = last.edits.front();
    std::string second;  // the edit at the clamped end, when it was run
    if (last.edits.size() > 1)
      second = ", " + last.edits[1].edit + " " + Sig(last.edits[1].total_wall, 2) + " s";
    // The 100k-tet linear part, meshed as FE mode meshes it (the case before the last).
    std::string linear;
    if (cases.size() > 1 && cases[cases.size() - 2].strips > 1) {
      const EditToForceCase& p1 = cases[cases.size() - 2];
      linear = "; " + p1.name + " (" + std::to_string(p1.one_piece.tets) + " tets):";
      for (const EditToForceRow& e : p1.edits)
        linear +=
            (&e == &p1.edits.front() ? " " : ", ") + e.edit + " " + Sig(e.total_wall, 2) + " s";
      linear += " (full recompute " + Sig(p1.full_wall(), 2) + " s)";
    }
    ctx.Headline(last.name + ", " + local.edit + ": first correct force " +
                 Sig(local.total_wall, 2) + " s after the edit" + second + " (full recompute " +
                 Sig(last.full_wall(), 2) + " s)" + linear + "; every patch block within " +
                 Sig(worst_error, 2) + " of a monolithic solve");
    ctx.Summary("edit to felt force " + Sig(local.total_wall, 2) + " s" + second +
                    ", full recompute " + Sig(last.full_wall(), 2) + " s (" +
                    last.name.substr(0, last.name.find(',')) +
                    (last.lattice            ? ", lattice surface"
                     : last.flat_cells > 0.0 ? ", flat faces coarsened as for FE mode's P2"
                                             : "") +
                    ")",
                "patch compliance within " + Sig(worst_error, 2) + " of a full solve");
  }
}

}  // namespace spidarcad::app
