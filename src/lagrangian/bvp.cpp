#include "fracvi/lagrangian/bvp.hpp"

#include <Eigen/LU>
#include <Eigen/SparseLU>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>

#include "discrete_system.hpp"
#include "fracvi/model/mechanical_model.hpp"

namespace fracvi {

// ---------------------------------------------------------------------------------------------
// Validation

namespace {

std::string fmt(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

[[noreturn]] void fail(const std::string& message) {
  throw ValidationError(message);
}

}  // namespace

void validate(const BoundaryValueProblem& p) {
  if (!p.lagrangian) fail("bvp.lagrangian is null");
  try {
    validate(p.grid);
  } catch (const std::invalid_argument& e) {
    fail(std::string("bvp.grid: ") + e.what());
  }
  if (p.grid.steps < 2) {
    fail("bvp.grid.steps = " + std::to_string(p.grid.steps) +
         " must be >= 2 (the boundary value problem needs an interior point)");
  }
  const Eigen::Index d = p.lagrangian->dimension();
  auto check = [&](const Eigen::VectorXd& v, const char* name) {
    if (v.size() != d) {
      fail(std::string(name) + " has size " + std::to_string(v.size()) +
           ", the Lagrangian's dimension is " + std::to_string(d));
    }
    if (!v.allFinite()) fail(std::string(name) + " has a non-finite entry");
  };
  check(p.x_start, "bvp.x_start");
  check(p.x_end, "bvp.x_end");
  auto check_guess = [&](const RowMatrixXd& g, const char* name) {
    if (g.size() == 0) return;
    if (g.rows() != p.grid.steps + 1 || g.cols() != d) {
      fail(std::string(name) + " is " + std::to_string(g.rows()) + " x " +
           std::to_string(g.cols()) + ", must be (N+1) x d = " + std::to_string(p.grid.steps + 1) +
           " x " + std::to_string(d));
    }
    if (!g.allFinite()) fail(std::string(name) + " has a non-finite entry");
  };
  check_guess(p.x_guess, "bvp.x_guess");
  check_guess(p.y_guess, "bvp.y_guess");
}

void validate(const BvpOptions& o) {
  if (!(o.residual_tolerance > 0.0)) {
    fail("bvp options residual_tolerance = " + fmt(o.residual_tolerance) + " must be positive");
  }
  if (o.max_iterations < 1) {
    fail("bvp options max_iterations = " + std::to_string(o.max_iterations) + " must be >= 1");
  }
  if (o.preconditioner_width < 1) {
    fail("bvp options preconditioner_width = " + std::to_string(o.preconditioner_width) +
         " must be >= 1");
  }
  if (!(o.krylov_tolerance > 0.0 && o.krylov_tolerance < 1.0)) {
    fail("bvp options krylov_tolerance = " + fmt(o.krylov_tolerance) + " must be in (0, 1)");
  }
  if (o.krylov_restart < 1 || o.krylov_max_iterations < 1) {
    fail("bvp options krylov_restart and krylov_max_iterations must be >= 1");
  }
}

// ---------------------------------------------------------------------------------------------
// The structured Jacobian

namespace {

// One entry of the linear map A_k (unknown → z_k) or C_k (G_k → equations): block m of z_k,
// grid point j (interior), x or y, coefficient.
struct MapEntry {
  int block;
  Eigen::Index point;
  bool is_y;
  double coeff;
};

}  // namespace

struct DiscreteElJacobian::Impl {
  internal::DiscreteElSystem system;
  Eigen::Index d, n;                  // dimension, N
  std::vector<Eigen::MatrixXd> hess;  // ∇²L at the points 0..point_count−1
  std::vector<std::array<bool, 36>> nonzero_blocks;

  Impl(const Lagrangian& lagrangian, const DiscreteGrid& grid, ActionSum sum, const Sequence& x,
       const Sequence& y)
      : system(lagrangian.dimension(), grid, sum), d(lagrangian.dimension()), n(grid.steps) {
    Eigen::MatrixXd z;
    system.phase_points(x, y, z);
    LagrangianDerivatives der;
    const Eigen::Index points = system.point_count();
    hess.resize(static_cast<std::size_t>(points));
    nonzero_blocks.resize(static_cast<std::size_t>(points));
    for (Eigen::Index k = 0; k < points; ++k) {
      lagrangian.derivatives(system.point_time(k), z.col(k), der);
      set_hessian(k, der.hessian);
    }
  }

  void set_hessian(Eigen::Index k, const Eigen::MatrixXd& h) {
    const auto kk = static_cast<std::size_t>(k);
    hess[kk] = h;
    for (int a = 0; a < 6; ++a)
      for (int b = 0; b < 6; ++b)
        nonzero_blocks[kk][static_cast<std::size_t>(6 * a + b)] =
            !h.block(a * d, b * d, d, d).isZero(0.0);
  }

  [[nodiscard]] Eigen::Index size() const { return 2 * (n - 1) * d; }
  [[nodiscard]] Eigen::Index index(Eigen::Index point, bool is_y) const {
    return 2 * d * (point - 1) + (is_y ? d : 0);
  }

  void unpack(const Eigen::VectorXd& v, Sequence& x, Sequence& y) const {
    x.setZero(d, n + 1);
    y.setZero(d, n + 1);
    for (Eigen::Index j = 1; j < n; ++j) {
      x.col(j) = v.segment(index(j, false), d);
      y.col(j) = v.segment(index(j, true), d);
    }
  }
  void pack(const Sequence& x, const Sequence& y, Eigen::VectorXd& v) const {
    v.resize(size());
    for (Eigen::Index j = 1; j < n; ++j) {
      v.segment(index(j, false), d) = x.col(j);
      v.segment(index(j, true), d) = y.col(j);
    }
  }

  [[nodiscard]] Eigen::VectorXd apply(const Eigen::VectorXd& v) const {
    Sequence dx, dy, ex, ey;
    unpack(v, dx, dy);
    Eigen::MatrixXd dz, dg;
    system.phase_points(dx, dy, dz);
    dg.setZero(dz.rows(), dz.cols());
    for (Eigen::Index k = 0; k < system.point_count(); ++k)
      dg.col(k).noalias() = hess[static_cast<std::size_t>(k)] * dz.col(k);
    system.assemble(dg, ex, ey);
    Eigen::VectorXd out;
    pack(ex, ey, out);
    return out;
  }

  // The entries of A_k (the unknowns that z_k depends on), CQ sums truncated after `width` lags.
  // C_k has the same entries with the fractional blocks routed to the other equation
  // (discrete_system.hpp).
  void input_entries(Eigen::Index k, Eigen::Index width, std::vector<MapEntry>& out) const {
    out.clear();
    const double inv_h = 1.0 / system.grid().step();
    const double inv_h_alpha = std::pow(system.grid().step(), -system.grid().alpha);
    const auto& w = system.weights();
    auto interior = [&](Eigen::Index j) { return j >= 1 && j <= n - 1; };
    auto add = [&](int block, Eigen::Index j, bool is_y, double c) {
      if (interior(j)) out.push_back({block, j, is_y, c});
    };
    if (k < n) {
      add(0, k, false, 0.5);
      add(0, k + 1, false, 0.5);
      add(1, k, true, 0.5);
      add(1, k + 1, true, 0.5);
      add(3, k, true, -inv_h);  // the ẏ slot (y_{k+1} − y_k)/h
      add(3, k + 1, true, inv_h);
    }
    if (k >= 1) {
      add(2, k, false, inv_h);
      add(2, k - 1, false, -inv_h);
    }
    for (Eigen::Index j = std::max<Eigen::Index>(1, k - width); j <= std::min(k, n - 1); ++j)
      add(4, j, false, inv_h_alpha * w[static_cast<std::size_t>(k - j)]);
    for (Eigen::Index j = std::max<Eigen::Index>(1, k); j <= std::min(n - 1, k + width); ++j)
      add(5, j, true, inv_h_alpha * w[static_cast<std::size_t>(j - k)]);
  }

  // Σ_k C_kᵀ H_k A_k with truncated CQ sums; sink(row, col, coefficient, d×d block).
  template <class Sink>
  void assemble(Eigen::Index width, Sink&& sink) const {
    std::vector<MapEntry> in;
    for (Eigen::Index k = 0; k < system.point_count(); ++k) {
      input_entries(k, width, in);
      const auto& h = hess[static_cast<std::size_t>(k)];
      const auto& nz = nonzero_blocks[static_cast<std::size_t>(k)];
      for (const MapEntry& o : in) {
        const bool out_y = o.block >= 4 ? !o.is_y : o.is_y;  // the paper's split
        const Eigen::Index row = index(o.point, out_y);
        for (const MapEntry& i : in) {
          if (!nz[static_cast<std::size_t>(6 * o.block + i.block)]) continue;
          sink(row, index(i.point, i.is_y), o.coeff * i.coeff,
               h.block(o.block * d, i.block * d, d, d));
        }
      }
    }
  }

  // Block-banded accumulation of a sparse matrix with d × d blocks: rows of point p couple to
  // points p − band … p + band (each 2d wide), then exact zeros are dropped.
  [[nodiscard]] Eigen::SparseMatrix<double> banded(Eigen::Index width) const {
    const Eigen::Index dim = size();
    const Eigen::Index band = std::min<Eigen::Index>(2 * width + 2, n - 2);
    const Eigen::Index cols = (2 * band + 1) * 2 * d;          // per row
    Eigen::MatrixXd store = Eigen::MatrixXd::Zero(cols, dim);  // column r holds row r's band
    assemble(width, [&](Eigen::Index r, Eigen::Index c, double coeff, const auto& block) {
      const Eigen::Index pr = r / (2 * d), pc = c / (2 * d);
      const Eigen::Index offset = (pc - pr + band) * 2 * d + c % (2 * d);
      for (Eigen::Index i = 0; i < d; ++i)
        for (Eigen::Index j = 0; j < d; ++j) store(offset + j, r + i) += coeff * block(i, j);
    });
    std::vector<Eigen::Triplet<double>> triplets;
    for (Eigen::Index r = 0; r < dim; ++r) {
      const Eigen::Index pr = r / (2 * d);
      for (Eigen::Index q = 0; q < cols; ++q) {
        const double v = store(q, r);
        if (v == 0.0) continue;
        const Eigen::Index pc = pr + q / (2 * d) - band;
        triplets.emplace_back(r, pc * 2 * d + q % (2 * d), v);
      }
    }
    Eigen::SparseMatrix<double> m(dim, dim);
    m.setFromTriplets(triplets.begin(), triplets.end());
    return m;
  }
};

DiscreteElJacobian::DiscreteElJacobian(const Lagrangian& lagrangian, const DiscreteGrid& grid,
                                       ActionSum sum, const Sequence& x, const Sequence& y) {
  validate(grid);
  const Eigen::Index d = lagrangian.dimension();
  if (grid.steps < 2 || x.rows() != d || y.rows() != d || x.cols() != grid.steps + 1 ||
      y.cols() != grid.steps + 1) {
    throw std::invalid_argument(
        "DiscreteElJacobian: x and y must be d x (N+1) with N >= 2, d the Lagrangian's dimension");
  }
  impl_ = std::make_unique<Impl>(lagrangian, grid, sum, x, y);
}
DiscreteElJacobian::~DiscreteElJacobian() = default;
DiscreteElJacobian::DiscreteElJacobian(DiscreteElJacobian&&) noexcept = default;
DiscreteElJacobian& DiscreteElJacobian::operator=(DiscreteElJacobian&&) noexcept = default;

Eigen::Index DiscreteElJacobian::size() const {
  return impl_->size();
}

Eigen::VectorXd DiscreteElJacobian::apply(const Eigen::VectorXd& v) const {
  if (v.size() != size()) {
    throw std::invalid_argument("DiscreteElJacobian::apply: v has size " +
                                std::to_string(v.size()) + ", need " + std::to_string(size()));
  }
  return impl_->apply(v);
}

Eigen::MatrixXd DiscreteElJacobian::dense() const {
  Eigen::MatrixXd j = Eigen::MatrixXd::Zero(size(), size());
  const Eigen::Index d = impl_->d;
  impl_->assemble(impl_->n, [&](Eigen::Index r, Eigen::Index c, double coeff, const auto& block) {
    j.block(r, c, d, d) += coeff * block;
  });
  return j;
}

Eigen::SparseMatrix<double> DiscreteElJacobian::banded(Eigen::Index width) const {
  if (width < 0) throw std::invalid_argument("DiscreteElJacobian::banded: width must be >= 0");
  return impl_->banded(std::min(width, impl_->n));
}

// ---------------------------------------------------------------------------------------------
// Newton

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Restarted GMRES(m) with right preconditioning, modified Gram–Schmidt and Givens rotations.
// Solves J x = b to ‖b − J x‖₂ ≤ max(tol ‖b‖₂, abs_tol); returns the iterations used and the final
// ‖b − J x‖₂ (recomputed, not the recursion's estimate).
template <class Apply, class Precondition>
std::pair<int, double> gmres(const Apply& apply, const Precondition& precondition,
                             const Eigen::VectorXd& b, Eigen::VectorXd& x, double tol,
                             double abs_tol, int restart, int max_iterations) {
  const Eigen::Index n = b.size();
  x.setZero(n);
  const double bnorm = b.norm();
  if (bnorm == 0.0) return {0, 0.0};
  const double target = std::max(tol * bnorm, abs_tol);
  int total = 0;
  Eigen::VectorXd r = b;
  double rnorm = bnorm;
  while (total < max_iterations) {
    const double beta = rnorm;
    if (beta <= target) return {total, beta};
    const int m = std::min(restart, max_iterations - total);
    Eigen::MatrixXd v(n, m + 1), zs(n, m), hm = Eigen::MatrixXd::Zero(m + 1, m);
    Eigen::VectorXd cs(m), sn(m), g = Eigen::VectorXd::Zero(m + 1);
    v.col(0) = r / beta;
    g(0) = beta;
    int k = 0;
    for (; k < m; ++k) {
      zs.col(k) = precondition(v.col(k));
      Eigen::VectorXd w = apply(zs.col(k));
      for (int i = 0; i <= k; ++i) {
        hm(i, k) = w.dot(v.col(i));
        w -= hm(i, k) * v.col(i);
      }
      hm(k + 1, k) = w.norm();
      if (hm(k + 1, k) > 0.0) v.col(k + 1) = w / hm(k + 1, k);
      for (int i = 0; i < k; ++i) {
        const double t = cs(i) * hm(i, k) + sn(i) * hm(i + 1, k);
        hm(i + 1, k) = -sn(i) * hm(i, k) + cs(i) * hm(i + 1, k);
        hm(i, k) = t;
      }
      const double den = std::hypot(hm(k, k), hm(k + 1, k));
      cs(k) = den == 0.0 ? 1.0 : hm(k, k) / den;
      sn(k) = den == 0.0 ? 0.0 : hm(k + 1, k) / den;
      hm(k, k) = den;
      hm(k + 1, k) = 0.0;
      g(k + 1) = -sn(k) * g(k);
      g(k) = cs(k) * g(k);
      ++total;
      if (std::abs(g(k + 1)) <= target || den == 0.0) {
        ++k;
        break;
      }
    }
    const Eigen::VectorXd yk =
        hm.topLeftCorner(k, k).triangularView<Eigen::Upper>().solve(g.head(k));
    x += zs.leftCols(k) * yk;
    r = b - apply(x);
    const double previous = rnorm;
    rnorm = r.norm();
    if (!std::isfinite(rnorm)) return {total, rnorm};
    // Stagnation at the round-off level of J·x (ε‖J‖‖x‖): another cycle cannot help.
    if (rnorm > 0.9 * previous) break;
  }
  return {total, rnorm};
}

class BvpSolver {
 public:
  BvpSolver(const BoundaryValueProblem& p, const BvpOptions& o)
      : p_(p),
        o_(o),
        L_(*p.lagrangian),
        d_(L_.dimension()),
        n_(p.grid.steps),
        system_(d_, p.grid, p.sum) {}

  BvpSolution run() {
    const auto start = std::chrono::steady_clock::now();
    BvpSolution sol;
    sol.sum = std::string(to_string(p_.sum));
    initial_guess();
    const Eigen::Index unknowns = 2 * (n_ - 1) * d_;
    const bool dense = o_.linear_solver == BvpLinearSolver::kDense ||
                       (o_.linear_solver == BvpLinearSolver::kAuto && unknowns <= o_.dense_limit);
    sol.linear_solver = dense ? "dense LU (n = " + std::to_string(unknowns) + ")"
                              : "GMRES(" + std::to_string(o_.krylov_restart) +
                                    ") + banded SparseLU (width " +
                                    std::to_string(std::min(o_.preconditioner_width, n_)) +
                                    ", n = " + std::to_string(unknowns) + ")";
    run_newton(sol, dense);
    // The best iterate, whatever the outcome.
    x_ = best_x_;
    y_ = best_y_;
    double norm = kNaN;
    try {
      norm = residual(x_, y_, &sol);
    } catch (const std::exception&) {
      // Keep the status and message of the failure that led here.
    }
    sol.residual_norm = norm;
    sol.residual_floor = floor_;
    sol.residual_tolerance = tolerance();
    sol.t.resize(n_ + 1);
    for (Eigen::Index k = 0; k <= n_; ++k) sol.t(k) = p_.grid.time(static_cast<double>(k));
    sol.x = x_.transpose();
    sol.y = y_.transpose();
    sol.wall_time_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return sol;
  }

 private:
  void initial_guess() {
    x_.resize(d_, n_ + 1);
    y_.resize(d_, n_ + 1);
    for (Eigen::Index k = 0; k <= n_; ++k) {
      const double s = static_cast<double>(k) / static_cast<double>(n_);
      x_.col(k) = p_.x_guess.size() ? Eigen::VectorXd(p_.x_guess.row(k).transpose())
                                    : Eigen::VectorXd((1 - s) * p_.x_start + s * p_.x_end);
      y_.col(k) = p_.y_guess.size() ? Eigen::VectorXd(p_.y_guess.row(k).transpose())
                                    : Eigen::VectorXd((1 - s) * p_.x_end + s * p_.x_start);
    }
    x_.col(0) = p_.x_start;
    x_.col(n_) = p_.x_end;
    y_.col(0) = p_.x_end;
    y_.col(n_) = p_.x_start;
  }

  // max-norm of the equations at (x, y); fills F (packed) and, if sol is given, its residuals.
  double residual(const Sequence& x, const Sequence& y, BvpSolution* sol = nullptr) {
    Eigen::MatrixXd z, g;
    system_.phase_points(x, y, z);
    g.setZero(z.rows(), z.cols());
    Eigen::VectorXd gk(z.rows());
    for (Eigen::Index k = 0; k < system_.point_count(); ++k) {
      L_.gradient(system_.point_time(k), z.col(k), gk);
      g.col(k) = gk;
    }
    Sequence ex, ey;
    system_.assemble(g, ex, ey);
    f_.resize(2 * (n_ - 1) * d_);
    for (Eigen::Index j = 1; j < n_; ++j) {
      f_.segment(2 * d_ * (j - 1), d_) = ex.col(j);
      f_.segment(2 * d_ * (j - 1) + d_, d_) = ey.col(j);
    }
    if (sol != nullptr) {
      sol->x_residual = ex.transpose();
      sol->y_residual = ey.transpose();
    }

    if (!f_.allFinite()) return kNaN;
    return f_.cwiseAbs().maxCoeff();
  }

  // The positions carry rounding ε|u|, which the equations amplify by ‖J‖_∞ (the 1/h² of the
  // second differences dominates): 2ε‖J‖_∞‖u‖_∞ is the floor below which no iterate can push
  // max |F|.
  // The tolerance in force: residual_tolerance, raised to the round-off floor of the last
  // Jacobian when above_round_off (BvpOptions).
  [[nodiscard]] double tolerance() const {
    return o_.above_round_off ? std::max(o_.residual_tolerance, floor_) : o_.residual_tolerance;
  }

  void update_floor(double jacobian_norm) {
    const double u = std::max(x_.cwiseAbs().maxCoeff(), y_.cwiseAbs().maxCoeff());
    floor_ = 2 * std::numeric_limits<double>::epsilon() * jacobian_norm * u;
  }

  void run_newton(BvpSolution& sol, bool dense) {
    const auto fail_with = [&](Status s, const std::string& why, int it) {
      sol.status = s;
      sol.message = why + " (Newton iteration " + std::to_string(it) + ")";
    };
    double norm;
    try {
      norm = residual(x_, y_);
    } catch (const std::exception& e) {
      best_x_ = x_;
      best_y_ = y_;
      fail_with(Status::kCallbackError, std::string("the Lagrangian threw: ") + e.what(), 0);
      return;
    }
    best_x_ = x_;
    best_y_ = y_;
    best_norm_ = norm;
    sol.residual_history.push_back(norm);
    if (!std::isfinite(norm)) {
      fail_with(Status::kNonFinite, "the residual at the starting iterate is not finite", 0);
      return;
    }
    for (int it = 1; it <= o_.max_iterations; ++it) {
      if (norm <= tolerance()) {
        sol.status = Status::kSuccess;
        sol.newton_iterations = it - 1;
        return;
      }
      sol.newton_iterations = it;
      Eigen::VectorXd delta;
      try {
        const DiscreteElJacobian jac(L_, p_.grid, p_.sum, x_, y_);
        const Eigen::VectorXd rhs = -f_;
        if (dense) {
          const Eigen::MatrixXd j = jac.dense();
          update_floor(j.cwiseAbs().rowwise().sum().maxCoeff());
          const Eigen::PartialPivLU<Eigen::MatrixXd> lu(j);
          const double rcond = lu.rcond();
          if (!(rcond > 1e3 * std::numeric_limits<double>::epsilon())) {
            fail_with(Status::kNewtonFailure,
                      "the Jacobian is singular to working precision (reciprocal condition "
                      "number " +
                          fmt(rcond) + ")",
                      it);
            return;
          }
          delta = lu.solve(rhs);
        } else {
          Eigen::SparseMatrix<double> band = jac.banded(o_.preconditioner_width);
          band.makeCompressed();
          update_floor(Eigen::MatrixXd(Eigen::MatrixXd::Ones(1, band.rows()) * band.cwiseAbs())
                           .maxCoeff());  // ‖Jᵀ‖_∞ ≈ ‖J‖_∞
          Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
          lu.compute(band);
          if (lu.info() != Eigen::Success) {
            fail_with(
                Status::kNewtonFailure,
                "the banded preconditioner could not be factored (" + lu.lastErrorMessage() + ")",
                it);
            return;
          }
          // Inexact Newton: the linear residual r enters the next F directly, so ‖r‖ ≤ tol/10 is
          // all Newton needs near the solution (asking for krylov_tolerance·‖F‖ there would go
          // below the round-off of J·v). A solve that stops short but reduced ‖r‖ is still a
          // descent direction; the line search decides.
          const auto [iterations, rnorm] = gmres(
              [&](const Eigen::VectorXd& v) { return jac.apply(v); },
              [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return lu.solve(v); }, rhs, delta,
              o_.krylov_tolerance, 0.1 * tolerance(), o_.krylov_restart, o_.krylov_max_iterations);
          sol.linear_iterations += static_cast<std::size_t>(iterations);
          if (!(rnorm <= 0.5 * rhs.norm())) {
            fail_with(Status::kNewtonFailure,
                      "GMRES did not reduce the linear residual (" + fmt(rnorm) + " vs " +
                          fmt(rhs.norm()) + " after " + std::to_string(iterations) +
                          " iterations; use --solver dense, or solver=\"dense\" in Python, for up "
                          "to a few thousand "
                          "unknowns)",
                      it);
            return;
          }
        }
      } catch (const std::exception& e) {
        fail_with(Status::kCallbackError, std::string("the Lagrangian threw: ") + e.what(), it);
        return;
      }
      if (!delta.allFinite()) {
        fail_with(Status::kNonFinite, "the Newton correction is not finite", it);
        return;
      }
      // Backtracking on ‖F‖₂ (sufficient decrease 1e-4·λ).
      const double f2 = f_.norm();
      double lambda = 1.0;
      bool accepted = false;
      Sequence xt = x_, yt = y_;
      for (int halvings = 0; halvings <= 12; ++halvings, lambda *= 0.5) {
        for (Eigen::Index j = 1; j < n_; ++j) {
          xt.col(j) = x_.col(j) + lambda * delta.segment(2 * d_ * (j - 1), d_);
          yt.col(j) = y_.col(j) + lambda * delta.segment(2 * d_ * (j - 1) + d_, d_);
        }
        double trial;
        try {
          trial = residual(xt, yt);
        } catch (const std::exception&) {
          continue;  // the Lagrangian refused this trial point: step back
        }
        if (std::isfinite(trial) && f_.norm() <= (1.0 - 1e-4 * lambda) * f2) {
          accepted = true;
          norm = trial;
          break;
        }
      }
      if (!accepted) {
        fail_with(
            Status::kNewtonFailure,
            "no decrease of the residual along the Newton direction (max |F| = " + fmt(best_norm_) +
                "); either the tolerance is below the round-off level of the equations or "
                "the starting iterate is too far from a solution",
            it);
        return;
      }
      x_ = xt;
      y_ = yt;
      const double previous = sol.residual_history.back();
      sol.residual_history.push_back(norm);
      stalled_ = norm > 0.5 * previous ? stalled_ + 1 : 0;
      if (norm < best_norm_) {
        best_norm_ = norm;
        best_x_ = x_;
        best_y_ = y_;
      }
      if (norm > tolerance() && stalled_ >= 3) {
        fail_with(Status::kNewtonFailure,
                  "Newton stagnated at max |F| = " + fmt(best_norm_) + " > residual_tolerance " +
                      fmt(tolerance()) +
                      " (three iterations without halving it); the round-off floor of these "
                      "equations is about " +
                      fmt(floor_) +
                      (floor_ > 0.1 * o_.residual_tolerance
                           ? ": the tolerance is too tight for this step size (without an "
                             "explicit tolerance the solver converges at the floor)"
                           : ""),
                  it);
        return;
      }
    }
    if (norm <= tolerance()) {
      sol.status = Status::kSuccess;
      return;
    }
    fail_with(Status::kNewtonFailure,
              "no convergence in " + std::to_string(o_.max_iterations) +
                  " iterations: max |F| = " + fmt(best_norm_) + " > residual_tolerance " +
                  fmt(tolerance()) + "; the best iterate is returned",
              o_.max_iterations);
  }

  const BoundaryValueProblem& p_;
  const BvpOptions& o_;
  const Lagrangian& L_;
  Eigen::Index d_, n_;
  internal::DiscreteElSystem system_;
  Sequence x_, y_, best_x_, best_y_;
  double best_norm_ = kNaN;
  double floor_ = 0.0;  // estimated round-off floor of max |F| at the last residual
  int stalled_ = 0;     // consecutive accepted steps that did not halve max |F|
  Eigen::VectorXd f_;
};

}  // namespace

BvpSolution solve_bvp(const BoundaryValueProblem& problem, const BvpOptions& options) {
  validate(problem);
  validate(options);
  BvpSolver solver(problem, options);
  return solver.run();
}

}  // namespace fracvi
