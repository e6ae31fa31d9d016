#include "linnet/io/yaml_values.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>

#include "linnet/core/error.h"
#include "linnet/io/text_parse.h"

namespace linnet::yaml {
namespace {

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// Scalar text of a node, or fail naming what was expected.
std::string scalarOf(const YAML::Node& n, const Context& ctx, const char* expected) {
  if (!n.IsScalar()) ctx.fail(n, std::string("expects ") + expected + ", got " + describe(n));
  return n.Scalar();
}

std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t sub = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

}  // namespace

std::string where(const std::string& source, const YAML::Mark& mark) {
  if (mark.is_null() || mark.line < 0) return source;
  return source + ":" + std::to_string(mark.line + 1);
}

std::string where(const std::string& source, const YAML::Node& node) {
  if (!node.IsDefined()) return source;
  return where(source, node.Mark());
}

void Context::fail(const YAML::Node& at, const std::string& what) const {
  std::string msg = where(source, at) + ": ";
  if (!key.empty()) msg += "key '" + key + "' ";
  msg += what;
  if (input_error) throw InputError(msg);
  throw ConfigError(msg);
}

std::string describe(const YAML::Node& node) {
  if (!node.IsDefined() || node.IsNull()) return "nothing";
  if (node.IsScalar()) return "'" + node.Scalar() + "'";
  if (node.IsSequence()) return "a list";
  if (node.IsMap()) return "a map";
  return "an unknown node";
}

bool stringNeedsQuotes(const std::string& s) {
  if (s.empty()) return true;
  const std::string l = lower(s);
  static const char* kSpecial[] = {"~",   "null", "true", "false", "yes",   "no",    "on",
                                   "off", "y",    "n",    ".inf",  "-.inf", "+.inf", ".nan"};
  for (const char* w : kSpecial)
    if (l == w) return true;
  double d = 0.0;
  if (io::parseDouble(s, &d)) return true;
  return s.front() == ' ' || s.back() == ' ';
}

void decode(const YAML::Node& n, const Context& ctx, bool& out) {
  const std::string l = lower(scalarOf(n, ctx, "true or false"));
  if (l == "true" || l == "yes" || l == "on") {
    out = true;
  } else if (l == "false" || l == "no" || l == "off") {
    out = false;
  } else {
    ctx.fail(n, "expects true or false, got '" + n.Scalar() + "'");
  }
}

void decode(const YAML::Node& n, const Context& ctx, std::string& out) {
  // A bare "null" / "~" is a Null node in yaml-cpp but still a scalar with text.
  if (n.IsNull() && n.IsDefined() && !n.Scalar().empty()) {
    out = n.Scalar();
    return;
  }
  out = scalarOf(n, ctx, "a string");
}

void decode(const YAML::Node& n, const Context& ctx, std::vector<bool>& out) {
  if (!n.IsSequence()) ctx.fail(n, "expects a list, got " + describe(n));
  std::vector<bool> result(n.size());
  for (std::size_t i = 0; i < n.size(); ++i) {
    bool b = false;
    decode(n[i], ctx.child(std::to_string(i)), b);
    result[i] = b;
  }
  out = std::move(result);
}

void encode(YAML::Emitter& out, const std::vector<bool>& v) {
  out << YAML::Flow << YAML::BeginSeq;
  for (bool b : v) encode(out, b);
  out << YAML::EndSeq;
}

std::int64_t decodeInteger(const YAML::Node& n, const Context& ctx, std::int64_t lo, std::uint64_t hi) {
  const std::string s = scalarOf(n, ctx, "an integer");
  std::int64_t v = 0;
  if (!io::parseInt64(s, &v)) ctx.fail(n, "expects an integer, got '" + s + "'");
  if (v < lo || (v > 0 && static_cast<std::uint64_t>(v) > hi))
    ctx.fail(n, "= " + s + " does not fit the field's integer type [" + std::to_string(lo) + ", " +
                    std::to_string(hi) + "]");
  return v;
}

double decodeReal(const YAML::Node& n, const Context& ctx) {
  const std::string s = scalarOf(n, ctx, "a number");
  const std::string l = lower(s);
  if (l == ".inf" || l == "+.inf") return std::numeric_limits<double>::infinity();
  if (l == "-.inf") return -std::numeric_limits<double>::infinity();
  if (l == ".nan") return std::numeric_limits<double>::quiet_NaN();
  double v = 0.0;
  if (!io::parseDouble(s, &v)) ctx.fail(n, "expects a number, got '" + s + "'");
  return v;
}

std::vector<double> decodeMatrixData(const YAML::Node& n, const Context& ctx, int rows, int cols) {
  std::vector<double> data;
  int got_rows = -1, got_cols = -1;
  if (n.IsMap()) {
    // Kalibr / OpenCV style {rows: R, cols: C, data: [...]}.
    for (auto it = n.begin(); it != n.end(); ++it) {
      const std::string k = it->first.Scalar();
      if (k != "rows" && k != "cols" && k != "data" && k != "dt")
        ctx.child(k).fail(it->first, "is not a matrix field (expected rows, cols, data)");
    }
    const YAML::Node d = n["data"];
    if (!d) ctx.fail(n, "is a matrix map without 'data'");
    if (!d.IsSequence()) ctx.child("data").fail(d, "expects a list of numbers, got " + describe(d));
    if (const YAML::Node r = n["rows"])
      got_rows = static_cast<int>(decodeInteger(r, ctx.child("rows"), 1, 1 << 20));
    if (const YAML::Node c = n["cols"])
      got_cols = static_cast<int>(decodeInteger(c, ctx.child("cols"), 1, 1 << 20));
    for (std::size_t i = 0; i < d.size(); ++i)
      data.push_back(decodeReal(d[i], ctx.child("data." + std::to_string(i))));
    if (got_rows > 0 && got_cols > 0 && static_cast<std::size_t>(got_rows * got_cols) != data.size())
      ctx.fail(n, "has rows*cols = " + std::to_string(got_rows * got_cols) + " but " +
                      std::to_string(data.size()) + " data values");
  } else if (n.IsSequence() && n.size() > 0 && n[0].IsSequence()) {
    got_rows = static_cast<int>(n.size());
    for (std::size_t r = 0; r < n.size(); ++r) {
      const YAML::Node row = n[r];
      if (!row.IsSequence()) ctx.fail(row, "row " + std::to_string(r) + " is not a list");
      if (got_cols < 0) got_cols = static_cast<int>(row.size());
      if (static_cast<int>(row.size()) != got_cols) ctx.fail(row, "has rows of different lengths");
      for (std::size_t c = 0; c < row.size(); ++c)
        data.push_back(decodeReal(row[c], ctx.child(std::to_string(r) + "." + std::to_string(c))));
    }
  } else if (n.IsSequence()) {
    for (std::size_t i = 0; i < n.size(); ++i) data.push_back(decodeReal(n[i], ctx.child(std::to_string(i))));
  } else {
    ctx.fail(n, "expects a matrix (a list of numbers or {rows, cols, data}), got " + describe(n));
  }
  if (rows > 0 && cols > 0) {
    const std::string shape = std::to_string(rows) + "x" + std::to_string(cols);
    if ((got_rows > 0 && got_rows != rows) || (got_cols > 0 && got_cols != cols))
      ctx.fail(n, "expects a " + shape + " matrix, got " + std::to_string(got_rows) + "x" +
                      std::to_string(got_cols));
    if (data.size() != static_cast<std::size_t>(rows * cols))
      ctx.fail(n, "expects a " + shape + " matrix (" + std::to_string(rows * cols) + " numbers), got " +
                      std::to_string(data.size()) + " numbers");
  }
  return data;
}

void decode(const YAML::Node& n, const Context& ctx, Pose& out) {
  const std::vector<double> d = decodeMatrixData(n, ctx, 4, 4);
  Mat4 T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = d[static_cast<std::size_t>(r * 4 + c)];
  if (!T.allFinite()) ctx.fail(n, "has non-finite values");
  if ((T.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9)
    ctx.fail(n, "is not a rigid transform: last row must be [0, 0, 0, 1]");
  const Mat3 R = T.block<3, 3>(0, 0);
  const double err = (R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff();
  if (err > 1e-6 || R.determinant() < 0.0)
    ctx.fail(n, "is not a rigid transform: rotation block is not orthonormal with det +1 (|R^T R - I| = " +
                    io::formatDouble(err) + ")");
  out = Pose::fromMatrix(T);
}

void encode(YAML::Emitter& out, bool v) { out << (v ? "true" : "false"); }

void encode(YAML::Emitter& out, const std::string& v) {
  if (stringNeedsQuotes(v)) out << YAML::DoubleQuoted;
  out << v;
}

/// Shortest round-trip text with a '.' in the mantissa ("20.0", "1.0e-09"), so that YAML 1.1 readers
/// (PyYAML) also see a float; YAML 1.2 readers and ours read the same value either way.
std::string yamlFloatText(std::string s) {
  if (s.find_first_of(".n") != std::string::npos) return s;  // has a dot, or is nan/inf (handled by callers)
  const std::size_t e = s.find('e');
  s.insert(e == std::string::npos ? s.size() : e, ".0");
  return s;
}

void encodeReal(YAML::Emitter& out, double v) {
  if (std::isnan(v)) {
    out << ".nan";
  } else if (std::isinf(v)) {
    out << (v > 0 ? ".inf" : "-.inf");
  } else {
    out << yamlFloatText(io::formatDouble(v));
  }
}

void encodeFloat(YAML::Emitter& out, float v) {
  if (!std::isfinite(v)) {
    encodeReal(out, static_cast<double>(v));
    return;
  }
  char buf[32];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), v);
  out << yamlFloatText(std::string(buf, ec == std::errc() ? ptr : buf));
}

void encodeInteger(YAML::Emitter& out, std::int64_t v) { out << std::to_string(v); }

void encode(YAML::Emitter& out, const Pose& v) {
  const Mat4 T = v.matrix();
  out << YAML::Flow << YAML::BeginSeq;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) encodeReal(out, T(r, c));
  out << YAML::EndSeq;
}

std::string closestName(const std::string& key, const std::vector<std::string>& candidates) {
  const std::string lk = lower(key);
  std::string best;
  bool found = false;
  long best_score = 0;  // distance minus the allowed distance
  for (const auto& c : candidates) {
    const std::string lc = lower(c);
    const long d = static_cast<long>(editDistance(lk, lc));
    // A few typos: up to a third of the longer name (at least 2) may differ.
    const long limit = static_cast<long>(std::max<std::size_t>(2, std::max(lk.size(), lc.size()) / 3));
    if (d <= limit && (!found || d - limit < best_score)) {
      found = true;
      best_score = d - limit;
      best = c;
    }
  }
  if (found) return best;
  // An abbreviation ("max_pts" for "max_points"): the key's letters appear in order in the candidate.
  for (const auto& c : candidates) {
    const std::string lc = lower(c);
    if (lk.size() < 3 || lk.front() != lc.front()) continue;
    std::size_t j = 0;
    for (char ch : lc)
      if (j < lk.size() && ch == lk[j]) ++j;
    if (j == lk.size()) return c;
  }
  return "";
}

}  // namespace linnet::yaml
