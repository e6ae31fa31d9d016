#include "linnet/io/map_io.h"

#include <cctype>
#include <string_view>

#include "linnet/core/error.h"
#include "linnet/io/config_yaml.h"
#include "linnet/io/text_parse.h"

namespace linnet {
namespace {

void checkColors(const MapGeometry& map) {
  if (!map.point_colors.empty() && map.point_colors.size() != map.points.size())
    throw UsageError("map writer: " + std::to_string(map.point_colors.size()) + " point colours for " +
                     std::to_string(map.points.size()) + " points");
  if (!map.segment_colors.empty() && map.segment_colors.size() != map.segments.size())
    throw UsageError("map writer: " + std::to_string(map.segment_colors.size()) + " segment colours for " +
                     std::to_string(map.segments.size()) + " segments");
}

void appendVec(std::string* out, const Vec3& v) {
  out->append(io::formatDouble(v.x())).push_back(' ');
  out->append(io::formatDouble(v.y())).push_back(' ');
  out->append(io::formatDouble(v.z()));
}

void appendRgb(std::string* out, const Rgb& c) {
  for (std::uint8_t x : c) out->append(" ").append(std::to_string(static_cast<int>(x)));
}

std::string lowerExt(const std::string& path) {
  const auto dot = path.rfind('.');
  std::string ext = dot == std::string::npos ? "" : path.substr(dot + 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

}  // namespace

void writePly(const std::string& path, const MapGeometry& map, const Rgb& default_color) {
  checkColors(map);
  const bool colored = !map.point_colors.empty() || !map.segment_colors.empty();
  const std::size_t n_vertices = map.points.size() + 2 * map.segments.size();
  std::string text = "ply\nformat ascii 1.0\ncomment Linnet point-and-line map (world frame, metres)\n";
  text += "element vertex " + std::to_string(n_vertices) + "\n";
  text += "property double x\nproperty double y\nproperty double z\n";
  if (colored) text += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (!map.segments.empty())
    text += "element edge " + std::to_string(map.segments.size()) +
            "\nproperty int vertex1\nproperty int vertex2\n";
  text += "end_header\n";
  text.reserve(text.size() + n_vertices * 64 + map.segments.size() * 16);
  for (std::size_t i = 0; i < map.points.size(); ++i) {
    appendVec(&text, map.points[i]);
    if (colored) appendRgb(&text, map.point_colors.empty() ? default_color : map.point_colors[i]);
    text.push_back('\n');
  }
  for (std::size_t i = 0; i < map.segments.size(); ++i) {
    const Rgb& c = map.segment_colors.empty() ? default_color : map.segment_colors[i];
    for (const Vec3* v : {&map.segments[i].a, &map.segments[i].b}) {
      appendVec(&text, *v);
      if (colored) appendRgb(&text, c);
      text.push_back('\n');
    }
  }
  const std::size_t base = map.points.size();
  for (std::size_t i = 0; i < map.segments.size(); ++i)
    text += std::to_string(base + 2 * i) + " " + std::to_string(base + 2 * i + 1) + "\n";
  writeTextFile(path, text);
}

void writeObj(const std::string& path, const MapGeometry& map, const Rgb& default_color) {
  checkColors(map);
  const bool colored = !map.point_colors.empty() || !map.segment_colors.empty();
  std::string text = "# Linnet point-and-line map (world frame, metres)\n";
  auto vertex = [&](const Vec3& v, const Rgb& c) {
    text += "v ";
    appendVec(&text, v);
    if (colored)
      for (std::uint8_t x : c) text.append(" ").append(io::formatDouble(x / 255.0));
    text.push_back('\n');
  };
  for (std::size_t i = 0; i < map.points.size(); ++i)
    vertex(map.points[i], map.point_colors.empty() ? default_color : map.point_colors[i]);
  for (std::size_t i = 0; i < map.segments.size(); ++i) {
    const Rgb& c = map.segment_colors.empty() ? default_color : map.segment_colors[i];
    vertex(map.segments[i].a, c);
    vertex(map.segments[i].b, c);
  }
  const std::size_t base = map.points.size() + 1;  // OBJ indices are 1-based
  for (std::size_t i = 0; i < map.segments.size(); ++i)
    text += "l " + std::to_string(base + 2 * i) + " " + std::to_string(base + 2 * i + 1) + "\n";
  writeTextFile(path, text);
}

void writeMap(const std::string& path, const MapGeometry& map) {
  if (lowerExt(path) == "obj")
    writeObj(path, map);
  else
    writePly(path, map);
}

MapGeometry readPly(const std::string& path) {
  const io::TextFile file = io::TextFile::read(path);
  io::TextLines lines = file.lines();
  std::string_view line;
  std::string_view f[16];

  struct Element {
    std::string name;
    long count = 0;
    std::vector<std::string> properties;
  };
  std::vector<Element> elements;
  if (!lines.next(&line) || line != "ply") lines.fail("not a PLY file (first line must be 'ply')");
  bool ascii = false, header_done = false;
  while (lines.next(&line)) {
    const int n = io::splitFields(line, ' ', f, 16);
    if (n == 0) continue;
    if (f[0] == "end_header") {
      header_done = true;
      break;
    }
    if (f[0] == "comment" || f[0] == "obj_info") continue;
    if (f[0] == "format") {
      if (n < 2 || f[1] != "ascii") lines.fail("only 'format ascii 1.0' PLY files are supported");
      ascii = true;
    } else if (f[0] == "element") {
      std::int64_t count = 0;
      if (n != 3 || !io::parseInt64(f[2], &count) || count < 0) lines.fail("bad element line");
      elements.push_back({std::string(f[1]), static_cast<long>(count), {}});
    } else if (f[0] == "property") {
      if (elements.empty() || n < 3) lines.fail("property outside an element");
      if (f[1] == "list") lines.fail("list properties are not supported (faces)");
      elements.back().properties.emplace_back(f[n - 1]);
    } else {
      lines.fail("unknown header line '" + std::string(line) + "'");
    }
  }
  if (!header_done) lines.fail("header has no end_header");
  if (!ascii) lines.fail("header has no 'format ascii 1.0' line");

  std::vector<Vec3> vertices;
  std::vector<Rgb> colors;
  std::vector<std::pair<long, long>> edges;
  for (const Element& e : elements) {
    const auto index = [&](const char* name) {
      for (std::size_t i = 0; i < e.properties.size(); ++i)
        if (e.properties[i] == name) return static_cast<int>(i);
      return -1;
    };
    const int np = static_cast<int>(e.properties.size());
    if (np > 16) lines.fail("element '" + e.name + "' has more than 16 properties");
    const int ix = index("x"), iy = index("y"), iz = index("z"), ir = index("red"), ig = index("green"),
              ib = index("blue"), i1 = index("vertex1"), i2 = index("vertex2");
    if (e.name == "vertex" && (ix < 0 || iy < 0 || iz < 0)) lines.fail("vertex element without x, y, z");
    if (e.name == "edge" && (i1 < 0 || i2 < 0)) lines.fail("edge element without vertex1, vertex2");
    for (long k = 0; k < e.count; ++k) {
      if (!lines.next(&line))
        lines.fail("file ends inside element '" + e.name + "' (" + std::to_string(k) + " of " +
                   std::to_string(e.count) + " rows)");
      const int n = io::splitFields(line, ' ', f, 16);
      if (n != np)
        lines.fail("element '" + e.name + "' row has " + std::to_string(n) + " values, expected " +
                   std::to_string(np));
      if (e.name == "vertex") {
        vertices.emplace_back(io::parseDoubleField(lines, f[ix], "x"),
                              io::parseDoubleField(lines, f[iy], "y"),
                              io::parseDoubleField(lines, f[iz], "z"));
        if (ir >= 0 && ig >= 0 && ib >= 0) {
          Rgb c{};
          const int idx[3] = {ir, ig, ib};
          for (int j = 0; j < 3; ++j) {
            const std::int64_t v = io::parseInt64Field(lines, f[idx[j]], "colour");
            if (v < 0 || v > 255) lines.fail("colour value out of [0, 255]");
            c[static_cast<std::size_t>(j)] = static_cast<std::uint8_t>(v);
          }
          colors.push_back(c);
        }
      } else if (e.name == "edge") {
        const std::int64_t a = io::parseInt64Field(lines, f[i1], "vertex1");
        const std::int64_t b = io::parseInt64Field(lines, f[i2], "vertex2");
        if (a < 0 || b < 0 || a >= static_cast<std::int64_t>(vertices.size()) ||
            b >= static_cast<std::int64_t>(vertices.size()))
          lines.fail("edge refers to a vertex that does not exist");
        edges.emplace_back(static_cast<long>(a), static_cast<long>(b));
      }
    }
  }

  MapGeometry map;
  std::vector<bool> used(vertices.size(), false);
  for (const auto& [a, b] : edges)
    used[static_cast<std::size_t>(a)] = used[static_cast<std::size_t>(b)] = true;
  const bool has_colors = !colors.empty();
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    if (used[i]) continue;
    map.points.push_back(vertices[i]);
    if (has_colors) map.point_colors.push_back(colors[i]);
  }
  for (const auto& [a, b] : edges) {
    map.segments.push_back({vertices[static_cast<std::size_t>(a)], vertices[static_cast<std::size_t>(b)]});
    if (has_colors) map.segment_colors.push_back(colors[static_cast<std::size_t>(a)]);
  }
  return map;
}

void writeMapLinesCsv(const std::string& path, const std::vector<MapLine>& lines) {
  std::string text =
      "#id,x0 [m],y0 [m],z0 [m],x1 [m],y1 [m],z1 [m],observations,t_last [ns],triangulation_angle [deg],"
      "endpoint_sigma [m]\n";
  text.reserve(text.size() + lines.size() * 128);
  for (const MapLine& l : lines) {
    text += std::to_string(l.id);
    for (const Vec3* v : {&l.a, &l.b})
      for (int k = 0; k < 3; ++k) text.append(",").append(io::formatDouble((*v)[k]));
    text += "," + std::to_string(l.observations) + "," + std::to_string(l.t_last) + "," +
            io::formatDouble(l.angle_deg) + "," + io::formatDouble(l.sigma_m) + "\n";
  }
  writeTextFile(path, text);
}

std::vector<MapLine> readMapLinesCsv(const std::string& path) {
  const io::TextFile file = io::TextFile::read(path);
  io::TextLines lines = file.lines();
  std::string_view line;
  std::string_view f[12];
  std::vector<MapLine> out;
  while (lines.next(&line)) {
    if (line.empty() || line.front() == '#') continue;
    const int n = io::splitFields(line, ',', f, 12);
    if (n != 8 && n != 10 && n != 11)
      lines.fail("expected 8, 10 or 11 columns "
                 "(id,x0,y0,z0,x1,y1,z1,observations[,t_last,triangulation_angle[,endpoint_sigma]]), got " +
                 std::to_string(n));
    MapLine l;
    l.id = io::parseInt64Field(lines, f[0], "id");
    for (int k = 0; k < 3; ++k) {
      l.a[k] = io::parseDoubleField(lines, f[1 + k], "x0/y0/z0");
      l.b[k] = io::parseDoubleField(lines, f[4 + k], "x1/y1/z1");
    }
    const std::int64_t obs = io::parseInt64Field(lines, f[7], "observations");
    if (obs < 0) lines.fail("negative observation count");
    l.observations = static_cast<int>(obs);
    if (n >= 10) {
      l.t_last = io::parseInt64Field(lines, f[8], "t_last");
      l.angle_deg = io::parseDoubleField(lines, f[9], "triangulation_angle");
    }
    if (n == 11) l.sigma_m = io::parseDoubleField(lines, f[10], "endpoint_sigma");
    out.push_back(l);
  }
  return out;
}

}  // namespace linnet
