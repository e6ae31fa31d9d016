// The options protocol: every module has one options struct with default member values and units in comments,
// and describes its fields to a visitor so that one generic piece of code loads, saves and validates all of them.
//
//   struct TrackerOptions {
//     int max_points = 150;          // features per frame
//     double min_distance_px = 25;   // between corners
//     std::string detector = "fast"; // "fast" | "shi_tomasi"
//     template <class V> void visit(V& v) {
//       v("max_points", max_points, "features per frame", 1, 5000);       // numeric, range-checked [lo, hi]
//       v("min_distance_px", min_distance_px, "pixels between corners", 1.0, 500.0);
//       v.choice("detector", detector, "corner detector", {"fast", "shi_tomasi"});
//       v.section("klt", klt);                                             // nested options struct
//       v("flag", some_bool, "a boolean has no range");
//     }
//   };
//
// Supported field types: bool, int, double, std::string, std::vector<double>, fixed-size Eigen matrices.
// The YAML reader / writer live in io (linnet/io/config_yaml.h); validate() below needs no YAML.
#pragma once

#include <initializer_list>
#include <sstream>
#include <string>
#include <vector>

#include "linnet/core/error.h"

namespace linnet {

/// Walks an options tree and throws ConfigError naming the first field out of its range.
class OptionsValidator {
 public:
  explicit OptionsValidator(std::string prefix = "") : prefix_(std::move(prefix)) {}

  template <class T>
  void operator()(const char* /*key*/, T& /*value*/, const char* /*doc*/) {}

  template <class T>
  void operator()(const char* key, T& value, const char* /*doc*/, T lo, T hi) {
    if (!(value >= lo && value <= hi)) {
      std::ostringstream os;
      os << "config key '" << path(key) << "' = " << value << " is out of range [" << lo << ", " << hi << "]";
      throw ConfigError(os.str());
    }
  }

  void choice(const char* key, std::string& value, const char* /*doc*/, std::initializer_list<const char*> allowed) {
    for (const char* a : allowed)
      if (value == a) return;
    std::string list;
    for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
    throw ConfigError("config key '" + path(key) + "' = '" + value + "' is not one of {" + list + "}");
  }

  template <class S>
  void section(const char* key, S& sub) {
    OptionsValidator child(path(key));
    sub.visit(child);
  }

 private:
  std::string path(const char* key) const { return prefix_.empty() ? std::string(key) : prefix_ + "." + key; }
  std::string prefix_;
};

/// Throws ConfigError if any field of `options` (an options struct) is out of range. `name` prefixes key paths.
template <class Options>
void validateOptions(Options& options, const std::string& name = "") {
  OptionsValidator v(name);
  options.visit(v);
}

}  // namespace linnet
