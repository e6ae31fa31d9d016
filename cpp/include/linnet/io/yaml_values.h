// Strict conversion of YAML nodes to the value types of options structs and sensor files, with error
// messages that name the file, the line and the key
// ("config.yaml:12: key 'estimator.window_size' expects an integer, got 'ten'").
//
// Accepted YAML for each C++ type:
//   bool                     true/false, yes/no, on/off (any case)
//   integers                 decimal text that fits the type ("1.0" is rejected)
//   float, double            decimal or exponent text, .inf/-.inf/.nan
//   std::string              any scalar
//   std::vector<T>           a sequence of T (may be empty)
//   std::array<T, N>         a sequence of exactly N
//   fixed-size Eigen matrix  a row-major list of rows*cols numbers, or a nested list of rows, or a Kalibr
//                            map {rows: R, cols: C, data: [...]}
//   linnet::Pose             a 4x4 transform: a 16-number row-major list or a Kalibr map
//                            {rows: 4, cols: 4, data: [...]}; the rotation block must be orthonormal
//                            (|R^T R - I| < 1e-6, det +1) and the last row 0 0 0 1
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "linnet/core/pose.h"
#include "linnet/core/types.h"

namespace linnet::yaml {

/// Where a value comes from: the file (or other source name), the full key path, and which error to throw.
struct Context {
  std::string source;        // file name shown in messages
  std::string key;           // full dotted key path
  bool input_error = false;  // throw InputError (data files) instead of ConfigError (configuration)

  /// Throws "<source>:<line>: key '<key>' <what>" (line of `at` when it has one).
  [[noreturn]] void fail(const YAML::Node& at, const std::string& what) const;
  Context child(const std::string& sub) const {
    return {source, key.empty() ? sub : key + "." + sub, input_error};
  }
};

/// "<source>:<line>" of a node (1-based line), or "<source>" when the node has no position.
std::string where(const std::string& source, const YAML::Node& node);
std::string where(const std::string& source, const YAML::Mark& mark);

/// The scalar text of a node, for messages ("[sequence]", "{map}", "nothing" otherwise).
std::string describe(const YAML::Node& node);

/// Text that YAML would read back as a string (quoted when it looks like a number, bool or null).
bool stringNeedsQuotes(const std::string& s);

// ---- scalar decoders (throw through ctx.fail) ----
void decode(const YAML::Node& n, const Context& ctx, bool& out);
void decode(const YAML::Node& n, const Context& ctx, std::string& out);
void decode(const YAML::Node& n, const Context& ctx, Pose& out);
void decode(const YAML::Node& n, const Context& ctx,
            std::vector<bool>& out);  // std::vector<bool> has proxies
std::int64_t decodeInteger(const YAML::Node& n, const Context& ctx, std::int64_t lo, std::uint64_t hi);
double decodeReal(const YAML::Node& n, const Context& ctx);
/// Numbers of a matrix node (any accepted form) in row-major order; checks the shape when it is given.
std::vector<double> decodeMatrixData(const YAML::Node& n, const Context& ctx, int rows, int cols);

template <class T>
std::enable_if_t<std::is_integral_v<T> && !std::is_same_v<T, bool>> decode(const YAML::Node& n,
                                                                           const Context& ctx, T& out) {
  out = static_cast<T>(decodeInteger(n, ctx, static_cast<std::int64_t>(std::numeric_limits<T>::min()),
                                     static_cast<std::uint64_t>(std::numeric_limits<T>::max())));
}

template <class T>
std::enable_if_t<std::is_floating_point_v<T>> decode(const YAML::Node& n, const Context& ctx, T& out) {
  out = static_cast<T>(decodeReal(n, ctx));
}

template <class T>
void decode(const YAML::Node& n, const Context& ctx, std::vector<T>& out);
template <class T, std::size_t N>
void decode(const YAML::Node& n, const Context& ctx, std::array<T, N>& out);

template <class S, int R, int C, int O, int MR, int MC>
void decode(const YAML::Node& n, const Context& ctx, Eigen::Matrix<S, R, C, O, MR, MC>& out) {
  static_assert(R > 0 && C > 0, "only fixed-size Eigen matrices are supported in options");
  const std::vector<double> data = decodeMatrixData(n, ctx, R, C);
  Eigen::Matrix<S, R, C, O, MR, MC> result;
  for (int r = 0; r < R; ++r) {
    for (int c = 0; c < C; ++c) {
      const double x = data[static_cast<std::size_t>(r * C + c)];
      if constexpr (std::is_integral_v<S>) {
        if (!(x == static_cast<double>(static_cast<S>(x))))
          ctx.fail(n, "expects integers, got " + std::to_string(x) + " at row " + std::to_string(r) +
                          ", column " + std::to_string(c));
      }
      result(r, c) = static_cast<S>(x);
    }
  }
  out = result;
}

template <class T>
void decode(const YAML::Node& n, const Context& ctx, std::vector<T>& out) {
  if (!n.IsSequence()) ctx.fail(n, "expects a list, got " + describe(n));
  std::vector<T> result(n.size());
  for (std::size_t i = 0; i < n.size(); ++i) decode(n[i], ctx.child(std::to_string(i)), result[i]);
  out = std::move(result);
}

template <class T, std::size_t N>
void decode(const YAML::Node& n, const Context& ctx, std::array<T, N>& out) {
  if (!n.IsSequence() || n.size() != N)
    ctx.fail(n, "expects a list of " + std::to_string(N) + " values, got " +
                    (n.IsSequence() ? "a list of " + std::to_string(n.size()) : describe(n)));
  std::array<T, N> result{};
  for (std::size_t i = 0; i < N; ++i) decode(n[i], ctx.child(std::to_string(i)), result[i]);
  out = result;
}

// ---- encoders (YAML::Emitter) ----
void encode(YAML::Emitter& out, bool v);
void encode(YAML::Emitter& out, const std::string& v);
void encode(YAML::Emitter& out, const Pose& v);
void encode(YAML::Emitter& out, const std::vector<bool>& v);
void encodeReal(YAML::Emitter& out, double v);  // shortest round-trip text, always with a '.'
void encodeInteger(YAML::Emitter& out, std::int64_t v);

template <class T>
std::enable_if_t<std::is_integral_v<T> && !std::is_same_v<T, bool>> encode(YAML::Emitter& out, T v) {
  encodeInteger(out, static_cast<std::int64_t>(v));
}
void encodeFloat(YAML::Emitter& out, float v);  // shortest text that reads back to the same float
template <class T>
std::enable_if_t<std::is_floating_point_v<T>> encode(YAML::Emitter& out, T v) {
  if constexpr (std::is_same_v<T, float>)
    encodeFloat(out, v);
  else
    encodeReal(out, static_cast<double>(v));
}
template <class T>
void encode(YAML::Emitter& out, const std::vector<T>& v) {
  out << YAML::Flow << YAML::BeginSeq;
  for (const auto& x : v) encode(out, x);
  out << YAML::EndSeq;
}
template <class T, std::size_t N>
void encode(YAML::Emitter& out, const std::array<T, N>& v) {
  out << YAML::Flow << YAML::BeginSeq;
  for (const auto& x : v) encode(out, x);
  out << YAML::EndSeq;
}
template <class S, int R, int C, int O, int MR, int MC>
void encode(YAML::Emitter& out, const Eigen::Matrix<S, R, C, O, MR, MC>& m) {
  out << YAML::Flow << YAML::BeginSeq;
  for (int r = 0; r < m.rows(); ++r)
    for (int c = 0; c < m.cols(); ++c) encode(out, m(r, c));
  out << YAML::EndSeq;
}

/// Closest of `candidates` to `key` by edit distance (case-insensitive), or "" if none is close.
std::string closestName(const std::string& key, const std::vector<std::string>& candidates);

}  // namespace linnet::yaml
