#include "fracvi/io/lagrangian_problem.hpp"

#include <Eigen/Eigenvalues>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "fracvi/io/output.hpp"
#include "fracvi/model/expression_potential.hpp"
#include "fracvi/schemes/registry.hpp"

namespace fracvi {

namespace {

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// U(x, t) = L(t, 0, …, 0) − L(t, x, 0, …, 0) for an L of mechanical form: −∂L/∂x and −∂²L/∂x² at
// (x, y = 0, velocities and fractional derivatives 0); by the form these do not depend on the
// zeroed arguments.
class LagrangianPotential final : public Potential {
 public:
  explicit LagrangianPotential(std::shared_ptr<const ExpressionLagrangian> lagrangian)
      : l_(std::move(lagrangian)),
        d_(l_->dimension()),
        time_dependent_(l_->expression().depends_on(static_cast<std::size_t>(6 * d_))) {}

  [[nodiscard]] Eigen::Index dimension() const override { return d_; }
  [[nodiscard]] double value(const Eigen::Ref<const Eigen::VectorXd>& x, double t) const override {
    Eigen::VectorXd z = Eigen::VectorXd::Zero(6 * d_);
    const double base = l_->value(t, z);
    z.head(d_) = x;
    return base - l_->value(t, z);
  }
  void gradient(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
                Eigen::Ref<Eigen::VectorXd> g) const override {
    Eigen::VectorXd z = Eigen::VectorXd::Zero(6 * d_), full(6 * d_);
    z.head(d_) = x;
    l_->gradient(t, z, full);
    g = -full.head(d_);
  }
  void hessian(const Eigen::Ref<const Eigen::VectorXd>& x, double t,
               Eigen::Ref<Eigen::MatrixXd> h) const override {
    Eigen::VectorXd z = Eigen::VectorXd::Zero(6 * d_);
    z.head(d_) = x;
    LagrangianDerivatives der;
    l_->derivatives(t, z, der);
    h = -der.hessian.topLeftCorner(d_, d_);
  }
  [[nodiscard]] bool is_time_dependent() const override { return time_dependent_; }

 private:
  std::shared_ptr<const ExpressionLagrangian> l_;
  Eigen::Index d_;
  bool time_dependent_;
};

}  // namespace

std::shared_ptr<const Lagrangian> make_lagrangian(const ProblemSpec& spec) {
  if (!spec.lagrangian.empty())
    return std::make_shared<const ExpressionLagrangian>(spec.dim, spec.lagrangian);
  // A g(x, v, t) has no Lagrangian: MechanicalLagrangian refuses it.
  const MechanicalModel model = make_mechanical_model(spec);
  const double order = 2.0 * spec.alpha;
  if (model.convention == Convention::kCaputo && order != 0.0 && order != 1.0 &&
      !model.is_undamped()) {
    throw ValidationError(
        "model.convention = caputo with damping order 2*alpha = " + fmt(order) +
        ": the variational formulation (FracEL, DiscFracEL) uses the paper's Riemann-Liouville "
        "derivatives D^alpha_- x, D^alpha_+ y; the Caputo model is a different one. Set "
        "model.convention = \"riemann-liouville\" (they coincide for alpha = 1/2)");
  }
  return std::make_shared<const MechanicalLagrangian>(model, spec.start, spec.end);
}

void check_velocity_hessian(const Lagrangian& lagrangian, double t,
                            const Eigen::Ref<const Eigen::VectorXd>& z, const std::string& where,
                            bool include_y) {
  const Eigen::Index d = lagrangian.dimension();
  LagrangianDerivatives der;
  lagrangian.derivatives(t, z, der);
  for (int b : {2, 3}) {
    if (b == 3 && !include_y) continue;
    const Eigen::MatrixXd h = der.hessian.block(b * d, b * d, d, d);
    const char* name = b == 2 ? "xdot" : "ydot";
    if (!h.allFinite()) {
      throw ValidationError(std::string("the Hessian of L in the velocities ") + name +
                            " is not finite at " + where);
    }
    const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(
                                   0.5 * (h + h.transpose()), Eigen::EigenvaluesOnly)
                                   .eigenvalues();
    const double scale = std::max(1.0, ev.cwiseAbs().maxCoeff());
    const double smallest = ev.cwiseAbs().minCoeff();
    if (smallest <= 1e-12 * scale) {
      throw ValidationError(
          std::string("the Hessian of L in the velocities, d2L/d") + name + "2, is singular at " +
          where + " (eigenvalues " + fmt(ev.minCoeff()) + " ... " + fmt(ev.maxCoeff()) +
          "): the discrete Euler-Lagrange equations cannot be solved for the next position. L "
          "must contain a kinetic term in every " +
          name + " component");
    }
  }
}

namespace {

// The scheme of a boundary value problem: "auto" takes the paper's scheme, the one with the full
// BVP theory (RestDiscVarPrin).
std::string_view boundary_value_scheme(const ProblemSpec& spec) {
  return spec.scheme == kAutoScheme ? fvi_gl().name() : std::string_view(spec.scheme);
}

}  // namespace

CqScheme boundary_value_quadrature(const ProblemSpec& spec) {
  const SchemeInfo* info = find_scheme(boundary_value_scheme(spec));
  if (info == nullptr) {
    throw ValidationError("method.scheme = \"" + spec.scheme +
                          "\" is not a known scheme (available: " + scheme_names() + ")");
  }
  return boundary_value_quadrature(*info);
}

BoundaryValueProblem make_boundary_value_problem(const ProblemSpec& spec) {
  if (spec.boundary_start.size() == 0) {
    throw ValidationError(
        "[boundary] missing: fracvi bvp needs start = x(a) and end = x(b) (y takes the mirrored "
        "values y(a) = end, y(b) = start)");
  }
  BoundaryValueProblem p;
  p.lagrangian = make_lagrangian(spec);
  p.grid = DiscreteGrid{spec.start, spec.end, static_cast<Eigen::Index>(spec.steps), spec.alpha};
  p.grid.quadrature = boundary_value_quadrature(spec);
  p.x_start = spec.boundary_start;
  p.x_end = spec.boundary_end;
  validate(p);
  // The velocity Hessian at the first point of the straight-line starting iterate.
  Sequence x(spec.dim, spec.steps + 1), y(spec.dim, spec.steps + 1);
  for (Eigen::Index k = 0; k <= spec.steps; ++k) {
    const double s = static_cast<double>(k) / static_cast<double>(spec.steps);
    x.col(k) = (1 - s) * p.x_start + s * p.x_end;
    y.col(k) = (1 - s) * p.x_end + s * p.x_start;
  }
  const Eigen::MatrixXd z = discrete_phase_points(x, y, p.grid);
  check_velocity_hessian(*p.lagrangian, p.grid.time(1.5), z.col(1),
                         "the starting iterate (t = " + fmt(p.grid.time(1.5)) + ")");
  return p;
}

BvpOptions make_bvp_options(const ProblemSpec& spec) {
  BvpOptions o;
  o.max_iterations = spec.newton_max_iterations;
  return o;
}

MechanicalForm mechanical_form(const std::shared_ptr<const ExpressionLagrangian>& lagrangian,
                               double alpha) {
  MechanicalForm out;
  const ForwardStepClass cls = forward_step_class(*lagrangian);
  if (!cls.forward_steppable) {
    out.reason = cls.reason;
    return out;
  }
  const Eigen::Index d = lagrangian->dimension();
  const Expression& e = lagrangian->expression();
  const auto names = ExpressionLagrangian::variable_names(d);
  const std::vector<double> zeros(names.size(), 0.0);
  auto index = [d](int block, Eigen::Index i) { return static_cast<std::size_t>(block * d + i); };
  // ∂L/∂(block b, i) may depend only on the variables of blocks `allowed` (t is index 6d).
  auto only_on = [&](const Expression& f, std::initializer_list<int> allowed, bool time,
                     std::string* offending) {
    for (std::size_t v = 0; v < names.size(); ++v) {
      const bool is_time = v == static_cast<std::size_t>(6 * d);
      bool ok = is_time ? time : false;
      for (int b : allowed) ok = ok || (!is_time && static_cast<int>(v / d) == b);
      if (!ok && f.depends_on(v)) {
        *offending = names[v];
        return false;
      }
    }
    return true;
  };
  MechanicalModel m;
  m.alpha = alpha;
  m.convention = Convention::kRiemannLiouville;
  Eigen::MatrixXd mass(d, d), damping(d, d);
  std::string bad;
  for (Eigen::Index i = 0; i < d; ++i) {
    const Expression pxi = e.derivative(index(2, i));    // ∂L/∂ẋ_i
    const Expression pdyi = e.derivative(index(5, i));   // ∂L/∂(D^α_+y)_i
    const Expression pxpos = e.derivative(index(0, i));  // ∂L/∂x_i
    if (!only_on(pxi, {2}, false, &bad)) {
      out.reason = "dL/d" + names[index(2, i)] + " depends on " + bad +
                   " (not a kinetic energy 1/2 xdot^T M xdot with constant M)";
      return out;
    }
    if (!only_on(pdyi, {4}, false, &bad)) {
      out.reason = "dL/d" + names[index(5, i)] + " depends on " + bad +
                   " (not a memory coupling -dx^T R dy with constant R)";
      return out;
    }
    if (!only_on(pxpos, {0}, true, &bad)) {
      out.reason =
          "dL/d" + names[index(0, i)] + " depends on " + bad + " (not a potential U(x, t))";
      return out;
    }
    if (pxi(zeros) != 0.0 || pdyi(zeros) != 0.0) {
      out.reason = "L has a term linear in " + names[pxi(zeros) != 0.0 ? index(2, i) : index(5, i)];
      return out;
    }
    for (Eigen::Index j = 0; j < d; ++j) {
      const Expression mij = pxi.derivative(index(2, j));
      const Expression rij = pdyi.derivative(index(4, j));  // ∂²L/∂dy_i∂dx_j = −R_ji
      if (!mij.is_constant() || !rij.is_constant()) {
        out.reason = "the coefficient of " + names[index(2, i)] + "*" + names[index(2, j)] +
                     " or of " + names[index(4, j)] + "*" + names[index(5, i)] + " is not constant";
        return out;
      }
      mass(i, j) = mij(zeros);
      damping(j, i) = -rij(zeros);
    }
  }
  m.mass = mass;
  m.damping = damping;
  m.potential = std::make_shared<const LagrangianPotential>(lagrangian);
  out.model = std::move(m);
  return out;
}

InitialValueProblem make_lagrangian_initial_value_problem(const ProblemSpec& spec) {
  if (spec.lagrangian.empty()) {
    throw ValidationError("make_lagrangian_initial_value_problem: the spec has no lagrangian");
  }
  auto lagrangian = std::make_shared<const ExpressionLagrangian>(spec.dim, spec.lagrangian);
  const MechanicalForm form = mechanical_form(lagrangian, spec.alpha);
  if (!form.model) {
    throw ValidationError(
        "model.lagrangian: fracvi run integrates Lagrangians of mechanical form "
        "1/2 xdot^T M xdot - U(x, t) - dx^T R dy + (terms in y, ydot, dy), and this one is not: " +
        form.reason +
        ". Solve it as a boundary value problem with fracvi bvp ([boundary] start, "
        "end)");
  }
  InitialValueProblem p;
  p.model = *form.model;
  p.x0 = spec.position;
  p.v0 = spec.velocity;
  p.t0 = spec.start;
  p.t_end = spec.end;
  p.steps = static_cast<std::size_t>(spec.steps);
  // A singular M means the step (M Δ + (h²/2)∇U = …) cannot be solved for x_{k+1}.
  Eigen::VectorXd z = Eigen::VectorXd::Zero(6 * spec.dim);
  z.head(spec.dim) = spec.position;
  z.segment(2 * spec.dim, spec.dim) = spec.velocity;
  check_velocity_hessian(*lagrangian, spec.start, z,
                         "the initial data (t = " + fmt(spec.start) + ")", /*include_y=*/false);
  const Eigen::MatrixXd r = p.model.damping.to_dense();
  if ((r - r.transpose()).cwiseAbs().maxCoeff() > 1e-12 * std::max(1.0, r.cwiseAbs().maxCoeff())) {
    throw ValidationError(
        "model.lagrangian: the memory coupling -dx^T R dy has a non-symmetric R (the coefficient "
        "of dx_i*dy_j differs from that of dx_j*dy_i); fracvi run needs R symmetric");
  }
  return p;
}

nlohmann::json make_bvp_summary(const ProblemSpec& spec, const BvpSolution& s) {
  const Eigen::Index n = s.x.rows() - 1;
  const double mirror =
      s.x.rows() > 0 ? (s.y - s.x.colwise().reverse()).cwiseAbs().maxCoeff() : 0.0;
  nlohmann::json history = nlohmann::json::array();
  for (double r : s.residual_history) history.push_back(json_number(r));
  return {
      {"status", s.ok() ? "success" : std::string(to_string(s.status))},
      {"message", s.message},
      {"steps", n},
      {"scheme", std::string(boundary_value_scheme(spec))},
      {"action_sum", s.sum},
      {"residual_norm", json_number(s.residual_norm)},
      {"residual_floor", json_number(s.residual_floor)},
      {"residual_tolerance", s.residual_tolerance},
      {"residual_history", history},
      {"newton_iterations", s.newton_iterations},
      {"linear_iterations", s.linear_iterations},
      {"linear_solver", s.linear_solver},
      {"wall_time_seconds", s.wall_time_seconds},
      {"mirror_error", json_number(mirror)},
      {"x_start", json_row(s.x, 0)},
      {"x_end", json_row(s.x, n)},
      {"y_start", json_row(s.y, 0)},
      {"y_end", json_row(s.y, n)},
      {"problem", to_json(spec)},
  };
}

void write_bvp_output(const std::filesystem::path& dir, const ProblemSpec& spec,
                      const BvpSolution& s) {
  prepare_output_directory(dir);
  const Eigen::Index d = s.x.cols(), rows = s.x.rows();
  std::string csv = "t";
  for (Eigen::Index i = 1; i <= d; ++i) csv += ",x" + std::to_string(i);
  for (Eigen::Index i = 1; i <= d; ++i) csv += ",y" + std::to_string(i);
  csv += ",residual_x,residual_y\n";
  const long long every = stored_every(spec);
  for (Eigen::Index k = 0; k < rows; ++k) {
    if (k % every != 0 && k != rows - 1) continue;
    append_csv_number(csv, s.t[k]);
    for (Eigen::Index i = 0; i < d; ++i) csv += ',', append_csv_number(csv, s.x(k, i));
    for (Eigen::Index i = 0; i < d; ++i) csv += ',', append_csv_number(csv, s.y(k, i));
    const bool has = s.x_residual.rows() == rows;
    csv += ',', append_csv_number(csv, has ? s.x_residual.row(k).cwiseAbs().maxCoeff() : NAN);
    csv += ',', append_csv_number(csv, has ? s.y_residual.row(k).cwiseAbs().maxCoeff() : NAN);
    csv += '\n';
  }
  write_file_atomically(dir / "trajectory.csv", csv);
  write_file_atomically(dir / "summary.json", make_bvp_summary(spec, s).dump(2) + "\n");
  write_file_atomically(dir / "problem.toml", to_toml(spec));
}

}  // namespace fracvi
