// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Library calls that poll nothing, in a child process, so that a window job can be cancelled
// while they run (issue 15: within 0.5 s): TetGen, CGAL Mesh_3 and the CHOLMOD factorisation of
// an FE precompute. They cannot be interrupted and a thread cannot be killed safely (abandoned
// threads were tried and withdrawn: docs/limits.md), but a process can: the parent starts this
// program again with the hidden `__worker` subcommand, sends the input and settings over a
// socket, the child runs the library call and sends back the result (raw doubles and ints: bit
// for bit what the in-process call gives), and on cancel the parent kills the child (SIGKILL) and
// reaps it. A child that crashes, aborts or is killed by someone else is an error naming the
// signal; the parent keeps running.
//
// CHOLMOD's input and output are large (K_ff and its factor: hundreds of MB for a fine model),
// so they do not go through the socket: the parent writes K_ff into an anonymous memory file
// (memfd_create: memory, never on disk) that the child gets as its fd kSharedFd, the child
// writes the factor's flat form (fem::CholeskyFactor::WriteFlat) over it, and the parent
// rebuilds the factor from it (ReadFlat), one copy, polling the cancel flag between chunks.
//
// The child path is taken only when a cancel flag is given and a worker program is set
// (SetWorkerProgram: main() sets "/proc/self/exe"); otherwise the call runs in-process as
// before (the CLI, tests, benches). Nothing is written to disk.
#pragma once

#include <Eigen/Geometry>
#include <atomic>
#include <memory>
#include <stdexcept>
#include <string>

#include "spidarcad/fem/cholesky_factor.h"
#include "spidarcad/modeling/cgal_mesher.h"
#include "spidarcad/modeling/implicit_evaluator.h"
#include "spidarcad/modeling/implicit_node.h"
#include "spidarcad/modeling/surface_mesher.h"
#include "spidarcad/modeling/tet_mesh.h"
#include "spidarcad/modeling/tetgen_mesher.h"

namespace spidarcad::app {

// The hidden subcommand's name (argv[1] of the child).
inline constexpr const char* kWorkerCommand = "__worker";
// The child's file descriptor of the shared memory of a factor request.
inline constexpr int kSharedFd = 3;

// The program run as the worker ("" = none: TetrahedralizeCancellable runs in-process). It must
// dispatch kWorkerCommand to RunWorker (spidarcad's main does). Thread safe.
void SetWorkerProgram(const std::string& path);
std::string WorkerProgram();

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

// Thrown by FactorizeCancellable when its cancel flag was raised; the child was killed.
class FactorizationCancelled : public std::runtime_error {
 public:
  FactorizationCancelled() : std::runtime_error("factorisation cancelled") {}
};

// fem::CholeskyFactor::Compute(k_ff) (k_ff n by n, compressed, both triangles stored; the lower
// one is read): with `cancel` set and a worker program, CHOLMOD runs in a child process that a
// raised flag kills within a few milliseconds (FactorizationCancelled), and the factor comes
// back through shared memory, bit for bit the in-process one. A child that dies without an
// answer throws std::runtime_error naming the signal ("CHOLMOD worker process was killed by
// signal 9 (SIGKILL)"), as does one that runs out of memory or sends a malformed factor; a
// worker that cannot be started throws std::runtime_error naming the program.
std::unique_ptr<fem::CholeskyFactor> FactorizeCancellable(const fem::SparseMatrixd& k_ff,
                                                          const std::atomic<bool>* cancel);

// The child's side: reads one request from fd `in`, runs TetGen, CGAL or CHOLMOD (whose input
// and output go through the memory file `shared`, −1: none), writes the answer to fd `out` (may
// equal `in`: a socket). Returns the exit status (0 when an answer, result or error, was sent; 2
// for a malformed request).
int RunWorker(int in, int out, int shared = -1);

}  // namespace spidarcad::app
