#include "fracvi/analysis/comparison.hpp"

#include "fracvi/analysis/convergence.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <utility>

namespace fracvi {

namespace {

// The measured errors of one successful run against the reference (comparison.hpp).
void measure(const Solution& s, double t0, const ComparisonReference& reference,
             ComparisonRow& row) {
  const std::size_t n = row.steps;
  const Eigen::Index d = s.x.cols();
  Eigen::VectorXd x_ref(d);
  const bool energies = static_cast<bool>(reference.energy) && s.energy.size() > 0;
  const double e0 = energies ? reference.energy(n, 0, t0) : 0.0;
  row.max_error = row.energy_error = row.dissipated_error = row.balance_error = 0.0;
  for (std::size_t k = 0; k <= n; ++k) {
    const auto r = static_cast<Eigen::Index>(k);
    // The grid's own times t_k (t0 + k h, as every stepper computes them).
    const double t = s.t[r];
    reference.position(n, k, t, x_ref);
    const double e = (s.x.row(r).transpose() - x_ref).cwiseAbs().maxCoeff();
    row.max_error = std::isnan(e) ? e : std::max(row.max_error, e);
    if (k == n) row.final_error = e;
    if (energies) {
      const double e_ref = reference.energy(n, k, t);
      row.energy_error = std::max(row.energy_error, std::abs(s.energy[r] - e_ref));
      row.dissipated_error =
          std::max(row.dissipated_error, std::abs(s.dissipated[r] - (e0 - e_ref)));
    }
  }
  if (!energies) row.energy_error = row.dissipated_error = ComparisonRow::kNaN;
  row.balance_error = s.max_balance_error;
}

}  // namespace

ComparisonReference fine_run_reference(Solution fine, const std::string& description) {
  auto shared = std::make_shared<const Solution>(std::move(fine));
  const auto node = [shared](std::size_t n, std::size_t k) {
    return static_cast<Eigen::Index>(k * (shared->steps_done / n));
  };
  ComparisonReference reference;
  reference.description = description;
  reference.position = [shared, node](std::size_t n, std::size_t k, double,
                                      Eigen::Ref<Eigen::VectorXd> x) {
    x = shared->x.row(node(n, k)).transpose();
  };
  if (shared->energy.size() > 0 && std::isfinite(shared->energy[0])) {
    reference.energy = [shared, node](std::size_t n, std::size_t k, double) {
      return shared->energy[node(n, k)];
    };
    reference.energy_description = "E of the reference run";
  }
  return reference;
}

Comparison compare_schemes(const std::string& problem, double t0, double interval,
                           std::span<const std::string> schemes, std::span<const std::size_t> steps,
                           const RunScheme& run, const ComparisonReference& reference,
                           const ComparisonOptions& options) {
  if (schemes.empty()) throw std::invalid_argument("--schemes: give at least one scheme");
  check_step_counts(steps, 1);
  if (options.repeat < 1) {
    throw std::invalid_argument("--repeat = " + std::to_string(options.repeat) +
                                ": must be at least 1");
  }
  if (options.energy_steps != 0 &&
      std::find(steps.begin(), steps.end(), options.energy_steps) == steps.end()) {
    throw std::invalid_argument("--energy-steps = " + std::to_string(options.energy_steps) +
                                ": must be one of the --steps entries");
  }
  Comparison out;
  out.problem = problem;
  out.reference = reference.description;
  out.energy_reference = reference.energy ? reference.energy_description : "";
  EnergyTrack& track = out.energy;
  if (options.energy_steps != 0 && reference.energy) {
    const std::size_t n = options.energy_steps;
    track.steps = n;
    track.t.resize(static_cast<Eigen::Index>(n + 1));
    track.reference_energy.resize(track.t.size());
    for (std::size_t k = 0; k <= n; ++k) {
      const auto r = static_cast<Eigen::Index>(k);
      track.t[r] = t0 + static_cast<double>(k) * (interval / static_cast<double>(n));
      track.reference_energy[r] = reference.energy(n, k, track.t[r]);
    }
    track.reference_dissipated = track.reference_energy[0] - track.reference_energy.array();
  }

  const std::size_t total = schemes.size() * steps.size();
  for (const std::string& scheme : schemes) {
    for (std::size_t n : steps) {
      ComparisonRow row;
      row.scheme = scheme;
      row.steps = n;
      row.h = interval / static_cast<double>(n);
      try {
        Solution best;
        for (int r = 0; r < options.repeat; ++r) {
          Solution s = run(scheme, n);
          if (r == 0 || s.wall_time_seconds < best.wall_time_seconds) best = std::move(s);
        }
        row.declared_order = best.declared_order;
        row.status = best.ok() ? "success" : std::string(to_string(best.status));
        row.message = best.message;
        row.wall_seconds = best.wall_time_seconds;
        row.newton_iterations = best.newton_iterations;
        if (best.ok()) measure(best, t0, reference, row);
        if (n == track.steps && track.steps != 0 && best.energy.size() > 0) {
          const Eigen::Index rows = track.t.size();
          Eigen::VectorXd e = Eigen::VectorXd::Constant(rows, ComparisonRow::kNaN);
          Eigen::VectorXd w = e;
          const Eigen::Index done = std::min(rows, best.energy.size());
          e.head(done) = best.energy.head(done);
          w.head(done) = best.dissipated.head(done);
          track.schemes.push_back(scheme);
          track.energy.push_back(std::move(e));
          track.dissipated.push_back(std::move(w));
        }
      } catch (const NotApplicable& e) {
        row.status = "not applicable";
        row.message = e.what();
      }
      out.rows.push_back(row);
      if (options.on_row) options.on_row(out.rows.back(), out.rows.size(), total);
    }
  }
  return out;
}

}  // namespace fracvi
