// CameraModel: shared undistortion (damped Newton), batch helpers, remap tables, and the factory.
#include "linnet/camera/camera_model.h"

#include <cctype>
#include <cmath>
#include <sstream>

#include "linnet/camera/distortion_models.h"
#include "linnet/core/error.h"

namespace linnet {

namespace {

constexpr double kUndistortTolerance = 1e-10;  // residual in normalised units for success
constexpr int kMaxNewtonIterations = 40;

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

Mat3 CameraModel::K() const {
  Mat3 K = Mat3::Identity();
  K(0, 0) = fx_;
  K(1, 1) = fy_;
  K(0, 2) = cx_;
  K(1, 2) = cy_;
  return K;
}

bool CameraModel::undistort(const Vec2& px, Vec2* uv_out) const {
  // Solve distort(uv) = px by Newton's method with step halving, starting from the undistorted pinhole guess.
  // The residual is measured in normalised units (pixel residual divided by the focal length).
  const auto residual = [&](const Vec2& uv, Mat2* J) {
    const Vec2 r = distort(uv, J) - px;
    return Vec2(r.x() / fx_, r.y() / fy_);
  };
  Vec2 uv((px.x() - cx_) / fx_, (px.y() - cy_) / fy_);
  Mat2 J;
  Vec2 r = residual(uv, &J);
  double err = r.norm();
  for (int it = 0; it < kMaxNewtonIterations && err > 1e-15; ++it) {
    Mat2 Jn = J;
    Jn.row(0) /= fx_;
    Jn.row(1) /= fy_;
    const double det = Jn.determinant();
    if (!(det > 1e-12) || !std::isfinite(det)) return false;  // fold of the distortion: not invertible here
    const Vec2 step = Jn.inverse() * r;
    double alpha = 1.0;
    bool improved = false;
    for (int k = 0; k < 12; ++k, alpha *= 0.5) {
      const Vec2 cand = uv - alpha * step;
      Mat2 Jc;
      const Vec2 rc = residual(cand, &Jc);
      const double ec = rc.norm();
      if (std::isfinite(ec) && ec < err) {
        uv = cand;
        r = rc;
        J = Jc;
        err = ec;
        improved = true;
        break;
      }
    }
    if (!improved) break;  // at the floor of double precision, or stuck
  }
  if (!(err < kUndistortTolerance)) return false;
  *uv_out = uv;
  return true;
}

bool CameraModel::unproject(const Vec2& px, Vec3* bearing) const {
  Vec2 uv;
  if (!undistort(px, &uv)) return false;
  *bearing = Vec3(uv.x(), uv.y(), 1.0).normalized();
  return true;
}

std::vector<Vec2> CameraModel::distortPoints(const std::vector<Vec2>& uv) const {
  std::vector<Vec2> px;
  px.reserve(uv.size());
  for (const Vec2& p : uv) px.push_back(distort(p));
  return px;
}

int CameraModel::undistortPoints(const std::vector<Vec2>& px, std::vector<Vec2>* uv,
                                 std::vector<unsigned char>* ok) const {
  uv->assign(px.size(), Vec2::Zero());
  if (ok) ok->assign(px.size(), 0);
  int n = 0;
  for (std::size_t i = 0; i < px.size(); ++i) {
    const bool good = undistort(px[i], &(*uv)[i]);
    if (!good) (*uv)[i].setZero();
    if (ok) (*ok)[i] = good ? 1 : 0;
    n += good ? 1 : 0;
  }
  return n;
}

void CameraModel::undistortionMap(const Mat3& K_new, int out_width, int out_height, std::vector<float>* map_x,
                                  std::vector<float>* map_y) const {
  if (out_width <= 0 || out_height <= 0 || !(K_new(0, 0) > 0.0) || !(K_new(1, 1) > 0.0))
    throw UsageError("CameraModel::undistortionMap: needs a positive output size and focal lengths");
  const std::size_t n = static_cast<std::size_t>(out_width) * static_cast<std::size_t>(out_height);
  map_x->resize(n);
  map_y->resize(n);
  const double ifx = 1.0 / K_new(0, 0), ify = 1.0 / K_new(1, 1);
  for (int v = 0; v < out_height; ++v) {
    const double y = (v - K_new(1, 2)) * ify;
    for (int u = 0; u < out_width; ++u) {
      const double x = (u - K_new(0, 2) - K_new(0, 1) * y) * ifx;
      const Vec2 px = distort(Vec2(x, y));
      const std::size_t i = static_cast<std::size_t>(v) * out_width + u;
      (*map_x)[i] = static_cast<float>(px.x());
      (*map_y)[i] = static_cast<float>(px.y());
    }
  }
}

std::unique_ptr<CameraModel> CameraModel::create(const CameraCalibration& calib) {
  const auto fail = [](const std::string& key, const std::string& what) {
    throw ConfigError("camera calibration key '" + key + "': " + what);
  };
  if (lower(calib.model) != "pinhole") fail("model", "'" + calib.model + "' is not one of {pinhole}");
  if (calib.width <= 0 || calib.height <= 0) {
    std::ostringstream os;
    os << "image size " << calib.width << " x " << calib.height << " must be positive";
    fail(calib.width <= 0 ? "width" : "height", os.str());
  }
  const auto& in = calib.intrinsics;
  for (double x : in)
    if (!std::isfinite(x)) fail("intrinsics", "values must be finite");
  if (!(in[0] > 0.0) || !(in[1] > 0.0)) fail("intrinsics", "focal lengths fx, fy must be positive");
  for (double x : calib.distortion_coeffs)
    if (!std::isfinite(x)) fail("distortion_coeffs", "values must be finite");

  const std::string d = lower(calib.distortion);
  const std::size_t n = calib.distortion_coeffs.size();
  if (d == "radtan" || d == "radial-tangential" || d == "radial_tangential" || d == "plumb_bob") {
    if (n != 4 && n != 5)
      fail("distortion_coeffs", "radtan needs 4 (k1 k2 p1 p2) or 5 (k1 k2 p1 p2 k3) values, got " + std::to_string(n));
    return std::make_unique<PinholeRadtanCamera>(calib.width, calib.height, in[0], in[1], in[2], in[3],
                                                 calib.distortion_coeffs);
  }
  if (d == "equidistant" || d == "fisheye" || d == "kannala_brandt" || d == "kb4") {
    if (n != 4) fail("distortion_coeffs", "equidistant needs 4 values (k1 k2 k3 k4), got " + std::to_string(n));
    return std::make_unique<PinholeEquidistantCamera>(calib.width, calib.height, in[0], in[1], in[2], in[3],
                                                      calib.distortion_coeffs);
  }
  if (d == "none") {
    for (double x : calib.distortion_coeffs)
      if (x != 0.0) fail("distortion_coeffs", "distortion 'none' takes no (or only zero) coefficients");
    return std::make_unique<PinholeCamera>(calib.width, calib.height, in[0], in[1], in[2], in[3]);
  }
  fail("distortion", "'" + calib.distortion + "' is not one of {radtan, equidistant, none}");
  return nullptr;  // unreachable
}

Pose CameraRig::T_C1_C0() const {
  if (!stereo()) throw UsageError("CameraRig::T_C1_C0: the rig has " + std::to_string(cameras.size()) + " camera(s)");
  return cameras[1].T_B_C.inverse() * cameras[0].T_B_C;
}

}  // namespace linnet
