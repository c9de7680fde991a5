// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// TetGen (and CGAL Mesh_3) in a child process, so that a window job can be cancelled while the
// library runs (issue 15: within 0.5 s). TetGen cannot be interrupted and a thread cannot be killed
// safely (an abandoned TetGen thread was tried and withdrawn: docs/limits.md), but a process can:
// the parent sends the surface and settings to a child running this program's hidden
// `__tetgen-worker` subcommand over a socket, the child runs modeling::TetrahedralizeSurface and
// sends back the mesh and its statistics (raw doubles: bit for bit what the in-process call gives),
// and on cancel the parent kills the child (SIGKILL) and reaps it. A child that crashes, aborts or
// is killed by someone else is a TetgenError naming the signal; the parent keeps running.
//
// The child path is taken only when a cancel flag is given and a worker program is set
// (SetTetgenWorkerProgram: main() sets "/proc/self/exe"); otherwise the call runs in-process as
// before (the CLI, tests, benches). Nothing is written to disk.
#pragma once

#include <Eigen/Geometry>
#include <string>

#include "spidarcad/modeling/cgal_mesher.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/implicit_node.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::app {

// The hidden subcommand's name (argv[1] of the child).
inline constexpr const char* kTetgenWorkerCommand = "__tetgen-worker";

// The program run as the worker ("" = none: TetrahedralizeCancellable runs in-process). It must
// dispatch kTetgenWorkerCommand to RunTetgenWorker (spidarcad's main does). Thread safe.
void SetTetgenWorkerProgram(const std::string& path);
std::string TetgenWorkerProgram();

// modeling::TetrahedralizeSurface with the same arguments, results and exceptions; with
// settings.cancel set and a worker program, it runs in a child process that a raised flag kills
// within a few milliseconds (TetMeshingCancelled). settings.progress is called on this thread.
// A child that dies of a signal or exits without an answer throws modeling::TetgenError
// (code 0) naming it, e.g. "TetGen worker process was killed by signal 9 (SIGKILL)"; a worker
// that cannot be started throws std::runtime_error naming the program.
modeling::TetMesh TetrahedralizeCancellable(const modeling::TriangleMesh& surface,
                                            const modeling::TetMeshSettings& settings,
                                            modeling::TetMeshStats* stats = nullptr);

// modeling::MeshImplicitWithCgal(compiled, bounds, settings, stats), where `compiled` is
// CompiledSolid::Compile(root): with settings.cancel set and a worker program, CGAL Mesh_3 runs in
// a child process (the tree goes as scene JSON, NodeToJson, and is compiled there) that a raised
// flag kills within a few milliseconds (CgalMeshCancelled); a child that dies without an answer
// throws modeling::CgalMeshError naming the signal ("CGAL worker process was killed by ...").
modeling::TetMesh MeshWithCgalCancellable(const modeling::ImplicitNode& root,
                                          const modeling::CompiledSolid& compiled,
                                          const Eigen::AlignedBox3d& bounds,
                                          const modeling::CgalMeshSettings& settings,
                                          modeling::CgalMeshStats* stats = nullptr);

// The child's side: reads one request from fd `in`, runs TetGen or CGAL, writes the answer to fd
// `out` (may equal `in`: a socket). Returns the exit status (0 when an answer, result or error, was
// sent; 2 for a malformed request).
int RunTetgenWorker(int in, int out);

}  // namespace spidarcad::app
