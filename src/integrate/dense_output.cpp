#include "fracvi/integrate/dense_output.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "fracvi/core/error.hpp"
#include "fracvi/expression/expression.hpp"

namespace fracvi {

void hermite_interpolate(double s, double h, const Eigen::Ref<const Eigen::VectorXd>& xa,
                         const Eigen::Ref<const Eigen::VectorXd>& va,
                         const Eigen::Ref<const Eigen::VectorXd>& xb,
                         const Eigen::Ref<const Eigen::VectorXd>& vb, Eigen::Ref<Eigen::VectorXd> x,
                         Eigen::Ref<Eigen::VectorXd> v) {
  if (s == 0.0) {
    x = xa;
    v = va;
    return;
  }
  if (s == 1.0) {
    x = xb;
    v = vb;
    return;
  }
  const double r = 1.0 - s;
  const double h00 = (1.0 + 2.0 * s) * r * r, h10 = s * r * r;
  const double h01 = s * s * (3.0 - 2.0 * s), h11 = s * s * (s - 1.0);
  // d/ds of the basis, divided by h for d/dt.
  const double d00 = 6.0 * s * (s - 1.0), d10 = r * (1.0 - 3.0 * s);
  const double d01 = -d00, d11 = s * (3.0 * s - 2.0);
  x = h00 * xa + (h * h10) * va + h01 * xb + (h * h11) * vb;
  v = (d00 / h) * xa + d10 * va + (d01 / h) * xb + d11 * vb;
}

void interpolate(const Solution& solution, double t, Eigen::Ref<Eigen::VectorXd> x,
                 Eigen::Ref<Eigen::VectorXd> v) {
  const Eigen::Index rows = solution.t.size();
  if (rows == 0 || !(t >= solution.t[0] && t <= solution.t[rows - 1])) {
    throw ValidationError(
        "sol(t) at t = " + format_number(t) + ": must be within the stored times [" +
        (rows == 0 ? std::string("none")
                   : format_number(solution.t[0]) + ", " + format_number(solution.t[rows - 1])) +
        "]");
  }
  // The last row whose time is <= t.
  const auto* begin = solution.t.data();
  const auto i = static_cast<Eigen::Index>(std::upper_bound(begin, begin + rows, t) - begin) - 1;
  if (t == solution.t[i]) {
    x = solution.x.row(i).transpose();
    v = solution.v.row(i).transpose();
    return;
  }
  const auto a = static_cast<std::size_t>(i);
  if (solution.step[a + 1] != solution.step[a] + 1) {
    throw ValidationError("sol(t) at t = " + format_number(t) +
                          ": the stored rows around it are "
                          "the steps " +
                          std::to_string(solution.step[a]) + " and " +
                          std::to_string(solution.step[a + 1]) +
                          ", not consecutive: dense output needs every step stored "
                          "(output.every = 1)");
  }
  const double ta = solution.t[i];
  const double h = solution.step_size > 0.0 ? solution.step_size : solution.t[i + 1] - ta;
  hermite_interpolate((t - ta) / h, h, solution.x.row(i).transpose(), solution.v.row(i).transpose(),
                      solution.x.row(i + 1).transpose(), solution.v.row(i + 1).transpose(), x, v);
}

Event formula_event(std::string name, std::string_view formula, Eigen::Index dimension,
                    EventDirection direction, bool terminal, const std::string& field) {
  std::vector<std::string> variables{"t"};
  for (Eigen::Index i = 1; i <= dimension; ++i) variables.push_back("x" + std::to_string(i));
  for (Eigen::Index i = 1; i <= dimension; ++i) variables.push_back("v" + std::to_string(i));
  Expression g;
  try {
    g = Expression::parse(formula, variables);
  } catch (const std::invalid_argument& e) {
    throw ValidationError(field + " = \"" + std::string(formula) +
                          "\": not a formula in t, x1..xd, v1..vd: " + e.what());
  }
  // Each copy of the function owns its argument buffer (one Integrator, one thread).
  std::vector<double> values(variables.size());
  Event event;
  event.name = std::move(name);
  event.direction = direction;
  event.terminal = terminal;
  event.function = [g = std::move(g), values = std::move(values)](
                       double t, const Eigen::Ref<const Eigen::VectorXd>& x,
                       const Eigen::Ref<const Eigen::VectorXd>& v) mutable {
    const std::size_t d = (values.size() - 1) / 2;
    values[0] = t;
    for (std::size_t i = 0; i < d; ++i) {
      values[1 + i] = x[static_cast<Eigen::Index>(i)];
      values[1 + d + i] = v[static_cast<Eigen::Index>(i)];
    }
    return g(values);
  };
  return event;
}

void validate_output(const std::vector<double>& output_times, const std::vector<Event>& events,
                     double t0, double t_end) {
  for (std::size_t i = 0; i < output_times.size(); ++i) {
    const double t = output_times[i];
    const std::string field = "output.times[" + std::to_string(i) + "] = " + format_number(t);
    if (!(t >= t0 && t <= t_end)) {
      throw ValidationError(field + " must be within [time.start, time.end] = [" +
                            format_number(t0) + ", " + format_number(t_end) + "]");
    }
    if (i > 0 && !(t >= output_times[i - 1])) {
      throw ValidationError(field + " is smaller than output.times[" + std::to_string(i - 1) +
                            "] = " + format_number(output_times[i - 1]) +
                            ": the times must be ascending");
    }
  }
  std::set<std::string> names;
  for (std::size_t i = 0; i < events.size(); ++i) {
    const Event& e = events[i];
    const std::string field = "events[" + std::to_string(i) + "]";
    if (e.name.empty()) throw ValidationError(field + ".name is empty: each event needs a name");
    if (!names.insert(e.name).second) {
      throw ValidationError(field + ".name = \"" + e.name +
                            "\" is the name of an earlier event: names must be distinct");
    }
    if (!e.function) throw ValidationError(field + " (\"" + e.name + "\") has no function g");
    if (!parse_event_direction(to_string(e.direction))) {
      throw ValidationError(field + ".direction has an unknown value");
    }
  }
}

}  // namespace fracvi
