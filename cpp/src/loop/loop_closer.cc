#include "linnet/loop/loop_closer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <Eigen/Eigenvalues>

namespace linnet {

namespace {

// Square root of a covariance's largest eigenvalue.
double largestStd(const Mat3& covariance) {
  const Eigen::SelfAdjointEigenSolver<Mat3> es(covariance, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, es.eigenvalues()(2)));
}

constexpr double kDegToRad = M_PI / 180.0;

double wrapPi(double a) { return std::atan2(std::sin(a), std::cos(a)); }

PlaceDescription placeDescription(const LoopOptions& o) {
  PlaceDescription pd;
  pd.patch_px = o.orb_patch_px;
  pd.corners = o.corners;
  pd.fast_threshold = o.fast_threshold;
  return pd;
}

}  // namespace

LoopCloser::LoopCloser(const LoopOptions& options, const CameraModel& cam0, const Pose& T_B_C0, const Pose& T_C1_C0)
    : options_(options), cam0_(cam0), T_B_C0_(T_B_C0), T_C1_C0_(T_C1_C0) {}

bool LoopCloser::addKeyframe(Timestamp t, const Pose& T_W_B, const cv::Mat& left,
                             const std::vector<PointObservation>& points) {
  return insert(t, T_W_B, describePlace(left, cam0_, points, T_C1_C0_, placeDescription(options_)));
}

void LoopCloser::queueKeyframe(Timestamp t, const Pose& T_W_B, const cv::Mat& left,
                               const std::vector<PointObservation>& points, const std::vector<LineObservation>& lines,
                               const FastCorners* corners, const std::vector<LbdDescriptor>* line_desc) {
  Queued q{t, T_W_B, describePlace(left, cam0_, points, T_C1_C0_, placeDescription(options_), corners), {}, {}};
  if (options_.use_lines) describePlaceLines(left, lines, LbdOptions{}, &q.place, line_desc);
  queued_.push_back(std::move(q));
}

int LoopCloser::updateWindow(const std::vector<std::pair<Timestamp, Pose>>& window,
                             const std::vector<std::pair<std::int64_t, Vec3>>& landmarks,
                             const std::vector<MapLine>& line_landmarks) {
  for (Queued& q : queued_) {
    const auto it = std::find_if(window.begin(), window.end(), [&](const auto& w) { return w.first == q.t; });
    if (it == window.end()) continue;
    q.T_W_B = it->second;
    q.p_W.assign(q.place.tracked_ids.size(), Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
    for (std::size_t i = 0; i < q.p_W.size(); ++i) {
      const auto lm = std::lower_bound(landmarks.begin(), landmarks.end(), q.place.tracked_ids[i],
                                       [](const std::pair<std::int64_t, Vec3>& a, std::int64_t id) { return a.first < id; });
      if (lm != landmarks.end() && lm->first == q.place.tracked_ids[i]) q.p_W[i] = lm->second;
    }
    q.lines_W.clear();
    for (std::int64_t id : q.place.line_ids) {
      const auto l = std::lower_bound(line_landmarks.begin(), line_landmarks.end(), id,
                                      [](const MapLine& a, std::int64_t b) { return a.id < b; });
      if (l != line_landmarks.end() && l->id == id) q.lines_W.push_back(*l);
    }
  }
  // Queued keyframes older than the window's oldest frame have left it: their estimates are final.
  return insertQueuedBefore(window.empty() ? std::numeric_limits<Timestamp>::max() : window.front().first);
}

int LoopCloser::flush() {
  const int loops = insertQueuedBefore(std::numeric_limits<Timestamp>::max());
  if (whole_solve_pending_) {
    ++solves_;
    graph_.optimise(solveOptions());
    whole_solve_pending_ = false;
  }
  return loops;
}

PoseGraphOptions LoopCloser::solveOptions() const {
  PoseGraphOptions po;
  po.loop_huber = options_.loop_huber;
  po.max_iterations = options_.max_iterations;
  return po;
}

int LoopCloser::insertQueuedBefore(Timestamp limit) {
  int loops = 0;
  while (!queued_.empty() && queued_.front().t < limit) {
    Queued q = std::move(queued_.front());
    queued_.pop_front();
    setPlaceDepths(q.p_W, q.T_W_B * T_B_C0_, &q.place);
    setPlaceLines(q.lines_W, q.T_W_B * T_B_C0_, &q.place);
    loops += insert(q.t, q.T_W_B, std::move(q.place)) ? 1 : 0;
  }
  return loops;
}

bool LoopCloser::insert(Timestamp t, const Pose& T_W_B, PlaceFeatures place) {
  Keyframe kf;
  kf.t = t;
  if (inserted_ > 0) path_m_ += (T_W_B.p - last_odometry_p_).norm();
  kf.path_m = path_m_;
  last_odometry_p_ = T_W_B.p;
  ++inserted_;
  const Pose correction = latestCorrection();
  const std::size_t k = graph_.addNode(T_W_B);
  graph_.setEstimate(k, correction * T_W_B);
  const std::size_t first = k > static_cast<std::size_t>(options_.sequential_edges)
                                ? k - static_cast<std::size_t>(options_.sequential_edges)
                                : 0;
  for (std::size_t i = first; i < k; ++i) {
    const double length = (graph_.odometryPose(k).p - graph_.odometryPose(i).p).norm();
    graph_.addEdge(graph_.odometryEdge(i, k, options_.odometry_sigma_m + options_.odometry_sigma_per_m * length,
                                       options_.odometry_sigma_yaw_deg * kDegToRad));
  }
  // The database's copy; the new keyframe is matched at full precision.
  kf.place = storePlace(place, options_.stored_corners);
  keyframes_.push_back(std::move(kf));
  const bool too_soon =
      any_loop_ && inserted_ - 1 - last_loop_keyframe_ < static_cast<std::size_t>(options_.min_keyframes_between_loops);
  const bool loop = !too_soon && tryLoop(k, place);
  if (loop) last_loop_keyframe_ = inserted_ - 1;
  if (placeDescribedBefore(k)) {
    keyframes_[k].place = StoredPlace{};
    // Without a description and a loop edge, the revisit's node would only relay the odometry between its
    // neighbours: the graph links them directly instead (its frames take the previous node's correction).
    if (!loop && options_.cull_revisits) {
      graph_.removeLastNode();
      keyframes_.pop_back();
    }
  }
  return loop;
}

std::size_t LoopCloser::describedKeyframes() const {
  return static_cast<std::size_t>(
      std::count_if(keyframes_.begin(), keyframes_.end(), [](const Keyframe& kf) { return kf.place.described(); }));
}

LoopStats LoopCloser::stats() const {
  LoopStats s;
  s.keyframes = inserted_;
  s.graph_nodes = keyframes_.size();
  s.described = describedKeyframes();
  s.graph_solves = solves_;
  std::size_t bytes = 0;
  for (const Keyframe& kf : keyframes_) bytes += kf.place.bytes();
  s.place_mb = 1e-6 * static_cast<double>(bytes);
  return s;
}

bool LoopCloser::placeDescribedBefore(std::size_t k) const {
  // A revisit: an older keyframe, described and at least min_time_gap_s older, within place_reuse_m and
  // place_reuse_deg of this one (corrected poses). Its description stands for the place; keeping every revisit's
  // would grow the database without bound on a long flight over the same space.
  if (!(options_.place_reuse_m > 0.0)) return false;
  const Keyframe& now = keyframes_[k];
  const Pose P = graph_.pose(k);
  const Vec3 axis = P.R() * T_B_C0_.R().col(2);
  const double cos_max = std::cos(options_.place_reuse_deg * kDegToRad);
  for (std::size_t j = 0; j < k; ++j) {
    const Keyframe& old = keyframes_[j];
    if (toSeconds(now.t - old.t) < options_.min_time_gap_s) break;
    if (!old.place.described()) continue;
    const Pose Q = graph_.pose(j);
    if ((Q.p - P.p).norm() < options_.place_reuse_m && axis.dot(Q.R() * T_B_C0_.R().col(2)) > cos_max) return true;
  }
  return false;
}

bool LoopCloser::tryLoop(std::size_t k, const PlaceFeatures& place) {
  const Keyframe& now = keyframes_[k];
  const Pose P_new = graph_.pose(k);
  const Vec3 axis_new = P_new.R() * T_B_C0_.R().col(2);
  const double cos_max = std::cos(options_.max_view_angle_deg * kDegToRad);
  std::vector<std::pair<double, std::size_t>> candidates;
  for (std::size_t j = 0; j < k; ++j) {
    const Keyframe& old = keyframes_[j];
    if (toSeconds(now.t - old.t) < options_.min_time_gap_s) break;  // keyframes are in time order
    if (!old.place.described()) continue;  // a revisit without its own description
    const Pose P_old = graph_.pose(j);
    const double d = (P_new.p - P_old.p).norm();
    const double radius = options_.search_radius_m + options_.search_radius_per_m * (now.path_m - old.path_m);
    if (d > radius) continue;
    if (axis_new.dot(P_old.R() * T_B_C0_.R().col(2)) < cos_max) continue;
    candidates.emplace_back(d, j);
  }
  std::sort(candidates.begin(), candidates.end());
  if (candidates.size() > static_cast<std::size_t>(options_.max_candidates))
    candidates.resize(static_cast<std::size_t>(options_.max_candidates));

  PlaceMatchOptions mo;
  mo.max_hamming = options_.max_hamming;
  mo.match_ratio = options_.match_ratio;
  mo.min_inliers = options_.min_inliers;
  mo.ransac_px = options_.ransac_px;
  mo.focal_px = cam0_.fx();
  mo.two_way = options_.two_way_pnp;
  mo.guided_radius_px = options_.guided_radius_px;
  mo.use_lines = options_.use_lines;
  mo.line_max_hamming = options_.line_max_hamming;
  mo.line_max_angle_deg = options_.line_max_angle_deg;
  for (const auto& [distance, j] : candidates) {
    // The corrected odometry's relative pose of the two bodies: what the measured one must agree with within the
    // search bounds; in the cameras, the prior of guided matching (multiplied out left to right, as the loops
    // measured so far were).
    const Pose predicted = graph_.pose(j).inverse() * P_new;
    mo.prior_T_Cold_Cnew = T_B_C0_.inverse() * graph_.pose(j).inverse() * P_new * T_B_C0_;
    const PlaceMatch m = matchPlaces(expandPlace(keyframes_[j].place), place, mo);
    if (!m.ok) continue;
    const Pose T_Bj_Bk = T_B_C0_ * m.T_Cold_Cnew * T_B_C0_.inverse();
    const double radius =
        options_.search_radius_m + options_.search_radius_per_m * (now.path_m - keyframes_[j].path_m);
    const double dyaw = wrapPi(graph_.heading(k, graph_.pose(j).R() * T_Bj_Bk.R()) - graph_.heading(k, P_new.R()));
    if ((T_Bj_Bk.p - predicted.p).norm() > radius ||
        std::abs(dyaw) > options_.max_yaw_change_deg * kDegToRad)
      continue;
    double sigma_t = options_.loop_sigma_m, sigma_yaw = options_.loop_sigma_yaw_deg * kDegToRad;
    if (options_.loop_pnp_sigma_scale > 0.0) {
      // The PnP's largest position and rotation standard deviations (a rotation into the body frame leaves them as
      // they are; the extrinsic's lever arm is left out).
      sigma_t = std::max(sigma_t, options_.loop_pnp_sigma_scale * largestStd(m.covariance.block<3, 3>(3, 3)));
      sigma_yaw = std::max(sigma_yaw, options_.loop_pnp_sigma_scale * largestStd(m.covariance.block<3, 3>(0, 0)));
    }
    if (m.inliers > 0 && m.inliers < options_.full_weight_inliers) {
      const double looser = static_cast<double>(options_.full_weight_inliers) / m.inliers;
      sigma_t *= looser;
      sigma_yaw *= looser;
    }
    graph_.addEdge(graph_.loopEdge(j, k, T_Bj_Bk, sigma_t, sigma_yaw));
    // A loop the corrected graph already agrees with (within consistent_loop_sigmas of its edge's sigmas) changes it
    // little: its edge is kept for the next solve, and the whole graph is not solved again now (on a long flight
    // over the same space most loops are of this kind, and each solve costs in proportion to all keyframes).
    auto within = [&](double sigmas) {
      return (T_Bj_Bk.p - predicted.p).norm() < sigmas * sigma_t && std::abs(dyaw) < sigmas * sigma_yaw;
    };
    const bool consistent = options_.consistent_loop_sigmas > 0.0 && within(options_.consistent_loop_sigmas);
    PoseGraphOptions po = solveOptions();
    // A small correction moves the newest nodes mostly: they are solved with the older ones held, at a cost that
    // does not grow with the graph. The whole graph is solved again at the end of the stream.
    const auto window = static_cast<std::size_t>(options_.solve_window_nodes);
    if (window > 0 && graph_.size() > window && within(options_.full_solve_sigmas))
      po.first_free_node = graph_.size() - window;
    if (consistent) {
      whole_solve_pending_ = true;  // its edge waits for the next solve
    } else {
      ++solves_;
      if (!graph_.optimise(po)) continue;
      whole_solve_pending_ = po.first_free_node > 0;  // a whole solve covers every edge added before it
    }
    LoopEvent e;
    e.t_new = now.t;
    e.t_old = keyframes_[j].t;
    e.inliers = m.inliers;
    e.T_old_new = T_Bj_Bk;
    e.sigma_m = sigma_t;
    e.sigma_yaw_deg = sigma_yaw / kDegToRad;
    e.method = m.method;
    const Pose after = graph_.pose(k);
    e.correction_m = (after.p - P_new.p).norm();
    e.correction_yaw_deg = std::abs(wrapPi(graph_.heading(k, after.R()) - graph_.heading(k, P_new.R()))) / kDegToRad;
    loops_.push_back(e);
    any_loop_ = true;
    return true;
  }
  return false;
}

Pose LoopCloser::correctionAt(Timestamp t) const {
  const auto it = std::upper_bound(keyframes_.begin(), keyframes_.end(), t,
                                   [](Timestamp x, const Keyframe& kf) { return x < kf.t; });
  if (it == keyframes_.begin()) return Pose::identity();
  return graph_.correction(static_cast<std::size_t>(it - keyframes_.begin()) - 1);
}

Pose LoopCloser::latestCorrection() const {
  if (keyframes_.empty()) return Pose::identity();
  return graph_.correction(keyframes_.size() - 1);
}

MapLine LoopCloser::correctedLine(MapLine line) const {
  const Pose C = line.t_last > 0 ? correctionAt(line.t_last) : latestCorrection();
  line.a = C * line.a;
  line.b = C * line.b;
  return line;
}

}  // namespace linnet
