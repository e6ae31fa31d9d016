#include "linnet/loop/place_matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/features/fast_corners.h"
#include "linnet/geometry/projection.h"
#include "linnet/geometry/triangulation.h"
#include "place_match_detail.h"

namespace linnet {

PlaceFeatures describePlace(const cv::Mat& left, const CameraModel& cam0, const std::vector<PointObservation>& points,
                            const Pose& T_C1_C0, const PlaceDescription& options, const FastCorners* found) {
  PlaceFeatures f;
  if (left.empty()) return f;
  // Upright descriptors (angle 0): the IMU keeps roll and pitch, and loops are searched within a bounded view angle.
  const float size = static_cast<float>(options.patch_px);
  std::vector<cv::KeyPoint> kps;
  for (std::size_t i = 0; i < points.size(); ++i) {
    cv::KeyPoint kp(static_cast<float>(points[i].px0.x()), static_cast<float>(points[i].px0.y()), size, 0.0f);
    kp.class_id = static_cast<int>(i);
    kps.push_back(kp);
  }
  const int n_tracked = static_cast<int>(kps.size());
  if (options.corners > 0) {
    std::vector<cv::KeyPoint> corners;
    if (found != nullptr && found->threshold == options.fast_threshold)
      corners = found->keypoints;
    else
      fastCorners(left, options.fast_threshold, &corners);
    cv::KeyPointsFilter::retainBest(corners, options.corners);
    // Strongest first (retainBest only partitions): the loop closer's database keeps a prefix of them.
    std::stable_sort(corners.begin(), corners.end(),
                     [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response > b.response; });
    for (cv::KeyPoint& c : corners) {
      c.size = size;
      c.angle = 0.0f;
      c.octave = 0;
      c.class_id = -1;
      kps.push_back(c);
    }
  }
  // One pyramid level: descriptors at the given corners only (ORB keeps the keypoints' angle when they are given).
  cv::Ptr<cv::ORB> orb = cv::ORB::create(std::max(1, static_cast<int>(kps.size())), 1.2f, 1, options.patch_px, 0, 2,
                                         cv::ORB::HARRIS_SCORE, options.patch_px);
  cv::Mat desc;
  orb->compute(left, kps, desc);
  if (desc.empty()) return f;

  TriangulationOptions tri;
  tri.min_depth_m = 0.1;
  tri.max_depth_m = 20.0;
  tri.min_parallax_deg = 0.2;
  tri.max_reprojection = 0.005;
  const std::vector<Pose> views = {Pose::identity(), T_C1_C0.inverse()};
  for (int k = 0; k < static_cast<int>(kps.size()); ++k) {
    const cv::KeyPoint& kp = kps[static_cast<std::size_t>(k)];
    Vec2 uv;
    if (kp.class_id >= 0 && kp.class_id < n_tracked) {
      const PointObservation& p = points[static_cast<std::size_t>(kp.class_id)];
      uv = p.uv0;
      Vec3 X;
      if (!p.has_right || triangulateChecked(views, {p.uv0, p.uv1}, tri, &X) != TriangulationStatus::kOk)
        X = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
      f.tracked_ids.push_back(p.id);
      f.tracked_descriptors.push_back(desc.row(k));
      f.tracked_stereo_p_C.push_back(X);
      f.tracked_rows.push_back(static_cast<int>(f.uv.size()));
    } else if (!cam0.undistort(Vec2(kp.pt.x, kp.pt.y), &uv)) {
      continue;
    }
    f.uv.push_back(uv);
    f.descriptors_2d.push_back(desc.row(k));
  }
  setPlaceDepths({}, Pose::identity(), &f);  // the stereo positions until the odometry's landmarks are known
  return f;
}

void setPlaceDepths(const std::vector<Vec3>& p_W_tracked, const Pose& T_W_C, PlaceFeatures* f) {
  f->p_C.clear();
  f->rows_3d.clear();
  f->descriptors_3d = cv::Mat();
  const bool rows = f->tracked_rows.size() == f->tracked_ids.size();
  const Pose T_C_W = T_W_C.inverse();
  for (std::size_t i = 0; i < f->tracked_ids.size(); ++i) {
    Vec3 X = f->tracked_stereo_p_C[i];
    if (i < p_W_tracked.size() && p_W_tracked[i].allFinite()) {
      const Vec3 p_C = T_C_W * p_W_tracked[i];
      if (p_C.z() > 0.1) X = p_C;
    }
    if (!X.allFinite()) continue;
    f->p_C.push_back(X);
    f->descriptors_3d.push_back(f->tracked_descriptors.row(static_cast<int>(i)));
    if (rows) f->rows_3d.push_back(f->tracked_rows[i]);
  }
}

namespace place_detail {

bool covarianceFromInformation(const Eigen::Matrix<double, 6, 6>& H, double sum_sq, std::size_t n,
                               Eigen::Matrix<double, 6, 6>* covariance) {
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(H);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) return false;
  const double variance = sum_sq / static_cast<double>(std::max<std::size_t>(1, 2 * n - 6));
  *covariance = variance * ldlt.solve(Eigen::Matrix<double, 6, 6>::Identity());
  return covariance->allFinite();
}

// Guided matches of a's 3D corners to b's corners: each 3D corner, moved into b by the prior T_Cb_Ca, takes the
// closest descriptor among b's corners within the radius of its projection (max_hamming; a second candidate within
// the radius must be clearly farther, match_ratio; one 3D point per corner).
void matchGuided(const PlaceFeatures& a, const PlaceFeatures& b, const Pose& T_Cb_Ca, const PlaceMatchOptions& options,
                 std::vector<cv::Point3d>* object, std::vector<cv::Point2d>* image) {
  const double radius = options.guided_radius_px / options.focal_px;
  const double radius_sq = radius * radius;
  std::vector<int> used(b.uv.size(), 0);
  for (int i = 0; i < static_cast<int>(a.p_C.size()); ++i) {
    const Vec3 p = T_Cb_Ca * a.p_C[static_cast<std::size_t>(i)];
    if (!(p.z() > 0.1)) continue;
    const Vec2 uv = p.head<2>() / p.z();
    int best = -1;
    double d1 = std::numeric_limits<double>::infinity(), d2 = d1;
    for (int k = 0; k < static_cast<int>(b.uv.size()); ++k) {
      if ((b.uv[static_cast<std::size_t>(k)] - uv).squaredNorm() > radius_sq) continue;
      const double d = cv::norm(a.descriptors_3d.row(i), b.descriptors_2d.row(k), cv::NORM_HAMMING);
      if (d < d1) {
        d2 = d1;
        d1 = d;
        best = k;
      } else if (d < d2) {
        d2 = d;
      }
    }
    if (best < 0 || d1 > options.max_hamming || d1 > options.match_ratio * d2) continue;
    if (used[static_cast<std::size_t>(best)]++) continue;
    const Vec3& X = a.p_C[static_cast<std::size_t>(i)];
    const Vec2& m = b.uv[static_cast<std::size_t>(best)];
    object->emplace_back(X.x(), X.y(), X.z());
    image->emplace_back(m.x(), m.y());
  }
}

PlaceMatch inverted(PlaceMatch r) {
  // The inverse: R' = R^T, t' = -R^T t, so dtheta' = -R^T dtheta and dt' = -R^T [t]x dtheta - R^T dt.
  const Mat3 Rt = r.T_Cold_Cnew.R().transpose();
  Eigen::Matrix<double, 6, 6> J = Eigen::Matrix<double, 6, 6>::Zero();
  J.block<3, 3>(0, 0) = -Rt;
  J.block<3, 3>(3, 0) = -Rt * skew(r.T_Cold_Cnew.p);
  J.block<3, 3>(3, 3) = -Rt;
  r.covariance = J * r.covariance * J.transpose();
  r.T_Cold_Cnew = r.T_Cold_Cnew.inverse();
  return r;
}

}  // namespace place_detail

using place_detail::covarianceFromInformation;
using place_detail::matchGuided;

namespace {

// Covariance of the pose (R, t) mapping `object` onto the normalised `image` points (x_b = R x_a + t), for the
// perturbation R <- exp(dtheta) R, t <- t + dt: sigma^2 (J^T J)^-1 with sigma^2 the residuals' variance (2 n - 6
// degrees of freedom). False when the system is singular or there are too few points.
bool pnpCovariance(const std::vector<cv::Point3d>& object, const std::vector<cv::Point2d>& image, const Mat3& R,
                   const Vec3& t, Eigen::Matrix<double, 6, 6>* covariance) {
  const int n = static_cast<int>(object.size());
  if (n < 4) return false;
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  double sum_sq = 0.0;
  for (int i = 0; i < n; ++i) {
    const Vec3 RX = R * Vec3(object[i].x, object[i].y, object[i].z);
    const Vec3 p = RX + t;
    if (!(p.z() > 1e-9)) return false;
    const Vec2 r = p.head<2>() / p.z() - Vec2(image[i].x, image[i].y);
    sum_sq += r.squaredNorm();
    Eigen::Matrix<double, 3, 6> dp;
    dp << -skew(RX), Mat3::Identity();  // d p / d(dtheta, dt)
    const Eigen::Matrix<double, 2, 6> J = projectionJacobian(p) * dp;
    H.noalias() += J.transpose() * J;
  }
  return covarianceFromInformation(H, sum_sq, static_cast<std::size_t>(n), covariance);
}

// Descriptor matches of a's 3D corners to b's corners (ratio test, one 3D corner per 2D corner): a's points in its
// camera frame and b's normalised coordinates.
void matchOneWay(const PlaceFeatures& a, const PlaceFeatures& b, const PlaceMatchOptions& options,
                 std::vector<cv::Point3d>* object, std::vector<cv::Point2d>* image) {
  cv::BFMatcher matcher(cv::NORM_HAMMING, false);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(a.descriptors_3d, b.descriptors_2d, knn, 2);
  std::vector<int> used(static_cast<std::size_t>(b.descriptors_2d.rows), 0);
  for (const std::vector<cv::DMatch>& m : knn) {
    if (m.empty() || m[0].distance > options.max_hamming) continue;
    if (m.size() > 1 && m[0].distance > options.match_ratio * m[1].distance) continue;
    if (used[static_cast<std::size_t>(m[0].trainIdx)]++) continue;  // one 3D point per corner
    const Vec3& X = a.p_C[static_cast<std::size_t>(m[0].queryIdx)];
    const Vec2& uv = b.uv[static_cast<std::size_t>(m[0].trainIdx)];
    object->emplace_back(X.x(), X.y(), X.z());
    image->emplace_back(uv.x(), uv.y());
  }
}

struct OneWay {
  PlaceMatch match;                 // T_Cold_Cnew holds T_Cb_Ca here
  std::vector<cv::Point3d> object;  // the PnP's inliers: a's points
  std::vector<cv::Point2d> image;   // and b's normalised corners
};

// Joint Gauss-Newton refinement of T_Cb_Ca = (R, t) on a's points seen in b (x_b = R X_a + t) and b's points seen in
// a (x_a = R^T (X_b - t)), perturbation R <- exp(dtheta) R, t <- t + dt; Huber-weighted at `huber` (normalised
// units). Writes the covariance as pnpCovariance does (both sets' residual variance). False if degenerate.
bool refineTwoWay(const std::vector<cv::Point3d>& obj_a, const std::vector<cv::Point2d>& img_b,
                  const std::vector<cv::Point3d>& obj_b, const std::vector<cv::Point2d>& img_a, double huber,
                  Mat3* R, Vec3* t, Eigen::Matrix<double, 6, 6>* covariance) {
  constexpr int kIterations = 8;
  const std::size_t n = obj_a.size() + obj_b.size();
  if (n < 4) return false;
  Mat3 Rk = *R;
  Vec3 tk = *t;
  Eigen::Matrix<double, 6, 6> H;
  double sum_sq = 0.0;
  for (int it = 0; it <= kIterations; ++it) {
    H.setZero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    sum_sq = 0.0;
    const auto add = [&](const Vec3& p, const Vec2& uv, const Eigen::Matrix<double, 3, 6>& dp) {
      if (!(p.z() > 1e-9)) return false;
      const Vec2 r = p.head<2>() / p.z() - uv;
      const Eigen::Matrix<double, 2, 6> J = projectionJacobian(p) * dp;
      const double e = r.norm();
      const double w = e <= huber ? 1.0 : huber / e;
      sum_sq += r.squaredNorm();
      H.noalias() += w * J.transpose() * J;
      g.noalias() += w * J.transpose() * r;
      return true;
    };
    for (std::size_t i = 0; i < obj_a.size(); ++i) {
      const Vec3 RX = Rk * Vec3(obj_a[i].x, obj_a[i].y, obj_a[i].z);
      Eigen::Matrix<double, 3, 6> dp;
      dp << -skew(RX), Mat3::Identity();
      if (!add(RX + tk, Vec2(img_b[i].x, img_b[i].y), dp)) return false;
    }
    for (std::size_t i = 0; i < obj_b.size(); ++i) {
      const Vec3 d = Vec3(obj_b[i].x, obj_b[i].y, obj_b[i].z) - tk;
      Eigen::Matrix<double, 3, 6> dp;
      dp << Rk.transpose() * skew(d), -Rk.transpose();
      if (!add(Rk.transpose() * d, Vec2(img_a[i].x, img_a[i].y), dp)) return false;
    }
    if (it == kIterations) break;
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(H);
    if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) return false;
    const Eigen::Matrix<double, 6, 1> delta = -ldlt.solve(g);
    if (!delta.allFinite()) return false;
    Rk = expSO3(Vec3(delta.head<3>())).toRotationMatrix() * Rk;
    tk += delta.tail<3>();
    if (delta.norm() < 1e-10) break;
  }
  if (!covarianceFromInformation(H, sum_sq, n, covariance) || !Rk.allFinite() || !tk.allFinite()) return false;
  *R = Rk;
  *t = tk;
  return true;
}

// A 3D point in a camera's frame agrees with its corner (normalised coordinates) when it is in front and projects
// within `gate` of it.
bool projectsWithin(const Vec3& p_C, const cv::Point2d& uv, double gate) {
  return p_C.z() > 0.0 && (p_C.head<2>() / p_C.z() - Vec2(uv.x, uv.y)).norm() <= gate;
}

// 3D points of `a` (its camera frame) matched to 2D corners of `b`; on success T_Cb_Ca.
// With a prior T_Cb_Ca the pairs come from guided matching instead of descriptors alone.
OneWay solveOneWay(const PlaceFeatures& a, const PlaceFeatures& b, const PlaceMatchOptions& options,
                   const std::optional<Pose>& prior_T_Cb_Ca = std::nullopt) {
  OneWay result;
  PlaceMatch& out = result.match;
  if (static_cast<int>(a.p_C.size()) < options.min_inliers || b.descriptors_2d.rows < 2) return result;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  if (prior_T_Cb_Ca)
    matchGuided(a, b, *prior_T_Cb_Ca, options, &object, &image);
  else
    matchOneWay(a, b, options, &object, &image);
  out.matches = static_cast<int>(object.size());
  if (out.matches < options.min_inliers) return result;
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  const cv::Mat K = cv::Mat::eye(3, 3, CV_64F);
  // Hypotheses from four points by AP3P (Ke & Roumeliotis, CVPR 2017), the inliers' pose then by EPnP (OpenCV's
  // choice after a P3P-family RANSAC) and refined below. Five-point EPnP hypotheses cost several times as much (a
  // 12 x 12 SVD each) for the same loops: a failing candidate runs all 200 of them.
  const bool solved = cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, 200,
                                         static_cast<float>(options.ransac_px / options.focal_px), 0.99, inliers,
                                         cv::SOLVEPNP_AP3P);
  out.inliers = static_cast<int>(inliers.size());
  if (!solved || out.inliers < options.min_inliers) return result;
  std::vector<cv::Point3d>& obj_in = result.object;
  std::vector<cv::Point2d>& img_in = result.image;
  const auto refine = [&](const std::vector<int>& set, Mat3* R, Vec3* t) {
    obj_in.clear();
    img_in.clear();
    for (int k : set) {
      obj_in.push_back(object[static_cast<std::size_t>(k)]);
      img_in.push_back(image[static_cast<std::size_t>(k)]);
    }
    cv::solvePnP(obj_in, img_in, K, cv::noArray(), rvec, tvec, true, cv::SOLVEPNP_ITERATIVE);
    cv::Mat Rcv;
    cv::Rodrigues(rvec, Rcv);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) (*R)(r, c) = Rcv.at<double>(r, c);
    *t = Vec3(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
    return R->allFinite() && t->allFinite();
  };
  Mat3 R;
  Vec3 t;
  if (!refine(inliers, &R, &t)) return result;
  // The inliers are those of the refined pose: RANSAC's are those of its best minimal-set hypothesis, a noisier pose
  // (from four points) that leaves some good matches just outside the threshold. Refined once more if they changed.
  std::vector<int> agreeing;
  const double gate = options.ransac_px / options.focal_px;
  for (std::size_t k = 0; k < object.size(); ++k)
    if (projectsWithin(R * Vec3(object[k].x, object[k].y, object[k].z) + t, image[k], gate))
      agreeing.push_back(static_cast<int>(k));
  if (static_cast<int>(agreeing.size()) < options.min_inliers) return result;
  if (agreeing != inliers && !refine(agreeing, &R, &t)) return result;
  out.inliers = static_cast<int>(agreeing.size());
  if (!pnpCovariance(obj_in, img_in, R, t, &out.covariance)) return result;
  out.T_Cold_Cnew = Pose(R, t);  // x_b = R x_a + t: T_Cb_Ca
  out.ok = true;
  return result;
}

// With options.two_way: b's 3D corners matched to a's corners that agree with T_Cb_Ca within ransac_px, and the
// relative pose refined on both sets together (refineTwoWay). Left as it is if too few agree or the refinement fails.
void refineOnBothKeyframes(const PlaceFeatures& a, const PlaceFeatures& b, const PlaceMatchOptions& options,
                           OneWay* one) {
  PlaceMatch& m = one->match;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  if (b.p_C.empty() || a.descriptors_2d.rows < 2) return;
  matchOneWay(b, a, options, &object, &image);
  const Mat3 R = m.T_Cold_Cnew.R();
  const Vec3 t = m.T_Cold_Cnew.p;
  const double gate = options.ransac_px / options.focal_px;
  std::vector<cv::Point3d> obj_b;
  std::vector<cv::Point2d> img_a;
  for (std::size_t i = 0; i < object.size(); ++i) {
    const Vec3 p = R.transpose() * (Vec3(object[i].x, object[i].y, object[i].z) - t);  // in a
    if (!projectsWithin(p, image[i], gate)) continue;
    obj_b.push_back(object[i]);
    img_a.push_back(image[i]);
  }
  if (static_cast<int>(obj_b.size()) < options.min_inliers / 2) return;
  Mat3 R2 = R;
  Vec3 t2 = t;
  Eigen::Matrix<double, 6, 6> covariance;
  if (!refineTwoWay(one->object, one->image, obj_b, img_a, gate, &R2, &t2, &covariance)) return;
  m.T_Cold_Cnew = Pose(Quat(R2).normalized(), t2);
  m.covariance = covariance;
  m.reverse_inliers = static_cast<int>(obj_b.size());
}

}  // namespace

const char* placeMatchMethodName(PlaceMatchMethod method) {
  switch (method) {
    case PlaceMatchMethod::kGuided: return "guided";
    case PlaceMatchMethod::kLines: return "lines";
    case PlaceMatchMethod::kDescriptors: break;
  }
  return "descriptors";
}

PlaceMatch matchPlaces(const PlaceFeatures& old_kf, const PlaceFeatures& new_kf, const PlaceMatchOptions& options) {
  PlaceMatch best;
  const bool guided = options.prior_T_Cold_Cnew.has_value() && options.guided_radius_px > 0.0;
  for (int pass = 0; pass < (guided ? 2 : 1); ++pass) {
    std::optional<Pose> forward_prior, backward_prior;
    if (pass == 1) {
      forward_prior = *options.prior_T_Cold_Cnew;
      backward_prior = options.prior_T_Cold_Cnew->inverse();
    }
    OneWay forward = solveOneWay(new_kf, old_kf, options, forward_prior);  // T_Cold_Cnew
    const PlaceMatchMethod method = pass == 1 ? PlaceMatchMethod::kGuided : PlaceMatchMethod::kDescriptors;
    if (forward.match.ok) {
      if (options.two_way) refineOnBothKeyframes(new_kf, old_kf, options, &forward);
      forward.match.method = method;
      return forward.match;
    }
    OneWay backward = solveOneWay(old_kf, new_kf, options, backward_prior);  // T_Cnew_Cold
    if (backward.match.ok && options.two_way) refineOnBothKeyframes(old_kf, new_kf, options, &backward);
    const PlaceMatch& m = forward.match;
    PlaceMatch r = backward.match;
    if (!r.ok) {
      best.matches = std::max({best.matches, r.matches, m.matches});
      best.inliers = std::max({best.inliers, r.inliers, m.inliers});
      continue;
    }
    r.method = method;
    return place_detail::inverted(r);
  }
  if (guided && options.use_lines) {
    const PlaceMatch lines = matchPlacesWithLines(old_kf, new_kf, options);
    if (lines.ok) return lines;
    best.matches = std::max(best.matches, lines.matches);
    best.inliers = std::max(best.inliers, lines.inliers);
  }
  return best;
}

}  // namespace linnet
