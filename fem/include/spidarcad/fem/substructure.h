// Substructured static solve: the elements of a mesh are partitioned into blocks (e.g. slabs cut
// by planes); each block's interior is factored on its own and condensed onto its interface, and
// only the small interface system is factored globally. A block whose content is unchanged since
// an earlier solver keeps that solver's factor (shared, not recomputed), so a local edit of the
// mesh re-does one block and the interface system instead of the whole factorisation.
//
// Dofs and signs as StaticSolver (static_solver.h): node v has dofs 3v + axis; free (f) and
// prescribed (c) dofs; K_ff u_f = f_f − K_fc u_c; reactions are forces ON the body (N). The free
// dofs are numbered as StaticSolver numbers them (increasing global dof), so FreeIndex, SolveFree
// and Solve are interchangeable with StaticSolver's and give the same numbers to rounding.
//
// Blocks. Each element has a block label in [0, #blocks). A node is an interface node when
// elements of two or more blocks share it, else it is interior to its one block. With I_b the
// free dofs of block b's interior nodes and Γ the free dofs of the interface nodes, K_ff is
// [K_II (block diagonal) K_IΓ; K_ΓI K_ΓΓ] and
//     S = Σ_b S_b,   S_b = K^b_ΓΓ − K^b_ΓI (K^b_II)⁻¹ K^b_IΓ
// (K^b the stiffness of block b's elements alone). Block b is factored by CHOLMOD with its
// interface dofs ordered last and a shift σ_b I on them, A_b = [K_II K_IΓ; K_ΓI K_ΓΓ + σ_b I] =
// L Lᵀ, so that S_b = L_ΓΓ L_ΓΓᵀ − σ_b I (σ_b = 1e-6 · max diag K^b_ΓΓ: S_b alone is singular for
// a block that floats but for its interface; the shift keeps the factorisation going and
// Cholesky's backward error, ~ε·max A_ii, does not depend on it). S is assembled from the dense
// S_b, its dofs ordered by the lowest, then the highest block sharing them (plane by plane for
// slabs), and within those by the node's position and the axis (what both blocks see alike).
// When S is then a chain (every block's interface dofs in one group of dofs shared by the same
// pair of blocks, or in two consecutive ones: slabs, whose groups are the planes) it is block
// tridiagonal and factored by groups, dense (LAPACK), twisted at one group k: the groups before
// k by the forward factor, eliminated from the first group on,
//     L_{g,g−1} = S_{g,g−1} L_{g−1,g−1}⁻ᵀ,  L_gg L_ggᵀ = S_gg − L_{g,g−1} L_{g,g−1}ᵀ,
// the groups after k by the backward factor, eliminated from the last group back,
//     M_{g,g+1} = S_{g,g+1} B_{g+1,g+1}⁻ᵀ,  B_gg B_ggᵀ = S_gg − M_{g,g+1} M_{g,g+1}ᵀ,
// and k last, T Tᵀ = S_kk − L_{k,k−1} L_{k,k−1}ᵀ − M_{k,k+1} M_{k,k+1}ᵀ (a Cholesky factor of S
// with its groups in the order 0, …, k−1, n−1, …, k+1, k). A solver made without a reuse solver
// twists at the last group (the plain forward factor). Otherwise CHOLMOD factors S. A solve is
//     y_b = K_II⁻¹ f_I,  u_Γ = S⁻¹ (f_Γ − Σ_b K_ΓI y_b),  u_I = K_II⁻¹ (f_I − K_IΓ u_Γ),
// where blocks without load skip the first step, and a solve asked only for some blocks'
// displacements skips the last step of the others (SolveFreeInBlocks: the compliance of nodes in
// one block needs that block's factor and S alone).
//
// Reuse. A block's content is its elements in mesh order, with local node numbers in order of
// first appearance: connectivity, node positions, each element's material, and for each node its
// prescribed axes and whether it is an interface node. Blocks of a `reuse` solver with the same
// content (compared in full, not only by hash) share their factor with the new solver; the rest
// are factored anew. Global node numbers do not enter, so a mesh whose untouched blocks kept their
// elements and nodes bit for bit (in any global numbering) reuses them. Prescribed values and
// loads do not enter (they only change right-hand sides). A chain interface keeps the reuse
// solver's forward factor blocks of its leading groups and its backward factor blocks of its
// trailing groups as long as they are summed from the same blocks' S_b in the same places (so are
// equal bit for bit), and twists at the first group in between: an edit of slab t refactors only
// the planes it touches (t − 1 and t; one plane for the first or the last slab), whichever slab it
// is. Of a plane next to a kept one, an edit that left the coupling block between them as it was
// keeps the coupling (L_{g,g−1} or M_{g,g+1}) and its product with its transpose, held per plane
// (8·#plane dofs² bytes each) for that purpose. The reuse solver needs both of its factors whole
// for this: PrepareReuse completes them (about one factorisation of S; FE mode runs it in the
// background once a model is ready), and a constructor given a reuse solver runs it first if it
// has not run.
//
// Threads. A solver is immutable after construction (but for the cache directory's pending
// writes, which FinishCacheWrites waits for, and PrepareReuse, which writes only what solves do
// not read); solves allocate their own CHOLMOD workspace, so one solver, or two solvers sharing
// blocks, may be solved from several threads at once.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "spidarcad/fem/boundary.h"
#include "spidarcad/fem/free_dof_solver.h"
#include "spidarcad/fem/material.h"
#include "spidarcad/fem/mesh.h"
#include "spidarcad/fem/static_solver.h"
#include "spidarcad/fem/stiffness.h"

namespace spidarcad::fem {

// Figures of one block.
struct BlockStats {
  // Elements and nodes (interior and interface) of the block.
  int num_elements = 0;
  int num_nodes = 0;
  // Free interior dofs (size of K_II) and free interface dofs of the block (size of S_b).
  int num_interior_dofs = 0;
  int num_interface_dofs = 0;
  // Nonzeros of the block's Cholesky factor (CHOLMOD's count; 0 without interior dofs).
  double factor_nonzeros = 0.0;
  // Content hash (FNV-1a 64) of the block (see the file comment).
  std::uint64_t key = 0;
  // True when the factor came from the `reuse` solver, or was loaded from the cache directory
  // (then the times below are those of the solver that factored it).
  bool reused = false;
  bool loaded = false;
  // Wall time of looking the block up in the cache directory (reading, checking, laying out
  // CHOLMOD's factor), s; 0 without a directory or when the reuse solver had it.
  double load_seconds = 0.0;
  // Wall time of the element stiffnesses and local assembly, of the ordering and
  // factorisation, and of forming S_b from the factor, in s.
  double assembly_seconds = 0.0;
  double factor_seconds = 0.0;
  double schur_seconds = 0.0;
};

// Figures of a substructured factorisation.
struct SubstructureStats {
  int num_blocks = 0;
  // Free dofs, and free interface dofs (size of S).
  int num_free = 0;
  int num_interface_dofs = 0;
  // Blocks factored by this solver, blocks whose factor came from the reuse solver, blocks
  // loaded from the cache directory, and blocks written to it (counted by FinishCacheWrites).
  int factored_blocks = 0;
  int reused_blocks = 0;
  int loaded_blocks = 0;
  int saved_blocks = 0;
  // Wall time (s) of looking blocks up in the cache directory, and of writing them there
  // (summed over the writing threads; counted by FinishCacheWrites); and why a block file was
  // refused or not written (each line names the block and the file).
  double cache_read_seconds = 0.0;
  double cache_write_seconds = 0.0;
  std::vector<std::string> cache_notes;
  // Nonzeros of S (both triangles) and of its Cholesky factor.
  long long interface_nonzeros = 0;
  double interface_factor_nonzeros = 0.0;
  // Groups of a chain interface (0 when S is factored by CHOLMOD), and the leading groups whose
  // factor blocks came from the reuse solver (see the file comment).
  int interface_groups = 0;
  int reused_interface_groups = 0;
  // Trailing groups whose backward factor blocks came from the reuse solver, the group the
  // factor is twisted at (see the file comment), and the groups whose dense blocks this solver
  // factored (the twist counted once).
  int reused_trailing_interface_groups = 0;
  int interface_twist = 0;
  int factored_interface_groups = 0;
  // Couplings of refactored groups that came from the reuse solver: to the group before
  // (L_{g,g−1} and L_{g,g−1} L_{g,g−1}ᵀ; S_{g,g−1} and L_{g−1,g−1} unchanged) or to the group
  // after (M_{g,g+1} and its product; S_{g,g+1} and B_{g+1,g+1} unchanged). The twist may count
  // one of each.
  int kept_interface_couplings = 0;
  // Groups whose factor blocks came from the cache directory (and, per group, 1 for those),
  // and groups written to it.
  int loaded_interface_groups = 0;
  std::vector<char> interface_group_loaded;
  int saved_interface_groups = 0;
  // Wall time (s) of the blocks factored here (assembly, factorisation and forming S_b, each
  // summed over them), of assembling and factoring S, and of the whole construction.
  double block_assembly_seconds = 0.0;
  double block_factor_seconds = 0.0;
  double block_schur_seconds = 0.0;
  double interface_seconds = 0.0;
  double wall_seconds = 0.0;
};

// What SubstructuredSolver::PrepareReuse did.
struct InterfacePreparation {
  // Dense groups factored (forward and backward factors together), forward planes written to the
  // cache directory, and the wall time, s.
  int factored_groups = 0;
  int saved_planes = 0;
  double seconds = 0.0;
  // Planes that could not be written, or a group that failed to factor (each names it).
  std::vector<std::string> notes;
};

// Thrown by SubstructuredSolver's constructor when its cancel flag was raised.
class SubstructureCancelled : public std::runtime_error {
 public:
  SubstructureCancelled() : std::runtime_error("substructured factorisation cancelled") {}
};

// Factors a model by blocks of elements and the interface Schur complement; solves like
// StaticSolver.
class SubstructuredSolver final : public FreeDofSolver {
 public:
  // Validates mesh, materials, constraints (CheckModelConstrained, as StaticSolver) and
  // `element_block` (#T labels, each >= 0; #blocks = max + 1), then factors every block whose
  // content differs from all blocks of `reuse` (may be null; must outlive nothing: shared
  // factors are reference counted) and the interface system. Throws std::invalid_argument on bad
  // input (naming the element or the label). A factorisation failure (a block interior or S not
  // positive definite) is reported through factor_status(), naming the block, not thrown.
  // With a `cache_directory`, a block the reuse solver does not have is looked for there
  // (<16 hex digits of its content key>.block: the content, K^b, the order, S_b and the values
  // of CHOLMOD's factor of K^b_II, checked by a checksum, the content compared in full and the
  // factor's layout against CHOLMOD's analysis; a file that fails any check is ignored and noted in
  // stats().cache_notes), and a block factored here is written there, one file after the
  // other on a thread of the solver's own, each as soon as its block is factored (8 bytes per
  // nonzero of L_II and of S_b's lower triangle: hundreds of megabytes for a large block).
  // FinishCacheWrites() waits for the writes. Blocks are read from it several at a time. A
  // chain interface keeps its planes' factor blocks there too (<key>.plane): a plane whose
  // owners, and those of the planes before it, are those of the file (blocks by content key)
  // is read instead of factored. When `cancel` (may be null) is raised, the constructor throws
  // SubstructureCancelled before the next block it would factor and before the interface: a
  // cancel waits for at most one block's factorisation (CHOLMOD cannot be interrupted); the
  // block files already queued for the cache directory are finished first.
  // `block_place` (empty, or one entry >= 0 per block): the place of each block in the interface
  // chain, for blocks that are strips of one slab (modeling::SlabCut::strip_planes), which share
  // their slab's place. Empty: each block is its own place. Γ's groups are then the dofs shared
  // by the same lowest and highest place; those shared within one place (the strip planes) join
  // the next place's group (the previous one's, after the last place). Slabs with strips stay a
  // chain: an edit of a strip refactors its slab's planes, not all of S.
  SubstructuredSolver(const TetMesh& mesh, const MaterialTable& materials,
                      const BoundaryConditions& bcs, const Eigen::VectorXi& element_block,
                      const SubstructuredSolver* reuse = nullptr,
                      const std::filesystem::path& cache_directory = {},
                      const std::atomic<bool>* cancel = nullptr,
                      const std::vector<int>& block_place = {});
  ~SubstructuredSolver() override;
  SubstructuredSolver(const SubstructuredSolver&) = delete;
  SubstructuredSolver& operator=(const SubstructuredSolver&) = delete;

  // Waits for the block files still being written to the cache directory and counts them in
  // stats() (saved_blocks, cache_write_seconds, and a note for each write that failed: not
  // thrown). The destructor waits too. Not to be called while another thread uses the solver.
  const SubstructureStats& FinishCacheWrites();

  // Completes the chain interface's forward and backward factors (see the file comment), which
  // a solver that reuses this one needs to keep the planes on both sides of its edit, and writes
  // the forward planes it factored to the cache directory given at construction. Runs once (a
  // second call, or a call from a solver built with this one as `reuse`, waits for the first and
  // returns its figures); about the cost of factoring S once. Safe to run while other threads
  // solve with this solver (the solves read none of what it writes); not while FinishCacheWrites
  // runs. Does nothing for a non-chain interface or a failed factorisation.
  const InterfacePreparation& PrepareReuse() const;

  // Status of the factorisation (blocks and S).
  const SolveStatus& factor_status() const override { return factor_status_; }
  // Figures of the factorisation, and of block b.
  const SubstructureStats& stats() const { return stats_; }
  const BlockStats& block_stats(int b) const;

  // Displacement and reactions under the loads and prescribed displacements of the
  // BoundaryConditions given at construction (as StaticSolver::Solve).
  StaticSolution Solve() const override;
  // Solves K_ff X = B for free-dof right-hand sides B (#free by m); X is resized. The status
  // holds the normwise backward error ||B − K_ff X|| / (||K_ff|| ||X|| + ||B||) (Frobenius;
  // ||K_ff|| is bounded below by (Σ_b ||K^b_ff||²)^½, so the figure is an upper bound), converged
  // below StaticSolver::kResidualTolerance.
  SolveStatus SolveFree(const Eigen::MatrixXd& rhs, Eigen::MatrixXd* x) const override;
  // As SolveFree, but X is computed only at the free dofs of the nodes of `blocks` (interior
  // and interface) and of every interface node; the other rows of X are zero. Blocks of B with
  // no load are skipped too, so a right-hand side on the nodes of block t asked for block t costs
  // two solves with block t's factor and one with S, whatever the number of blocks. The status
  // carries no residual (residual = 0; converged when the factorisation was). Throws
  // std::invalid_argument for a block index out of range.
  SolveStatus SolveFreeInBlocks(const Eigen::MatrixXd& rhs, const std::vector<int>& blocks,
                                Eigen::MatrixXd* x) const;
  // Row groups (FreeDofSolver): the blocks; an interface node is in group −1.
  int num_row_groups() const override { return num_blocks(); }
  int RowGroupOfNode(int v) const override { return BlockOfNode(v); }
  SolveStatus SolveFreeInGroups(const Eigen::MatrixXd& rhs, const std::vector<int>& groups,
                                Eigen::MatrixXd* x) const override {
    return SolveFreeInBlocks(rhs, groups, x);
  }
  // The other blocks' back-substitution from the interface rows X already holds (read, not
  // solved again), then SolveFree's residual check: X equals SolveFree's bit for bit.
  SolveStatus CompleteSolveFree(const Eigen::MatrixXd& rhs, const std::vector<int>& groups,
                                Eigen::MatrixXd* x) const override;

  // Index of global dof d (3v + axis) among the free dofs, or −1 if it is prescribed.
  int FreeIndex(int dof) const override { return free_index_[dof]; }
  // Global dof of free index i.
  int FreeDof(int i) const { return free_dofs_[i]; }
  // Number of free dofs.
  int num_free() const override { return static_cast<int>(free_dofs_.size()); }
  // Number of blocks.
  int num_blocks() const { return stats_.num_blocks; }
  // Block of node v when it is interior to one block; −1 for an interface node or a node in no
  // element.
  int BlockOfNode(int v) const { return node_block_[v] < 0 ? -1 : node_block_[v]; }
  // The model's boundary conditions.
  const BoundaryConditions& bcs() const override { return bcs_; }
  // K u for a full displacement u (3·#V), the stiffness applied block by block (no global K is
  // ever assembled), 3·#V, N.
  Eigen::VectorXd MultiplyStiffness(const Eigen::VectorXd& u) const;

 private:
  struct BlockFactor;
  struct Block;
  struct Interface;
  // K_ff X for free-dof vectors (#free by m).
  Eigen::MatrixXd MultiplyFree(const Eigen::MatrixXd& x) const;
  SolveStatus SolveImpl(const Eigen::MatrixXd& rhs, const std::vector<char>* wanted,
                        Eigen::MatrixXd* x) const;
  // u_I of block b from the right-hand sides and the interface rows of X, into X; false when
  // CHOLMOD's solve failed.
  bool BackSubstitute(int b, const Eigen::MatrixXd& rhs, Eigen::MatrixXd* x) const;
  // The residual check of SolveFree on a solved X.
  SolveStatus CheckResidual(const Eigen::MatrixXd& rhs, const Eigen::MatrixXd& x) const;
  // Blocks listed (range-checked) as a flag per block.
  std::vector<char> WantedBlocks(const char* who, const std::vector<int>& blocks) const;
  // Factors S as a chain of groups (returns false, doing nothing, when S is not one) or by
  // CHOLMOD; owners[p]: (block, local index) of the blocks holding Γ position p; order: Γ
  // positions by the pair of blocks sharing them.
  bool FactorInterfaceAsChain(const TetMesh& mesh,
                              const std::vector<std::vector<std::pair<int, int>>>& owners,
                              const std::vector<int>& order,
                              const std::vector<std::pair<int, int>>& pair_of,
                              const SubstructuredSolver* reuse,
                              const std::filesystem::path& cache_directory);
  // Interface S's blocks of group g summed from the blocks' S_b: S_gg, or S_{g,g−1} (rows in g).
  Eigen::MatrixXd InterfaceBlock(int g, bool coupling_to_previous) const;
  // L_{g,g−1} and its gram for g > 0 (from L_{g−1,g−1}); M_{g,g+1} and its gram for g below the
  // last (from B_{g+1,g+1}); each kept from `old` (may be null) when the record says it is the
  // same. Returns whether it was kept.
  bool ForwardCoupling(int g, const Interface* old) const;
  bool BackwardCoupling(int g, const Interface* old) const;
  // Cholesky factor (lower) of S_gg minus the grams given (each may be null); null on a zero
  // pivot, whose Γ position is then in *failed.
  std::shared_ptr<const Eigen::MatrixXd> FactorGroup(int g, const Eigen::MatrixXd* gram,
                                                     const Eigen::MatrixXd* other_gram,
                                                     int* failed) const;
  void FactorInterfaceWithCholmod(const TetMesh& mesh,
                                  const std::vector<std::vector<std::pair<int, int>>>& owners,
                                  std::vector<int>& order);
  // Sets factor_status_ for a zero pivot of S at Γ position p.
  void InterfaceFailure(const TetMesh& mesh, int p);

  BoundaryConditions bcs_;
  std::vector<Block> blocks_;
  struct CacheWriter;
  std::unique_ptr<CacheWriter> writer_;  // block files being written (FinishCacheWrites)
  std::unique_ptr<Interface> interface_;
  std::vector<int> free_index_, free_dofs_, node_block_;
  std::vector<int> interface_index_;  // per free index: position in Γ, or −1
  std::vector<int> interface_free_;   // per Γ position: free index
  SolveStatus factor_status_;
  SubstructureStats stats_;
  double k_norm_ = 0.0;  // lower bound of ||K_ff||_F
};

// Element blocks of slabs along `axis` (0, 1, 2 = x, y, z): element e goes to the number of
// planes at or below its corner centroid's coordinate, so `planes` (sorted, m) cut the mesh into
// planes.size() + 1 slabs. Throws std::invalid_argument for a bad axis or unsorted planes.
Eigen::VectorXi SlabBlocks(const TetMesh& mesh, int axis, const std::vector<double>& planes);

// `count` − 1 planes that cut the nodes' extent along `axis` into `count` slabs of equal width.
std::vector<double> EvenPlanes(const TetMesh& mesh, int axis, int count);

}  // namespace spidarcad::fem
