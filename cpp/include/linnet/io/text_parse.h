// Fast, strict parsing of line-oriented text files (csv, TUM): the whole file is read at once, lines are handed out
// as string_views, fields are split without allocation and numbers are parsed with std::from_chars.
// Every error is an InputError "<file>:<line>: <what>" (lines counted from 1, as an editor shows them).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "linnet/core/types.h"

namespace linnet::io {

/// Throws InputError "<file>:<line>: <what>" ("<file>: <what>" when line <= 0): the same text as
/// InputError(file, line, what), built out of line (GCC 12 reports a false -Wrestrict when that constructor
/// is inlined with a constant line).
[[noreturn]] void failInput(const std::string& file, long line, const std::string& what);

/// A text file held in memory, read line by line. Accepts LF and CRLF line endings (the '\r' is stripped).
class TextFile {
 public:
  /// Reads the whole file. Throws InputError "<path>: ..." if it is missing, a directory or unreadable.
  static TextFile read(const std::string& path);

  /// Wraps text that is already in memory (tests, streams); `name` is used in error messages.
  static TextFile fromString(std::string text, std::string name);

  /// Next line without its terminator. Returns false at the end. line() is its 1-based number afterwards.
  bool next(std::string_view* line);

  /// Next line that is neither blank nor a comment (first non-blank character '#').
  bool nextData(std::string_view* line);

  long line() const { return line_no_; }
  const std::string& path() const { return path_; }
  std::size_t sizeBytes() const { return text_.size(); }

  /// Throws InputError "<path>:<line>: <what>" for the current line.
  [[noreturn]] void fail(const std::string& what) const;

 private:
  TextFile(std::string text, std::string path) : text_(std::move(text)), path_(std::move(path)) {}
  std::string text_;
  std::string path_;
  std::size_t pos_ = 0;
  long line_no_ = 0;
};

/// Splits `line` at `sep` into at most `max_fields` fields, trimming blanks around each one.
/// Returns the number of fields found; a return value > max_fields means "too many" (the rest is not stored).
/// sep == ' ' splits at runs of blanks and tabs (TUM files) and ignores leading/trailing blanks.
int splitFields(std::string_view line, char sep, std::string_view* fields, int max_fields);

/// Strict number parsing of a whole field (no trailing characters). Return false on any error.
bool parseInt64(std::string_view s, std::int64_t* value);
bool parseDouble(std::string_view s, double* value);  // also accepts nan, inf, -inf

/// Decimal seconds ("1403715273.262142976", "-0.5", "12") -> int64 nanoseconds, exactly for up to 9 decimals
/// (more decimals are rounded to the nearest nanosecond). Exponent forms ("1.4e9") go through double.
bool parseSecondsToNs(std::string_view s, Timestamp* t_ns);

/// int64 nanoseconds -> seconds with exactly 9 decimals ("1403715273.262142976"), no rounding.
std::string formatSeconds(Timestamp t_ns);

/// Shortest decimal text that parses back to exactly the same double (std::to_chars); "nan", "inf", "-inf".
std::string formatDouble(double x);

/// Convenience wrappers that throw via file.fail() naming the column.
std::int64_t parseInt64Field(const TextFile& file, std::string_view s, const char* column);
double parseDoubleField(const TextFile& file, std::string_view s, const char* column);

}  // namespace linnet::io
