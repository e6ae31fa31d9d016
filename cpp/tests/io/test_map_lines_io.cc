// The line map on disk: csv round trip (ids, bit-exact coordinates, observation counts, last time, angle and
// endpoint sigma, infinite included), the older 8- and 10-column rows, line-numbered errors on malformed rows, and
// line maps as PLY edges.
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "io_test_util.h"
#include "linnet/core/error.h"
#include "linnet/io/map_io.h"

namespace linnet {
namespace {

std::vector<MapLine> randomLines(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<MapLine> lines;
  for (int i = 0; i < n; ++i) {
    MapLine l;
    l.id = i % 3 == 0 ? std::numeric_limits<std::int64_t>::max() - i : 17 * i;
    l.a = Vec3(g(rng), g(rng), g(rng)) * 10.0;
    l.b = l.a + Vec3(g(rng), g(rng), g(rng)) * std::pow(10.0, i % 7 - 3);
    l.observations = 2 + i;
    l.t_last = 1'403'715'273'262'142'976 + 50'000'000LL * i;
    l.angle_deg = 90.0 * std::abs(g(rng)) / 3.0;
    l.sigma_m = i % 4 == 1 ? std::numeric_limits<double>::infinity() : 0.01 * std::abs(g(rng));
    lines.push_back(l);
  }
  // Values whose shortest text is long or special.
  lines[0].a = Vec3(1.0 / 3.0, -0.0, 1e-300);
  lines[0].b = Vec3(std::nextafter(1.0, 2.0), -1.7976931348623157e308, 4.9406564584124654e-324);
  return lines;
}

std::string readError(const std::string& path) {
  try {
    readMapLinesCsv(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(MapLinesIo, CsvRoundTripIsExact) {
  const io_test::TempDir dir("lines_csv");
  const std::vector<MapLine> lines = randomLines(50, 5);
  const std::string path = (dir / "lines.csv").string();
  writeMapLinesCsv(path, lines);
  const std::string header = io_test::headLines(path, 1);
  EXPECT_EQ(header.rfind("#id,x0 [m],y0 [m],z0 [m],x1 [m],y1 [m],z1 [m],observations", 0), 0u) << header;
  const std::vector<MapLine> back = readMapLinesCsv(path);
  ASSERT_EQ(back.size(), lines.size());
  for (std::size_t i = 0; i < lines.size(); ++i) {
    EXPECT_EQ(back[i].id, lines[i].id) << i;
    for (int k = 0; k < 3; ++k) {
      // Bit-exact, including the sign of zero.
      EXPECT_EQ(std::signbit(back[i].a[k]), std::signbit(lines[i].a[k])) << i;
      EXPECT_EQ(back[i].a[k], lines[i].a[k]) << i << " " << k;
      EXPECT_EQ(back[i].b[k], lines[i].b[k]) << i << " " << k;
    }
    EXPECT_EQ(back[i].observations, lines[i].observations) << i;
    EXPECT_EQ(back[i].t_last, lines[i].t_last) << i;
    EXPECT_EQ(back[i].angle_deg, lines[i].angle_deg) << i;
    EXPECT_EQ(back[i].sigma_m, lines[i].sigma_m) << i;
  }
  // Writing what was read gives the same file.
  writeMapLinesCsv((dir / "again.csv").string(), back);
  EXPECT_EQ(io_test::headLines(dir / "again.csv", 100), io_test::headLines(path, 100));
  // An empty map: just the header, read back as nothing.
  writeMapLinesCsv(path, {});
  EXPECT_EQ(io_test::headLines(path, 5).find('\n'), io_test::headLines(path, 5).size() - 1);
  EXPECT_TRUE(readMapLinesCsv(path).empty());
}

TEST(MapLinesIo, OlderEightColumnRowsAndBlankLines) {
  const io_test::TempDir dir("lines_old");
  const std::string path = (dir / "old.csv").string();
  io_test::writeFile(path, "#id,x0,y0,z0,x1,y1,z1,observations\n3,1,2,3,4,5,6,7\n\n-4,0.5,0,0,1e3,0,0,0\r\n");
  const std::vector<MapLine> back = readMapLinesCsv(path);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].id, 3);
  EXPECT_EQ(back[0].a, Vec3(1, 2, 3));
  EXPECT_EQ(back[0].b, Vec3(4, 5, 6));
  EXPECT_EQ(back[0].observations, 7);
  EXPECT_EQ(back[0].t_last, 0);
  EXPECT_EQ(back[0].angle_deg, 0.0);
  EXPECT_EQ(back[1].id, -4);
  EXPECT_EQ(back[1].b, Vec3(1000, 0, 0));
  EXPECT_EQ(back[1].observations, 0);
  EXPECT_TRUE(std::isinf(back[1].sigma_m));
  // 10 columns (before the endpoint sigma): time and angle read, sigma unknown.
  io_test::writeFile(path, "#id,x0,y0,z0,x1,y1,z1,observations,t_last,angle\n3,1,2,3,4,5,6,7,100,2.5\n");
  const std::vector<MapLine> ten = readMapLinesCsv(path);
  ASSERT_EQ(ten.size(), 1u);
  EXPECT_EQ(ten[0].t_last, 100);
  EXPECT_EQ(ten[0].angle_deg, 2.5);
  EXPECT_TRUE(std::isinf(ten[0].sigma_m));
}

TEST(MapLinesIo, MalformedRowsNameTheFileAndLine) {
  const io_test::TempDir dir("lines_bad");
  const std::string header = "#id,x0 [m],y0 [m],z0 [m],x1 [m],y1 [m],z1 [m],observations,t_last [ns],angle\n";
  const std::string good = "1,0,0,0,1,1,1,3,100,2.5\n";
  const struct {
    const char* name;
    std::string text;
    int line;
    const char* what;  // part of the message
  } cases[] = {
      {"few.csv", header + good + "2,0,0,0,1,1\n", 3, "columns"},
      {"nine.csv", header + "2,0,0,0,1,1,1,3,100\n", 2, "columns"},
      {"many.csv", header + good + good + "2,0,0,0,1,1,1,3,100,2.5,0.1,7\n", 4, "columns"},
      {"sigma.csv", header + "2,0,0,0,1,1,1,3,100,2.5,tight\n", 2, "tight"},
      {"id.csv", header + "x,0,0,0,1,1,1,3,100,2.5\n", 2, "'id'"},
      {"coord.csv", header + good + "2,0,abc,0,1,1,1,3,100,2.5\n", 3, "abc"},
      {"empty_field.csv", header + "2,0,0,,1,1,1,3,100,2.5\n", 2, "expected a number"},
      {"obs.csv", header + "2,0,0,0,1,1,1,-3,100,2.5\n", 2, "negative"},
      {"obs_float.csv", header + "2,0,0,0,1,1,1,3.5,100,2.5\n", 2, "observations"},
      {"t.csv", header + "2,0,0,0,1,1,1,3,1.5e9,2.5\n", 2, "t_last"},
      {"angle.csv", header + "2,0,0,0,1,1,1,3,100,wide\n", 2, "wide"},
  };
  for (const auto& c : cases) {
    const std::string path = (dir / c.name).string();
    io_test::writeFile(path, c.text);
    const std::string what = readError(path);
    const std::string prefix = path + ":" + std::to_string(c.line) + ": ";
    EXPECT_EQ(what.rfind(prefix, 0), 0u) << c.name << ": '" << what << "'";
    EXPECT_NE(what.find(c.what), std::string::npos) << c.name << ": '" << what << "'";
  }
  const std::string absent = (dir / "absent.csv").string();
  EXPECT_EQ(readError(absent), absent + ": file not found");
  EXPECT_THROW(writeMapLinesCsv((dir / "no_dir" / "x.csv").string(), randomLines(2, 1)), InputError);
}

TEST(MapLinesIo, LineMapAsPlyEdges) {
  const io_test::TempDir dir("lines_ply");
  const std::vector<MapLine> lines = randomLines(20, 9);
  MapGeometry map;
  for (const MapLine& l : lines) map.segments.push_back({l.a, l.b});
  const std::string path = (dir / "lines.ply").string();
  writePly(path, map);
  const MapGeometry back = readPly(path);
  EXPECT_TRUE(back.points.empty());
  EXPECT_TRUE(back.segment_colors.empty());
  ASSERT_EQ(back.segments.size(), map.segments.size());
  for (std::size_t i = 0; i < map.segments.size(); ++i) {
    EXPECT_EQ(back.segments[i].a, map.segments[i].a) << i;
    EXPECT_EQ(back.segments[i].b, map.segments[i].b) << i;
  }

  // With points and colours; a zero-length segment and a segment sharing a point's coordinates stay segments.
  map.segments.push_back({Vec3(1, 1, 1), Vec3(1, 1, 1)});
  map.points = {Vec3(1, 1, 1), Vec3(-2, 0.5, 3)};
  map.point_colors = {{1, 2, 3}, {4, 5, 6}};
  for (std::size_t i = 0; i < map.segments.size(); ++i)
    map.segment_colors.push_back({static_cast<std::uint8_t>(i), 200, static_cast<std::uint8_t>(255 - i)});
  writePly(path, map);
  const MapGeometry back2 = readPly(path);
  ASSERT_EQ(back2.points.size(), 2u);
  ASSERT_EQ(back2.segments.size(), map.segments.size());
  ASSERT_EQ(back2.segment_colors.size(), map.segments.size());
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(back2.points[i], map.points[i]);
    EXPECT_EQ(back2.point_colors[i], map.point_colors[i]);
  }
  for (std::size_t i = 0; i < map.segments.size(); ++i) {
    EXPECT_EQ(back2.segments[i].a, map.segments[i].a) << i;
    EXPECT_EQ(back2.segments[i].b, map.segments[i].b) << i;
    EXPECT_EQ(back2.segment_colors[i], map.segment_colors[i]) << i;
  }
}

}  // namespace
}  // namespace linnet
