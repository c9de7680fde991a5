// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/cholesky_factor.h"

#include <Eigen/CholmodSupport>
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

namespace spidarcad::fem {
namespace {

// CHOLMOD's factor object is protected in Eigen's wrapper: read it, and adopt a rebuilt one.
class FactorLlt : public Eigen::CholmodSupernodalLLT<SparseMatrixd, Eigen::Lower> {
 public:
  const cholmod_factor* factor() const { return m_cholmodFactor; }
  // (CholmodSupernodalLLT hides m_cholmod; its accessor is not const, the object is mutable.)
  cholmod_common* common() const { return &const_cast<FactorLlt*>(this)->cholmod(); }
  // Takes `f` (allocated with common()) as this object's factorisation.
  void Adopt(cholmod_factor* f) {
    if (m_cholmodFactor != nullptr) cholmod_free_factor(&m_cholmodFactor, common());
    m_cholmodFactor = f;
    m_isInitialized = true;
    m_info = f->minor == f->n ? Eigen::Success : Eigen::NumericalIssue;
    m_analysisIsOk = true;
    m_factorizationIsOk = true;
  }
};

constexpr std::uint64_t kMagic = (std::uint64_t{0x46435053} << 32) | 1;  // "SPCF", version 1

// Header words.
enum Word : std::size_t {
  kMagicWord,
  kN,
  kFailedColumn,
  kOk,
  kNonzeros,
  kPeakBytes,
  kMinor,
  kNsuper,
  kSsize,
  kXsize,
  kMaxcsize,
  kMaxesize,
  kOrdering,
  kIsLl,
  kIsMonotonic,
  kHasColCount,
  kHasIperm,
  kReserved,
};
static_assert(kReserved + 1 == CholeskyFactor::kFlatHeaderWords);

constexpr std::size_t Padded(std::size_t bytes) { return (bytes + 7) & ~std::size_t{7}; }

// Byte offsets of the arrays after the header, and the total.
struct Layout {
  std::size_t perm = 0, colcount = 0, iperm = 0, super = 0, pi = 0, px = 0, s = 0, x = 0, end = 0;
};

// Callers bound every count by the block's length first, so that nothing here overflows.
Layout MakeLayout(std::size_t n, bool colcount, bool iperm, std::size_t nsuper, std::size_t ssize,
                  std::size_t xsize) {
  Layout l;
  std::size_t at = CholeskyFactor::kFlatHeaderWords * 8;
  const auto take = [&at](std::size_t bytes) {
    const std::size_t here = at;
    at += Padded(bytes);
    return here;
  };
  l.perm = take(4 * n);
  l.colcount = colcount ? take(4 * n) : 0;
  l.iperm = iperm ? take(4 * n) : 0;
  l.super = take(4 * (nsuper + 1));
  l.pi = take(4 * (nsuper + 1));
  l.px = take(4 * (nsuper + 1));
  l.s = take(4 * ssize);
  l.x = take(8 * xsize);
  l.end = at;
  return l;
}

Layout LayoutOf(const cholmod_factor& f) {
  return MakeLayout(f.n, f.ColCount != nullptr, f.IPerm != nullptr, f.nsuper, f.ssize, f.xsize);
}

std::uint64_t Bits(double v) {
  std::uint64_t u;
  std::memcpy(&u, &v, 8);
  return u;
}

double FromBits(std::uint64_t u) {
  double v;
  std::memcpy(&v, &u, 8);
  return v;
}

[[noreturn]] void Bad(const std::string& what) {
  throw std::invalid_argument("CholeskyFactor::ReadFlat: " + what);
}

// The int32 array of `count` entries at byte `offset` of the block.
std::vector<std::int32_t> Ints(const char* data, std::size_t offset, std::size_t count) {
  std::vector<std::int32_t> v(count);
  if (count > 0) std::memcpy(v.data(), data + offset, 4 * count);
  return v;
}

// Frees a factor being rebuilt unless released.
struct FactorGuard {
  cholmod_factor* f;
  cholmod_common* c;
  ~FactorGuard() {
    if (f != nullptr) cholmod_free_factor(&f, c);
  }
};

}  // namespace

struct CholeskyFactor::Impl {
  FactorLlt llt;
  bool computed = false;
  bool ok = false;
  int n = 0;
  int failed_column = -1;
  double nonzeros = 0.0;
  double peak_bytes = 0.0;
};

CholeskyFactor::CholeskyFactor() : impl_(std::make_unique<Impl>()) {}
CholeskyFactor::~CholeskyFactor() = default;

bool CholeskyFactor::Compute(const SparseMatrixd& a) {
  Impl& m = *impl_;
  m.llt.compute(a);
  m.computed = true;
  m.n = static_cast<int>(a.rows());
  m.ok = m.llt.info() == Eigen::Success;
  m.failed_column = -1;
  const cholmod_factor* f = m.llt.factor();
  if (f != nullptr && f->minor < f->n) {
    const auto* perm = static_cast<const int*>(f->Perm);
    m.failed_column = perm ? perm[f->minor] : static_cast<int>(f->minor);
  }
  m.nonzeros = m.llt.common()->lnz;
  m.peak_bytes = static_cast<double>(m.llt.common()->memory_usage);
  return m.ok;
}

bool CholeskyFactor::ok() const { return impl_->ok; }
int CholeskyFactor::size() const { return impl_->n; }
int CholeskyFactor::failed_column() const { return impl_->failed_column; }
double CholeskyFactor::nonzeros() const { return impl_->nonzeros; }
double CholeskyFactor::peak_bytes() const { return impl_->peak_bytes; }

Eigen::MatrixXd CholeskyFactor::Solve(const Eigen::MatrixXd& b) const {
  if (!impl_->ok) throw std::logic_error("CholeskyFactor::Solve: no factor of a definite matrix");
  return impl_->llt.solve(b);
}

std::size_t CholeskyFactor::FlatBytes() const {
  const Impl& m = *impl_;
  if (!m.ok) return kFlatHeaderWords * 8;
  return LayoutOf(*m.llt.factor()).end;
}

void CholeskyFactor::WriteFlat(char* out) const {
  const Impl& m = *impl_;
  if (!m.computed) throw std::logic_error("CholeskyFactor::WriteFlat: nothing was factorised");
  std::uint64_t header[kFlatHeaderWords] = {};
  header[kMagicWord] = kMagic;
  header[kN] = static_cast<std::uint64_t>(m.n);
  header[kFailedColumn] = static_cast<std::uint64_t>(static_cast<std::int64_t>(m.failed_column));
  header[kOk] = m.ok ? 1 : 0;
  header[kNonzeros] = Bits(m.nonzeros);
  header[kPeakBytes] = Bits(m.peak_bytes);
  const cholmod_factor* f = m.llt.factor();
  if (!m.ok) {
    std::memcpy(out, header, sizeof header);
    return;
  }
  if (!f->is_super || f->xtype != CHOLMOD_REAL || f->itype != CHOLMOD_INT || f->p != nullptr)
    throw std::logic_error("CholeskyFactor::WriteFlat: not a real supernodal int32 factor");
  header[kMinor] = f->minor;
  header[kNsuper] = f->nsuper;
  header[kSsize] = f->ssize;
  header[kXsize] = f->xsize;
  header[kMaxcsize] = f->maxcsize;
  header[kMaxesize] = f->maxesize;
  header[kOrdering] = static_cast<std::uint64_t>(f->ordering);
  header[kIsLl] = static_cast<std::uint64_t>(f->is_ll);
  header[kIsMonotonic] = static_cast<std::uint64_t>(f->is_monotonic);
  header[kHasColCount] = f->ColCount != nullptr ? 1 : 0;
  header[kHasIperm] = f->IPerm != nullptr ? 1 : 0;
  std::memcpy(out, header, sizeof header);
  const Layout l = LayoutOf(*f);
  const auto put = [out](std::size_t offset, const void* data, std::size_t bytes) {
    if (bytes > 0) std::memcpy(out + offset, data, bytes);
    // Padding is written, so that the block is the same bytes every time.
    const std::size_t pad = Padded(bytes) - bytes;
    if (pad > 0) std::memset(out + offset + bytes, 0, pad);
  };
  put(l.perm, f->Perm, 4 * f->n);
  if (f->ColCount != nullptr) put(l.colcount, f->ColCount, 4 * f->n);
  if (f->IPerm != nullptr) put(l.iperm, f->IPerm, 4 * f->n);
  put(l.super, f->super, 4 * (f->nsuper + 1));
  put(l.pi, f->pi, 4 * (f->nsuper + 1));
  put(l.px, f->px, 4 * (f->nsuper + 1));
  put(l.s, f->s, 4 * f->ssize);
  put(l.x, f->x, 8 * f->xsize);
}

std::unique_ptr<CholeskyFactor> CholeskyFactor::ReadFlat(const char* data, std::size_t bytes, int n,
                                                         const std::atomic<bool>* cancel) {
  const auto cancelled = [cancel] {
    return cancel != nullptr && cancel->load(std::memory_order_relaxed);
  };
  if (bytes < kFlatHeaderWords * 8)
    Bad("the block has " + std::to_string(bytes) + " bytes, shorter than its header");
  std::uint64_t h[kFlatHeaderWords];
  std::memcpy(h, data, sizeof h);
  if (h[kMagicWord] != kMagic) Bad("not a factor of this format (magic or version)");
  if (n < 1 || h[kN] != static_cast<std::uint64_t>(n))
    Bad("the factor is of size " + std::to_string(h[kN]) + ", expected " + std::to_string(n));
  auto result = std::make_unique<CholeskyFactor>();
  Impl& m = *result->impl_;
  m.computed = true;
  m.n = n;
  m.nonzeros = FromBits(h[kNonzeros]);
  m.peak_bytes = FromBits(h[kPeakBytes]);
  const auto failed = static_cast<std::int64_t>(h[kFailedColumn]);
  if (h[kOk] == 0) {
    if (failed < -1 || failed >= n)
      Bad("failed column " + std::to_string(failed) + " out of range");
    if (bytes != kFlatHeaderWords * 8) Bad("a failed factor's block must be its header only");
    m.failed_column = static_cast<int>(failed);
    return result;
  }
  if (h[kOk] != 1 || failed != -1 || h[kMinor] != static_cast<std::uint64_t>(n))
    Bad("the factor is marked ok but has a failed column");
  const std::uint64_t nsuper = h[kNsuper], ssize = h[kSsize], xsize = h[kXsize];
  // Bounds by the block's length first: every array must fit in it.
  if (nsuper < 1 || nsuper > static_cast<std::uint64_t>(n)) Bad("bad supernode count");
  if (ssize > bytes / 4 || xsize > bytes / 8) Bad("array sizes larger than the block");
  if (h[kHasColCount] > 1 || h[kHasIperm] > 1 || h[kIsLl] != 1 || h[kIsMonotonic] > 1)
    Bad("bad flags");
  const Layout l = MakeLayout(static_cast<std::size_t>(n), h[kHasColCount] == 1, h[kHasIperm] == 1,
                              nsuper, ssize, xsize);
  if (l.end != bytes)
    Bad("the block has " + std::to_string(bytes) + " bytes, its header says " +
        std::to_string(l.end));

  // The permutation, supernodes, pointers and row indices, checked so that a solve stays in
  // bounds.
  const std::vector<std::int32_t> perm = Ints(data, l.perm, n);
  {
    std::vector<char> seen(n, 0);
    for (const std::int32_t p : perm) {
      if (p < 0 || p >= n || seen[p]) Bad("Perm is not a permutation");
      seen[p] = 1;
    }
  }
  if (l.iperm != 0) {
    const std::vector<std::int32_t> iperm = Ints(data, l.iperm, n);
    for (int i = 0; i < n; ++i)
      if (iperm[i] < 0 || iperm[i] >= n || perm[iperm[i]] != i) Bad("IPerm is not Perm's inverse");
  }
  const std::vector<std::int32_t> super = Ints(data, l.super, nsuper + 1);
  const std::vector<std::int32_t> pi = Ints(data, l.pi, nsuper + 1);
  const std::vector<std::int32_t> px = Ints(data, l.px, nsuper + 1);
  const std::vector<std::int32_t> s = Ints(data, l.s, ssize);
  if (super[0] != 0 || super[nsuper] != n || pi[0] != 0 ||
      pi[nsuper] != static_cast<std::int64_t>(ssize) || px[0] != 0)
    Bad("supernode pointers do not start at 0 or end at the array sizes");
  std::uint64_t max_e = 0;
  for (std::uint64_t k = 0; k < nsuper; ++k) {
    const std::int64_t cols = static_cast<std::int64_t>(super[k + 1]) - super[k];
    const std::int64_t rows = static_cast<std::int64_t>(pi[k + 1]) - pi[k];
    if (cols < 1 || rows < cols) Bad("supernode " + std::to_string(k) + " has a bad shape");
    if (static_cast<std::int64_t>(px[k + 1]) - px[k] != rows * cols)
      Bad("supernode " + std::to_string(k) + " has a bad value pointer");
    for (std::int64_t j = 0; j < rows; ++j) {
      const std::int32_t row = s[pi[k] + j];
      if (row < 0 || row >= n || (j < cols && row != super[k] + j))
        Bad("supernode " + std::to_string(k) + " has a bad row index");
    }
    max_e = std::max<std::uint64_t>(max_e, static_cast<std::uint64_t>(rows - cols));
  }
  if (static_cast<std::uint64_t>(px[nsuper]) > xsize) Bad("values past the end of x");
  if (h[kMaxesize] < max_e) Bad("maxesize below the largest supernode's");
  if (cancelled()) return nullptr;

  // The factor, allocated by CHOLMOD as its own (cholmod_free_factor frees it).
  cholmod_common* c = m.llt.common();
  FactorGuard guard{cholmod_allocate_factor(static_cast<std::size_t>(n), c), c};
  cholmod_factor* f = guard.f;
  if (f == nullptr) throw std::bad_alloc();
  const auto alloc = [c](std::size_t count, std::size_t size) {
    void* p = cholmod_malloc(count, size, c);
    if (p == nullptr) throw std::bad_alloc();
    return p;
  };
  f->minor = static_cast<std::size_t>(n);
  f->ordering = static_cast<int>(h[kOrdering]);
  f->is_ll = 1;
  f->is_monotonic = static_cast<int>(h[kIsMonotonic]);
  f->nsuper = nsuper;
  f->ssize = ssize;
  f->xsize = xsize;
  f->maxcsize = h[kMaxcsize];
  f->maxesize = h[kMaxesize];
  std::memcpy(f->Perm, perm.data(), 4 * static_cast<std::size_t>(n));
  if (l.colcount != 0) {
    std::memcpy(f->ColCount, data + l.colcount, 4 * static_cast<std::size_t>(n));
  } else {
    cholmod_free(static_cast<std::size_t>(n), sizeof(int), f->ColCount, c);
    f->ColCount = nullptr;
  }
  if (l.iperm != 0) {
    f->IPerm = alloc(static_cast<std::size_t>(n), sizeof(int));
    std::memcpy(f->IPerm, data + l.iperm, 4 * static_cast<std::size_t>(n));
  }
  // Each array is set on the factor as soon as it is allocated, so that the guard frees it.
  f->super = alloc(nsuper + 1, sizeof(int));
  std::memcpy(f->super, super.data(), 4 * (nsuper + 1));
  f->pi = alloc(nsuper + 1, sizeof(int));
  std::memcpy(f->pi, pi.data(), 4 * (nsuper + 1));
  f->px = alloc(nsuper + 1, sizeof(int));
  std::memcpy(f->px, px.data(), 4 * (nsuper + 1));
  f->s = alloc(ssize, sizeof(int));
  if (ssize > 0) std::memcpy(f->s, s.data(), 4 * ssize);
  f->is_super = 1;  // cholmod_free_factor frees the supernodal arrays and x by xsize from here on
  f->x = alloc(xsize, sizeof(double));
  f->xtype = CHOLMOD_REAL;
  for (std::size_t done = 0; done < 8 * xsize;) {
    if (cancelled()) return nullptr;
    const std::size_t chunk = std::min(kFlatChunkBytes, 8 * xsize - done);
    std::memcpy(static_cast<char*>(f->x) + done, data + l.x + done, chunk);
    done += chunk;
  }
  m.llt.Adopt(f);
  guard.f = nullptr;
  m.ok = true;
  return result;
}

}  // namespace spidarcad::fem
