// A renderable scene for the trajectory-replay simulator: textured planar quads in the world frame W.
//
// Every surface is a parallelogram  X(s, t) = origin + s * axis_u + t * axis_v,  s, t in [0, 1],  with a grey-level
// texture stretched over it (texel (0, 0) at the origin, columns along axis_u, rows along axis_v). Boxes, walls,
// posters and frames are all made of such quads, so every straight edge of the scene is known exactly in 3D and can be
// written out as ground truth for scoring front-ends.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/core/types.h"

namespace linnet::sim {

/// One textured parallelogram in W.
struct Quad {
  Vec3 origin = Vec3::Zero();   // corner at texture coordinate (0, 0), m, in W
  Vec3 axis_u = Vec3::UnitX();  // edge from the origin to texture coordinate (1, 0), m
  Vec3 axis_v = Vec3::UnitY();  // edge from the origin to texture coordinate (0, 1), m (not parallel to axis_u)
  int texture = 0;              // index into Scene::textures()
  double shade = 1.0;           // radiance factor of this face (a crude fixed lighting), >= 0
};

/// A grey-level texture with its mip-map pyramid (level 0 = the full-resolution image).
class Texture {
 public:
  /// `image` is CV_8UC1, at least 2x2. Levels are built by Gaussian pyramid reduction down to ~4 texels.
  explicit Texture(const cv::Mat& image);

  int levels() const { return static_cast<int>(levels_.size()); }
  const cv::Mat& level(int i) const { return levels_[static_cast<std::size_t>(i)]; }
  int width() const { return levels_.front().cols; }
  int height() const { return levels_.front().rows; }

 private:
  std::vector<cv::Mat> levels_;  // CV_8UC1 each
};

/// Textures + quads. Immutable once handed to the renderer (the renderer only reads it).
class Scene {
 public:
  /// Adds a texture (CV_8UC1, copied) and returns its index. Throws InputError on a wrong type or size.
  int addTexture(const cv::Mat& image);
  /// Adds a quad. Throws InputError if its texture index is unknown, its axes are degenerate or shade < 0.
  void addQuad(const Quad& quad);

  const std::vector<Texture>& textures() const { return textures_; }
  const std::vector<Quad>& quads() const { return quads_; }

 private:
  std::vector<Texture> textures_;
  std::vector<Quad> quads_;
};

}  // namespace linnet::sim
