// Point-and-line maps as files that 3D viewers open (MeshLab, CloudCompare, Open3D, Blender).
//
// PLY (ascii 1.0): element "vertex" with x y z (double) and, when colours are given, red green blue (uchar);
// line segments are element "edge" (vertex1 vertex2, int) over two extra vertices per segment, appended after
// the map points. OBJ: "v x y z [r g b]" lines (colour as floats in [0, 1]) and "l i j" segments (1-based).
// Coordinates are written with the shortest text that reads back to the same double.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "linnet/core/map_line.h"
#include "linnet/core/types.h"

namespace linnet {

using Rgb = std::array<std::uint8_t, 3>;

/// A 3D line segment with end points in the world frame.
struct Segment3 {
  Vec3 a = Vec3::Zero();
  Vec3 b = Vec3::Zero();
};

/// What a map file holds: points (optionally coloured) and line segments (optionally coloured).
struct MapGeometry {
  std::vector<Vec3> points;
  std::vector<Rgb> point_colors;  // empty, or one per point
  std::vector<Segment3> segments;
  std::vector<Rgb> segment_colors;  // empty, or one per segment
};

/// Writes a PLY file. UsageError if a colour list has the wrong length, InputError if the file cannot be
/// written. Colours are written if either list is non-empty (uncoloured items get `default_color`).
void writePly(const std::string& path, const MapGeometry& map, const Rgb& default_color = {200, 200, 200});
/// Writes an OBJ file (same rules).
void writeObj(const std::string& path, const MapGeometry& map, const Rgb& default_color = {200, 200, 200});
/// By extension: ".obj" -> OBJ, else PLY.
void writeMap(const std::string& path, const MapGeometry& map);

/// Writes the line map as csv: a header `#id,x0 [m],y0 [m],z0 [m],x1 [m],y1 [m],z1 [m],observations,t_last [ns],
/// triangulation_angle [deg],endpoint_sigma [m]`, then one line per map line (W, metres). InputError if the file
/// cannot be written.
void writeMapLinesCsv(const std::string& path, const std::vector<MapLine>& lines);
/// Reads a file written by writeMapLinesCsv (older files with 8 or 10 columns are accepted). InputError
/// "<file>:<line>: ..." on bad content.
std::vector<MapLine> readMapLinesCsv(const std::string& path);

/// Reads an ascii PLY with vertex x y z [red green blue] and optional edge elements (as written by writePly):
/// vertices used by edges become segments, the others points. InputError "<file>:<line>: ..." on bad content.
MapGeometry readPly(const std::string& path);

}  // namespace linnet
