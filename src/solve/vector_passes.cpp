#include "fracvi/solve/vector_passes.hpp"

namespace fracvi::internal::kernels {

// Each kernel is its loop (vector_passes.hpp) in a function with an x86-64-v3 clone.

FRACVI_HOT_KERNEL
bool add_and_check(const double* a, const double* b, double* out, Eigen::Index n) {
  return loops::add_and_check<true>(a, b, out, n);
}

FRACVI_HOT_KERNEL
bool diagonal_residual(const double* m, const double* increment, double s, const double* g,
                       const double* c, double* out, Eigen::Index n) {
  return loops::diagonal_residual<true>(m, increment, s, g, c, out, n);
}

FRACVI_HOT_KERNEL
bool general_residual(double s, const double* g, const double* c, double* out, Eigen::Index n) {
  return loops::general_residual<true>(s, g, c, out, n);
}

FRACVI_HOT_KERNEL
CorrectionPass apply_correction(const double* delta, const double* a, double* increment,
                                double* mid, Eigen::Index n, bool with_next) {
  return loops::apply_correction<true>(delta, a, increment, mid, n, with_next);
}

FRACVI_HOT_KERNEL
bool all_finite(const double* v, Eigen::Index n) {
  return loops::all_finite<true>(v, n);
}

FRACVI_HOT_KERNEL
double midpoint(const double* a, const double* increment, double* out, Eigen::Index n,
                bool with_scale) {
  return loops::midpoint<true>(a, increment, out, n, with_scale);
}

FRACVI_HOT_KERNEL
void start_momentum(const double* p, const double* force, double impulse, double h, double* p_plus,
                    double* rhs, Eigen::Index n) {
  loops::start_momentum<true>(p, force, impulse, h, p_plus, rhs, n);
}

FRACVI_HOT_KERNEL
void scale_and_subtract(double s, const double* b, double* a, Eigen::Index n) {
  loops::scale_and_subtract<true>(s, b, a, n);
}

FRACVI_HOT_KERNEL
void subtract_scaled(const double* a, double s, const double* b, double* out, Eigen::Index n) {
  loops::subtract_scaled<true>(a, s, b, out, n);
}

FRACVI_HOT_KERNEL
void shifted(const double* x, const double* x0, double t, const double* v0, double* out,
             Eigen::Index n) {
  loops::shifted<true>(x, x0, t, v0, out, n);
}

FRACVI_HOT_KERNEL
bool new_position(const double* m, bool unit_mass, const double* increment, double s,
                  const double* p_plus, const double* a, const double* x0, double t,
                  const double* v0, double* p_minus, double* next, double* tilde,
                  const double* root_mass, double* squares, Eigen::Index n) {
  return loops::new_position<true>(m, unit_mass, increment, s, p_plus, a, x0, t, v0, p_minus, next,
                                   tilde, root_mass, squares, n);
}

FRACVI_HOT_KERNEL
MomentumPass new_momentum(const double* r, const double* sum, const double* p_minus, double c,
                          const double* m, bool unit_mass, double* force, double* p, double* v,
                          double* w, bool with_dots, Eigen::Index n) {
  return loops::new_momentum<true>(r, sum, p_minus, c, m, unit_mass, force, p, v, w, with_dots, n);
}

FRACVI_HOT_KERNEL
void trapezoid_known(const double* r, const double* x, const double* x0, double t, const double* v0,
                     double w, const double* sum, const double* g_poly, const double* g_poly_prev,
                     const double* q, double h, double* mid_tilde, double* rhs, Eigen::Index n) {
  loops::trapezoid_known<true>(r, x, x0, t, v0, w, sum, g_poly, g_poly_prev, q, h, mid_tilde, rhs,
                               n);
}

FRACVI_HOT_KERNEL
TrapezoidPass trapezoid_step(const double* m, bool unit_mass, const double* r, const double* a,
                             const double* increment, double s, double w, const double* sum,
                             const double* g_poly, const double* g_poly_prev, double h,
                             double* next, double* q, double* mid_tilde, double* g_tilde,
                             double* g_total, double* p, double* v, bool with_work,
                             Eigen::Index n) {
  return loops::trapezoid_step<true>(m, unit_mass, r, a, increment, s, w, sum, g_poly, g_poly_prev,
                                     h, next, q, mid_tilde, g_tilde, g_total, p, v, with_work, n);
}

FRACVI_HOT_KERNEL
double dot(const double* a, const double* b, Eigen::Index n) {
  return loops::dot<true>(a, b, n);
}

FRACVI_HOT_KERNEL
double weighted_squares(const double* w, const double* x, Eigen::Index n) {
  return loops::weighted_squares<true>(w, x, n);
}

}  // namespace fracvi::internal::kernels
