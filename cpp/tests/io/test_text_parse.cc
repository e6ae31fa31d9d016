// Text parsing helpers: number parsing agrees with std::from_chars, exact seconds <-> ns, line numbers in
// chunks.
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "io_test_util.h"
#include "linnet/core/error.h"
#include "linnet/io/text_parse.h"

namespace linnet::io {
namespace {

double fromChars(const std::string& s) {
  double v = 0.0;
  const char* b = s.data() + (s[0] == '+' ? 1 : 0);
  std::from_chars(b, s.data() + s.size(), v);
  return v;
}

TEST(TextParse, ParseDoubleMatchesFromCharsBitForBit) {
  std::mt19937_64 rng(42);
  std::uniform_int_distribution<int> ndig(1, 20), nexp(-30, 30), digit(0, 9), coin(0, 3);
  for (int k = 0; k < 200000; ++k) {
    std::string s;
    if (coin(rng) == 0) s += '-';
    const int a = ndig(rng), b = coin(rng) ? ndig(rng) : 0;
    for (int i = 0; i < a; ++i) s += static_cast<char>('0' + digit(rng));
    if (b > 0) {
      s += '.';
      for (int i = 0; i < b; ++i) s += static_cast<char>('0' + digit(rng));
    }
    if (coin(rng) == 0) s += "e" + std::to_string(nexp(rng));
    double v = 0.0;
    ASSERT_TRUE(parseDouble(s, &v)) << s;
    const double ref = fromChars(s);
    ASSERT_EQ(std::memcmp(&v, &ref, sizeof v), 0) << s << " " << v << " vs " << ref;
  }
  // Shortest text of random doubles reads back exactly.
  std::uniform_real_distribution<double> u(-1e3, 1e3);
  for (int k = 0; k < 20000; ++k) {
    const double x = u(rng) * std::pow(10.0, nexp(rng) / 3);
    double y = 0.0;
    ASSERT_TRUE(parseDouble(formatDouble(x), &y));
    ASSERT_EQ(x, y);
  }
}

TEST(TextParse, RejectsMalformedNumbers) {
  double v = 0.0;
  std::int64_t i = 0;
  for (const char* bad :
       {"", "-", ".", "1.2.3", "1e", "1e+", "abc", "1,5", "0x10", " 1", "1 ", "--1", "1e400"})
    EXPECT_FALSE(parseDouble(bad, &v)) << bad;
  for (const char* bad : {"", "1.0", "1e3", "x", "99999999999999999999", "+"})
    EXPECT_FALSE(parseInt64(bad, &i)) << bad;
  EXPECT_TRUE(parseDouble("+2.5", &v));
  EXPECT_EQ(v, 2.5);
  EXPECT_TRUE(parseDouble("-0", &v));
  EXPECT_TRUE(std::signbit(v));
  EXPECT_TRUE(parseDouble("nan", &v));
  EXPECT_TRUE(std::isnan(v));
  EXPECT_TRUE(parseInt64("-1403715273262142976", &i));
  EXPECT_EQ(i, -1403715273262142976);
}

TEST(TextParse, SecondsAndNanosecondsConvertExactly) {
  Timestamp t = 0;
  EXPECT_EQ(formatSeconds(1403715273262142976), "1403715273.262142976");
  EXPECT_EQ(formatSeconds(5), "0.000000005");
  EXPECT_EQ(formatSeconds(-1500000000), "-1.500000000");
  ASSERT_TRUE(parseSecondsToNs("1403715273.262142976", &t));
  EXPECT_EQ(t, 1403715273262142976);
  ASSERT_TRUE(parseSecondsToNs("1403715274.302", &t));
  EXPECT_EQ(t, 1403715274302000000);
  ASSERT_TRUE(parseSecondsToNs("12", &t));
  EXPECT_EQ(t, 12000000000);
  ASSERT_TRUE(parseSecondsToNs("0.0000000015", &t));  // 10th decimal rounds
  EXPECT_EQ(t, 2);
  ASSERT_TRUE(parseSecondsToNs("-1.5", &t));
  EXPECT_EQ(t, -1500000000);
  ASSERT_TRUE(parseSecondsToNs("1.4037152732621430e9", &t));
  EXPECT_NEAR(static_cast<double>(t), 1403715273262143000.0, 512.0);
  for (const char* bad : {"", ".", "1.2.3", "1.x", "abc", "--1"})
    EXPECT_FALSE(parseSecondsToNs(bad, &t)) << bad;
  for (Timestamp x : {Timestamp{0}, Timestamp{1}, Timestamp{-7}, Timestamp{1403715273262142976}}) {
    ASSERT_TRUE(parseSecondsToNs(formatSeconds(x), &t));
    EXPECT_EQ(t, x);
  }
}

TEST(TextParse, SplitFields) {
  std::string_view f[4];
  EXPECT_EQ(splitFields("a, b ,c", ',', f, 4), 3);
  EXPECT_EQ(f[1], "b");
  EXPECT_EQ(splitFields("1,2,3,4,5", ',', f, 4), 5);
  EXPECT_EQ(splitFields("  1 \t 2   3 ", ' ', f, 4), 3);
  EXPECT_EQ(f[2], "3");
  EXPECT_EQ(splitFields("x,", ',', f, 4), 2);
  EXPECT_EQ(f[1], "");
}

TEST(TextParse, ChunkedParsingKeepsOrderAndLineNumbersForAnyThreadCount) {
  std::string text = "# header\r\n";
  for (int i = 0; i < 50000; ++i)
    text += std::to_string(i) + "," + std::to_string(i * 0.5) + (i % 7 ? "\n" : "\r\n");
  const TextFile file = TextFile::fromString(text, "mem.csv");
  auto parse = [](const TextLines& lines, std::string_view line) {
    std::string_view f[2];
    if (splitFields(line, ',', f, 2) != 2) lines.fail("columns");
    return std::make_pair(parseInt64Field(lines, f[0], "i"), lines.line());
  };
  for (int threads : {1, 2, 3, 8}) {
    const auto rows = parseRows<std::pair<std::int64_t, long>>(file, threads, parse);
    ASSERT_EQ(rows.size(), 50000u);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      ASSERT_EQ(rows[i].first, static_cast<std::int64_t>(i));
      ASSERT_EQ(rows[i].second, static_cast<long>(i) + 2);
    }
  }
  // Two bad lines: the first in file order is reported, whatever the thread count.
  std::string bad = text;
  bad.replace(bad.find("\n40000,"), 7, "\n4x000,");
  bad.replace(bad.find("\n30000,"), 7, "\n3x000,");
  const TextFile bad_file = TextFile::fromString(bad, "bad.csv");
  for (int threads : {1, 2, 5}) {
    try {
      parseRows<std::pair<std::int64_t, long>>(bad_file, threads, parse);
      FAIL() << "no error";
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()), "bad.csv:30002: column 'i': expected an integer, got '3x000'");
    }
  }
  EXPECT_EQ(file.lineOfDataRow(0), 2);
  EXPECT_EQ(file.lineOfDataRow(49999), 50001);
  EXPECT_EQ(file.lineOfDataRow(50000), 0);
}

TEST(TextParse, ByteOrderMarkAndEmptyFile) {
  TextFile bom = TextFile::fromString("\xEF\xBB\xBF#header\n1,2\n", "bom.csv");
  TextLines lines = bom.lines();
  std::string_view line;
  ASSERT_TRUE(lines.nextData(&line));
  EXPECT_EQ(line, "1,2");
  EXPECT_EQ(lines.line(), 2);
  // The same from a file on disk (memory-mapped).
  const io_test::TempDir dir("bom");
  io_test::writeFile(dir / "bom.csv", "\xEF\xBB\xBF#header\r\n1,2\r\n");
  const TextFile mapped = TextFile::read((dir / "bom.csv").string());
  EXPECT_EQ(mapped.text(), "#header\r\n1,2\r\n");
  io_test::writeFile(dir / "empty.csv", "");
  EXPECT_EQ(TextFile::read((dir / "empty.csv").string()).sizeBytes(), 0u);
  const TextFile empty = TextFile::fromString("", "empty.csv");
  TextLines none = empty.lines();
  EXPECT_FALSE(none.next(&line));
  EXPECT_TRUE(parseRows<int>(empty, 4, [](const TextLines&, std::string_view) { return 1; }).empty());
}

TEST(TextParse, MissingFileAndDirectory) {
  try {
    TextFile::read("/nonexistent/linnet/x.csv");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "/nonexistent/linnet/x.csv: file not found");
  }
  EXPECT_THROW(TextFile::read("/tmp"), InputError);
}

}  // namespace
}  // namespace linnet::io
