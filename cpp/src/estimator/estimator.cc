// Frame flow, initialisation and failure handling of the estimator (DESIGN B1; thesis ch. 5).
#include <algorithm>
#include <chrono>
#include <cmath>

#include "estimator_core.h"
#include "linnet/core/error.h"
#include "linnet/estimator/initial_prior.h"
#include "linnet/estimator/keyframe_policy.h"
#include "linnet/estimator/pnp.h"
#include "linnet/imu/gravity_alignment.h"

namespace linnet {

namespace {
constexpr double kDegToRad = M_PI / 180.0;
}

const char* toString(TrackingStatus s) {
  switch (s) {
    case TrackingStatus::kInitialising:
      return "initialising";
    case TrackingStatus::kTracking:
      return "tracking";
    case TrackingStatus::kLost:
      return "lost";
  }
  return "?";
}

// ---------------------------------------------------------------------------------------------------------------
Estimator::Estimator(const EstimatorOptions& options, const ImuNoise& noise, const Pose& T_B_C0,
                     std::optional<Pose> T_B_C1) {
  EstimatorOptions o = options;
  validateOptions(o, "estimator");
  core_ = std::make_unique<EstimatorCore>(o, noise, T_B_C0, std::move(T_B_C1));
}
Estimator::~Estimator() = default;
void Estimator::addImu(const ImuSample& s) { core_->addImu(s); }
EstimatorOutput Estimator::addFrame(const FrameObservations& obs) { return core_->addFrame(obs); }
std::vector<Vec3> Estimator::landmarkPositions() const { return core_->landmarkPositions(); }
std::vector<MapLine> Estimator::mapLines() const { return core_->mapLines(); }
std::map<std::int64_t, std::vector<LineSighting>> Estimator::mapLineSightings() const {
  return core_->mapLineSightings();
}
std::vector<MapLine> Estimator::windowLines() const { return core_->windowLines(); }
std::vector<std::pair<Timestamp, Pose>> Estimator::windowPoses() const { return core_->windowPoses(); }
std::vector<std::pair<std::int64_t, Vec3>> Estimator::pointLandmarks() const { return core_->pointLandmarks(); }

// ---------------------------------------------------------------------------------------------------------------
namespace {
ImuNoise weightedNoise(ImuNoise noise, const ImuWeightOptions& w) {
  noise.acc_noise_density *= w.noise_density_scale;
  noise.gyr_noise_density *= w.noise_density_scale;
  noise.acc_random_walk *= w.random_walk_scale;
  noise.gyr_random_walk *= w.random_walk_scale;
  return noise;
}
}  // namespace

EstimatorCore::EstimatorCore(const EstimatorOptions& options, const ImuNoise& noise, const Pose& T_B_C0,
                             std::optional<Pose> T_B_C1)
    : options_(options),
      noise_(weightedNoise(noise, options.imu)),
      T_B_C0_(T_B_C0),
      T_B_C1_(T_B_C1),
      g_W_(0.0, 0.0, -noise.gravity),
      points_(options.solver, T_B_C0, T_B_C1),
      lines_(options.lines, options.solver.focal_length, T_B_C0, T_B_C1),
      huber_(options.solver.huber_px),
      line_loss_(options.lines.loss == "cauchy"
                     ? static_cast<ceres::LossFunction*>(new ceres::CauchyLoss(options.lines.huber_px))
                     : new ceres::HuberLoss(options.lines.huber_px)) {
  time_offset_[0] = 1e-3 * options.time_offset.initial_ms;
  preint_options_.gap_dt_s = options.imu_gap.gap_periods / noise.rate_hz;
  preint_options_.gap_acc_sigma = options.imu_gap.acc_sigma;
  preint_options_.gap_gyr_sigma = options.imu_gap.gyr_sigma;
  ImuBufferOptions buffer;
  buffer.max_gap_s = 10.0;  // longer gaps are handled here (restartAfterImuGap), not refused
  imu_ = ImuBuffer(buffer);
}

void EstimatorCore::observeLines(FrameId frame, const FrameObservations& obs) {
  if (!options_.lines.enabled || obs.lines.empty()) return;
  ScopedMs timer(&line_ms_);
  lines_.observe(frame, obs.t, obs.lines);
}

void EstimatorCore::clearLandmarks() {
  points_.clear();
  ScopedMs timer(&line_ms_);
  lines_.clear();
}

void EstimatorCore::addImu(const ImuSample& s) {
  // A step shorter than a gap (gap_periods sample periods) is always integrated, whatever max_bridge_s says.
  const double bridge_s = std::max(options_.imu_gap.max_bridge_s, preint_options_.gap_dt_s);
  if (!imu_.empty() && s.t > imu_.endTime() && toSeconds(s.t - imu_.endTime()) > bridge_s) {
    // Too long to integrate: restart the buffer after the gap; the next frame re-initialises (restartAfterImuGap).
    if (imu_gap_start_ < 0) imu_gap_start_ = imu_.endTime();
    imu_gap_end_ = s.t;
    imu_ = ImuBuffer(imu_.options());
  }
  imu_.append(s);
}

void EstimatorCore::restartAfterImuGap(Timestamp t) {
  std::optional<NavState> s;
  if (mode_ == Mode::kTracking && !window_.empty()) {
    const WindowFrame& f = window_.newest();
    s = NavState{};
    s->t = f.t;
    s->T_W_B = f.T_W_B();
    s->v_W = f.v();
    s->b_a = f.ba();
    s->b_g = f.bg();
  } else if (last_good_) {
    s = last_good_;
  }
  window_.clear();
  clearLandmarks();
  priors_.clear();
  mode_ = Mode::kWaitingForFirstFrame;
  last_good_.reset();
  if (s) {
    // Constant velocity over the gap, to the first sample after it (where the IMU buffer starts again).
    s->T_W_B.p += s->v_W * toSeconds(imu_gap_end_ - s->t);
    s->t = imu_gap_end_;
    last_good_ = s;
    lost_since_ = t;
    ++reinitialisations_;
  }
  imu_gap_start_ = imu_gap_end_ = -1;
}

EstimatorOutput EstimatorCore::output(const WindowFrame& f) const {
  EstimatorOutput out;
  out.t = f.t;
  out.has_pose = true;
  out.status = TrackingStatus::kTracking;
  out.T_W_B = f.T_W_B();
  out.v_W = f.v();
  out.b_a = f.ba();
  out.b_g = f.bg();
  out.keyframe = f.keyframe;
  out.num_points = points_.countUsed();
  out.num_lines = lines_.countUsed();
  out.reinitialisations = reinitialisations_;
  out.T_B_R = rigCorrection();
  out.S_C1 = stereoCorrection();
  out.time_offset_s = timeOffset();
  return out;
}

NavState EstimatorCore::predictFrom(const WindowFrame& f, Timestamp t) const {
  Preintegration pre(noise_, f.ba(), f.bg(), preint_options_);
  for (const ImuSample& m : imu_.samplesBetween(f.t, t)) pre.push(m);
  return predictWith(f, pre, t);
}

NavState EstimatorCore::predictWith(const WindowFrame& f, const Preintegration& pre, Timestamp t) const {
  NavState s;
  s.t = t;
  s.b_a = f.ba();
  s.b_g = f.bg();
  const Pose T = f.T_W_B();
  const double dt = pre.sumDt();
  s.T_W_B = Pose(T.q * pre.gamma(), T.p + f.v() * dt + 0.5 * g_W_ * dt * dt + T.q * pre.alpha());
  s.v_W = f.v() + g_W_ * dt + T.q * pre.beta();
  return s;
}

WindowFrame& EstimatorCore::pushPredicted(Timestamp t) {
  const WindowFrame& prev = window_.newest();
  auto pre = std::make_unique<Preintegration>(noise_, prev.ba(), prev.bg(), preint_options_);
  for (const ImuSample& m : imu_.samplesBetween(prev.t, t)) pre->push(m);
  const NavState s = predictWith(prev, *pre, t);  // the frame's own preintegration: the samples integrated once
  WindowFrame& f = window_.push(t);
  f.preint = std::move(pre);
  f.setPose(s.T_W_B);
  f.setV(s.v_W);
  f.setBiases(s.b_a, s.b_g);
  f.gyr = gyroAt(t);
  return f;
}

NavState EstimatorCore::firstState(Timestamp t, bool* is_static) const {
  const Timestamp t0 = std::max(imu_.startTime(), t - fromSeconds(options_.init.gravity_window_s));
  const std::vector<ImuSample> samples = imu_.samplesBetween(t0, t);
  NavState s;
  s.t = t;
  s.T_W_B = Pose(gravityAlignedRotation(samples), Vec3::Zero());
  *is_static = isStatic(samples, options_.init.at_rest, noise_.gravity);
  if (*is_static) s.b_g = imuStatistics(samples).gyr_mean;  // at rest the mean angular rate is the gyro bias
  return s;
}

void EstimatorCore::addInitialPrior(double velocity_sigma) {
  const InitOptions& o = options_.init;
  InitialPriorSigmas s;
  s.position_m = o.prior_position_m;
  s.yaw_rad = o.prior_yaw_deg * kDegToRad;
  s.velocity = velocity_sigma;
  s.acc_bias = o.prior_acc_bias;
  s.gyr_bias = o.prior_gyr_bias;
  priors_.push_back(makeInitialPrior(window_[0], s, &pose_manifold_));
  addCalibrationPriors();
}

bool EstimatorCore::startWindow(const FrameObservations& obs, const NavState& start, double velocity_sigma) {
  window_.clear();
  clearLandmarks();
  priors_.clear();
  WindowFrame& f = window_.push(obs.t);
  f.gyr = gyroAt(obs.t);
  f.setPose(start.T_W_B);
  f.setV(start.v_W);
  f.setBiases(start.b_a, start.b_g);
  f.keyframe = true;
  points_.observe(f.id, obs.points);
  points_.triangulate(window_);
  observeLines(f.id, obs);
  {
    ScopedMs timer(&line_ms_);
    lines_.triangulate(window_);
  }
  // Stereo lines count as landmarks too: a low-texture frame may start a window with few points.
  const int n = points_.countTriangulatedIn(f.id) + lines_.countTriangulatedIn(f.id);
  if (n < options_.init.min_points) {
    window_.clear();
    clearLandmarks();
    return false;
  }
  const bool velocity_known = velocity_sigma > 0.0;
  mode_ = velocity_known ? Mode::kTracking : Mode::kCollecting;
  if (velocity_known) addInitialPrior(velocity_sigma);
  return velocity_known;
}

bool EstimatorCore::collectStep(const FrameObservations& obs) {
  // Pose of the new frame: IMU rotation as the guess, then PnP against the window's stereo points.
  WindowFrame& f = pushPredicted(obs.t);
  const WindowFrame& prev = window_[window_.size() - 2];
  f.setPose(Pose(f.T_W_B().q, prev.T_W_B().p));
  f.setV(Vec3::Zero());
  f.keyframe = true;
  points_.observe(f.id, obs.points);
  observeLines(f.id, obs);
  std::vector<Vec3> p_W;
  std::vector<Vec2> uv;
  points_.triangulatedIn(window_, f.id, &p_W, &uv);
  if (static_cast<int>(p_W.size()) < options_.init.min_points) return false;
  Pose T = f.T_W_B();
  const PnpResult r = refinePosePnp(p_W, uv, T_B_C0(), options_.solver.focal_length, 3.0 * options_.solver.outlier_px,
                                    &T);
  if (!r.ok || r.rms_px > options_.init.max_pnp_error_px || r.inliers < options_.init.min_points) return false;
  f.setPose(T);
  points_.triangulate(window_);
  {
    ScopedMs timer(&line_ms_);
    lines_.triangulate(window_);
  }
  return true;
}

bool EstimatorCore::finishMovingInit() {
  // Gyroscope bias from visual vs preintegrated rotations (thesis ch. 5; Qin et al., VINS-Mono, 2018, sec. V-B):
  // for each consecutive pair, Log(gamma_ij(bg)^-1 q_i^-1 q_j) ~= J_gamma_bg dbg, stacked least squares.
  Mat3 A = Mat3::Zero();
  Vec3 b = Vec3::Zero();
  for (int k = 1; k < window_.size(); ++k) {
    const Preintegration& pre = *window_[k].preint;
    const Quat q_ij = window_[k - 1].T_W_B().q.conjugate() * window_[k].T_W_B().q;
    const Mat3 J = pre.jacobian().block<3, 3>(Preintegration::kR, Preintegration::kBg);
    const Vec3 r = logSO3(pre.gamma().conjugate() * q_ij);
    A += J.transpose() * J;
    b += J.transpose() * r;
  }
  const Vec3 dbg = A.ldlt().solve(b);
  if (!dbg.allFinite() || dbg.norm() > options_.failure.max_gyr_bias) return false;
  for (int k = 0; k < window_.size(); ++k) window_[k].setBiases(window_[k].ba(), window_[k].bg() + dbg);
  for (int k = 1; k < window_.size(); ++k) window_[k].preint->repropagate(window_[k - 1].ba(), window_[k - 1].bg());
  // Velocities from the preintegrated position constraint with known gravity:
  // p_j = p_i + v_i dt + 1/2 g dt^2 + R_i alpha_ij  =>  v_i = (p_j - p_i - 1/2 g dt^2 - R_i alpha_ij) / dt.
  for (int k = 0; k + 1 < window_.size(); ++k) {
    const Preintegration& pre = *window_[k + 1].preint;
    const double dt = pre.sumDt();
    const Pose Ti = window_[k].T_W_B(), Tj = window_[k + 1].T_W_B();
    window_[k].setV((Tj.p - Ti.p - 0.5 * g_W_ * dt * dt - Ti.q * pre.alpha()) / dt);
  }
  const int n = window_.size();
  const Preintegration& last = *window_[n - 1].preint;
  window_[n - 1].setV(window_[n - 2].v() + g_W_ * last.sumDt() + window_[n - 2].T_W_B().q * last.beta());
  addInitialPrior(0.0);
  mode_ = Mode::kTracking;
  return true;
}

void EstimatorCore::decideKeyframe(WindowFrame& f, int tracked) {
  const FrameId kf_id = window_.lastKeyframeBefore(window_.size() - 1);
  const WindowFrame* kf = window_.find(kf_id);
  if (kf == nullptr) {
    f.keyframe = true;
    return;
  }
  KeyframeInputs in;
  const Pose T_kf = kf->T_W_B(), T_new = f.T_W_B();
  in.translation_m = (T_new.p - T_kf.p).norm();
  in.rotation_rad = logSO3(T_kf.q.conjugate() * T_new.q).norm();
  in.dt_s = toSeconds(f.t - kf->t);
  in.tracked = tracked;
  const Mat3 R_Cnew_Ckf = ((T_new * T_B_C0()).inverse() * (T_kf * T_B_C0())).R();
  in.parallax_px =
      compensatedParallaxPx(points_.correspondences(kf->id, f.id), R_Cnew_Ckf, options_.solver.focal_length);
  f.keyframe = keyframeDecision(options_.keyframe, in) != KeyframeReason::kNone;
}

bool EstimatorCore::detectRest(const WindowFrame& prev, const WindowFrame& f) const {
  const ZeroVelocityOptions& o = options_.zero_velocity;
  if (f.v().norm() > o.max_speed || prev.v().norm() > o.max_speed) return false;
  const std::vector<std::pair<Vec2, Vec2>> pairs = points_.correspondences(prev.id, f.id);
  if (static_cast<int>(pairs.size()) < o.min_points) return false;
  std::vector<double> motion;
  motion.reserve(pairs.size());
  for (const auto& [a, b] : pairs) motion.push_back(options_.solver.focal_length * (b - a).norm());
  std::nth_element(motion.begin(), motion.begin() + static_cast<std::ptrdiff_t>(motion.size() / 2), motion.end());
  if (motion[motion.size() / 2] > o.max_motion_px) return false;
  const Timestamp t0 = f.t - fromSeconds(o.window_s);
  if (!imu_.covers(t0, f.t)) return false;
  return isStatic(imu_.samplesBetween(t0, f.t), options_.init.at_rest, noise_.gravity);
}

bool EstimatorCore::failureAfterSolve(const NavState& predicted) const {
  const WindowFrame& f = window_.newest();
  const FailureOptions& o = options_.failure;
  if (!f.v().allFinite() || f.v().norm() > o.max_velocity) return true;
  if (f.ba().norm() > o.max_acc_bias || f.bg().norm() > o.max_gyr_bias) return true;
  const Pose T = f.T_W_B();
  if (!T.p.allFinite() || (T.p - predicted.T_W_B.p).norm() > o.max_jump_m) return true;
  if (logSO3(predicted.T_W_B.q.conjugate() * T.q).norm() > o.max_jump_deg * kDegToRad) return true;
  return false;
}

void EstimatorCore::resetAfterFailure(const FrameObservations& obs, const NavState& state, EstimatorOutput* out) {
  ++reinitialisations_;
  if (lost_since_ < 0) lost_since_ = obs.t;
  last_good_ = state;
  out->t = obs.t;
  out->status = TrackingStatus::kLost;
  out->has_pose = true;
  out->T_W_B = state.T_W_B;
  out->v_W = state.v_W;
  out->b_a = state.b_a;
  out->b_g = state.b_g;
  out->reinitialisations = reinitialisations_;
  // A new window from the last good (IMU-propagated) state; tracking resumes at once if the frame has stereo points.
  if (startWindow(obs, state, options_.init.prior_velocity_reinit)) lost_since_ = -1;
  else mode_ = Mode::kWaitingForFirstFrame;
}

EstimatorOutput EstimatorCore::addFrame(const FrameObservations& obs) {
  const auto t0 = std::chrono::steady_clock::now();
  line_ms_ = 0.0;
  solver_ms_ = 0.0;
  if (have_frame_ && obs.t <= last_frame_t_)
    throw UsageError("Estimator::addFrame: frame time " + std::to_string(obs.t) + " ns is not after the previous " +
                     std::to_string(last_frame_t_) + " ns");
  have_frame_ = true;
  last_frame_t_ = obs.t;
  EstimatorOutput out;
  out.t = obs.t;
  out.reinitialisations = reinitialisations_;
  auto finish = [&](EstimatorOutput o) {
    // The window's preintegrations hold their own samples: keep only what later frames can still ask for.
    Timestamp keep = obs.t - fromSeconds(options_.init.gravity_window_s);
    if (!window_.empty()) keep = std::min(keep, window_[0].t);
    if (last_good_) keep = std::min(keep, last_good_->t);
    imu_.dropBefore(keep);
    o.solve_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    o.line_ms = line_ms_;
    o.solver_ms = solver_ms_;
    return o;
  };
  if (imu_gap_end_ >= 0) restartAfterImuGap(obs.t);
  if (!imu_.empty() && obs.t < imu_.startTime()) {  // a frame inside an IMU gap that was not bridged: no pose
    out.status = last_good_ ? TrackingStatus::kLost : TrackingStatus::kInitialising;
    return finish(out);
  }
  if (!T_B_C1_.has_value() || !obs.stereo) return finish(out);  // monocular: no initialiser yet

  if (mode_ == Mode::kWaitingForFirstFrame) {
    if (last_good_.has_value()) {
      // Re-initialising after a failure: dead-reckon from the last good state, restart when points allow.
      NavState s = *last_good_;
      {
        WindowFrame tmp;
        tmp.t = s.t;
        tmp.setPose(s.T_W_B);
        tmp.setV(s.v_W);
        tmp.setBiases(s.b_a, s.b_g);
        s = predictFrom(tmp, obs.t);
      }
      const bool expired = lost_since_ >= 0 && toSeconds(obs.t - lost_since_) > options_.failure.max_dead_reckoning_s;
      if (expired) s.v_W.setZero();  // assume the body stopped rather than integrating without bound
      last_good_ = s;
      if (startWindow(obs, s, options_.init.prior_velocity_reinit)) {
        lost_since_ = -1;
        return finish(output(window_.newest()));
      }
      out.status = TrackingStatus::kLost;
      out.has_pose = true;
      out.T_W_B = s.T_W_B;
      out.v_W = s.v_W;
      out.b_a = s.b_a;
      out.b_g = s.b_g;
      return finish(out);
    }
    // The stillness test and gravity alignment need IMU history before the frame: wait (a few frames at most)
    // until there is gravity_window_s of it, or at least enough samples for the stillness test.
    const double needed_s = std::min(options_.init.gravity_window_s,
                                     (options_.init.at_rest.min_samples + 1) / noise_.rate_hz);
    if (imu_.empty() || !imu_.covers(imu_.startTime(), obs.t) || toSeconds(obs.t - imu_.startTime()) < needed_s)
      return finish(out);
    bool is_static = false;
    const NavState s = firstState(obs.t, &is_static);
    if (startWindow(obs, s, is_static ? options_.init.prior_velocity_static : 0.0)) {
      last_good_ = s;
      return finish(output(window_.newest()));
    }
    return finish(out);
  }

  if (mode_ == Mode::kCollecting) {
    if (!collectStep(obs)) {
      mode_ = Mode::kWaitingForFirstFrame;
      window_.clear();
      clearLandmarks();
      return finish(out);
    }
    if (window_.size() < options_.init.moving_frames) return finish(out);
    if (!finishMovingInit()) {
      mode_ = Mode::kWaitingForFirstFrame;
      window_.clear();
      clearLandmarks();
      return finish(out);
    }
    // The first solve starts from the initialiser's rough state (velocities from differences, biases from a
    // linear fit): it gets more iterations and every cam1 residual, unlike a per-frame solve from an IMU prediction.
    solveWindow(std::max(options_.solver.max_num_iterations, options_.init.solver_iterations), true);
    points_.rejectOutliers(window_);
    {
      ScopedMs timer(&line_ms_);
      lines_.rejectOutliers(window_);
    }
    slideWindow();
    const WindowFrame& f = window_.newest();
    last_good_ = NavState{f.t, f.T_W_B(), f.v(), f.ba(), f.bg()};
    return finish(output(f));
  }

  // Tracking.
  WindowFrame& f = pushPredicted(obs.t);
  const NavState predicted{f.t, f.T_W_B(), f.v(), f.ba(), f.bg()};
  points_.observe(f.id, obs.points);
  observeLines(f.id, obs);
  const int tracked_points = points_.countTriangulatedFromElsewhere(f.id);
  // Lines already in the map count as tracked landmarks: in low texture they carry the frame.
  const int tracked = tracked_points + lines_.countTriangulatedIn(f.id);
  if (tracked < options_.failure.min_tracked) {
    resetAfterFailure(obs, predicted, &out);
    return finish(out);
  }
  decideKeyframe(f, tracked_points);
  f.at_rest = options_.zero_velocity.enabled && detectRest(window_[window_.size() - 2], f);
  points_.triangulate(window_);
  int reidentified = 0;
  {
    ScopedMs timer(&line_ms_);
    reidentified = lines_.reidentify(window_);
    lines_.gateNewest(window_);
    lines_.triangulate(window_);
  }
  solveWindow(options_.solver.max_num_iterations);
  if (failureAfterSolve(predicted)) {
    resetAfterFailure(obs, predicted, &out);
    return finish(out);
  }
  points_.rejectOutliers(window_);
  {
    ScopedMs timer(&line_ms_);
    lines_.rejectOutliers(window_);
  }
  const bool keyframe = window_.newest().keyframe;
  const int used = points_.countUsed();
  const int used_lines = lines_.countUsed();
  slideWindow();
  const WindowFrame& n = window_.newest();
  last_good_ = NavState{n.t, n.T_W_B(), n.v(), n.ba(), n.bg()};
  EstimatorOutput o = output(n);
  o.keyframe = keyframe;
  o.num_points = used;
  o.num_lines = used_lines;
  o.reidentified_lines = reidentified;
  return finish(o);
}

}  // namespace linnet
