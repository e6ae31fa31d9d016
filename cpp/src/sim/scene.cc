#include "linnet/sim/scene.h"

#include <algorithm>
#include <string>

#include <opencv2/imgproc.hpp>

#include "linnet/core/error.h"

namespace linnet::sim {

Texture::Texture(const cv::Mat& image) {
  if (image.type() != CV_8UC1 || image.cols < 2 || image.rows < 2)
    throw InputError("sim::Texture: expected an 8-bit single-channel image of at least 2x2 texels, got type " +
                     std::to_string(image.type()) + " of " + std::to_string(image.cols) + "x" +
                     std::to_string(image.rows));
  levels_.push_back(image.clone());
  // Gaussian pyramid: each level low-passes before halving, which is what keeps far surfaces from aliasing.
  while (levels_.back().cols >= 8 && levels_.back().rows >= 8) {
    cv::Mat next;
    cv::pyrDown(levels_.back(), next);
    levels_.push_back(next);
  }
}

int Scene::addTexture(const cv::Mat& image) {
  textures_.emplace_back(image);
  return static_cast<int>(textures_.size()) - 1;
}

void Scene::addQuad(const Quad& quad) {
  const std::string where = "sim::Scene::addQuad (quad " + std::to_string(quads_.size()) + "): ";
  if (quad.texture < 0 || quad.texture >= static_cast<int>(textures_.size()))
    throw InputError(where + "texture index " + std::to_string(quad.texture) + " is not in [0, " +
                     std::to_string(textures_.size()) + ")");
  if (quad.axis_u.cross(quad.axis_v).norm() < 1e-12 * std::max(1.0, quad.axis_u.squaredNorm()))
    throw InputError(where + "axis_u and axis_v are parallel or zero");
  if (!(quad.shade >= 0.0)) throw InputError(where + "shade must be >= 0");
  if (!quad.origin.allFinite() || !quad.axis_u.allFinite() || !quad.axis_v.allFinite())
    throw InputError(where + "non-finite coordinates");
  quads_.push_back(quad);
}

}  // namespace linnet::sim
