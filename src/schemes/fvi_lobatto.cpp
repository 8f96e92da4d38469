// fvi-lobatto2, fvi-lobatto3, fvi-lobatto4: the restricted discrete variational principle with the
// Lobatto–Galerkin discrete Lagrangian on s Lobatto nodes and the damping by the Lobatto IIIC
// Runge–Kutta convolution quadrature of s^{2α} on the stage values (docs/theory/fvi_lobatto.md;
// Hariz, Ober-Blöbaum & Jiménez, arXiv 2510.11082). s = 2, 3, 4; declared orders 2, 4, 6.
//
// On the interval [t_n, t_{n+1}] the curve is the polynomial through the stage values
// X_n = (X_{n,1}, …, X_{n,s}), X_{n,a} ≈ x(t_n + c_a h), with X_{n,1} = x_n and X_{n,s} = x_{n+1}.
// The interval force (fvi_lobatto.md §3), column k of a d × s block,
//
//   F_{n,k} = Σ_a b_a D_{ak} M V_{n,a} − h b_k [∇U(X_{n,k}, t_{n,k}) − f(t_{n,k}) + R G̃_{n,k}] −
//   L_{n,k}, V_{n,a} = (1/h) Σ_k D_{ak} X_{n,k},   G̃_n = h^{−β} Σ_{j=0}^{n} W_j X̃_{n−j}   (β = 2α),
//
// with D the differentiation matrix of the Lobatto nodes, W_j the RKCQ block weights
// (fractional/runge_kutta_cq.hpp), X̃ = X − P the stage values minus the Taylor polynomial
// P(t) = x_0 + (t − t_0) v_0 (the split of fvi_bdf2.md §5.2), and L_{n,k} = h R ∫_0^1 ℓ_k(σ)
// D^β P(t_n + σh) dσ the exact Galerkin moment of P's damping force (§2, "moments": the pointwise
// value costs the order 2 − 2α at t_0 and is infinite there for Riemann–Liouville data).
//
// Step n (the momentum form, §4.1): unknowns X_{n,2 … s}; equations p_n + F_{n,1} = 0 and
// F_{n,i} = 0 for the internal stages i = 2 … s − 1; then x_{n+1} = X_{n,s}, p_{n+1} = F_{n,s}.
// Newton's matrix (4.2) has the blocks (K_D)_{im} M/h − h^{1−β} b_i (W_0)_{im} R − δ_{im} h b_i
// ∇²U: the current interval's damping acts on the unknowns (implicit), and for s = 2 the potential
// does not enter it at all (a linear solve per step for any U, as for Störmer–Verlet).
//
// A non-conservative force g(x, v, t) (docs/theory/forces.md §5) enters like f, by the Lobatto
// quadrature of the virtual work: h b_k g(X_{n,k}, V_{n,k}, t_{n,k}) in F_{n,k}, with V the stage
// derivative of the interpolant; Newton's matrix gains h b_k (δ_{km} ∂g/∂x + (D_{km}/h) ∂g/∂v)
// (not symmetric, and coupling every stage to every unknown through V: dense LU).
//
// Stability (§8): the conservative part is the Lobatto IIIA–IIIB method, conditionally stable
// (λ_max(M⁻¹∇²U) h² < 4, 8, 30), and for 0 < 2α < 1 the spring-like part of the damping adds a
// bound on λ_max(M⁻¹R) h^{2−2α} (measured table below). 1 ≤ 2α < 2: no damping bound found.
#include <Eigen/Eigenvalues>
#include <Eigen/SparseLU>
#include <algorithm>
#include <array>
#include <boost/math/quadrature/gauss.hpp>
#include <boost/math/quadrature/tanh_sinh.hpp>
#include <boost/math/special_functions/binomial.hpp>
#include <boost/math/special_functions/gamma.hpp>
#include <cassert>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "forcing_moments.hpp"
#include "fractional_series.hpp"
#include "fracvi/core/error.hpp"
#include "fracvi/fractional/runge_kutta_cq.hpp"
#include "fracvi/internal/vectorize.hpp"
#include "fracvi/memory/block_history.hpp"
#include "fracvi/schemes/history_budget.hpp"
#include "fracvi/schemes/stability.hpp"
#include "fracvi/schemes/stepper.hpp"
#include "fracvi/solve/band_lu.hpp"
#include "fracvi/solve/midpoint_newton.hpp"
#include "mass_solver.hpp"
#include "mirror_run.hpp"
#include "scheme_rows.hpp"

namespace fracvi::internal {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---------------------------------------------------------------------------------------------
// The Lobatto nodes: tableau, differentiation matrix and the Lagrange basis in monomials.

struct LobattoNodes {
  int s = 0;
  Eigen::VectorXd b, c;
  Eigen::MatrixXd D;      // D_{ak} = ℓ_k'(c_a)
  Eigen::MatrixXd BD;     // B D (row a scaled by b_a): column k of V·BD is Σ_a b_a D_{ak} V_a
  Eigen::MatrixXd KD;     // Dᵀ B D
  Eigen::MatrixXd basis;  // basis(k, m): coefficient of σ^m in ℓ_k(σ)
  Eigen::MatrixXd slope;  // slope(k, m): coefficient of σ^m in ℓ_k'(σ)

  explicit LobattoNodes(int stages) : s(stages) {
    const ButcherTableau& tableau = lobatto_iiic(stages);
    b = tableau.b;
    c = tableau.c;
    // Barycentric differentiation: D_{ak} = (w_k / w_a) / (c_a − c_k), D_{aa} = −Σ_{k≠a} D_{ak}.
    Eigen::VectorXd w = Eigen::VectorXd::Ones(s);
    for (int k = 0; k < s; ++k)
      for (int m = 0; m < s; ++m)
        if (m != k) w(k) /= c(k) - c(m);
    D.setZero(s, s);
    for (int a = 0; a < s; ++a) {
      for (int k = 0; k < s; ++k) {
        if (k == a) continue;
        D(a, k) = (w(k) / w(a)) / (c(a) - c(k));
        D(a, a) -= D(a, k);
      }
    }
    BD = b.asDiagonal() * D;
    KD = D.transpose() * BD;
    // ℓ_k(c_a) = Σ_m basis(k, m) c_a^m = δ_{ka}: basis = (Vᵀ)^{−1}, V_{am} = c_a^m.
    Eigen::MatrixXd vandermonde(s, s);
    for (int a = 0; a < s; ++a)
      for (int m = 0; m < s; ++m) vandermonde(a, m) = std::pow(c(a), m);
    basis = vandermonde.transpose().fullPivLu().inverse();
    slope.setZero(s, s);
    for (int k = 0; k < s; ++k)
      for (int m = 0; m + 1 < s; ++m) slope(k, m) = (m + 1) * basis(k, m + 1);
  }
};

// ---------------------------------------------------------------------------------------------
// The Galerkin moments of a power load φ(τ) = τ^γ on interval n (τ = t − t_0 = (n + σ) h):
//   ∫_0^1 ℓ_k(σ) φ(t_n + σh) dσ  and  ∫_0^1 ℓ_k'(σ) φ(t_n + σh) dσ,
// through μ_m(n) = ∫_0^1 σ^m (n + σ)^γ dσ: n = 0 exactly, 1/(m + γ + 1) (γ > −1: the
// singularity at τ = 0 is integrable); 1 ≤ n < kSeriesFrom by Gauss–Legendre (the integrand is
// analytic on a Bernstein ellipse of parameter ≥ 3 + √8, so 20 points give round-off); beyond, by
// the binomial series n^γ Σ_j C(γ, j) n^{−j}/(m + j + 1) (terms fall by ≤ 2/n: one power per step).
class PowerMoments {
 public:
  static constexpr std::size_t kSeriesFrom = 32;
  static constexpr int kSeriesTerms = 14;

  PowerMoments(const LobattoNodes& nodes, double gamma, double scale)
      : nodes_(nodes), gamma_(gamma), scale_(scale), mu_(nodes.s) {
    for (int j = 0; j < kSeriesTerms; ++j) binomial_[j] = generalized_binomial(gamma, j);
  }

  /// value(k) = scale ∫ℓ_k φ, derivative(k) = scale ∫ℓ_k' φ on interval n.
  void operator()(std::size_t n, Eigen::Ref<Eigen::VectorXd> value,
                  Eigen::Ref<Eigen::VectorXd> derivative) {
    const int s = nodes_.s;
    if (n == 0) {
      for (int m = 0; m < s; ++m) mu_(m) = 1.0 / (m + gamma_ + 1.0);
    } else if (n < kSeriesFrom) {
      const double nn = static_cast<double>(n);
      for (int m = 0; m < s; ++m) {
        mu_(m) = boost::math::quadrature::gauss<double, 20>::integrate(
            [&](double sigma) { return std::pow(sigma, m) * std::pow(nn + sigma, gamma_); }, 0.0,
            1.0);
      }
    } else {
      const double nn = static_cast<double>(n);
      const double lead = std::pow(nn, gamma_);
      for (int m = 0; m < s; ++m) {
        double sum = 0.0, power = 1.0;
        for (int j = 0; j < kSeriesTerms; ++j) {
          sum += binomial_[j] * power / (m + j + 1.0);
          power /= nn;
        }
        mu_(m) = lead * sum;
      }
    }
    value.noalias() = scale_ * (nodes_.basis * mu_);
    derivative.noalias() = scale_ * (nodes_.slope * mu_);
  }

 private:
  static double generalized_binomial(double gamma, int j) {
    double value = 1.0;
    for (int i = 0; i < j; ++i) value *= (gamma - i) / (i + 1.0);
    return value;
  }
  const LobattoNodes& nodes_;
  double gamma_, scale_;
  Eigen::VectorXd mu_;
  std::array<double, kSeriesTerms> binomial_{};
};

// ---------------------------------------------------------------------------------------------
// The stage system's Newton matrix, (s − 1)d × (s − 1)d, unknown stage m (1 … s − 1) at columns
// (m − 1)d …, equation row i (0 … s − 2) at rows i·d …: dense LU; or, when M, R and ∇²U are stored
// sparse, band LU (internal::BandLu, solve/band_lu.hpp) on the stages interleaved per
// degree of freedom, or sparse LU (Eigen's SparseLU, COLAMD ordering). The matrix is not symmetric
// (W_0 and the row/column selection of K_D are not), so the symmetric factorisations of the
// midpoint schemes do not apply.
//
// Band: every block (i, m) has the pattern of M, R and ∇²U, of bandwidth b in the degrees of
// freedom; numbering unknown (dof j, stage m) as j(s − 1) + m − 1 (and the equations alike) puts
// every entry within (s − 1)(b + 1) − 1 of the diagonal — 3 for a chain with s = 3. dgbtrf then
// costs O(d·s³b²) and works in storage sized at set-up: the refactorisations of a nonlinear
// potential do not allocate (Eigen's SparseLU::factorize does, on every call). kAuto takes the band
// up to the bandwidth the midpoint schemes' band Cholesky does (kMaxAutoBandwidth), sparse LU
// beyond (a periodic chain: b = d − 1).
class StageMatrix {
 public:
  /// Block row r holds the equation of stage r + first_equation, block column c the unknown
  /// stage c + first_unknown: (0, 1) for the x-step (equations of stages 1 … s − 1 in the paper's
  /// numbering, unknowns 2 … s), (1, 0) for the mirror's y-step (equations 2 … s, unknowns
  /// 1 … s − 1). `current` is the weight of the interval's own stages (W_0, or J W_0 J).
  StageMatrix(const LobattoNodes& nodes, const Eigen::MatrixXd& current, double h, double beta,
              const ModelMatrix& mass, const ModelMatrix& damping, bool damped,
              const Potential* potential, LinearSolver requested, int first_equation = 0,
              int first_unknown = 1, const StateForce* state_force = nullptr,
              double velocity_sign = 1.0)
      : s_(nodes.s),
        d_(mass.rows()),
        potential_(potential),
        state_force_(state_force),
        velocity_sign_(velocity_sign),
        h_(h),
        b_(nodes.b),
        D_(nodes.D),
        internal_hessians_(potential != nullptr && nodes.s > 2),
        first_equation_(first_equation),
        first_unknown_(first_unknown) {
    const Eigen::Index n = (s_ - 1) * d_;
    // Coefficients of M and R in block (r, c).
    Eigen::MatrixXd mass_coeff(s_ - 1, s_ - 1), damping_coeff(s_ - 1, s_ - 1);
    for (int r = 0; r + 1 < s_; ++r) {
      const int e = r + first_equation;
      for (int c = 0; c + 1 < s_; ++c) {
        const int u = c + first_unknown;
        mass_coeff(r, c) = nodes.KD(e, u) / h;
        damping_coeff(r, c) = damped ? -std::pow(h, 1.0 - beta) * nodes.b(e) * current(e, u) : 0.0;
      }
    }
    for (int i = 1; i + 1 < s_; ++i) hessian_coeff_.push_back(-h * nodes.b(i));
    const bool structured =
        mass.is_sparse() && (!damped || damping.is_sparse()) &&
        (potential == nullptr || !internal_hessians_ || potential->has_sparse_hessian());
    kind_ = requested == LinearSolver::kSparse || requested == LinearSolver::kBanded ||
                    (requested == LinearSolver::kAuto && structured && n > kDenseUpTo)
                ? LinearSolver::kSparse
                : LinearSolver::kDense;
    if (state_force != nullptr) {
      // ∂g/∂v couples every stage to every unknown and is not symmetric: dense LU only.
      if (requested == LinearSolver::kSparse || requested == LinearSolver::kBanded) {
        throw ValidationError(
            "method.linear_solver = \"" +
            std::string(requested == LinearSolver::kBanded ? "banded" : "sparse") +
            "\" is not available for the stage system of a model with a force g(x, v, t) "
            "(model.force "
            "in x or v): its Jacobian couples all stages; use linear_solver = \"dense\" or "
            "\"auto\"");
      }
      kind_ = LinearSolver::kDense;
      force_value_.setZero(d_);
      force_velocity_.setZero(d_);
      force_dx_.setZero(d_, d_);
      force_dv_.setZero(d_, d_);
    }
    if (kind_ == LinearSolver::kDense) {
      if (n > kMaxDenseDimension) {
        throw ValidationError(
            "the stage system of this Lobatto scheme would be factored dense ((s-1)d = " +
            std::to_string(n) + " > " + std::to_string(kMaxDenseDimension) +
            "): store M and R sparse and give the potential a sparse Hessian");
      }
      const Eigen::MatrixXd m = mass.to_dense();
      const Eigen::MatrixXd r = damped ? damping.to_dense() : Eigen::MatrixXd::Zero(d_, d_);
      constant_.resize(n, n);
      for (int i = 0; i + 1 < s_; ++i)
        for (int m2 = 0; m2 + 1 < s_; ++m2)
          constant_.block(i * d_, m2 * d_, d_, d_) =
              mass_coeff(i, m2) * m + damping_coeff(i, m2) * r;
      jacobian_.resize(n, n);
      lu_ = Eigen::PartialPivLU<Eigen::MatrixXd>(n);
      if (internal_hessians_) hessian_.resize(d_, d_);
      return;
    }
    // Sparse: the constant triplets, then the Hessian pattern's positions (values per factor).
    auto add = [&](const ModelMatrix& a, const Eigen::MatrixXd& coeff) {
      const ModelMatrix::Sparse sa =
          a.is_sparse() ? a.sparse() : ModelMatrix::Sparse(a.to_dense().sparseView());
      for (int k = 0; k < sa.outerSize(); ++k)
        for (ModelMatrix::Sparse::InnerIterator it(sa, k); it; ++it)
          for (int i = 0; i + 1 < s_; ++i)
            for (int m2 = 0; m2 + 1 < s_; ++m2)
              if (coeff(i, m2) != 0.0)
                triplets_.emplace_back(static_cast<int>(i * d_ + it.row()),
                                       static_cast<int>(m2 * d_ + it.col()),
                                       coeff(i, m2) * it.value());
    };
    add(mass, mass_coeff);
    if (damped) add(damping, damping_coeff);
    constant_count_ = triplets_.size();
    if (internal_hessians_) {
      if (potential->has_sparse_hessian()) {
        pattern_ = potential->hessian_pattern();
      } else {
        for (Eigen::Index col = 0; col < d_; ++col)
          for (Eigen::Index row = 0; row <= col; ++row) pattern_.push_back({row, col});
        hessian_.resize(d_, d_);
      }
      hessian_values_.resize(pattern_.size());
      for (int i = 1; i + 1 < s_; ++i) {
        const Eigen::Index row = (i - first_equation_) * d_, col = (i - first_unknown_) * d_;
        for (const Potential::HessianEntry& e : pattern_) {
          triplets_.emplace_back(static_cast<int>(row + e.row), static_cast<int>(col + e.col), 0.0);
          if (e.row != e.col)
            triplets_.emplace_back(static_cast<int>(row + e.col), static_cast<int>(col + e.row),
                                   0.0);
        }
      }
    }
    // Each degree of freedom's stages in the order whose elimination needs no row interchanges
    // for the mass term's coupling, which dominates as h → 0: the x-step's equations of stages
    // 1 … s − 1 against unknowns 2 … s interchanged every other row in stage order (dgbtrf,
    // fvi-lobatto3 and 4 on the chains), in reverse order none, and a solve without interchanges
    // runs along the band in registers (solve/band_lu.cpp): fvi-lobatto3's step at d = 1000 took
    // 75 against 100 µs (bench/RESULTS.md 2026-12-02). dgbtrf still interchanges where the values
    // ask for it: the order changes the speed and the rounding, not the stability.
    reversed_ = interchanges(mass_coeff) && !interchanges(mass_coeff.reverse());
    // The band of the interleaved numbering (the header above); kAuto keeps sparse LU for wide
    // bands.
    Eigen::Index lower_band = 0, upper_band = 0;
    for (const Eigen::Triplet<double>& t : triplets_) {
      const Eigen::Index row = interleaved(t.row()), col = interleaved(t.col());
      lower_band = std::max(lower_band, row - col);
      upper_band = std::max(upper_band, col - row);
    }
    const Eigen::Index dof_bandwidth = (std::max(lower_band, upper_band) + 1) / (s_ - 1) - 1;
    const double band_bytes = internal::BandLu::storage_bytes(n, lower_band, upper_band);
    if (requested == LinearSolver::kBanded ||
        (requested == LinearSolver::kAuto && dof_bandwidth <= kMaxAutoBandwidth &&
         band_bytes <= kMaxBandBytes)) {
      kind_ = LinearSolver::kBanded;
      if (band_bytes > kMaxBandBytes) {
        throw ValidationError(
            "the band LU of this Lobatto scheme's stage system would need " +
            format_number(band_bytes / 1e9) + " GB (" + std::to_string(n) + " unknowns, " +
            std::to_string(2 * lower_band + upper_band + 1) +
            " band rows): method.linear_solver = \"banded\" needs a narrow band (M, R and the "
            "Hessian of bandwidth <= " +
            std::to_string(kMaxAutoBandwidth) + " in the degrees of freedom); use \"sparse\"");
      }
      band_lu_ = internal::BandLu(n, lower_band, upper_band);
      band_constant_.assign(band_lu_.band().size(), 0.0);
      band_at_.reserve(triplets_.size());
      for (const Eigen::Triplet<double>& t : triplets_)
        band_at_.push_back(band_lu_.offset(interleaved(t.row()), interleaved(t.col())));
      for (std::size_t k = 0; k < constant_count_; ++k)
        band_constant_[band_at_[k]] += triplets_[k].value();
      return;
    }
    sparse_matrix_.resize(n, n);
    sparse_matrix_.setFromTriplets(triplets_.begin(), triplets_.end());
    sparse_matrix_.makeCompressed();
    sparse_lu_.analyzePattern(sparse_matrix_);
    sparse_work_.resize(n);
  }

  [[nodiscard]] bool needs_hessians() const { return internal_hessians_; }
  /// kDense, kBanded or kSparse.
  [[nodiscard]] LinearSolver kind() const { return kind_; }
  /// How many times factor() ran (a checkpoint sets it back: set_factorizations).
  [[nodiscard]] std::size_t factorizations() const { return factorizations_; }
  void set_factorizations(std::size_t count) { factorizations_ = count; }

  /// Forms J = constant part − h b_i ∇²U(X_i, t_i) (internal stages i = 2 … s − 1, columns of
  /// `stages`) + the state force's h b_e (δ_{eu} ∂g/∂x + σ (D_{eu}/h) ∂g/∂v) at the stage
  /// velocities `velocities` (σ the velocity sign: −1 for the mirror's reversed orientation) and
  /// factors it. False when singular.
  bool factor(const Eigen::MatrixXd& stages, const Eigen::VectorXd& times,
              const Eigen::MatrixXd& velocities) {
    ++factorizations_;
    if (kind_ == LinearSolver::kDense) {
      jacobian_ = constant_;
      for (int i = 1; internal_hessians_ && i + 1 < s_; ++i) {
        potential_->hessian(stages.col(i), times(i), hessian_);
        jacobian_.block((i - first_equation_) * d_, (i - first_unknown_) * d_, d_, d_) +=
            hessian_coeff_[i - 1] * hessian_;
      }
      for (int r = 0; state_force_ != nullptr && r + 1 < s_; ++r) {
        const int e = r + first_equation_;
        force_velocity_ = velocity_sign_ * velocities.col(e);
        state_force_->jacobians(stages.col(e), force_velocity_, times(e), force_value_, force_dx_,
                                force_dv_);
        for (int c = 0; c + 1 < s_; ++c) {
          const int u = c + first_unknown_;
          auto block = jacobian_.block(r * d_, c * d_, d_, d_);
          if (e == u) block += (h_ * b_(e)) * force_dx_;
          block += (b_(e) * velocity_sign_ * D_(e, u)) * force_dv_;
        }
      }
      lu_.compute(jacobian_);
      // PartialPivLU does not report singularity: a zero pivot shows as a non-finite solve.
      return lu_.matrixLU().diagonal().cwiseAbs().minCoeff() > 0.0;
    }
    std::size_t at = constant_count_;
    for (int i = 1; internal_hessians_ && i + 1 < s_; ++i) {
      if (potential_->has_sparse_hessian()) {
        potential_->hessian_values(stages.col(i), times(i), hessian_values_);
      } else {
        potential_->hessian(stages.col(i), times(i), hessian_);
        for (std::size_t e = 0; e < pattern_.size(); ++e)
          hessian_values_[e] = hessian_(pattern_[e].row, pattern_[e].col);
      }
      for (std::size_t e = 0; e < pattern_.size(); ++e) {
        const double v = hessian_coeff_[i - 1] * hessian_values_[e];
        set_value(at++, v);
        if (pattern_[e].row != pattern_[e].col) set_value(at++, v);
      }
    }
    if (kind_ == LinearSolver::kBanded) {
      std::vector<double>& band = band_lu_.band();
      std::copy(band_constant_.begin(), band_constant_.end(), band.begin());
      for (std::size_t k = constant_count_; k < triplets_.size(); ++k)
        band[band_at_[k]] += triplets_[k].value();
      return band_lu_.factor();
    }
    if (internal_hessians_) {
      sparse_matrix_.setFromTriplets(triplets_.begin(), triplets_.end());
      sparse_matrix_.makeCompressed();
    }
    sparse_lu_.factorize(sparse_matrix_);
    return sparse_lu_.info() == Eigen::Success;
  }

  /// rhs ← J⁻¹ rhs.
  void solve_in_place(Eigen::VectorXd& rhs, Eigen::VectorXd& scratch) const {
    if (kind_ == LinearSolver::kDense) {
      scratch.noalias() = lu_.solve(rhs);
      rhs.swap(scratch);
      return;
    }
    if (kind_ == LinearSolver::kBanded) {
      // Stage-major (d × (s − 1), column m − 1 = stage m) to interleaved ((s − 1) × d): a
      // transpose (with the stages reversed: reversed_).
      const Eigen::Index stages = s_ - 1;
      const Eigen::Map<const Eigen::MatrixXd> stage_major(rhs.data(), d_, stages);
      Eigen::Map<Eigen::MatrixXd> by_dof(scratch.data(), stages, d_);
      if (reversed_) {
        by_dof = stage_major.rowwise().reverse().transpose();
      } else {
        by_dof = stage_major.transpose();
      }
      band_lu_.solve_in_place(scratch.data());
      Eigen::Map<Eigen::MatrixXd> solved(rhs.data(), d_, stages);
      if (reversed_) {
        solved = by_dof.transpose().rowwise().reverse();
      } else {
        solved = by_dof.transpose();
      }
      return;
    }
    // Eigen's SparseLU::solve, step by step (SparseLU.h, _solve_impl), without its two
    // allocations per call: the supernodal L solve sizes a work vector each time, and the final
    // in-place column permutation a mask (a Lobatto step on a 600-mass chain allocated 2–4.5
    // times; bench/RESULTS.md). The same operations in the same order: the solution is bitwise
    // Eigen's. scratch = P_r rhs, then L and U in place, then rhs = P_c⁻¹ scratch.
    scratch.noalias() = sparse_lu_.rowsPermutation() * rhs;
    lower_solve_in_place(scratch);
    sparse_lu_.matrixU().solveInPlace(scratch);
    rhs.noalias() = sparse_lu_.colsPermutation().inverse() * scratch;
  }

 private:
  // MappedSuperNodalMatrix::solveInPlace (Eigen/src/SparseLU/SparseLU_SupernodalMatrix.h) for one
  // right-hand side, with the work vector sized once (sparse_work_) instead of on every call.
  void lower_solve_in_place(Eigen::VectorXd& x) const {
    using Supernodal = decltype(sparse_lu_.matrixL().m_mapL);
    const auto& lower = sparse_lu_.matrixL().m_mapL;
    const double* values = lower.valuePtr();
    Eigen::VectorXd& work = sparse_work_;
    for (Eigen::Index k = 0; k <= lower.nsuper(); ++k) {
      const Eigen::Index first = lower.supToCol()[k];  // the supernode's first column
      const Eigen::Index start = lower.rowIndexPtr()[first];
      const Eigen::Index rows = lower.rowIndexPtr()[first + 1] - start;
      const Eigen::Index cols = lower.supToCol()[k + 1] - first;
      const Eigen::Index below = rows - cols;  // rows below the diagonal block
      if (cols == 1) {
        typename std::remove_cvref_t<Supernodal>::InnerIterator it(lower, first);
        ++it;  // past the diagonal
        for (; it; ++it) x(it.row()) -= x(first) * it.value();
        continue;
      }
      const Eigen::Index at = lower.colIndexPtr()[first];
      const Eigen::Index lda = lower.colIndexPtr()[first + 1] - at;
      using Block = Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>>;
      const Block diagonal(values + at, cols, cols, Eigen::OuterStride<>(lda));
      Eigen::Map<Eigen::VectorXd> u(x.data() + first, cols);
      u = diagonal.triangularView<Eigen::UnitLower>().solve(u);
      const Block rest(values + at + cols, below, cols, Eigen::OuterStride<>(lda));
      work.head(below).noalias() = rest * u;
      Eigen::Index index = start + cols;
      for (Eigen::Index i = 0; i < below; ++i, ++index) {
        x(lower.rowIndex()[index]) -= work(i);
      }
    }
  }

  // Stage-major index m·d + j (unknown stage m + 1, or equation m, of dof j) in the interleaved
  // numbering j(s − 1) + m (j(s − 1) + s − 2 − m with reversed_).
  [[nodiscard]] Eigen::Index interleaved(Eigen::Index stage_major) const {
    const Eigen::Index stage = stage_major / d_;
    return (stage_major % d_) * (s_ - 1) + (reversed_ ? s_ - 2 - stage : stage);
  }

  // Whether LU with partial pivoting of `a` interchanges rows (Eigen's choice of the largest
  // entry in each column, as dgbtrf's).
  static bool interchanges(const Eigen::MatrixXd& a) {
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(a);
    const auto& p = lu.permutationP().indices();
    for (Eigen::Index i = 0; i < p.size(); ++i)
      if (p(i) != i) return true;
    return false;
  }

  void set_value(std::size_t at, double value) {
    triplets_[at] = Eigen::Triplet<double>(triplets_[at].row(), triplets_[at].col(), value);
  }

  // Up to this size the stage matrix is factored dense even for sparse storage (a d = 20 problem
  // file stores its scalar mass sparse; dense LU is faster there and allocation-free).
  static constexpr Eigen::Index kDenseUpTo = 96;
  // A band LU larger than this (bytes of band storage) is refused when forced and not chosen by
  // kAuto: a periodic chain's band spans the matrix.
  static constexpr double kMaxBandBytes = 2e9;

  int s_;
  Eigen::Index d_;
  const Potential* potential_;
  const StateForce* state_force_;
  double velocity_sign_, h_;
  Eigen::VectorXd b_, force_value_, force_velocity_;
  Eigen::MatrixXd D_, force_dx_, force_dv_;
  bool internal_hessians_;
  int first_equation_, first_unknown_;
  // The band numbering takes each degree of freedom's stages in reverse order (interleaved()).
  bool reversed_ = false;
  LinearSolver kind_ = LinearSolver::kDense;
  std::size_t factorizations_ = 0;
  std::vector<double> hessian_coeff_;  // −h b_i, internal stages
  // Dense.
  Eigen::MatrixXd constant_, jacobian_, hessian_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;
  // Band and sparse: the entries as (stage-major row, column, value); the first constant_count_
  // are M's and R's, the rest the internal stages' Hessians (set per factorisation).
  std::vector<Eigen::Triplet<double>> triplets_;
  std::size_t constant_count_ = 0;
  std::vector<Potential::HessianEntry> pattern_;
  std::vector<double> hessian_values_;
  // Band: the constant entries in band storage, where each triplet lands, and the factor.
  std::vector<double> band_constant_;
  std::vector<std::size_t> band_at_;
  internal::BandLu band_lu_;
  // Sparse.
  Eigen::SparseMatrix<double> sparse_matrix_;
  Eigen::SparseLU<Eigen::SparseMatrix<double>, Eigen::COLAMDOrdering<int>> sparse_lu_;
  mutable Eigen::VectorXd sparse_work_;  // lower_solve_in_place's products (n ≥ any supernode)
};

// ---------------------------------------------------------------------------------------------
// The stepper.

// The d × s blocks of one interval (column a = stage a) and its stage times: increments
// X_a − (the known node), stage values, X̃ = X − P, the known memory Σ_{j≥1} (W_j X̃_{n−j}), V,
// M V B D, ∇U − f, R G̃ (h^{−β} scaled), the interval force F and P's loads L.
struct Blocks {
  Eigen::MatrixXd delta, stages, tilde, memory, velocities, kinetic, forces, damping_forces, force,
      loads, state_forces;  // state_forces: g(X_a, σV_a, τ_a)
  Eigen::VectorXd times, scratch, state_velocity;
  // Where interval_force()'s one pass reads the memory: the history's kept sum (valid until its
  // next push), or null for `memory`.
  const double* kept_memory = nullptr;
  void resize(Eigen::Index d, int s) {
    for (Eigen::MatrixXd* m : {&delta, &stages, &tilde, &memory, &velocities, &kinetic, &forces,
                               &damping_forces, &force, &loads, &state_forces}) {
      m->setZero(d, s);
    }
    times.setZero(s);
    scratch.setZero(d);
    state_velocity.setZero(d);
  }
};

// interval_force() for a diagonal M and R and no state force, one pass over the rows: each degree
// of freedom's s stages are independent of the others', so its velocities, X̃ and interval forces
// come out of one loop over the rows with the s × s node matrices in registers — in place of
// about 6s + 4 passes of Eigen expressions over d × s blocks (with the step's other Eigen passes
// ≈ 40 % of a one-thread step of fvi-lobatto3 at d = 10^4, perf; bench/RESULTS.md). The operations
// per element are those of the general path in its order (the sums over the stages ascending); with
// the x86-64-v3 clone the products and sums are contracted to multiply–adds, so the results differ
// from the general path's in their last bits.
struct IntervalRows {
  Eigen::Index rows, ld;  // rows of this call; the column stride of the d × s blocks
  int last;               // force columns [0, last)
  bool forces_only;       // store only the forces (a linear step's residual)
  const double *delta, *stages, *forces, *memory, *loads;  // d × s blocks at the first row
  double *velocities, *tilde, *damping_forces, *force;
  const double* mass;     // M's diagonal
  const double* damping;  // R's diagonal; null: undamped
  const double *x0, *v0;  // P's, for X̃ = X − x_0 − τ v_0; null: X̃ = X
  double h, h_power;
  std::array<double, 4> tau, hb;                  // τ_a = t_a − t_0, h b_k
  std::array<std::array<double, 4>, 4> D, BD, W;  // D, BD, and the interval's own weight
};

// The loop with everything it reads in locals (a store through a double* could otherwise alias
// the struct, and GCC would reload its fields every row instead of vectorising), and the number of
// force columns, the damping and P's split as template parameters. The pass is bound by moving
// its d × s blocks (at d = 10^4 they come from L3): a linear step's residual (kStore false) stores
// only the forces — the velocities, X̃ and damping forces are read after the accepted stages' call
// (a nonlinear step's Newton reads X̃ for its stopping rule and keeps the velocities with its
// matrix) — and without loads (a Caputo order above 1 has none) they are not read.
template <int S, int kLast, bool kDamped, bool kSplit, bool kLoads, bool kStore>
[[gnu::always_inline]] inline void interval_rows(const IntervalRows& r) {
  const Eigen::Index n = r.rows, ld = r.ld;
  const double* delta = r.delta;
  const double* stages = r.stages;
  const double* forces = r.forces;
  const double* memory = r.memory;
  const double* loads = r.loads;
  double* velocities = r.velocities;
  double* tilde_out = r.tilde;
  double* damping_forces = r.damping_forces;
  double* force = r.force;
  const double* mass = r.mass;
  const double* damping = r.damping;
  const double* x0 = r.x0;
  const double* v0 = r.v0;
  const double h = r.h, h_power = r.h_power;
  double tau[S], hb[S], D[S][S], BD[S][S], W[S][S];
  for (int a = 0; a < S; ++a) {
    tau[a] = r.tau[a];
    hb[a] = r.hb[a];
    for (int j = 0; j < S; ++j) {
      D[a][j] = r.D[a][j];
      BD[a][j] = r.BD[a][j];
      W[a][j] = r.W[a][j];
    }
  }
  FRACVI_INDEPENDENT_ITERATIONS
  for (Eigen::Index i = 0; i < n; ++i) {
    double kinetic[S], tilde[S];
    for (int a = 0; a < S; ++a) {
      double v = 0.0;
      for (int j = 0; j < S; ++j) v += delta[j * ld + i] * D[a][j];
      v /= h;
      if constexpr (kStore) velocities[a * ld + i] = v;
      kinetic[a] = mass[i] * v;
      if constexpr (kDamped) {
        const double x = stages[a * ld + i];
        tilde[a] = kSplit ? (x - x0[i]) - tau[a] * v0[i] : x;
        if constexpr (kStore) tilde_out[a * ld + i] = tilde[a];
      }
    }
    for (int k = 0; k < kLast; ++k) {
      double f = 0.0;
      for (int a = 0; a < S; ++a) f += kinetic[a] * BD[a][k];
      f -= hb[k] * forces[k * ld + i];
      if constexpr (kDamped) {
        double g = 0.0;
        for (int l = 0; l < S; ++l) g += tilde[l] * W[k][l];
        g += memory[k * ld + i];
        const double damping_force = (damping[i] * g) * h_power;
        if constexpr (kStore) damping_forces[k * ld + i] = damping_force;
        f -= hb[k] * damping_force;
      }
      force[k * ld + i] = kLoads ? f - loads[k * ld + i] : f;
    }
  }
}

template <int S>
struct IntervalKernel {
  template <int kLast, bool kLoads, bool kStore>
  FRACVI_HOT_KERNEL static void run(const IntervalRows& r) {
    if (r.damping == nullptr) {
      interval_rows<S, kLast, false, false, kLoads, kStore>(r);
    } else if (r.x0 == nullptr) {
      interval_rows<S, kLast, true, false, kLoads, kStore>(r);
    } else {
      interval_rows<S, kLast, true, true, kLoads, kStore>(r);
    }
  }
  template <int kLast, bool kStore>
  static void run(const IntervalRows& r) {
    if (r.loads != nullptr) {
      run<kLast, true, kStore>(r);
    } else {
      run<kLast, false, kStore>(r);
    }
  }
  static void run(const IntervalRows& r) {
    if (r.last == S) {
      run<S, true>(r);
    } else if (r.forces_only) {
      assert(r.last == S - 1);
      run<S - 1, false>(r);
    } else {
      assert(r.last == S - 1);
      run<S - 1, true>(r);
    }
  }
};

// advance()'s passes over the d × s blocks, one loop over the rows each, with the operations of
// the Eigen expressions they replaced (a pass per operation: a copy, an add, a negation, a max, a
// finiteness check), in the same order, so the same numbers. Finiteness as in vector_passes.hpp:
// Σ 0·v is 0 exactly when every v is finite.
// The guess Δ_a = (c_a h) v_n and X_a = Δ_a + x_n.
void guess_pass(const double* ch, int s, const double* v, const double* x, double* delta,
                double* stages, Eigen::Index d) {
  for (int a = 0; a < s; ++a) {
    double* da = delta + a * d;
    double* xa = stages + a * d;
    const double c = ch[a];
    for (Eigen::Index i = 0; i < d; ++i) {
      da[i] = c * v[i];
      xa[i] = da[i] + x[i];
    }
  }
}

// Newton's right-hand side −r: −F_{n,1} − p_n, −F_{n,i} (i = 2 … s − 1); whether it is finite.
bool residual_pass(const double* force, const double* p, int s, double* residual, Eigen::Index d) {
  double zero = 0.0;
  for (int m = 0; m + 1 < s; ++m) {
    const double* f = force + m * d;
    double* r = residual + m * d;
    if (m == 0) {
#pragma omp simd reduction(+ : zero)
      for (Eigen::Index i = 0; i < d; ++i) {
        r[i] = -f[i] - p[i];
        zero += 0.0 * r[i];
      }
    } else {
#pragma omp simd reduction(+ : zero)
      for (Eigen::Index i = 0; i < d; ++i) {
        r[i] = -f[i];
        zero += 0.0 * r[i];
      }
    }
  }
  return zero == 0.0;
}

// The correction δ (in place of the residual) onto Δ_m and X_m = Δ_m + x_n, m = 2 … s (the first
// stage is x_n, unchanged); max|δ| and whether the new stages are finite.
struct StageCorrection {
  double size = 0.0;
  bool finite = true;
};
StageCorrection correction_pass(const double* delta_in, const double* x, int s, double* delta,
                                double* stages, Eigen::Index d) {
  double size = 0.0, zero = 0.0;
  for (int m = 1; m < s; ++m) {
    const double* c = delta_in + (m - 1) * d;
    double* dm = delta + m * d;
    double* xm = stages + m * d;
#pragma omp simd reduction(max : size) reduction(+ : zero)
    for (Eigen::Index i = 0; i < d; ++i) {
      dm[i] += c[i];
      xm[i] = dm[i] + x[i];
      size = std::max(size, std::abs(c[i]));
      zero += 0.0 * xm[i];
    }
  }
  return {size, zero == 0.0};
}

class LobattoStepper final : public Stepper {
 public:
  LobattoStepper(int stages, const InitialValueProblem& problem, const IntegratorOptions& options)
      : problem_(problem),
        options_(options),
        nodes_(stages),
        s_(stages),
        beta_(problem.model.damping_order()),
        d_(problem.model.dimension()),
        h_(problem.step_size()),
        damped_(!problem.model.is_undamped()),
        has_forcing_(static_cast<bool>(problem.model.forcing)),
        forcing_moments_(has_forcing_ && options.load == ForcingLoad::kMoments),
        u_time_dependent_(problem.model.potential && problem.model.potential->is_time_dependent()),
        diagnostics_(options.diagnostics),
        potential_(problem.model.potential.get()),
        w0_(RungeKuttaCq{stages, beta_, 0}.weight(0)),
        mass_(problem.model.mass.symmetric_part()),
        damping_(problem.model.damping.symmetric_part()),
        state_force_(problem.model.state_force.get()),
        mass_solver_(mass_, damping_, options.linear_solver),
        stage_matrix_(nodes_, w0_, h_, beta_, mass_, damping_, damped_, potential_,
                      options.linear_solver, 0, 1, state_force_),
        linear_(state_force_ == nullptr &&
                (s_ == 2 || potential_ == nullptr || potential_->has_constant_hessian())),
        h_power_(std::pow(h_, -beta_)) {
    const bool caputo = problem.model.convention == Convention::kCaputo;
    split_ = damped_ && beta_ > 0.0;
    // A diagonal M and R and no state force: interval_force() in one pass over the rows.
    fused_rows_ = state_force_ == nullptr && d_ >= kVectorPassesFrom &&
                  mass_.stored_diagonal() != nullptr &&
                  (!damped_ || damping_.stored_diagonal() != nullptr);
    // D^β P per unit R (fvi_midpoint.cpp, same cases): v_0 τ^{1−β}/Γ(2−β) (0 < β < 2; none for
    // Caputo β > 1), and for Riemann–Liouville 0 < β < 1 x_0 τ^{−β}/Γ(1−β). Moments scale h^γ.
    if (split_ && !(caputo && beta_ > 1.0)) {
      velocity_load_ = std::make_unique<PowerMoments>(
          nodes_, 1.0 - beta_, std::pow(h_, 1.0 - beta_) / boost::math::tgamma(2.0 - beta_));
    }
    if (split_ && !caputo && beta_ < 1.0) {
      position_load_ = std::make_unique<PowerMoments>(
          nodes_, -beta_, std::pow(h_, -beta_) / boost::math::tgamma(1.0 - beta_));
    }
    cur_.resize(d_, s_);
    if (forcing_moments_) {
      forcing_load_ =
          std::make_unique<ForcingMoments>(nodes_.basis, nodes_.slope, problem.model.forcing, d_);
      forcing_value_.setZero(d_, s_);
      forcing_slope_.setZero(d_, s_);
    }
    has_loads_ = velocity_load_ || position_load_ || forcing_load_;
    for (Eigen::VectorXd* v : {&x_, &v_, &p_, &r_v0_, &r_x0_}) v->setZero(d_);
    for (Eigen::VectorXd* v : {&load_v_, &load_x_, &work_v_, &work_x_}) v->setZero(s_);
    residual_.setZero((s_ - 1) * d_);
    solve_scratch_.setZero((s_ - 1) * d_);
    factored_stages_.setZero(d_, s_);
    factored_times_.setZero(s_);
    factored_velocities_.setZero(d_, s_);
    if (damped_) {
      damping_.multiply(problem.x0, r_x0_);
      damping_.multiply(problem.v0, r_v0_);
      const RungeKuttaCq known{s_, beta_, /*lag=*/1};
      // β = 0: W_j = 0 for j ≥ 1, nothing to remember.
      if (beta_ > 0.0) {
        history_ = make_block_history(options.history, known, d_, problem.steps,
                                      stepper_history_tolerance(options));
        history_->set_threads(options.threads);
      }
    }
    x_ = problem.x0;
    v_ = problem.v0;
    mass_.multiply(problem.v0, p_);
    work_ = supplied_ = diagnostics_ ? 0.0 : kNaN;
    if (linear_) {
      cur_.stages.colwise() = problem.x0;
      for (int a = 0; a < s_; ++a) cur_.times(a) = problem.t0 + nodes_.c(a) * h_;
      if (!stage_matrix_.factor(cur_.stages, cur_.times, cur_.velocities)) {
        throw ValidationError("the stage system of " + std::string(name()) +
                              " is singular for this problem (h = " + format_number(h_) + ")");
      }
    }
  }

  [[nodiscard]] const Eigen::VectorXd& position() const override { return x_; }
  [[nodiscard]] const Eigen::VectorXd& velocity() const override { return v_; }
  [[nodiscard]] const Eigen::VectorXd& momentum() const override { return p_; }
  [[nodiscard]] double work() const override { return work_; }
  [[nodiscard]] double supplied_work() const override { return supplied_; }
  [[nodiscard]] LinearSolver linear_solver() const override { return stage_matrix_.kind(); }
  [[nodiscard]] std::size_t jacobian_factorizations() const override {
    return stage_matrix_.factorizations();
  }
  [[nodiscard]] HistoryReport history() const override {
    return history_ ? history_->report() : HistoryReport{};
  }
  /// The step index k (SeriesShiftStepper maps the state at t_k).
  [[nodiscard]] std::size_t step_index() const { return n_; }
  [[nodiscard]] const Eigen::MatrixXd* stage_values() const override {
    return n_ > 0 ? &cur_.stages : nullptr;
  }

  void visit_state(StateArchive& archive) override {
    visit_step_index(archive, d_, problem_.steps, n_);
    archive.expect("lobatto.stages", static_cast<std::size_t>(s_));
    archive.dense("lobatto.x", x_);
    archive.dense("lobatto.v", v_);  // M⁻¹p_n, Newton's guess
    archive.dense("lobatto.p", p_);
    archive.dense("lobatto.stage_values", cur_.stages);  // stage_values() of the last interval
    archive.number("lobatto.work", work_);
    archive.number("lobatto.supplied", supplied_);
    std::size_t factorizations = stage_matrix_.factorizations();
    archive.count("lobatto.factorizations", factorizations);
    if (!linear_) {
      // Simplified Newton keeps the stage matrix of an earlier iterate, possibly of an earlier
      // step: it is formed again at the same stages and times (the same bits), so that the
      // resumed iterates are the uninterrupted ones.
      archive.flag("lobatto.factored", factored_);
      archive.dense("lobatto.factored_stages", factored_stages_);
      archive.dense("lobatto.factored_times", factored_times_);
      if (state_force_ != nullptr)
        archive.dense("lobatto.factored_velocities", factored_velocities_);
      if (archive.loading() && factored_ &&
          !stage_matrix_.factor(factored_stages_, factored_times_, factored_velocities_)) {
        throw CheckpointError(
            "checkpoint record 'lobatto.factored_stages': the stage matrix "
            "cannot be factored there (corrupt)");
      }
    }
    // The recorded count: forming the kept matrix again is not a factorisation of the run's.
    if (archive.loading()) stage_matrix_.set_factorizations(factorizations);
    archive.optional("lobatto.history", history_.get());
  }

 private:
  [[nodiscard]] std::string_view name() const {
    return s_ == 2 ? "fvi-lobatto2" : (s_ == 3 ? "fvi-lobatto3" : "fvi-lobatto4");
  }
  Status advance() override;
  // Columns a ∈ [first, last) of b.forces: ∇U(X_a, τ_a) − f(τ_a) at the stage times b.times.
  void stage_forces(Blocks& b, int first, int last) const;
  // b.tilde = b.stages − P(b.times) (b.stages when there is no split).
  void subtract_polynomial(Blocks& b) const;
  // Columns [0, last) of F (b.force) from b.delta, b.stages (= known node + b.delta), b.memory,
  // b.loads and b.forces, with `current` the weight of the interval's own stages (W_0 for the
  // x-equation, J W_0 J for the mirror y-equation).
  // The state force g enters with the velocity σV (σ = velocity_sign: −1 for the mirror's
  // reversed orientation, where the physical velocity is −ẏ).
  void interval_force(Blocks& b, const Eigen::MatrixXd& current, int last,
                      double velocity_sign = 1.0) const;
  [[nodiscard]] bool mirror_run(MirrorRows& rows) const override;
  [[nodiscard]] bool mirror_steps(MirrorRows& rows) const;  // mirror_run but for its catch

  const InitialValueProblem& problem_;
  IntegratorOptions options_;
  LobattoNodes nodes_;
  int s_;
  double beta_;
  Eigen::Index d_;
  double h_;
  bool damped_, has_forcing_, forcing_moments_, u_time_dependent_, diagnostics_;
  const Potential* potential_;
  Eigen::MatrixXd w0_;
  ModelMatrix mass_, damping_;
  const StateForce* state_force_;
  MassSolver mass_solver_;
  StageMatrix stage_matrix_;
  bool linear_;
  bool factored_ =
      false;  // nonlinear U: the stage matrix holds a factorisation (simplified Newton) …
  Eigen::MatrixXd factored_stages_;      // … formed at these stages (d × s)
  Eigen::VectorXd factored_times_;       // … and stage times (for a checkpoint to form it again)
  Eigen::MatrixXd factored_velocities_;  // … and stage velocities (with a state force g)
  double h_power_;                       // h^{−β}
  bool split_ = false;
  bool fused_rows_ = false;  // interval_force() by IntervalKernel
  bool has_loads_ = false;   // P's or f's moments: Blocks::loads is not zero
  std::unique_ptr<PowerMoments> velocity_load_, position_load_;
  std::unique_ptr<ForcingMoments> forcing_load_;
  Eigen::MatrixXd forcing_value_, forcing_slope_;  // d × s moments of f on the current interval
  std::unique_ptr<BlockHistory> history_;

  std::size_t n_ = 0;
  Eigen::VectorXd x_, v_, p_, r_v0_, r_x0_, load_v_, load_x_, work_v_, work_x_, residual_,
      solve_scratch_;
  Blocks cur_;
  double work_ = 0.0, supplied_ = 0.0;
};

void LobattoStepper::stage_forces(Blocks& b, int first, int last) const {
  for (int a = first; a < last; ++a) {
    auto g = b.forces.col(a);
    if (potential_ != nullptr) {
      potential_->gradient(b.stages.col(a), b.times(a), g);
    } else {
      g.setZero();
    }
    if (has_forcing_ && !forcing_moments_) {
      problem_.model.forcing(b.times(a), b.scratch);
      g -= b.scratch;
    }
  }
}

void LobattoStepper::subtract_polynomial(Blocks& b) const {
  if (!split_) {
    b.tilde = b.stages;
    return;
  }
  // One pass per stage, the roundings of x − x_0 and then − τ v_0 (as two in-place passes made).
  for (int a = 0; a < s_; ++a) {
    const double tau = b.times(a) - problem_.t0;
    b.tilde.col(a) = (b.stages.col(a) - problem_.x0) - tau * problem_.v0;
  }
}

void LobattoStepper::interval_force(Blocks& b, const Eigen::MatrixXd& current, int last,
                                    double velocity_sign) const {
  if (fused_rows_) {
    IntervalRows r{};
    r.rows = d_;
    r.ld = d_;
    r.last = last;
    r.forces_only = last < s_ && linear_;
    r.delta = b.delta.data();
    r.stages = b.stages.data();
    r.forces = b.forces.data();
    r.memory = b.kept_memory != nullptr ? b.kept_memory : b.memory.data();
    r.loads = has_loads_ ? b.loads.data() : nullptr;
    r.velocities = b.velocities.data();
    r.tilde = b.tilde.data();
    r.damping_forces = b.damping_forces.data();
    r.force = b.force.data();
    r.mass = mass_.stored_diagonal()->data();
    r.damping = damped_ ? damping_.stored_diagonal()->data() : nullptr;
    r.x0 = split_ ? problem_.x0.data() : nullptr;
    r.v0 = split_ ? problem_.v0.data() : nullptr;
    r.h = h_;
    r.h_power = h_power_;
    for (int a = 0; a < s_; ++a) {
      r.tau[a] = b.times(a) - problem_.t0;
      r.hb[a] = h_ * nodes_.b(a);
      for (int j = 0; j < s_; ++j) {
        r.D[a][j] = nodes_.D(a, j);
        r.BD[a][j] = nodes_.BD(a, j);
        r.W[a][j] = current(a, j);
      }
    }
    switch (s_) {
      case 2: IntervalKernel<2>::run(r); break;
      case 3: IntervalKernel<3>::run(r); break;
      default: IntervalKernel<4>::run(r); break;
    }
    return;
  }
  // V = Δ Dᵀ / h (Σ_k D_{ak} = 0, so increments suffice: no cancellation of the node value),
  // then Σ_a b_a D_{ak} M V_a = (M V B D)_k.
  b.velocities.noalias() = b.delta * nodes_.D.transpose();
  b.velocities /= h_;
  for (int a = 0; a < s_; ++a) mass_.multiply(b.velocities.col(a), b.kinetic.col(a));
  if (damped_) subtract_polynomial(b);
  for (int k = 0; k < last; ++k) {
    auto f = b.force.col(k);
    f.noalias() = b.kinetic * nodes_.BD.col(k);
    f -= (h_ * nodes_.b(k)) * b.forces.col(k);
    if (state_force_ != nullptr) {
      // The Lobatto quadrature of ∫ g·δx dt: + h b_k g(X_k, σV_k, τ_k) (docs/theory/forces.md §5).
      b.state_velocity = velocity_sign * b.velocities.col(k);
      state_force_->value(b.stages.col(k), b.state_velocity, b.times(k), b.state_forces.col(k));
      f += (h_ * nodes_.b(k)) * b.state_forces.col(k);
    }
    if (damped_) {
      // R G̃_k = R h^{−β} (Σ_l current_{kl} X̃_l + memory_k).
      b.scratch.noalias() = b.tilde * current.row(k).transpose();
      b.scratch += b.memory.col(k);
      damping_.multiply(b.scratch, b.damping_forces.col(k));
      b.damping_forces.col(k) *= h_power_;
      f -= (h_ * nodes_.b(k)) * b.damping_forces.col(k);
    }
    f -= b.loads.col(k);
  }
}

Status LobattoStepper::advance() {
  const std::size_t n = n_;
  const double tn = problem_.time(static_cast<double>(n));
  for (int a = 0; a < s_; ++a) cur_.times(a) = tn + nodes_.c(a) * h_;
  // Known this step: the memory of the earlier intervals and the Taylor polynomial's loads.
  cur_.kept_memory = nullptr;
  if (damped_) {
    if (history_ && history_->size() > 0) {
      // The one pass reads the sum where the history keeps it (no d × s copy).
      if (fused_rows_) cur_.kept_memory = history_->kept_sum();
      if (cur_.kept_memory == nullptr) history_->sum(cur_.memory);
    } else {
      cur_.memory.setZero();
    }
  }
  if (has_loads_) cur_.loads.setZero();  // (else it stays zero)
  if (velocity_load_) {
    (*velocity_load_)(n, load_v_, work_v_);
    for (int a = 0; a < s_; ++a) cur_.loads.col(a) += (h_ * load_v_(a)) * r_v0_;
  }
  if (position_load_) {
    (*position_load_)(n, load_x_, work_x_);
    for (int a = 0; a < s_; ++a) cur_.loads.col(a) += (h_ * load_x_(a)) * r_x0_;
  }
  if (forcing_load_) {
    // f enters F as +h∫ℓ_k f (the pointwise form's +h b_k f(t_{n,k})).
    (*forcing_load_)(tn, h_, n == 0, forcing_value_, forcing_slope_);
    cur_.loads.noalias() -= h_ * forcing_value_;
  }
  // Guess: the stages on the line x_n + (t − t_n) v_n (v_n = M⁻¹p_n, kept by the previous step).
  std::array<double, 4> ch{};
  for (int a = 0; a < s_; ++a) ch[a] = nodes_.c(a) * h_;
  guess_pass(ch.data(), s_, v_.data(), x_.data(), cur_.delta.data(), cur_.stages.data(), d_);
  stage_forces(cur_, 0, s_ - 1);
  const NewtonOptions& newton = options_.newton;
  int iterations = 0;
  // Simplified Newton for nonlinear U: the stage matrix of an earlier iterate (or step) is kept
  // while the corrections contract fast (θ = |δ_k|/|δ_{k−1}| ≤ kRefactorContraction) and formed
  // again at the current iterate when they do not; the limit is the same (the residual is exact),
  // only the factorisations are fewer (one every few steps for smooth motion instead of one per
  // iteration: the sparse LU dominated the cost of the chains, bench/RESULTS.md).
  constexpr double kRefactorContraction = 0.25;
  bool refactor = !factored_;
  // A matrix kept from an earlier step has no observed contraction at the first correction.
  const bool kept_from_earlier_step = !refactor && !linear_;
  double previous_correction = std::numeric_limits<double>::infinity();
  for (;;) {
    interval_force(cur_, w0_, s_ - 1);
    // Residual rows: p_n + F_{n,1}, F_{n,i} (i = 2 … s − 1); Newton: J δ = −r.
    if (!residual_pass(cur_.force.data(), p_.data(), s_, residual_.data(), d_))
      return fail(Status::kNonFinite, "non-finite stage residual");
    if (!linear_ && refactor) {
      factored_stages_ = cur_.stages;
      factored_times_ = cur_.times;
      factored_velocities_ = cur_.velocities;
      factored_ = stage_matrix_.factor(cur_.stages, cur_.times, cur_.velocities);
      if (!factored_) {
        return fail(Status::kNewtonFailure,
                    "the stage system's Newton matrix could not be factored (singular)");
      }
      refactor = false;
    }
    stage_matrix_.solve_in_place(residual_, solve_scratch_);
    ++iterations;
    const StageCorrection corrected =
        correction_pass(residual_.data(), x_.data(), s_, cur_.delta.data(), cur_.stages.data(), d_);
    const double correction = corrected.size;
    if (!corrected.finite) return fail(Status::kNonFinite, "non-finite stage values");
    if (linear_) break;  // the equations are linear in the stages: one correction is exact
    stage_forces(cur_, 1, s_ - 1);
    // The stopping rule of NewtonOptions, floored at the round-off of the stage equations: the
    // memory acts on X̃ = X − P, and P(t) = x_0 + (t − t_0) v_0 grows with t, so the corrections
    // stall at a few ulps of max|X̃| (measured: 9e-17 against a requested 8.7e-17 with |X| =
    // 0.009, |X̃| = 24 at t = 125), which a tight relative tolerance could otherwise never meet.
    const double scale = std::max(cur_.stages.cwiseAbs().maxCoeff(), x_.cwiseAbs().maxCoeff());
    const double roundoff_scale =
        damped_ ? std::max(scale, cur_.tilde.cwiseAbs().maxCoeff()) : scale;
    const double tolerance =
        std::max(newton.absolute_tolerance + newton.relative_tolerance * scale,
                 4.0 * std::numeric_limits<double>::epsilon() * roundoff_scale);
    const double contraction = iterations == 1 && kept_from_earlier_step
                                   ? std::numeric_limits<double>::infinity()
                                   : correction / previous_correction;
    if (newton_converged(correction, tolerance, contraction,
                         4.0 * std::numeric_limits<double>::epsilon() * roundoff_scale))
      break;
    if (correction > kRefactorContraction * previous_correction) refactor = true;
    previous_correction = correction;
    if (iterations >= newton.max_iterations) {
      set_iterations(iterations);
      return fail(Status::kNewtonFailure,
                  "Newton on the stage system did not converge within %d iterations (last "
                  "correction %.3e > tolerance %.3e)",
                  iterations, correction, tolerance);
    }
  }
  set_iterations(iterations);
  // p_{n+1} = F_{n,s}, the right discrete Legendre transform (with the damping).
  stage_forces(cur_, s_ - 1, s_);
  if (linear_) stage_forces(cur_, 1, s_ - 1);  // (the Newton loop left them at the accepted stages)
  interval_force(cur_, w0_, s_);
  if (!cur_.force.allFinite()) return fail(Status::kNonFinite, "non-finite momentum");
  if (diagnostics_) {
    // W += h Σ_a b_a (R G̃_a − f_a)·V_a + ∫ R D^βP · ẋ_h dt (exact moments) − ∫ ∂_t U dt.
    // The work of f and of ∂_tU is also summed apart (supplied_work(): the health check tells
    // energy put in from outside from energy put in by an unstable damping term).
    auto supply = [&](double w) {
      work_ -= w;
      supplied_ += w;
    };
    for (int a = 0; a < s_; ++a) {
      if (damped_) {
        work_ += h_ * nodes_.b(a) * cur_.damping_forces.col(a).dot(cur_.velocities.col(a));
      }
      if (has_forcing_ && !forcing_moments_) {
        problem_.model.forcing(cur_.times(a), cur_.scratch);
        supply(h_ * nodes_.b(a) * cur_.scratch.dot(cur_.velocities.col(a)));
      }
      if (forcing_moments_) supply(forcing_slope_.col(a).dot(cur_.delta.col(a)));
      // g's work by the same quadrature, h b_a g_a·V_a.
      if (state_force_ != nullptr)
        supply(h_ * nodes_.b(a) * cur_.state_forces.col(a).dot(cur_.velocities.col(a)));
      if (damped_ && velocity_load_) work_ += work_v_(a) * r_v0_.dot(cur_.delta.col(a));
      if (damped_ && position_load_) work_ += work_x_(a) * r_x0_.dot(cur_.delta.col(a));
      if (u_time_dependent_) {
        // ∂_t U at the stage by a central difference (step ε^{1/3} scale: error ~ 1e-11 relative).
        const double dt = 6e-6 * std::max(1.0, std::abs(cur_.times(a)));
        const double dudt = (potential_->value(cur_.stages.col(a), cur_.times(a) + dt) -
                             potential_->value(cur_.stages.col(a), cur_.times(a) - dt)) /
                            (2.0 * dt);
        supply(h_ * nodes_.b(a) * dudt);
      }
    }
  }
  // X̃ of the accepted stages: formed by the last interval_force() (a history means damping).
  if (history_) history_->push(cur_.tilde);
  x_ = cur_.stages.col(s_ - 1);
  p_ = cur_.force.col(s_ - 1);
  mass_solver_.inverse(p_, v_);
  if (!x_.allFinite() || !v_.allFinite()) return fail(Status::kNonFinite, "non-finite state");
  ++n_;
  return Status::kSuccess;
}

// The mirror run (fvi_lobatto.md §5): the y-equation solved backwards, interval m = N − 1 … 0, in
// its own orientation. Unknowns Y_{m,1 … s−1} (0-based stages 0 … s − 2; Y_{m,s} = y_{m+1} known),
// equations F^y_{m,s} = q_{m+1} (node) and F^y_{m,i} = 0 (internal), then y_m = Y_{m,1} and
// q_m = −F^y_{m,1}; start y_N = x_0, q_N = −M v_0. F^y is F with U_f at the mirrored times
// a + b − t_{m,a}, P's loads of the mirrored interval, the forward-running memory
// Σ_{j≥0} J W_j J Ỹ_{m+j} (a causal block history over Ỹ_{N−1}, Ỹ_{N−2}, … fed with the stages
// reversed and read back reversed), and J W_0 J on the interval's own stages. Nothing is shared
// with the x-run but the model: the reversed trajectory solves these equations exactly (the
// symmetry W_jᵀB = J B W_j J of Lobatto IIIC), so the difference is round-off.
bool LobattoStepper::mirror_run(MirrorRows& rows) const {
  try {
    return mirror_steps(rows);
  } catch (...) {
    return false;  // a callback threw: the check is unavailable, the run not invalid
  }
}

bool LobattoStepper::mirror_steps(MirrorRows& rows) const {
  const std::size_t n_steps = problem_.steps;
  const std::span<const std::size_t> steps = rows.steps();
  const Eigen::MatrixXd reversal = Eigen::MatrixXd::Identity(s_, s_).rowwise().reverse();
  const Eigen::MatrixXd current = reversal * w0_ * reversal;
  // The y-curve runs backwards in time: g sees the physical velocity −ẏ (σ = −1).
  StageMatrix matrix(nodes_, current, h_, beta_, mass_, damping_, damped_, potential_,
                     options_.linear_solver, /*first_equation=*/1, /*first_unknown=*/0,
                     state_force_, /*velocity_sign=*/-1.0);
  std::unique_ptr<BlockHistory> history;
  if (damped_ && beta_ > 0.0) {
    history = make_block_history(options_.history, RungeKuttaCq{s_, beta_, 1}, d_, n_steps,
                                 stepper_history_tolerance(options_));
  }
  std::unique_ptr<PowerMoments> velocity_load, position_load;
  if (velocity_load_) velocity_load = std::make_unique<PowerMoments>(*velocity_load_);
  if (position_load_) position_load = std::make_unique<PowerMoments>(*position_load_);
  std::unique_ptr<ForcingMoments> forcing_load;
  Eigen::MatrixXd forcing_value(d_, s_), forcing_slope(d_, s_);
  if (forcing_moments_) {
    forcing_load =
        std::make_unique<ForcingMoments>(nodes_.basis, nodes_.slope, problem_.model.forcing, d_);
  }
  // Its own M⁻¹: a sparse M's factor solves in a workspace of its own, and the x-run may be
  // solving with mass_solver_ on another thread (Stepper::mirror_run).
  const MassSolver mass_solver(mass_, damping_, options_.linear_solver);
  Blocks y;
  y.resize(d_, s_);
  Eigen::VectorXd node = problem_.x0, q(d_), yv(d_), value(s_), slope(s_);
  mass_.multiply(problem_.v0, q);
  q = -q;
  Eigen::VectorXd residual((s_ - 1) * d_), scratch((s_ - 1) * d_);
  Eigen::MatrixXd reversed(d_, s_);
  const bool linear = linear_;
  if (linear) {
    y.stages.colwise() = node;
    y.times.setConstant(problem_.t_end);
    if (!matrix.factor(y.stages, y.times, y.velocities)) return false;
  }
  // Stored rows: x at steps[i] mirrors y at N − steps[i]; walk them as y_m is produced.
  std::size_t row = 0;
  auto compare = [&](std::size_t m, const Eigen::VectorXd& ym) {
    while (row < steps.size() && steps[row] < n_steps - m) ++row;
    if (row < steps.size() && steps[row] == n_steps - m) rows.put(row, ym);
  };
  compare(n_steps, node);
  for (std::size_t m = n_steps; m-- > 0;) {
    if (rows.stop()) return false;
    const double tm = problem_.time(static_cast<double>(m));
    for (int a = 0; a < s_; ++a)
      y.times(a) = problem_.t0 + problem_.t_end - (tm + nodes_.c(a) * h_);
    if (damped_) {
      if (history && history->size() > 0) {
        history->sum(reversed);
        y.memory = reversed.rowwise().reverse();
      } else {
        y.memory.setZero();
      }
    }
    y.loads.setZero();
    const std::size_t mirrored = n_steps - 1 - m;  // the x-interval of the same times
    if (velocity_load) {
      (*velocity_load)(mirrored, value, slope);
      for (int a = 0; a < s_; ++a) y.loads.col(a) += (h_ * value(s_ - 1 - a)) * r_v0_;
    }
    if (position_load) {
      (*position_load)(mirrored, value, slope);
      for (int a = 0; a < s_; ++a) y.loads.col(a) += (h_ * value(s_ - 1 - a)) * r_x0_;
    }
    if (forcing_load) {
      (*forcing_load)(problem_.time(static_cast<double>(mirrored)), h_, mirrored == 0,
                      forcing_value, forcing_slope);
      y.loads.noalias() -= h_ * forcing_value.rowwise().reverse();
    }
    // Guess: the line through y_{m+1} with the y-velocity M⁻¹q_{m+1}.
    mass_solver.inverse(q, yv);
    for (int a = 0; a < s_; ++a) y.delta.col(a) = (-(1.0 - nodes_.c(a)) * h_) * yv;
    y.stages = y.delta;
    y.stages.colwise() += node;
    stage_forces(y, 0, s_);
    double previous_correction = std::numeric_limits<double>::infinity();
    for (int iteration = 1;; ++iteration) {
      interval_force(y, current, s_, -1.0);
      for (int r = 0; r + 1 < s_; ++r) residual.segment(r * d_, d_) = -y.force.col(r + 1);
      residual.tail(d_) += q;
      if (!residual.allFinite()) return false;
      if (!linear && !matrix.factor(y.stages, y.times, y.velocities)) return false;
      matrix.solve_in_place(residual, scratch);
      double correction = 0.0;
      for (int c = 0; c + 1 < s_; ++c) {
        y.delta.col(c) += residual.segment(c * d_, d_);
        correction = std::max(correction, residual.segment(c * d_, d_).cwiseAbs().maxCoeff());
      }
      y.stages = y.delta;
      y.stages.colwise() += node;
      stage_forces(y, 0, s_);
      if (linear) break;
      const double scale = std::max(y.stages.cwiseAbs().maxCoeff(), y.tilde.cwiseAbs().maxCoeff());
      const double tolerance =
          std::max(options_.newton.absolute_tolerance + options_.newton.relative_tolerance * scale,
                   4.0 * std::numeric_limits<double>::epsilon() * scale);
      if (newton_converged(correction, tolerance, correction / previous_correction,
                           4.0 * std::numeric_limits<double>::epsilon() * scale))
        break;
      previous_correction = correction;
      if (iteration >= options_.newton.max_iterations) return false;
    }
    interval_force(y, current, s_, -1.0);
    if (history) {
      subtract_polynomial(y);
      reversed = y.tilde.rowwise().reverse();
      history->push(reversed);
    }
    node = y.stages.col(0);
    q = -y.force.col(0);
    if (!node.allFinite() || !q.allFinite()) return false;
    compare(m, node);
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Registry: stability bounds (fvi_lobatto.md §8.2).

// κ* = sup of λ_max(M⁻¹∇²U) h² for the undamped Lobatto IIIA–IIIB method (ωh < 2, 2√2, √30).
double undamped_bound(int s) {
  return s == 2 ? 4.0 : (s == 3 ? 8.0 : 30.0);
}

// ρ*_0(s, β): the first λ_max(M⁻¹R) h^{2−β} at which a root of the characteristic function enters
// the unit disc, κ → 0, measured on β = 0.1, 0.25, 0.5, 0.75, 0.9 (fvi_lobatto.md §8.2; β = 0 is
// the spring limit ρ* = κ*). Between table points the smaller neighbour is used (the bound is not
// monotone in β for s = 3, 4), and 0.9 ≤ β < 1 uses the β = 0.9 value (the bound grows without
// limit as β → 1). Only for 0 < β < 1.
double damping_bound(int s, double beta) {
  static constexpr std::array<double, 6> kBeta{0.0, 0.1, 0.25, 0.5, 0.75, 0.9};
  static constexpr std::array<std::array<double, 6>, 3> kRho{{
      {4.0, 4.00, 4.13, 4.92, 8.02, 18.1},
      {8.0, 7.90, 20.2, 19.5, 25.7, 50.6},
      {30.0, 26.9, 55.0, 46.5, 53.3, 96.8},
  }};
  const auto& rho = kRho[static_cast<std::size_t>(s - 2)];
  if (beta >= kBeta.back()) return rho.back();
  for (std::size_t i = 0; i + 1 < kBeta.size(); ++i) {
    if (beta == kBeta[i + 1]) return rho[i + 1];
    if (beta < kBeta[i + 1]) return std::min(rho[i], rho[i + 1]);
  }
  return rho.back();
}

// λ_max(M⁻¹∇²U(x_0, t_0)) (0 without a potential; the linearisation at the start for nonlinear U).
double stiffness_spectral_radius(const InitialValueProblem& problem) {
  const Potential* potential = problem.model.potential.get();
  if (potential == nullptr) return 0.0;
  const Eigen::Index d = problem.model.dimension();
  ModelMatrix hessian;
  if (potential->has_sparse_hessian()) {
    const std::vector<Potential::HessianEntry> pattern = potential->hessian_pattern();
    std::vector<double> values(pattern.size());
    potential->hessian_values(problem.x0, problem.t0, values);
    std::vector<Eigen::Triplet<double>> triplets;
    for (std::size_t e = 0; e < pattern.size(); ++e) {
      triplets.emplace_back(static_cast<int>(pattern[e].row), static_cast<int>(pattern[e].col),
                            values[e]);
      if (pattern[e].row != pattern[e].col)
        triplets.emplace_back(static_cast<int>(pattern[e].col), static_cast<int>(pattern[e].row),
                              values[e]);
    }
    ModelMatrix::Sparse sparse(d, d);
    sparse.setFromTriplets(triplets.begin(), triplets.end());
    hessian = ModelMatrix(sparse);
  } else {
    Eigen::MatrixXd dense(d, d);
    potential->hessian(problem.x0, problem.t0, dense);
    hessian = ModelMatrix(dense);
  }
  return pencil_spectral_radius(hessian, problem.model.mass);
}

StabilityBound lobatto_bound(int s, const InitialValueProblem& problem) {
  const double beta = problem.model.damping_order();
  const double lambda_k = std::max(0.0, stiffness_spectral_radius(problem));
  const double lambda_r =
      problem.model.is_undamped() ? 0.0 : damping_spectral_radius(problem.model);
  const double kappa_star = undamped_bound(s);
  const bool damping_limited = lambda_r > 0.0 && beta > 0.0 && beta < 1.0;
  // β = 0: R is a second spring (D^0 x = x): κ + ρ < κ*.
  const bool spring = lambda_r > 0.0 && beta == 0.0;
  // The measured ρ* come from counting the roots in |ζ| < 0.995, which misses the slowly growing
  // modes just past the threshold: hand-stepped bisection (tests/schemes/fvi_lobatto_test.cpp)
  // puts the true threshold 0.1–1.9 % below the table (s = 2, 2α = 0.9: 0.9814 × 18.1). The
  // registry keeps a 3 % margin so that the bound is sufficient.
  constexpr double kDampingBoundMargin = 0.97;
  const double rho_star =
      damping_limited ? kDampingBoundMargin * damping_bound(s, beta) : kappa_star;
  // Admissible iff κ < κ* and (damping-limited) ρ < ρ*_0 (1 − κ/κ*): both sides monotone in h.
  auto margin = [&](double h) {
    const double kappa = lambda_k * h * h;
    if (spring) return (kappa + lambda_r * h * h) / kappa_star;
    if (!damping_limited) return kappa / kappa_star;
    const double rho = lambda_r * std::pow(h, 2.0 - beta);
    if (kappa >= kappa_star) return kappa / kappa_star;
    return std::max(kappa / kappa_star, rho / (rho_star * (1.0 - kappa / kappa_star)));
  };
  StabilityBound bound;
  // Sharp: the undamped bound (a root crosses the circle at κ*, measured 0.98/1.02) and the
  // damping bound at the measured β (0.9/1.1, fvi_lobatto.md §8.2). With damping the undamped
  // bound is only sufficient (strong damping stabilises beyond κ*), and between table points the
  // smaller neighbour is taken.
  bound.sharp = lambda_r == 0.0;
  const double h = problem.step_size();
  const double value = margin(h);
  bound.stable = value < 1.0;
  if (lambda_k == 0.0 && !damping_limited && !spring) {
    bound.largest_step = std::numeric_limits<double>::infinity();
  } else {
    double lo = 0.0, hi = std::max(h, 1e-300);
    while (margin(hi) < 1.0 && hi < 1e300) hi *= 2.0;
    for (int it = 0; it < 200 && hi - lo > 1e-15 * hi; ++it) {
      const double mid = 0.5 * (lo + hi);
      (margin(mid) < 1.0 ? lo : hi) = mid;
    }
    bound.largest_step = hi;
  }
  const std::string kappa = format_number(lambda_k * h * h);
  std::string rule = "lambda_max(M^-1 Hess U(x0)) h^2 = " + kappa + " must be < " +
                     format_number(kappa_star) + " (the undamped Lobatto IIIA-IIIB bound)";
  if (spring) {
    rule = "(lambda_max(M^-1 Hess U(x0)) + lambda_max(M^-1 R)) h^2 = " +
           format_number((lambda_k + lambda_r) * h * h) + " must be < " +
           format_number(kappa_star) + " (2alpha = 0: R is a spring)";
  } else if (damping_limited) {
    rule += ", and lambda_max(M^-1 R) h^(2-2alpha) = " +
            format_number(lambda_r * std::pow(h, 2.0 - beta)) + " must be < " +
            format_number(rho_star) + " (1 - " + kappa + "/" + format_number(kappa_star) +
            ") (measured damping bound for 0 < 2alpha < 1)";
  }
  bound.rule = rule;
  return bound;
}

std::string lobatto_applicability(const InitialValueProblem& problem) {
  const double beta = problem.model.damping_order();
  if (beta < 2.0 || problem.model.is_undamped()) return {};
  return "model.alpha = 1 (2alpha = 2) is outside 0 <= 2alpha < 2 (stability of the Lobatto "
         "RKCQ damping not measured there); use fvi-gl or fvi-bdf2";
}

// 2s − 2 where the solution is smooth at t_0 (integer 2α: the RKCQ is exact and local, or R = 0);
// 2 for fractional damping (fvi_lobatto.md §13.5, "The declared order"): on smooth data the cap is
// min(2s − 2, s + 2 − 2α) (§13.1), but with split = "taylor" the first steps' error (x − P has
// non-smooth powers at t_0) brings the order over all nodes, which the Richardson error estimate
// reads, to 1.8–2.5 at 2α = 1.5 (§7.4, §13.2); split = "series" lifts the positions to the cap, but
// its velocities are not measured and this order cannot depend on the options.
//
// s = 2 with 1 < 2α < 2: the positions keep order 2, but the node momentum p_{n+1} = F_{n,2}
// carries h b_2 R G_{n,2}, the RKCQ's stage value of D^{2α}x, whose error near t_0 is of order
// q + 1 − 2α (stage order q = 1): velocities of order 3 − 2α (measured 1.54 at 2α = 1.5; s = 3:
// 4 − 2α = 2.5, measured 2.49). The declared order counts the velocities too: 1 there.
int lobatto_order(int s, const MechanicalModel& model) {
  const double beta = model.damping_order();
  if (model.is_undamped() || beta == 0.0 || beta == 1.0) return 2 * s - 2;
  if (s == 2 && beta > 1.0) return 1;
  return 2;
}

// ---------------------------------------------------------------------------------------------
// method.split = "series" (fvi_lobatto.md §13.3, §13.5): the change of variables x = w + S(t), S
// the fractional Taylor terms c_γ τ^γ (1 < γ ≤ 2s − 1, τ = t − t_0) of the solution of the linear
// problem M x'' + R D^β x + K x + g_0 = f(t) with f a finite sum of power laws Σ f_φ τ^φ (from the
// force formulas: Expression::power_laws), computed from the data and the equation
// (fractional_series.hpp). The Lobatto stepper integrates the remainder w — same M, R, U, data
// (S(t_0) = Ṡ(t_0) = 0), Taylor split P — under the forcing
//
//   f_w(t) = f(t) − (M S''(t) + R D^β S(t) + K S(t)) = Σ_φ f_φ τ^φ − Σ_γ [γ(γ − 1) M c_γ τ^{γ−2}
//            + g(γ) R c_γ τ^{γ−β} + K c_γ τ^γ],
//
// its equal powers merged (a forcing whose response the series holds exactly, such as the
// Bagley–Torvik problems with exact t³ and t^{5/2}, leaves f_w at round-off), by its exact moments
// (method.load = "moments": tanh–sinh on the first interval, where τ^{γ−2} may be singular).
// w = x − P − S vanishes to order > 2s − 1 at t_0, so neither the memory nor the Galerkin part
// meets the non-smooth terms. The state is reported for x: x_k = w_k + S(t_k), v_k = v^w_k +
// Ṡ(t_k), p_k = p^w_k + M Ṡ(t_k); the energy account is the remainder's, E_w + W_w − E_{w,0} (W
// reported as W_w + (E_w − E_x) − (E_{w,0} − E_{x,0})), and the mirror run is the remainder's,
// compared with x − S.

// S's terms and f's power laws (both in τ, coefficient vectors of size d).
struct SeriesSplit {
  std::vector<SeriesTerm> terms, forcing;
};

// The power laws f_φ τ^φ of the force formulas, per exponent; refused unless every component is
// a finite sum of power laws in t − t_0 with φ ≥ 0 (empty without forcing).
std::vector<SeriesTerm> forcing_power_laws(const InitialValueProblem& problem, const char* field) {
  const MechanicalModel& model = problem.model;
  if (!model.forcing) return {};
  const Eigen::Index d = model.dimension();
  if (static_cast<Eigen::Index>(model.forcing_formulas.size()) != d) {
    throw ValidationError(std::string(field) +
                          " needs the force as formulas in t (model.force in a problem file or "
                          "Python's force strings), to read its power laws: this problem's force "
                          "is a function; use \"taylor\"");
  }
  const std::string rule =
      "must be a finite sum of c*(t - t0)^g with constants c and g >= 0 (sums, constant factors, "
      "powers and sqrt of t - t0; t0 = " +
      format_number(problem.t0) + ")";
  std::map<long long, SeriesTerm> laws;
  for (Eigen::Index i = 0; i < d; ++i) {
    const Expression& formula = model.forcing_formulas[static_cast<std::size_t>(i)];
    const auto component = formula.power_laws(0, problem.t0);
    const std::string value =
        "model.force component " + std::to_string(i + 1) + " = \"" + formula.text() + "\"";
    if (!component) {
      throw ValidationError(std::string(field) + ": " + value + " " + rule + "; use \"taylor\"");
    }
    for (const PowerLaw& law : *component) {
      if (law.exponent < 0.0) {
        throw ValidationError(std::string(field) + ": " + value + " has the power (t - t0)^" +
                              format_number(law.exponent) + ", and " + rule + "; use \"taylor\"");
      }
      auto [it, inserted] = laws.try_emplace(exponent_key(law.exponent),
                                             SeriesTerm{law.exponent, Eigen::VectorXd::Zero(d)});
      it->second.coefficient(i) += law.coefficient;
    }
  }
  std::vector<SeriesTerm> forcing;
  for (auto& [key, term] : laws) forcing.push_back(std::move(term));
  // The formulas stand for `forcing` only if nobody replaced one without the other (a C++ caller
  // may): compare them at a few times of the run, to 1e-10 of the force's size.
  Eigen::VectorXd f(d), sum(d);
  for (const double share : {0.0, 0.1234, 0.5, 0.8765, 1.0}) {
    const double t = problem.t0 + share * (problem.t_end - problem.t0);
    model.forcing(t, f);
    sum.setZero();
    for (const SeriesTerm& term : forcing) {
      sum +=
          term.coefficient * (term.exponent == 0.0 ? 1.0 : std::pow(t - problem.t0, term.exponent));
    }
    if (!((f - sum).lpNorm<Eigen::Infinity>() <= 1e-10 * (1.0 + f.lpNorm<Eigen::Infinity>()))) {
      throw ValidationError(
          std::string(field) +
          ": model.forcing differs from model.forcing_formulas at t = " + format_number(t) +
          " (max difference " + format_number((f - sum).lpNorm<Eigen::Infinity>()) +
          "): the formulas must be those of the force; use \"taylor\"");
    }
  }
  return forcing;
}

// The series of `problem` (validated: linear, forcing a sum of power laws, terms bounded on
// [t_0, t_end]).
SeriesSplit series_for(int s, const InitialValueProblem& problem) {
  const char* const field = "method.split = \"series\"";
  const MechanicalModel& model = problem.model;
  if (model.state_force) {
    throw ValidationError(std::string(field) +
                          " is for linear problems: a force g(x, v, t) (model.force in x or v) has "
                          "no fractional series; use \"taylor\"");
  }
  const Potential* potential = model.potential.get();
  if (potential != nullptr &&
      (!potential->has_constant_hessian() || potential->is_time_dependent())) {
    throw ValidationError(std::string(field) +
                          " is for linear problems (a time-independent potential with a constant "
                          "Hessian, e.g. model.stiffness): the potential of this problem is not; "
                          "use \"taylor\"");
  }
  SeriesSplit split{{}, forcing_power_laws(problem, field)};
  const Eigen::Index d = model.dimension();
  const double beta = model.damping_order();
  if (model.is_undamped() || beta == 0.0) return split;  // no memory: nothing to remove
  Eigen::MatrixXd stiffness = Eigen::MatrixXd::Zero(d, d);
  // The right-hand side's power laws: f, and −g_0 = −∇U(0) at φ = 0.
  std::vector<SeriesTerm> loads = split.forcing;
  if (potential != nullptr) {
    potential->hessian(problem.x0, problem.t0, stiffness);
    Eigen::VectorXd constant_force(d);
    potential->gradient(Eigen::VectorXd::Zero(d), problem.t0, constant_force);
    loads.push_back({0.0, -constant_force});
  }
  const Eigen::MatrixXd mass = model.mass.symmetric_part().to_dense();
  split.terms = fractional_series(mass, model.damping.symmetric_part().to_dense(), stiffness, loads,
                                  beta, model.convention == Convention::kCaputo, problem.x0,
                                  problem.v0, 2.0 * s - 1.0);
  // S grows like τ^{2s−1}: x = w + S then adds large numbers, and loses their round-off. Refused
  // when a term at t_end exceeds 10³ times the size the data and the loads give x: the Taylor
  // polynomial and each load's first response M⁻¹ b_φ τ^{φ+2}/((φ + 1)(φ + 2)).
  const double span = problem.t_end - problem.t0;
  double natural_size =
      std::max({problem.x0.cwiseAbs().maxCoeff(), span * problem.v0.cwiseAbs().maxCoeff(),
                std::numeric_limits<double>::min()});
  const Eigen::FullPivLU<Eigen::MatrixXd> mass_lu(mass);
  for (const SeriesTerm& load : loads) {
    const double phi = load.exponent;
    natural_size =
        std::max(natural_size, mass_lu.solve(load.coefficient).cwiseAbs().maxCoeff() *
                                   std::pow(span, phi + 2.0) / ((phi + 1.0) * (phi + 2.0)));
  }
  for (const SeriesTerm& term : split.terms) {
    const double size = term.coefficient.cwiseAbs().maxCoeff() * std::pow(span, term.exponent);
    if (!(size <= 1e3 * natural_size)) {
      throw ValidationError(
          std::string(field) + ": the series term of exponent " + format_number(term.exponent) +
          " reaches " + format_number(size) +
          " at time.t_end, more than 10^3 times the size the data and the forcing give x (" +
          format_number(natural_size) +
          ": the Taylor polynomial and each force term's first response): its round-off would "
          "cost more than the series gains; shorten the interval or use \"taylor\"");
    }
  }
  return split;
}

class SeriesShiftStepper final : public Stepper {
 public:
  SeriesShiftStepper(int stages, const InitialValueProblem& problem,
                     const IntegratorOptions& options)
      : problem_(problem),
        diagnostics_(options.diagnostics),
        split_(series_for(stages, problem)),
        remainder_(remainder_problem(problem, split_)),
        mass_(problem.model.mass.symmetric_part()),
        c_(lobatto_iiic(stages).c) {
    IntegratorOptions inner = options;
    inner.split = TaylorSplit::kTaylor;
    inner.load = ForcingLoad::kMoments;
    stepper_ = std::make_unique<LobattoStepper>(stages, remainder_, inner);
    const Eigen::Index d = problem.model.dimension();
    for (Eigen::VectorXd* v : {&x_, &v_, &p_, &shift_, &rate_, &scratch_}) v->setZero(d);
    stages_.setZero(d, stages);
    report(0);
    energy_offset_ = diagnostics_ ? energy_gap() : 0.0;
    work_ = stepper_->work();  // 0 (NaN without diagnostics)
  }

  [[nodiscard]] const Eigen::VectorXd& position() const override { return x_; }
  [[nodiscard]] const Eigen::VectorXd& velocity() const override { return v_; }
  [[nodiscard]] const Eigen::VectorXd& momentum() const override { return p_; }
  [[nodiscard]] double work() const override { return work_; }
  [[nodiscard]] double supplied_work() const override {
    // U is independent of t (series_for); the work of a force f is not tracked here: the
    // remainder's account books f_w, not f.
    return diagnostics_ && split_.forcing.empty() ? 0.0 : kNaN;
  }
  [[nodiscard]] LinearSolver linear_solver() const override { return stepper_->linear_solver(); }
  [[nodiscard]] std::size_t jacobian_factorizations() const override {
    return stepper_->jacobian_factorizations();
  }
  [[nodiscard]] HistoryReport history() const override { return stepper_->history(); }
  [[nodiscard]] const Eigen::MatrixXd* stage_values() const override {
    return stepper_->stage_values() != nullptr ? &stages_ : nullptr;
  }
  void visit_state(StateArchive& archive) override {
    stepper_->visit_state(archive);
    if (archive.loading()) report(stepper_->step_index());
  }
  // The remainder's mirror run, its y shifted by the series as x is (report()): y + S(t) at the
  // mirrored step's time.
  [[nodiscard]] bool mirror_run(MirrorRows& rows) const override {
    struct Shifted final : MirrorRows {
      const SeriesShiftStepper& self;
      MirrorRows& outer;
      Eigen::VectorXd shift, rate, y_total;
      Shifted(const SeriesShiftStepper& s, MirrorRows& o, Eigen::Index d)
          : MirrorRows(o.steps()), self(s), outer(o), shift(d), rate(d), y_total(d) {}
      void put(std::size_t row, const Eigen::VectorXd& y) override {
        self.evaluate(self.problem_.time(static_cast<double>(steps()[row])), shift, rate);
        y_total = y + shift;
        outer.put(row, y_total);
      }
      bool stop() override { return outer.stop(); }
    } shifted(*this, rows, problem_.model.dimension());
    return static_cast<const Stepper&>(*stepper_).mirror_run(shifted);
  }

 private:
  static InitialValueProblem remainder_problem(const InitialValueProblem& problem,
                                               const SeriesSplit& split) {
    InitialValueProblem remainder = problem;
    if (split.terms.empty()) return remainder;
    const MechanicalModel& model = problem.model;
    const double beta = model.damping_order();
    const bool caputo = model.convention == Convention::kCaputo;
    const Eigen::Index d = model.dimension();
    Eigen::MatrixXd stiffness = Eigen::MatrixXd::Zero(d, d);
    if (model.potential) model.potential->hessian(problem.x0, problem.t0, stiffness);
    const Eigen::MatrixXd mass = model.mass.symmetric_part().to_dense();
    const Eigen::MatrixXd damping = model.damping.symmetric_part().to_dense();
    // f_w's power laws, equal exponents merged.
    std::map<long long, SeriesTerm> merged;
    auto add = [&](double exponent, const Eigen::VectorXd& value) {
      auto [it, inserted] = merged.try_emplace(exponent_key(exponent), SeriesTerm{exponent, value});
      if (!inserted) it->second.coefficient += value;
    };
    for (const SeriesTerm& law : split.forcing) add(law.exponent, law.coefficient);
    for (const SeriesTerm& term : split.terms) {
      const double gamma = term.exponent;
      add(gamma - 2.0, -gamma * (gamma - 1.0) * (mass * term.coefficient));
      const double factor = power_derivative_factor(gamma, beta, caputo);
      if (factor != 0.0) add(gamma - beta, -factor * (damping * term.coefficient));
      add(gamma, -(stiffness * term.coefficient));
    }
    std::vector<SeriesTerm> loads;
    for (auto& [key, load] : merged)
      if (!load.coefficient.isZero(0.0)) loads.push_back(std::move(load));
    const double t0 = problem.t0;
    remainder.model.forcing = [loads, t0](double t, Eigen::Ref<Eigen::VectorXd> out) {
      out.setZero();
      const double tau = std::max(t - t0, 0.0);
      for (const SeriesTerm& load : loads) out += std::pow(tau, load.exponent) * load.coefficient;
    };
    remainder.model.forcing_formulas.clear();
    return remainder;
  }

  // S(t) and Ṡ(t).
  void evaluate(double t, Eigen::VectorXd& shift, Eigen::VectorXd& rate) const {
    shift.setZero();
    rate.setZero();
    const double tau = std::max(t - problem_.t0, 0.0);
    for (const SeriesTerm& term : split_.terms) {
      shift += std::pow(tau, term.exponent) * term.coefficient;
      rate += (term.exponent * std::pow(tau, term.exponent - 1.0)) * term.coefficient;
    }
  }

  // x, v, p (and the stage values) of step k from the remainder's.
  void report(std::size_t k) {
    if (const Eigen::MatrixXd* w = stepper_->stage_values(); w != nullptr && k > 0) {
      const double start = problem_.time(static_cast<double>(k - 1));
      const double h = problem_.step_size();
      for (Eigen::Index a = 0; a < stages_.cols(); ++a) {
        evaluate(start + c_(a) * h, scratch_, rate_);
        stages_.col(a) = w->col(a) + scratch_;
      }
    }
    evaluate(problem_.time(static_cast<double>(k)), shift_, rate_);
    x_ = stepper_->position() + shift_;
    v_ = stepper_->velocity() + rate_;
    mass_.multiply(rate_, scratch_);
    p_ = stepper_->momentum() + scratch_;
    work_ = diagnostics_ ? stepper_->work() + energy_gap() - energy_offset_ : kNaN;
  }

  // E_w − E_x at the current step (½ vᵀp + U).
  [[nodiscard]] double energy_gap() const {
    const double t = problem_.time(static_cast<double>(stepper_->step_index()));
    const Potential* u = problem_.model.potential.get();
    const double remainder = 0.5 * stepper_->velocity().dot(stepper_->momentum()) +
                             (u != nullptr ? u->value(stepper_->position(), t) : 0.0);
    const double full = 0.5 * v_.dot(p_) + (u != nullptr ? u->value(x_, t) : 0.0);
    return remainder - full;
  }

  Status advance() override {
    const Status status = stepper_->step();
    set_iterations(stepper_->last_iterations());
    if (status != Status::kSuccess) return fail(status, "%s", stepper_->failure_message());
    report(stepper_->step_index());
    return Status::kSuccess;
  }

  const InitialValueProblem& problem_;
  bool diagnostics_;
  SeriesSplit split_;
  InitialValueProblem remainder_;  // the stepper keeps a reference: declared before it
  ModelMatrix mass_;
  Eigen::VectorXd c_;
  std::unique_ptr<LobattoStepper> stepper_;
  Eigen::VectorXd x_, v_, p_, shift_, rate_, scratch_;
  Eigen::MatrixXd stages_;
  double work_ = 0.0, energy_offset_ = 0.0;
};

template <int S>
std::unique_ptr<Stepper> make_lobatto(const InitialValueProblem& problem,
                                      const IntegratorOptions& options) {
  if (options.split == TaylorSplit::kSeries) {
    return std::make_unique<SeriesShiftStepper>(S, problem, options);
  }
  return std::make_unique<LobattoStepper>(S, problem, options);
}

constexpr std::string_view kLobattoReference =
    "Hariz, Ober-Bloebaum & Jimenez, arXiv 2510.11082 (github.com/khaledharizb/RKCQ); "
    "docs/theory/fvi_lobatto.md";
// One registry row per s; only the name, the summary, the order rule and κ* differ.
template <int S>
SchemeInfo lobatto_row(std::string_view name, std::string_view summary, std::string_view order_rule,
                       std::string_view stability_rule) {
  return SchemeInfo{
      .name = name,
      .summary = summary,
      .reference = kLobattoReference,
      .order_rule = order_rule,
      .stages = S,
      .variational = true,
      .variational_quadrature = std::nullopt,  // its Δ^α_± act on stage values: no BVP form yet
      .has_mirror = true,
      .exact_balance = false,  // O(h^{2s−2}) (fvi_lobatto.md §6)
      .fast_history = true,
      .momentum_quadrature = CqScheme::kGrunwaldLetnikov,  // block weights summable
      .forcing_moments = true,
      .series_split = true,
      .checkpoints = true,
      .no_state_force = "",
      .applies_to = "0 <= 2alpha < 2",
      .stability_rule = stability_rule,
      .declared_order = [](const MechanicalModel& model) { return lobatto_order(S, model); },
      .applicability = lobatto_applicability,
      .stability = [](const InitialValueProblem& problem) { return lobatto_bound(S, problem); },
      .make_stepper = make_lobatto<S>,
  };
}

}  // namespace

const SchemeInfo kFviLobatto2 = lobatto_row<2>(
    "fvi-lobatto2",
    "FVI with the Lobatto-Galerkin discrete Lagrangian on 2 nodes (Stoermer-Verlet) and Lobatto "
    "IIIC (s = 2) Runge-Kutta CQ memory on the stage values; implicit damping",
    "2 (velocities 3 - 2alpha for 1 < 2alpha < 2)",
    "lambda_max(M^-1 Hess U) h^2 < 4; 0 < 2alpha < 1: also a measured bound on "
    "lambda_max(M^-1 R) h^(2-2alpha) (docs/theory/fvi_lobatto.md section 8)");

const SchemeInfo kFviLobatto3 = lobatto_row<3>(
    "fvi-lobatto3",
    "FVI with the Lobatto-Galerkin discrete Lagrangian on 3 nodes and Lobatto IIIC (s = 3) "
    "Runge-Kutta CQ memory on the stage values; implicit damping",
    "4 (2 for fractional 2alpha; its cap on smooth data min(4, 5 - 2alpha), theory 13)",
    "lambda_max(M^-1 Hess U) h^2 < 8; 0 < 2alpha < 1: also a measured bound on "
    "lambda_max(M^-1 R) h^(2-2alpha) (docs/theory/fvi_lobatto.md section 8)");

const SchemeInfo kFviLobatto4 = lobatto_row<4>(
    "fvi-lobatto4",
    "FVI with the Lobatto-Galerkin discrete Lagrangian on 4 nodes and Lobatto IIIC (s = 4) "
    "Runge-Kutta CQ memory on the stage values; implicit damping",
    "6 (2 for fractional 2alpha; its cap on smooth data 6 - 2alpha, theory 13)",
    "lambda_max(M^-1 Hess U) h^2 < 30; 0 < 2alpha < 1: also a measured bound on "
    "lambda_max(M^-1 R) h^(2-2alpha) (docs/theory/fvi_lobatto.md section 8)");

}  // namespace fracvi::internal
