// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/column_cache.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include "node_lists.h"

namespace spidarcad::fem {

// ---------------------------------------------------------------------------------------------
// ColumnCache

ColumnCache::ColumnCache(const StaticSolver& solver, const Eigen::MatrixX3d& nodes,
                         const std::vector<int>& output_nodes,
                         const std::vector<int>& candidate_nodes,
                         const ColumnCacheSettings& settings)
    : ColumnCache(std::make_unique<StaticSolverView>(solver), nullptr, nodes, output_nodes,
                  candidate_nodes, settings) {}

ColumnCache::ColumnCache(const FreeDofSolver& solver, const Eigen::MatrixX3d& nodes,
                         const std::vector<int>& output_nodes,
                         const std::vector<int>& candidate_nodes,
                         const ColumnCacheSettings& settings)
    : ColumnCache(nullptr, &solver, nodes, output_nodes, candidate_nodes, settings) {}

ColumnCache::ColumnCache(std::unique_ptr<const FreeDofSolver> view, const FreeDofSolver* borrowed,
                         const Eigen::MatrixX3d& nodes, const std::vector<int>& output_nodes,
                         const std::vector<int>& candidate_nodes,
                         const ColumnCacheSettings& settings)
    : view_(std::move(view)),
      solver_(borrowed != nullptr ? *borrowed : *view_),
      precision_(settings.precision),
      settings_(settings),
      output_nodes_(output_nodes),
      candidate_nodes_(candidate_nodes) {
  const int n = solver_.bcs().num_nodes();
  if (nodes.rows() != n) {
    throw std::invalid_argument("ColumnCache: " + std::to_string(nodes.rows()) +
                                " node positions for a model of " + std::to_string(n) + " nodes");
  }
  if (!(settings.memory_budget_bytes > 0.0)) {
    throw std::invalid_argument("ColumnCache: memory_budget_bytes must be > 0, got " +
                                std::to_string(settings.memory_budget_bytes));
  }
  if (settings.block_nodes < 1 || settings.first_block_nodes < 0 || settings.neighbours < 0 ||
      !(settings.idle_poll_seconds > 0.0)) {
    throw std::invalid_argument(
        "ColumnCache: block_nodes must be >= 1 (got " + std::to_string(settings.block_nodes) +
        "), first_block_nodes >= 0 (got " + std::to_string(settings.first_block_nodes) +
        "), neighbours >= 0 (got " + std::to_string(settings.neighbours) +
        ") and idle_poll_seconds > 0");
  }
  if (!solver_.factor_status().converged) {
    throw std::runtime_error("ColumnCache: the model's factorisation failed: " +
                             solver_.factor_status().message);
  }
  const detail::NodeListIndex index =
      detail::IndexNodeLists("ColumnCache", "candidate", n, output_nodes, candidate_nodes);
  node_to_candidate_ = index.subset_index;
  candidate_row_ = index.subset_row;
  for (const int v : candidate_nodes) {
    positions_.push_back(nodes.row(v).transpose());
    bool fixed = false;
    for (int i = 0; i < 3; ++i) fixed = fixed || solver_.FreeIndex(3 * v + i) < 0;
    fixed_.push_back(fixed ? 1 : 0);
  }
  const int num_out = num_outputs(), num_cand = num_candidates();
  row_group_.assign(num_out, -1);
  const int groups = solver_.num_row_groups();
  if (settings.near_rows_first && groups >= 2 && groups <= 63) {
    all_groups_ = (1ull << groups) - 1;
    for (int a = 0; a < num_out; ++a) row_group_[a] = solver_.RowGroupOfNode(output_nodes[a]);
  }

  // Baseline: the model's own loads.
  const StaticSolution base = solver_.Solve();
  u0_.resize(3 * num_out);
  for (int a = 0; a < num_out; ++a)
    u0_.segment<3>(3 * a) = base.displacement.segment<3>(3 * output_nodes[a]);

  bytes_per_node_ = static_cast<std::size_t>(9) * num_out * BytesPerValue(precision_);
  const double fit =
      std::floor(settings.memory_budget_bytes / static_cast<double>(bytes_per_node_));
  num_slots_ = static_cast<int>(std::clamp(fit, 1.0, static_cast<double>(std::max(1, num_cand))));
  slots_ = std::make_unique<Slot[]>(num_slots_);
  slot_of_ = std::make_unique<std::atomic<int>[]>(std::max(1, num_cand));
  ready_block_ = std::make_unique<std::atomic<long>[]>(std::max(1, num_cand));
  for (int b = 0; b < num_cand; ++b) {
    slot_of_[b].store(-1);
    ready_block_[b].store(-1);
  }
  failed_.assign(num_cand, 0);

  // Nearest free (not fixed) candidates of each candidate (a grid search; the brute force's lists).
  num_neighbours_ = std::min(settings.neighbours, std::max(0, num_cand - 1));
  if (!settings.neighbours_on_worker) MakeNeighbours();
  if (settings.start_worker) Start();
}

void ColumnCache::MakeNeighbours() {
  if (neighbours_ready_.load()) return;
  std::vector<char> free(positions_.size());
  for (std::size_t b = 0; b < free.size(); ++b) free[b] = fixed_[b] ? 0 : 1;
  neighbours_ = detail::NearestAllowed(positions_, free, num_neighbours_);
  neighbours_ready_.store(true, std::memory_order_release);
}

ColumnCache::~ColumnCache() { Stop(); }

void ColumnCache::Start() {
  if (worker_.joinable()) return;
  stop_.store(false);
  idle_seq_.store(~0ull);
  worker_ = std::thread([this] { WorkerLoop(); });
}

void ColumnCache::Stop() {
  if (!worker_.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(wake_mutex_);
    stop_.store(true);
  }
  wake_.notify_all();
  worker_.join();
  stop_.store(false);
}

bool ColumnCache::WaitUntilIdle(double timeout_seconds) const {
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration<double>(std::max(0.0, timeout_seconds));
  while (worker_.joinable()) {
    if (idle_seq_.load() == focus_seq_.load()) return true;
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  return true;
}

void ColumnCache::RequestNear(const Eigen::Vector3d& p_W, double radius) {
  const std::uint64_t seq = focus_seq_.load(std::memory_order_relaxed);
  focus_seq_.store(seq + 1, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);
  focus_x_.store(p_W.x(), std::memory_order_relaxed);
  focus_y_.store(p_W.y(), std::memory_order_relaxed);
  focus_z_.store(p_W.z(), std::memory_order_relaxed);
  focus_radius_.store(radius, std::memory_order_relaxed);
  focus_seq_.store(seq + 2, std::memory_order_release);
}

bool ColumnCache::ReadFocus(Eigen::Vector3d* p, double* radius, std::uint64_t* seq) const {
  for (;;) {
    const std::uint64_t s1 = focus_seq_.load(std::memory_order_acquire);
    if (s1 & 1) {
      std::this_thread::yield();
      continue;
    }
    const double x = focus_x_.load(std::memory_order_relaxed);
    const double y = focus_y_.load(std::memory_order_relaxed);
    const double z = focus_z_.load(std::memory_order_relaxed);
    const double r = focus_radius_.load(std::memory_order_relaxed);
    std::atomic_thread_fence(std::memory_order_acquire);
    if (focus_seq_.load(std::memory_order_relaxed) != s1) continue;
    *p = Eigen::Vector3d(x, y, z);
    *radius = r;
    *seq = s1;
    return std::isfinite(x) && std::isfinite(y) && std::isfinite(z) && r >= 0.0;
  }
}

void ColumnCache::WorkerLoop() {
  // Threads inherit the creator's policy: never run the worker at real-time priority.
  sched_param param{};
  param.sched_priority = 0;
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &param);
  while (!stop_.load()) {
    if (WorkStep()) {
      // After the first block of columns (a no-op once made): not before it, as a worker
      // started before its first focus would otherwise make them while the focus arrives.
      MakeNeighbours();
      continue;
    }
    std::unique_lock<std::mutex> lock(wake_mutex_);
    wake_.wait_for(lock, std::chrono::duration<double>(settings_.idle_poll_seconds),
                   [this] { return stop_.load(); });
  }
}

bool ColumnCache::WorkStep() {
  Eigen::Vector3d p;
  double radius = 0.0;
  std::uint64_t seq = 0;
  const bool focused = ReadFocus(&p, &radius, &seq);
  if (!focused || paused_.load()) {
    idle_seq_.store(seq);
    // Let go meanwhile (SetPaused(false) stores paused_, then idle_seq_): not idle after all.
    if (focused && !paused_.load()) idle_seq_.store(~0ull);
    return false;
  }
  std::vector<int> block, slots;
  PlanBlock(p, radius, seq, &block, &slots);
  if (block.empty()) {
    idle_seq_.store(seq);  // done for this focus
    return false;
  }
  // Near rows first when the focus's groups are some, not all, of the model's.
  const bool near = order_groups_ != 0 && order_groups_ != all_groups_;
  SolveAndPublish(block, slots, near ? order_groups_ : 0);
  return true;
}

void ColumnCache::PlanBlock(const Eigen::Vector3d& p, double radius, std::uint64_t seq,
                            std::vector<int>* block, std::vector<int>* slots) {
  // Re-plan only when the focus has moved by more than 5 % of the radius (a haptic thread may
  // post the same or a nearly same focus every tick: no need to sort the candidates each time).
  const bool moved = order_seq_ == ~0ull || (p - order_p_).norm() > 0.05 * radius ||
                     std::abs(radius - order_radius_) > 0.05 * radius;
  if (seq != order_seq_ && moved) {
    order_p_ = p;
    order_radius_ = radius;
    order_.clear();
    for (int b = 0; b < num_candidates(); ++b)
      if (!fixed_[b] && (positions_[b] - p).norm() <= radius) order_.push_back(b);
    std::stable_sort(order_.begin(), order_.end(), [&](int a, int b) {
      return (positions_[a] - p).squaredNorm() < (positions_[b] - p).squaredNorm();
    });
    order_seq_ = seq;
    order_groups_ = 0;
    for (int b : order_) {
      const int g = row_group_[candidate_row_[b]];
      if (g >= 0) order_groups_ |= 1ull << g;
    }
  }
  const int limit = blocks_.load() == 0 && settings_.first_block_nodes > 0
                        ? std::min(settings_.first_block_nodes, settings_.block_nodes)
                        : settings_.block_nodes;
  for (int b : order_) {
    if (static_cast<int>(block->size()) >= limit) break;
    if (failed_[b] || slot_of_[b].load() >= 0) continue;
    const int s = TakeSlotFor(&p, (positions_[b] - p).norm(), nullptr);
    if (s < 0) break;  // the rest is farther still
    block->push_back(b);
    slots->push_back(s);
  }
}

// A free slot (reserved: owner −2), else one freed by evicting the unpinned ready node farthest
// from p (only if farther than d_b), or with p null any unpinned node not in *keep.
int ColumnCache::TakeSlotFor(const Eigen::Vector3d* p, double d_b, const std::vector<int>* keep) {
  for (int s = 0; s < num_slots_; ++s) {
    int expected = -1;
    if (slots_[s].owner.compare_exchange_strong(expected, -2)) {
      slots_[s].rows.store(0);
      if (!slots_[s].data) {
        slots_[s].data = std::make_unique<unsigned char[]>(bytes_per_node_);
        allocated_slots_.fetch_add(1);
      }
      return s;
    }
  }
  for (int attempt = 0; attempt < 4; ++attempt) {
    int victim = -1;
    double worst = p ? d_b : -1.0;
    for (int s = 0; s < num_slots_; ++s) {
      const int o = slots_[s].owner.load();
      if (o < 0 || slots_[s].pins.load() != 0) continue;
      if (keep && std::find(keep->begin(), keep->end(), o) != keep->end()) continue;
      const double d = p ? (positions_[o] - *p).norm() : 0.0;
      if (d > worst) {
        worst = d;
        victim = s;
      }
    }
    if (victim < 0) return -1;
    if (TryEvict(victim)) return victim;
  }
  return -1;
}

bool ColumnCache::TryEvict(int s) {
  Slot& slot = slots_[s];
  int zero = 0;
  if (!slot.pins.compare_exchange_strong(zero, -1)) return false;  // pinned meanwhile
  const int o = slot.owner.load();
  if (o >= 0) {
    slot_of_[o].store(-1);
    ready_block_[o].store(-1);
    if (slot.rows.load() & kComplete) ready_count_.fetch_sub(1);
    evictions_.fetch_add(1);
  }
  slot.rows.store(0);
  slot.owner.store(-2);
  slot.pins.store(0);
  return true;
}

void ColumnCache::Publish(int b, int s, std::uint64_t rows) {
  slots_[s].rows.store(rows);
  slots_[s].owner.store(b);
  if (rows & kComplete) ready_block_[b].store(blocks_.load());
  slot_of_[b].store(s, std::memory_order_seq_cst);  // after the data: release
  if (rows & kComplete) ready_count_.fetch_add(1);
}

void ColumnCache::Complete(int b, int s) {
  ready_block_[b].store(blocks_.load());
  slots_[s].rows.fetch_or(kComplete, std::memory_order_seq_cst);  // after the data: release
  ready_count_.fetch_add(1);
}

void ColumnCache::WriteRows(int c, int s, std::uint64_t groups, bool first) {
  unsigned char* raw = slots_[s].data.get();
  const int num_out = num_outputs();
  const size_t rows = 3 * static_cast<size_t>(num_out);
  const bool all = (groups & kComplete) != 0;
  for (int j = 0; j < 3; ++j)
    for (int a = 0; a < num_out; ++a) {
      const int g = row_group_[a];
      const bool want = all || (g < 0 ? first : ((groups >> g) & 1) != 0);
      if (!want && !first) continue;
      for (int i = 0; i < 3; ++i) {
        const int fi = solver_.FreeIndex(3 * output_nodes_[a] + i);
        const double v = !want    ? std::numeric_limits<double>::quiet_NaN()
                         : fi < 0 ? 0.0
                                  : x_(fi, 3 * c + j);
        const size_t idx = j * rows + 3 * a + i;
        if (precision_ == ColumnPrecision::kFloat) {
          reinterpret_cast<float*>(raw)[idx] = static_cast<float>(v);
        } else {
          reinterpret_cast<double*>(raw)[idx] = v;
        }
      }
    }
}

void ColumnCache::SolveAndPublish(const std::vector<int>& block, const std::vector<int>& slots,
                                  std::uint64_t near) {
  const auto t0 = std::chrono::steady_clock::now();
  const int count = static_cast<int>(block.size());
  rhs_.setZero(solver_.num_free(), 3 * count);
  for (int c = 0; c < count; ++c)
    for (int j = 0; j < 3; ++j) {
      const int fi = solver_.FreeIndex(3 * candidate_nodes_[block[c]] + j);
      if (fi >= 0) rhs_(fi, 3 * c + j) = 1.0;
    }
  SolveStatus status;
  bool published = false;
  if (near != 0) {
    // The rows near the focus first (published with the rest NaN), then the rest.
    std::vector<int> groups;
    for (int g = 0; g < 63; ++g)
      if ((near >> g) & 1) groups.push_back(g);
    status = solver_.SolveFreeInGroups(rhs_, groups, &x_);
    if (status.converged) {
      for (int c = 0; c < count; ++c) {
        WriteRows(c, slots[c], near, true);
        Publish(block[c], slots[c], near);
      }
      published = true;
      near_blocks_.fetch_add(1);
      status = solver_.CompleteSolveFree(rhs_, groups, &x_);
      if (status.converged)
        for (int c = 0; c < count; ++c) {
          WriteRows(c, slots[c], all_groups_ & ~near, false);
          Complete(block[c], slots[c]);
        }
    }
  } else {
    status = solver_.SolveFree(rhs_, &x_);
    if (status.converged)
      for (int c = 0; c < count; ++c) {
        WriteRows(c, slots[c], kComplete, true);
        Publish(block[c], slots[c], kComplete);
      }
  }
  if (!status.converged)
    for (int c = 0; c < count; ++c) {
      failed_[block[c]] = 1;
      // Withdrawn (a contact pinning its near rows keeps them: they stay right).
      if (!published || TryEvict(slots[c])) slots_[slots[c]].owner.store(-1);
    }
  if (status.converged) computed_nodes_.fetch_add(count);
  blocks_.fetch_add(1);
  compute_seconds_.fetch_add(
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}

int ColumnCache::ComputeNodes(const std::vector<int>& candidates) {
  if (running()) throw std::logic_error("ColumnCache::ComputeNodes: stop the worker first");
  std::vector<int> todo;
  for (int b : candidates) {
    if (b < 0 || b >= num_candidates()) {
      throw std::invalid_argument("ColumnCache::ComputeNodes: candidate index " +
                                  std::to_string(b) + " out of range");
    }
    if (!fixed_[b] && slot_of_[b].load() < 0 &&
        std::find(todo.begin(), todo.end(), b) == todo.end())
      todo.push_back(b);
  }
  MakeNeighbours();
  int done = 0;
  for (size_t start = 0; start < todo.size(); start += settings_.block_nodes) {
    std::vector<int> block, slots;
    for (size_t i = start; i < std::min(todo.size(), start + settings_.block_nodes); ++i) {
      const int s = TakeSlotFor(nullptr, 0.0, &candidates);
      if (s < 0) break;
      block.push_back(todo[i]);
      slots.push_back(s);
    }
    if (block.empty()) break;
    const long before = computed_nodes_.load();
    SolveAndPublish(block, slots);
    done += static_cast<int>(computed_nodes_.load() - before);
  }
  return done;
}

void ColumnCache::EvictAll() {
  if (running()) throw std::logic_error("ColumnCache::EvictAll: stop the worker first");
  for (int s = 0; s < num_slots_; ++s) {
    if (slots_[s].owner.load() >= 0 && TryEvict(s)) slots_[s].owner.store(-1);
  }
}

int ColumnCache::CandidateOfNode(int v) const {
  if (v < 0 || v >= static_cast<int>(node_to_candidate_.size())) return -1;
  return node_to_candidate_[v];
}

bool ColumnCache::IsReady(int b) const {
  const int s = slot_of_[b].load(std::memory_order_acquire);
  return s >= 0 && (slots_[s].rows.load(std::memory_order_acquire) & kComplete) != 0;
}

bool ColumnCache::RowReady(int a, int b) const {
  const int s = slot_of_[b].load(std::memory_order_acquire);
  if (s < 0) return false;
  const std::uint64_t rows = slots_[s].rows.load(std::memory_order_acquire);
  const int g = row_group_[a];
  return (rows & kComplete) != 0 || g < 0 || ((rows >> g) & 1) != 0;
}

int ColumnCache::ReadyNodeNearest(int b) const {
  if (slot_of_[b].load(std::memory_order_acquire) >= 0) return b;
  const int nn = UsableNeighbours();
  const int* list = neighbours_.data() + static_cast<size_t>(b) * nn;
  for (int i = 0; i < nn; ++i) {
    const int c = list[i];
    if (c >= 0 && slot_of_[c].load(std::memory_order_acquire) >= 0) return c;
  }
  int best = -1;
  double best_d2 = std::numeric_limits<double>::infinity();
  for (int s = 0; s < num_slots_; ++s) {
    const int o = slots_[s].owner.load(std::memory_order_acquire);
    if (o < 0 || slot_of_[o].load(std::memory_order_acquire) != s) continue;
    const double d2 = (positions_[o] - positions_[b]).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = o;
    }
  }
  return best;
}

int ColumnCache::ShiftedCandidate(int a, int b, int r, double* mismatch) const {
  if (mismatch) *mismatch = 0.0;
  if (a == b) return r;
  const Eigen::Vector3d target = positions_[r] + positions_[a] - positions_[b];
  int best = r;
  double best_d2 = (positions_[r] - target).squaredNorm();
  const int nn = UsableNeighbours();
  const int* list = neighbours_.data() + static_cast<size_t>(r) * nn;
  for (int i = 0; i < nn; ++i) {
    const int c = list[i];
    if (c < 0) continue;
    const double d2 = (positions_[c] - target).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = c;
    }
  }
  if (mismatch) *mismatch = std::sqrt(best_d2);
  return best;
}

bool ColumnCache::Pin(int b) {
  const int s = slot_of_[b].load();
  if (s < 0) return false;
  std::atomic<int>& pins = slots_[s].pins;
  int p = pins.load();
  do {
    if (p < 0) return false;  // being evicted
  } while (!pins.compare_exchange_weak(p, p + 1));
  if (slot_of_[b].load() != s) {  // evicted (and maybe reused) before the pin took
    pins.fetch_sub(1);
    return false;
  }
  return true;
}

void ColumnCache::Unpin(int b) {
  const int s = slot_of_[b].load();
  if (s >= 0) slots_[s].pins.fetch_sub(1);
}

const double* ColumnCache::DoubleData(int s) const {
  return reinterpret_cast<const double*>(slots_[s].data.get());
}

const float* ColumnCache::FloatData(int s) const {
  return reinterpret_cast<const float*>(slots_[s].data.get());
}

double ColumnCache::Value(int row, int b, int j) const {
  const int s = slot_of_[b].load(std::memory_order_acquire);
  const size_t idx = static_cast<size_t>(j) * 3 * num_outputs() + row;
  return precision_ == ColumnPrecision::kFloat ? FloatData(s)[idx] : DoubleData(s)[idx];
}

Eigen::Matrix3d ColumnCache::Block(int a, int b) const {
  const int s = slot_of_[b].load(std::memory_order_acquire);
  const size_t rows = 3 * static_cast<size_t>(num_outputs());
  Eigen::Matrix3d m;
  if (precision_ == ColumnPrecision::kFloat) {
    const float* d = FloatData(s);
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) m(i, j) = d[j * rows + 3 * a + i];
  } else {
    const double* d = DoubleData(s);
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) m(i, j) = d[j * rows + 3 * a + i];
  }
  return m;
}

void ColumnCache::AddColumn(int b, int j, double scale, double* u) const {
  const int s = slot_of_[b].load(std::memory_order_acquire);
  const size_t rows = 3 * static_cast<size_t>(num_outputs());
  const std::uint64_t ready = slots_[s].rows.load(std::memory_order_acquire);
  if (!(ready & kComplete)) {  // near rows only: row block by row block
    for (int a = 0; a < num_outputs(); ++a) {
      const int g = row_group_[a];
      if (g >= 0 && !((ready >> g) & 1)) continue;
      for (int i = 0; i < 3; ++i) u[3 * a + i] += scale * Value(3 * a + i, b, j);
    }
    return;
  }
  if (precision_ == ColumnPrecision::kFloat) {
    const float* d = FloatData(s) + j * rows;
    for (size_t r = 0; r < rows; ++r) u[r] += scale * d[r];
  } else {
    const double* d = DoubleData(s) + j * rows;
    for (size_t r = 0; r < rows; ++r) u[r] += scale * d[r];
  }
}

double ColumnCache::MemoryBytes() const {
  const double tables =
      4.0 * (output_nodes_.size() + 3.0 * candidate_nodes_.size() + node_to_candidate_.size() +
             static_cast<std::size_t>(UsableNeighbours()) * positions_.size()) +
      8.0 * candidate_nodes_.size() * 4 + 64.0 * num_slots_;
  return allocated_slots_.load() * static_cast<double>(bytes_per_node_) + 8.0 * u0_.size() + tables;
}

ColumnCacheStats ColumnCache::stats() const {
  ColumnCacheStats st;
  st.computed_nodes = computed_nodes_.load();
  st.evictions = evictions_.load();
  st.blocks = blocks_.load();
  st.near_blocks = near_blocks_.load();
  st.compute_seconds = compute_seconds_.load();
  return st;
}

ColumnSet ColumnCache::Export(std::uint64_t key) const {
  ColumnSet set;
  set.key = key;
  set.precision = precision_;
  set.output_nodes = output_nodes_;
  set.baseline = u0_;
  std::vector<int> ready;
  for (int b = 0; b < num_candidates(); ++b)
    if (IsReady(b)) ready.push_back(b);
  set.columns.resize(3 * num_outputs(), 3 * static_cast<Eigen::Index>(ready.size()));
  auto* self = const_cast<ColumnCache*>(this);
  int kept = 0;
  for (int b : ready) {
    if (!self->Pin(b)) continue;
    for (int j = 0; j < 3; ++j)
      for (int r = 0; r < 3 * num_outputs(); ++r) set.columns(r, 3 * kept + j) = Value(r, b, j);
    self->Unpin(b);
    set.nodes.push_back(candidate_nodes_[b]);
    ++kept;
  }
  set.columns.conservativeResize(Eigen::NoChange, 3 * kept);
  return set;
}

int ColumnCache::Import(const ColumnSet& set) {
  if (running()) throw std::logic_error("ColumnCache::Import: stop the worker first");
  if (set.output_nodes != output_nodes_) {
    throw std::invalid_argument(
        "ColumnCache::Import: the set's " + std::to_string(set.output_nodes.size()) +
        " output nodes differ from the cache's " + std::to_string(output_nodes_.size()));
  }
  if (set.columns.rows() != 3 * num_outputs() ||
      set.columns.cols() != 3 * static_cast<Eigen::Index>(set.nodes.size())) {
    throw std::invalid_argument(
        "ColumnCache::Import: the set's columns are " + std::to_string(set.columns.rows()) +
        " by " + std::to_string(set.columns.cols()) + ", expected " +
        std::to_string(3 * num_outputs()) + " by " + std::to_string(3 * set.nodes.size()));
  }
  int loaded = 0;
  const size_t rows = 3 * static_cast<size_t>(num_outputs());
  for (size_t k = 0; k < set.nodes.size(); ++k) {
    const int b = CandidateOfNode(set.nodes[k]);
    if (b < 0 || fixed_[b] || HasColumn(b)) continue;
    int s = -1;
    for (int t = 0; t < num_slots_ && s < 0; ++t) {
      int expected = -1;
      if (slots_[t].owner.compare_exchange_strong(expected, -2)) s = t;
    }
    if (s < 0) break;
    if (!slots_[s].data) {
      slots_[s].data = std::make_unique<unsigned char[]>(bytes_per_node_);
      allocated_slots_.fetch_add(1);
    }
    unsigned char* raw = slots_[s].data.get();
    for (int j = 0; j < 3; ++j)
      for (size_t r = 0; r < rows; ++r) {
        const double v = set.columns(r, 3 * k + j);
        if (precision_ == ColumnPrecision::kFloat) {
          reinterpret_cast<float*>(raw)[j * rows + r] = static_cast<float>(v);
        } else {
          reinterpret_cast<double*>(raw)[j * rows + r] = v;
        }
      }
    Publish(b, s, kComplete);
    ++loaded;
  }
  return loaded;
}

// ---------------------------------------------------------------------------------------------
// CachedContactSolver

CachedContactSolver::CachedContactSolver(ColumnCache* cache, int max_contacts)
    : cache_(cache), max_contacts_(max_contacts), chol_(std::max(1, max_contacts)) {
  if (max_contacts < 1) {
    throw std::invalid_argument("CachedContactSolver: max_contacts must be >= 1, got " +
                                std::to_string(max_contacts));
  }
  work_ = Eigen::VectorXd::Zero(3 * max_contacts);
  normal_b_ = Eigen::MatrixXd::Zero(3 * max_contacts, max_contacts);
  normal_a_ = Eigen::MatrixXd::Zero(max_contacts, max_contacts);
  normal_beta_ = Eigen::VectorXd::Zero(max_contacts);
  slots_.assign(max_contacts, -1);
  subs_.assign(max_contacts, -1);
  slot_of_.assign(cache->num_candidates(), -1);
}

CachedContactSolver::~CachedContactSolver() { Clear(); }

int CachedContactSolver::num_substituted() const {
  int n = 0;
  for (int s = 0; s < k_; ++s) n += subs_[s] != slots_[s];
  return n;
}

Eigen::Matrix3d CachedContactSolver::Read(int row, int col) const {
  const int a = cache_->OutputIndexOfCandidate(row);
  if (!cache_->RowReady(a, col))
    return Eigen::Matrix3d::Constant(std::numeric_limits<double>::quiet_NaN());
  return cache_->Block(a, col);
}

Eigen::Matrix3d CachedContactSolver::Shifted(int a, int b, int r, double* mismatch) const {
  return Read(cache_->ShiftedCandidate(a, b, r, mismatch), r);
}

Eigen::Matrix3d CachedContactSolver::PairBlock(int i, int j) const {
  const int ci = slots_[i], cj = slots_[j], ri = subs_[i], rj = subs_[j];
  if (i == j) {
    const Eigen::Matrix3d m = Shifted(ci, ci, ri, nullptr);  // exact when ri == ci
    return 0.5 * (m + m.transpose());
  }
  double m1 = 0.0, m2 = 0.0;
  if (rj == cj && ri == ci) return Read(ci, cj);
  // A substituted contact reads every block of its own from its substitute's column,
  // translated (mixing exact blocks with the substitute's self block can make Ĝ_cc indefinite).
  if (ri == ci) return Shifted(ci, cj, rj, &m1);
  if (rj == cj) return Shifted(cj, ci, ri, &m2).transpose();
  // Both translated: of the two estimates (G_ij from j's substitute, G_jiᵀ from i's), keep the
  // one whose translated point landed closer to a node (one may fall off an edge).
  const Eigen::Matrix3d a = Shifted(ci, cj, rj, &m1);
  const Eigen::Matrix3d b = Shifted(cj, ci, ri, &m2).transpose();
  if (m1 < m2 - 1e-12 * (m1 + m2)) return a;
  if (m2 < m1 - 1e-12 * (m1 + m2)) return b;
  return 0.5 * (a + b);
}

bool CachedContactSolver::FactorFrom(int first, int* bad) {
  chol_.Truncate(first);
  for (int t = first; t < k_; ++t) {
    // Border: the blocks Ĝ(slot t, slot i) of the earlier slots.
    for (int i = 0; i < t; ++i) {
      const Eigen::Matrix3d b = PairBlock(t, i);
      for (int j = 0; j < 3; ++j) {
        double* row = chol_.BorderRow(j);
        for (int l = 0; l < 3; ++l) row[3 * i + l] = b(j, l);
      }
    }
    if (!chol_.AppendBlock(PairBlock(t, t))) {
      *bad = t;
      return false;
    }
  }
  return true;
}

CachedContactStatus CachedContactSolver::Add(int b) {
  if (b < 0 || b >= static_cast<int>(slot_of_.size())) return CachedContactStatus::kBadIndex;
  if (slot_of_[b] >= 0) return CachedContactStatus::kAlreadyInContact;
  if (cache_->IsFixed(b)) return CachedContactStatus::kFixedNode;
  if (k_ >= max_contacts_) return CachedContactStatus::kFull;
  int r = -1;
  for (int attempt = 0; attempt < 4 && r < 0; ++attempt) {
    r = cache_->ReadyNodeNearest(b);
    if (r < 0) return CachedContactStatus::kNoColumnReady;
    if (!cache_->Pin(r)) r = -1;  // evicted between the lookup and the pin: look again
  }
  if (r < 0) return CachedContactStatus::kNoColumnReady;
  slots_[k_] = b;
  subs_[k_] = r;
  slot_of_[b] = k_;
  ++k_;
  int bad = 0;
  if (!FactorFrom(k_ - 1, &bad)) {
    --k_;
    slot_of_[b] = -1;
    slots_[k_] = subs_[k_] = -1;
    cache_->Unpin(r);
    return CachedContactStatus::kNotPositiveDefinite;
  }
  return CachedContactStatus::kOk;
}

CachedContactStatus CachedContactSolver::Remove(int b) {
  if (b < 0 || b >= static_cast<int>(slot_of_.size())) return CachedContactStatus::kBadIndex;
  const int s = slot_of_[b];
  if (s < 0) return CachedContactStatus::kNotInContact;
  cache_->Unpin(subs_[s]);
  // Close the gap: rows of later slots move up, their columns of later slots move left. The
  // rows from slot s on are then re-bordered (rows before s are unchanged).
  for (int t = s; t + 1 < k_; ++t) {
    slots_[t] = slots_[t + 1];
    subs_[t] = subs_[t + 1];
    slot_of_[slots_[t]] = t;
  }
  --k_;
  slots_[k_] = subs_[k_] = -1;
  slot_of_[b] = -1;
  int bad = 0;
  if (!FactorFrom(s, &bad)) {
    // A principal block of a positive definite matrix is positive definite: only rounding can
    // get here. Drop the contacts from the failing slot on.
    for (int t = bad; t < k_; ++t) {
      cache_->Unpin(subs_[t]);
      slot_of_[slots_[t]] = -1;
      slots_[t] = subs_[t] = -1;
    }
    k_ = bad;
  }
  return CachedContactStatus::kOk;
}

void CachedContactSolver::Clear() {
  for (int t = 0; t < k_; ++t) {
    cache_->Unpin(subs_[t]);
    slot_of_[slots_[t]] = -1;
    slots_[t] = subs_[t] = -1;
  }
  k_ = 0;
  chol_.Truncate(0);
}

int CachedContactSolver::Refresh() {
  int first = k_, switched = 0;
  for (int s = 0; s < k_; ++s) {
    const int b = slots_[s];
    if (subs_[s] == b || !cache_->IsReady(b) || !cache_->Pin(b)) continue;
    cache_->Unpin(subs_[s]);
    subs_[s] = b;
    first = std::min(first, s);
    ++switched;
  }
  int bad = 0;
  if (switched > 0 && !FactorFrom(first, &bad)) {
    for (int t = bad; t < k_; ++t) {
      cache_->Unpin(subs_[t]);
      slot_of_[slots_[t]] = -1;
      slots_[t] = subs_[t] = -1;
    }
    k_ = bad;
  }
  return switched;
}

bool CachedContactSolver::Solve(const double* target, double* forces) {
  if (k_ == 0) return false;
  const int n3 = 3 * k_;
  const Eigen::VectorXd& u0 = cache_->baseline();
  for (int i = 0; i < n3; ++i) {
    const int row = 3 * cache_->OutputIndexOfCandidate(slots_[i / 3]) + i % 3;
    work_(i) = target[i] - u0(row);
  }
  chol_.Solve(work_.data());
  for (int i = 0; i < n3; ++i) forces[i] = work_(i);
  return true;
}

bool CachedContactSolver::SolveNormal(const double* normals, const double* target, double* forces,
                                      double* displacement) {
  if (k_ == 0) return false;
  const int n3 = 3 * k_;
  const Eigen::VectorXd& u0 = cache_->baseline();
  const BorderedCholesky::FactorMatrix& l = chol_.factor();
  // B(:, s) = Lᵀ(:, 3s..3s+2) n_s: rows 3s..3s+2 of L, nonzero in columns m <= 3s + 2.
  for (int s = 0; s < k_; ++s) {
    double* b = &normal_b_(0, s);
    for (int m = 0; m < n3; ++m) b[m] = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double n = normals[3 * s + i];
      const double* row = &l(3 * s + i, 0);
      for (int m = 0; m <= 3 * s + i; ++m) b[m] += n * row[m];
    }
  }
  // A = BᵀB (lower triangle), factored in place: A = C Cᵀ.
  double scale = 0.0;
  for (int s = 0; s < k_; ++s) {
    const double* bs = &normal_b_(0, s);
    for (int t = 0; t <= s; ++t) {
      const double* bt = &normal_b_(0, t);
      const int top = 3 * t + 3;  // B(m, t) = 0 for m >= 3t + 3
      double sum = 0.0;
      for (int m = 0; m < top; ++m) sum += bs[m] * bt[m];
      normal_a_(s, t) = sum;
    }
    scale = std::max(scale, normal_a_(s, s));
  }
  if (!(scale > 0.0) || !std::isfinite(scale)) return false;
  for (int s = 0; s < k_; ++s) {
    for (int t = 0; t <= s; ++t) {
      double sum = normal_a_(s, t);
      for (int m = 0; m < t; ++m) sum -= normal_a_(s, m) * normal_a_(t, m);
      if (s == t) {
        if (!(sum > 1e-14 * scale)) return false;
        normal_a_(s, s) = std::sqrt(sum);
      } else {
        normal_a_(s, t) = sum / normal_a_(t, t);
      }
    }
  }
  // β = A⁻¹ Nᵀ(target − u0_c).
  for (int s = 0; s < k_; ++s) {
    const int row = 3 * cache_->OutputIndexOfCandidate(slots_[s]);
    double rhs = 0.0;
    for (int i = 0; i < 3; ++i) rhs += normals[3 * s + i] * (target[3 * s + i] - u0(row + i));
    for (int m = 0; m < s; ++m) rhs -= normal_a_(s, m) * normal_beta_(m);
    normal_beta_(s) = rhs / normal_a_(s, s);
  }
  for (int s = k_ - 1; s >= 0; --s) {
    const double beta = normal_beta_(s) / normal_a_(s, s);
    normal_beta_(s) = beta;
    for (int m = 0; m < s; ++m) normal_beta_(m) -= normal_a_(s, m) * beta;
  }
  // y = B β (= Lᵀ f), u_c − u0_c = L y.
  for (int m = 0; m < n3; ++m) work_(m) = 0.0;
  for (int s = 0; s < k_; ++s) {
    const double* bs = &normal_b_(0, s);
    const double beta = normal_beta_(s);
    for (int m = 0; m < 3 * s + 3; ++m) work_(m) += bs[m] * beta;
  }
  for (int i = 0; i < n3; ++i) {
    const double* row = &l(i, 0);
    double sum = 0.0;
    for (int m = 0; m <= i; ++m) sum += row[m] * work_(m);
    const int out = 3 * cache_->OutputIndexOfCandidate(slots_[i / 3]) + i % 3;
    displacement[i] = u0(out) + sum;
  }
  for (int s = 0; s < k_; ++s)
    for (int i = 0; i < 3; ++i) forces[3 * s + i] = normal_beta_(s) * normals[3 * s + i];
  return true;
}

void CachedContactSolver::OutputDisplacement(const double* forces, Eigen::VectorXd* u_out) const {
  *u_out = cache_->baseline();
  double* u = u_out->data();
  for (int s = 0; s < k_; ++s) {
    const int b = slots_[s], r = subs_[s];
    const int rb = 3 * cache_->OutputIndexOfCandidate(b),
              rr = 3 * cache_->OutputIndexOfCandidate(r);
    for (int j = 0; j < 3; ++j) {
      const double f = forces[3 * s + j];
      cache_->AddColumn(r, j, f, u);
      if (r == b || !cache_->RowReady(rb / 3, r) || !cache_->RowReady(rr / 3, r)) continue;
      // Shift: swap the row blocks of b and r in r's column.
      for (int i = 0; i < 3; ++i) {
        const double g_rr = cache_->Value(rr + i, r, j), g_br = cache_->Value(rb + i, r, j);
        u[rb + i] += f * (g_rr - g_br);
        u[rr + i] += f * (g_br - g_rr);
      }
    }
  }
}

Eigen::MatrixXd CachedContactSolver::ContactBlock() const {
  Eigen::MatrixXd m(3 * k_, 3 * k_);
  for (int i = 0; i < k_; ++i)
    for (int j = 0; j <= i; ++j) {
      const Eigen::Matrix3d b = PairBlock(i, j);
      m.block<3, 3>(3 * i, 3 * j) = b;
      m.block<3, 3>(3 * j, 3 * i) = b.transpose();
    }
  return m;
}

}  // namespace spidarcad::fem
