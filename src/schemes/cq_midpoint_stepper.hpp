// The `DiscEqs` family (internal): the restricted discrete variational principle with the midpoint
// discrete Lagrangian and discrete fractional derivatives Δ^α_± given by a convolution quadrature
// with generating function δ. The restricted variation composes Δ^α_− and Δ^α_+ into the CQ of
// order 2α (δ^α·δ^α = δ^{2α}), so for k = 1 … N−1 the x-equation is
//
//   M (x_{k+1} − 2x_k + x_{k−1})/h² + F_k + ½∇U_f(x̄_k, t_{k+½}) + ½∇U_f(x̄_{k−1}, t_{k−½}) = 0,
//   F_k = R h^{−2α} Σ_{m=0}^{k} ω_m x̃_{k−m} (+ the exact force of the removed polynomial, below),
//
// and the mirror y-equation is the same with the sum running forward (docs/theory/start_step.md for
// δ = 1 − ζ, the paper's scheme `fvi-gl`; docs/theory/fvi_bdf2.md for δ = BDF2, `fvi-bdf2`).
// The damping involves known states only (explicit memory), hence the stability bound
// λ_max(M⁻¹R) h^{2−2α} δ(−1)^{2α}/4 < 1 (docs/theory/stability.md).
//
// It is solved in the momentum form p⁺_k = p_k − (h/2) F_k,
//   M (x_{k+1} − x_k)/h + (h/2) ∇U_f(x̄_k, t_{k+½}) = p⁺_k,   p⁻_{k+1} = 2MΔ_k/h − p⁺_k,
//   p_{k+1} = p⁻_{k+1} − (h/2) F_{k+1},
// by Newton's method with Jacobian M + (h²/4) ∇²U(x̄_k).
//
// The two members of the family differ only in how the memory meets the initial data:
//  * kPaperStart (fvi-gl): the memory acts on x̃ = x − x_0 (Caputo, 2α ∉ {0, 1}) − t v_0 (2α > 1);
//    for 2α = 1 Lemma 5.3's local difference with F_0 = R v_0; for Riemann–Liouville with
//    0 < 2α < 1 the start impulse takes the full weight h F_0 (start_step.md §2a).
//  * kTaylorSplit (fvi-bdf2): x = P + x̃ with P(t) = x_0 + (t − t_0) v_0. The memory acts on
//    x̃ = O(t²) (smooth enough for the second-order CQ), and the damping force of P is added in
//    closed form as the second difference (H(t_{k+1}) − 2H(t_k) + H(t_{k−1}))/h² of its double
//    antiderivative H (2H(t_1)/h² at k = 0), which the scheme integrates exactly, so that a
//    singular RL force x_0 t^{−2α}/Γ(1−2α) costs no order.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <memory>

#include "forcing_moments.hpp"
#include "fracvi/fractional/convolution_quadrature.hpp"
#include "fracvi/internal/team_chooser.hpp"
#include "fracvi/memory/history.hpp"
#include "fracvi/schemes/stepper.hpp"
#include "fracvi/solve/midpoint_newton.hpp"
#include "mass_solver.hpp"

namespace fracvi::internal {

enum class MemoryStart { kPaperStart, kTaylorSplit };

/// The parts of a step split by rows (CqMidpointStepper::step_by_rows): a team of n ≤ kRowParts
/// threads takes n contiguous runs of them (a team of two, the halves), one thread all of them.
/// Fixed, so that the sums formed part by part are the same for every team.
inline constexpr int kRowParts = 8;

class CqMidpointStepper final : public Stepper {
 public:
  CqMidpointStepper(const InitialValueProblem& problem, const IntegratorOptions& options,
                    CqScheme generating_function, MemoryStart memory_start);

  [[nodiscard]] const Eigen::VectorXd& position() const override { return x_cur_; }
  [[nodiscard]] const Eigen::VectorXd& velocity() const override { return v_cur_; }
  [[nodiscard]] const Eigen::VectorXd& momentum() const override { return p_; }
  [[nodiscard]] double work() const override { return work_; }
  [[nodiscard]] double supplied_work() const override { return supplied_; }
  [[nodiscard]] bool mirror_run(MirrorRows& rows) const override;
  [[nodiscard]] LinearSolver linear_solver() const override { return newton_.linear_solver(); }
  [[nodiscard]] std::size_t jacobian_factorizations() const override {
    return newton_.factorizations();
  }
  [[nodiscard]] HistoryReport history() const override;
  void visit_state(StateArchive& archive) override;

 private:
  Status advance() override;
  // advance() from p⁺_k to the momentum pass by rows (by_rows_): a linear step's Newton passes
  // (split_newton_; else Newton's solve on one thread), the position pass, the history's push
  // and the momentum pass, each on the rows of kRowParts parts, the parts on one thread or split
  // over a team; the linear solve on one thread. The
  // momentum pass reads the memory sum where the history keeps it. momentum and mass_squares: the
  // passes' sums, part by part, added in part order (whatever the team).
  Status step_by_rows(const Eigen::VectorXd* forcing, MomentumPass& momentum, double& mass_squares);
  [[nodiscard]] double time(std::size_t i) const {
    return problem_.t0 + static_cast<double>(i) * h_;
  }
  [[nodiscard]] double half_time(std::size_t i) const {
    return problem_.t0 + (static_cast<double>(i) + 0.5) * h_;
  }
  [[nodiscard]] double potential_value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const {
    return problem_.model.potential ? problem_.model.potential->value(x, t) : 0.0;
  }
  // x̃_i = x_i − (shift of the initial data), for index i of the clock running from t_0.
  void tilde(const Eigen::Ref<const Eigen::VectorXd>& x, std::size_t i, Eigen::VectorXd& out) const;
  // kTaylorSplit: adds P's damping force at node k to the history sum s (units F = R h^{−2α} s),
  // P from the initial data x0, v0 (the problem's, or the mirror run's own copies).
  void add_polynomial_force(std::size_t k, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                            Eigen::VectorXd& s) const;
  // The same on rows [lo, hi) of s (each element as in the whole vector's).
  void add_polynomial_force(std::size_t k, const Eigen::VectorXd& x0, const Eigen::VectorXd& v0,
                            Eigen::VectorXd& s, Eigen::Index lo, Eigen::Index hi) const;

  const InitialValueProblem& problem_;
  IntegratorOptions options_;
  ConvolutionQuadrature damping_sum_;  // δ^{2α}
  MemoryStart memory_start_;
  Eigen::Index d_;
  std::size_t n_steps_;
  double h_;
  bool damped_;
  bool viscous_local_;  // kPaperStart, 2α = 1: Lemma 5.3 without a history
  bool use_history_;
  bool shift_x0_, shift_v0_;
  double start_force_weight_;
  // kTaylorSplit: H(τ) = jx τ^{ex} x_0 + jv τ^{ev} v_0 (τ = t − t_0); zero coefficients are absent.
  double jx_ = 0.0, ex_ = 0.0, jv_ = 0.0, ev_ = 0.0, poly_scale_ = 0.0;
  bool has_forcing_;
  MidpointForce midpoint_force_;  // f at t_{k+½}, or its cell average (method.load)
  bool u_time_dependent_;
  bool diagnostics_;

  ModelMatrix mass_, damping_, force_matrix_;
  MassSolver mass_solver_;
  std::unique_ptr<History> history_;
  MidpointNewton newton_;

  std::size_t k_ = 0;
  Eigen::VectorXd x_cur_, x_next_, v_cur_, v_next_, x_first_;
  Eigen::VectorXd p_, p_plus_, p_minus_, force_, force_next_, sum_, x_tilde_, f_mid_, rhs_, mid_,
      grad_, dx_,
      g_mid_;          // g(x̄_k, Δ_k/h, t_{k+½}), the non-conservative force of the cell
  Eigen::VectorXd w_;  // M⁻¹F_{k+1}, of the energy account only (its F·w)
  // Diagonal M (quotients in mass_solver_) and R', the chains' with damping: the element passes
  // after the Newton solve run as two fused passes (new_position_pass, new_momentum_pass), the
  // same roundings.
  bool fused_passes_ = false;
  Eigen::VectorXd tilde_x0_, tilde_v0_;  // x_0 and v_0 as x̃ subtracts them (zero where not)
  Eigen::VectorXd root_mass_;  // √M_ii for the health check's sum (fused, M ≠ I, large d only)
  double fv_ = 0.0, fw_ = 0.0, work_ = 0.0, supplied_ = 0.0;
  // The step split by rows (step_by_rows(), from options.row_split_from degrees of freedom): the
  // rows [bounds[p], bounds[p + 1]) of part p, the team's size chosen by timing (TeamChooser).
  bool by_rows_ = false;
  bool split_newton_ = false;  // MidpointNewton::solves_by_rows: its passes by rows too
  std::array<Eigen::Index, kRowParts + 1> part_bounds_{};
  TeamChooser row_team_;
  std::size_t row_steps_ = 0, row_team_steps_ = 0;
  std::size_t history_window_ = 0;  // n0: from this many values on, pushes run the recursions
  bool next_started_ = false;  // the last split step formed p⁺_k, h p⁺_k and the midpoint of k_
};

}  // namespace fracvi::internal
