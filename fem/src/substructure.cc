// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/substructure.h"

#include <cholmod.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <functional>
#include <map>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <tuple>
#include <utility>

#include "solve_checks.h"
#include "spidarcad/base/every_core.h"
#include "spidarcad/fem/blas_kernels.h"
#include "spidarcad/fem/cache_file.h"
#include "spidarcad/fem/precompute_cache.h"

// LAPACK (in OpenBLAS, linked by this library for CHOLMOD): A := U Uᵀ for the upper triangle U
// of A (n³/3 flops, a third of a general product).
extern "C" void dlauum_(const char* uplo, const int* n, double* a, const int* lda, int* info);
// LAPACK and BLAS for the block tridiagonal interface factor: Cholesky of a dense block, a
// triangular solve from the right, and a symmetric rank-k update (lower triangles).
extern "C" void dpotrf_(const char* uplo, const int* n, double* a, const int* lda, int* info);
extern "C" void dtrsm_(const char* side, const char* uplo, const char* transa, const char* diag,
                       const int* m, const int* n, const double* alpha, const double* a,
                       const int* lda, double* b, const int* ldb);
extern "C" void dsyrk_(const char* uplo, const char* trans, const int* n, const int* k,
                       const double* alpha, const double* a, const int* lda, const double* beta,
                       double* c, const int* ldc);
// And for its solves, a general product (C := α op(A) B + β C).
extern "C" void dgemm_(const char* transa, const char* transb, const int* m, const int* n,
                       const int* k, const double* alpha, const double* a, const int* lda,
                       const double* b, const int* ldb, const double* beta, double* c,
                       const int* ldc);

namespace spidarcad::fem {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Row copies between column-major matrices (right-hand sides of up to ~50 columns and 10⁵ rows),
// done a column at a time: a row at a time would touch one cache line per column.
// dst.row(p) = src.row(rows[p]) for p < count.
template <class Src, class Dst>
void GatherRows(const Src& src, const int* rows, int count, Dst&& dst) {
  for (Eigen::Index c = 0; c < src.cols(); ++c)
    for (int p = 0; p < count; ++p) dst(p, c) = src(rows[p], c);
}
// dst.row(rows[p]) = src.row(p) for p < count.
template <class Src, class Dst>
void ScatterRows(const Src& src, const int* rows, int count, Dst&& dst) {
  for (Eigen::Index c = 0; c < src.cols(); ++c)
    for (int p = 0; p < count; ++p) dst(rows[p], c) = src(p, c);
}

// A cholmod_common for one call (CHOLMOD's workspace is per common: a common per call makes
// solves re-entrant, so factors can be shared between solvers and threads).
struct Common {
  cholmod_common c;
  Common() {
    cholmod_start(&c);
    c.print = 0;  // a library writes nothing to stdout/stderr; failures come back as status
  }
  ~Common() { cholmod_finish(&c); }
  Common(const Common&) = delete;
  Common& operator=(const Common&) = delete;
};

// An owned CHOLMOD factor.
struct OwnedFactor {
  cholmod_factor* l = nullptr;
  OwnedFactor() = default;
  ~OwnedFactor() {
    if (l != nullptr) {
      Common common;
      cholmod_free_factor(&l, &common.c);
    }
  }
  OwnedFactor(const OwnedFactor&) = delete;
  OwnedFactor& operator=(const OwnedFactor&) = delete;
};

// A rows × cols matrix of zeros, written rather than read first. A fresh large allocation comes
// straight from mmap (and malloc followed by a fill may be compiled into calloc, which skips the
// fill): a first read maps the shared zero page, and the write after it replaces the page and
// flushes every core's TLB, an interprocessor interrupt per 4 KiB page (the interface's group of
// 2,100 dofs: 35 MB, 0.1 s on a 2-core VM).
Eigen::MatrixXd WrittenZero(Eigen::Index rows, Eigen::Index cols) {
  Eigen::MatrixXd m(rows, cols);
  // The compiler may not merge the allocation and the fill below into calloc across this.
  asm volatile("" : : "r"(m.data()) : "memory");
  m.setZero();
  return m;
}

// CHOLMOD view of a compressed sparse matrix whose lower triangle is used (stype −1).
template <class Sparse>  // SparseMatrixd or a Map of one
cholmod_sparse ViewLower(const Sparse& a) {
  cholmod_sparse s;
  std::memset(&s, 0, sizeof(s));
  s.nrow = static_cast<size_t>(a.rows());
  s.ncol = static_cast<size_t>(a.cols());
  s.nzmax = static_cast<size_t>(a.nonZeros());
  s.p = const_cast<int*>(a.outerIndexPtr());
  s.i = const_cast<int*>(a.innerIndexPtr());
  s.x = const_cast<double*>(a.valuePtr());
  s.stype = -1;
  s.itype = CHOLMOD_INT;
  s.xtype = CHOLMOD_REAL;
  s.dtype = CHOLMOD_DOUBLE;
  s.sorted = 1;
  s.packed = 1;
  return s;
}

// CHOLMOD view of a dense column-major matrix.
cholmod_dense ViewDense(Eigen::MatrixXd* m) {
  cholmod_dense d;
  std::memset(&d, 0, sizeof(d));
  d.nrow = static_cast<size_t>(m->rows());
  d.ncol = static_cast<size_t>(m->cols());
  d.nzmax = static_cast<size_t>(m->size());
  d.d = static_cast<size_t>(m->rows());
  d.x = m->data();
  d.xtype = CHOLMOD_REAL;
  d.dtype = CHOLMOD_DOUBLE;
  return d;
}

// Solves sys (CHOLMOD_A, CHOLMOD_L, CHOLMOD_Lt) with factor l for b in place.
bool CholmodSolve(int sys, cholmod_factor* l, Eigen::MatrixXd* b) {
  if (b->size() == 0) return true;
  Common common;
  cholmod_dense bv = ViewDense(b);
  cholmod_dense* x = cholmod_solve(sys, l, &bv, &common.c);
  if (x == nullptr) return false;
  std::memcpy(b->data(), x->x, sizeof(double) * static_cast<size_t>(b->size()));
  cholmod_free_dense(&x, &common.c);
  return true;
}

// Nonzeros of a supernodal factor's L (its lower trapezoids; CHOLMOD's own count, lnz, is not
// set by a supernodal factorisation).
double SupernodalNonzeros(const cholmod_factor* l) {
  if (l == nullptr || !l->is_super) return 0.0;
  const int* super = static_cast<const int*>(l->super);
  const int* pi = static_cast<const int*>(l->pi);
  double nnz = 0.0;
  for (std::size_t s = 0; s < l->nsuper; ++s) {
    const double ncol = super[s + 1] - super[s], nrow = pi[s + 1] - pi[s];
    nnz += ncol * nrow - 0.5 * ncol * (ncol - 1.0);
  }
  return nnz;
}

// Values below this fraction of max diag K_ΓΓ are the interface shift σ (see the header).
constexpr double kInterfaceShift = 1e-6;

const char* const kAxis[3] = {"x", "y", "z"};

std::string Point(const Eigen::Vector3d& p) {
  std::ostringstream s;
  s.precision(4);
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

// Node flags of a block's content: prescribed axes (bits 0..2), interface node (bit 3).
constexpr unsigned char kInterfaceFlag = 8;

// A fill-reducing order of a block's interior dofs (`interior`: local dofs 3·node + axis,
// ascending, so a node's dofs are consecutive) from the graph of the nodes they belong to (two
// nodes adjacent when an element holds both; `connectivity`: #elements × npe local nodes): METIS
// nested dissection on that graph (CHOLMOD's cholmod_metis, AMD if METIS fails), each node's
// dofs kept together. Returns, for each factor position, the interior index (into `interior`)
// eliminated there. It needs no stiffness values, so it runs beside the assembly. On the graph
// of nodes rather than of dofs METIS sees a ninth of the edges, and its order fills less than
// CHOLMOD's default (AMD on the dofs): on the platform's bracket slab (P2, 10 mm) the numeric
// factorisation fell from 0.95 to 0.66 s (docs/design/2026-12-06-node-order.md).
std::vector<int> InteriorNodeOrder(const std::vector<int>& interior,
                                   const std::vector<int>& connectivity, int npe, int num_nodes) {
  const int ni = static_cast<int>(interior.size());
  std::vector<int> order;
  order.reserve(ni);
  if (ni == 0) return order;
  std::vector<int> id(num_nodes, -1), start, count;
  for (int i = 0; i < ni; ++i) {
    const int v = interior[i] / 3;
    if (id[v] < 0) {
      id[v] = static_cast<int>(start.size());
      start.push_back(i);
      count.push_back(0);
    }
    ++count[id[v]];
  }
  const int m = static_cast<int>(start.size());
  // The graph in compressed columns (both triangles; cholmod_metis reads the upper one).
  const int ne = npe > 0 ? static_cast<int>(connectivity.size()) / npe : 0;
  std::vector<int> colp(m + 1, 0), l;
  l.reserve(npe);
  auto element_nodes = [&](int e) {
    l.clear();
    for (int j = 0; j < npe; ++j) {
      const int w = id[connectivity[static_cast<std::size_t>(e) * npe + j]];
      if (w >= 0) l.push_back(w);
    }
  };
  for (int e = 0; e < ne; ++e) {
    element_nodes(e);
    for (int a : l) colp[a + 1] += static_cast<int>(l.size()) - 1;
  }
  for (int a = 0; a < m; ++a) colp[a + 1] += colp[a];
  std::vector<int> rows(colp[m]), fill(colp.begin(), colp.end() - 1);
  for (int e = 0; e < ne; ++e) {
    element_nodes(e);
    for (int a : l)
      for (int b : l)
        if (a != b) rows[fill[a]++] = b;
  }
  int nz = 0;
  for (int a = 0; a < m; ++a) {
    const auto first = rows.begin() + colp[a], last = rows.begin() + colp[a + 1];
    std::sort(first, last);
    const int kept = static_cast<int>(std::unique(first, last) - first);
    if (nz != colp[a]) std::copy(first, first + kept, rows.begin() + nz);
    colp[a] = nz;
    nz += kept;
  }
  colp[m] = nz;
  cholmod_sparse graph{};
  graph.nrow = graph.ncol = static_cast<std::size_t>(m);
  graph.nzmax = static_cast<std::size_t>(nz);
  graph.p = colp.data();
  graph.i = rows.data();
  graph.stype = 1;
  graph.itype = CHOLMOD_INT;
  graph.xtype = CHOLMOD_PATTERN;
  graph.dtype = CHOLMOD_DOUBLE;
  graph.sorted = 1;
  graph.packed = 1;
  std::vector<int> node_perm(m);
  Common common;
  {
    // METIS 5.1 draws from one random generator for the whole process, seeded at the start of
    // each call: two calls at once (blocks factored on two threads) would draw from each other's
    // sequence, and the orders, the factors and the solves would no longer be the same each run.
    static std::mutex metis_mutex;
    const std::lock_guard<std::mutex> lock(metis_mutex);
    if (!cholmod_metis(&graph, nullptr, 0, 1, node_perm.data(), &common.c) &&
        !cholmod_amd(&graph, nullptr, 0, node_perm.data(), &common.c))
      throw std::runtime_error("substructure: no fill-reducing order of a block's nodes");
  }
  for (int w : node_perm)
    for (int c = 0; c < count[w]; ++c) order.push_back(start[w] + c);
  return order;
}

// Block files (SubstructuredSolver's cache directory): magic, format version, and the CHOLMOD
// version that laid out the factor.
constexpr char kBlockFileMagic[8] = {'S', 'P', 'D', 'B', 'L', 'K', '0', '1'};
// Interface plane files: a chain interface's factor blocks L_gg, L_{g,g−1} of one group.
constexpr char kPlaneFileMagic[8] = {'S', 'P', 'D', 'P', 'L', 'N', '0', '1'};
constexpr std::uint64_t kPlaneFileVersion = 3;  // 3: a plane's dofs ordered by position
constexpr std::uint32_t kBlockFileVersion = 3;
constexpr int kCholmodVersion[3] = {CHOLMOD_MAIN_VERSION, CHOLMOD_SUB_VERSION,
                                    CHOLMOD_SUBSUB_VERSION};

}  // namespace

// The content of a block (see the header) and everything factored from it; immutable once
// made, shared between solvers whose blocks have the same content.
struct SubstructuredSolver::BlockFactor {
  // Content.
  int npe = 0;
  std::vector<int> connectivity;     // #elements × npe, local node numbers
  std::vector<double> positions;     // 3 per local node
  std::vector<double> materials;     // E, ν, formulation per element
  std::vector<unsigned char> flags;  // per local node
  std::uint64_t key = 0;

  // Local dofs (3·local node + axis): free interior dofs, free interface dofs, each ascending.
  std::vector<int> interior, interface;
  SparseMatrixd k;        // K^b over every local dof (3·#local nodes square, both triangles)
  SparseMatrixd k_ig;     // K^b_IΓ, #interior by #interface
  double ff_norm2 = 0.0;  // ||K^b_ff||_F²
  OwnedFactor factor;     // of A_b = [K_II K_IΓ; K_ΓI K_ΓΓ + σI], interface last (if #I > 0)
  std::vector<int> perm;  // factor's permutation: A index of factor position
  Eigen::MatrixXd schur;  // S_b, #interface square
  // Failure: A index of the first non-positive pivot (−1: factored).
  int failed = -1;
  double factor_nonzeros = 0.0;
  double assembly_seconds = 0.0, factor_seconds = 0.0, schur_seconds = 0.0;

  int num_nodes() const { return static_cast<int>(flags.size()); }
  int ni() const { return static_cast<int>(interior.size()); }
  int ng() const { return static_cast<int>(interface.size()); }

  bool SameContent(const BlockFactor& o) const {
    return key == o.key && npe == o.npe && connectivity == o.connectivity &&
           positions == o.positions && materials == o.materials && flags == o.flags;
  }

  void HashContent() {
    std::uint64_t h = kFnvOffsetBasis;
    h = Fnv1a64(&npe, sizeof(npe), h);
    const std::uint64_t sizes[4] = {connectivity.size(), positions.size(), materials.size(),
                                    flags.size()};
    h = Fnv1a64(sizes, sizeof(sizes), h);
    h = Fnv1a64(connectivity.data(), sizeof(int) * connectivity.size(), h);
    h = Fnv1a64(positions.data(), sizeof(double) * positions.size(), h);
    h = Fnv1a64(materials.data(), sizeof(double) * materials.size(), h);
    key = Fnv1a64(flags.data(), flags.size(), h);
  }

  // K^b over the block's local dofs, from the content.
  void AssembleLocalStiffness() {
    const int n_loc = num_nodes();
    const int ne = npe > 0 ? static_cast<int>(connectivity.size()) / npe : 0;
    TetMesh local;
    local.nodes.resize(n_loc, 3);
    for (int v = 0; v < n_loc; ++v)
      for (int i = 0; i < 3; ++i) local.nodes(v, i) = positions[3 * v + i];
    local.elements.resize(ne, npe);
    for (int e = 0; e < ne; ++e)
      for (int j = 0; j < npe; ++j) local.elements(e, j) = connectivity[e * npe + j];
    // The materials from the content (so the table is local too): one region per distinct
    // (E, ν, formulation), numbered as they first appear.
    local.regions.resize(ne);
    MaterialTable table;
    std::map<std::array<double, 3>, int> region_of;  // (E, ν, formulation) -> region
    for (int e = 0; e < ne; ++e) {
      const std::array<double, 3> triple = {materials[3 * static_cast<std::size_t>(e)],
                                            materials[3 * static_cast<std::size_t>(e) + 1],
                                            materials[3 * static_cast<std::size_t>(e) + 2]};
      if (!std::isfinite(triple[0] + triple[1] + triple[2]))  // a map cannot order NaN
        throw std::invalid_argument("substructure: element " + std::to_string(e) +
                                    " has a material that is not finite");
      const auto [it, added] = region_of.emplace(triple, static_cast<int>(region_of.size()));
      if (added) {
        Material m;
        m.youngs_modulus = triple[0];
        m.poisson_ratio = triple[1];
        m.formulation = static_cast<Formulation>(static_cast<int>(triple[2]));
        table.Set(it->second, m);
      }
      local.regions(e) = it->second;
    }
    k = AssembleStiffness(local, table);
    k.makeCompressed();
  }

  // The free local dofs (3·node + axis, ascending) from the flags: those of interior nodes and
  // (when `interface_dofs` is given) those of interface nodes.
  void ClassifyDofs(std::vector<int>* interior_dofs, std::vector<int>* interface_dofs) const {
    interior_dofs->clear();
    if (interface_dofs) interface_dofs->clear();
    for (int d = 0; d < 3 * num_nodes(); ++d) {
      const unsigned char f = flags[d / 3];
      if (f & (1u << (d % 3))) continue;
      if (!(f & kInterfaceFlag)) {
        interior_dofs->push_back(d);
      } else if (interface_dofs) {
        interface_dofs->push_back(d);
      }
    }
  }

  // From k and the flags: the dof classes, K^b_IΓ, ||K^b_ff||_F², σ, and A_b's lower triangle
  // (interior first, then interface; empty without interior dofs, when *kgg gets K^b_ΓΓ).
  SparseMatrixd Prepare(double* sigma, Eigen::MatrixXd* kgg) {
    // Local dof classes and the A numbering: interior first, then interface.
    const int nd = 3 * num_nodes();
    ClassifyDofs(&interior, &interface);
    std::vector<int> a_index(nd, -1);
    const int ni_ = ni(), ng_ = ng();
    for (int i = 0; i < ni_; ++i) a_index[interior[i]] = i;
    for (int g = 0; g < ng_; ++g) a_index[interface[g]] = ni_ + g;

    double max_gg = 0.0;
    for (int g = 0; g < ng_; ++g)
      max_gg = std::max(max_gg, std::abs(k.coeff(interface[g], interface[g])));
    *sigma = kInterfaceShift * max_gg;

    std::vector<Eigen::Triplet<double, int>> ta, tig;
    ta.reserve(static_cast<size_t>(k.nonZeros() / 2 + nd));
    ff_norm2 = 0.0;
    *kgg = Eigen::MatrixXd::Zero(ni_ == 0 ? ng_ : 0, ni_ == 0 ? ng_ : 0);
    for (int c = 0; c < k.outerSize(); ++c) {
      const int ac = a_index[c];
      if (ac < 0) continue;
      for (SparseMatrixd::InnerIterator it(k, c); it; ++it) {
        const int ar = a_index[it.row()];
        if (ar < 0) continue;
        ff_norm2 += it.value() * it.value();
        if (ar >= ac) ta.emplace_back(ar, ac, it.value());
        if (ar < ni_ && ac >= ni_) tig.emplace_back(ar, ac - ni_, it.value());
        if (ni_ == 0) (*kgg)(ar, ac) = it.value();
      }
    }
    k_ig.resize(ni_, ng_);
    k_ig.setFromTriplets(tig.begin(), tig.end());
    k_ig.makeCompressed();
    SparseMatrixd a;
    if (ni_ == 0) return a;
    for (int g = 0; g < ng_; ++g) ta.emplace_back(ni_ + g, ni_ + g, *sigma);
    a.resize(ni_ + ng_, ni_ + ng_);
    a.setFromTriplets(ta.begin(), ta.end());
    a.makeCompressed();
    return a;
  }

  // CHOLMOD's supernodal symbolic factor of A with the order `perm` (interface last, kept).
  cholmod_factor* Analyze(const SparseMatrixd& a) {
    Common common;
    common.c.nmethods = 1;
    common.c.method[0].ordering = CHOLMOD_GIVEN;
    common.c.postorder = 0;  // keep the interface last
    common.c.supernodal = CHOLMOD_SUPERNODAL;
    cholmod_sparse view = ViewLower(a);
    cholmod_factor* l = cholmod_analyze_p(&view, perm.data(), nullptr, 0, &common.c);
    if (l == nullptr) throw std::runtime_error("substructure: CHOLMOD analysis failed");
    const int* lp = static_cast<const int*>(l->Perm);
    for (int p = 0; p < static_cast<int>(perm.size()); ++p) {
      if (lp[p] != perm[p]) {
        cholmod_free_factor(&l, &common.c);
        throw std::logic_error("substructure: CHOLMOD changed the order");
      }
    }
    return l;
  }

  // Assembles and factors (content already set).
  void Factor() {
    const auto t0 = Clock::now();
    // The fill-reducing order of K_II (InteriorNodeOrder) needs only the connectivity and the
    // flags: a thread of its own computes it while this one assembles.
    std::vector<int> node_order, dofs;
    ClassifyDofs(&dofs, nullptr);  // the thread's own copy: Prepare rewrites `interior`
    std::exception_ptr order_error;
    auto order_nodes = [this, &node_order, &order_error, &dofs] {
      try {
        node_order = InteriorNodeOrder(dofs, connectivity, npe, num_nodes());
      } catch (...) {
        order_error = std::current_exception();
      }
    };
    std::thread orderer;
    try {
      orderer = std::thread(order_nodes);
    } catch (const std::system_error&) {
      order_nodes();  // no thread to be had: in turn
    }
    struct Joiner {
      std::thread* t;
      ~Joiner() {
        if (t->joinable()) t->join();
      }
    } joiner{&orderer};
    AssembleLocalStiffness();
    double sigma = 0.0;
    Eigen::MatrixXd kgg;
    const SparseMatrixd a = Prepare(&sigma, &kgg);
    const int ni_ = ni(), ng_ = ng();
    assembly_seconds = Seconds(t0);

    const auto t1 = Clock::now();
    if (orderer.joinable()) orderer.join();
    if (order_error) std::rethrow_exception(order_error);
    if (ni_ == 0) {
      schur = kgg;  // nothing to condense
      factor_seconds = Seconds(t1);
      return;
    }

    // K_II in the nodes' fill-reducing order, then the interface in order.
    if (static_cast<int>(node_order.size()) != ni_)
      throw std::logic_error("substructure: the node order misses interior dofs");
    perm.resize(ni_ + ng_);
    std::copy(node_order.begin(), node_order.end(), perm.begin());
    for (int g = 0; g < ng_; ++g) perm[ni_ + g] = ni_ + g;

    factor.l = Analyze(a);
    Common common;
    cholmod_sparse view = ViewLower(a);
    cholmod_factorize(&view, factor.l, &common.c);
    factor_nonzeros = SupernodalNonzeros(factor.l);
    if (factor.l->minor < factor.l->n) {
      failed = perm[factor.l->minor];
      factor_seconds = Seconds(t1);
      return;
    }
    if (!factor.l->is_super) throw std::logic_error("substructure: factor is not supernodal");

    factor_seconds = Seconds(t1);

    // L_ΓΓ: the trailing interface columns of the supernodes; S_b = L_ΓΓ L_ΓΓᵀ − σ I. The product
    // is LAPACK's U Uᵀ of the reversed factor U = J L_ΓΓ J (J the reversal: U is upper
    // triangular and J U Uᵀ J = L_ΓΓ L_ΓΓᵀ).
    const auto t2 = Clock::now();
    Eigen::MatrixXd u = WrittenZero(ng_, ng_);
    const int* super = static_cast<const int*>(factor.l->super);
    const int* pi = static_cast<const int*>(factor.l->pi);
    const int* px = static_cast<const int*>(factor.l->px);
    const int* ls = static_cast<const int*>(factor.l->s);
    const double* lx = static_cast<const double*>(factor.l->x);
    const int last = ni_ + ng_ - 1;
    for (size_t s = 0; s < factor.l->nsuper; ++s) {
      const int k1 = super[s], k2 = super[s + 1];
      if (k2 <= ni_) continue;
      const int nrow = pi[s + 1] - pi[s];
      for (int j = std::max(k1, ni_); j < k2; ++j) {
        const double* col = lx + px[s] + static_cast<size_t>(j - k1) * nrow;
        for (int r = 0; r < nrow; ++r) {
          const int row = ls[pi[s] + r];
          if (row >= j) u(last - row, last - j) = col[r];
        }
      }
    }
    schur.resize(ng_, ng_);
    if (ng_ > 0) {
      const char uplo = 'U';
      int info = 0;
      dlauum_(&uplo, &ng_, u.data(), &ng_, &info);
      if (info != 0) throw std::runtime_error("substructure: LAPACK dlauum failed");
      for (int j = 0; j < ng_; ++j)
        for (int i = 0; i <= j; ++i)
          schur(ng_ - 1 - i, ng_ - 1 - j) = schur(ng_ - 1 - j, ng_ - 1 - i) = u(i, j);
      schur.diagonal().array() -= sigma;
    }
    schur_seconds = Seconds(t2);
  }

  // The block file body (see BlockFileMagic): content, k, the order, S_b and the supernodal
  // factor's layout and values. Only for a block that factored.
  std::vector<unsigned char> Serialize() const {
    ByteWriter w;
    w.Put(kBlockFileVersion);
    w.Put(key);
    w.PutArray(kCholmodVersion, 3);
    w.Put(static_cast<std::int32_t>(npe));
    w.PutVector(connectivity);
    w.PutVector(positions);
    w.PutVector(materials);
    w.PutVector(flags);
    w.Put(static_cast<std::int64_t>(k.rows()));
    w.Put(static_cast<std::int64_t>(k.nonZeros()));
    w.PutArray(k.outerIndexPtr(), static_cast<std::size_t>(k.cols()) + 1);
    w.PutArray(k.innerIndexPtr(), static_cast<std::size_t>(k.nonZeros()));
    w.PutArray(k.valuePtr(), static_cast<std::size_t>(k.nonZeros()));
    w.PutVector(perm);
    w.Put(static_cast<std::int64_t>(schur.rows()));
    for (Eigen::Index j = 0; j < schur.cols(); ++j)  // lower triangle (S_b is symmetric)
      w.PutArray(schur.data() + j * schur.rows() + j, static_cast<std::size_t>(schur.rows() - j));
    const cholmod_factor* l = factor.l;
    const std::uint64_t nsuper = l ? l->nsuper : 0, xsize = l ? l->xsize : 0;
    w.Put(nsuper);
    w.Put(xsize);
    if (l) {
      const int* super = static_cast<const int*>(l->super);
      const int* pi = static_cast<const int*>(l->pi);
      const int* px = static_cast<const int*>(l->px);
      const double* x = static_cast<const double*>(l->x);
      const int* rows = static_cast<const int*>(l->s);
      w.PutArray(super, nsuper + 1);
      w.PutArray(pi, nsuper + 1);
      // L_II alone: each supernode's interior columns from the diagonal down to the last
      // interior row. SolveInterior reads nothing else (its interface rows are zero on the way
      // back), and S_b is kept apart; the rest is half the factor where the interface is large.
      const int ni_ = ni();
      for (std::size_t s = 0; s < nsuper; ++s) {
        const int ncol = super[s + 1] - super[s], nrow = pi[s + 1] - pi[s];
        const int nrow_i =
            static_cast<int>(std::lower_bound(rows + pi[s], rows + pi[s + 1], ni_) - rows - pi[s]);
        for (int j = 0; j < ncol && super[s] + j < ni_; ++j)
          w.PutArray(x + px[s] + static_cast<std::size_t>(j) * nrow + j, nrow_i - j);
      }
    }
    w.Put(factor_nonzeros);
    w.Put(assembly_seconds);
    w.Put(factor_seconds);
    w.Put(schur_seconds);
    return std::move(w.bytes());
  }

  // A block of `content` from a file body; nothing, with the reason, when the body is not for
  // this content (another key, content, format or CHOLMOD version) or does not fit together.
  static std::shared_ptr<BlockFactor> Deserialize(const MappedCacheFile& body,
                                                  const BlockFactor& content, std::string* why) {
    ByteReader r(body.data(), body.size());
    auto fail = [&](const std::string& reason) -> std::shared_ptr<BlockFactor> {
      *why = reason;
      return nullptr;
    };
    std::uint32_t version = 0;
    std::uint64_t file_key = 0;
    int cholmod_version[3] = {0, 0, 0};
    if (!r.Get(&version) || version != kBlockFileVersion)
      return fail("format version " + std::to_string(version) + ", expected " +
                  std::to_string(kBlockFileVersion));
    if (!r.Get(&file_key) || file_key != content.key)
      return fail("holds key " + HexKey(file_key) + ", expected " + HexKey(content.key));
    if (!r.GetArray(cholmod_version, 3) ||
        !std::equal(cholmod_version, cholmod_version + 3, kCholmodVersion))
      return fail("written with CHOLMOD " + std::to_string(cholmod_version[0]) + "." +
                  std::to_string(cholmod_version[1]) + "." + std::to_string(cholmod_version[2]));
    auto b = std::make_shared<BlockFactor>();
    std::int32_t file_npe = 0;
    if (!r.Get(&file_npe) || !r.GetVector(&b->connectivity) || !r.GetVector(&b->positions) ||
        !r.GetVector(&b->materials) || !r.GetVector(&b->flags))
      return fail("truncated content");
    b->npe = file_npe;
    b->key = file_key;
    if (!b->SameContent(content)) return fail("its block differs (a hash collision)");
    std::int64_t n = 0, nnz = 0;
    if (!r.Get(&n) || !r.Get(&nnz) || n != 3 * b->num_nodes() || nnz < 0 ||
        static_cast<std::uint64_t>(nnz) > r.remaining())
      return fail("bad stiffness size");
    b->k.resize(n, n);
    b->k.resizeNonZeros(nnz);
    if (!r.GetArray(b->k.outerIndexPtr(), static_cast<std::size_t>(n) + 1) ||
        !r.GetArray(b->k.innerIndexPtr(), static_cast<std::size_t>(nnz)) ||
        !r.GetArray(b->k.valuePtr(), static_cast<std::size_t>(nnz)))
      return fail("truncated stiffness");
    const int* outer = b->k.outerIndexPtr();
    for (std::int64_t c = 0; c < n; ++c)
      if (outer[c] < 0 || outer[c] > outer[c + 1]) return fail("bad stiffness columns");
    if (outer[0] != 0 || outer[n] != nnz) return fail("bad stiffness columns");
    for (std::int64_t i = 0; i < nnz; ++i)
      if (b->k.innerIndexPtr()[i] < 0 || b->k.innerIndexPtr()[i] >= n)
        return fail("bad stiffness rows");
    double sigma = 0.0;
    Eigen::MatrixXd kgg;
    const SparseMatrixd a = b->Prepare(&sigma, &kgg);
    const int ni_ = b->ni(), ng_ = b->ng();
    std::int64_t schur_rows = 0;
    if (!r.GetVector(&b->perm) || !r.Get(&schur_rows) || schur_rows != ng_)
      return fail("bad order or Schur complement size");
    b->schur.resize(ng_, ng_);
    for (int j = 0; j < ng_; ++j) {
      if (!r.GetArray(b->schur.data() + static_cast<std::size_t>(j) * ng_ + j,
                      static_cast<std::size_t>(ng_ - j)))
        return fail("truncated Schur complement");
      for (int i = j + 1; i < ng_; ++i) b->schur(j, i) = b->schur(i, j);
    }
    std::uint64_t nsuper = 0, xsize = 0;
    if (!r.Get(&nsuper) || !r.Get(&xsize)) return fail("truncated factor");
    if (ni_ == 0) {
      if (nsuper != 0 || !b->perm.empty()) return fail("a factor for a block with no interior");
    } else {
      // The order: a permutation of A's indices with the interface last in order.
      const int na = ni_ + ng_;
      std::vector<char> seen(na, 0);
      if (static_cast<int>(b->perm.size()) != na) return fail("bad order size");
      for (int p = 0; p < na; ++p) {
        const int q = b->perm[p];
        if (q < 0 || q >= na || seen[q] || (p >= ni_ && q != p)) return fail("bad order");
        seen[q] = 1;
      }
      // The layout CHOLMOD makes of A in this order must be the file's (same version, same
      // pattern: always, unless the file is not for this block); then its values are the file's.
      std::vector<int> super(nsuper + 1), pi(nsuper + 1);
      if (nsuper > static_cast<std::uint64_t>(na) || !r.GetArray(super.data(), nsuper + 1) ||
          !r.GetArray(pi.data(), nsuper + 1))
        return fail("truncated factor");
      b->factor.l = b->Analyze(a);
      cholmod_factor* l = b->factor.l;
      if (l->nsuper != nsuper || l->xsize != xsize ||
          !std::equal(super.begin(), super.end(), static_cast<const int*>(l->super)) ||
          !std::equal(pi.begin(), pi.end(), static_cast<const int*>(l->pi)))
        return fail("its supernodes differ from CHOLMOD's analysis of the block");
      Common common;
      if (!cholmod_change_factor(CHOLMOD_REAL, 1, 1, 1, 1, l, &common.c) || l->x == nullptr)
        return fail("out of memory for the factor");
      // L_II (see Serialize); the interface rows zero and L_ΓΓ the identity, so that the
      // sweeps of SolveInterior give what they give with the whole factor, bit for bit.
      double* x = static_cast<double*>(l->x);
      const int* px = static_cast<const int*>(l->px);
      const int* rows = static_cast<const int*>(l->s);
      std::memset(x, 0, sizeof(double) * xsize);
      for (std::size_t s = 0; s < nsuper; ++s) {
        const int ncol = super[s + 1] - super[s], nrow = pi[s + 1] - pi[s];
        const int nrow_i =
            static_cast<int>(std::lower_bound(rows + pi[s], rows + pi[s + 1], ni_) - rows - pi[s]);
        for (int j = 0; j < ncol; ++j) {
          double* column = x + px[s] + static_cast<std::size_t>(j) * nrow;
          if (super[s] + j >= ni_) {
            column[j] = 1.0;
          } else if (!r.GetArray(column + j, nrow_i - j)) {
            return fail("truncated factor values");
          }
        }
      }
      l->minor = l->n;
    }
    if (!r.Get(&b->factor_nonzeros) || !r.Get(&b->assembly_seconds) || !r.Get(&b->factor_seconds) ||
        !r.Get(&b->schur_seconds) || r.remaining() != 0)
      return fail("bad trailer");
    return b;
  }

  // Y = K_II⁻¹ F (#interior by m) through the factor of A_b: forward sweep on [F; 0], interface
  // rows zeroed, backward sweep (the interior rows of both sweeps see L_II alone).
  bool SolveInterior(const Eigen::MatrixXd& f, Eigen::MatrixXd* y) const {
    const int ni_ = ni(), n = ni_ + ng();
    Eigen::MatrixXd b = Eigen::MatrixXd::Zero(n, f.cols());
    GatherRows(f, perm.data(), ni_, b);
    if (!CholmodSolve(CHOLMOD_L, factor.l, &b)) return false;
    b.bottomRows(n - ni_).setZero();
    if (!CholmodSolve(CHOLMOD_Lt, factor.l, &b)) return false;
    y->resize(ni_, f.cols());
    ScatterRows(b, perm.data(), ni_, *y);
    return true;
  }
};

// Writes cache files (blocks, interface planes) one after the other on a thread of its own
// (one at a time: the disk is the limit, and parallel writes only take the cores from the
// factorisations).
struct SubstructuredSolver::CacheWriter {
  struct Job {
    std::string what;  // "block 3", "interface plane 1"
    std::filesystem::path file;
    const char (*magic)[8] = nullptr;
    std::function<std::vector<unsigned char>()> body;
    bool saved = false;
    std::string error;
    double seconds = 0.0;
  };
  std::mutex mutex;
  std::condition_variable wake;
  std::vector<std::unique_ptr<Job>> jobs;  // in order of Add; the thread takes jobs[next]
  std::size_t next = 0;
  bool closing = false;
  std::thread thread;

  // Writes what is queued and joins (a constructor that throws, e.g. on cancel, leaves no thread
  // running).
  ~CacheWriter() { Finish(); }

  static void Write(Job* job) {
    const auto t0 = Clock::now();
    job->saved = WriteCacheFile(job->file, *job->magic, job->body(), &job->error);
    job->body = nullptr;  // lets go of what it kept alive
    job->seconds = Seconds(t0);
  }
  void Run() {
    for (;;) {
      Job* job = nullptr;
      {
        std::unique_lock<std::mutex> lock(mutex);
        wake.wait(lock, [&] { return next < jobs.size() || closing; });
        if (next == jobs.size()) return;
        job = jobs[next++].get();
      }
      Write(job);
    }
  }
  void Add(std::string what, const std::filesystem::path& file, const char (&magic)[8],
           std::function<std::vector<unsigned char>()> body) {
    auto job = std::make_unique<Job>();
    job->what = std::move(what);
    job->file = file;
    job->magic = &magic;
    job->body = std::move(body);
    {
      std::lock_guard<std::mutex> lock(mutex);
      jobs.push_back(std::move(job));
    }
    wake.notify_one();
    if (thread.joinable()) return;
    try {
      thread = std::thread([this] { Run(); });
    } catch (const std::system_error&) {
      // No thread to be had: write what is queued now.
      std::lock_guard<std::mutex> lock(mutex);
      for (; next < jobs.size(); ++next) Write(jobs[next].get());
    }
  }
  void Finish() {
    {
      std::lock_guard<std::mutex> lock(mutex);
      closing = true;
    }
    wake.notify_one();
    if (thread.joinable()) thread.join();
  }
};

// A block of this solver: its shared factor and where its local dofs sit globally.
struct SubstructuredSolver::Block {
  std::shared_ptr<const BlockFactor> factor;
  std::vector<int> nodes;          // global node of each local node
  std::vector<int> interior_free;  // free index of each interior dof
  std::vector<int> interface_pos;  // Γ position of each interface dof
  BlockStats stats;
};

// The interface system S = Σ_b S_b and its factor: CHOLMOD's in general; for a chain (each
// block's interface dofs in at most two consecutive groups, groups being the dofs that the same
// pair of blocks share: slabs, whose groups are the planes) a block Cholesky factor by groups,
// dense, twisted at one group: the groups before the twist are eliminated from the first group
// on (the forward factor), those after it from the last group back (the backward factor), and the
// twist last. The forward factor's leading groups and the backward factor's trailing groups are
// what an edit elsewhere in the chain leaves as they were, and are then shared instead of
// refactored.
struct SubstructuredSolver::Interface {
  OwnedFactor factor;  // general case

  // Chain case. Each group g holds the Γ positions order[begin[g] .. begin[g+1]).
  // Forward factor: L_gg (lower triangle; of S_gg − L_{g,g−1} L_{g,g−1}ᵀ) and L_{g,g−1}
  // (= S_{g,g−1} L_{g−1,g−1}⁻ᵀ, null for g = 0) with `gram` = L_{g,g−1} L_{g,g−1}ᵀ (lower
  // triangle; null for g = 0). Backward factor: B_gg (lower; of S_gg − M_{g,g+1} M_{g,g+1}ᵀ),
  // M_{g,g+1} = S_{g,g+1} B_{g+1,g+1}⁻ᵀ (null for the last group) and its `b_gram`.
  // `owners` says what S_gg and S_{g,g−1} were summed from: for each dof of the group in order,
  // the (block factor, block, local interface index) of every block holding it; two groups with
  // equal owners (and equal owners of the group before) have S blocks equal bit for bit.
  // `sub_record` says what S_{g,g−1} was summed from (per column of group g − 1 its owners, per
  // block among them where its rows land in group g): two equal records give S_{g,g−1} equal bit
  // for bit, so with the same L_{g−1,g−1} the same L_{g,g−1} and gram, and with the same
  // B_{g,g} the same M_{g−1,g} and b_gram of group g − 1.
  struct Group {
    std::vector<std::tuple<const void*, int, int>> owners;
    std::vector<int> owner_count;  // per dof of the group
    std::vector<std::intptr_t> sub_record;
    std::shared_ptr<const Eigen::MatrixXd> l_diag, l_sub, gram;
    std::shared_ptr<const Eigen::MatrixXd> b_diag, b_sup, b_gram;
  };
  bool chain = false;
  std::vector<int> order, begin;
  std::vector<Group> groups;
  // The twist k and its factor T (lower; of S_kk − L_{k,k−1} L_{k,k−1}ᵀ − M_{k,k+1} M_{k,k+1}ᵀ).
  // A solve uses the forward factor's groups before k (and L_{k,k−1}), the backward factor's
  // after k (and M_{k,k+1}) and T: PrepareReuse fills in the rest of both factors without
  // touching those, so it may run while the solver solves.
  int twist = 0;
  std::shared_ptr<const Eigen::MatrixXd> t_diag;
  // What PrepareReuse needs to sum S's blocks again: per Γ position its owners (block, local
  // index), group and place in the group; and to write forward planes to the cache directory.
  std::vector<std::vector<std::pair<int, int>>> owners;
  std::vector<int> group_of, local_of;
  std::filesystem::path cache_directory;
  std::vector<std::vector<std::uint64_t>> record;  // per group: the owner record of groups 0..g
  std::vector<std::uint64_t> plane_key;
  std::once_flag prepared;
  InterfacePreparation preparation;

  int size(int g) const { return begin[g + 1] - begin[g]; }
  // The cache directory's file of group g's forward factor blocks.
  std::filesystem::path PlaneFile(int g) const {
    return cache_directory / (HexKey(plane_key[g]) + ".plane");
  }

  // X = S⁻¹ B in place (B: ng by m, rows in Γ positions): sweeps by groups towards the twist
  // (forward factor before it, backward factor after it), the twist's two triangular solves,
  // and sweeps away from it; each step a dense triangular solve and product (BLAS: the groups are
  // 10³–10⁴ dofs). With the twist at the last group this is the forward factor's plain forward
  // and backward substitution.
  void SolveChain(Eigen::MatrixXd* b) const {
    const int ng = static_cast<int>(order.size()), m = static_cast<int>(b->cols());
    if (ng == 0 || m == 0) return;
    Eigen::MatrixXd y(ng, m);
    GatherRows(*b, order.data(), ng, y);
    const int n = static_cast<int>(groups.size()), k = twist;
    const char left = 'L', lower = 'L', no_trans = 'N', trans = 'T', non_unit = 'N';
    const double one = 1.0, minus_one = -1.0;
    // y_g −= op(A) y_h, A: size(g) by size(h) (no_trans) or size(h) by size(g) (trans).
    auto subtract = [&](int g, int h, const Eigen::MatrixXd& a, const char* op) {
      const int bg = size(g), bh = size(h);
      if (bg == 0 || bh == 0) return;
      dgemm_(op, &no_trans, &bg, &m, &bh, &minus_one, a.data(), *op == 'N' ? &bg : &bh,
             y.data() + begin[h], &ng, &one, y.data() + begin[g], &ng);
    };
    // y_g = op(L)⁻¹ y_g.
    auto solve = [&](int g, const Eigen::MatrixXd& l, const char* op) {
      const int bg = size(g);
      if (bg == 0) return;
      dtrsm_(&left, &lower, op, &non_unit, &bg, &m, &one, l.data(), &bg, y.data() + begin[g], &ng);
    };
    for (int g = 0; g < k; ++g) {
      if (g > 0) subtract(g, g - 1, *groups[g].l_sub, &no_trans);
      solve(g, *groups[g].l_diag, &no_trans);
    }
    for (int g = n - 1; g > k; --g) {
      if (g + 1 < n) subtract(g, g + 1, *groups[g].b_sup, &no_trans);
      solve(g, *groups[g].b_diag, &no_trans);
    }
    if (k > 0) subtract(k, k - 1, *groups[k].l_sub, &no_trans);
    if (k + 1 < n) subtract(k, k + 1, *groups[k].b_sup, &no_trans);
    solve(k, *t_diag, &no_trans);
    solve(k, *t_diag, &trans);
    for (int g = k - 1; g >= 0; --g) {
      subtract(g, g + 1, *groups[g + 1].l_sub, &trans);
      solve(g, *groups[g].l_diag, &trans);
    }
    for (int g = k + 1; g < n; ++g) {
      subtract(g, g - 1, *groups[g - 1].b_sup, &trans);
      solve(g, *groups[g].b_diag, &trans);
    }
    ScatterRows(y, order.data(), ng, *b);
  }
};

SubstructuredSolver::SubstructuredSolver(const TetMesh& mesh, const MaterialTable& materials,
                                         const BoundaryConditions& bcs,
                                         const Eigen::VectorXi& element_block,
                                         const SubstructuredSolver* reuse,
                                         const std::filesystem::path& cache_directory,
                                         const std::atomic<bool>* cancel,
                                         const std::vector<int>& block_place)
    : bcs_(bcs), interface_(std::make_unique<Interface>()) {
  // Every BLAS call of the set-up on its caller's thread: the blocks are factored one per core
  // (step 3), and the interface's dense factor took up to 1.3 s instead of 0.1 s with OpenBLAS's
  // two threads as soon as another thread wanted a core
  // (docs/design/2026-12-07-edit-critical-path.md).
  const SingleThreadedBlas single_threaded;
  auto check_cancel = [cancel] {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) throw SubstructureCancelled();
  };
  const auto t_start = Clock::now();
  mesh.Validate();
  if (bcs.num_nodes() != mesh.num_nodes()) {
    throw std::invalid_argument("SubstructuredSolver: boundary conditions are for " +
                                std::to_string(bcs.num_nodes()) + " nodes, mesh has " +
                                std::to_string(mesh.num_nodes()));
  }
  if (element_block.size() != mesh.num_elements()) {
    throw std::invalid_argument("SubstructuredSolver: element_block has " +
                                std::to_string(element_block.size()) + " labels, mesh has " +
                                std::to_string(mesh.num_elements()) + " elements");
  }
  int nb = 0;
  for (int e = 0; e < mesh.num_elements(); ++e) {
    if (element_block(e) < 0) {
      throw std::invalid_argument("SubstructuredSolver: element " + std::to_string(e) +
                                  " has block label " + std::to_string(element_block(e)) +
                                  "; labels must be >= 0");
    }
    nb = std::max(nb, element_block(e) + 1);
    materials.Get(mesh.regions(e));
  }
  CheckModelConstrained(mesh, bcs);

  // Free dofs as StaticSolver numbers them.
  const int nv = mesh.num_nodes(), ndof = 3 * nv, npe = mesh.NodesPerElement();
  free_index_.assign(ndof, -1);
  for (int d = 0; d < ndof; ++d) {
    if (bcs.prescribed().count(d)) continue;
    free_index_[d] = static_cast<int>(free_dofs_.size());
    free_dofs_.push_back(d);
  }

  // Interior (block) or interface (−2) node; −1: in no element.
  node_block_.assign(nv, -1);
  std::vector<std::vector<int>> block_elements(nb);
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const int b = element_block(e);
    block_elements[b].push_back(e);
    for (int j = 0; j < npe; ++j) {
      int& nbk = node_block_[mesh.elements(e, j)];
      if (nbk == -1) {
        nbk = b;
      } else if (nbk != b) {
        nbk = -2;
      }
    }
  }
  interface_index_.assign(free_dofs_.size(), -1);
  for (int i = 0; i < num_free(); ++i) {
    if (node_block_[free_dofs_[i] / 3] != -2) continue;
    interface_index_[i] = static_cast<int>(interface_free_.size());
    interface_free_.push_back(i);
  }

  // Blocks of the reuse solver by key.
  std::multimap<std::uint64_t, std::shared_ptr<const BlockFactor>> old;
  if (reuse != nullptr) {
    for (const Block& b : reuse->blocks_)
      if (b.factor && b.factor->failed < 0) old.emplace(b.factor->key, b.factor);
  }

  if (!block_place.empty()) {
    if (static_cast<int>(block_place.size()) != nb)
      throw std::invalid_argument("SubstructuredSolver: " + std::to_string(block_place.size()) +
                                  " block places for " + std::to_string(nb) + " blocks");
    for (int b = 0; b < nb; ++b)
      if (block_place[b] < 0)
        throw std::invalid_argument("SubstructuredSolver: block " + std::to_string(b) +
                                    " has the negative place " + std::to_string(block_place[b]));
  }
  blocks_.resize(nb);
  stats_.num_blocks = nb;
  // 1. Each block's content, and its factor when the reuse solver has it.
  std::vector<std::shared_ptr<BlockFactor>> contents(nb);
  std::vector<std::shared_ptr<const BlockFactor>> found(nb);
  std::vector<int> local_of(nv, -1);
  for (int b = 0; b < nb; ++b) {
    auto content = std::make_shared<BlockFactor>();
    Block& block = blocks_[b];
    content->npe = npe;
    for (int e : block_elements[b]) {
      for (int j = 0; j < npe; ++j) {
        const int v = mesh.elements(e, j);
        if (local_of[v] < 0) {
          local_of[v] = static_cast<int>(block.nodes.size());
          block.nodes.push_back(v);
        }
        content->connectivity.push_back(local_of[v]);
      }
      const Material& m = materials.Get(mesh.regions(e));
      content->materials.push_back(m.youngs_modulus);
      content->materials.push_back(m.poisson_ratio);
      content->materials.push_back(static_cast<double>(static_cast<int>(m.formulation)));
    }
    for (int v : block.nodes) {
      for (int i = 0; i < 3; ++i) content->positions.push_back(mesh.nodes(v, i));
      unsigned char f = node_block_[v] == -2 ? kInterfaceFlag : 0;
      for (int i = 0; i < 3; ++i)
        if (free_index_[3 * v + i] < 0) f |= static_cast<unsigned char>(1u << i);
      content->flags.push_back(f);
      local_of[v] = -1;
    }
    content->HashContent();
    for (auto [it, end] = old.equal_range(content->key); it != end; ++it) {
      if (it->second->SameContent(*content)) {
        found[b] = it->second;
        break;
      }
    }
    block.stats.reused = found[b] != nullptr;
    if (block.stats.reused) ++stats_.reused_blocks;
    contents[b] = std::move(content);
  }

  // 2. The others from the cache directory, several files at once (mapping, checking and
  // copying a file is bound by memory, not by one core).
  auto file_of = [&](int b) { return cache_directory / (HexKey(contents[b]->key) + ".block"); };
  if (!cache_directory.empty()) {
    std::vector<int> wanted;
    for (int b = 0; b < nb; ++b)
      if (!found[b]) wanted.push_back(b);
    std::vector<std::string> why(nb);
    std::atomic<std::size_t> next{0};
    auto load = [&] {
      for (std::size_t i; (i = next.fetch_add(1)) < wanted.size();) {
        const int b = wanted[i];
        const auto t_read = Clock::now();
        const std::filesystem::path file = file_of(b);
        if (auto body = MapCacheFile(file, kBlockFileMagic, &why[b])) {
          try {
            found[b] = BlockFactor::Deserialize(*body, *contents[b], &why[b]);
          } catch (const std::exception& e) {
            why[b] = e.what();
          }
          if (!found[b]) why[b] = file.string() + ": " + why[b];
        }
        blocks_[b].stats.load_seconds = Seconds(t_read);
      }
    };
    base::RunOnEveryCore(wanted.size(), load);
    for (int b : wanted) {
      Block& block = blocks_[b];
      block.stats.loaded = found[b] != nullptr;
      stats_.cache_read_seconds += block.stats.load_seconds;
      if (found[b]) {
        ++stats_.loaded_blocks;
      } else if (why[b] != "absent") {
        stats_.cache_notes.push_back("block " + std::to_string(b) + ": refused " + why[b]);
      }
    }
  }

  // 3. The rest factored here, one block per core at a time, each with single-threaded BLAS
  // (OpenBLAS's threads under CHOLMOD's supernodes on a 2-core machine spent much of their time
  // waiting for each other, and several times as long as soon as another thread wanted a core).
  // The first failure in block order is thrown once every thread has stopped. Then each is
  // written to the cache directory by the writer's thread.
  {
    std::vector<int> todo;
    for (int b = 0; b < nb; ++b)
      if (!found[b]) todo.push_back(b);
    std::vector<std::exception_ptr> errors(todo.size());
    std::atomic<std::size_t> next{0};
    std::atomic<bool> stop{false};
    auto factor = [&] {
      for (std::size_t i; !stop.load() && (i = next.fetch_add(1)) < todo.size();) {
        try {
          check_cancel();
          contents[todo[i]]->Factor();
        } catch (...) {
          errors[i] = std::current_exception();
          stop.store(true);
        }
      }
    };
    base::RunOnEveryCore(todo.size(), factor);
    for (const std::exception_ptr& error : errors)
      if (error) std::rethrow_exception(error);
  }
  for (int b = 0; b < nb; ++b) {
    Block& block = blocks_[b];
    if (found[b]) {
      block.factor = found[b];
    } else {
      BlockFactor& content = *contents[b];
      block.factor = contents[b];
      ++stats_.factored_blocks;
      stats_.block_assembly_seconds += content.assembly_seconds;
      stats_.block_factor_seconds += content.factor_seconds;
      stats_.block_schur_seconds += content.schur_seconds;
      if (!cache_directory.empty() && content.failed < 0) {
        if (!writer_) writer_ = std::make_unique<CacheWriter>();
        writer_->Add("block " + std::to_string(b), file_of(b), kBlockFileMagic,
                     [factor = std::shared_ptr<const BlockFactor>(contents[b])] {
                       return factor->Serialize();
                     });
      }
    }
    contents[b].reset();
    const BlockFactor& bf = *block.factor;
    for (int d : bf.interior)
      block.interior_free.push_back(free_index_[3 * block.nodes[d / 3] + d % 3]);
    for (int d : bf.interface)
      block.interface_pos.push_back(interface_index_[free_index_[3 * block.nodes[d / 3] + d % 3]]);
    k_norm_ += bf.ff_norm2;
    block.stats.num_elements = static_cast<int>(block_elements[b].size());
    block.stats.num_nodes = bf.num_nodes();
    block.stats.num_interior_dofs = bf.ni();
    block.stats.num_interface_dofs = bf.ng();
    block.stats.factor_nonzeros = bf.factor_nonzeros;
    block.stats.key = bf.key;
    block.stats.assembly_seconds = bf.assembly_seconds;
    block.stats.factor_seconds = bf.factor_seconds;
    block.stats.schur_seconds = bf.schur_seconds;
    if (bf.failed >= 0 && factor_status_.message.empty()) {
      const int d = bf.interior[bf.failed];
      const int v = block.nodes[d / 3];
      factor_status_.message =
          "Cholesky factorisation of block " + std::to_string(b) +
          " failed: the stiffness of its interior is not positive definite (a mechanism inside "
          "the block, or parts of it held only through one or two interface nodes); the first "
          "zero pivot is the " +
          std::string(kAxis[d % 3]) + " displacement of node " + std::to_string(v) + " at " +
          Point(mesh.nodes.row(v).transpose());
    }
  }
  k_norm_ = std::sqrt(k_norm_);

  // S = Σ_b S_b, factored.
  const auto t_s = Clock::now();
  const int ng = static_cast<int>(interface_free_.size());
  stats_.num_free = num_free();
  stats_.num_interface_dofs = ng;
  if (factor_status_.message.empty() && ng > 0) {
    std::vector<std::vector<std::pair<int, int>>> owners(ng);  // (block, local index)
    for (std::size_t b = 0; b < blocks_.size(); ++b)
      for (std::size_t j = 0; j < blocks_[b].interface_pos.size(); ++j)
        owners[blocks_[b].interface_pos[j]].emplace_back(static_cast<int>(b), static_cast<int>(j));
    // Order S by the blocks that share each dof (lowest, then highest block): for slabs this is
    // plane by plane, so S is block tridiagonal and its factor fills nothing beyond the blocks,
    // without a fill-reducing ordering of a matrix of Σ_b #Γ_b² entries (AMD took most of S's
    // time on the platform).
    // Within a pair, by the node's position (x, then y, then z) and the axis: both blocks
    // sharing the dofs see the same nodes at the same places, so an edit of either block that
    // leaves their common nodes as they were orders them the same way, whatever the numbering
    // of the mesh or of either block.
    // With block places (strips of a slab share its place) the pair is of places; dofs that
    // blocks of one place alone share (the strip planes) go with the plane after that place (the
    // one before, for the last place), so that the strips, like their slab, have their interface
    // in two consecutive groups.
    std::vector<int> order(ng);
    std::vector<std::pair<int, int>> pair_of(ng);
    const int last_place = block_place.empty()
                               ? static_cast<int>(blocks_.size()) - 1
                               : *std::max_element(block_place.begin(), block_place.end());
    for (int p = 0; p < ng; ++p) {
      order[p] = p;
      int lo = static_cast<int>(blocks_.size()), hi = -1;
      for (const auto& [b, j] : owners[p]) {
        const int at = block_place.empty() ? b : block_place[b];
        lo = std::min(lo, at);
        hi = std::max(hi, at);
      }
      if (lo == hi) {
        if (lo < last_place) {
          ++hi;
        } else if (lo > 0) {
          --lo;
        }
      }
      pair_of[p] = {lo, hi};
    }
    auto place = [&](int p) {
      const int d = free_dofs_[interface_free_[p]];
      const auto x = mesh.nodes.row(d / 3);
      return std::make_tuple(x(0), x(1), x(2), d % 3);
    };
    std::sort(order.begin(), order.end(), [&](int a, int b) {
      return pair_of[a] != pair_of[b] ? pair_of[a] < pair_of[b] : place(a) < place(b);
    });
    check_cancel();
    if (FactorInterfaceAsChain(mesh, owners, order, pair_of, reuse, cache_directory)) {
      stats_.interface_twist = interface_->twist;
    } else {
      FactorInterfaceWithCholmod(mesh, owners, order);
    }
  }
  stats_.interface_seconds = Seconds(t_s);
  factor_status_.converged = factor_status_.message.empty();
  stats_.wall_seconds = Seconds(t_start);
}

void SubstructuredSolver::FactorInterfaceWithCholmod(
    const TetMesh& mesh, const std::vector<std::vector<std::pair<int, int>>>& owners,
    std::vector<int>& order) {
  const int ng = static_cast<int>(interface_free_.size());
  // Lower triangle of S column by column: the rows of column c are the interface dofs of the
  // blocks that hold c (no triplet sort over Σ_b #Γ_b² entries).
  std::vector<int> outer(ng + 1, 0), inner, mark(ng, -1), rows;
  std::vector<double> values, sum(ng, 0.0);
  for (int c = 0; c < ng; ++c) {
    rows.clear();
    for (const auto& [b, j] : owners[c]) {
      const std::vector<int>& pos = blocks_[b].interface_pos;
      const Eigen::MatrixXd& sb = blocks_[b].factor->schur;
      for (std::size_t i = 0; i < pos.size(); ++i) {
        const int r = pos[i];
        if (r < c) continue;
        if (mark[r] != c) {
          mark[r] = c;
          sum[r] = 0.0;
          rows.push_back(r);
        }
        sum[r] += sb(static_cast<Eigen::Index>(i), j);
      }
    }
    std::sort(rows.begin(), rows.end());
    for (int r : rows) {
      inner.push_back(r);
      values.push_back(sum[r]);
    }
    outer[c + 1] = static_cast<int>(inner.size());
  }
  const Eigen::Map<const SparseMatrixd> s(ng, ng, static_cast<Eigen::Index>(values.size()),
                                          outer.data(), inner.data(), values.data());
  stats_.interface_nonzeros = 2 * s.nonZeros() - ng;
  Common common;
  common.c.supernodal = CHOLMOD_SUPERNODAL;
  common.c.nmethods = 1;
  common.c.method[0].ordering = CHOLMOD_GIVEN;
  cholmod_sparse view = ViewLower(s);
  interface_->factor.l = cholmod_analyze_p(&view, order.data(), nullptr, 0, &common.c);
  if (interface_->factor.l == nullptr)
    throw std::runtime_error("substructure: CHOLMOD analysis of S failed");
  cholmod_factorize(&view, interface_->factor.l, &common.c);
  stats_.interface_factor_nonzeros = SupernodalNonzeros(interface_->factor.l);
  if (interface_->factor.l->minor < interface_->factor.l->n) {
    const int p = static_cast<const int*>(interface_->factor.l->Perm)[interface_->factor.l->minor];
    InterfaceFailure(mesh, p);
  }
}

void SubstructuredSolver::InterfaceFailure(const TetMesh& mesh, int p) {
  const int d = free_dofs_[interface_free_[p]];
  factor_status_.message =
      "Cholesky factorisation of the interface system failed: it is not positive definite "
      "(a mechanism across blocks); the first zero pivot is the " +
      std::string(kAxis[d % 3]) + " displacement of interface node " + std::to_string(d / 3) +
      " at " + Point(mesh.nodes.row(d / 3).transpose());
}

Eigen::MatrixXd SubstructuredSolver::InterfaceBlock(int g, bool coupling_to_previous) const {
  const Interface& in = *interface_;
  // Columns of group g give S_gg; columns of group g − 1 give S_{g,g−1} (its rows in g). Each
  // entry is summed over the blocks holding its column, in block order.
  const int cg = coupling_to_previous ? g - 1 : g;
  Eigen::MatrixXd s = WrittenZero(in.size(g), in.size(cg));
  // Each block's rows in group g, found once: (row of S_b, row of s).
  std::vector<std::vector<std::pair<int, int>>> rows_in_g(blocks_.size());
  std::vector<char> listed(blocks_.size(), 0);
  for (int q = in.begin[cg]; q < in.begin[cg + 1]; ++q) {
    const int c = in.order[q], cc = q - in.begin[cg];
    double* out = s.col(cc).data();
    for (const auto& [b, j] : in.owners[c]) {
      std::vector<std::pair<int, int>>& rows = rows_in_g[b];
      if (!listed[b]) {
        const std::vector<int>& pos = blocks_[b].interface_pos;
        for (std::size_t i = 0; i < pos.size(); ++i)
          if (in.group_of[pos[i]] == g) rows.emplace_back(static_cast<int>(i), in.local_of[pos[i]]);
        listed[b] = 1;
      }
      const Eigen::MatrixXd& sb = blocks_[b].factor->schur;
      const double* column = sb.data() + static_cast<std::ptrdiff_t>(j) * sb.rows();
      for (const auto& [i, r] : rows) out[r] += column[i];
    }
  }
  return s;
}

namespace {

// C = A L⁻ᵀ in place (A: rows by cols, L: cols by cols lower) and its gram C Cᵀ (lower).
std::shared_ptr<const Eigen::MatrixXd> Gram(const Eigen::MatrixXd& l, Eigen::MatrixXd* a) {
  const int rows = static_cast<int>(a->rows()), cols = static_cast<int>(a->cols());
  const char right = 'R', lower = 'L', trans = 'T', no_trans = 'N', non_unit = 'N';
  const double one = 1.0, zero = 0.0;
  dtrsm_(&right, &lower, &trans, &non_unit, &rows, &cols, &one, l.data(), &cols, a->data(), &rows);
  auto gram = std::make_shared<Eigen::MatrixXd>(rows, rows);
  dsyrk_(&lower, &no_trans, &rows, &cols, &one, a->data(), &rows, &zero, gram->data(), &rows);
  return gram;
}

}  // namespace

bool SubstructuredSolver::ForwardCoupling(int g, const Interface* old) const {
  Interface& in = *interface_;
  Interface::Group& group = in.groups[g];
  // Same L_{g−1,g−1} and S_{g,g−1} as the old chain: its L_{g,g−1} and gram.
  if (old != nullptr && g < static_cast<int>(old->groups.size()) && old->groups[g].gram &&
      old->groups[g].l_sub && in.groups[g - 1].l_diag == old->groups[g - 1].l_diag &&
      old->groups[g].sub_record == group.sub_record) {
    group.l_sub = old->groups[g].l_sub;
    group.gram = old->groups[g].gram;
    return true;
  }
  Eigen::MatrixXd sub = InterfaceBlock(g, true);
  if (sub.size() > 0) group.gram = Gram(*in.groups[g - 1].l_diag, &sub);
  group.l_sub = std::make_shared<const Eigen::MatrixXd>(std::move(sub));
  return false;
}

bool SubstructuredSolver::BackwardCoupling(int g, const Interface* old) const {
  Interface& in = *interface_;
  Interface::Group& group = in.groups[g];
  const Interface::Group& next = in.groups[g + 1];
  // Same B_{g+1,g+1} and S_{g+1,g} as the old chain: its M_{g,g+1} and gram.
  if (old != nullptr && old->groups.size() == in.groups.size() && old->groups[g].b_gram &&
      old->groups[g].b_sup && next.b_diag == old->groups[g + 1].b_diag &&
      old->groups[g + 1].sub_record == next.sub_record) {
    group.b_sup = old->groups[g].b_sup;
    group.b_gram = old->groups[g].b_gram;
    return true;
  }
  Eigen::MatrixXd sup = InterfaceBlock(g + 1, true).transpose();
  if (sup.size() > 0) group.b_gram = Gram(*next.b_diag, &sup);
  group.b_sup = std::make_shared<const Eigen::MatrixXd>(std::move(sup));
  return false;
}

std::shared_ptr<const Eigen::MatrixXd> SubstructuredSolver::FactorGroup(
    int g, const Eigen::MatrixXd* gram, const Eigen::MatrixXd* other_gram, int* failed) const {
  const Interface& in = *interface_;
  Eigen::MatrixXd diag = InterfaceBlock(g, false);
  if (gram != nullptr) diag.triangularView<Eigen::Lower>() -= *gram;
  if (other_gram != nullptr) diag.triangularView<Eigen::Lower>() -= *other_gram;
  const int bg = in.size(g);
  const char lower = 'L';
  int info = 0;
  if (bg > 0) dpotrf_(&lower, &bg, diag.data(), &bg, &info);
  if (info < 0) throw std::runtime_error("substructure: LAPACK dpotrf rejected its arguments");
  if (info > 0) {
    *failed = in.order[in.begin[g] + info - 1];
    return nullptr;
  }
  diag.triangularView<Eigen::StrictlyUpper>().setZero();
  return std::make_shared<const Eigen::MatrixXd>(std::move(diag));
}

namespace {

// The body of a plane file: the owner record, then L_gg's lower triangle and L_{g,g−1}.
std::vector<unsigned char> PlaneFileBody(const std::vector<std::uint64_t>& words,
                                         const Eigen::MatrixXd& l_diag,
                                         const Eigen::MatrixXd* l_sub) {
  ByteWriter w;
  w.PutVector(words);
  const auto bg = l_diag.rows(), bp = l_sub != nullptr ? l_sub->cols() : 0;
  w.Put(static_cast<std::int64_t>(bg));
  w.Put(static_cast<std::int64_t>(bp));
  for (Eigen::Index j = 0; j < bg; ++j)  // lower triangle
    w.PutArray(l_diag.data() + j * bg + j, static_cast<std::size_t>(bg - j));
  if (l_sub != nullptr) w.PutArray(l_sub->data(), static_cast<std::size_t>(l_sub->size()));
  return std::move(w.bytes());
}

}  // namespace

bool SubstructuredSolver::FactorInterfaceAsChain(
    const TetMesh& mesh, const std::vector<std::vector<std::pair<int, int>>>& owners,
    const std::vector<int>& order, const std::vector<std::pair<int, int>>& pair_of,
    const SubstructuredSolver* reuse, const std::filesystem::path& cache_directory) {
  const int ng = static_cast<int>(order.size());
  Interface& in = *interface_;
  // Groups: runs of equal block pairs in `order`.
  in.begin.clear();
  std::vector<int> group_of(ng), local_of(ng);
  for (int q = 0; q < ng; ++q) {
    if (q == 0 || pair_of[order[q]] != pair_of[order[q - 1]]) in.begin.push_back(q);
    group_of[order[q]] = static_cast<int>(in.begin.size()) - 1;
    local_of[order[q]] = q - in.begin.back();
  }
  in.begin.push_back(ng);
  const int n = static_cast<int>(in.begin.size()) - 1;
  // A chain: every block's interface dofs lie in one group or two consecutive ones.
  std::vector<int> lowest(blocks_.size()), highest(blocks_.size());  // group of each block
  for (std::size_t b = 0; b < blocks_.size(); ++b) {
    int lo = n, hi = -1;
    for (int p : blocks_[b].interface_pos) {
      lo = std::min(lo, group_of[p]);
      hi = std::max(hi, group_of[p]);
    }
    if (hi - lo > 1) return false;
    lowest[b] = lo;
    highest[b] = hi;
  }
  in.chain = true;
  in.order = order;
  in.owners = owners;
  in.group_of = std::move(group_of);
  in.local_of = std::move(local_of);
  in.cache_directory = cache_directory;
  in.groups.assign(n, {});
  for (int g = 0; g < n; ++g) {
    Interface::Group& group = in.groups[g];
    for (int q = in.begin[g]; q < in.begin[g + 1]; ++q) {
      group.owner_count.push_back(static_cast<int>(owners[order[q]].size()));
      for (const auto& [b, j] : owners[order[q]])
        group.owners.emplace_back(blocks_[b].factor.get(), b, j);
    }
    // What S_{g,g−1} is summed from: the owners of each column of group g − 1 that have rows in
    // group g too (the others add nothing to it), then for each block among them (its factor, in
    // order of first appearance) where its rows land in g.
    if (g == 0) continue;
    group.sub_record.push_back(in.size(g));  // S_{g,g−1}'s rows
    std::vector<int> seen;
    auto coupled = [&](int b) { return lowest[b] == g - 1 && highest[b] == g; };
    for (int q = in.begin[g - 1]; q < in.begin[g]; ++q) {
      const auto& column = owners[order[q]];
      group.sub_record.push_back(std::count_if(
          column.begin(), column.end(), [&](const auto& owner) { return coupled(owner.first); }));
      for (const auto& [b, j] : column) {
        if (!coupled(b)) continue;
        group.sub_record.push_back(reinterpret_cast<std::intptr_t>(blocks_[b].factor.get()));
        group.sub_record.push_back(j);
        if (std::find(seen.begin(), seen.end(), b) == seen.end()) seen.push_back(b);
      }
    }
    for (int b : seen) {
      group.sub_record.push_back(reinterpret_cast<std::intptr_t>(blocks_[b].factor.get()));
      for (int p : blocks_[b].interface_pos)
        group.sub_record.push_back(in.group_of[p] == g ? in.local_of[p] : -1);
    }
  }
  const Interface* old = reuse != nullptr && reuse->interface_ && reuse->interface_->chain
                             ? reuse->interface_.get()
                             : nullptr;
  if (old != nullptr) reuse->PrepareReuse();  // both of its factors, whole
  auto same_owners = [&](int g) {
    return old != nullptr && g < static_cast<int>(old->groups.size()) &&
           old->groups[g].owners == in.groups[g].owners &&
           old->groups[g].owner_count == in.groups[g].owner_count;
  };
  // Leading groups whose S blocks are those of the reuse solver keep its forward factor blocks
  // (L_gg and L_{g,g−1} depend only on S blocks of groups up to g); trailing ones of a chain as
  // long keep its backward factor blocks (B_gg and M_{g,g+1} depend only on groups from g on).
  int shared = 0;  // (a reuse solver whose S failed has no factor blocks from that plane on)
  while (shared < n && same_owners(shared) && old->groups[shared].l_diag) {
    in.groups[shared].l_diag = old->groups[shared].l_diag;
    in.groups[shared].l_sub = old->groups[shared].l_sub;
    in.groups[shared].gram = old->groups[shared].gram;
    ++shared;
  }
  int trailing = 0;
  while (old != nullptr && static_cast<int>(old->groups.size()) == n && trailing < n &&
         same_owners(n - 1 - trailing) && old->groups[n - 1 - trailing].b_diag) {
    const int g = n - 1 - trailing;
    in.groups[g].b_diag = old->groups[g].b_diag;
    in.groups[g].b_sup = old->groups[g].b_sup;
    in.groups[g].b_gram = old->groups[g].b_gram;
    ++trailing;
  }
  stats_.interface_groups = n;
  stats_.reused_interface_groups = shared;
  stats_.reused_trailing_interface_groups = trailing;
  stats_.interface_group_loaded.assign(n, 0);
  // Plane files: group g's forward factor blocks are those of any chain whose groups 0..g have
  // the same owners (blocks by content key, their places in the chain and local indices): the
  // record of groups 0..g, in words, is stored in the file and compared in full; its hash names
  // it.
  in.record.assign(n, {});
  in.plane_key.assign(n, 0);
  if (!cache_directory.empty()) {
    std::vector<std::uint64_t> words = {kPlaneFileVersion};
    for (int g = 0; g < n; ++g) {
      const Interface::Group& group = in.groups[g];
      words.push_back(static_cast<std::uint64_t>(group.owner_count.size()));
      for (int c : group.owner_count) words.push_back(static_cast<std::uint64_t>(c));
      for (const auto& [factor, b, j] : group.owners) {
        words.push_back(blocks_[b].factor->key);
        words.push_back((static_cast<std::uint64_t>(b) << 32) | static_cast<std::uint32_t>(j));
      }
      in.record[g] = words;
      in.plane_key[g] = Fnv1a64(words.data(), sizeof(std::uint64_t) * words.size());
    }
  }
  // Group g's forward factor blocks from its file; false (with a note for a bad file) when absent.
  auto load_plane = [&](int g) {
    const int bg = in.size(g), bp = g > 0 ? in.size(g - 1) : 0;
    std::string why;
    const auto t0 = Clock::now();
    bool ok = false;
    if (auto body = MapCacheFile(in.PlaneFile(g), kPlaneFileMagic, &why)) {
      ByteReader r(body->data(), body->size());
      std::vector<std::uint64_t> stored;
      std::int64_t rows = 0, cols = 0;
      auto diag = std::make_shared<Eigen::MatrixXd>(Eigen::MatrixXd::Zero(bg, bg));
      auto sub = std::make_shared<Eigen::MatrixXd>(bg, bp);
      const char* problem = nullptr;
      if (!r.GetVector(&stored)) {
        problem = "truncated owner record";
      } else if (stored != in.record[g]) {
        problem = "its owner record is not this chain's (a hash collision)";
      } else if (!r.Get(&rows) || !r.Get(&cols) || rows != bg || cols != bp) {
        problem = "bad block sizes";
      }
      for (int j = 0; problem == nullptr && j < bg; ++j) {
        if (!r.GetArray(diag->data() + static_cast<std::size_t>(j) * bg + j,
                        static_cast<std::size_t>(bg - j)))
          problem = "truncated factor";
      }
      if (problem == nullptr &&
          (!r.GetArray(sub->data(), static_cast<std::size_t>(sub->size())) || r.remaining() != 0))
        problem = "truncated or overlong factor";
      ok = problem == nullptr;
      if (ok) {
        in.groups[g].l_diag = std::move(diag);
        if (g > 0) in.groups[g].l_sub = std::move(sub);
      } else {
        why = in.PlaneFile(g).string() + ": " + problem;
      }
    }
    if (!ok && why != "absent")
      stats_.cache_notes.push_back("interface plane " + std::to_string(g) + ": refused " + why);
    stats_.cache_read_seconds += Seconds(t0);
    if (ok) {
      ++stats_.loaded_interface_groups;
      stats_.interface_group_loaded[g] = 1;
    }
    return ok;
  };
  long long nonzeros = 0;
  double factor_nonzeros = 0.0;
  for (int g = 0; g < n; ++g) {
    const int bg = in.size(g), bp = g > 0 ? in.size(g - 1) : 0;
    factor_nonzeros += 0.5 * bg * (bg + 1.0) + double(bg) * bp;
    nonzeros += static_cast<long long>(bg) * bg + 2LL * bg * bp;
  }
  stats_.interface_nonzeros = nonzeros;
  stats_.interface_factor_nonzeros = factor_nonzeros;
  int failed = -1;
  // Group g's forward factor blocks: L_{g,g−1} = S_{g,g−1} L_{g−1,g−1}⁻ᵀ (dtrsm) and
  // L_gg = chol(S_gg − L_{g,g−1} L_{g,g−1}ᵀ) (dsyrk, dpotrf), from the cache directory when a
  // file has them; false on a zero pivot.
  int load_failed = -1;  // a plane whose file was just looked for in vain
  auto forward = [&](int g) {
    if (!cache_directory.empty() && g != load_failed && load_plane(g)) return true;
    if (g > 0 && ForwardCoupling(g, old)) ++stats_.kept_interface_couplings;
    in.groups[g].l_diag = FactorGroup(g, in.groups[g].gram.get(), nullptr, &failed);
    if (!in.groups[g].l_diag) return false;
    ++stats_.factored_interface_groups;
    if (!cache_directory.empty()) {
      if (!writer_) writer_ = std::make_unique<CacheWriter>();
      writer_->Add(
          "interface plane " + std::to_string(g), in.PlaneFile(g), kPlaneFileMagic,
          [words = in.record[g], l_diag = in.groups[g].l_diag, l_sub = in.groups[g].l_sub] {
            return PlaneFileBody(words, *l_diag, l_sub.get());
          });
    }
    return true;
  };
  // Without the old chain's trailing groups: the forward factor, twisted at the last group (as
  // an untwisted Cholesky factor), the leading groups shared or loaded. With them, the changed
  // groups lie between the leading groups kept (or loaded) and the trailing ones: the twist is
  // the first changed group, the groups after it up to the trailing ones get backward factor
  // blocks. Either way each changed group is factored once.
  auto fail = [&] {
    InterfaceFailure(mesh, failed);
    return true;
  };
  if (shared == n && trailing == n) {  // nothing changed: the old twist too
    in.twist = old->twist;
    in.t_diag = old->t_diag;
    return true;
  }
  int k = n - 1;
  if (trailing > 0) {
    while (shared < n && !cache_directory.empty() && load_failed < 0) {
      if (load_plane(shared)) {
        ++shared;
      } else {
        load_failed = shared;
      }
    }
    k = std::min(shared, n - 1);
  }
  for (int g = shared; g < k; ++g)
    if (!forward(g)) return fail();
  in.twist = k;
  if (k == n - 1) {
    if (k >= shared && !forward(k)) return fail();
    in.t_diag = in.groups[k].l_diag;
    return true;
  }
  for (int g = n - 1 - trailing; g > k; --g) {
    if (BackwardCoupling(g, old)) ++stats_.kept_interface_couplings;
    in.groups[g].b_diag = FactorGroup(g, in.groups[g].b_gram.get(), nullptr, &failed);
    if (!in.groups[g].b_diag) return fail();
    ++stats_.factored_interface_groups;
  }
  if (k > 0 && ForwardCoupling(k, old)) ++stats_.kept_interface_couplings;
  if (BackwardCoupling(k, old)) ++stats_.kept_interface_couplings;
  in.t_diag = FactorGroup(k, in.groups[k].gram.get(), in.groups[k].b_gram.get(), &failed);
  if (!in.t_diag) return fail();
  ++stats_.factored_interface_groups;
  return true;
}

const InterfacePreparation& SubstructuredSolver::PrepareReuse() const {
  Interface& in = *interface_;
  std::call_once(in.prepared, [&] {
    if (!in.chain || !factor_status_.converged) return;
    const auto t0 = Clock::now();
    InterfacePreparation& p = in.preparation;
    const int n = static_cast<int>(in.groups.size());
    int failed = -1;
    auto note_failure = [&](const char* which, int g) {
      p.notes.push_back("interface plane " + std::to_string(g) + ": the " + which +
                        " factor failed (a zero pivot at interface position " +
                        std::to_string(failed) + "): not kept for reuse");
    };
    for (int g = 0; g < n; ++g) {  // the forward factor from the twist on
      Interface::Group& group = in.groups[g];
      if (group.l_diag) continue;
      if (g > 0 && !group.l_sub) ForwardCoupling(g, nullptr);
      group.l_diag = FactorGroup(g, group.gram.get(), nullptr, &failed);
      if (!group.l_diag) {
        note_failure("forward", g);
        break;
      }
      ++p.factored_groups;
      if (in.cache_directory.empty()) continue;
      std::string error;
      if (WriteCacheFile(in.PlaneFile(g), kPlaneFileMagic,
                         PlaneFileBody(in.record[g], *group.l_diag, group.l_sub.get()), &error)) {
        ++p.saved_planes;
      } else {
        p.notes.push_back("interface plane " + std::to_string(g) + ": not saved: " + error);
      }
    }
    for (int g = n - 1; g >= 0; --g) {  // the backward factor up to the twist
      Interface::Group& group = in.groups[g];
      if (group.b_diag) continue;
      if (g + 1 < n && !group.b_sup) BackwardCoupling(g, nullptr);
      group.b_diag = FactorGroup(g, group.b_gram.get(), nullptr, &failed);
      if (!group.b_diag) {
        note_failure("backward", g);
        break;
      }
      ++p.factored_groups;
    }
    p.seconds = Seconds(t0);
  });
  return in.preparation;
}

SubstructuredSolver::~SubstructuredSolver() { FinishCacheWrites(); }

const SubstructureStats& SubstructuredSolver::FinishCacheWrites() {
  if (!writer_) return stats_;
  writer_->Finish();
  for (const std::unique_ptr<CacheWriter::Job>& job : writer_->jobs) {
    stats_.cache_write_seconds += job->seconds;
    if (job->saved) {
      ++(job->what.rfind("block", 0) == 0 ? stats_.saved_blocks : stats_.saved_interface_groups);
    } else {
      stats_.cache_notes.push_back(job->what + ": not saved: " + job->error);
    }
  }
  writer_.reset();
  return stats_;
}

const BlockStats& SubstructuredSolver::block_stats(int b) const {
  if (b < 0 || b >= num_blocks())
    throw std::invalid_argument("SubstructuredSolver: no block " + std::to_string(b));
  return blocks_[b].stats;
}

SolveStatus SubstructuredSolver::SolveImpl(const Eigen::MatrixXd& rhs,
                                           const std::vector<char>* wanted,
                                           Eigen::MatrixXd* x) const {
  SolveStatus status;
  if (!detail::CanSolve(factor_status_, rhs.rows(), num_free(), &status)) return status;
  const Eigen::Index m = rhs.cols();
  const int ng = static_cast<int>(interface_free_.size());
  Eigen::MatrixXd g(ng, m);
  GatherRows(rhs, interface_free_.data(), ng, g);
  // y_b = K_II⁻¹ f_I; g −= K_ΓI y_b (blocks without load skipped).
  Eigen::MatrixXd f;
  for (std::size_t b = 0; b < blocks_.size(); ++b) {
    const Block& block = blocks_[b];
    const BlockFactor& bf = *block.factor;
    if (bf.ni() == 0 || bf.ng() == 0) continue;
    f.resize(bf.ni(), m);
    GatherRows(rhs, block.interior_free.data(), bf.ni(), f);
    if (f.isZero(0.0)) continue;
    Eigen::MatrixXd y;
    if (!bf.SolveInterior(f, &y)) {
      status.message = "CHOLMOD solve failed in block " + std::to_string(b);
      return status;
    }
    const Eigen::MatrixXd gy = bf.k_ig.transpose() * y;
    for (Eigen::Index c = 0; c < m; ++c)
      for (int j = 0; j < bf.ng(); ++j) g(block.interface_pos[j], c) -= gy(j, c);
  }
  // u_Γ = S⁻¹ g.
  if (ng > 0 && interface_->chain) {
    interface_->SolveChain(&g);
  } else if (ng > 0 && !CholmodSolve(CHOLMOD_A, interface_->factor.l, &g)) {
    status.message = "CHOLMOD solve of the interface system failed";
    return status;
  }
  x->setZero(num_free(), m);
  ScatterRows(g, interface_free_.data(), ng, *x);
  // u_I = K_II⁻¹ (f_I − K_IΓ u_Γ).
  for (int b = 0; b < num_blocks(); ++b) {
    if (wanted != nullptr && !(*wanted)[b]) continue;
    if (!BackSubstitute(b, rhs, x)) {
      status.message = "CHOLMOD solve failed in block " + std::to_string(b);
      return status;
    }
  }
  status.converged = true;
  return status;
}

bool SubstructuredSolver::BackSubstitute(int b, const Eigen::MatrixXd& rhs,
                                         Eigen::MatrixXd* x) const {
  const Block& block = blocks_[b];
  const BlockFactor& bf = *block.factor;
  if (bf.ni() == 0) return true;
  const Eigen::Index m = rhs.cols();
  Eigen::MatrixXd r(bf.ni(), m);
  GatherRows(rhs, block.interior_free.data(), bf.ni(), r);
  if (bf.ng() > 0) {
    std::vector<int> rows(bf.ng());
    for (int j = 0; j < bf.ng(); ++j) rows[j] = interface_free_[block.interface_pos[j]];
    Eigen::MatrixXd ug(bf.ng(), m);
    GatherRows(*x, rows.data(), bf.ng(), ug);
    r.noalias() -= bf.k_ig * ug;
  }
  if (r.isZero(0.0)) return true;
  Eigen::MatrixXd u;
  if (!bf.SolveInterior(r, &u)) return false;
  ScatterRows(u, block.interior_free.data(), bf.ni(), *x);
  return true;
}

Eigen::MatrixXd SubstructuredSolver::MultiplyFree(const Eigen::MatrixXd& x) const {
  // Row-major copies: a sparse (column-major) times dense product adds whole rows of the dense
  // factor, which are contiguous here; the sums are those of the column-major product, in the
  // same order.
  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const RowMajor xr = x;
  RowMajor y = RowMajor::Zero(x.rows(), x.cols());
  RowMajor xl, yl;
  for (const Block& block : blocks_) {
    const BlockFactor& bf = *block.factor;
    const int nd = 3 * bf.num_nodes();
    xl.setZero(nd, x.cols());
    std::vector<int> free_of(nd, -1);
    for (int d = 0; d < nd; ++d) {
      const int i = free_index_[3 * block.nodes[d / 3] + d % 3];
      if (i < 0) continue;
      free_of[d] = i;
      xl.row(d) = xr.row(i);
    }
    yl.noalias() = bf.k * xl;
    for (int d = 0; d < nd; ++d)
      if (free_of[d] >= 0) y.row(free_of[d]) += yl.row(d);
  }
  return y;
}

Eigen::VectorXd SubstructuredSolver::MultiplyStiffness(const Eigen::VectorXd& u) const {
  Eigen::VectorXd y = Eigen::VectorXd::Zero(u.size());
  for (const Block& block : blocks_) {
    const BlockFactor& bf = *block.factor;
    const int nd = 3 * bf.num_nodes();
    Eigen::VectorXd ul(nd);
    for (int d = 0; d < nd; ++d) ul(d) = u(3 * block.nodes[d / 3] + d % 3);
    const Eigen::VectorXd yl = bf.k * ul;
    for (int d = 0; d < nd; ++d) y(3 * block.nodes[d / 3] + d % 3) += yl(d);
  }
  return y;
}

SolveStatus SubstructuredSolver::SolveFree(const Eigen::MatrixXd& rhs, Eigen::MatrixXd* x) const {
  const SolveStatus status = SolveImpl(rhs, nullptr, x);
  return status.converged ? CheckResidual(rhs, *x) : status;
}

SolveStatus SubstructuredSolver::CompleteSolveFree(const Eigen::MatrixXd& rhs,
                                                   const std::vector<int>& groups,
                                                   Eigen::MatrixXd* x) const {
  SolveStatus status;
  if (!detail::CanSolve(factor_status_, rhs.rows(), num_free(), &status)) return status;
  if (x->rows() != num_free() || x->cols() != rhs.cols())
    throw std::invalid_argument("CompleteSolveFree: X is not the partial solve of these loads");
  const std::vector<char> done = WantedBlocks("CompleteSolveFree", groups);
  for (int b = 0; b < num_blocks(); ++b) {
    if (done[b]) continue;
    if (!BackSubstitute(b, rhs, x)) {
      status.message = "CHOLMOD solve failed in block " + std::to_string(b);
      return status;
    }
  }
  return CheckResidual(rhs, *x);
}

SolveStatus SubstructuredSolver::CheckResidual(const Eigen::MatrixXd& rhs,
                                               const Eigen::MatrixXd& x) const {
  SolveStatus status;
  const Eigen::MatrixXd r = rhs - MultiplyFree(x);
  const double denom = k_norm_ * x.norm() + rhs.norm();
  status.residual = denom > 0.0 ? r.norm() / denom : 0.0;
  status.converged =
      std::isfinite(status.residual) && status.residual < StaticSolver::kResidualTolerance;
  if (!status.converged) {
    std::ostringstream s;
    s << "backward error " << status.residual << " above " << StaticSolver::kResidualTolerance;
    status.message = s.str();
  }
  return status;
}

std::vector<char> SubstructuredSolver::WantedBlocks(const char* who,
                                                    const std::vector<int>& blocks) const {
  std::vector<char> wanted(blocks_.size(), 0);
  for (int b : blocks) {
    if (b < 0 || b >= num_blocks())
      throw std::invalid_argument(std::string(who) + ": no block " + std::to_string(b) + " (0.." +
                                  std::to_string(num_blocks() - 1) + ")");
    wanted[b] = 1;
  }
  return wanted;
}

SolveStatus SubstructuredSolver::SolveFreeInBlocks(const Eigen::MatrixXd& rhs,
                                                   const std::vector<int>& blocks,
                                                   Eigen::MatrixXd* x) const {
  const std::vector<char> wanted = WantedBlocks("SolveFreeInBlocks", blocks);
  return SolveImpl(rhs, &wanted, x);
}

StaticSolution SubstructuredSolver::Solve() const {
  StaticSolution sol;
  const int ndof = static_cast<int>(free_index_.size());
  Eigen::VectorXd u_c = Eigen::VectorXd::Zero(ndof);
  bool moved = false;  // a prescribed displacement is not zero
  for (const auto& [d, value] : bcs_.prescribed()) {
    u_c(d) = value;
    moved = moved || value != 0.0;
  }
  // K·0 is 0: clamps and no loads (a model made only to be touched) need no product at all.
  const Eigen::VectorXd k_uc = moved ? MultiplyStiffness(u_c) : Eigen::VectorXd::Zero(ndof);
  Eigen::VectorXd rhs(num_free());
  for (int i = 0; i < num_free(); ++i) rhs(i) = bcs_.loads()(free_dofs_[i]) - k_uc(free_dofs_[i]);
  sol.displacement = u_c;
  const bool loaded = rhs.norm() != 0.0;
  if (!loaded) {
    sol.status.converged = factor_status_.converged;
    sol.status.message = factor_status_.message;
  } else {
    Eigen::MatrixXd x;
    sol.status = SolveFree(rhs, &x);
    if (x.size() == num_free())
      for (int i = 0; i < num_free(); ++i) sol.displacement(free_dofs_[i]) = x(i, 0);
  }
  sol.reaction =
      (moved || loaded ? MultiplyStiffness(sol.displacement) : Eigen::VectorXd::Zero(ndof).eval()) -
      bcs_.loads();
  for (int d : free_dofs_) sol.reaction(d) = 0.0;
  return sol;
}

Eigen::VectorXi SlabBlocks(const TetMesh& mesh, int axis, const std::vector<double>& planes) {
  if (axis < 0 || axis > 2)
    throw std::invalid_argument("SlabBlocks: axis must be 0, 1 or 2, got " + std::to_string(axis));
  if (!std::is_sorted(planes.begin(), planes.end()))
    throw std::invalid_argument("SlabBlocks: the planes must be sorted");
  Eigen::VectorXi blocks(mesh.num_elements());
  for (int e = 0; e < mesh.num_elements(); ++e) {
    double c = 0.0;
    for (int j = 0; j < 4; ++j) c += 0.25 * mesh.nodes(mesh.elements(e, j), axis);
    blocks(e) =
        static_cast<int>(std::upper_bound(planes.begin(), planes.end(), c) - planes.begin());
  }
  return blocks;
}

std::vector<double> EvenPlanes(const TetMesh& mesh, int axis, int count) {
  if (axis < 0 || axis > 2)
    throw std::invalid_argument("EvenPlanes: axis must be 0, 1 or 2, got " + std::to_string(axis));
  std::vector<double> planes;
  if (mesh.num_nodes() == 0 || count < 2) return planes;
  const double lo = mesh.nodes.col(axis).minCoeff(), hi = mesh.nodes.col(axis).maxCoeff();
  for (int i = 1; i < count; ++i) planes.push_back(lo + (hi - lo) * i / count);
  return planes;
}

}  // namespace spidarcad::fem
