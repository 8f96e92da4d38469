// Recursive-descent parser for formulas (grammar in include/fracvi/expression/expression.hpp)
// and its error messages.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <numbers>
#include <optional>
#include <unordered_map>
#include <unordered_set>

#include "graph.hpp"

namespace fracvi {

namespace {

bool is_continuation_byte(char c) {
  return (static_cast<unsigned char>(c) & 0xC0U) == 0x80U;
}

// The reason, then the expression (a window around the column if it is long) and a caret.
std::string format_message(const std::string& reason, std::string_view expr, std::size_t column) {
  constexpr std::size_t kContext = 60;
  column = std::min(column, expr.size());
  std::size_t begin = 0, end = expr.size();
  std::string line;
  if (expr.size() > 2 * kContext + 20) {
    if (column > kContext) {
      begin = column - kContext;
      while (begin < column && is_continuation_byte(expr[begin])) ++begin;
      line = "...";
    }
    if (column + kContext < expr.size()) {
      end = column + kContext;
      while (end < expr.size() && is_continuation_byte(expr[end])) ++end;
    }
  }
  const std::size_t caret = line.size() + static_cast<std::size_t>(std::count_if(
                                              expr.begin() + static_cast<std::ptrdiff_t>(begin),
                                              expr.begin() + static_cast<std::ptrdiff_t>(column),
                                              [](char c) { return !is_continuation_byte(c); }));
  for (char c : expr.substr(begin, end - begin))
    line += (c == '\n' || c == '\r' || c == '\t' || c == '\v' || c == '\f') ? ' ' : c;
  if (end < expr.size()) line += "...";
  return reason + "\n  " + line + "\n  " + std::string(caret, ' ') + "^";
}

}  // namespace

ExpressionError::ExpressionError(std::string reason, std::string expression, std::size_t column)
    : std::invalid_argument(format_message(reason, expression, column)),
      reason_(std::move(reason)),
      expression_(std::move(expression)),
      column_(column) {}

namespace internal {

namespace {

constexpr int kMaxNesting = 200;  // bounds the parser's recursion depth

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v';
}
bool is_digit(char c) {
  return c >= '0' && c <= '9';
}
bool is_alpha(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
}
bool is_alnum(char c) {
  return is_alpha(c) || is_digit(c);
}

bool is_identifier(std::string_view s) {
  return !s.empty() && is_alpha(s[0]) && std::all_of(s.begin(), s.end(), is_alnum);
}

// Optimal string alignment distance (Levenshtein plus adjacent transpositions: "sni" -> "sin"
// is one edit), case-insensitive.
std::size_t edit_distance(std::string_view a, std::string_view b) {
  const auto lower = [](char c) { return (c >= 'A' && c <= 'Z') ? static_cast<char>(c + 32) : c; };
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::size_t> d((n + 1) * (m + 1));
  const auto at = [&](std::size_t i, std::size_t j) -> std::size_t& { return d[i * (m + 1) + j]; };
  for (std::size_t i = 0; i <= n; ++i) at(i, 0) = i;
  for (std::size_t j = 0; j <= m; ++j) at(0, j) = j;
  for (std::size_t i = 1; i <= n; ++i) {
    for (std::size_t j = 1; j <= m; ++j) {
      const std::size_t cost = lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1;
      at(i, j) = std::min({at(i - 1, j) + 1, at(i, j - 1) + 1, at(i - 1, j - 1) + cost});
      if (i > 1 && j > 1 && lower(a[i - 1]) == lower(b[j - 2]) &&
          lower(a[i - 2]) == lower(b[j - 1]))
        at(i, j) = std::min(at(i, j), at(i - 2, j - 2) + 1);
    }
  }
  return at(n, m);
}

// The unique nearest candidate if it is close (1 edit for names up to 3 characters, else 2);
// no suggestion when two candidates tie ("x3" among x1, x2).
std::optional<std::string> nearest(std::string_view name, const std::vector<std::string>& names) {
  const std::size_t limit = name.size() <= 3 ? 1 : 2;
  std::size_t best = limit + 1, count = 0;
  const std::string* best_name = nullptr;
  for (const std::string& candidate : names) {
    const std::size_t dist = edit_distance(name, candidate);
    if (dist < best) {
      best = dist;
      count = 1;
      best_name = &candidate;
    } else if (dist == best) {
      ++count;
    }
  }
  if (best_name == nullptr || count != 1) return std::nullopt;
  return *best_name;
}

std::string join(const std::vector<std::string>& names, std::size_t max_listed = 12) {
  std::string out;
  for (std::size_t i = 0; i < names.size() && i < max_listed; ++i)
    out += (i ? ", " : "") + names[i];
  if (names.size() > max_listed) out += ", ... (" + std::to_string(names.size()) + " in total)";
  return out;
}

enum class Tok {
  kNumber,
  kName,
  kPlus,
  kMinus,
  kStar,
  kSlash,
  kCaret,
  kLParen,
  kRParen,
  kComma,
  kEnd
};

struct Token {
  Tok kind = Tok::kEnd;
  std::size_t begin = 0, end = 0;
  double number = 0.0;
};

class Parser {
 public:
  Parser(std::string_view text, const std::vector<std::string>& variables, Builder& builder)
      : text_(text), variables_(variables), builder_(builder) {
    index_.reserve(variables.size());
    for (std::size_t i = 0; i < variables.size(); ++i) index_.emplace(variables[i], i);
  }

  NodeId parse_all() {
    advance();
    if (tok_.kind == Tok::kEnd) fail("empty expression", 0);
    const NodeId root = expr();
    if (tok_.kind == Tok::kRParen) fail("unmatched ')'", tok_.begin);
    if (tok_.kind != Tok::kEnd) {
      const bool operand =
          tok_.kind == Tok::kNumber || tok_.kind == Tok::kName || tok_.kind == Tok::kLParen;
      fail("unexpected " + quote(tok_) + " after a complete expression" +
               (operand ? " (missing an operator such as '*'?)" : ""),
           tok_.begin);
    }
    return root;
  }

 private:
  [[noreturn]] void fail(std::string reason, std::size_t column) const {
    throw ExpressionError(std::move(reason), std::string(text_), column);
  }

  std::string quote(const Token& t) const {
    if (t.kind == Tok::kEnd) return "end of expression";
    std::string s(1, '\'');  // built by appending: GCC 12 warns (-Wrestrict) on "'" + string
    s.append(text_.substr(t.begin, t.end - t.begin));
    s += '\'';
    return s;
  }

  // A constant subexpression that is not finite (1e308*10, log(0), 0^-1, sqrt(-1)) is almost
  // certainly a mistake, and would poison every evaluation; say so where it happens.
  NodeId finite(NodeId id, std::size_t column) const {
    const Node& n = builder_.node(id);
    if (n.op == Op::kConst && !std::isfinite(n.value))
      fail(std::string("constant subexpression evaluates to ") +
               (std::isnan(n.value) ? "NaN" : (n.value > 0 ? "inf" : "-inf")),
           column);
    return id;
  }

  void advance() {
    std::size_t i = tok_.end;
    while (i < text_.size() && is_space(text_[i])) ++i;
    tok_ = Token{Tok::kEnd, i, i, 0.0};
    if (i == text_.size()) return;
    const char c = text_[i];
    if (is_digit(c) || (c == '.' && i + 1 < text_.size() && is_digit(text_[i + 1]))) {
      lex_number(i);
      return;
    }
    if (is_alpha(c)) {
      std::size_t j = i;
      while (j < text_.size() && is_alnum(text_[j])) ++j;
      tok_ = Token{Tok::kName, i, j, 0.0};
      return;
    }
    tok_.end = i + 1;
    switch (c) {
      case '+': tok_.kind = Tok::kPlus; return;
      case '-': tok_.kind = Tok::kMinus; return;
      case '*': tok_.kind = Tok::kStar; return;
      case '/': tok_.kind = Tok::kSlash; return;
      case '^': tok_.kind = Tok::kCaret; return;
      case '(': tok_.kind = Tok::kLParen; return;
      case ')': tok_.kind = Tok::kRParen; return;
      case ',': tok_.kind = Tok::kComma; return;
      default: break;
    }
    const std::string_view rest = text_.substr(i);
    if (static_cast<unsigned char>(c) >= 0x80) {
      std::string hint;  // look-alikes pasted from papers
      if (rest.starts_with("\u2212")) hint = " (a Unicode minus sign; use '-')";
      if (rest.starts_with("\u00d7") || rest.starts_with("\u00b7") || rest.starts_with("\u22c5"))
        hint = " (use '*' for products)";
      fail("unexpected non-ASCII character" + hint, i);
    }
    fail(std::string("unexpected character '") + c + "'" + (c == '[' ? " (use parentheses)" : ""),
         i);
  }

  // C-like literals. The token is the maximal run of [0-9A-Za-z_.] (plus a sign right after an
  // exponent letter) so that "2x" or "1.5f" is one malformed token rather than a confusing
  // parse; std::from_chars (locale-independent) must consume all of it.
  void lex_number(std::size_t i) {
    const bool hex =
        text_[i] == '0' && i + 1 < text_.size() && (text_[i + 1] == 'x' || text_[i + 1] == 'X');
    std::size_t j = i;
    while (j < text_.size()) {
      const char c = text_[j];
      if (is_alnum(c) || c == '.') {
        ++j;
      } else if ((c == '+' || c == '-') && j > i &&
                 (hex ? (text_[j - 1] == 'p' || text_[j - 1] == 'P')
                      : (text_[j - 1] == 'e' || text_[j - 1] == 'E'))) {
        ++j;
      } else {
        break;
      }
    }
    const std::string_view token = text_.substr(i, j - i);
    const std::string_view body = hex ? token.substr(2) : token;
    double value = 0.0;
    const char* first = body.data();
    const char* last = body.data() + body.size();
    std::from_chars_result r{first, std::errc::invalid_argument};
    const bool body_ok = !body.empty() && (body[0] == '.' ||
                                           std::isxdigit(static_cast<unsigned char>(body[0])) != 0);
    if (body_ok) {
      r = std::from_chars(first, last, value,
                          hex ? std::chars_format::hex : std::chars_format::general);
    }
    if (r.ec == std::errc::result_out_of_range)
      fail("number '" + std::string(token) + "' is out of the range of double", i);
    if (r.ec != std::errc() || r.ptr != last) {
      std::string hint;
      const std::string_view head(first, r.ptr), tail(r.ptr, last);
      if (r.ec == std::errc() && is_alpha(tail[0]) && tail[0] != '_' &&
          std::all_of(tail.begin(), tail.end(), is_alnum)) {
        if (tail.find_first_not_of("fFlLuU") == std::string_view::npos)
          hint = " (C suffixes such as '" + std::string(tail) + "' are not supported)";
        else
          hint = " (for a product write '" + std::string(hex ? "0x" : "") + std::string(head) +
                 "*" + std::string(tail) + "')";
      }
      fail("malformed number '" + std::string(token) + "'" + hint, i);
    }
    if (!hex && token.size() > 1 && token[0] == '0' &&
        token.find_first_not_of("0123456789") == std::string_view::npos)
      fail("integer literal '" + std::string(token) +
               "' has a leading zero (C would read it as octal); write it without",
           i);
    tok_ = Token{Tok::kNumber, i, j, value};
  }

  NodeId expr() {
    NodeId lhs = term();
    while (tok_.kind == Tok::kPlus || tok_.kind == Tok::kMinus) {
      const Token op = tok_;
      advance();
      const NodeId rhs = term();
      lhs =
          finite(op.kind == Tok::kPlus ? builder_.add(lhs, rhs) : builder_.sub(lhs, rhs), op.begin);
    }
    return lhs;
  }

  NodeId term() {
    NodeId lhs = unary();
    while (tok_.kind == Tok::kStar || tok_.kind == Tok::kSlash) {
      const Token op = tok_;
      advance();
      const NodeId rhs = unary();
      if (op.kind == Tok::kSlash && builder_.is_constant(rhs, 0.0))
        fail("division by zero", op.begin);
      lhs =
          finite(op.kind == Tok::kStar ? builder_.mul(lhs, rhs) : builder_.div(lhs, rhs), op.begin);
    }
    return lhs;
  }

  NodeId unary() {
    if (tok_.kind != Tok::kPlus && tok_.kind != Tok::kMinus) return power();
    const Token op = tok_;
    if (++depth_ > kMaxNesting) fail("expression nested too deeply", op.begin);
    advance();
    const NodeId operand = unary();
    --depth_;
    return op.kind == Tok::kMinus ? builder_.neg(operand) : operand;
  }

  NodeId power() {
    const NodeId base = primary();
    if (tok_.kind != Tok::kCaret) return base;
    const Token op = tok_;
    if (++depth_ > kMaxNesting) fail("expression nested too deeply", op.begin);
    advance();
    const NodeId exponent = unary();  // right-associative, and x^-2 is allowed
    --depth_;
    return finite(builder_.pow(base, exponent), op.begin);
  }

  NodeId primary() {
    const Token t = tok_;
    switch (t.kind) {
      case Tok::kNumber: advance(); return builder_.constant(t.number);
      case Tok::kName: return name();
      case Tok::kLParen: {
        if (++depth_ > kMaxNesting) fail("expression nested too deeply", t.begin);
        advance();
        const NodeId inner = expr();
        --depth_;
        if (tok_.kind != Tok::kRParen) {
          fail(tok_.kind == Tok::kEnd
                   ? "missing ')' to close '(' at column " + std::to_string(t.begin)
                   : "expected ')' to close '(' at column " + std::to_string(t.begin) +
                         " but found " + quote(tok_),
               tok_.begin);
        }
        advance();
        return inner;
      }
      default: break;
    }
    const std::string expected = "expected a number, a variable, a function call or '('";
    if (t.kind == Tok::kEnd) fail("unexpected end of expression; " + expected, t.begin);
    const bool double_star = t.kind == Tok::kStar && t.begin > 0 && text_[t.begin - 1] == '*';
    fail("unexpected " + quote(t) + "; " + expected + (double_star ? " (use '^' for powers)" : ""),
         t.begin);
  }

  NodeId name() {
    const Token t = tok_;
    const std::string_view id = text_.substr(t.begin, t.end - t.begin);
    advance();
    const auto var = index_.find(id);
    if (tok_.kind == Tok::kLParen) return call(t, id, var != index_.end());
    if (var != index_.end()) return builder_.variable(var->second);
    if (id == "pi") return builder_.constant(std::numbers::pi);
    if (id == "e") return builder_.constant(std::numbers::e);
    if (const Op op = function_by_name(id); op != Op::kConst)
      fail("function '" + std::string(id) + "' needs an argument list, e.g. " + std::string(id) +
               (is_binary(op) ? "(x, 2)" : "(x)"),
           t.begin);
    std::string reason =
        "unknown variable '" + std::string(id) + "' (" +
        (variables_.empty() ? "no variables are defined" : "known: " + join(variables_)) + ")";
    if (auto s = nearest(id, variables_)) reason += "; did you mean '" + *s + "'?";
    fail(reason, t.begin);
  }

  NodeId call(const Token& t, std::string_view id, bool is_variable) {
    const Op op = function_by_name(id);
    if (op == Op::kConst) {
      if (is_variable || id == "pi" || id == "e")
        fail("'" + std::string(id) + "' is a " + (is_variable ? "variable" : "constant") +
                 ", not a function (missing '*' before '('?)",
             t.begin);
      std::string reason = "unknown function '" + std::string(id) + "'";
      if (auto s = nearest(id, function_names())) reason += "; did you mean '" + *s + "'?";
      fail(reason + " (functions: " + join(function_names(), function_names().size()) + ")",
           t.begin);
    }
    const Token open = tok_;
    if (++depth_ > kMaxNesting) fail("expression nested too deeply", open.begin);
    advance();
    std::vector<NodeId> args;
    if (tok_.kind != Tok::kRParen) {
      args.push_back(expr());
      while (tok_.kind == Tok::kComma) {
        advance();
        args.push_back(expr());
      }
    }
    --depth_;
    if (tok_.kind != Tok::kRParen) {
      fail(tok_.kind == Tok::kEnd ? "missing ')' to close the call of '" + std::string(id) +
                                        "' opened at column " + std::to_string(open.begin)
                                  : "expected ',' or ')' in the call of '" + std::string(id) +
                                        "' but found " + quote(tok_),
           tok_.begin);
    }
    advance();
    const std::size_t arity = is_binary(op) ? 2 : 1;
    if (args.size() != arity)
      fail("function '" + std::string(id) + "' takes " + std::to_string(arity) + " argument" +
               (arity == 1 ? "" : "s") + " but was given " + std::to_string(args.size()),
           t.begin);
    if (op == Op::kPow) return finite(builder_.pow(args[0], args[1]), t.begin);
    if (is_binary(op)) return finite(builder_.function(op, args[0], args[1]), t.begin);
    return finite(builder_.function(op, args[0]), t.begin);
  }

  std::string_view text_;
  const std::vector<std::string>& variables_;
  Builder& builder_;
  std::unordered_map<std::string_view, std::size_t> index_;
  Token tok_;
  int depth_ = 0;
};

}  // namespace

NodeId parse(std::string_view text, const std::vector<std::string>& variables, Builder& builder) {
  return Parser(text, variables, builder).parse_all();
}

void validate_variable_names(const std::vector<std::string>& variables) {
  std::unordered_set<std::string_view> seen;
  for (const std::string& v : variables) {
    if (!is_identifier(v))
      throw std::invalid_argument("variable name '" + v +
                                  "' is not an identifier ([A-Za-z_][A-Za-z0-9_]*)");
    if (v == "pi" || v == "e" || function_by_name(v) != Op::kConst)
      throw std::invalid_argument("variable name '" + v + "' is reserved (constant or function)");
    if (!seen.insert(v).second)
      throw std::invalid_argument("variable name '" + v + "' is given twice");
  }
}

}  // namespace internal
}  // namespace fracvi
