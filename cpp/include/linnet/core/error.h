// Errors at the API boundary. Every message names what is wrong: the file and line, or the config key.
#pragma once

#include <stdexcept>
#include <string>

namespace linnet {

/// Base of every error Linnet throws on purpose.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

/// Bad input data: missing or corrupt files, unparsable lines, non-monotonic time stamps, IMU gaps.
/// The message starts with "<file>:<line>: " when a line is known, "<file>: " otherwise.
class InputError : public Error {
 public:
  explicit InputError(const std::string& what) : Error(what) {}
  InputError(const std::string& file, long line, const std::string& what) : Error(locate(file, line, what)) {}

 private:
  static std::string locate(const std::string& file, long line, const std::string& what) {
    std::string msg = file;
    if (line > 0) {
      msg += ':';
      msg += std::to_string(line);
    }
    msg += ": ";
    msg += what;
    return msg;
  }
};

/// Bad configuration: unknown key, wrong type, value out of range. The message names the key's full path.
class ConfigError : public Error {
 public:
  explicit ConfigError(const std::string& what) : Error(what) {}
};

/// Misuse of the API (calls out of order, wrong image size, time going backwards at the System boundary).
class UsageError : public Error {
 public:
  explicit UsageError(const std::string& what) : Error(what) {}
};

}  // namespace linnet
