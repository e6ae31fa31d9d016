// YAML loading and saving of options structs through the visit() protocol of core/options.h.
//
//   MyOptions opt;
//   loadOptionsFile("config.yaml", opt);   // keys present override defaults; unknown keys / bad values throw
//   saveOptionsFile("out.yaml", opt);      // every field, with its doc string and range as a comment
//
// Loading is strict: an unknown key, a duplicated key, a value of the wrong type, a value outside [lo, hi] or
// not among the choices throws ConfigError naming the file, the line and the full key path, e.g.
//   config.yaml:12: key 'estimator.window_size' = 0 is out of range [2, 50]
//   config.yaml:5: unknown key 'points.max_pts' (did you mean 'max_points'?)
// Saving writes numbers as the shortest text that reads back to the same value, so save -> load gives back
// the same options (Pose fields go through a rotation matrix and come back to within 1e-16). Value types and
// their YAML forms: see io/yaml_values.h.
#pragma once

#include <algorithm>
#include <initializer_list>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "linnet/core/error.h"
#include "linnet/io/text_parse.h"
#include "linnet/io/yaml_values.h"

namespace linnet {

/// Visitor that reads the keys present in one YAML map into an options struct (see loadOptions()).
class YamlOptionsReader {
 public:
  /// `node` must be a map or null/undefined (nothing to read). `prefix` is the key path of this map.
  YamlOptionsReader(const YAML::Node& node, std::string source, std::string prefix);

  template <class T>
  void operator()(const char* key, T& value, const char* /*doc*/) {
    if (const YAML::Node n = find(key)) yaml::decode(n, context(key), value);
  }

  template <class T, class L, class H>
  void operator()(const char* key, T& value, const char* /*doc*/, L lo, H hi) {
    static_assert(std::is_arithmetic_v<T>, "ranges [lo, hi] apply to numeric fields only");
    const YAML::Node n = find(key);
    if (!n) return;
    T v = value;
    const yaml::Context ctx = context(key);
    yaml::decode(n, ctx, v);
    if (!(lessEqual(lo, v) && lessEqual(v, hi)))
      ctx.fail(n, "= " + n.Scalar() + " is out of range [" + number(lo) + ", " + number(hi) + "]");
    value = v;
  }

  void choice(const char* key, std::string& value, const char* doc,
              std::initializer_list<const char*> allowed);

  template <class S>
  void section(const char* key, S& sub) {
    const YAML::Node n = find(key);
    if (!n || n.IsNull()) return;  // absent or "key:" with nothing: keep the defaults
    YamlOptionsReader child(n, source_, path(key));
    sub.visit(child);
    child.finish();
  }

  /// Throws ConfigError on keys of this map that the options struct did not visit (call after visit()).
  void finish() const;

 private:
  YAML::Node find(const char* key);
  yaml::Context context(const char* key) const { return {source_, path(key), false}; }
  std::string path(const char* key) const { return prefix_.empty() ? std::string(key) : prefix_ + "." + key; }
  template <class N>
  static std::string number(N x) {
    if constexpr (std::is_floating_point_v<N>)
      return io::formatDouble(static_cast<double>(x));
    else
      return std::to_string(x);
  }
  /// a <= b without sign-compare surprises (unsigned field, int bounds); false if either is NaN.
  template <class A, class B>
  static bool lessEqual(A a, B b) {
    if constexpr (std::is_integral_v<A> && std::is_integral_v<B>)
      return std::cmp_less_equal(a, b);
    else
      return a <= b;
  }

  YAML::Node node_;
  std::string source_;
  std::string prefix_;
  std::vector<std::string> known_;  // keys the options struct visited at this level
};

/// Visitor that emits an options struct as a YAML block map, with the doc strings as end-of-line comments.
class YamlOptionsWriter {
 public:
  YamlOptionsWriter(YAML::Emitter& out, bool comments) : out_(out), comments_(comments) {}

  template <class T>
  void operator()(const char* key, T& value, const char* doc) {
    out_ << YAML::Key << key << YAML::Value;
    yaml::encode(out_, value);
    comment(doc);
  }

  template <class T, class L, class H>
  void operator()(const char* key, T& value, const char* doc, L lo, H hi) {
    out_ << YAML::Key << key << YAML::Value;
    yaml::encode(out_, value);
    comment(std::string(doc) + " [" + number(lo) + ", " + number(hi) + "]");
  }

  void choice(const char* key, std::string& value, const char* doc,
              std::initializer_list<const char*> allowed);

  template <class S>
  void section(const char* key, S& sub) {
    out_ << YAML::Key << key << YAML::Value << YAML::BeginMap;
    sub.visit(*this);
    out_ << YAML::EndMap;
  }

 private:
  void comment(const std::string& doc);
  template <class N>
  static std::string number(N x) {
    if constexpr (std::is_floating_point_v<N>)
      return io::formatDouble(static_cast<double>(x));
    else
      return std::to_string(x);
  }
  YAML::Emitter& out_;
  bool comments_;
};

/// Reads the keys present in `node` (a map, or null for "nothing to change") into `options`.
/// `source` names the file in error messages. Throws ConfigError (see the top of this file).
template <class O>
void loadOptions(const YAML::Node& node, O& options, const std::string& source) {
  YamlOptionsReader reader(node, source, "");
  options.visit(reader);
  reader.finish();
}

/// Parses a YAML file; InputError "<path>: file not found" or "<path>:<line>: YAML syntax error: ...".
YAML::Node loadYamlFile(const std::string& path);

/// loadOptions() on a whole file (an empty file changes nothing).
template <class O>
void loadOptionsFile(const std::string& path, O& options) {
  loadOptions(loadYamlFile(path), options, path);
}

/// The YAML text of `options` (every field), with doc-string comments when `comments` is true.
template <class O>
std::string optionsToYaml(O& options, bool comments = true) {
  YAML::Emitter out;
  out.SetIndent(2);
  out << YAML::BeginMap;
  YamlOptionsWriter writer(out, comments);
  options.visit(writer);
  out << YAML::EndMap;
  if (!out.good()) throw UsageError("optionsToYaml: YAML emitter error: " + out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

/// The options as a YAML node (a map holding every field).
template <class O>
YAML::Node saveOptions(O& options) {
  return YAML::Load(optionsToYaml(options, false));
}

/// Writes optionsToYaml() to `path` under an optional header comment. InputError if it cannot be written.
void writeTextFile(const std::string& path, const std::string& text);
template <class O>
void saveOptionsFile(const std::string& path, O& options, const std::string& header = "") {
  std::string text;
  if (!header.empty()) {
    std::size_t start = 0;
    while (start <= header.size()) {
      const std::size_t end = std::min(header.find('\n', start), header.size());
      text += "# " + header.substr(start, end - start) + "\n";
      start = end + 1;
    }
  }
  writeTextFile(path, text + optionsToYaml(options, true));
}

}  // namespace linnet
