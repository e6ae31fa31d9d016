// Software renderer of the simulator: z-buffered rasterisation of textured quads straight into the DISTORTED image.
//
// Instead of rendering a pinhole image and remapping it, every (super)sample of the output image is given its viewing
// ray once, at construction (the camera model's undistortion of the sample's pixel position). Planar quads stay
// straight in normalised (undistorted) coordinates, so coverage is an exact convex-polygon test there, depth 1/z is
// affine in (x, y), and texture coordinates follow from a per-quad homography. The result is the exact distorted
// image (radtan or any CameraModel), anti-aliased by mip-mapped texture lookups inside surfaces and by ss x ss
// supersampling of the pixels on geometric edges (adaptive: only where neighbouring pixels see different quads).
//
// Photometry (applied after the box filter): radiance = texture * shade * gain * vignetting, then sensor noise
// (read noise + shot noise), rounding to 8 bits. Everything is deterministic: the noise comes from a counter-based
// hash of (seed, pixel index), independent of threads and call order.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/core/pose.h"
#include "linnet/sim/scene.h"

namespace linnet::sim {

struct RenderOptions {
  int supersample = 2;            // samples per pixel along each axis (1 = no anti-aliasing)
  double near_m = 0.05;           // near clipping distance, m
  double background = 0.0;        // grey level where no surface is hit
  double read_noise = 1.2;        // sensor read noise std, grey levels
  double shot_noise = 0.04;       // photon noise: variance += shot_noise * grey level (grey levels^2)
  double vignetting = 0.25;       // relative brightness loss at the image corners (0 = none)
  double lod_bias = 0.0;          // mip level bias (negative = sharper, more aliasing), levels

  template <class V>
  void visit(V& v) {
    v("supersample", supersample, "samples per pixel per axis", 1, 4);
    v("near_m", near_m, "near clipping distance, m", 1e-3, 10.0);
    v("background", background, "grey level of empty space", 0.0, 255.0);
    v("read_noise", read_noise, "read noise std, grey levels", 0.0, 50.0);
    v("shot_noise", shot_noise, "shot noise variance per grey level", 0.0, 10.0);
    v("vignetting", vignetting, "brightness loss at the corners, fraction", 0.0, 0.9);
    v("lod_bias", lod_bias, "mip level bias, levels", -4.0, 4.0);
  }
};

/// Renders one camera. Construction precomputes the viewing rays of every sample (one undistortion each); rendering
/// is const and re-entrant (per-call buffers), so one Renderer may serve several threads.
class Renderer {
 public:
  /// Throws ConfigError on invalid options.
  Renderer(const CameraModel& camera, const RenderOptions& options);

  int width() const { return width_; }
  int height() const { return height_; }
  const RenderOptions& options() const { return options_; }

  /// Noise-free radiance image (CV_32FC1, grey levels before gain and vignetting) seen from camera pose T_W_C.
  cv::Mat renderRadiance(const Scene& scene, const Pose& T_W_C) const;

  /// Mean radiance over several camera poses (sub-frame averaging = motion blur). Throws UsageError if empty.
  cv::Mat renderRadianceBlurred(const Scene& scene, const std::vector<Pose>& T_W_C) const;

  /// Radiance -> 8-bit image: multiplies by `gain` and the vignetting, adds noise seeded by `seed`, rounds, clamps.
  cv::Mat expose(const cv::Mat& radiance, double gain, std::uint64_t seed) const;

  /// Convenience: expose(renderRadiance(scene, T_W_C), gain, seed).
  cv::Mat render(const Scene& scene, const Pose& T_W_C, double gain, std::uint64_t seed) const;

  /// Depth z (m, camera frame) at every pixel centre (no supersampling), 0 where nothing is hit. CV_32FC1.
  cv::Mat renderDepth(const Scene& scene, const Pose& T_W_C) const;
  /// Index of the quad seen at every pixel centre, -1 where nothing is hit. CV_32SC1.
  cv::Mat renderQuadIds(const Scene& scene, const Pose& T_W_C) const;

 private:
  // Viewing rays of a sample grid: normalised coordinates per sample, and per tile the bounding box of its samples.
  struct RayGrid {
    int cols = 0, rows = 0;          // samples
    std::vector<float> x, y;         // normalised coordinates, row-major; NaN where undistortion failed
    int tile = 16;                   // tile edge, samples
    int tiles_x = 0, tiles_y = 0;
    std::vector<float> tile_box;     // per tile: xmin, xmax, ymin, ymax
    std::vector<float> col_box;      // per column of tiles: xmin, xmax (union over its tiles)
    std::vector<float> row_box;      // per row of tiles: ymin, ymax
    float xmin = 0, xmax = 0, ymin = 0, ymax = 0;  // bounds of all samples
    double samples_per_unit = 1.0;   // samples per unit of normalised coordinate (~ f * ss), for mip selection
  };
  struct Raster;  // per-call buffers (defined in renderer.cc)

  static RayGrid makeGrid(const CameraModel& camera, int ss);
  void rasterise(const Scene& scene, const Pose& T_W_C, const RayGrid& grid, Raster* raster) const;

  RenderOptions options_;
  int width_ = 0, height_ = 0;
  RayGrid grid_ss_;            // supersampled grid
  RayGrid grid_1_;             // pixel centres
  std::vector<float> vignette_;  // per pixel factor in (0, 1]
};

}  // namespace linnet::sim
