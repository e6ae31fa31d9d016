// Camera models: round trips over the whole image, analytic Jacobians, cross-checks against OpenCV, config errors.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <set>
#include <string>
#include <vector>

#include "linnet/camera/camera_model.h"
#include "linnet/camera/distortion_models.h"
#include "linnet/core/error.h"
#include "linnet/core/options.h"

namespace linnet {
namespace {

CameraCalibration eurocCam0() { return CameraCalibration(); }  // the defaults are EuRoC cam0

CameraCalibration radtan5() {
  CameraCalibration c;
  c.distortion_coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05, 0.0123};
  return c;
}

// TUM-VI (512x512, ~190 deg field of view): the image corners look further than 90 degrees off axis.
CameraCalibration tumvi() {
  CameraCalibration c;
  c.distortion = "equidistant";
  c.width = 512;
  c.height = 512;
  c.intrinsics = {190.97847715128717, 190.9733070521226, 254.93170605935475, 256.8974428996504};
  c.distortion_coeffs = {0.0034823894022493434, 0.0007150348452162257, -0.0020532361418706202,
                         0.00020293673591811182};
  return c;
}

// A milder fisheye whose whole image stays inside 90 degrees.
CameraCalibration mildFisheye() {
  CameraCalibration c;
  c.distortion = "equidistant";
  c.width = 640;
  c.height = 480;
  c.intrinsics = {330.0, 331.0, 318.5, 241.2};
  c.distortion_coeffs = {-0.012, 0.034, -0.021, 0.004};
  return c;
}

std::vector<Vec2> imageGrid(const CameraModel& cam, double step) {
  std::vector<Vec2> g;
  for (double v = 0.0; v <= cam.height() - 1; v += step)
    for (double u = 0.0; u <= cam.width() - 1; u += step) g.emplace_back(u, v);
  const double W = cam.width() - 1, H = cam.height() - 1;
  for (const Vec2& c : {Vec2(0, 0), Vec2(W, 0), Vec2(0, H), Vec2(W, H), Vec2(W / 2, 0), Vec2(0, H / 2)}) g.push_back(c);
  return g;
}

cv::Mat cvK(const CameraModel& cam) {
  return (cv::Mat_<double>(3, 3) << cam.fx(), 0, cam.cx(), 0, cam.fy(), cam.cy(), 0, 0, 1);
}

void expectRoundTrip(const CameraCalibration& calib) {
  const auto cam = CameraModel::create(calib);
  int n = 0;
  for (const Vec2& px : imageGrid(*cam, 7.0)) {
    Vec2 uv;
    ASSERT_TRUE(cam->undistort(px, &uv)) << px.transpose();
    EXPECT_LT((cam->distort(uv) - px).norm(), 1e-7) << px.transpose();
    Vec2 uv2;
    ASSERT_TRUE(cam->undistort(cam->distort(uv), &uv2));
    EXPECT_LT((uv2 - uv).norm(), 1e-10);
    ++n;
  }
  EXPECT_GT(n, 4000);
}

TEST(CameraModel, RadtanRoundTripWholeImage) { expectRoundTrip(eurocCam0()); }
TEST(CameraModel, Radtan5RoundTripWholeImage) { expectRoundTrip(radtan5()); }
TEST(CameraModel, EquidistantRoundTripWholeImage) { expectRoundTrip(mildFisheye()); }

TEST(CameraModel, PinholeNone) {
  CameraCalibration c;
  c.distortion = "none";
  c.distortion_coeffs = {};
  const auto cam = CameraModel::create(c);
  EXPECT_EQ(cam->distortionName(), "none");
  Vec2 uv;
  ASSERT_TRUE(cam->undistort(Vec2(10.0, 20.0), &uv));
  EXPECT_NEAR(uv.x(), (10.0 - c.intrinsics[2]) / c.intrinsics[0], 1e-15);
  EXPECT_LT((cam->distort(uv) - Vec2(10.0, 20.0)).norm(), 1e-12);
}

TEST(CameraModel, EquidistantBeyondNinetyDegreesIsRejected) {
  const auto cam = CameraModel::create(tumvi());
  int ok = 0, rejected = 0;
  for (const Vec2& px : imageGrid(*cam, 8.0)) {
    Vec2 uv;
    // theta_d = |xd| is monotone in theta for these coefficients; theta = pi/2 gives theta_d = thd90.
    const double t = std::numbers::pi / 2, t2 = t * t;
    const auto& k = tumvi().distortion_coeffs;
    const double thd90 = t * (1 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
    const double thd = Vec2((px.x() - cam->cx()) / cam->fx(), (px.y() - cam->cy()) / cam->fy()).norm();
    const bool good = cam->undistort(px, &uv);
    if (thd < thd90 - 1e-3) {
      ASSERT_TRUE(good) << px.transpose();
      EXPECT_LT((cam->distort(uv) - px).norm(), 1e-7);
      ++ok;
    } else if (thd > thd90 + 1e-3) {
      EXPECT_FALSE(good) << px.transpose();
      ++rejected;
    }
  }
  EXPECT_GT(ok, 2000);
  EXPECT_GT(rejected, 100);  // the corners
  Vec2 uv;
  EXPECT_FALSE(cam->undistort(Vec2(0.0, 0.0), &uv));
}

TEST(CameraModel, DistortJacobianMatchesNumeric) {
  for (const CameraCalibration& calib : {eurocCam0(), radtan5(), mildFisheye(), tumvi()}) {
    const auto cam = CameraModel::create(calib);
    for (const Vec2& uv : {Vec2(0.0, 0.0), Vec2(0.3, -0.2), Vec2(-0.7, 0.45), Vec2(1e-10, 2e-10), Vec2(0.9, 0.6)}) {
      Mat2 J;
      cam->distort(uv, &J);
      Mat2 Jn;
      const double h = 1e-6;
      for (int k = 0; k < 2; ++k) {
        Vec2 d = Vec2::Zero();
        d[k] = h;
        Jn.col(k) = (cam->distort(uv + d) - cam->distort(uv - d)) / (2 * h);
      }
      EXPECT_LT((J - Jn).norm(), 1e-5 * std::max(1.0, Jn.norm())) << calib.distortion << " at " << uv.transpose();
    }
  }
}

TEST(CameraModel, RadtanMatchesOpenCV) {
  for (const CameraCalibration& calib : {eurocCam0(), radtan5()}) {
    const auto cam = CameraModel::create(calib);
    const cv::Mat D(calib.distortion_coeffs, true);
    const std::vector<Vec2> grid = imageGrid(*cam, 11.0);
    std::vector<cv::Point2d> px_cv;
    for (const Vec2& p : grid) px_cv.emplace_back(p.x(), p.y());
    std::vector<cv::Point2d> uv_cv;
    cv::undistortPoints(px_cv, uv_cv, cvK(*cam), D, cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 500, 1e-15));
    std::vector<cv::Point3d> rays;
    std::vector<Vec2> uv_ours(grid.size());
    for (std::size_t i = 0; i < grid.size(); ++i) {
      ASSERT_TRUE(cam->undistort(grid[i], &uv_ours[i]));
      EXPECT_LT((uv_ours[i] - Vec2(uv_cv[i].x, uv_cv[i].y)).norm(), 1e-6) << grid[i].transpose();
      rays.emplace_back(uv_ours[i].x(), uv_ours[i].y(), 1.0);
    }
    std::vector<cv::Point2d> proj;
    cv::projectPoints(rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cvK(*cam), D, proj);
    for (std::size_t i = 0; i < grid.size(); ++i)
      EXPECT_LT((cam->distort(uv_ours[i]) - Vec2(proj[i].x, proj[i].y)).norm(), 1e-9);
  }
}

TEST(CameraModel, EquidistantMatchesOpenCVFisheye) {
  for (const CameraCalibration& calib : {mildFisheye(), tumvi()}) {
    const auto cam = CameraModel::create(calib);
    const cv::Mat D(calib.distortion_coeffs, true);
    std::vector<Vec2> grid;
    for (const Vec2& p : imageGrid(*cam, 9.0)) {
      Vec2 uv;
      if (cam->undistort(p, &uv)) grid.push_back(p);
    }
    ASSERT_GT(grid.size(), 1500u);
    std::vector<cv::Point2d> px_cv;
    for (const Vec2& p : grid) px_cv.emplace_back(p.x(), p.y());
    std::vector<cv::Point2d> uv_cv;
    cv::fisheye::undistortPoints(px_cv, uv_cv, cvK(*cam), D, cv::noArray(), cv::noArray(),
                                 cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-14));
    std::vector<cv::Point3d> rays;
    for (std::size_t i = 0; i < grid.size(); ++i) {
      Vec2 uv;
      ASSERT_TRUE(cam->undistort(grid[i], &uv));
      const Vec2 ref(uv_cv[i].x, uv_cv[i].y);
      EXPECT_LT((uv - ref).norm(), 1e-6 * std::max(1.0, ref.norm())) << grid[i].transpose();
      rays.emplace_back(uv.x(), uv.y(), 1.0);
    }
    std::vector<cv::Point2d> proj;
    cv::fisheye::projectPoints(rays, proj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), cvK(*cam), D);
    for (std::size_t i = 0; i < grid.size(); ++i) {
      Vec2 uv((rays[i].x), rays[i].y);
      EXPECT_LT((cam->distort(uv) - Vec2(proj[i].x, proj[i].y)).norm(), 1e-8);
    }
  }
}

TEST(CameraModel, UndistortionMapMatchesOpenCV) {
  const auto cam = CameraModel::create(eurocCam0());
  Mat3 Knew = cam->K();
  Knew(0, 0) *= 0.8;
  Knew(1, 1) *= 0.8;
  std::vector<float> mx, my;
  cam->undistortionMap(Knew, 752, 480, &mx, &my);
  cv::Mat cx, cy;
  cv::Mat Kn = (cv::Mat_<double>(3, 3) << Knew(0, 0), 0, Knew(0, 2), 0, Knew(1, 1), Knew(1, 2), 0, 0, 1);
  cv::initUndistortRectifyMap(cvK(*cam), cv::Mat(eurocCam0().distortion_coeffs, true), cv::Mat(), Kn,
                              cv::Size(752, 480), CV_32FC1, cx, cy);
  double worst = 0.0;
  for (int v = 0; v < 480; v += 3)
    for (int u = 0; u < 752; u += 3) {
      const std::size_t i = static_cast<std::size_t>(v) * 752 + u;
      worst = std::max(worst, std::hypot(double(mx[i]) - cx.at<float>(v, u), double(my[i]) - cy.at<float>(v, u)));
    }
  EXPECT_LT(worst, 1e-2);
}

TEST(CameraModel, BatchHelpers) {
  const auto cam = CameraModel::create(eurocCam0());
  const std::vector<Vec2> px{{10.0, 10.0}, {376.0, 240.0}, {741.0, 470.0}};
  std::vector<Vec2> uv;
  std::vector<unsigned char> ok;
  EXPECT_EQ(cam->undistortPoints(px, &uv, &ok), 3);
  ASSERT_EQ(uv.size(), 3u);
  const std::vector<Vec2> back = cam->distortPoints(uv);
  for (std::size_t i = 0; i < px.size(); ++i) {
    EXPECT_EQ(ok[i], 1);
    EXPECT_LT((back[i] - px[i]).norm(), 1e-7);
  }
  Vec3 b;
  ASSERT_TRUE(cam->unproject(Vec2(376.0, 240.0), &b));
  EXPECT_NEAR(b.norm(), 1.0, 1e-12);
  EXPECT_GT(b.z(), 0.99);
}

template <class F>
std::string configErrorOf(F&& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(CameraModel, CreateRejectsBadCalibrations) {
  CameraCalibration c = eurocCam0();
  c.distortion_coeffs = {0.1, 0.2, 0.3};
  EXPECT_NE(configErrorOf([&] { CameraModel::create(c); }).find("distortion_coeffs"), std::string::npos);
  c = tumvi();
  c.distortion_coeffs.push_back(0.0);
  EXPECT_NE(configErrorOf([&] { CameraModel::create(c); }).find("equidistant needs 4"), std::string::npos);
  c = eurocCam0();
  c.distortion = "none";
  EXPECT_NE(configErrorOf([&] { CameraModel::create(c); }).find("distortion_coeffs"), std::string::npos);
  c = eurocCam0();
  c.distortion = "omni";
  EXPECT_NE(configErrorOf([&] { CameraModel::create(c); }).find("'distortion'"), std::string::npos);
  c = eurocCam0();
  c.model = "double_sphere";
  EXPECT_NE(configErrorOf([&] { CameraModel::create(c); }).find("'model'"), std::string::npos);
  c = eurocCam0();
  c.intrinsics[1] = -5.0;
  EXPECT_NE(configErrorOf([&] { CameraModel::create(c); }).find("intrinsics"), std::string::npos);
  c = eurocCam0();
  c.width = 0;
  EXPECT_NE(configErrorOf([&] { CameraModel::create(c); }).find("width"), std::string::npos);
  // Kalibr's names are accepted.
  c = eurocCam0();
  c.distortion = "radial-tangential";
  EXPECT_EQ(CameraModel::create(c)->distortionName(), "radtan");
  c = tumvi();
  c.distortion = "fisheye";
  EXPECT_EQ(CameraModel::create(c)->distortionName(), "equidistant");
}

struct KeyCollector {
  std::set<std::string> keys;
  template <class T>
  void operator()(const char* key, T&, const char*) { keys.insert(key); }
  template <class T>
  void operator()(const char* key, T&, const char*, T, T) { keys.insert(key); }
  void choice(const char* key, std::string&, const char*, std::initializer_list<const char*>) { keys.insert(key); }
};

TEST(CameraModel, CalibrationVisitAndValidation) {
  CameraCalibration c;
  KeyCollector k;
  c.visit(k);
  EXPECT_EQ(k.keys, (std::set<std::string>{"model", "distortion", "width", "height", "intrinsics",
                                           "distortion_coeffs", "T_B_C", "rate_hz"}));
  EXPECT_NO_THROW(validateOptions(c, "cam0"));
  c.distortion = "fisheye62";
  EXPECT_NE(configErrorOf([&] { validateOptions(c, "cam0"); }).find("cam0.distortion"), std::string::npos);
  c = CameraCalibration();
  c.rate_hz = -1.0;
  EXPECT_NE(configErrorOf([&] { validateOptions(c, "cam0"); }).find("cam0.rate_hz"), std::string::npos);
}

TEST(CameraModel, RigExtrinsic) {
  CameraRig rig;
  rig.cameras.resize(2);
  Mat4 T0, T1;  // EuRoC cam0 / cam1 T_BS
  T0 << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975, 0.999557249008, 0.0149672133247,
      0.025715529948, -0.064676986768, -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949, 0, 0, 0,
      1;
  T1 << 0.0125552670891, -0.999755099723, 0.0182237714554, -0.0198435579556, 0.999598781151, 0.0130119051815,
      0.0251588363115, 0.0453689425024, -0.0253898008918, 0.0179005838253, 0.999517347078, 0.00786212447038, 0, 0, 0,
      1;
  rig.cameras[0].T_B_C = Pose::fromMatrix(T0);
  rig.cameras[1].T_B_C = Pose::fromMatrix(T1);
  const Pose T = rig.T_C1_C0();
  EXPECT_NEAR(T.p.norm(), 0.110, 0.002);  // EuRoC baseline ~11 cm
  EXPECT_LT(T.p.x(), -0.1);               // cam0 sits to the left of cam1
  CameraRig mono;
  mono.cameras.resize(1);
  EXPECT_THROW(mono.T_C1_C0(), UsageError);
}

}  // namespace
}  // namespace linnet
