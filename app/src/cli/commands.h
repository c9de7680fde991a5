// Registration of the spidarcad subcommands. Each Register* adds one subcommand to the CLI11
// app; its callback runs the command and returns through CommandExit.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <CLI/CLI.hpp>

namespace spidarcad::app {

// `spidarcad fk --batch`: forward kinematics, lengths in, poses out (cli/fk_command.cc).
void RegisterFkCommand(CLI::App& app);
// `spidarcad ik --batch`: inverse kinematics, poses in, lengths out (cli/fk_command.cc).
void RegisterIkCommand(CLI::App& app);
// `spidarcad tension --batch`: tension distribution (cli/tension_command.cc).
void RegisterTensionCommand(CLI::App& app);
// `spidarcad workspace`: deliverable force across the workspace (cli/workspace_command.cc).
void RegisterWorkspaceCommand(CLI::App& app);
// `spidarcad calibrate --simulated`: calibration of string parameters (cli/calibrate_command.cc).
void RegisterCalibrateCommand(CLI::App& app);

// `spidarcad mesh`: implicit scene -> surface / tetrahedral mesh files (cli/mesh_command.cc).
void RegisterMeshCommand(CLI::App& app);
// `spidarcad fem`: static FE solve of a meshed scene or mesh file (cli/fem_command.cc).
void RegisterFemCommand(CLI::App& app);
// `spidarcad felt`: felt stiffness of an FE part against the cell size (cli/felt_command.cc).
void RegisterFeltCommand(CLI::App& app);
// `spidarcad run`: headless haptic session on a scripted trajectory (cli/run_command.cc).
void RegisterRunCommand(CLI::App& app);
// `spidarcad trajectory KIND --out T.csv`: scripted grip trajectories (cli/trajectory_command.cc).
void RegisterTrajectoryCommand(CLI::App& app);
// `spidarcad device list`: USB SPIDAR-G controllers (cli/device_command.cc).
void RegisterDeviceCommand(CLI::App& app);
// `spidarcad report --out DIR`: the performance report (cli/report_command.cc).
void RegisterReportCommand(CLI::App& app);

// `spidarcad info FILE`: the objects of a document, one line each (cli/info_command.cc).
void RegisterInfoCommand(CLI::App& app);
// `spidarcad import FILE --into DOC`: a mesh file into a document (cli/import_command.cc).
void RegisterImportCommand(CLI::App& app);

// `spidarcad __worker --parent PID` (hidden, not a CLI11 subcommand): TetGen, CGAL or CHOLMOD
// in a child process for a cancellable window job (scene/worker_process.h, cli/worker_command.cc).
// main() calls it when argv[1] is the command; returns the exit status.
int RunWorkerCommand(int argc, char** argv);

}  // namespace spidarcad::app
