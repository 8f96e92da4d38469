#include "fracvi/lagrangian/lagrangian.hpp"

#include <atomic>
#include <numeric>
#include <unordered_map>

namespace fracvi {

void LagrangianDerivatives::resize(Eigen::Index d) {
  const Eigen::Index n = kPhaseBlockCount * d;
  if (gradient.size() != n) gradient.resize(n);
  if (hessian.rows() != n || hessian.cols() != n) hessian.resize(n, n);
  if (time_gradient.size() != 4 * d) time_gradient.resize(4 * d);
}

namespace {

std::uint64_t next_id() {
  static std::atomic<std::uint64_t> counter{0};
  return ++counter;
}

const char* const kBlockNames[kPhaseBlockCount] = {"x", "y", "xdot", "ydot", "dx", "dy"};

std::string component_name(Eigen::Index index, Eigen::Index d) {
  return kBlockNames[index / d] + std::to_string(index % d + 1);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// ExpressionLagrangian

std::vector<std::string> ExpressionLagrangian::variable_names(Eigen::Index d) {
  std::vector<std::string> names;
  names.reserve(static_cast<std::size_t>(kPhaseBlockCount * d + 1));
  for (Eigen::Index i = 0; i < kPhaseBlockCount * d; ++i) names.push_back(component_name(i, d));
  names.emplace_back("t");
  return names;
}

namespace {

CompiledDerivatives compile_lagrangian(Eigen::Index d, const std::string& text) {
  if (d < 1) {
    throw std::invalid_argument("ExpressionLagrangian: d = " + std::to_string(d) + " must be >= 1");
  }
  // Derivatives with respect to every variable including t: the last Hessian column gives the
  // mixed derivatives ∂_t ∇_z L that d/dt ∂L/∂ẋ needs along a curve (`FracEL`).
  const Expression e = Expression::parse(text, ExpressionLagrangian::variable_names(d));
  return CompiledDerivatives(e);
}

}  // namespace

struct ExpressionLagrangian::Scratch {
  std::vector<double> args;
  std::vector<double> gradient;
  Eigen::MatrixXd hessian;
  CompiledDerivatives::Workspace workspace;
};

ExpressionLagrangian::ExpressionLagrangian(Eigen::Index d, const std::string& text)
    : dim_(d), derivatives_(compile_lagrangian(d, text)), id_(next_id()) {
  const Eigen::Index n = kPhaseBlockCount * d;
  pattern_ = HessianPattern::Constant(n, n, false);
  for (const HessianEntry& e : derivatives_.hessian_pattern()) {
    const auto r = static_cast<Eigen::Index>(e.row), c = static_cast<Eigen::Index>(e.col);
    if (r < n && c < n) pattern_(r, c) = pattern_(c, r) = true;
  }
}

std::string ExpressionLagrangian::description() const {
  return "L = " + derivatives_.expression().text();
}

ExpressionLagrangian::Scratch& ExpressionLagrangian::scratch(
    double t, const Eigen::Ref<const Eigen::VectorXd>& z) const {
  // Per thread and per object (ids are never reused), so concurrent const calls are safe.
  thread_local std::unordered_map<std::uint64_t, Scratch> per_object;
  auto [it, inserted] = per_object.try_emplace(id_);
  Scratch& s = it->second;
  const auto n = static_cast<std::size_t>(kPhaseBlockCount * dim_);
  if (inserted) {
    s.args.resize(n + 1);
    s.gradient.resize(n + 1);
    s.hessian.resize(static_cast<Eigen::Index>(n + 1), static_cast<Eigen::Index>(n + 1));
    s.workspace = derivatives_.make_workspace();
  }
  for (std::size_t i = 0; i < n; ++i) s.args[i] = z[static_cast<Eigen::Index>(i)];
  s.args[n] = t;
  return s;
}

double ExpressionLagrangian::value(double t, const Eigen::Ref<const Eigen::VectorXd>& z) const {
  Scratch& s = scratch(t, z);
  return derivatives_.evaluate(s.args, s.workspace);
}

double ExpressionLagrangian::gradient(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                                      Eigen::Ref<Eigen::VectorXd> g) const {
  Scratch& s = scratch(t, z);
  const double v = derivatives_.evaluate(s.args, s.gradient, s.workspace);
  for (Eigen::Index i = 0; i < g.size(); ++i) g[i] = s.gradient[static_cast<std::size_t>(i)];
  return v;
}

void ExpressionLagrangian::derivatives(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                                       LagrangianDerivatives& out) const {
  out.resize(dim_);
  Scratch& s = scratch(t, z);
  const Eigen::Index n = kPhaseBlockCount * dim_;
  out.value = derivatives_.evaluate_dense(s.args, s.gradient, s.hessian, s.workspace);
  for (Eigen::Index i = 0; i < n; ++i) out.gradient[i] = s.gradient[static_cast<std::size_t>(i)];
  out.hessian = s.hessian.topLeftCorner(n, n);
  out.time_gradient = s.hessian.col(n).segment(2 * dim_, 4 * dim_);
}

// ---------------------------------------------------------------------------------------------
// MechanicalLagrangian

MechanicalLagrangian::MechanicalLagrangian(const MechanicalModel& model, double a, double b)
    : mass_(model.mass.to_dense()),
      damping_(model.damping.to_dense()),
      potential_(model.potential),
      forcing_(model.forcing),
      a_plus_b_(a + b) {
  validate(model);
  if (model.state_force) {
    throw ValidationError(
        "model.force depends on x or v: a non-conservative force g(x, v, t) has no Lagrangian, "
        "so the action sum and the boundary value problem (which are variational) do not take "
        "it; integrate the initial value problem with a scheme that does (docs/theory/forces.md)");
  }
  if (!(std::isfinite(a) && std::isfinite(b) && a < b)) {
    throw ValidationError("MechanicalLagrangian: the interval [a, b] = [" + std::to_string(a) +
                          ", " + std::to_string(b) + "] must be finite with a < b");
  }
  if (damping_.size() == 0) damping_ = Eigen::MatrixXd::Zero(mass_.rows(), mass_.cols());
}

std::string MechanicalLagrangian::description() const {
  return "mechanical L = 1/2 xdot^T M xdot - U_f(x, t) + 1/2 ydot^T M ydot - U_f(y, a+b-t) - "
         "dx^T R dy (PartLagrangian)";
}

namespace {

// U_f(x, t) = U(x, t) − f(t)·x and its gradient; the potential and the forcing may be absent.
double effective_potential(const Potential* U, const Forcing& f, const Eigen::VectorXd& x, double t,
                           Eigen::VectorXd* gradient) {
  const Eigen::Index d = x.size();
  double value = 0.0;
  if (gradient != nullptr) gradient->setZero(d);
  if (U != nullptr) {
    value += U->value(x, t);
    if (gradient != nullptr) U->gradient(x, t, *gradient);
  }
  if (f) {
    Eigen::VectorXd ft(d);
    f(t, ft);
    value -= ft.dot(x);
    if (gradient != nullptr) *gradient -= ft;
  }
  return value;
}

}  // namespace

double MechanicalLagrangian::value(double t, const Eigen::Ref<const Eigen::VectorXd>& z) const {
  const Eigen::Index d = dimension();
  const Eigen::VectorXd x = z.segment(0, d), y = z.segment(d, d), xd = z.segment(2 * d, d),
                        yd = z.segment(3 * d, d), dx = z.segment(4 * d, d),
                        dy = z.segment(5 * d, d);
  return 0.5 * xd.dot(mass_ * xd) + 0.5 * yd.dot(mass_ * yd) -
         effective_potential(potential_.get(), forcing_, x, t, nullptr) -
         effective_potential(potential_.get(), forcing_, y, a_plus_b_ - t, nullptr) -
         dx.dot(damping_ * dy);
}

double MechanicalLagrangian::gradient(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                                      Eigen::Ref<Eigen::VectorXd> g) const {
  const Eigen::Index d = dimension();
  const Eigen::VectorXd x = z.segment(0, d), y = z.segment(d, d), xd = z.segment(2 * d, d),
                        yd = z.segment(3 * d, d), dx = z.segment(4 * d, d),
                        dy = z.segment(5 * d, d);
  Eigen::VectorXd gx(d), gy(d);
  const double ux = effective_potential(potential_.get(), forcing_, x, t, &gx);
  const double uy = effective_potential(potential_.get(), forcing_, y, a_plus_b_ - t, &gy);
  g.segment(0, d) = -gx;
  g.segment(d, d) = -gy;
  g.segment(2 * d, d) = mass_ * xd;
  g.segment(3 * d, d) = mass_ * yd;
  g.segment(4 * d, d) = -damping_ * dy;
  g.segment(5 * d, d) = -damping_.transpose() * dx;
  return 0.5 * xd.dot(mass_ * xd) + 0.5 * yd.dot(mass_ * yd) - ux - uy - dx.dot(damping_ * dy);
}

void MechanicalLagrangian::derivatives(double t, const Eigen::Ref<const Eigen::VectorXd>& z,
                                       LagrangianDerivatives& out) const {
  const Eigen::Index d = dimension();
  out.resize(d);
  out.value = gradient(t, z, out.gradient);
  out.hessian.setZero();
  if (potential_) {
    const Eigen::VectorXd x = z.segment(0, d), y = z.segment(d, d);
    Eigen::MatrixXd h(d, d);
    potential_->hessian(x, t, h);
    out.hessian.block(0, 0, d, d) = -h;
    potential_->hessian(y, a_plus_b_ - t, h);
    out.hessian.block(d, d, d, d) = -h;
  }
  out.hessian.block(2 * d, 2 * d, d, d) = mass_;
  out.hessian.block(3 * d, 3 * d, d, d) = mass_;
  out.hessian.block(4 * d, 5 * d, d, d) = -damping_;
  out.hessian.block(5 * d, 4 * d, d, d) = -damping_.transpose();
  // ∂L/∂ẋ = Mẋ, ∂L/∂ẏ = Mẏ, ∂L/∂D^α_−x = −R D^α_+y, ∂L/∂D^α_+y = −R D^α_−x: no explicit t.
  out.time_gradient.setZero();
}

std::optional<HessianPattern> MechanicalLagrangian::hessian_pattern() const {
  const Eigen::Index d = dimension();
  HessianPattern p = HessianPattern::Constant(6 * d, 6 * d, false);
  if (potential_) {
    p.block(0, 0, d, d).setConstant(true);
    p.block(d, d, d, d).setConstant(true);
  }
  p.block(2 * d, 2 * d, d, d) = mass_.array() != 0.0;
  p.block(3 * d, 3 * d, d, d) = mass_.array() != 0.0;
  p.block(4 * d, 5 * d, d, d) = damping_.array() != 0.0;
  p.block(5 * d, 4 * d, d, d) = damping_.transpose().array() != 0.0;
  return p;
}

// ---------------------------------------------------------------------------------------------
// Forward-steppable class

ForwardStepClass forward_step_class(const Lagrangian& lagrangian) {
  const auto pattern = lagrangian.hessian_pattern();
  if (!pattern) {
    return {false,
            "the Lagrangian's Hessian pattern is unknown (a C++ functor), so it cannot be shown "
            "that the x-equation decouples from y"};
  }
  const Eigen::Index d = lagrangian.dimension();
  const auto& p = *pattern;
  auto any = [&](PhaseBlock row, PhaseBlock col, std::string* which) {
    const Eigen::Index r0 = block_offset(row, d), c0 = block_offset(col, d);
    for (Eigen::Index i = 0; i < d; ++i)
      for (Eigen::Index j = 0; j < d; ++j)
        if (p(r0 + i, c0 + j)) {
          *which = "dL/d" + component_name(r0 + i, d) + " depends on " + component_name(c0 + j, d);
          return true;
        }
    return false;
  };
  std::string which;
  // (1) The x-equation, ½(D_1L(k) + D_1L(k−1)) + Δ_+D_3L(k) + Δ^α_−D_6L(k), must not see y.
  for (PhaseBlock row : {PhaseBlock::kX, PhaseBlock::kXdot, PhaseBlock::kDyAlpha}) {
    for (PhaseBlock col : {PhaseBlock::kY, PhaseBlock::kYdot, PhaseBlock::kDyAlpha}) {
      if (any(row, col, &which)) {
        return {false, "the x-equation involves y (" + which +
                           "): x and y must be solved together as a boundary value problem"};
      }
    }
  }
  // (2) Δ_+D_3L(k) contains D_3L(k+1), whose midpoint S x_{k+1} holds x_{k+2}.
  if (any(PhaseBlock::kXdot, PhaseBlock::kX, &which)) {
    return {false, which +
                       ": L(k) pairs the midpoint S x_k with the backward difference, so "
                       "the x-equation at k would involve x_(k+2); not a one-step recursion"};
  }
  return {true, {}};
}

}  // namespace fracvi
