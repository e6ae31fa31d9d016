// A small synthetic scene for the line front-end tests: grey planar quads in front of a pinhole stereo rig,
// rendered with sub-pixel polygon filling, a little blur and noise; ground-truth 3D edges to score detections.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "linnet/camera/distortion_models.h"
#include "linnet/core/pose.h"
#include "linnet/features/line_types.h"

namespace linnet::testing {

/// An image (752 x 480) whose pixels are the mean of grey(x, y) over a samples x samples grid of points in each
/// pixel's square: pixel-area coverage of sharp shapes.
inline cv::Mat coverageImage(const std::function<double(double, double)>& grey, int samples = 8) {
  cv::Mat img(480, 752, CV_8UC1);
  const double n = static_cast<double>(samples);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      double v = 0.0;
      for (int sy = 0; sy < samples; ++sy)
        for (int sx = 0; sx < samples; ++sx) v += grey(x - 0.5 + (sx + 0.5) / n, y - 0.5 + (sy + 0.5) / n);
      img.at<std::uint8_t>(y, x) = cv::saturate_cast<std::uint8_t>(v / (n * n));
    }
  return img;
}

struct SceneQuad {
  Vec3 corners[4];  // world frame, in order around the quad
  int grey = 128;
};

struct LineScene {
  std::vector<SceneQuad> quads;
  int background = 90;
};

/// Random fronto-parallel-ish quads at 2.5..7 m in front of a camera at the origin looking along +z (fixed seed).
inline LineScene makeScene(unsigned seed = 3, int count = 14) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(-2.6, 2.6), uy(-1.6, 1.6), uz(2.5, 7.0), us(0.4, 1.4), ua(-0.5, 0.5);
  std::uniform_int_distribution<int> ug(0, 11);
  LineScene scene;
  for (int k = 0; k < count; ++k) {
    SceneQuad q;
    const Vec3 c(ux(rng), uy(rng), uz(rng));
    const double w = us(rng), h = us(rng), yaw = ua(rng), roll = 0.6 * ua(rng);
    const Mat3 R = (Eigen::AngleAxisd(roll, Vec3::UnitZ()) * Eigen::AngleAxisd(yaw, Vec3::UnitY())).toRotationMatrix();
    const Vec3 ex = R * Vec3(w / 2, 0, 0), ey = R * Vec3(0, h / 2, 0);
    q.corners[0] = c - ex - ey;
    q.corners[1] = c + ex - ey;
    q.corners[2] = c + ex + ey;
    q.corners[3] = c - ex + ey;
    q.grey = 30 + 18 * ug(rng);  // 30 .. 228, never equal to the background (90 is not on the grid)
    if (q.grey == 84 || q.grey == 102) q.grey += 40;
    scene.quads.push_back(q);
  }
  return scene;
}

/// Renders the scene seen from camera pose T_W_C (pinhole, no distortion). Painter's algorithm by quad depth.
inline cv::Mat renderScene(const LineScene& scene, const PinholeCamera& cam, const Pose& T_W_C, double noise_sigma,
                           unsigned seed) {
  cv::Mat img(cam.height(), cam.width(), CV_8UC1, cv::Scalar(scene.background));
  const Pose T_C_W = T_W_C.inverse();
  std::vector<std::pair<double, int>> order;
  for (int k = 0; k < static_cast<int>(scene.quads.size()); ++k) {
    double z = 0.0;
    for (const Vec3& p : scene.quads[k].corners) z += (T_C_W * p).z();
    order.push_back({-z, k});
  }
  std::sort(order.begin(), order.end());
  constexpr int kShift = 4;
  for (const auto& [negz, k] : order) {
    std::vector<cv::Point> poly;
    bool ok = true;
    for (const Vec3& p : scene.quads[k].corners) {
      Vec2 px = Vec2::Zero();
      if (!cam.project(T_C_W * p, &px)) ok = false;
      poly.emplace_back(static_cast<int>(std::lround(px.x() * (1 << kShift))),
                        static_cast<int>(std::lround(px.y() * (1 << kShift))));
    }
    if (!ok) continue;
    cv::fillConvexPoly(img, poly, cv::Scalar(scene.quads[k].grey), cv::LINE_AA, kShift);
  }
  cv::GaussianBlur(img, img, cv::Size(5, 5), 0.8);
  if (noise_sigma > 0.0) {
    cv::Mat noise(img.size(), CV_16SC1);
    cv::RNG rng(seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, noise_sigma);
    cv::Mat img16;
    img.convertTo(img16, CV_16SC1);
    img16 += noise;
    img16.convertTo(img, CV_8UC1);
  }
  return img;
}

/// Projected ground-truth edges (pixels) of every quad visible in front of the camera, index = 4 * quad + edge.
inline std::vector<LineSegment> projectEdges(const LineScene& scene, const PinholeCamera& cam, const Pose& T_W_C) {
  std::vector<LineSegment> edges;
  const Pose T_C_W = T_W_C.inverse();
  for (const SceneQuad& q : scene.quads)
    for (int e = 0; e < 4; ++e) {
      LineSegment s;
      Vec2 a = Vec2::Zero(), b = Vec2::Zero();
      const bool ok = cam.project(T_C_W * q.corners[e], &a) && cam.project(T_C_W * q.corners[(e + 1) % 4], &b);
      s.s = ok ? a : Vec2(-1e6, -1e6);
      s.e = ok ? b : Vec2(-1e6, -1e6);
      edges.push_back(s);
    }
  return edges;
}

/// The ground-truth edge a detected segment lies on: both endpoints within tol_px of the edge's line and at least
/// min_overlap of the detection inside the edge's extent. -1 if none.
inline int assignEdge(const LineSegment& det, const std::vector<LineSegment>& edges, double tol_px = 2.0,
                      double min_overlap = 0.5) {
  int best = -1;
  double best_d = tol_px;
  for (int k = 0; k < static_cast<int>(edges.size()); ++k) {
    const LineSegment& g = edges[k];
    const double len = g.length();
    if (!(len > 1.0) || g.s.x() < -1e5) continue;
    const Vec2 d = g.direction(), n(-d.y(), d.x());
    const double ds = std::abs((det.s - g.s).dot(n)), de = std::abs((det.e - g.s).dot(n));
    const double dmax = std::max(ds, de);
    if (dmax > best_d) continue;
    double t0 = (det.s - g.s).dot(d), t1 = (det.e - g.s).dot(d);
    if (t0 > t1) std::swap(t0, t1);
    const double inter = std::min(t1, len) - std::max(t0, 0.0);
    if (inter < min_overlap * std::max(1e-9, t1 - t0)) continue;
    best_d = dmax;
    best = k;
  }
  return best;
}

}  // namespace linnet::testing
