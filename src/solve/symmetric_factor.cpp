#include "fracvi/solve/symmetric_factor.hpp"

#include <lapacke.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>

#include "fracvi/internal/vectorize.hpp"
#include "fracvi/solve/band_lu.hpp"

namespace fracvi {

std::optional<LinearSolver> parse_linear_solver(std::string_view name) {
  if (name == "auto") return LinearSolver::kAuto;
  if (name == "dense") return LinearSolver::kDense;
  if (name == "banded") return LinearSolver::kBanded;
  if (name == "sparse") return LinearSolver::kSparse;
  return std::nullopt;
}

std::string_view to_string(LinearSolver solver) {
  switch (solver) {
    case LinearSolver::kAuto: return "auto";
    case LinearSolver::kDense: return "dense";
    case LinearSolver::kBanded: return "banded";
    case LinearSolver::kSparse: return "sparse";
  }
  return "unknown";
}

namespace internal {

SymmetricPattern::SymmetricPattern(Eigen::Index dimension) : d_(dimension) {
  if (dimension < 1) {
    throw std::invalid_argument("SymmetricPattern: dimension = " + std::to_string(dimension) +
                                " must be >= 1");
  }
  entries_.reserve(static_cast<std::size_t>(dimension));
  for (Eigen::Index i = 0; i < dimension; ++i) entries_.push_back({i, i});
}

void SymmetricPattern::add(const ModelMatrix& a) {
  if (final_) throw std::logic_error("SymmetricPattern::add after finalize()");
  if (!a.is_sparse()) {
    for (Eigen::Index j = 0; j < a.cols(); ++j)
      for (Eigen::Index i = 0; i <= j; ++i) entries_.push_back({i, j});
    return;
  }
  const ModelMatrix::Sparse& s = a.sparse();
  for (Eigen::Index j = 0; j < s.outerSize(); ++j) {
    for (ModelMatrix::Sparse::InnerIterator it(s, j); it; ++it) {
      entries_.push_back({std::min(it.row(), it.col()), std::max(it.row(), it.col())});
    }
  }
}

void SymmetricPattern::add(const Potential& potential) {
  if (final_) throw std::logic_error("SymmetricPattern::add after finalize()");
  if (!potential.has_sparse_hessian()) {
    for (Eigen::Index j = 0; j < d_; ++j)
      for (Eigen::Index i = 0; i <= j; ++i) entries_.push_back({i, j});
    return;
  }
  for (const auto& e : potential.hessian_pattern()) {
    if (e.row < 0 || e.col < 0 || e.row >= d_ || e.col >= d_) {
      throw std::invalid_argument("Potential::hessian_pattern has entry (" + std::to_string(e.row) +
                                  ", " + std::to_string(e.col) + ") outside the " +
                                  std::to_string(d_) + " x " + std::to_string(d_) + " matrix");
    }
    entries_.push_back({std::min(e.row, e.col), std::max(e.row, e.col)});
  }
}

void SymmetricPattern::finalize() {
  auto by_column = [](const Potential::HessianEntry& a, const Potential::HessianEntry& b) {
    return a.col != b.col ? a.col < b.col : a.row < b.row;
  };
  std::sort(entries_.begin(), entries_.end(), by_column);
  entries_.erase(
      std::unique(entries_.begin(), entries_.end(),
                  [](const auto& a, const auto& b) { return a.row == b.row && a.col == b.col; }),
      entries_.end());
  column_start_.assign(static_cast<std::size_t>(d_) + 1, 0);
  for (const auto& e : entries_) ++column_start_[static_cast<std::size_t>(e.col) + 1];
  for (std::size_t j = 0; j < static_cast<std::size_t>(d_); ++j)
    column_start_[j + 1] += column_start_[j];
  final_ = true;
}

std::size_t SymmetricPattern::index_of(Eigen::Index row, Eigen::Index col) const {
  if (!final_) throw std::logic_error("SymmetricPattern::index_of before finalize()");
  const Eigen::Index r = std::min(row, col), c = std::max(row, col);
  if (r < 0 || c >= d_) throw std::out_of_range("SymmetricPattern::index_of: outside the matrix");
  const auto first =
      entries_.begin() + static_cast<std::ptrdiff_t>(column_start_[static_cast<std::size_t>(c)]);
  const auto last = entries_.begin() +
                    static_cast<std::ptrdiff_t>(column_start_[static_cast<std::size_t>(c) + 1]);
  const auto it =
      std::lower_bound(first, last, r, [](const auto& e, Eigen::Index v) { return e.row < v; });
  if (it == last || it->row != r) {
    throw std::out_of_range("SymmetricPattern::index_of: (" + std::to_string(r) + ", " +
                            std::to_string(c) + ") is not in the pattern");
  }
  return static_cast<std::size_t>(it - entries_.begin());
}

Eigen::Index SymmetricPattern::bandwidth() const {
  Eigen::Index b = 0;
  for (const auto& e : entries_) b = std::max(b, e.col - e.row);
  return b;
}

LinearSolver choose_factorization(const SymmetricPattern& pattern) {
  const auto d = static_cast<double>(pattern.dimension());
  const double upper_entries = 0.5 * d * (d + 1.0);
  if (pattern.dimension() <= 4 || static_cast<double>(pattern.size()) > 0.25 * upper_entries) {
    return LinearSolver::kDense;
  }
  return pattern.bandwidth() <= kMaxAutoBandwidth ? LinearSolver::kBanded : LinearSolver::kSparse;
}

// LAPACK band storage (column-major). Cholesky, UPLO = 'U': ldab = kd + 1, A(i, j) at
// (kd + i − j) + j·ldab for j − kd ≤ i ≤ j. The LU fallback (kl = ku = kd) is BandLu
// (solve/band_lu.hpp: dgbtrf, and dgbtrs's substitutions in plain loops).
// Bandwidths 0 and 1 have their own routines: a diagonal is divided by, and a tridiagonal matrix
// is factored LDLᵀ by tridiagonal_ldlt (dpttrf's numbers, chunked; positive definite) or by
// LAPACK's dgttrf/dgttrs (LU with pivoting), which are plain loops — the general band routines call
// a level-2 BLAS kernel per column, and for a chain of 1000 masses that made the factorisation 22
// µs instead of a few. The solve with the tridiagonal LDLᵀ factor (L unit lower bidiagonal with
// L(i+1, i) = e_i) is two recurrences, y_i = b_i − e_{i−1} y_{i−1} forward and z_i = y_i/d_i − e_i
// z_{i+1} backward: each element waits for the previous one, so LAPACK's dpttrs runs at the latency
// of a multiply–add, ≈ 4 µs for d = 1000 — 12–16 % of a step of the fractional chain
// (bench/RESULTS.md). Cut into kChunks chunks, the recurrences run in all chunks at once (kChunks
// independent chains keep the multiply–add pipes busy), each chunk started from zero; the exact
// solution is the chunk's local one plus a multiple of the value just before it (forward) or just
// after it (backward): y_i = y_i^loc + g_i y_{s−1}, g_s = −e_{s−1}, g_i = −e_{i−1} g_{i−1} (the
// "spikes", computed once per factorisation). The corrected value before (after) each chunk goes
// chunk by chunk, as it needs the previous chunk's corrected; then the corrections are a
// vectorised pass, which stops where the spike has underflowed (|g| < DBL_MIN is stored as 0, so no
// denormal enters the pass): for the diagonally dominant matrices of chains (|e| ≈ h²k/4) that is
// after a few elements. Used when n ≥ kChunkedMinimum and every |e_i| ≤ 1/2: then |g| ≤ 2^−t
// decays, the local solutions are no larger than the true ones and the correction cannot cancel
// more than the sequential recurrence would; otherwise (and for the LU fallback) LAPACK.
constexpr std::size_t kChunks = 16;
constexpr std::size_t kChunkedMinimum = 32 * kChunks;
constexpr double kChunkedMaxCoupling = 0.5;

struct SymmetricFactor::Banded {
  lapack_int n = 0, kd = 0, ldab_chol = 0;
  std::vector<double> chol;
  BandLu lu;                                                   // kd ≥ 2, not positive definite
  std::vector<lapack_int> pivots;                              // kd = 1: dgttrf's
  std::vector<std::size_t> chol_at, lu_upper_at, lu_lower_at;  // per pattern entry
  bool use_lu = false;
  // kd ≤ 1: diagonal and first off-diagonal (copies for the LU fallback: dl, d, du, du2).
  std::vector<double> diag, off, lu_dl, lu_d, lu_du, lu_du2;
  std::vector<std::size_t> tri_at;  // per pattern entry: i for (i, i), n + i for (i, i + 1)
  // Every (i, i) and (i, i + 1) in the pattern: sorted by column, the values are then
  // a_0, e_0, a_1, e_1, …, a_{n−1} and the scatter is a strided copy.
  bool full_tridiagonal = false;
  // The chunked solve of the LDLᵀ factor (tridiagonal_chunked_solve below), when use_chunks.
  bool use_chunks = false;
  std::size_t chunk = 0;                  // chunk length c (the last chunk takes the rest)
  std::vector<double> forward, backward;  // g_i, h_i: the spikes
  std::vector<double> inverse_diag;       // 1/d_i (a division pass was a third of the solve)
  std::array<std::size_t, kChunks> forward_reach{}, backward_reach{};  // their non-zero lengths
  // e_i, g_i and 1/d_i of the chunks' first c rows interleaved, [t kChunks + p] = v[p c + t] (set
  // with the spikes), and the solve's scratch in that layout (mutable: solve_in_place is const,
  // like Sparse's scratch, so one factor is not solved from two threads at once).
  std::vector<double> lane_off, lane_forward, lane_inverse;
  mutable std::vector<double> lanes;
};

// The sparse LDLᵀ of P J Pᵀ, P the approximate-minimum-degree ordering of the pattern computed
// once. Eigen's SimplicialLDLT<…, AMDOrdering>::factorize(J) copies J, permuted, into a new matrix
// on every call (and constructs one even without an ordering), so the step loop allocated once per
// factorisation; here the permuted upper triangle is stored once, each factorisation scatters the
// values into it (`at`: pattern entry → its slot) and runs Eigen's numeric factorisation on it
// directly (factorize_preordered, protected: hence the subclass), and the solve permutes in and
// out through `scratch`. What still allocates: factorize_preordered's work vectors (d doubles, two
// of d ints) come from the stack up to EIGEN_STACK_ALLOCATION_LIMIT (128 KB each), from the heap
// beyond: one allocation per factorisation for 16384 < d ≤ 32768, three beyond.
struct SymmetricFactor::Sparse {
  using Matrix = Eigen::SparseMatrix<double>;  // column-major, int indices: Eigen's CholMatrixType
  class PreorderedLdlt
      : public Eigen::SimplicialLDLT<Matrix, Eigen::Upper, Eigen::NaturalOrdering<int>> {
   public:
    // The symbolic analysis, and D sized (the first numeric factorisation would size it).
    void analyze(const Matrix& upper) {
      this->analyzePattern(upper);
      this->m_diag.resize(upper.rows());
    }
    // The numeric factorisation of a matrix already in the analysed order and pattern.
    void factorize_ordered(const Matrix& upper) {
      this->template factorize_preordered<true>(upper);
    }
    // D (vectorD() returns a copy).
    [[nodiscard]] const Eigen::VectorXd& diagonal() const { return this->m_diag; }
  };
  Matrix permuted;              // upper triangle of P J Pᵀ
  std::vector<std::size_t> at;  // pattern entry e → its value's index in `permuted`
  Eigen::VectorXi position;     // row i of J is row position[i] of P J Pᵀ
  PreorderedLdlt ldlt;
  mutable Eigen::VectorXd scratch;
};

namespace {

// Chunk p covers [p c, (p + 1) c) and the last one [(kChunks − 1) c, n).
std::size_t chunk_begin(std::size_t p, std::size_t c) {
  return p * c;
}

}  // namespace

namespace {

// The recurrence of the LDLᵀ factor from row i to hi − 1, given the pivot x = d_i:
//   d_i = x,  l_i = e_i / d_i,  d_{i+1} = a_{i+1} − l_i e_i,
// LAPACK's dpttrf's operations in its order (ISO C++ mode keeps the products unfused), so the
// numbers are dpttrf's bit for bit. With `check`, it stops at the first row whose stored d_i is x
// already, bit for bit: the rest of the run was computed from that same value.
void ldlt_run(std::size_t i, std::size_t hi, double x, bool check, std::size_t n, const double* a,
              const double* e, double* d, double* l) noexcept {
  for (; i < hi; ++i) {
    if (check && std::bit_cast<std::uint64_t>(d[i]) == std::bit_cast<std::uint64_t>(x)) return;
    d[i] = x;
    if (i + 1 == n) return;
    l[i] = e[i] / x;
    x = a[i + 1] - l[i] * e[i];
  }
}

}  // namespace

// Each pivot waits for the previous one through a division and a multiply–add (≈ 20 cycles), so
// LAPACK's dpttrf is latency-bound: ≈ 7 µs for d = 1000, twice per step of the β-FPUT chain.
// Here the chunks of the solve run side by side, chunk p > 0 started as if e_{s−1} were 0
// (d_s = a_s): kChunks independent recurrences keep the divider busy. Then, chunk by chunk from
// the second, the recurrence is re-run from the true pivot d_s = a_s − l_{s−1} e_{s−1} until it
// meets the stored value bit for bit. The map d_{i−1} ↦ d_i has derivative l_{i−1}², so a wrong
// start is forgotten after a few rows for the chains' weak coupling (|l| ≈ h²k/4m); with strong
// coupling the re-run is longer, at worst a whole sequential pass: the result is exact in any case.
bool tridiagonal_ldlt(std::size_t n, const double* a, const double* e, double* d,
                      double* l) noexcept {
  if (n == 0) return true;
  const std::size_t c = n / kChunks;
  if (c < 2) {
    ldlt_run(0, n, a[0], false, n, a, e, d, l);
  } else {
    std::array<double, kChunks> pivot{};
    for (std::size_t p = 0; p < kChunks; ++p) pivot[p] = a[chunk_begin(p, c)];
    for (std::size_t t = 0; t + 1 < c; ++t) {
      for (std::size_t p = 0; p < kChunks; ++p) {
        const std::size_t i = chunk_begin(p, c) + t;
        d[i] = pivot[p];
        l[i] = e[i] / pivot[p];
        pivot[p] = a[i + 1] - l[i] * e[i];
      }
    }
    for (std::size_t p = 0; p + 1 < kChunks; ++p) {
      const std::size_t i = chunk_begin(p + 1, c) - 1;
      d[i] = pivot[p];
      l[i] = e[i] / pivot[p];
    }
    // The last chunk takes the rest of the rows: one run to n.
    const std::size_t last = chunk_begin(kChunks - 1, c);
    ldlt_run(last + c - 1, n, pivot[kChunks - 1], false, n, a, e, d, l);
    for (std::size_t p = 1; p < kChunks; ++p) {
      const std::size_t s = chunk_begin(p, c), hi = p + 1 < kChunks ? s + c : n;
      ldlt_run(s, hi, a[s] - l[s - 1] * e[s - 1], true, n, a, e, d, l);
    }
  }
  // dpttrf stops at the first d_i ≤ 0 (NaN passes, as there); a count, so that the test vectorises.
  std::size_t non_positive = 0;
  for (std::size_t i = 0; i < n; ++i) non_positive += d[i] <= 0.0;
  return non_positive == 0;
}

namespace {

// The kChunks recurrences of a chunked solve are kChunks lanes of SIMD vectors: element p c + t
// (chunk p, row t) is at t kChunks + p of an interleaved ("lanes") copy, so that row t of every
// chunk is kChunks/W contiguous vectors of W doubles. Walking the chunks at stride c instead, GCC
// left the recurrences scalar (16 loads, multiplies, subtractions and stores per row: ≈ 40 % of
// the solve in perf), and the corrections and the scaling were three more passes over x. Here
// there are three: the forward recurrence, reading x through W × W register transposes; the
// corrections, the scaling and the backward recurrence together; the backward corrections,
// writing x through transposes. e, g and 1/d are interleaved once per factorisation
// (prepare_chunked_solve). d = 1000 (bench/tridiagonal_bench, AVX2): the solve ≈ 1.7 → 1.0 µs,
// a factorisation ≈ 5.2 → 5.5 µs.
// Every element gets the operations of the sequential chunked solve in the same order (a lane is
// a chunk's recurrence; a correction is selected by a mask where its spike reaches, as adding a
// zero would turn −0 into +0; this file is compiled with -ffp-contract=off, so the AVX2 version
// has no FMA either): the numbers are the same bit for bit (symmetric_factor_test).
// GNU vector extensions (GCC, Clang): V is W doubles, elementwise arithmetic, and a comparison
// gives a mask of 0 / −1 integers that `mask ? a : b` selects with.
typedef double Lanes2 __attribute__((vector_size(2 * sizeof(double))));
typedef double Lanes4 __attribute__((vector_size(4 * sizeof(double))));

template <class V>
constexpr std::size_t kWidth = sizeof(V) / sizeof(double);

// Unaligned access to W doubles (as Clang's own intrinsics do it: a packed may_alias struct; by
// reference, since passing a 32-byte vector by value to a function changes the ABI without AVX).
template <class V>
struct __attribute__((packed, may_alias)) Unaligned {
  V v;
};
template <class V>
[[gnu::always_inline]] inline const Unaligned<V>& at(const double* p) {
  return *reinterpret_cast<const Unaligned<V>*>(p);
}
template <class V>
[[gnu::always_inline]] inline Unaligned<V>& at(double* p) {
  return *reinterpret_cast<Unaligned<V>*>(p);
}

// r[j] (lanes of row j) ↦ r[j] (rows of lane j). (A build uses one width or both.)
[[maybe_unused, gnu::always_inline]] inline void transpose(Lanes2 (&r)[2]) {
  const Lanes2 a = __builtin_shufflevector(r[0], r[1], 0, 2);
  const Lanes2 b = __builtin_shufflevector(r[0], r[1], 1, 3);
  r[0] = a;
  r[1] = b;
}
[[maybe_unused, gnu::always_inline]] inline void transpose(Lanes4 (&r)[4]) {
  const Lanes4 t0 = __builtin_shufflevector(r[0], r[1], 0, 4, 2, 6);
  const Lanes4 t1 = __builtin_shufflevector(r[0], r[1], 1, 5, 3, 7);
  const Lanes4 t2 = __builtin_shufflevector(r[2], r[3], 0, 4, 2, 6);
  const Lanes4 t3 = __builtin_shufflevector(r[2], r[3], 1, 5, 3, 7);
  r[0] = __builtin_shufflevector(t0, t2, 0, 1, 4, 5);
  r[1] = __builtin_shufflevector(t1, t3, 0, 1, 4, 5);
  r[2] = __builtin_shufflevector(t0, t2, 2, 3, 6, 7);
  r[3] = __builtin_shufflevector(t1, t3, 2, 3, 6, 7);
}

// v[p c + t] ↦ lanes[t kChunks + p] for the chunks' first c rows, two rows at a time through 2 × 2
// transposes (element by element, at stride kChunks, this was half of a factorisation at d = 10^4).
void interleave(const double* v, std::size_t c, double* lanes) noexcept {
  std::size_t t = 0;
  for (; t + 2 <= c; t += 2) {
#pragma GCC unroll 8
    for (std::size_t p = 0; p < kChunks; p += 2) {
      Lanes2 r[2] = {at<Lanes2>(v + chunk_begin(p, c) + t).v,
                     at<Lanes2>(v + chunk_begin(p + 1, c) + t).v};
      transpose(r);
      at<Lanes2>(lanes + t * kChunks + p).v = r[0];
      at<Lanes2>(lanes + (t + 1) * kChunks + p).v = r[1];
    }
  }
  for (; t < c; ++t) {
    for (std::size_t p = 0; p < kChunks; ++p) lanes[t * kChunks + p] = v[chunk_begin(p, c) + t];
  }
}

}  // namespace

void SymmetricFactor::prepare_chunked_solve(Banded& b) noexcept {
  const auto n = static_cast<std::size_t>(b.n);
  const std::size_t c = b.chunk;
  if (c == 0) return;
  const double* e = b.off.data();
  // A count rather than an early exit, so that the test vectorises (NaN counts: LAPACK's solve).
  std::size_t strong = 0;
  for (std::size_t i = 0; i + 1 < n; ++i) strong += !(std::abs(e[i]) <= kChunkedMaxCoupling);
  if (strong != 0) return;
  for (std::size_t i = 0; i < n; ++i) b.inverse_diag[i] = 1.0 / b.diag[i];
  // Forward spikes of chunks 1 … kChunks − 1, backward spikes of chunks 0 … kChunks − 2: each a
  // product recurrence that stops where it underflows (a chain's |e| ≈ 1e−4: ≈ 80 rows). One chunk
  // after the other they were latency-bound (half of this function's time); run side by side, each
  // spike with the same products in the same order, so the same numbers.
  std::array<double, kChunks> g_forward{}, g_backward{};
  g_forward.fill(1.0);
  g_backward.fill(1.0);
  b.forward_reach.fill(0);
  b.backward_reach.fill(0);
  double* forward = b.forward.data();
  double* backward = b.backward.data();
  const std::size_t last_length = n - chunk_begin(kChunks - 1, c);
  for (std::size_t t = 0;; ++t) {
    bool extended = false;  // a spike is still running at t when its reach is t
    for (std::size_t p = 1; p < kChunks; ++p) {
      const std::size_t length = p + 1 < kChunks ? c : last_length;
      if (b.forward_reach[p] != t || t >= length) continue;
      const std::size_t i = chunk_begin(p, c) + t;
      const double g = g_forward[p] * -e[i - 1];
      if (std::abs(g) < DBL_MIN) continue;
      forward[i] = g;
      g_forward[p] = g;
      b.forward_reach[p] = t + 1;
      extended = true;
    }
    for (std::size_t p = 0; p + 1 < kChunks; ++p) {
      if (b.backward_reach[p] != t || t >= c) continue;
      const std::size_t i = chunk_begin(p + 1, c) - 1 - t;
      const double g = g_backward[p] * -e[i];
      if (std::abs(g) < DBL_MIN) continue;
      backward[i] = g;
      g_backward[p] = g;
      b.backward_reach[p] = t + 1;
      extended = true;
    }
    if (!extended) break;
  }
  // The interleaved copies (beyond a spike's reach, g_i is stale or 0: the solve masks it out).
  interleave(e, c, b.lane_off.data());
  interleave(forward, c, b.lane_forward.data());
  interleave(b.inverse_diag.data(), c, b.lane_inverse.data());
  b.use_chunks = true;
}

namespace {

// The solve's data, for its kernel: a free function, so that it can have an AVX2 version.
struct ChunkedSolve {
  std::size_t n, c;
  const double *off, *forward, *backward, *inverse_diag;  // e_i, g_i, h_i, 1/d_i
  const double *lane_off, *lane_forward, *lane_inverse;   // interleaved, rows [0, kChunks c)
  const std::size_t *forward_reach, *backward_reach;
  double* lanes;  // kChunks·c scratch, interleaved
};

template <class V>
[[gnu::always_inline]] inline void chunked_solve_lanes(const ChunkedSolve& s, double* x) noexcept {
  constexpr std::size_t W = kWidth<V>, G = kChunks / W;  // G vectors per row
  const std::size_t n = s.n, c = s.c, last = chunk_begin(kChunks - 1, c), rest = last + c;
  const double* e = s.off;
  double* lanes = s.lanes;
  // Forward, L y = b: the chunks' local recurrences, lane by lane, reading x W rows at a time
  // (W × W transposes) and writing the lanes; then the last chunk's rest.
  V carry[G];
#pragma GCC unroll 16
  for (std::size_t g = 0; g < G; ++g) {
#pragma GCC unroll 4
    for (std::size_t j = 0; j < W; ++j) carry[g][j] = x[chunk_begin(W * g + j, c)];
    at<V>(lanes + W * g).v = carry[g];
  }
  std::size_t t = 1;
  for (; t + W <= c; t += W) {
#pragma GCC unroll 16
    for (std::size_t g = 0; g < G; ++g) {
      V r[W];
#pragma GCC unroll 4
      for (std::size_t j = 0; j < W; ++j) r[j] = at<V>(x + chunk_begin(W * g + j, c) + t).v;
      transpose(r);
#pragma GCC unroll 4
      for (std::size_t j = 0; j < W; ++j) {
        carry[g] = r[j] - at<V>(s.lane_off + (t + j - 1) * kChunks + W * g).v * carry[g];
        at<V>(lanes + (t + j) * kChunks + W * g).v = carry[g];
      }
    }
  }
  for (; t < c; ++t) {
#pragma GCC unroll 16
    for (std::size_t g = 0; g < G; ++g) {
      V r;
#pragma GCC unroll 4
      for (std::size_t j = 0; j < W; ++j) r[j] = x[chunk_begin(W * g + j, c) + t];
      carry[g] = r - at<V>(s.lane_off + (t - 1) * kChunks + W * g).v * carry[g];
      at<V>(lanes + t * kChunks + W * g).v = carry[g];
    }
  }
  if (rest < n) {
    x[rest] -= e[rest - 1] * lanes[(c - 1) * kChunks + kChunks - 1];
    for (std::size_t i = rest + 1; i < n; ++i) x[i] -= e[i - 1] * x[i - 1];
  }
  // The corrections y_i += g_i y_{s−1}, where g reaches (t < reach: a mask), and the scaling by
  // 1/d_i are one pass with the backward recurrence, D Lᵀ z = y, over the lanes from their ends
  // (each element is corrected and scaled, then takes its step of the recurrence). The corrected
  // values y_{s−1} first: each chunk's needs the previous chunk's, corrected. Then the last
  // chunk's rest, all three passes (its values are final), which the last lane continues from.
  alignas(32) double before[kChunks] = {}, reach[kChunks] = {};
  for (std::size_t p = 1; p < kChunks; ++p) {
    double y = lanes[(c - 1) * kChunks + p - 1];
    if (c - 1 < s.forward_reach[p - 1]) y += s.forward[chunk_begin(p, c) - 1] * before[p - 1];
    before[p] = y;
    reach[p] = static_cast<double>(s.forward_reach[p]);
  }
#pragma GCC unroll 16
  for (std::size_t g = 0; g < G; ++g) carry[g] = V{};
  if (rest < n) {
    const double y = before[kChunks - 1];
    for (std::size_t i = rest; i < last + s.forward_reach[kChunks - 1]; ++i)
      x[i] += s.forward[i] * y;
    for (std::size_t i = rest; i < n; ++i) x[i] *= s.inverse_diag[i];
    for (std::size_t i = n - 1; i-- > rest;) x[i] -= e[i] * x[i + 1];
    carry[G - 1][W - 1] = x[rest];
  }
  // Beyond the farthest reach every lane's mask selects y: those rows skip the spikes (the solve
  // moves each row's data through the caches; at d = 10^4 it is bound by that, not by its
  // recurrences' latency: bench/RESULTS.md).
  const auto spiked = static_cast<std::size_t>(*std::max_element(reach, reach + kChunks));
  for (std::size_t row = c; row-- > spiked;) {
#pragma GCC unroll 16
    for (std::size_t g = 0; g < G; ++g) {
      const std::size_t k = row * kChunks + W * g;
      const V scaled = at<V>(lanes + k).v * at<V>(s.lane_inverse + k).v;
      carry[g] = scaled - at<V>(s.lane_off + k).v * carry[g];
      at<V>(lanes + k).v = carry[g];
    }
  }
  for (std::size_t row = std::min(spiked, c); row-- > 0;) {
    V tv;
#pragma GCC unroll 4
    for (std::size_t j = 0; j < W; ++j) tv[j] = static_cast<double>(row);
#pragma GCC unroll 16
    for (std::size_t g = 0; g < G; ++g) {
      const std::size_t k = row * kChunks + W * g;
      const V y = at<V>(lanes + k).v;
      const V corrected = y + at<V>(s.lane_forward + k).v * at<V>(before + W * g).v;
      const V scaled = (tv < at<V>(reach + W * g).v ? corrected : y) * at<V>(s.lane_inverse + k).v;
      carry[g] = scaled - at<V>(s.lane_off + k).v * carry[g];
      at<V>(lanes + k).v = carry[g];
    }
  }
  // The corrections z_i += h_i z_{s+c} (from row c − reach on: a mask), fused with the copy back to
  // x (W × W transposes). The corrected values z_{s+c} first, from the last chunk down.
  alignas(32) double after[kChunks] = {}, from[kChunks] = {};
  after[kChunks - 2] = lanes[kChunks - 1];
  from[kChunks - 1] = static_cast<double>(c);
  for (std::size_t p = kChunks - 1; p-- > 0;) {
    from[p] = static_cast<double>(c - s.backward_reach[p]);
    if (p == 0) break;
    double z = lanes[p];
    if (s.backward_reach[p] == c) z += s.backward[chunk_begin(p, c)] * after[p];
    after[p - 1] = z;
  }
  // Rows row … row + W − 1 of the lanes W g … W g + W − 1, as W vectors of W rows (one a lane).
  const auto lane_rows = [lanes](std::size_t row, std::size_t g, V(&r)[W]) {
#pragma GCC unroll 4
    for (std::size_t j = 0; j < W; ++j) r[j] = at<V>(lanes + (row + j) * kChunks + W * g).v;
    transpose(r);
  };
  // Before the nearest backward spike's start every lane's mask selects z: those rows are copied.
  const std::size_t unspiked =
      static_cast<std::size_t>(*std::min_element(from, from + kChunks)) / W * W;
  std::size_t row = 0;
  for (; row + W <= std::min(unspiked, c); row += W) {
#pragma GCC unroll 16
    for (std::size_t g = 0; g < G; ++g) {
      V r[W];
      lane_rows(row, g, r);
#pragma GCC unroll 4
      for (std::size_t j = 0; j < W; ++j) at<V>(x + chunk_begin(W * g + j, c) + row).v = r[j];
    }
  }
  for (; row + W <= c; row += W) {
    V tv;
#pragma GCC unroll 4
    for (std::size_t j = 0; j < W; ++j) tv[j] = static_cast<double>(row + j);
#pragma GCC unroll 16
    for (std::size_t g = 0; g < G; ++g) {
      V r[W];
      lane_rows(row, g, r);
#pragma GCC unroll 4
      for (std::size_t j = 0; j < W; ++j) {
        const std::size_t p = W * g + j, i = chunk_begin(p, c) + row;
        const V corrected = r[j] + at<V>(s.backward + i).v * after[p];
        at<V>(x + i).v = tv >= from[p] ? corrected : r[j];
      }
    }
  }
  for (; row < c; ++row) {
    for (std::size_t p = 0; p < kChunks; ++p) {
      const std::size_t i = chunk_begin(p, c) + row;
      double z = lanes[row * kChunks + p];
      if (static_cast<double>(row) >= from[p]) z += s.backward[i] * after[p];
      x[i] = z;
    }
  }
}

// A portable x86-64 build gets an AVX2 version (4 doubles a vector) beside the SSE2 one (2),
// picked by the dynamic loader (GCC's function multiversioning: an ifunc, as FRACVI_HOT_KERNEL's
// clones, but with a different width in each body).
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(__AVX2__)
__attribute__((target("default"))) void chunked_solve(const ChunkedSolve& s, double* x) noexcept {
  chunked_solve_lanes<Lanes2>(s, x);
}
__attribute__((target("arch=x86-64-v3"))) void chunked_solve(const ChunkedSolve& s,
                                                             double* x) noexcept {
  chunked_solve_lanes<Lanes4>(s, x);
}
#elif defined(__AVX__)
void chunked_solve(const ChunkedSolve& s, double* x) noexcept {
  chunked_solve_lanes<Lanes4>(s, x);
}
#else
void chunked_solve(const ChunkedSolve& s, double* x) noexcept {
  chunked_solve_lanes<Lanes2>(s, x);
}
#endif

}  // namespace

void SymmetricFactor::tridiagonal_chunked_solve(const Banded& b, double* x) noexcept {
  const ChunkedSolve s{static_cast<std::size_t>(b.n),
                       b.chunk,
                       b.off.data(),
                       b.forward.data(),
                       b.backward.data(),
                       b.inverse_diag.data(),
                       b.lane_off.data(),
                       b.lane_forward.data(),
                       b.lane_inverse.data(),
                       b.forward_reach.data(),
                       b.backward_reach.data(),
                       b.lanes.data()};
  chunked_solve(s, x);
}

SymmetricFactor::SymmetricFactor(std::shared_ptr<const SymmetricPattern> pattern,
                                 LinearSolver solver)
    : pattern_(std::move(pattern)), backend_(solver) {
  if (!pattern_) throw std::invalid_argument("SymmetricFactor: pattern is null");
  if (solver != LinearSolver::kBanded && solver != LinearSolver::kSparse) {
    throw std::invalid_argument("SymmetricFactor: backend must be banded or sparse");
  }
  const SymmetricPattern& p = *pattern_;
  values_.assign(p.size(), 0.0);
  const Eigen::Index d = p.dimension();
  if (solver == LinearSolver::kBanded) {
    banded_ = std::make_unique<Banded>();
    Banded& b = *banded_;
    b.n = static_cast<lapack_int>(d);
    b.kd = static_cast<lapack_int>(p.bandwidth());
    b.ldab_chol = b.kd + 1;
    b.chol.assign(static_cast<std::size_t>(b.ldab_chol) * static_cast<std::size_t>(d), 0.0);
    const auto kd = static_cast<std::size_t>(b.kd);
    const auto n = static_cast<std::size_t>(d);
    if (b.kd <= 1) {
      b.diag.assign(n, 0.0);
      b.off.assign(n, 0.0);
      for (std::vector<double>* v : {&b.lu_dl, &b.lu_d, &b.lu_du, &b.lu_du2}) v->assign(n, 0.0);
      if (b.kd == 1 && n >= kChunkedMinimum) {
        b.chunk = n / kChunks;
        b.forward.assign(n, 0.0);
        b.backward.assign(n, 0.0);
        b.inverse_diag.assign(n, 0.0);
        for (std::vector<double>* v : {&b.lane_off, &b.lane_forward, &b.lane_inverse, &b.lanes})
          v->assign(kChunks * b.chunk, 0.0);
      }
      for (const auto& e : p.entries()) {
        const auto i = static_cast<std::size_t>(e.row);
        b.tri_at.push_back(e.row == e.col ? i : n + i);
      }
      b.full_tridiagonal = b.kd == 1 && p.size() == 2 * n - 1;
      b.pivots.assign(n, 0);
      b.chol.clear();
    } else {
      b.lu = BandLu(d, b.kd, b.kd);
      for (const auto& e : p.entries()) {
        const auto i = static_cast<std::size_t>(e.row), j = static_cast<std::size_t>(e.col);
        b.chol_at.push_back(kd + i - j + j * static_cast<std::size_t>(b.ldab_chol));
        b.lu_upper_at.push_back(b.lu.offset(e.row, e.col));
        b.lu_lower_at.push_back(b.lu.offset(e.col, e.row));
      }
    }
  } else {
    sparse_ = std::make_unique<Sparse>();
    Sparse& s = *sparse_;
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(p.size());
    for (const auto& e : p.entries()) triplets.emplace_back(e.row, e.col, 1.0);
    Sparse::Matrix upper(d, d);
    upper.setFromTriplets(triplets.begin(), triplets.end());
    // The ordering as Eigen's SimplicialLDLT computes it (SimplicialCholeskyBase::ordering): AMD on
    // the full symmetric pattern, which yields P⁻¹.
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> inverse;
    {
      Sparse::Matrix full;
      full = upper.selfadjointView<Eigen::Upper>();
      Eigen::AMDOrdering<int> ordering;
      ordering(full, inverse);
    }
    const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> ordering =
        inverse.inverse();
    s.position = ordering.indices();
    triplets.clear();
    for (const auto& e : p.entries()) {
      const int r = s.position(e.row), c = s.position(e.col);
      triplets.emplace_back(std::min(r, c), std::max(r, c), 1.0);
    }
    s.permuted.resize(d, d);
    s.permuted.setFromTriplets(triplets.begin(), triplets.end());
    s.permuted.makeCompressed();
    s.at.reserve(p.size());
    for (const auto& e : p.entries()) {
      const int r = s.position(e.row), c = s.position(e.col);
      s.at.push_back(static_cast<std::size_t>(&s.permuted.coeffRef(std::min(r, c), std::max(r, c)) -
                                              s.permuted.valuePtr()));
    }
    s.ldlt.analyze(s.permuted);
    s.scratch.resize(d);
  }
}

SymmetricFactor::~SymmetricFactor() = default;
SymmetricFactor::SymmetricFactor(SymmetricFactor&&) noexcept = default;
SymmetricFactor& SymmetricFactor::operator=(SymmetricFactor&&) noexcept = default;

bool SymmetricFactor::factor() noexcept {
  if (banded_ && banded_->kd <= 1) return factor_tridiagonal();
  if (banded_) {
    Banded& b = *banded_;
    std::fill(b.chol.begin(), b.chol.end(), 0.0);
    for (std::size_t e = 0; e < values_.size(); ++e) b.chol[b.chol_at[e]] = values_[e];
    b.use_lu = false;
    if (LAPACKE_dpbtrf_work(LAPACK_COL_MAJOR, 'U', b.n, b.kd, b.chol.data(), b.ldab_chol) == 0) {
      return true;
    }
    // Not positive definite: band LU with partial pivoting.
    b.use_lu = true;
    std::vector<double>& band = b.lu.band();
    std::fill(band.begin(), band.end(), 0.0);
    const auto& entries = pattern_->entries();
    for (std::size_t e = 0; e < values_.size(); ++e) {
      band[b.lu_upper_at[e]] = values_[e];
      if (entries[e].row != entries[e].col) band[b.lu_lower_at[e]] = values_[e];
    }
    return b.lu.factor();
  }
  Sparse& s = *sparse_;
  double* permuted = s.permuted.valuePtr();
  for (std::size_t e = 0; e < values_.size(); ++e) permuted[s.at[e]] = values_[e];
  s.ldlt.factorize_ordered(s.permuted);
  return s.ldlt.info() == Eigen::Success;
}

bool SymmetricFactor::factor_tridiagonal() noexcept {
  Banded& b = *banded_;
  const auto n = static_cast<std::size_t>(b.n);
  const double* v = values_.data();
  b.use_lu = false;
  if (b.kd == 0) {  // diagonal: solve_in_place divides
    std::fill(b.diag.begin(), b.diag.end(), 0.0);
    for (std::size_t e = 0; e < values_.size(); ++e) b.diag[b.tri_at[e]] = v[e];
    return std::all_of(b.diag.begin(), b.diag.end(), [](double x) { return x != 0.0; });
  }
  // J's diagonal and off-diagonal go to lu_d and lu_du, which the LDLᵀ factorisation reads (its
  // factor goes to diag and off) and the LU fallback keeps.
  if (b.full_tridiagonal) {
    for (std::size_t i = 0; i < n; ++i) b.lu_d[i] = v[2 * i];
    for (std::size_t i = 0; i + 1 < n; ++i) b.lu_du[i] = v[2 * i + 1];
  } else {
    std::fill(b.lu_d.begin(), b.lu_d.end(), 0.0);
    std::fill(b.lu_du.begin(), b.lu_du.end(), 0.0);
    for (std::size_t e = 0; e < values_.size(); ++e) {
      const std::size_t at = b.tri_at[e];
      (at < n ? b.lu_d[at] : b.lu_du[at - n]) = v[e];
    }
  }
  b.use_chunks = false;
  if (tridiagonal_ldlt(n, b.lu_d.data(), b.lu_du.data(), b.diag.data(), b.off.data())) {
    prepare_chunked_solve(b);
    return true;
  }
  b.use_lu = true;  // not positive definite: tridiagonal LU with partial pivoting
  std::copy(b.lu_du.begin(), b.lu_du.end(), b.lu_dl.begin());
  return LAPACKE_dgttrf_work(b.n, b.lu_dl.data(), b.lu_d.data(), b.lu_du.data(), b.lu_du2.data(),
                             b.pivots.data()) == 0;
}

void SymmetricFactor::solve_in_place(Eigen::Ref<Eigen::VectorXd> rhs) const noexcept {
  if (banded_ && banded_->kd == 0) {
    rhs.array() /= Eigen::Map<const Eigen::ArrayXd>(banded_->diag.data(), rhs.size());
    return;
  }
  if (banded_ && banded_->kd == 1) {
    const Banded& b = *banded_;
    if (b.use_lu) {
      LAPACKE_dgttrs_work(LAPACK_COL_MAJOR, 'N', b.n, 1, b.lu_dl.data(), b.lu_d.data(),
                          b.lu_du.data(), b.lu_du2.data(), b.pivots.data(), rhs.data(), b.n);
    } else if (b.use_chunks) {
      tridiagonal_chunked_solve(b, rhs.data());
    } else {
      LAPACKE_dpttrs_work(LAPACK_COL_MAJOR, b.n, 1, b.diag.data(), b.off.data(), rhs.data(), b.n);
    }
    return;
  }
  if (banded_) {
    const Banded& b = *banded_;
    if (b.use_lu) {
      b.lu.solve_in_place(rhs.data());
    } else {
      LAPACKE_dpbtrs_work(LAPACK_COL_MAJOR, 'U', b.n, b.kd, 1, b.chol.data(), b.ldab_chol,
                          rhs.data(), b.n);
    }
    return;
  }
  // SimplicialLDLT::solve's steps (L, D, Lᵀ), between the permutation in and out.
  const Sparse& s = *sparse_;
  for (Eigen::Index i = 0; i < rhs.size(); ++i) s.scratch(s.position(i)) = rhs(i);
  s.ldlt.matrixL().solveInPlace(s.scratch);
  s.scratch.array() /= s.ldlt.diagonal().array();
  s.ldlt.matrixU().solveInPlace(s.scratch);
  for (Eigen::Index i = 0; i < rhs.size(); ++i) rhs(i) = s.scratch(s.position(i));
}

std::vector<std::pair<std::size_t, double>> scatter_upper(const SymmetricPattern& pattern,
                                                          const ModelMatrix& a) {
  std::vector<std::pair<std::size_t, double>> out;
  if (!a.is_sparse()) {
    const Eigen::MatrixXd& m = a.dense();
    for (Eigen::Index j = 0; j < m.cols(); ++j)
      for (Eigen::Index i = 0; i <= j; ++i)
        if (m(i, j) != 0.0) out.emplace_back(pattern.index_of(i, j), m(i, j));
    return out;
  }
  const ModelMatrix::Sparse& s = a.sparse();
  for (Eigen::Index j = 0; j < s.outerSize(); ++j) {
    for (ModelMatrix::Sparse::InnerIterator it(s, j); it; ++it) {
      if (it.row() <= it.col()) out.emplace_back(pattern.index_of(it.row(), it.col()), it.value());
    }
  }
  return out;
}

}  // namespace internal
}  // namespace fracvi
