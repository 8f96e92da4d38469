#include "fracvi/schemes/stability.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SparseCholesky>
#include <cmath>
#include <limits>
#include <string>

#include "fracvi/core/error.hpp"

namespace fracvi {

double damping_spectral_radius(const MechanicalModel& model) {
  return pencil_spectral_radius(model.damping, model.mass);
}

double pencil_spectral_radius(const ModelMatrix& matrix, const ModelMatrix& mass_matrix) {
  const ModelMatrix mass = mass_matrix.symmetric_part();
  const ModelMatrix damping = matrix.symmetric_part();
  const Eigen::Index d = mass.rows();
  if (damping.is_zero()) return 0.0;
  if (mass.is_diagonal() && damping.is_diagonal()) {
    double lambda = 0.0;
    for (Eigen::Index i = 0; i < d; ++i) lambda = std::max(lambda, damping(i, i) / mass(i, i));
    return lambda;
  }
  if (d <= 2000 && !mass.is_sparse() && !damping.is_sparse()) {
    const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> pencil(
        damping.to_dense(), mass.to_dense(), Eigen::EigenvaluesOnly);
    return pencil.eigenvalues().maxCoeff();
  }
  // Power iteration on M⁻¹R; the Rayleigh quotient xᵀRx / xᵀMx bounds λ_max from below.
  Eigen::SparseMatrix<double> m = mass.is_sparse() ? mass.sparse() : mass.to_dense().sparseView();
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(m);
  Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(d, 1.0, 2.0), rx(d), mx(d);
  double lambda = 0.0;
  for (int it = 0; it < 300; ++it) {
    damping.multiply(x, rx);
    mass.multiply(x, mx);
    const double next = x.dot(rx) / x.dot(mx);
    x = solver.solve(rx);
    const double norm = x.norm();
    if (!(norm > 0.0)) break;
    x /= norm;
    const bool settled = std::abs(next - lambda) <= 1e-10 * std::abs(next);
    lambda = next;
    if (settled) break;
  }
  return lambda;
}

StabilityBound explicit_memory_bound(const InitialValueProblem& problem,
                                     const ConvolutionQuadrature& damping_sum) {
  StabilityBound bound;
  const double lambda = damping_spectral_radius(problem.model);
  const double beta = damping_sum.order;  // 2α
  const double symbol = damping_sum.symbol_at_minus_one();
  const double h = problem.step_size();
  if (lambda == 0.0) {
    bound.stable = true;
    bound.largest_step = std::numeric_limits<double>::infinity();
    bound.rule = "R = 0: stable for every h";
    return bound;
  }
  // c h^{2−2α} < 1 with c = λ δ(−1)^{2α} / 4.
  const double c = lambda * symbol / 4.0;
  const double value = c * std::pow(h, 2.0 - beta);
  bound.stable = value < 1.0;
  bound.largest_step = beta < 2.0 ? std::pow(1.0 / c, 1.0 / (2.0 - beta))
                                  : (c < 1.0 ? std::numeric_limits<double>::infinity() : 0.0);
  bound.rule = "lambda_max(M^-1 R) h^(2-2alpha) delta(-1)^(2alpha) / 4 = " + format_number(lambda) +
               " * " + format_number(h) + "^" + format_number(2.0 - beta) + " * " +
               format_number(symbol) + " / 4 = " + format_number(value) + " must be < 1";
  return bound;
}

}  // namespace fracvi
