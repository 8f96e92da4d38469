#include "fracvi/fractional/convolution_quadrature.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "fracvi/core/error.hpp"

namespace fracvi {

namespace {

std::vector<double> drop_first(std::vector<double> w, std::size_t lag) {
  w.erase(w.begin(), w.begin() + static_cast<std::ptrdiff_t>(std::min(lag, w.size())));
  return w;
}

}  // namespace

std::vector<double> ConvolutionQuadrature::weights(std::size_t count) const {
  if (lag == 0) return cq_weights(scheme, order, count);
  return drop_first(cq_weights(scheme, order, count + lag), lag);
}

bool ConvolutionQuadrature::is_local() const {
  return scheme != CqScheme::kTrapezoidal && (order == 0.0 || order == 1.0 || order == 2.0);
}

std::vector<double> ConvolutionQuadrature::local_weights() const {
  if (!is_local()) {
    throw std::invalid_argument("ConvolutionQuadrature::local_weights: " + describe() +
                                " has no terminating weights");
  }
  const std::vector<double> delta = scheme == CqScheme::kGrunwaldLetnikov
                                        ? std::vector<double>{1.0, -1.0}
                                        : std::vector<double>{1.5, -2.0, 0.5};
  std::vector<double> power{1.0};
  for (int p = 0; p < static_cast<int>(order); ++p) {  // power ← power · δ (exact: dyadic)
    std::vector<double> next(power.size() + delta.size() - 1, 0.0);
    for (std::size_t i = 0; i < power.size(); ++i)
      for (std::size_t j = 0; j < delta.size(); ++j) next[i + j] += power[i] * delta[j];
    power = std::move(next);
  }
  return drop_first(std::move(power), lag);
}

double ConvolutionQuadrature::symbol_at_minus_one() const {
  // |ζ^lag| = 1 on the unit circle: the lag does not change the magnitude.
  switch (scheme) {
    case CqScheme::kGrunwaldLetnikov: return std::pow(2.0, order);
    case CqScheme::kBdf2: return std::pow(4.0, order);
    case CqScheme::kTrapezoidal:
      return order == 0.0 ? 1.0 : std::numeric_limits<double>::infinity();
  }
  return std::numeric_limits<double>::quiet_NaN();
}

std::string ConvolutionQuadrature::describe() const {
  std::string text = std::string(to_string(scheme)) + " CQ of order " + format_number(order);
  if (lag != 0) text += " from lag " + std::to_string(lag);
  return text;
}

}  // namespace fracvi
