// The backward mirror run of the schemes with the midpoint discrete Lagrangian (internal): fvi-gl,
// fvi-bdf2 and fvi-midpoint share everything but their damping.
//
// The y-equation at node k (k = N−1 … 1), with y_j ≈ x_{N−j} and U, f at the mirrored times,
//
//   M (y_{k+1} − 2y_k + y_{k−1})/h² + D_k + ½∇U_f(ȳ_k, τ_k) + ½∇U_f(ȳ_{k−1}, τ_{k−1}) = 0,
//
// is solved for y_{k−1} from y_N = x_0, y_{N−1} = x_1 in its literal second-difference form (not
// the momentum form of the x-run), in increments Δ_k = y_{k−1} − y_k (round-off stays out of the
// differences, as in the x-run):
//
//   J Δ_k + (h²/2) ∇U_f(y_k + Δ_k/2, τ_{k−1}) = M Δ_{k+1} − h² D^known_k − (h²/2) ∇U_f(ȳ_k, τ_k),
//
// where the scheme splits D_k into a known part and a part linear in Δ_k that it has put into
// the Newton matrix J (M for the explicit memories of fvi-gl and fvi-bdf2). The scheme's damping
// is a callback object with
//   void start(const Eigen::VectorXd& y_n, const Eigen::VectorXd& y_n1);   // y_N, y_{N−1}
//   void known(std::size_t k, const Eigen::VectorXd& y_k, Eigen::VectorXd& d);  // d = D^known_k
//   void accept(std::size_t k, const Eigen::VectorXd& y_km1, const Eigen::VectorXd& y_k);
// (accept() after y_{k−1} is solved). y_{k−1} goes to rows.put() at the stored rows it mirrors
// (row i of the run's rows is x at step rows.steps()[i], ascending). false when Newton fails, a
// callback throws (the check is then unavailable, the run not invalid) or rows.stop() asks to
// stop. The callbacks, like this loop, read per step the stepper's vectors and matrices only
// through copies made on the mirror run's thread (see below: false sharing with the run
// alongside).
#pragma once

#include <Eigen/Dense>
#include <cstddef>
#include <span>

#include "forcing_moments.hpp"
#include "fracvi/core/matrix.hpp"
#include "fracvi/schemes/options.hpp"
#include "fracvi/schemes/stepper.hpp"
#include "fracvi/solve/midpoint_newton.hpp"

namespace fracvi::internal {

template <class Damping>
bool backward_mirror_run(const InitialValueProblem& problem, const IntegratorOptions& options,
                         const ModelMatrix& mass, const ModelMatrix& newton_matrix, double h,
                         const Eigen::VectorXd& x1, MirrorRows& rows, Damping& damping) {
  const std::span<const std::size_t> steps = rows.steps();
  try {
    const std::size_t n = problem.steps;
    if (n < 2) return true;
    // Run alongside the run (IntegratorOptions::mirror_alongside), this loop reads the stepper's
    // matrices and vectors per step only through this thread's own copies (M here, the solver's
    // J; t_0): a small system's are a few bytes each, allocated next to vectors the run writes
    // every step, and reading them from the other core cost both runs their cache lines (d = 1,
    // N = 10^7: run + mirror run alongside 1.79–2.59 s against 1.54–1.60 s for the run alone;
    // 1.57–1.68 s with the copies, bench/RESULTS.md).
    const ModelMatrix own_mass = mass;
    const double t0 = problem.t0;
    MidpointNewton solver(newton_matrix, h, problem.model.potential.get(), options.newton, t0,
                          options.linear_solver, problem.model.state_force.get());
    const Eigen::Index d = problem.model.dimension();
    const bool has_forcing = static_cast<bool>(problem.model.forcing);
    MidpointForce midpoint_force(problem, options.load);
    auto half_time = [&](std::size_t i) { return t0 + (static_cast<double>(i) + 0.5) * h; };
    Eigen::VectorXd y_next = problem.x0, y_k = x1, y_prev(d), known(d), g(d), f_tau(d), f_tau2(d),
                    c(d), ym(d), step(d), g_state(d);
    Eigen::VectorXd delta = y_k - y_next;
    damping.start(y_next, y_k);
    std::size_t next_row = 0;
    for (std::size_t kk = n - 1; kk >= 1; --kk) {
      if (rows.stop()) return false;
      damping.known(kk, y_k, known);
      // ȳ_k = (y_{k+1} + y_k)/2 mirrors x̄ at t_{N−k−½}; ȳ_{k−1} mirrors x̄ at t_{N−k+½}.
      const double tau_known = half_time(n - kk - 1), tau_new = half_time(n - kk);
      const Eigen::VectorXd* f_known = nullptr;
      const Eigen::VectorXd* f_new = nullptr;
      if (has_forcing) {
        // The cells of the same times in x: n − kk − 1 and n − kk.
        midpoint_force(n - kk - 1, tau_known, f_tau);
        midpoint_force(n - kk, tau_new, f_tau2);
        f_known = &f_tau;
        f_new = &f_tau2;
      }
      // Plain element loops in this loop (the same roundings as the Eigen expressions, whose
      // set-up cost more than their work at d = 1).
      for (Eigen::Index i = 0; i < d; ++i) ym[i] = 0.5 * (y_next[i] + y_k[i]);
      solver.effective_gradient(ym, tau_known, f_known, g);
      // A non-conservative force g(x, v, t) at the physical state of the mirrored cell: its
      // increment x_{N−k} − x_{N−k−1} is delta = y_k − y_{k+1}, and solve() evaluates the new
      // cell with the increment y_{k−1} − y_k = x_{N−k+1} − x_{N−k} (docs/theory/forces.md §4).
      if (solver.has_state_force()) {
        solver.state_force(ym, delta, tau_known, g_state);
        g -= g_state;
      }
      own_mass.multiply(delta, c);
      for (Eigen::Index i = 0; i < d; ++i) {
        c[i] = (c[i] - (h * h) * known[i]) - (0.5 * h * h) * g[i];  // c −= …, then c −= …
        step[i] = delta[i];                                         // predictor
      }
      const NewtonReport report = solver.solve(y_k, tau_new, c, f_new, step);
      if (report.status != Status::kSuccess) return false;
      for (Eigen::Index i = 0; i < d; ++i) {
        delta[i] = step[i];
        y_prev[i] = y_k[i] + delta[i];
      }
      const std::size_t mirrored = n - kk + 1;  // y_{kk−1} ≈ x_{mirrored}
      while (next_row < steps.size() && steps[next_row] < mirrored) ++next_row;
      if (next_row < steps.size() && steps[next_row] == mirrored) rows.put(next_row, y_prev);
      damping.accept(kk, y_prev, y_k);
      y_next.swap(y_k);
      y_k.swap(y_prev);
    }
    return true;
  } catch (...) {
    return false;
  }
}

}  // namespace fracvi::internal
