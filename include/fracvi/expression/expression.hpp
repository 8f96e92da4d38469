// Formulas from problem files: potentials U(x, t), forces f(t), Lagrangians.
//
// A problem file gives U as text; the integrator needs U, ∇U and the Hessian ∇²U at every Newton
// iteration of every step (`DiscEqs`). DESIGN §4 rules out finite differences in the solver path,
// so the text is parsed once into a hash-consed DAG (identical subexpressions are one node), the
// derivatives are built symbolically on that DAG with light simplification (the gradient by one
// reverse sweep, Hessian columns by forward sweeps over it), and value + gradient + Hessian are
// compiled into one straight-line tape whose common subexpressions are computed once.
// Evaluating the tape writes into a caller-owned Workspace and never allocates.
//
// Cost (bench/expression_bench.cpp): an interpreted tape, about 10 ns per call plus 1–3 ns per
// instruction; 2–25× a hand-written C++ function (the ratio is small when sin/cos/exp dominate).
// Potentials compiled into a program should be templated functors with automatic
// differentiation instead (DESIGN §4).
//
// Grammar (whitespace allowed anywhere between tokens):
//   expr    := term (('+' | '-') term)*
//   term    := unary (('*' | '/') unary)*
//   unary   := ('+' | '-') unary | power
//   power   := primary ('^' unary)?          right-associative; -x^2 = -(x^2), x^-2 = x^(-2)
//   primary := number | name | name '(' expr (',' expr)* ')' | '(' expr ')'
// Numbers use C notation: 123, 1.5, .5, 5., 1e-3, 1E+3, 0x1F, 0x1.8p1 (no suffixes; a
// leading-zero integer such as 017 is rejected because C would read it as octal). The constant
// constants `pi` and `e` and the functions sin cos tan exp log sqrt abs sign sinh cosh tanh atan
// floor heaviside and pow(a, b) min(a, b) max(a, b) atan2(y, x) are built in. Derivatives at
// kinks and jumps (docs/problem-file.md, "Formulas"): abs' = sign (0 at 0); sign, floor and
// heaviside (1/2 at 0) have derivative 0 (their jumps are not seen); min and max take the
// derivative of the selected argument and the mean of the two at a tie; atan2(y, x)' =
// (x y' − y x')/(x² + y²).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <initializer_list>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace fracvi {

namespace internal {
struct ExpressionData;
struct Program;
struct Instruction;
}  // namespace internal

/// A formula that could not be parsed. what() is a multi-line message: the reason, the
/// expression, and a caret under the offending column, e.g.
///
///     unknown variable 'x3' (known: t, x1, x2)
///       1 - cos(x3)
///               ^
class ExpressionError : public std::invalid_argument {
 public:
  ExpressionError(std::string reason, std::string expression, std::size_t column);

  /// The first line of what(), without the expression and caret.
  const std::string& reason() const { return reason_; }
  const std::string& expression() const { return expression_; }
  /// 0-based byte offset into expression() (expression().size() for "unexpected end").
  std::size_t column() const { return column_; }

 private:
  std::string reason_;
  std::string expression_;
  std::size_t column_;
};

/// One term c·(v − origin)^γ of Expression::power_laws.
struct PowerLaw {
  double exponent = 0.0;     ///< γ
  double coefficient = 0.0;  ///< c
};

/// An immutable scalar formula in a fixed, ordered list of variables. Cheap to copy (shared
/// state); all const members are safe to call concurrently.
class Expression {
 public:
  /// The constant 0 with no variables.
  Expression();

  /// Parses `text`. Only the given variable names may appear; they must be identifiers, distinct,
  /// and must not shadow `pi` or a function name (std::invalid_argument otherwise). Malformed
  /// text, unknown names, wrong argument counts, a division by something that simplifies to 0
  /// and a constant subexpression that is not finite (log(0), 1e400) throw ExpressionError.
  static Expression parse(std::string_view text, std::vector<std::string> variables);

  /// The value at `values` (one per variable, in the order of variables()). Does not allocate
  /// after the first call on a thread (uses a thread-local scratch buffer).
  double operator()(std::span<const double> values) const;
  double operator()(std::initializer_list<double> values) const {
    return (*this)(std::span<const double>(values.begin(), values.size()));
  }

  /// The exact partial derivative with respect to variables()[var], simplified. Differentiating
  /// abs gives sign; sign is treated as piecewise constant (derivative 0).
  Expression derivative(std::size_t var) const;
  /// Same, by name (std::invalid_argument if the name is not a variable).
  Expression derivative(std::string_view variable) const;

  /// Parseable text with minimal parentheses; parse(to_string()) evaluates bitwise like this
  /// expression. Shared subexpressions are written out in full, so the text of a high-order
  /// derivative can be long.
  std::string to_string() const;
  /// The text this expression was parsed from ("" for derivatives).
  const std::string& text() const;

  const std::vector<std::string>& variables() const;
  std::optional<std::size_t> variable_index(std::string_view name) const;
  /// Structural dependence after simplification (x - x does not depend on x).
  bool depends_on(std::size_t var) const;
  bool is_constant() const;

  /// An upper bound on the total degree if the expression is structurally a polynomial in all
  /// variables; nullopt otherwise (sin(x), 1/x, x^0.5, x^-1). (x+1)^2 - x^2 reports 2.
  std::optional<int> polynomial_degree() const;
  /// The same, treating every variable not in `vars` as a coefficient: U = x^2/2 - sin(t)*x has
  /// degree 2 in {x} (a linear equation of motion with a time-dependent force) and none in {x, t}.
  std::optional<int> polynomial_degree(std::span<const std::size_t> vars) const;
  bool is_polynomial_of_degree_at_most(int degree) const;
  /// True when a function whose derivative jumps — abs, sign, min, max, floor, heaviside — is
  /// applied to something that depends on one of `vars`: the expression may have kinks (or jumps)
  /// in them. Structural: abs(x)^2 counts, although its derivative is continuous.
  bool has_kinks_in(std::span<const std::size_t> vars) const;

  /// The expression as a finite sum Σ_j c_j (v − origin)^{γ_j} of power laws in the variable
  /// v = variables()[var] (no other variable may appear), γ_j real and increasing, c_j ≠ 0 (0: no
  /// term); nullopt when it is not one. Recognised: constants, v, sums, differences, products,
  /// integer powers (sums expanded, up to 64 terms), quotients by one term, and constant powers and
  /// sqrt of one term (a negative coefficient only to an integer power). So t^3 + 6*t +
  /// 16/(5*sqrt(pi))*t^2.5 at origin 0 and (t - 1)^1.5 at origin 1 are sums of power laws;
  /// t^1.5 at origin 1, (1 + t)^0.5, sin(t) and abs(t) are not (method.split = "series" folds a
  /// power-law forcing into its fractional series, docs/theory/fvi_lobatto.md §13.5).
  std::optional<std::vector<PowerLaw>> power_laws(std::size_t var, double origin) const;

  /// Number of DAG nodes (a size diagnostic).
  std::size_t node_count() const;

 private:
  explicit Expression(std::shared_ptr<const internal::ExpressionData> data);
  std::shared_ptr<const internal::ExpressionData> data_;
  friend class CompiledDerivatives;
};

/// Parses several formulas over the same variables, e.g. a force {"sin(t)", "0"}. An error's
/// reason() names the component ("component 2 of 2: ...").
std::vector<Expression> parse_expressions(std::span<const std::string> texts,
                                          const std::vector<std::string>& variables);

/// One structurally nonzero entry of the upper triangle of a Hessian (row <= col), in gradient
/// coordinates (positions in CompiledDerivatives::wrt()).
struct HessianEntry {
  std::size_t row;
  std::size_t col;
  friend bool operator==(const HessianEntry&, const HessianEntry&) = default;
};

/// Value, gradient and Hessian of an Expression compiled into one straight-line tape.
///
/// Derivatives are taken with respect to a chosen subset of the variables (typically the
/// positions x1..xd of U(x, t), not t); `values` passed to evaluate always holds every variable.
/// Structurally zero gradient entries and Hessian entries are known at compile time:
/// gradient_pattern() and hessian_pattern() (upper triangle), so a chain of d springs has O(d)
/// Hessian entries and evaluation costs O(d).
///
/// Thread-compatibility: the const members, each used with its own Workspace, may run
/// concurrently. The overloads without a Workspace use one owned by the object and are
/// non-const.
class CompiledDerivatives {
 public:
  /// Scratch memory for one evaluation at a time. Created by make_workspace(); holds the tape's
  /// constants, so it belongs to the object that made it (checked).
  class Workspace {
   public:
    Workspace() = default;
    /// The variables' own slots (num_variables() of them): values written here and passed
    /// back to evaluate() or gradient() are not copied again (ExpressionPotential fills them
    /// directly: its formula is evaluated several times per step).
    std::span<double> values() { return {slots_.data(), variables_}; }

   private:
    friend class CompiledDerivatives;
    std::size_t variables_ = 0;
    std::vector<double> slots_;
    const internal::Program* owner_ = nullptr;
  };

  /// With respect to all variables.
  explicit CompiledDerivatives(const Expression& f);
  /// With respect to variables()[wrt[k]], k = 0..wrt.size()-1 (distinct, in range).
  CompiledDerivatives(const Expression& f, std::vector<std::size_t> wrt);

  const Expression& expression() const { return f_; }
  std::size_t num_variables() const { return f_.variables().size(); }
  /// Gradient coordinate k is the derivative with respect to variables()[wrt()[k]].
  const std::vector<std::size_t>& wrt() const { return wrt_; }
  std::size_t gradient_size() const { return wrt_.size(); }
  /// Gradient coordinates that are not identically zero, ascending.
  const std::vector<std::size_t>& gradient_pattern() const { return gradient_pattern_; }
  /// Upper-triangle Hessian entries that are not identically zero, sorted by (row, col).
  const std::vector<HessianEntry>& hessian_pattern() const { return hessian_pattern_; }
  /// True when every Hessian entry simplified to a constant and U is a polynomial in wrt() (so
  /// quadratic, with second-order coefficients independent of the other variables too): Newton
  /// converges in one iteration. False for piecewise-linear U such as abs(x1) or max(x1, 0),
  /// whose Hessian is 0 wherever it exists but whose gradient jumps.
  bool hessian_is_constant() const { return hessian_is_constant_; }
  /// Number of tape instructions for value + gradient + Hessian (a cost diagnostic).
  std::size_t tape_size() const;

  Workspace make_workspace() const;

  /// Value only.
  double evaluate(std::span<const double> values, Workspace& ws) const;
  /// Value and dense gradient (size gradient_size(); structural zeros are written as 0).
  double evaluate(std::span<const double> values, std::span<double> gradient, Workspace& ws) const;
  /// Dense gradient only: the value's own instructions are skipped (the same gradient, bit for
  /// bit, as the overload above).
  void gradient(std::span<const double> values, std::span<double> gradient, Workspace& ws) const;
  /// Value, dense gradient, and the Hessian entries in the order of hessian_pattern().
  double evaluate(std::span<const double> values, std::span<double> gradient,
                  std::span<double> hessian_values, Workspace& ws) const;
  /// Value, dense gradient, and the full symmetric dense Hessian (gradient_size() squared).
  double evaluate_dense(std::span<const double> values, std::span<double> gradient,
                        Eigen::Ref<Eigen::MatrixXd> hessian, Workspace& ws) const;

  /// The same with the object's own workspace (not thread-safe).
  double evaluate(std::span<const double> values) { return evaluate(values, workspace_); }
  double evaluate(std::span<const double> values, std::span<double> gradient) {
    return evaluate(values, gradient, workspace_);
  }
  double evaluate(std::span<const double> values, std::span<double> gradient,
                  std::span<double> hessian_values) {
    return evaluate(values, gradient, hessian_values, workspace_);
  }
  double evaluate_dense(std::span<const double> values, std::span<double> gradient,
                        Eigen::Ref<Eigen::MatrixXd> hessian) {
    return evaluate_dense(values, gradient, hessian, workspace_);
  }

 private:
  // Inline: at d = 1 the call cost as much as the tape it guards (a formula is evaluated several
  // times per step); the messages are built out of line.
  void check(std::span<const double> values, const Workspace& ws) const {
    if (values.size() != tape_variables_ || ws.owner_ != program_.get()) [[unlikely]] {
      throw_mismatch(values.size());
    }
  }
  // The exception check() throws: a wrong number of values, else a workspace of another object.
  [[noreturn]] void throw_mismatch(std::size_t values) const;
  // Runs `code` (which computes the gradient) and copies the gradient out; returns the slots.
  const double* run_gradient(std::span<const internal::Instruction> code,
                             std::span<const double> values, std::span<double> gradient,
                             Workspace& ws) const;

  Expression f_;
  std::vector<std::size_t> wrt_;
  std::vector<std::size_t> gradient_pattern_;
  std::vector<HessianEntry> hessian_pattern_;
  bool hessian_is_constant_ = true;
  std::shared_ptr<const internal::Program> program_;
  std::size_t tape_variables_ = 0;  // program_->num_variables, for the inline check()
  Workspace workspace_;
};

}  // namespace fracvi
