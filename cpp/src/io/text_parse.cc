#include "linnet/io/text_parse.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>

#include "linnet/core/error.h"

namespace linnet::io {
namespace {

bool isBlank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && isBlank(s.front())) s.remove_prefix(1);
  while (!s.empty() && isBlank(s.back())) s.remove_suffix(1);
  return s;
}

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

}  // namespace

void failInput(const std::string& file, long line, const std::string& what) {
  std::string msg = file;
  if (line > 0) msg += ":" + std::to_string(line);
  msg += ": ";
  msg += what;
  throw InputError(msg);
}

TextFile TextFile::read(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) failInput(path, 0, "file not found");
  if (std::filesystem::is_directory(status)) failInput(path, 0, "is a directory, expected a file");
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "rb"));
  if (!f) failInput(path, 0, "cannot open file for reading");
  std::string text;
  const auto size = std::filesystem::file_size(path, ec);
  if (!ec) text.resize(static_cast<std::size_t>(size));
  std::size_t got = text.empty() ? 0 : std::fread(text.data(), 1, text.size(), f.get());
  text.resize(got);
  // A file that grew or whose size is unknown (pipes): read the rest in chunks.
  char buf[65536];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof(buf), f.get())) > 0) text.append(buf, n);
  if (std::ferror(f.get())) failInput(path, 0, "read error");
  return TextFile(std::move(text), path);
}

TextFile TextFile::fromString(std::string text, std::string name) { return TextFile(std::move(text), std::move(name)); }

bool TextFile::next(std::string_view* line) {
  if (pos_ >= text_.size()) return false;
  const std::size_t end = text_.find('\n', pos_);
  const std::size_t stop = end == std::string::npos ? text_.size() : end;
  std::string_view l(text_.data() + pos_, stop - pos_);
  if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
  pos_ = end == std::string::npos ? text_.size() : end + 1;
  ++line_no_;
  *line = l;
  return true;
}

bool TextFile::nextData(std::string_view* line) {
  std::string_view l;
  while (next(&l)) {
    const std::string_view t = trim(l);
    if (t.empty() || t.front() == '#') continue;
    *line = l;
    return true;
  }
  return false;
}

void TextFile::fail(const std::string& what) const { failInput(path_, line_no_, what); }

int splitFields(std::string_view line, char sep, std::string_view* fields, int max_fields) {
  int count = 0;
  if (sep == ' ') {
    std::size_t i = 0;
    while (true) {
      while (i < line.size() && isBlank(line[i])) ++i;
      if (i >= line.size()) break;
      std::size_t j = i;
      while (j < line.size() && !isBlank(line[j])) ++j;
      if (count < max_fields) fields[count] = line.substr(i, j - i);
      if (++count > max_fields) return count;
      i = j;
    }
    return count;
  }
  std::size_t start = 0;
  while (true) {
    const std::size_t end = line.find(sep, start);
    const std::string_view f = trim(line.substr(start, end == std::string_view::npos ? line.npos : end - start));
    if (count < max_fields) fields[count] = f;
    if (++count > max_fields) return count;
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
  return count;
}

bool parseInt64(std::string_view s, std::int64_t* value) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), *value);
  return ec == std::errc() && ptr == s.data() + s.size();
}

bool parseDouble(std::string_view s, double* value) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), *value);
  return ec == std::errc() && ptr == s.data() + s.size();
}

bool parseSecondsToNs(std::string_view s, Timestamp* t_ns) {
  if (s.empty()) return false;
  if (s.find_first_of("eE") != std::string_view::npos) {
    double sec = 0.0;
    if (!parseDouble(s, &sec) || !std::isfinite(sec) || std::fabs(sec) > 9.2e9) return false;
    *t_ns = fromSeconds(sec);
    return true;
  }
  bool negative = false;
  if (s.front() == '-' || s.front() == '+') {
    negative = s.front() == '-';
    s.remove_prefix(1);
  }
  const std::size_t dot = s.find('.');
  const std::string_view int_part = s.substr(0, dot);
  const std::string_view frac = dot == std::string_view::npos ? std::string_view() : s.substr(dot + 1);
  if (int_part.empty() && frac.empty()) return false;
  std::int64_t sec = 0;
  if (!int_part.empty()) {
    if (int_part.front() == '-' || int_part.front() == '+') return false;
    if (!parseInt64(int_part, &sec) || sec > 9'000'000'000LL) return false;
  }
  std::int64_t ns = 0;
  int digits = 0;
  for (char c : frac) {
    if (c < '0' || c > '9') return false;
    if (digits < 9) {
      ns = ns * 10 + (c - '0');
    } else if (digits == 9 && c >= '5') {
      ++ns;  // round half up on the 10th decimal
    }
    ++digits;
  }
  for (int d = digits; d < 9; ++d) ns *= 10;
  const std::int64_t total = sec * 1'000'000'000LL + ns;
  *t_ns = negative ? -total : total;
  return true;
}

std::string formatSeconds(Timestamp t_ns) {
  const bool negative = t_ns < 0;
  // Work on the magnitude as unsigned to handle INT64_MIN.
  const std::uint64_t mag = negative ? 0ULL - static_cast<std::uint64_t>(t_ns) : static_cast<std::uint64_t>(t_ns);
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%s%llu.%09llu", negative ? "-" : "",
                static_cast<unsigned long long>(mag / 1'000'000'000ULL),
                static_cast<unsigned long long>(mag % 1'000'000'000ULL));
  return buf;
}

std::string formatDouble(double x) {
  if (std::isnan(x)) return "nan";
  if (std::isinf(x)) return x > 0 ? "inf" : "-inf";
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), x);
  return std::string(buf, ec == std::errc() ? ptr : buf);
}

std::int64_t parseInt64Field(const TextFile& file, std::string_view s, const char* column) {
  std::int64_t v = 0;
  if (!parseInt64(s, &v)) file.fail("column '" + std::string(column) + "': expected an integer, got '" + std::string(s) + "'");
  return v;
}

double parseDoubleField(const TextFile& file, std::string_view s, const char* column) {
  double v = 0.0;
  if (!parseDouble(s, &v)) file.fail("column '" + std::string(column) + "': expected a number, got '" + std::string(s) + "'");
  return v;
}

}  // namespace linnet::io
