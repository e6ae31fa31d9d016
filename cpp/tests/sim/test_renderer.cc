// Unit tests of the simulator's rasteriser: coverage, depth, z-buffer, texture mapping, distortion, photometry.
#include <cmath>

#include <gtest/gtest.h>

#include "linnet/core/error.h"
#include "linnet/sim/renderer.h"

namespace linnet::sim {
namespace {

/// Test camera: pinhole with an optional one-coefficient radial distortion x_d = x (1 + k1 r^2).
class TestCamera : public CameraModel {
 public:
  TestCamera(int w, int h, double f, double k1 = 0.0) : CameraModel(w, h, f, f, (w - 1) / 2.0, (h - 1) / 2.0), k1_(k1) {}
  using CameraModel::distort;
  std::string distortionName() const override { return "test_radial"; }
  std::vector<double> distortionCoeffs() const override { return {k1_}; }
  Vec2 distort(const Vec2& uv, Mat2* J) const override {
    const double s = 1.0 + k1_ * uv.squaredNorm();
    if (J) *J = Mat2::Identity();  // not used by the renderer
    return Vec2(fx_ * uv.x() * s + cx_, fy_ * uv.y() * s + cy_);
  }
  bool undistort(const Vec2& px, Vec2* uv) const override {
    const Vec2 d((px.x() - cx_) / fx_, (px.y() - cy_) / fy_);
    Vec2 u = d;
    for (int i = 0; i < 50; ++i) u = d / (1.0 + k1_ * u.squaredNorm());
    *uv = u;
    return true;
  }

 private:
  double k1_;
};

RenderOptions cleanOptions(int ss = 2) {
  RenderOptions o;
  o.supersample = ss;
  o.read_noise = 0.0;
  o.shot_noise = 0.0;
  o.vignetting = 0.0;
  return o;
}

cv::Mat uniformTexture(int value) { return cv::Mat(8, 8, CV_8UC1, cv::Scalar(value)); }

/// A texture black on the left half (s < 0.5) and white on the right half.
cv::Mat stepTexture() {
  cv::Mat t(64, 64, CV_8UC1, cv::Scalar(0));
  t.colRange(32, 64).setTo(200);
  return t;
}

/// Quad in the plane z = depth (camera = world frame), covering [x0, x1] x [y0, y1] metres.
Quad frontalQuad(double x0, double x1, double y0, double y1, double depth, int texture) {
  Quad q;
  q.origin = Vec3(x0, y0, depth);
  q.axis_u = Vec3(x1 - x0, 0, 0);
  q.axis_v = Vec3(0, y1 - y0, 0);
  q.texture = texture;
  return q;
}

TEST(SimRenderer, DepthOfFrontalAndTiltedPlanes) {
  TestCamera cam(160, 120, 100.0);
  Renderer renderer(cam, cleanOptions());
  Scene scene;
  const int tex = scene.addTexture(uniformTexture(100));
  scene.addQuad(frontalQuad(-10, 10, -10, 10, 3.0, tex));
  const cv::Mat depth = renderer.renderDepth(scene, Pose());
  for (int r = 0; r < depth.rows; r += 7)
    for (int c = 0; c < depth.cols; c += 7) EXPECT_NEAR(depth.at<float>(r, c), 3.0f, 1e-4f);

  // Plane z = 2 + 0.5 x (tilted about the y axis): depth along each ray is 2 / (1 - 0.5 x_n).
  Scene tilted;
  const int t2 = tilted.addTexture(uniformTexture(100));
  Quad q;
  q.origin = Vec3(-3, -3, 2 - 1.5);
  q.axis_u = Vec3(6, 0, 3);
  q.axis_v = Vec3(0, 6, 0);
  q.texture = t2;
  tilted.addQuad(q);
  const cv::Mat d2 = renderer.renderDepth(tilted, Pose());
  for (int c = 0; c < d2.cols; c += 9) {
    const double xn = (c - cam.cx()) / cam.fx();
    EXPECT_NEAR(d2.at<float>(60, c), 2.0 / (1.0 - 0.5 * xn), 1e-3) << "column " << c;
  }
}

TEST(SimRenderer, CoverageMatchesProjectedCorners) {
  TestCamera cam(200, 160, 120.0);
  Renderer renderer(cam, cleanOptions(4));
  Scene scene;
  const int white = scene.addTexture(uniformTexture(200));
  // Quad edges project to x = cx + 120 * (-0.5/2) = cx - 30 and cx + 40; y = cy - 24 and cy + 36.
  scene.addQuad(frontalQuad(-0.5, 0.6667, -0.4, 0.6, 2.0, white));
  const cv::Mat img = renderer.renderRadiance(scene, Pose());
  // The sum of coverage along a row equals the projected width (anti-aliased edges give fractional pixels).
  const int row = static_cast<int>(cam.cy());
  double covered = 0.0;
  for (int c = 0; c < img.cols; ++c) covered += img.at<float>(row, c) / 200.0;
  EXPECT_NEAR(covered, 120.0 * (0.6667 + 0.5) / 2.0, 0.3);
  double covered_v = 0.0;
  const int col = static_cast<int>(cam.cx());
  for (int r = 0; r < img.rows; ++r) covered_v += img.at<float>(r, col) / 200.0;
  EXPECT_NEAR(covered_v, 120.0 * 1.0 / 2.0, 0.3);
  const cv::Mat ids = renderer.renderQuadIds(scene, Pose());
  EXPECT_EQ(ids.at<int>(row, col), 0);
  EXPECT_EQ(ids.at<int>(2, 2), -1);
}

TEST(SimRenderer, ZBufferKeepsTheNearestSurfaceWhateverTheOrder) {
  TestCamera cam(120, 90, 80.0);
  Renderer renderer(cam, cleanOptions());
  for (int order = 0; order < 2; ++order) {
    Scene scene;
    const int dark = scene.addTexture(uniformTexture(50));
    const int bright = scene.addTexture(uniformTexture(180));
    const Quad far = frontalQuad(-5, 5, -5, 5, 4.0, dark);
    const Quad near = frontalQuad(-0.2, 0.2, -0.2, 0.2, 1.0, bright);
    if (order == 0) {
      scene.addQuad(far);
      scene.addQuad(near);
    } else {
      scene.addQuad(near);
      scene.addQuad(far);
    }
    const cv::Mat img = renderer.renderRadiance(scene, Pose());
    EXPECT_NEAR(img.at<float>(45, 60), 180.0f, 1e-3f);
    EXPECT_NEAR(img.at<float>(5, 5), 50.0f, 1e-3f);
  }
}

/// Sub-pixel column where a row crosses grey level `level` going left to right.
double crossing(const cv::Mat& img, int row, float level) {
  for (int c = 0; c + 1 < img.cols; ++c) {
    const float a = img.at<float>(row, c), b = img.at<float>(row, c + 1);
    if (a < level && b >= level) return c + (level - a) / (b - a);
  }
  return -1.0;
}

TEST(SimRenderer, TextureEdgeLandsOnItsProjection) {
  for (double k1 : {0.0, -0.2}) {
    TestCamera cam(240, 180, 150.0, k1);
    Renderer renderer(cam, cleanOptions(4));
    Scene scene;
    const int tex = scene.addTexture(stepTexture());
    // The step of the texture lies at s = 0.5, i.e. at x = 0.3 m on a 4 m wide quad starting at x = -1.7 m.
    scene.addQuad(frontalQuad(-1.7, 2.3, -2.0, 2.0, 2.5, tex));
    const cv::Mat img = renderer.renderRadiance(scene, Pose());
    for (int row : {30, 90, 150}) {
      // Undistorted normalised y of this row at the edge, found by undistorting a nearby pixel iteratively.
      Vec2 uv;
      cam.undistort(Vec2(cam.cx() + 150.0 * 0.12, row), &uv);
      const Vec2 expected = cam.distort(Vec2(0.3 / 2.5, uv.y()));
      EXPECT_NEAR(crossing(img, row, 100.0f), expected.x(), 0.1) << "k1 " << k1 << " row " << row;
    }
  }
}

TEST(SimRenderer, NearClippingAndBehindTheCamera) {
  TestCamera cam(100, 80, 60.0);
  RenderOptions opt = cleanOptions();
  Renderer renderer(cam, opt);
  Scene scene;
  const int tex = scene.addTexture(uniformTexture(90));
  Quad floor;  // a floor under the camera reaching from behind it to 10 m ahead
  floor.origin = Vec3(-5, 1.0, -5);
  floor.axis_u = Vec3(10, 0, 0);
  floor.axis_v = Vec3(0, 0, 15);
  floor.texture = tex;
  scene.addQuad(floor);
  scene.addQuad(frontalQuad(-1, 1, -1, 1, -2.0, tex));  // entirely behind: never drawn
  const cv::Mat depth = renderer.renderDepth(scene, Pose());
  const cv::Mat ids = renderer.renderQuadIds(scene, Pose());
  double min_depth = 1e9;
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c) {
      EXPECT_NE(ids.at<int>(r, c), 1);
      if (depth.at<float>(r, c) > 0) min_depth = std::min<double>(min_depth, depth.at<float>(r, c));
    }
  EXPECT_GE(min_depth, opt.near_m - 1e-6);
  EXPECT_EQ(ids.at<int>(79, 50), 0);   // the bottom row sees the floor
  EXPECT_EQ(ids.at<int>(0, 50), -1);   // the top row sees nothing
}

TEST(SimRenderer, PoseMovesTheImageConsistently) {
  TestCamera cam(160, 120, 100.0);
  Renderer renderer(cam, cleanOptions(4));
  Scene scene;
  const int tex = scene.addTexture(stepTexture());
  scene.addQuad(frontalQuad(-2, 2, -2, 2, 3.0, tex));  // step at x = 0
  // Camera translated by +0.3 m along x: the edge moves to x_n = -0.1 (15 px left of the centre... f=100 -> 10 px).
  const Pose T_W_C(Quat::Identity(), Vec3(0.3, 0, 0));
  const cv::Mat img = renderer.renderRadiance(scene, T_W_C);
  EXPECT_NEAR(crossing(img, 60, 100.0f), cam.cx() - 100.0 * 0.3 / 3.0, 0.1);
  // Camera yawed by 0.1 rad about its y axis: the edge (now at angle -0.1) is at x_n = tan(-0.1).
  const Pose yaw(Quat(Eigen::AngleAxisd(0.1, Vec3::UnitY())), Vec3::Zero());
  const cv::Mat img2 = renderer.renderRadiance(scene, yaw);
  EXPECT_NEAR(crossing(img2, 60, 100.0f), cam.cx() + 100.0 * std::tan(-0.1), 0.1);
}

TEST(SimRenderer, NoiseIsDeterministicAndHasTheRequestedLevel) {
  TestCamera cam(200, 150, 100.0);
  RenderOptions opt = cleanOptions(1);
  opt.read_noise = 2.0;
  opt.shot_noise = 0.05;
  Renderer renderer(cam, opt);
  Scene scene;
  const int tex = scene.addTexture(uniformTexture(100));
  scene.addQuad(frontalQuad(-10, 10, -10, 10, 3.0, tex));
  const cv::Mat a = renderer.render(scene, Pose(), 1.0, 7);
  const cv::Mat b = renderer.render(scene, Pose(), 1.0, 7);
  const cv::Mat c = renderer.render(scene, Pose(), 1.0, 8);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_L1), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1), 0.0);
  cv::Scalar mean, stddev;
  cv::meanStdDev(a, mean, stddev);
  EXPECT_NEAR(mean[0], 100.0, 0.1);
  EXPECT_NEAR(stddev[0], std::sqrt(4.0 + 0.05 * 100.0), 0.1);  // rounding adds 1/12 grey level^2
}

TEST(SimRenderer, VignettingDarkensCornersAndGainScales) {
  TestCamera cam(160, 120, 100.0);
  RenderOptions opt = cleanOptions(1);
  opt.vignetting = 0.3;
  Renderer renderer(cam, opt);
  Scene scene;
  const int tex = scene.addTexture(uniformTexture(100));
  scene.addQuad(frontalQuad(-10, 10, -10, 10, 3.0, tex));
  const cv::Mat img = renderer.render(scene, Pose(), 1.5, 1);
  EXPECT_NEAR(img.at<std::uint8_t>(60, 80), 150, 1);
  EXPECT_NEAR(img.at<std::uint8_t>(0, 0), 105, 1);
}

TEST(SimRenderer, MotionBlurAveragesSubFrames) {
  TestCamera cam(160, 120, 100.0);
  Renderer renderer(cam, cleanOptions(1));
  Scene scene;
  const int tex = scene.addTexture(stepTexture());
  scene.addQuad(frontalQuad(-2, 2, -2, 2, 1.0, tex));
  std::vector<Pose> poses;
  for (int k = 0; k < 5; ++k) poses.emplace_back(Quat::Identity(), Vec3(0.01 * k, 0, 0));  // 1 px per sub-frame
  const cv::Mat blurred = renderer.renderRadianceBlurred(scene, poses);
  // The step is spread over ~5 pixels: intermediate values appear.
  int ramp = 0;
  for (int c = 0; c < blurred.cols; ++c) {
    const float v = blurred.at<float>(60, c);
    if (v > 20 && v < 180) ++ramp;
  }
  EXPECT_GE(ramp, 3);
  EXPECT_THROW(renderer.renderRadianceBlurred(scene, {}), UsageError);
}

TEST(SimRenderer, RejectsBadInput) {
  TestCamera cam(64, 48, 50.0);
  RenderOptions bad;
  bad.supersample = 0;
  EXPECT_THROW(Renderer(cam, bad), ConfigError);
  Scene scene;
  EXPECT_THROW(scene.addTexture(cv::Mat(4, 4, CV_32FC1)), InputError);
  EXPECT_THROW(scene.addQuad(Quad{}), InputError);  // no texture yet
  scene.addTexture(uniformTexture(1));
  Quad degenerate;
  degenerate.axis_v = degenerate.axis_u;
  EXPECT_THROW(scene.addQuad(degenerate), InputError);
}

}  // namespace
}  // namespace linnet::sim
