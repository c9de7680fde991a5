// Lazy compliance columns computed ahead of the tool, with a nearest-ready fallback, a memory
// bound, and a real-time contact solve that reads them.
//
// A full surface condensation of a large model is gigabytes of dense data; most of it is never
// touched. ColumnCache computes the three compliance columns of a candidate node (the response,
// observed at every output node, to a unit force on that node along x, y, z; the same columns
// as Compliance) only when the tool comes near: a background worker thread solves blocks of
// columns with the StaticSolver's factor, nearest the focus point first, and publishes each
// column to readers with a release store once it is fully written. Nodes outside the requested
// radius are never condensed.
//
// Threads. The worker is the only user of a StaticSolver while it runs (its CHOLMOD solve is
// not re-entrant: do not call the solver from elsewhere meanwhile, or Stop() first; a
// SubstructuredSolver's solves are re-entrant). The focus
// (RequestNear) is a seqlock written by ONE producer (the app or the haptic thread, not both),
// read by the worker. Readers (the haptic thread) use atomics only: IsReady, ReadyNodeNearest,
// Pin/Unpin and the reads of a pinned column never lock, allocate or throw.
//
// Memory. Columns live in slots of 9·#output values (float or double); at most
// floor(memory_budget_bytes / bytes per node) slots exist, allocated when first needed. When the
// slots are full the worker evicts the ready node farthest from the focus, and only for a node
// nearer the focus than it. A pinned column (in use by a contact) is never evicted: the reader
// increments the slot's pin count and then re-checks that the node still owns the slot; the
// worker unpublishes a node and then re-checks that its pin count is zero (both sequentially
// consistent), so either the reader sees the eviction or the worker sees the pin.
//
// Fallback. Until node b's column is ready the contact solve uses the column of the nearest
// ready node r, translated to b: the response at node a to a force on b is taken as the
// response at node m to a force on r, m being the candidate nearest p_a + (p_r − p_b) among r
// and r's neighbour list (so Ĝ_bb = G_rr, and two missing contacts that share a substitute keep
// their relative offset; of the two estimates of a block between two missing contacts the one
// whose translated point lands nearer a node is used). Ĝ_cc can still fail to be positive
// definite for unlucky substitutes: Add then refuses the node (kNotPositiveDefinite) and the
// caller tries again on a later tick, when more columns are ready. Every block of a substituted
// contact comes from its substitute's column (mixing in exact blocks with ready contacts made
// Ĝ_cc indefinite near a clamp, where compliance changes fast). For the display
// (OutputDisplacement) the column is shifted more cheaply: G(:, r) with the row blocks of b and
// r swapped, so the peak of the response moves with the load. The force error of the
// substitution grows with |p_b − p_r| (figures in the README, test in column_cache_test).
//
// Float storage rounds each entry to nearest: |Ĝ_ij − G_ij| <= 2^-24 |G_ij|.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <Eigen/Core>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "spidarcad/fem/bordered_cholesky.h"
#include "spidarcad/fem/free_dof_solver.h"
#include "spidarcad/fem/precompute_cache.h"
#include "spidarcad/fem/static_solver.h"

namespace spidarcad::fem {

// Settings of a ColumnCache.
struct ColumnCacheSettings {
  // Storage of the columns (float halves the memory; see the header comment for its error).
  ColumnPrecision precision = ColumnPrecision::kDouble;
  // Bound on the column storage, in bytes (the baseline and index tables come on top; see
  // ColumnCache::MemoryBytes). At least one node's columns always fit.
  double memory_budget_bytes = 256.0e6;
  // Candidate nodes solved per multi-right-hand-side solve (3 columns each).
  int block_nodes = 16;
  // Candidate nodes of the first block the worker solves (0: block_nodes). A solve's cost grows
  // with its columns, so a smaller first block makes the columns nearest the focus (those a
  // tool already in contact needs) ready sooner after the cache is made.
  int first_block_nodes = 0;
  // Length of the precomputed nearest-candidate list of each candidate (fallback lookup);
  // beyond it ReadyNodeNearest scans the ready slots.
  int neighbours = 16;
  // Start the worker thread at construction (false: call Start() or ComputeNodes()).
  bool start_worker = true;
  // Make the neighbour lists on the worker thread once its first block is published (or
  // ComputeNodes, whichever comes first), not in the constructor: a model is ready
  // sooner (32,500 candidates: 0.07 s). Until then ReadyNodeNearest scans the ready slots and
  // ShiftedCandidate returns r itself.
  bool neighbours_on_worker = false;
  // Near rows first: with a model whose solves give some nodes' rows before the rest (a
  // SubstructuredSolver's blocks, FreeDofSolver::num_row_groups, 2 to 63 of them), each block
  // of columns is first solved only for the groups of the candidates within the focus radius
  // (and the group-free rows, e.g. interface nodes) and published so, then completed. A contact
  // reads rows near the focus only, so it can use the columns that much sooner (P2 platform at
  // 10 mm in 4 slabs: one slab's back-substitution of four, and no residual, before the first
  // force). Rows not computed yet read NaN (see HasColumn); IsReady waits for the whole column.
  bool near_rows_first = false;
  // How often the idle worker looks at the focus, in s.
  double idle_poll_seconds = 1.0e-3;
};

// Counters of a ColumnCache (read at any time; approximate while the worker runs).
struct ColumnCacheStats {
  // Candidate nodes whose columns were computed (3 columns each), including recomputations.
  long computed_nodes = 0;
  // Columns evicted to make room.
  long evictions = 0;
  // Blocks solved, and of those the ones published near rows first (near_rows_first).
  long blocks = 0;
  long near_blocks = 0;
  // Wall time spent in solves and copying, in s.
  double compute_seconds = 0.0;
};

// Lazily computed compliance columns of candidate nodes, observed at output nodes.
class ColumnCache {
 public:
  // Cache of the columns of `candidate_nodes` (mesh indices; each must be an output node)
  // observed at `output_nodes` (mesh indices, e.g. the surface nodes), for the model factored
  // by `solver` (which must outlive the cache). `nodes` are the mesh positions (#V by 3, m),
  // used to order the work and to find substitutes. Computes the baseline (one solve) and the
  // neighbour lists, then starts the worker unless settings say otherwise. Create it from an
  // ordinary thread (threads inherit SCHED_FIFO; the worker also resets itself to SCHED_OTHER).
  // Throws std::invalid_argument on bad node lists or settings, std::runtime_error when the
  // solver's factorisation failed.
  ColumnCache(const StaticSolver& solver, const Eigen::MatrixX3d& nodes,
              const std::vector<int>& output_nodes, const std::vector<int>& candidate_nodes,
              const ColumnCacheSettings& settings = {});
  // The same for any factored model (e.g. a SubstructuredSolver, whose solves are re-entrant).
  ColumnCache(const FreeDofSolver& solver, const Eigen::MatrixX3d& nodes,
              const std::vector<int>& output_nodes, const std::vector<int>& candidate_nodes,
              const ColumnCacheSettings& settings = {});
  // Stops and joins the worker.
  ~ColumnCache();
  ColumnCache(const ColumnCache&) = delete;
  ColumnCache& operator=(const ColumnCache&) = delete;

  // --- Worker control (not real-time) ---
  // Starts the background worker (no-op when running).
  void Start();
  // Stops and joins the worker (no-op when stopped); ready columns stay.
  void Stop();
  // True while the worker thread runs.
  bool running() const { return worker_.joinable(); }
  // Pauses the worker after the block it is solving (without waiting for it), or lets it go on.
  // A paused cache counts as idle; its ready columns stay readable. For a model about to be
  // replaced, whose columns would take the cores its successor's precomputation needs.
  void SetPaused(bool paused) {
    paused_.store(paused);
    if (!paused) idle_seq_.store(~0ull);  // not idle until the worker has looked again
  }
  bool paused() const { return paused_.load(); }
  // True once a focus has been requested (RequestNear).
  bool has_focus() const { return focus_seq_.load() != 0; }
  // Waits until the worker has nothing left to do for the latest focus (every candidate in the
  // radius is ready, or the memory is full of nearer columns). Returns false on timeout (s).
  bool WaitUntilIdle(double timeout_seconds) const;
  // Computes the columns of candidate indices `candidates` now on the calling thread (the
  // worker must be stopped; throws std::logic_error otherwise). Nodes that do not fit in the
  // memory bound (all slots pinned or holding listed nodes) are skipped. Returns how many were
  // computed.
  int ComputeNodes(const std::vector<int>& candidates);
  // Evicts every unpinned column (the worker must be stopped; throws std::logic_error).
  void EvictAll();

  // --- Focus (real-time safe, single producer) ---
  // Asks for the columns of the candidates within `radius` (m) of p_W (mesh frame), nearest
  // first. Atomics only.
  void RequestNear(const Eigen::Vector3d& p_W, double radius);

  // --- Readers (real-time safe: atomics only, no allocation) ---
  // Number of candidate nodes, and of output nodes.
  int num_candidates() const { return static_cast<int>(candidate_nodes_.size()); }
  int num_outputs() const { return static_cast<int>(output_nodes_.size()); }
  // Mesh index of candidate b.
  int candidate_node(int b) const { return candidate_nodes_[b]; }
  // Candidate index of mesh node v, or −1.
  int CandidateOfNode(int v) const;
  // Position of candidate b in the output list (its row block).
  int OutputIndexOfCandidate(int b) const { return candidate_row_[b]; }
  // True if candidate b has a prescribed dof (no contact there; never condensed).
  bool IsFixed(int b) const { return fixed_[b] != 0; }
  // True if candidate b's columns are ready, every row (may change at any time unless pinned).
  bool IsReady(int b) const;
  // True if b's columns are published: ready, or (near_rows_first) holding the rows near the
  // focus they were solved for so far, the other rows NaN until complete. A pinned column only
  // gains rows. A contact solve reads only rows of its contacts; a NaN there makes it refuse
  // the node (CachedContactSolver::Add), to be tried again on a later tick.
  bool HasColumn(int b) const { return slot_of_[b].load(std::memory_order_acquire) >= 0; }
  // True if row block a (an output index) of b's published column is computed (b pinned).
  bool RowReady(int a, int b) const;
  // Candidate whose columns to use for b: b itself when published (HasColumn), else the
  // nearest published candidate (neighbour list first, then a scan of the slots); −1 when none.
  int ReadyNodeNearest(int b) const;
  // Candidate nearest p_r + (p_a − p_b) among r and r's neighbour list: the node whose
  // response to a force on r stands for a's response to a force on b (translation). The
  // distance from that point to the node found goes to *mismatch (m) when not null.
  int ShiftedCandidate(int a, int b, int r, double* mismatch = nullptr) const;
  // Pins b's columns if ready (returns false otherwise): they stay valid and unchanged until
  // the matching Unpin. Pins nest. Lock-free (a compare-and-swap on the slot's pin count,
  // which the worker sets to −1 while it evicts the slot).
  bool Pin(int b);
  // Releases one pin of b (b must be pinned).
  void Unpin(int b);
  // Entry (row, 3·b + j) of G: displacement of output dof `row` (3a + i) under a unit force
  // on candidate b along j, in m/N. b must be pinned.
  double Value(int row, int b, int j) const;
  // 3 by 3 block of G: rows of output node a, columns of candidate b (pinned), in m/N.
  Eigen::Matrix3d Block(int a, int b) const;
  // Adds scale · G(:, 3b + j) to u (3·#output). b must be pinned; rows not computed yet (NaN,
  // see HasColumn) are skipped.
  void AddColumn(int b, int j, double scale, double* u) const;
  // Displacement of the output nodes under the model's own loads, 3·#output, m.
  const Eigen::VectorXd& baseline() const { return u0_; }

  // --- Figures ---
  // Bytes of one node's three columns (9 · #output · 4 or 8).
  double BytesPerNode() const { return static_cast<double>(bytes_per_node_); }
  // Maximum number of nodes held at once (the memory bound).
  int capacity_nodes() const { return num_slots_; }
  // Nodes whose columns are ready now (every row).
  int ready_nodes() const { return ready_count_.load(); }
  // Bytes held now: allocated slots, baseline and index tables.
  double MemoryBytes() const;
  // Order in which candidate b became ready (0, 1, 2, ... by block; −1 if never).
  long ReadyBlock(int b) const { return ready_block_[b].load(); }
  // Counters.
  ColumnCacheStats stats() const;
  // Precision of the stored columns.
  ColumnPrecision precision() const { return precision_; }

  // --- Disk ---
  // The ready columns (worker should be stopped or idle) as a ColumnSet with the given key.
  ColumnSet Export(std::uint64_t key) const;
  // Loads columns from a set (same output nodes, candidates among ours; worker stopped) into
  // free slots, in the set's order, until the memory bound. Returns how many nodes were
  // loaded; throws std::invalid_argument when the output nodes differ.
  int Import(const ColumnSet& set);

 private:
  struct Slot {
    std::unique_ptr<unsigned char[]> data;  // 9·#output values, column-major (3 columns)
    std::atomic<int> owner{-1};             // candidate held, −1 when free
    std::atomic<int> pins{0};               // −1 while the worker evicts the slot
    // Row groups computed (bit g), kComplete once every row is; set before the owner is
    // published, only ever gaining bits until the slot is freed.
    std::atomic<std::uint64_t> rows{0};
  };
  static constexpr std::uint64_t kComplete = 1ull << 63;
  void WorkerLoop();
  // One step of work for the current focus; returns false when there is nothing to do.
  bool WorkStep();
  // Candidate indices to compute next for focus p (nearest first, not ready, within radius),
  // with a slot reserved for each (evicting farther nodes when needed).
  void PlanBlock(const Eigen::Vector3d& p, double radius, std::uint64_t seq,
                 std::vector<int>* block, std::vector<int>* slots);
  int TakeSlotFor(const Eigen::Vector3d* p, double d_b, const std::vector<int>* keep);
  bool TryEvict(int s);
  // Solves and publishes a block; `near` (bits of row groups, 0: none) asks for those rows
  // first (near_rows_first).
  void SolveAndPublish(const std::vector<int>& block, const std::vector<int>& slots,
                       std::uint64_t near = 0);
  // Writes into slot s the rows of column block c of x_ whose row group is in `groups` (bits;
  // kComplete: every row). The slot's first write (`first`) also writes the group-free rows
  // (group −1) and NaN into every row it leaves for later.
  void WriteRows(int c, int s, std::uint64_t groups, bool first);
  void Publish(int b, int s, std::uint64_t rows);
  void Complete(int b, int s);
  bool ReadFocus(Eigen::Vector3d* p, double* radius, std::uint64_t* seq) const;
  const double* DoubleData(int s) const;
  const float* FloatData(int s) const;

  ColumnCache(std::unique_ptr<const FreeDofSolver> view, const FreeDofSolver* solver,
              const Eigen::MatrixX3d& nodes, const std::vector<int>& output_nodes,
              const std::vector<int>& candidate_nodes, const ColumnCacheSettings& settings);

  std::unique_ptr<const FreeDofSolver> view_;  // owned view of a StaticSolver, or null
  const FreeDofSolver& solver_;
  ColumnPrecision precision_;
  ColumnCacheSettings settings_;
  std::vector<int> output_nodes_, candidate_nodes_, candidate_row_;
  std::vector<Eigen::Vector3d> positions_;  // of candidates
  std::vector<char> fixed_;
  std::vector<int> node_to_candidate_;
  std::vector<int> neighbours_;  // #candidates by settings.neighbours, nearest first (−1 pad)
  int num_neighbours_ = 0;
  // Set (release) once neighbours_ is made; readers read neighbours_ only after seeing it.
  std::atomic<bool> neighbours_ready_{false};
  // Makes the neighbour lists unless made (the worker, or a caller while it is stopped).
  void MakeNeighbours();
  // Length of the lists a reader may use now (0 until they are made).
  int UsableNeighbours() const {
    return neighbours_ready_.load(std::memory_order_acquire) ? num_neighbours_ : 0;
  }
  Eigen::VectorXd u0_;
  std::size_t bytes_per_node_ = 0;

  std::unique_ptr<Slot[]> slots_;
  int num_slots_ = 0;
  std::vector<char> failed_;        // worker only: candidates whose solve failed (not retried)
  std::vector<int> order_;          // worker only: candidates in the radius, nearest first
  std::uint64_t order_groups_ = 0;  // worker only: row groups of order_ (near_rows_first)
  std::vector<int> row_group_;      // per output node: its row group, −1 (none or near rows off)
  std::uint64_t all_groups_ = 0;    // bits of every row group (0: near rows off)
  std::uint64_t order_seq_ = ~0ull;
  Eigen::Vector3d order_p_ = Eigen::Vector3d::Zero();  // focus the order was made for
  double order_radius_ = 0.0;
  std::unique_ptr<std::atomic<int>[]> slot_of_;       // per candidate: slot or −1
  std::unique_ptr<std::atomic<long>[]> ready_block_;  // per candidate
  std::atomic<int> ready_count_{0};
  std::atomic<int> allocated_slots_{0};

  // Focus seqlock.
  std::atomic<std::uint64_t> focus_seq_{0};
  std::atomic<double> focus_x_{0.0}, focus_y_{0.0}, focus_z_{0.0}, focus_radius_{-1.0};
  std::atomic<std::uint64_t> idle_seq_{~0ull};  // focus_seq_ value the worker found done

  // Worker.
  std::thread worker_;
  std::atomic<bool> stop_{false};
  mutable std::mutex wake_mutex_;
  std::condition_variable wake_;
  std::atomic<long> computed_nodes_{0}, evictions_{0}, blocks_{0}, near_blocks_{0};
  std::atomic<bool> paused_{false};
  std::atomic<double> compute_seconds_{0.0};
  Eigen::MatrixXd rhs_, x_;  // worker scratch
};

// What a CachedContactSolver update did.
enum class CachedContactStatus {
  kOk,
  kFull,                 // max_contacts already in contact
  kAlreadyInContact,     // Add of a node in contact
  kNotInContact,         // Remove of a node not in contact
  kFixedNode,            // the node is constrained: no contact there
  kNotPositiveDefinite,  // the bordered block was not positive definite (node refused)
  kBadIndex,             // not a candidate index
  kNoColumnReady,        // no column at all is ready yet: no force can be computed
};

// Real-time k-contact solve on a ColumnCache, like ContactSolver on a Compliance, but each
// contact reads its own column when ready and otherwise the nearest ready node's column,
// shifted (see the ColumnCache header comment). All buffers are sized at construction for
// max_contacts; Add, Remove, Refresh, Solve and OutputDisplacement never allocate, lock or
// throw. Each contact pins the column it reads, so the worker never evicts it.
//
// The Cholesky factor L (lower, 3k by 3k, slot order; a BorderedCholesky) of the contact block
// is bordered by one 3-row block on Add (O(k²)); Remove and Refresh re-border the slots from
// the first changed one (O((k − s)·k²) for slot s). The system solved is Ĝ_cc f = d − u0_c (f:
// forces ON the body).
class CachedContactSolver {
 public:
  // Solver for up to max_contacts (>= 1) nodes on `cache` (which must outlive it).
  CachedContactSolver(ColumnCache* cache, int max_contacts);
  // Releases the pins.
  ~CachedContactSolver();
  CachedContactSolver(const CachedContactSolver&) = delete;
  CachedContactSolver& operator=(const CachedContactSolver&) = delete;

  // Puts candidate b in contact (appended as the last slot), with its own column when ready,
  // else the nearest ready one.
  CachedContactStatus Add(int b);
  // Takes candidate b out of contact; later slots move down by one.
  CachedContactStatus Remove(int b);
  // Takes every node out of contact.
  void Clear();
  // Switches every contact that uses a substitute to its own column if that is ready now,
  // re-factoring from the first switched slot. Slot order is kept. Returns how many switched.
  int Refresh();

  // Number of nodes in contact, k.
  int num_contacts() const { return k_; }
  // Candidate index in slot s.
  int contact(int s) const { return slots_[s]; }
  // Candidate whose column slot s reads (== contact(s) when exact).
  int substitute(int s) const { return subs_[s]; }
  // Slots that use a substitute column.
  int num_substituted() const;

  // Forces on the body f (3k, N, slot order) so that each contact node's total displacement
  // equals target (3k, m, slot order). Returns false (forces untouched) when k = 0.
  bool Solve(const double* target, double* forces);
  // Frictionless contact: forces along the given unit normals only, f_s = β_s n_s, such that
  // each contact node's displacement along its normal reaches the target's:
  // n_s·u_s = n_s·target_s with u_c = u0_c + Ĝ_cc f (tangential displacements free).
  // normals, target: 3k (slot order; unit normals, m). Writes forces (3k, N) and displacement,
  // the contact nodes' resulting total displacement u_c (3k, m; may be the target's buffer). With
  // Ĝ_cc = L Lᵀ (the factor) and B = Lᵀ N (3k by k), β solves (BᵀB) β = Nᵀ(target − u0_c) and u_c =
  // u0_c + L B β: O(k³) work instead of the 2k solves that freeing the tangents with K_c = Ĝ_cc⁻¹
  // takes. Returns false (outputs untouched) when k = 0 or BᵀB is not positive definite (parallel
  // normals cannot make it so; a non-finite normal can). Allocation-free.
  bool SolveNormal(const double* normals, const double* target, double* forces,
                   double* displacement);
  // Displacement of all output nodes (3·#output, m) for contact forces f (3k, slot order),
  // u = u0 + Σ Ĝ(:, slot s) f_s. u_out must already have size 3·#output.
  void OutputDisplacement(const double* forces, Eigen::VectorXd* u_out) const;
  // The contact block Ĝ_cc (3k by 3k, slot order) the factor represents (allocates; not RT).
  Eigen::MatrixXd ContactBlock() const;

 private:
  // Block of Ĝ: rows of contact slot i, columns of contact slot j.
  Eigen::Matrix3d PairBlock(int i, int j) const;
  // Block of candidate col's column at candidate row's rows; NaN (which the factor refuses:
  // Add reports kNotPositiveDefinite) when those rows are not computed yet (near_rows_first).
  Eigen::Matrix3d Read(int row, int col) const;
  // Translated-column block: rows of candidate a, column of candidate b, read from r's column.
  Eigen::Matrix3d Shifted(int a, int b, int r, double* mismatch) const;
  // Factor rows of slots first..k−1 (rows before are kept). Returns false on a non-positive
  // pivot (the factor is then valid only for slots before the returned slot in *bad).
  bool FactorFrom(int first, int* bad);

  ColumnCache* cache_;
  int max_contacts_;
  int k_ = 0;
  BorderedCholesky chol_;  // factor of Ĝ_cc, 3·max square
  Eigen::VectorXd work_;
  // SolveNormal scratch: B = Lᵀ N (3k by k, column s contiguous) and the Cholesky factor of BᵀB.
  Eigen::MatrixXd normal_b_, normal_a_;
  Eigen::VectorXd normal_beta_;
  std::vector<int> slots_, subs_, slot_of_;
};

}  // namespace spidarcad::fem
