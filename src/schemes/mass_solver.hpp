// v = M⁻¹p and w = M⁻¹(R' s) for the scaled damping R' = R h^{−2α} (internal to the schemes).
//
// A dense M keeps its explicit inverse and M⁻¹R' (one matrix–vector product each); a sparse M is
// factored once, banded or sparse like the Newton matrix, and w is the solve with the R' s the step
// has formed (its damping force). Diagonal M (chains): the solve is a quotient, the same roundings
// as the factor's division; M = I: a copy.
#pragma once

#include <Eigen/Dense>
#include <memory>
#include <string>

#include "fracvi/core/error.hpp"
#include "fracvi/internal/vectorize.hpp"
#include "fracvi/model/model_matrix.hpp"
#include "fracvi/solve/midpoint_newton.hpp"
#include "fracvi/solve/symmetric_factor.hpp"

namespace fracvi::internal {

class MassSolver {
 public:
  MassSolver(const ModelMatrix& mass, const ModelMatrix& damping, LinearSolver solver)
      : dense_(!mass.is_sparse() || solver == LinearSolver::kDense) {
    const Eigen::Index d = mass.rows();
    if (dense_) {
      if (d > kMaxDenseDimension) {
        throw ValidationError("model.mass would be inverted dense (d = " + std::to_string(d) +
                              " > " + std::to_string(kMaxDenseDimension) +
                              "): store M sparse (e.g. ModelMatrix::identity, a scalar or vector "
                              "mass in a problem file) and use linear_solver = auto");
      }
      const Eigen::MatrixXd m = mass.to_dense();
      const Eigen::LLT<Eigen::MatrixXd> llt(m);
      minv_damping_ = ModelMatrix(Eigen::MatrixXd(llt.solve(damping.to_dense())));
      const Eigen::MatrixXd inverse = llt.solve(Eigen::MatrixXd::Identity(d, d));
      inverse_ = ModelMatrix(Eigen::MatrixXd(0.5 * (inverse + inverse.transpose())));
      return;
    }
    auto pattern = std::make_shared<SymmetricPattern>(d);
    pattern->add(mass);
    pattern->finalize();
    LinearSolver backend = solver == LinearSolver::kAuto ? choose_factorization(*pattern) : solver;
    if (backend == LinearSolver::kDense) backend = LinearSolver::kSparse;  // M is stored sparse
    factor_ = std::make_unique<SymmetricFactor>(pattern, backend);
    std::span<double> values = factor_->values();
    for (const auto& [at, value] : scatter_upper(*pattern, mass)) values[at] += value;
    if (!factor_->factor()) {
      throw ValidationError("model.mass could not be factored (not positive definite)");
    }
    if (mass.is_diagonal()) {
      mass_diagonal_ = mass.sparse().diagonal();
      unit_mass_ = (mass_diagonal_.array() == 1.0).all();
    }
  }

  /// out = M⁻¹ p
  void inverse(const Eigen::Ref<const Eigen::VectorXd>& p, Eigen::Ref<Eigen::VectorXd> out) const {
    if (dense_) {
      inverse_.multiply(p, out);
    } else if (unit_mass_) {
      copy_elements(p.data(), out.data(), p.size());
    } else if (mass_diagonal_.size() > 0) {
      out.array() = p.array() / mass_diagonal_.array();
    } else {
      out = p;
      factor_->solve_in_place(out);
    }
  }
  /// The diagonal m of M = diag(m) when inverse() is the quotient by it (or the copy, M = I),
  /// else null (a dense M's explicit inverse, a factored sparse M).
  [[nodiscard]] const Eigen::VectorXd* diagonal() const {
    return !dense_ && mass_diagonal_.size() > 0 ? &mass_diagonal_ : nullptr;
  }
  [[nodiscard]] bool unit_mass() const { return unit_mass_; }
  /// out = M⁻¹ R' s, given force = R' s (the step forms it anyway): M⁻¹ applied to it, except on
  /// the dense path, which multiplies s by its M⁻¹R'. (On the other paths this is the quotient or
  /// solve of R' s, the numbers of forming R' s again here, without the second product.)
  /// VectorXd, not Eigen::Ref: the step's members, and a by-value Ref costs a store-forwarding
  /// stall at d = 1 (midpoint_newton.hpp's solve()).
  void inverse_damping(const Eigen::VectorXd& s, const Eigen::VectorXd& force,
                       Eigen::VectorXd& out) const {
    if (dense_) {
      minv_damping_.multiply(s, out);
    } else {
      inverse(force, out);
    }
  }

 private:
  bool dense_;
  ModelMatrix inverse_, minv_damping_;  // dense path: M⁻¹ and M⁻¹R' (1 × 1 products inline)
  std::unique_ptr<SymmetricFactor> factor_;
  Eigen::VectorXd mass_diagonal_;  // when M is diagonal
  // M = I (chains of unit masses): the quotients by 1 are the identity, bit for bit, and a
  // division pass costs ≈ 1 µs per 1000 degrees of freedom in the SSE2 build.
  bool unit_mass_ = false;
};

}  // namespace fracvi::internal
