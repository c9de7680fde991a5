// The sections of `spidarcad report`, one function each (listed in ReportSections(),
// report_command.cc). Each runs its sweep in-process, writes its figures and tables through
// the context and sets its headline.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include "cli/report_common.h"

namespace spidarcad::app {

// Forward kinematics: methods × noise, time against position and rotation error
// (report_fk.cc).
void ReportForwardKinematics(ReportContext& ctx);
// Tension distribution: cold/warm × saturated/feasible, time against the gap to the optimum
// and the share of the commanded wrench displayed (report_tension.cc).
void ReportTensions(ReportContext& ctx);
// FK conditioning: maps of the error gain and of FK's refusals on slices of the workspace,
// the interior singular set (report_singular.cc).
void ReportSingularSet(ReportContext& ctx);
// Calibration: pose error against the number of calibration poses (report_calibration.cc).
void ReportCalibration(ReportContext& ctx);
// Workspace: deliverable force and moment maps on slices through the frame
// (report_workspace.cc).
void ReportWorkspace(ReportContext& ctx);
// Implicit evaluation: time against tree size, full and pruned tapes (report_implicit.cc).
void ReportImplicit(ReportContext& ctx);
// Surface meshing: time against two-sided Hausdorff error, plain and sharpened
// (report_mesh.cc).
void ReportSurfaceMeshing(ReportContext& ctx);
// Tetrahedral meshing: TetGen against CGAL (report_mesh.cc).
void ReportTetMeshing(ReportContext& ctx);
// FE: precompute and tick time against tip error, float/double columns, borrowed columns,
// condensed against full solve (report_fe.cc).
void ReportFe(ReportContext& ctx);
// Edit to first correct felt force: slab re-meshing and the substructured solver against a full
// recompute, for edits of growing size (report_edit.cc, cli/edit_to_force.h).
void ReportEditToForce(ReportContext& ctx);
// Haptic tick per scene kind: distributions (report_tick.cc).
void ReportTick(ReportContext& ctx);
// Sculpting: update time against touched vertices, volume error (report_sculpt.cc).
void ReportSculpt(ReportContext& ctx);
// Hard cases: every Hard<Thing> test of the build tree's test executables, its measured figure
// and pass line (report_hard.cc).
void ReportHardCases(ReportContext& ctx);

}  // namespace spidarcad::app
