// A potential U(x1..xd, t) given as a formula, e.g. from a problem file, and a force f(t) or
// g(x, v, t) given as d formulas.
//
// The formula is parsed once; value, gradient and Hessian come from the expression engine's exact
// symbolic derivatives compiled into one tape (no finite differences).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "fracvi/expression/expression.hpp"
#include "fracvi/model/mechanical_model.hpp"
#include "fracvi/model/potential.hpp"
#include "fracvi/model/state_force.hpp"

namespace fracvi {

class ExpressionPotential final : public Potential {
 public:
  /// The variables are x1..xd and t. Throws ExpressionError (with the column) for a malformed
  /// formula.
  ExpressionPotential(Eigen::Index dimension, const std::string& potential);

  /// The variable names x1..xd.
  static std::vector<std::string> position_names(Eigen::Index dimension);

  [[nodiscard]] Eigen::Index dimension() const override { return dimension_; }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const override;
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                Eigen::Ref<Eigen::VectorXd> g) const override;
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
               Eigen::Ref<Eigen::MatrixXd> H) const override;
  [[nodiscard]] bool has_constant_hessian() const override {
    return derivatives_.hessian_is_constant();
  }
  [[nodiscard]] bool is_time_dependent() const override { return time_dependent_; }
  /// Expression::has_kinks_in the positions x1..xd.
  [[nodiscard]] bool has_kinks() const override { return kinks_; }
  /// The engine's symbolic Hessian pattern: a chain of springs has O(d) entries.
  [[nodiscard]] bool has_sparse_hessian() const override { return true; }
  [[nodiscard]] std::vector<HessianEntry> hessian_pattern() const override;
  void hessian_values(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                      std::span<double> values) const override;

  [[nodiscard]] const Expression& expression() const { return derivatives_.expression(); }
  /// True when gradient() forms b + Kx instead of running the tape (a quadratic U without t and
  /// kinks; see set_up_affine_gradient).
  [[nodiscard]] bool has_affine_gradient() const { return affine_gradient_; }

 private:
  // Writes x1..xd, t into this thread's workspace (its variable slots, Workspace::values) and
  // returns it. The workspace is per thread and per object, so concurrent const calls are safe
  // and, after the first call on a thread, allocation-free.
  struct Scratch {
    std::vector<double> gradient;
    CompiledDerivatives::Workspace workspace;
  };
  Scratch& scratch(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const;

  // A quadratic U (constant Hessian, no t, no kinks) has the affine gradient ∇U(x) = b + Kx:
  // gradient() forms it from b and the rows of K (compressed, both triangles) instead of running
  // the tape — at d = 1 the tape's gradient was 144 of a 1682-instruction step (callgrind). Set
  // up from the tape at x = 0 and checked against it at a second point (affine_gradient_ stays
  // false otherwise). The value keeps the tape: ½xᵀKx would cancel for translation-invariant
  // springs (the energy balance needs the formula's own form).
  void set_up_affine_gradient();

  Eigen::Index dimension_;
  CompiledDerivatives derivatives_;
  bool time_dependent_;
  bool kinks_;
  std::uint64_t id_;  // never reused, unlike the object's address
  bool affine_gradient_ = false;
  std::vector<double> gradient_at_zero_;     // b
  std::vector<Eigen::Index> row_start_;      // K's row i: entries row_start_[i] … row_start_[i+1]
  std::vector<Eigen::Index> stiffness_col_;  // their columns
  std::vector<double> stiffness_value_;      // and values
};

/// f(t) from d formulas in t, as the model's Forcing callback (allocation-free after the first
/// call on a thread). Throws ExpressionError for a malformed formula.
Forcing make_expression_forcing(const std::vector<std::string>& force);

/// A non-conservative force g(x, v, t) from d formulas in x1..xd, v1..vd and t, with its exact
/// Jacobians from the expression engine (each component's gradient with respect to x and v).
class ExpressionForce final : public StateForce {
 public:
  /// Throws ExpressionError (naming the component, with the column) for a malformed formula.
  ExpressionForce(Eigen::Index dimension, const std::vector<std::string>& force);

  /// The variable names x1..xd, v1..vd, t.
  static std::vector<std::string> variable_names(Eigen::Index dimension);

  [[nodiscard]] Eigen::Index dimension() const override { return dimension_; }
  void value(const Eigen::Ref<const Eigen::VectorXd>& x, const Eigen::Ref<const Eigen::VectorXd>& v,
             double t, Eigen::Ref<Eigen::VectorXd> out) const override;
  void jacobians(const Eigen::Ref<const Eigen::VectorXd>& x,
                 const Eigen::Ref<const Eigen::VectorXd>& v, double t,
                 Eigen::Ref<Eigen::VectorXd> out, Eigen::Ref<Eigen::MatrixXd> dx,
                 Eigen::Ref<Eigen::MatrixXd> dv) const override;

 private:
  struct Scratch {
    std::vector<double> args, gradient;
    std::vector<CompiledDerivatives::Workspace> workspaces;
  };
  Scratch& scratch(const Eigen::Ref<const Eigen::VectorXd>& x,
                   const Eigen::Ref<const Eigen::VectorXd>& v, double t) const;

  Eigen::Index dimension_;
  std::vector<CompiledDerivatives> components_;
  std::uint64_t id_;
};

/// The model's forces from the `force` formulas (problem files, Python): d formulas in t, x1..xd,
/// v1..vd, or none. When no formula mentions a name other than t, they become the f(t) callback
/// of make_expression_forcing, exactly as before state forces existed (published numbers stay
/// bit-identical); otherwise all of them become one ExpressionForce g(x, v, t) (which throws
/// ExpressionError for an unknown name).
struct ExpressionForces {
  Forcing forcing;
  std::shared_ptr<const StateForce> state_force;
  std::vector<Expression> forcing_formulas;  ///< those of `forcing` (MechanicalModel)
};
ExpressionForces make_expression_forces(Eigen::Index dimension,
                                        const std::vector<std::string>& force);

}  // namespace fracvi
