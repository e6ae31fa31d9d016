#include "linnet/io/text_parse.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>

#include "linnet/core/error.h"

namespace linnet::io {
namespace {

bool isBlank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

std::string_view trim(std::string_view s) {
  while (!s.empty() && isBlank(s.front())) s.remove_prefix(1);
  while (!s.empty() && isBlank(s.back())) s.remove_suffix(1);
  return s;
}

}  // namespace

void failInput(const std::string& file, long line, const std::string& what) {
  std::string msg = file;
  if (line > 0) msg += ":" + std::to_string(line);
  msg += ": ";
  msg += what;
  throw InputError(msg);
}

TextFile::~TextFile() {
  if (map_) ::munmap(map_, map_size_);
}

TextFile::TextFile(TextFile&& o) noexcept
    : path_(std::move(o.path_)),
      owned_(std::move(o.owned_)),
      data_(o.data_),
      size_(o.size_),
      map_(o.map_),
      map_size_(o.map_size_) {
  if (!map_) data_ = owned_.data();
  o.map_ = nullptr;
  o.data_ = nullptr;
  o.size_ = 0;
}

TextFile& TextFile::operator=(TextFile&& o) noexcept {
  if (this == &o) return *this;
  if (map_) ::munmap(map_, map_size_);
  path_ = std::move(o.path_);
  owned_ = std::move(o.owned_);
  size_ = o.size_;
  map_ = o.map_;
  map_size_ = o.map_size_;
  data_ = map_ ? o.data_ : owned_.data();
  o.map_ = nullptr;
  o.data_ = nullptr;
  o.size_ = 0;
  return *this;
}

TextFile TextFile::read(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) failInput(path, 0, "file not found");
  if (std::filesystem::is_directory(status)) failInput(path, 0, "is a directory, expected a file");
  TextFile file;
  file.path_ = path;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) failInput(path, 0, "cannot open file for reading");
  struct stat st{};
  if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0) {
    // Map the page cache directly: no copy, no zero-filled buffer.
    void* m =
        ::mmap(nullptr, static_cast<std::size_t>(st.st_size), PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
    if (m != MAP_FAILED) {
      ::close(fd);
      file.map_ = m;
      file.map_size_ = static_cast<std::size_t>(st.st_size);
      file.data_ = static_cast<const char*>(m);
      file.size_ = file.map_size_;
      file.skipBom();
      return file;
    }
  }
  // Not mappable (empty file, pipe, special file): read it.
  char buf[65536];
  ssize_t n = 0;
  while ((n = ::read(fd, buf, sizeof(buf))) > 0) file.owned_.append(buf, static_cast<std::size_t>(n));
  ::close(fd);
  if (n < 0) failInput(path, 0, "read error");
  file.data_ = file.owned_.data();
  file.size_ = file.owned_.size();
  file.skipBom();
  return file;
}

void TextFile::skipBom() {
  // A UTF-8 byte order mark (files saved by some Windows editors) is not part of the first line.
  if (text().substr(0, 3) != "\xEF\xBB\xBF") return;
  if (map_) {
    data_ += 3;
    size_ -= 3;
  } else {
    owned_.erase(0, 3);
    data_ = owned_.data();
    size_ = owned_.size();
  }
}

TextFile TextFile::fromString(std::string text, std::string name) {
  TextFile file;
  file.path_ = std::move(name);
  file.owned_ = std::move(text);
  file.data_ = file.owned_.data();
  file.size_ = file.owned_.size();
  file.skipBom();
  return file;
}

std::vector<TextLines> TextFile::split(int n) const {
  const std::string_view t = text();
  std::vector<TextLines> chunks;
  if (n <= 1 || t.size() < static_cast<std::size_t>(n) * 4096) {
    chunks.push_back(lines());
    return chunks;
  }
  std::size_t begin = 0;
  long first_line = 1;
  for (int k = 0; k < n && begin < t.size(); ++k) {
    std::size_t end =
        k + 1 == n ? t.size() : t.size() / static_cast<std::size_t>(n) * static_cast<std::size_t>(k + 1);
    if (end < begin) end = begin;
    if (end < t.size()) {
      const std::size_t nl = t.find('\n', end);
      end = nl == std::string_view::npos ? t.size() : nl + 1;
    }
    const std::string_view part = t.substr(begin, end - begin);
    chunks.emplace_back(part, &path_, first_line);
    first_line += static_cast<long>(std::count(part.begin(), part.end(), '\n'));
    begin = end;
  }
  return chunks;
}

long TextFile::lineOfDataRow(std::size_t index) const {
  TextLines l = lines();
  std::string_view line;
  for (std::size_t i = 0; l.nextData(&line); ++i)
    if (i == index) return l.line();
  return 0;
}

void failTimeOrder(const TextFile& file, std::size_t index, Timestamp t, Timestamp previous) {
  failInput(file.path(), file.lineOfDataRow(index),
            "time stamp " + std::to_string(t) + " ns " +
                (t == previous ? "is duplicated" : "goes backwards") + " (previous row " +
                std::to_string(previous) + " ns)");
}

int parseThreads(std::size_t bytes, int max_threads) {
  if (bytes < (4u << 20)) return 1;
  int hw = max_threads > 0 ? max_threads : static_cast<int>(std::thread::hardware_concurrency());
  hw = std::clamp(hw, 1, 16);
  return std::min<int>(hw, static_cast<int>(bytes / (2u << 20)));
}

bool TextLines::next(std::string_view* line) {
  if (pos_ >= text_.size()) return false;
  const std::size_t end = text_.find('\n', pos_);
  const std::size_t stop = end == std::string_view::npos ? text_.size() : end;
  std::string_view l = text_.substr(pos_, stop - pos_);
  if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
  pos_ = end == std::string_view::npos ? text_.size() : end + 1;
  ++line_no_;
  *line = l;
  return true;
}

bool TextLines::nextData(std::string_view* line) {
  std::string_view l;
  while (next(&l)) {
    const std::string_view t = trim(l);
    if (t.empty() || t.front() == '#') continue;
    *line = l;
    return true;
  }
  return false;
}

void TextLines::fail(const std::string& what) const { failInput(*path_, line_no_, what); }

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
    const std::string_view f =
        trim(line.substr(start, end == std::string_view::npos ? line.npos : end - start));
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

/// Clinger's fast path (W. D. Clinger, "How to read floating point numbers accurately", PLDI 1990): a decimal
/// with an integer mantissa m <= 2^53 and a power of ten 10^e with |e| <= 22 is m * 10^e or m / 10^-e, both
/// exact doubles, so one IEEE operation gives the correctly rounded result, the same as std::from_chars.
/// Returns false when the text is not of the plain form [-]digits[.digits][e[+-]digits] or out of the fast
/// range.
bool parseDoubleFast(std::string_view s, double* value) {
  static constexpr double kPow10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                        1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                        1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  std::size_t i = 0;
  const bool negative = i < s.size() && s[i] == '-';
  if (negative) ++i;
  std::uint64_t m = 0;
  int digits = 0, frac_digits = 0;
  bool any = false;
  for (; i < s.size() && s[i] >= '0' && s[i] <= '9'; ++i) {
    any = true;
    if (m == 0 && s[i] == '0') continue;  // leading zeros
    if (++digits > 16) return false;
    m = m * 10 + static_cast<std::uint64_t>(s[i] - '0');
  }
  if (i < s.size() && s[i] == '.') {
    for (++i; i < s.size() && s[i] >= '0' && s[i] <= '9'; ++i) {
      any = true;
      ++frac_digits;
      if (m == 0 && s[i] == '0') continue;
      if (++digits > 16) return false;
      m = m * 10 + static_cast<std::uint64_t>(s[i] - '0');
    }
  }
  if (!any) return false;
  int e = 0;
  if (i < s.size() && (s[i] == 'e' || s[i] == 'E')) {
    ++i;
    bool eneg = false;
    if (i < s.size() && (s[i] == '-' || s[i] == '+')) eneg = s[i++] == '-';
    if (i >= s.size()) return false;
    for (; i < s.size() && s[i] >= '0' && s[i] <= '9'; ++i) {
      e = e * 10 + (s[i] - '0');
      if (e > 1000) return false;
    }
    if (eneg) e = -e;
  }
  if (i != s.size()) return false;
  if (m > (std::uint64_t{1} << 53)) return false;
  e -= frac_digits;
  double x = static_cast<double>(m);
  if (m == 0) {
    x = 0.0;
  } else if (e >= 0 && e <= 22) {
    x *= kPow10[e];
  } else if (e < 0 && e >= -22) {
    x /= kPow10[-e];
  } else {
    return false;
  }
  *value = negative ? -x : x;
  return true;
}

bool parseDouble(std::string_view s, double* value) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty()) return false;
  if (parseDoubleFast(s, value)) return true;
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
  const std::uint64_t mag =
      negative ? 0ULL - static_cast<std::uint64_t>(t_ns) : static_cast<std::uint64_t>(t_ns);
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

std::int64_t parseInt64Field(const TextLines& file, std::string_view s, const char* column) {
  std::int64_t v = 0;
  if (!parseInt64(s, &v))
    file.fail("column '" + std::string(column) + "': expected an integer, got '" + std::string(s) + "'");
  return v;
}

double parseDoubleField(const TextLines& file, std::string_view s, const char* column) {
  double v = 0.0;
  if (!parseDouble(s, &v))
    file.fail("column '" + std::string(column) + "': expected a number, got '" + std::string(s) + "'");
  return v;
}

}  // namespace linnet::io
