// Point front-end: KLT tracking, outlier rejection, replenishment and stereo matching (DESIGN B1).
#include "linnet/features/point_tracker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

#include <opencv2/imgproc.hpp>

#include "linnet/core/error.h"
#include "linnet/core/options.h"
#include "linnet/features/image_pyramid.h"
#include "linnet/features/klt_round_trip.h"
#include "linnet/features/point_detection.h"
#include "linnet/features/point_ransac.h"
#include "linnet/features/point_stereo.h"

namespace linnet {

namespace {

void checkImage(const cv::Mat& img, const CameraModel& cam, const char* which) {
  if (img.type() != CV_8UC1 || img.cols != cam.width() || img.rows != cam.height()) {
    std::ostringstream os;
    os << "PointTracker::track: the " << which << " image must be 8-bit grayscale " << cam.width() << "x"
       << cam.height() << ", got type " << img.type() << " of " << img.cols << "x" << img.rows;
    throw UsageError(os.str());
  }
}

// Adaptive stereo CLAHE decides only on frames with at least this many stereo attempts (a handful of tracks says
// little about the image pair).
constexpr int kMinStereoAttemptsForDecision = 20;

cv::Point2f toCv(const Vec2& v) { return cv::Point2f(static_cast<float>(v.x()), static_cast<float>(v.y())); }
Vec2 toEigen(const cv::Point2f& p) { return Vec2(p.x, p.y); }

}  // namespace

PointTracker::PointTracker(const PointTrackerOptions& options, const CameraModel& cam0, const CameraModel* cam1,
                           const Pose& T_C1_C0)
    : opt_(options), cam0_(cam0), cam1_(cam1), T_C1_C0_(T_C1_C0) {
  validateOptions(opt_, "points");
  if (opt_.clahe || opt_.stereo_clahe)
    clahe_ = cv::createCLAHE(opt_.clahe_clip_limit, cv::Size(opt_.clahe_tiles, opt_.clahe_tiles));
}

PointTracker::~PointTracker() = default;

void PointTracker::setRotationPrediction(const Mat3& R_Ccur_Cprev) { R_pred_ = R_Ccur_Cprev; }

void PointTracker::reset() {
  tracks_.clear();
  pyr_prev_.clear();
  has_last_ = false;
  R_pred_.reset();
  stereo_clahe_on_ = true;
  frames_since_probe_ = 0;
}

void PointTracker::track(Timestamp t, const cv::Mat& left_in, const cv::Mat& right_in,
                         std::vector<PointObservation>* points) {
  const auto t0 = std::chrono::steady_clock::now();
  checkImage(left_in, cam0_, "left");
  const bool use_right = cam1_ != nullptr && opt_.stereo && !right_in.empty();
  if (!right_in.empty() && cam1_ == nullptr)
    throw UsageError("PointTracker::track: a right image was given to a monocular tracker");
  if (use_right) checkImage(right_in, *cam1_, "right");
  if (has_last_ && t <= last_t_) {
    std::ostringstream os;
    os << "PointTracker::track: time stamp " << t << " ns is not after the previous one (" << last_t_ << " ns)";
    throw UsageError(os.str());
  }
  stats_ = PointTrackerStats();
  fast_corners_ = FastCorners{};
  stats_.previous = static_cast<int>(tracks_.size());

  // Never write into the caller's images: the preprocessed copies are fresh buffers.
  cv::Mat left = left_in;
  if (opt_.clahe) {
    left = cv::Mat();
    clahe_->apply(left_in, left);
  }
  const cv::Size win(opt_.klt_window_px, opt_.klt_window_px);
  // Pyramids without derivative images: lucasKanade computes the derivatives of the windows it reads.
  buildPyramid(left, win, opt_.klt_pyramid_levels, &pyr_cur_);

  if (has_last_ && !tracks_.empty()) trackTemporal(toSeconds(t - last_t_));
  replenish(left);

  if (use_right) {
    // Stereo CLAHE (on copies: the temporal tracker works on raw images). Adaptive: a frame matched on raw images
    // decides whether the next ones need CLAHE; if its raw matches fall short, that frame is matched again with CLAHE.
    const bool may_clahe = opt_.stereo_clahe && !opt_.clahe;
    bool with_clahe = may_clahe;
    if (may_clahe && opt_.stereo_clahe_adaptive)
      with_clahe = stereo_clahe_on_ && ++frames_since_probe_ < opt_.stereo_clahe_probe_frames;
    if (may_clahe && !with_clahe) {
      const std::vector<Track> before = tracks_;
      // A probe while CLAHE is on takes every match's full check (no prior shortcut), so that its verdict on the raw
      // images is as strict as the matching it may replace.
      stereoPass(left, right_in, false, /*prior_shortcut=*/!stereo_clahe_on_);
      const bool decided = stats_.stereo_attempted >= kMinStereoAttemptsForDecision;
      const bool raw_ok = decided && stats_.stereo_matched >= opt_.stereo_clahe_min_ratio * stats_.stereo_attempted;
      if (decided) {
        stereo_clahe_on_ = !raw_ok;
        frames_since_probe_ = 0;
      }
      if (!raw_ok) {
        tracks_ = before;
        stereoPass(left_in, right_in, true, true);
      }
    } else {
      stereoPass(left, right_in, with_clahe, true);
    }
  } else {
    for (Track& tr : tracks_) tr.has_right = tr.right_prior = tr.stereo_skipped = false;
  }

  points->reserve(points->size() + tracks_.size());
  for (const Track& tr : tracks_) {
    PointObservation o;
    o.id = tr.id;
    o.uv0 = tr.uv;
    o.px0 = toEigen(tr.px);
    o.velocity0 = tr.velocity;
    o.has_right = tr.has_right;
    if (tr.has_right) {
      o.uv1 = tr.uv1;
      o.px1 = toEigen(tr.px1);
    }
    o.track_length = tr.length;
    points->push_back(o);
  }

  std::swap(pyr_prev_, pyr_cur_);
  ++frame_index_;
  last_t_ = t;
  has_last_ = true;
  R_pred_.reset();
  stats_.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void PointTracker::trackTemporal(double dt) {
  const std::size_t n = tracks_.size();
  std::vector<cv::Point2f> prev(n), cur(n), rotated(n), start(n);
  const bool predict = R_pred_.has_value() && opt_.use_rotation_prediction;
  stats_.used_rotation_prediction = predict;
  const float flow_dt = opt_.klt_flow_prediction ? static_cast<float>(dt) : 0.f;
  for (std::size_t i = 0; i < n; ++i) {
    prev[i] = tracks_[i].px;
    rotated[i] = prev[i];
    if (predict) {
      const Vec3 a = *R_pred_ * Vec3(tracks_[i].uv.x(), tracks_[i].uv.y(), 1.0);
      if (a.z() > 1e-6) {
        const Vec2 px = cam0_.distort(Vec2(a.x() / a.z(), a.y() / a.z()));
        if (cam0_.inImage(px)) rotated[i] = toCv(px);
      }
    }
    // Constant translational flow: the track's last motion beyond the rotation, carried over the frame interval.
    const cv::Point2f moved = rotated[i] + tracks_[i].flow * flow_dt;
    start[i] = cam0_.inImage(toEigen(moved)) ? moved : rotated[i];
  }
  // Tracks started from their own flow need few pyramid levels; fresh tracks (no flow yet) get all of them, and so do
  // the predicted tracks that the small pyramid loses (a prediction off by more than its reach). Every track is in
  // one of the two calls, which write its cur and ok.
  std::vector<unsigned char> ok(n, 0);
  std::vector<std::size_t> predicted, full;
  for (std::size_t i = 0; i < n; ++i) {
    const bool has_flow = opt_.klt_flow_prediction && tracks_[i].length >= 2;
    (has_flow && opt_.klt_predicted_levels < opt_.klt_pyramid_levels ? predicted : full).push_back(i);
  }
  kltForwardBackward(prev, start, predicted, opt_.klt_predicted_levels, &cur, &ok);
  for (std::size_t i : predicted)
    if (!ok[i]) full.push_back(i);
  stats_.klt_retried = static_cast<int>(full.size() - (n - predicted.size()));
  std::sort(full.begin(), full.end());
  kltForwardBackward(prev, start, full, opt_.klt_pyramid_levels, &cur, &ok);

  std::vector<Track> kept;
  std::vector<Vec2> uv_prev;
  std::vector<float> start_error;
  kept.reserve(n);
  uv_prev.reserve(n);
  start_error.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    Vec2 uv;
    if (!ok[i] || !cam0_.undistort(toEigen(cur[i]), &uv)) {
      ++stats_.klt_failed;
      continue;
    }
    start_error.push_back(static_cast<float>(cv::norm(cur[i] - start[i])));
    Track tr = tracks_[i];
    tr.flow = dt > 0.0 ? (cur[i] - rotated[i]) / static_cast<float>(dt) : cv::Point2f(0.f, 0.f);
    uv_prev.push_back(tr.uv);
    // Stereo prior for this frame: last frame's right match moved by this frame's left flow.
    tr.right_prior = tr.has_right || tr.stereo_skipped;
    if (tr.right_prior) tr.px1 += cur[i] - prev[i];
    tr.has_right = false;
    tr.px = cur[i];
    tr.velocity = dt > 0.0 ? Vec2((uv - tr.uv) / dt) : Vec2::Zero();
    tr.uv = uv;
    ++tr.length;
    kept.push_back(tr);
  }
  if (!start_error.empty()) {
    const auto mid = start_error.begin() + static_cast<std::ptrdiff_t>(start_error.size() / 2);
    std::nth_element(start_error.begin(), mid, start_error.end());
    stats_.klt_start_error_px = *mid;
  }
  tracks_ = std::move(kept);
  rejectOutliers(uv_prev);
}

void PointTracker::kltForwardBackward(const std::vector<cv::Point2f>& prev, const std::vector<cv::Point2f>& start,
                                      const std::vector<std::size_t>& which, int levels, std::vector<cv::Point2f>* cur,
                                      std::vector<unsigned char>* ok) const {
  if (which.empty()) return;
  std::vector<cv::Point2f> from, to;
  from.reserve(which.size());
  to.reserve(which.size());
  for (std::size_t i : which) {
    from.push_back(prev[i]);
    to.push_back(start[i]);
  }
  // The backward check: fewer levels are cheaper but weaker (VINS-Fusion uses 1).
  const KltRoundTripParams p =
      kltRoundTripParams(opt_.klt_window_px, opt_.klt_max_iterations, opt_.klt_epsilon, opt_.klt_min_eigen, levels,
                         std::min(opt_.fb_pyramid_levels, levels), opt_.fb_threshold_px);
  const std::vector<unsigned char> kept =
      kltRoundTrip(pyr_prev_, pyr_cur_, from, &to, p, [&](std::size_t, const cv::Point2f& q) {
        return cam0_.inImage(toEigen(q), opt_.border_px) ? RoundTrip::kCheck : RoundTrip::kDrop;
      });
  for (std::size_t k = 0; k < which.size(); ++k) {
    (*cur)[which[k]] = to[k];
    (*ok)[which[k]] = kept[k];
  }
}

void PointTracker::rejectOutliers(const std::vector<Vec2>& uv_prev) {
  std::string mode = opt_.outlier_rejection;
  if (mode == "none" || tracks_.size() < 8) return;
  if (mode == "auto" || mode == "rotation") mode = R_pred_.has_value() ? "rotation" : "fundamental";
  std::vector<Vec2> uv_cur(tracks_.size());
  for (std::size_t i = 0; i < tracks_.size(); ++i) uv_cur[i] = tracks_[i].uv;
  TwoViewRansacParams p;
  p.focal_px = 0.5 * (cam0_.fx() + cam0_.fy());
  p.threshold_px = opt_.ransac_threshold_px;
  p.confidence = opt_.ransac_confidence;
  p.max_iterations = opt_.ransac_max_iterations;
  const std::vector<unsigned char> inl = mode == "rotation" ? knownRotationInliers(uv_prev, uv_cur, *R_pred_, p)
                                                            : fundamentalInliers(uv_prev, uv_cur, p);
  std::vector<Track> kept;
  kept.reserve(tracks_.size());
  for (std::size_t i = 0; i < tracks_.size(); ++i) {
    if (inl[i])
      kept.push_back(tracks_[i]);
    else
      ++stats_.ransac_rejected;
  }
  tracks_ = std::move(kept);
}

void PointTracker::replenish(const cv::Mat& image) {
  // Crowding: longer tracks first claim their disc; a track inside an older one's disc is dropped (as VINS-Mono does).
  std::vector<std::size_t> order(tracks_.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return tracks_[a].length > tracks_[b].length; });
  std::vector<cv::Point2f> pts(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) pts[k] = tracks_[order[k]].px;
  std::vector<unsigned char> keep_sorted;
  PointDetectorParams dp;
  dp.detector = opt_.detector;
  dp.fast_threshold = opt_.fast_threshold;
  dp.shi_tomasi_quality = opt_.shi_tomasi_quality;
  dp.grid_cols = opt_.grid_cols;
  dp.grid_rows = opt_.grid_rows;
  dp.min_distance_px = opt_.min_distance_px;
  dp.border_px = std::max(4, static_cast<int>(std::ceil(opt_.border_px)) + 1);
  cv::Mat mask = detectionMask(image.size(), pts, opt_.min_distance_px, dp.border_px, &keep_sorted);
  std::vector<unsigned char> keep(tracks_.size(), 1);
  for (std::size_t k = 0; k < order.size(); ++k) keep[order[k]] = keep_sorted[k];
  std::vector<Track> kept;
  kept.reserve(static_cast<std::size_t>(opt_.max_points));
  for (std::size_t i = 0; i < tracks_.size(); ++i) {
    if (keep[i])
      kept.push_back(tracks_[i]);
    else
      ++stats_.crowded;
  }
  tracks_ = std::move(kept);

  const int need = opt_.max_points - static_cast<int>(tracks_.size());
  if (need <= 0 || need < std::min(opt_.min_new_points, opt_.max_points)) return;
  // The corners of the raw image only: a CLAHE copy's are not the left image's.
  for (const cv::Point2f& p : detectCorners(image, &mask, need, dp, opt_.clahe ? nullptr : &fast_corners_)) {
    Vec2 uv;
    if (!cam0_.undistort(toEigen(p), &uv)) continue;
    Track tr;
    tr.id = next_id_++;
    tr.px = p;
    tr.uv = uv;
    tr.velocity = Vec2::Zero();
    tr.flow = cv::Point2f(0.f, 0.f);
    tr.length = 1;
    tr.has_right = false;
    tr.right_prior = false;
    tr.stereo_retry_frame = 0;
    tr.stereo_frame = 0;
    tr.stereo_skipped = false;
    tr.px1 = cv::Point2f(0.f, 0.f);
    tr.uv1 = Vec2::Zero();
    tracks_.push_back(tr);
    ++stats_.detected;
  }
}

void PointTracker::stereoPass(const cv::Mat& left, const cv::Mat& right_in, bool stereo_clahe, bool prior_shortcut) {
  const cv::Size win(opt_.klt_window_px, opt_.klt_window_px);
  cv::Mat sl = left, sr = right_in;
  const std::vector<cv::Mat>* pyr_left = &pyr_cur_;
  // Stereo matching reads no level above its search level (its KLT stops there too, see matchStereoPoints): the
  // stereo-only pyramids end there.
  const int stereo_levels = std::min(opt_.klt_pyramid_levels, std::max(1, opt_.stereo_search_level));
  stats_.used_stereo_clahe = stereo_clahe || opt_.clahe;
  if (stereo_clahe) {
    sl = cv::Mat();
    sr = cv::Mat();
    clahe_->apply(left, sl);
    clahe_->apply(right_in, sr);
    buildPyramid(sl, win, stereo_levels, &pyr_left_stereo_);
    pyr_left = &pyr_left_stereo_;
  } else if (opt_.clahe) {
    sr = cv::Mat();
    clahe_->apply(right_in, sr);
  }
  if (opt_.stereo_gain_compensation) {
    // KLT assumes equal brightness; the two cameras' gains differ (EuRoC: ~10%). Affine map of the right image's
    // mean and standard deviation onto the left's.
    cv::Scalar ml, dl, mr, dr;
    cv::meanStdDev(sl, ml, dl);
    cv::meanStdDev(sr, mr, dr);
    if (dr[0] > 1.0 && dl[0] > 1.0) {
      const double alpha = dl[0] / dr[0];
      cv::Mat adjusted;
      sr.convertTo(adjusted, CV_8U, alpha, ml[0] - alpha * mr[0]);
      sr = adjusted;
    }
  }
  buildPyramid(sr, win, stereo_levels, &pyr_right_);
  matchStereo(*pyr_left, prior_shortcut);
}

void PointTracker::matchStereo(const std::vector<cv::Mat>& pyr_left, bool prior_shortcut) {
  std::vector<std::size_t> idx;
  std::vector<cv::Point2f> px0, prior;
  std::vector<Vec2> uv0;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (std::size_t i = 0; i < tracks_.size(); ++i) {
    Track& tr = tracks_[i];
    tr.has_right = false;
    tr.stereo_skipped = tr.right_prior && frame_index_ - tr.stereo_frame < opt_.stereo_refresh_interval;
    if (tr.stereo_skipped) continue;
    if (tr.right_prior) tr.stereo_frame = frame_index_;
    if (!tr.right_prior && frame_index_ < tr.stereo_retry_frame) continue;
    idx.push_back(i);
    px0.push_back(tr.px);
    uv0.push_back(tr.uv);
    prior.push_back(tr.right_prior ? tr.px1 : cv::Point2f(nan, nan));
  }
  stats_.stereo_attempted = static_cast<int>(idx.size());
  StereoPointParams sp;
  sp.klt_window_px = opt_.klt_window_px;
  sp.klt_levels = opt_.klt_pyramid_levels;
  sp.klt_max_iterations = opt_.klt_max_iterations;
  sp.klt_epsilon = opt_.klt_epsilon;
  sp.klt_min_eigen = opt_.klt_min_eigen;
  sp.search_min_depth_m = opt_.stereo_search_min_depth_m;
  sp.search_min_zncc = opt_.stereo_search_min_zncc;
  sp.search_level = opt_.stereo_search_level;
  sp.fb_threshold_px = opt_.stereo_fb_threshold_px;
  sp.prior_levels = prior_shortcut ? opt_.stereo_prior_levels : -1;
  sp.prior_agree_px = prior_shortcut ? opt_.stereo_prior_agree_px : 0.0;
  sp.epipolar_threshold_px = opt_.stereo_epipolar_threshold_px;
  sp.min_depth_m = opt_.stereo_min_depth_m;
  sp.border_px = opt_.border_px;
  StereoPointStats ss;
  const std::vector<StereoPointResult> res =
      matchStereoPoints(pyr_left, pyr_right_, cam0_, *cam1_, T_C1_C0_, px0, uv0, &prior, sp, &ss);
  for (std::size_t k = 0; k < idx.size(); ++k) {
    Track& tr = tracks_[idx[k]];
    tr.has_right = res[k].ok;
    tr.right_prior = false;
    if (res[k].ok) {
      tr.px1 = res[k].px1;
      tr.uv1 = res[k].uv1;
    } else {
      tr.stereo_retry_frame = frame_index_ + opt_.stereo_retry_interval;
    }
  }
  stats_.stereo_matched = ss.matched;
  stats_.stereo_search_failed = ss.search_failed;
  stats_.stereo_klt_failed = ss.klt_failed;
  stats_.stereo_round_trip_skipped = ss.round_trip_skipped;
  stats_.stereo_epipolar_rejected = ss.epipolar_rejected;
  stats_.stereo_depth_rejected = ss.depth_rejected;
}

}  // namespace linnet
