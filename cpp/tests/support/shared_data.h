// Locating ../shared/data for tests. Tests that need it FAIL (never skip) when CI=true and it is missing.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

namespace linnet::testing {

/// Root of the shared data: $LINNET_SHARED_DATA, else <source>/../shared/data.
inline std::filesystem::path sharedDataDir() {
  if (const char* env = std::getenv("LINNET_SHARED_DATA")) return env;
  return std::filesystem::path(LINNET_SOURCE_DIR) / ".." / "shared" / "data";
}

inline bool runningInCi() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && std::string(ci) == "true";
}

/// The V1_01_easy_micro EuRoC folder (the one holding mav0/).
inline std::filesystem::path eurocMicroDir() { return sharedDataDir() / "euroc" / "V1_01_easy_micro"; }

}  // namespace linnet::testing

/// Use at the top of a test that needs shared data: fails under CI=true if missing, skips otherwise.
#define LINNET_REQUIRE_SHARED_DATA(path)                                                        \
  do {                                                                                          \
    if (!std::filesystem::exists(path)) {                                                       \
      if (::linnet::testing::runningInCi()) FAIL() << "shared data missing: " << (path);        \
      GTEST_SKIP() << "shared data missing: " << (path);                                        \
    }                                                                                           \
  } while (0)
