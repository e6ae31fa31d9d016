// Fast, strict parsing of line-oriented text files (csv, TUM): the file is memory-mapped (or read at once),
// lines are handed out as string_views, fields are split without allocation and numbers are parsed with
// std::from_chars. Large files are parsed in parallel chunks (parseRows), with the same result for any thread
// count. Every error is an InputError "<file>:<line>: <what>" (lines counted from 1, as an editor shows
// them).
#pragma once

#include <cstdint>
#include <exception>
#include <memory>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "linnet/core/types.h"

namespace linnet::io {

/// Throws InputError "<file>:<line>: <what>" ("<file>: <what>" when line <= 0): the same text as
/// InputError(file, line, what), built out of line (GCC 12 reports a false -Wrestrict when that constructor
/// is inlined with a constant line).
[[noreturn]] void failInput(const std::string& file, long line, const std::string& what);

/// A run of lines of a text file, read one by one. Accepts LF and CRLF line endings (the '\r' is stripped).
class TextLines {
 public:
  TextLines(std::string_view text, const std::string* path, long first_line)
      : text_(text), path_(path), line_no_(first_line - 1) {}

  /// Next line without its terminator. Returns false at the end. line() is its 1-based number afterwards.
  bool next(std::string_view* line);
  /// Next line that is neither blank nor a comment (first non-blank character '#').
  bool nextData(std::string_view* line);

  long line() const { return line_no_; }
  const std::string& path() const { return *path_; }
  /// Throws InputError "<path>:<line>: <what>" for the current line.
  [[noreturn]] void fail(const std::string& what) const;

 private:
  std::string_view text_;
  const std::string* path_;
  std::size_t pos_ = 0;
  long line_no_ = 0;
};

/// A whole text file in memory (memory-mapped when possible), without a leading UTF-8 byte order mark.
class TextFile {
 public:
  /// Throws InputError "<path>: ..." if the file is missing, a directory or unreadable.
  static TextFile read(const std::string& path);
  /// Text that is already in memory (tests, streams); `name` is used in error messages.
  static TextFile fromString(std::string text, std::string name);

  TextFile(TextFile&& o) noexcept;
  TextFile& operator=(TextFile&& o) noexcept;
  TextFile(const TextFile&) = delete;
  TextFile& operator=(const TextFile&) = delete;
  ~TextFile();

  std::string_view text() const { return {data_, size_}; }
  const std::string& path() const { return path_; }
  std::size_t sizeBytes() const { return size_; }
  TextLines lines() const { return TextLines(text(), &path_, 1); }
  /// Up to `n` runs of whole lines covering the file, of about equal size, with their first line numbers.
  std::vector<TextLines> split(int n) const;
  /// 1-based line number of the `index`-th data line (not blank, not '#'), 0 if there are fewer.
  long lineOfDataRow(std::size_t index) const;

 private:
  TextFile() = default;
  void skipBom();
  std::string path_;
  std::string owned_;  // contents when not memory-mapped
  const char* data_ = nullptr;
  std::size_t size_ = 0;
  void* map_ = nullptr;  // mmap region (nullptr if owned_ holds the text)
  std::size_t map_size_ = 0;
};

/// Threads worth using for a file of `bytes` bytes: 1 below 4 MB, else up to `max_threads` (0 = hardware).
int parseThreads(std::size_t bytes, int max_threads = 0);

/// Parses every data line (not blank, not '#') of `file` with `parse_row(lines, line) -> Row`, in `threads`
/// chunks in parallel, and returns the rows in file order. If rows fail, the error of the first failing line
/// in file order is thrown, so the result and the error do not depend on the thread count.
template <class Row, class ParseRow>
std::vector<Row> parseRows(const TextFile& file, int threads, ParseRow parse_row,
                           std::size_t bytes_per_row = 64) {
  std::vector<TextLines> chunks = file.split(threads);
  std::vector<std::vector<Row>> parts(chunks.size());
  std::vector<std::exception_ptr> errors(chunks.size());
  auto work = [&](std::size_t k) {
    try {
      std::vector<Row>& out = parts[k];
      TextLines& lines = chunks[k];
      out.reserve(file.sizeBytes() / chunks.size() / bytes_per_row + 16);
      std::string_view line;
      while (lines.nextData(&line)) out.push_back(parse_row(lines, line));
    } catch (...) {
      errors[k] = std::current_exception();
    }
  };
  if (chunks.size() == 1) {
    work(0);
  } else {
    std::vector<std::jthread> pool;
    for (std::size_t k = 1; k < chunks.size(); ++k) pool.emplace_back(work, k);
    work(0);
  }  // joined here
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
  if (parts.size() == 1) return std::move(parts[0]);
  std::size_t total = 0;
  for (const auto& p : parts) total += p.size();
  std::vector<Row> rows;
  rows.reserve(total);
  for (auto& p : parts)
    rows.insert(rows.end(), std::make_move_iterator(p.begin()), std::make_move_iterator(p.end()));
  return rows;
}

/// Throws InputError at the line of data row `index`: "time stamp <t> ns goes backwards / is duplicated".
[[noreturn]] void failTimeOrder(const TextFile& file, std::size_t index, Timestamp t, Timestamp previous);

/// Checks that get_t(rows[i]) strictly increases; the error names the file line of the first offending row.
template <class Row, class GetT>
void checkStrictlyIncreasing(const TextFile& file, const std::vector<Row>& rows, GetT get_t) {
  for (std::size_t i = 1; i < rows.size(); ++i)
    if (!(get_t(rows[i - 1]) < get_t(rows[i]))) failTimeOrder(file, i, get_t(rows[i]), get_t(rows[i - 1]));
}

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

/// Convenience wrappers that throw via lines.fail() naming the column.
std::int64_t parseInt64Field(const TextLines& lines, std::string_view s, const char* column);
double parseDoubleField(const TextLines& lines, std::string_view s, const char* column);

}  // namespace linnet::io
