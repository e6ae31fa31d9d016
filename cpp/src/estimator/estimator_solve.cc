// Problem building, solving and window sliding with marginalisation (DESIGN B1; thesis ch. 4).
#include <algorithm>

#include <ceres/problem.h>
#include <ceres/solver.h>

#include "estimator_core.h"
#include "linnet/estimator/factors/imu_factor.h"
#include "linnet/estimator/factors/zero_velocity_factor.h"
#include "linnet/estimator/marginaliser.h"
#include "linnet/estimator/schur_lm_solver.h"

namespace linnet {

void EstimatorCore::repropagateIfNeeded() {
  for (int k = 1; k < window_.size(); ++k) {
    Preintegration& pre = *window_[k].preint;
    const WindowFrame& i = window_[k - 1];
    if (pre.biasMovedFar(i.ba(), i.bg())) pre.repropagate(i.ba(), i.bg());
  }
}

std::vector<ResidualSpec> EstimatorCore::imuResiduals(int first, int last) {
  std::vector<ResidualSpec> out;
  for (int k = std::max(1, first); k <= last && k < window_.size(); ++k) {
    WindowFrame& i = window_[k - 1];
    WindowFrame& j = window_[k];
    if (!j.preint) continue;
    ResidualSpec r;
    r.cost = std::make_shared<ImuFactor>(*j.preint, g_W_);
    r.blocks = {i.pose.data(), i.speed_bias.data(), j.pose.data(), j.speed_bias.data()};
    r.keys = {frameBlockKey(i.id, BlockKind::kPose), frameBlockKey(i.id, BlockKind::kSpeedBias),
              frameBlockKey(j.id, BlockKind::kPose), frameBlockKey(j.id, BlockKind::kSpeedBias)};
    out.push_back(std::move(r));
  }
  return out;
}

std::vector<ResidualSpec> EstimatorCore::zeroVelocityResiduals(int first, int last) {
  std::vector<ResidualSpec> out;
  for (int k = std::max(0, first); k <= last && k < window_.size(); ++k) {
    WindowFrame& f = window_[k];
    if (!f.at_rest) continue;
    const ZeroVelocityOptions& o = options_.zero_velocity;
    ResidualSpec r;
    r.cost = std::make_shared<ZeroVelocityFactor>(o.velocity_sigma);
    r.blocks = {f.speed_bias.data()};
    r.keys = {frameBlockKey(f.id, BlockKind::kSpeedBias)};
    out.push_back(std::move(r));
    if (k == 0) continue;
    WindowFrame& i = window_[k - 1];
    ResidualSpec m;
    m.cost = std::make_shared<NoMotionFactor>(o.position_sigma_m, o.rotation_sigma_deg * M_PI / 180.0);
    m.blocks = {i.pose.data(), f.pose.data()};
    m.keys = {frameBlockKey(i.id, BlockKind::kPose), frameBlockKey(f.id, BlockKind::kPose)};
    out.push_back(std::move(m));
  }
  return out;
}

bool EstimatorCore::nonKeyframeSolve(bool all_right) const {
  // A per-frame solve of a frame that is not a keyframe: the frame leaves the window without entering the prior (the
  // first solve, which takes every cam1 residual, is never one).
  return !all_right && !window_.empty() && !window_.newest().keyframe;
}

void EstimatorCore::solveWindow(int max_iterations, bool all_right) {
  repropagateIfNeeded();
  updateCalibrationHolds();
  setCaptureShifts();
  if (options_.solver.engine == "schur_lm") {
    solveWindowSchurLm(max_iterations, all_right);
    return;
  }
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  // The residuals are built here from well-formed specs (no block appears twice in one residual); Ceres' per-call
  // checks of that cost a measurable share of a solve.
  po.disable_all_safety_checks = true;
  ceres::Problem problem(po);
  for (int k = 0; k < window_.size(); ++k) {
    problem.AddParameterBlock(window_[k].pose.data(), kPoseAmbientSize, &pose_manifold_);
    problem.AddParameterBlock(window_[k].speed_bias.data(), kSpeedBiasSize);
  }
  if (options_.extrinsics.estimate) problem.AddParameterBlock(rig_.data(), kPoseAmbientSize, &pose_manifold_);
  if (stereoEstimated()) problem.AddParameterBlock(stereo_.data(), kPoseAmbientSize, &pose_manifold_);
  if (options_.time_offset.estimate) problem.AddParameterBlock(time_offset_.data(), 1);
  if (options_.solver.calibration_on_keyframes && nonKeyframeSolve(all_right)) {
    if (options_.extrinsics.estimate) problem.SetParameterBlockConstant(rig_.data());
    if (stereoEstimated()) problem.SetParameterBlockConstant(stereo_.data());
    if (options_.time_offset.estimate) problem.SetParameterBlockConstant(time_offset_.data());
  }
  // Keep the cost functions alive for the solve (the problem does not own them).
  std::vector<std::shared_ptr<ceres::CostFunction>> keep;
  std::vector<std::shared_ptr<PriorFactor>> prior_factors;
  for (const auto& prior : priors_) {
    std::vector<double*> blocks;
    bool complete = true;
    for (BlockKey key : prior->keys) {
      double* b = blockOf(key);
      if (b == nullptr) complete = false;
      blocks.push_back(b);
    }
    if (!complete) continue;
    auto f = std::make_shared<PriorFactor>(prior);
    problem.AddResidualBlock(f.get(), nullptr, blocks);
    keep.push_back(f);
  }
  std::vector<ResidualSpec> residuals = imuResiduals(1, window_.size() - 1);
  for (ResidualSpec& r : zeroVelocityResiduals(0, window_.size() - 1)) residuals.push_back(std::move(r));
  std::vector<ResidualSpec> visual = points_.residuals(window_, -1, all_right, frameWeights(false));
  {
    ScopedMs timer(&line_ms_);
    std::vector<ResidualSpec> lines = lines_.residuals(window_, -1, frameWeights(true));
    for (ResidualSpec& r : lines) {
      problem.AddParameterBlock(r.blocks[1], kLineAmbientSize, &line_manifold_);
      visual.push_back(std::move(r));
    }
  }
  correctCalibration(&visual);
  for (ResidualSpec& r : visual) residuals.push_back(std::move(r));
  for (const ResidualSpec& r : residuals) {
    problem.AddResidualBlock(r.cost.get(), lossOf(r), r.blocks.data(), static_cast<int>(r.blocks.size()));
    keep.push_back(r.cost);
  }
  // The gauge (position and yaw) is held by the window's initial prior, carried on by marginalisation; no block is
  // held constant, so roll and pitch stay free for gravity to correct.
  const SolverOptions& so = options_.solver;
  ceres::Solver::Options opts;
  opts.max_num_iterations = max_iterations;
  opts.max_solver_time_in_seconds = so.max_solver_time_s;
  opts.num_threads = 1;
  opts.logging_type = ceres::SILENT;
  opts.trust_region_strategy_type =
      so.trust_region == "dogleg" ? ceres::DOGLEG : ceres::LEVENBERG_MARQUARDT;
  opts.linear_solver_type =
      so.linear_solver == "dense_schur" ? ceres::DENSE_SCHUR : ceres::SPARSE_NORMAL_CHOLESKY;
  ceres::Solver::Summary summary;
  {
    ScopedMs timer(&solver_ms_);
    ceres::Solve(opts, &problem, &summary);
  }
  applyRig();
}

void EstimatorCore::solveWindowSchurLm(int max_iterations, bool all_right) {
  SchurLmSolver solver;
  for (int k = 0; k < window_.size(); ++k) {
    solver.addParameterBlock(window_[k].pose.data(), kPoseAmbientSize, &pose_manifold_, false);
    solver.addParameterBlock(window_[k].speed_bias.data(), kSpeedBiasSize, nullptr, false);
  }
  const bool hold = options_.solver.calibration_on_keyframes && nonKeyframeSolve(all_right);
  const bool hold_lines = options_.solver.lines_on_keyframes && nonKeyframeSolve(all_right);
  const auto addCalibration = [&](double* data, int size, const ceres::Manifold* manifold) {
    if (hold)
      solver.addConstantBlock(data, size);
    else
      solver.addParameterBlock(data, size, manifold, false);
  };
  if (options_.extrinsics.estimate) addCalibration(rig_.data(), kPoseAmbientSize, &pose_manifold_);
  if (stereoEstimated()) addCalibration(stereo_.data(), kPoseAmbientSize, &pose_manifold_);
  if (options_.time_offset.estimate) addCalibration(time_offset_.data(), 1, nullptr);
  std::vector<std::shared_ptr<PriorFactor>> prior_factors;
  for (const auto& prior : priors_) {
    std::vector<double*> blocks;
    for (BlockKey key : prior->keys) blocks.push_back(blockOf(key));
    if (std::find(blocks.begin(), blocks.end(), nullptr) != blocks.end()) continue;
    prior_factors.push_back(std::make_shared<PriorFactor>(prior));
    solver.addResidual(prior_factors.back().get(), nullptr, blocks);
  }
  std::vector<ResidualSpec> imu = imuResiduals(1, window_.size() - 1);
  for (ResidualSpec& r : zeroVelocityResiduals(0, window_.size() - 1)) imu.push_back(std::move(r));
  for (const ResidualSpec& r : imu) solver.addResidual(r.cost.get(), nullptr, r.blocks);
  // Held, the calibration is already in the landmarks' extrinsics (applyRig after each solve) and, while the time
  // offset is estimated, goes into the frames' capture shifts for this solve: the residuals need no wrappers.
  const bool shift_for_solve = hold && options_.time_offset.estimate && !time_offset_held_;
  if (shift_for_solve) setCaptureShifts(time_offset_[0]);
  std::vector<ResidualSpec> visual = points_.residuals(window_, -1, all_right, frameWeights(false));
  {
    ScopedMs timer(&line_ms_);
    std::vector<ResidualSpec> lines = lines_.residuals(window_, -1, frameWeights(true));
    for (ResidualSpec& r : lines) visual.push_back(std::move(r));
  }
  if (!hold) correctCalibration(&visual);
  for (const ResidualSpec& r : visual) {
    for (std::size_t b = 0; b < r.keys.size(); ++b) {
      // A landmark's block (negative key) is registered with its first residual.
      if (r.keys[b] >= 0 || solver.hasBlock(r.blocks[b])) continue;
      if (r.line && hold_lines)
        solver.addConstantBlock(r.blocks[b], kLineAmbientSize);
      else if (r.line)
        solver.addParameterBlock(r.blocks[b], kLineAmbientSize, &line_manifold_, true);
      else
        solver.addParameterBlock(r.blocks[b], 1, nullptr, true);
    }
    solver.addResidual(r.cost.get(), lossOf(r), r.blocks);
  }
  SchurLmOptions so;
  so.max_iterations = max_iterations;
  so.max_time_s = options_.solver.max_solver_time_s;
  so.function_tolerance = options_.solver.function_tolerance;
  so.landmark_iterations = options_.solver.line_iterations;
  {
    ScopedMs timer(&solver_ms_);
    solver.solve(so);
  }
  if (shift_for_solve)
    for (int k = 0; k < window_.size(); ++k) window_[k].capture_shift = Pose::identity();
  applyRig();
}

ceres::LossFunction* EstimatorCore::lossOf(const ResidualSpec& r) {
  if (!r.robust) return nullptr;
  return r.line ? line_loss_.get() : &huber_;
}

std::map<FrameId, double> EstimatorCore::frameWeights(bool for_lines) const {
  // Patent: with more than N lines matched in a frame, points and lines get fixed weights (line-dominant);
  // otherwise the weights follow the counts. Costs are scaled by 2 w, so equal weights leave them unchanged.
  std::map<FrameId, double> w;
  const LineOptions& o = options_.lines;
  if (!o.weighting) return w;
  for (int k = 0; k < window_.size(); ++k) {
    const FrameId id = window_[k].id;
    const int n_l = lines_.countObservedIn(id);
    const int n_p = points_.countObservedIn(id);
    double wp = 0.5, wl = 0.5;
    if (n_l > o.weighting_min_lines) {
      wp = o.point_weight;
      wl = o.line_weight;
    } else if (n_p + n_l > 0) {
      wp = static_cast<double>(n_p) / (n_p + n_l);
      wl = static_cast<double>(n_l) / (n_p + n_l);
    }
    w[id] = 2.0 * (for_lines ? wl : wp);
  }
  return w;
}

void EstimatorCore::marginaliseOldest() {
  setCaptureShifts();
  const WindowFrame& old = window_[0];
  const FrameId old_id = old.id;
  Marginaliser m;
  auto reg = [&](BlockKey key, double* values, int size, const ceres::Manifold* manifold) {
    if (!m.hasParameterBlock(key)) m.addParameterBlock(key, values, size, manifold);
  };
  auto regFrameKey = [&](BlockKey key) { reg(key, blockOf(key), ambientSizeOf(key), manifoldOf(key)); };
  const std::vector<BlockKey> drop_frame = {frameBlockKey(old_id, BlockKind::kPose),
                                            frameBlockKey(old_id, BlockKind::kSpeedBias)};
  std::vector<std::shared_ptr<const MarginalizationPrior>> kept_priors;
  for (const auto& prior : priors_) {
    const bool touches = std::any_of(prior->keys.begin(), prior->keys.end(), [&](BlockKey k) {
      return k == drop_frame[0] || k == drop_frame[1];
    });
    if (!touches) {
      kept_priors.push_back(prior);
      continue;
    }
    for (BlockKey k : prior->keys) regFrameKey(k);
    m.addResidual(std::make_shared<PriorFactor>(prior), nullptr, prior->keys);
  }
  std::vector<ResidualSpec> inertial = imuResiduals(1, 1);
  for (ResidualSpec& r : zeroVelocityResiduals(0, 1)) {  // the rest priors that touch the oldest frame
    if (std::find_first_of(r.keys.begin(), r.keys.end(), drop_frame.begin(), drop_frame.end()) != r.keys.end())
      inertial.push_back(std::move(r));
  }
  for (const ResidualSpec& r : inertial) {
    for (BlockKey k : r.keys) regFrameKey(k);
    m.addResidual(r.cost, nullptr, std::span<const BlockKey>(r.keys.begin(), r.keys.size()));
  }
  std::vector<BlockKey> drop = drop_frame;
  // A visual residual: its frame (and calibration) blocks are kept, its landmark is dropped with the frame.
  auto addVisual = [&](const ResidualSpec& r) {
    for (std::size_t b = 0; b < r.keys.size(); ++b) {
      if (r.keys[b] >= 0) {
        regFrameKey(r.keys[b]);
      } else if (!m.hasParameterBlock(r.keys[b])) {
        if (r.line)
          m.addParameterBlock(r.keys[b], r.blocks[b], kLineAmbientSize, &line_manifold_);
        else
          m.addParameterBlock(r.keys[b], r.blocks[b], 1, nullptr);
        drop.push_back(r.keys[b]);
      }
    }
    m.addResidual(r.cost, lossOf(r), std::span<const BlockKey>(r.keys.begin(), r.keys.size()));
  };
  std::vector<ResidualSpec> visual = points_.residuals(window_, old_id, false, frameWeights(false));
  correctCalibration(&visual);
  for (const ResidualSpec& r : visual) addVisual(r);
  if (options_.lines.marginalise) {
    ScopedMs timer(&line_ms_);
    std::vector<ResidualSpec> lines = lines_.residuals(window_, old_id, frameWeights(true));
    correctCalibration(&lines);
    for (const ResidualSpec& r : lines) addVisual(r);
  }
  // Frame blocks must be registered even if nothing else touches them (a lone oldest frame).
  for (BlockKey k : drop_frame) regFrameKey(k);
  std::shared_ptr<const MarginalizationPrior> prior = m.marginalise(drop);
  priors_ = std::move(kept_priors);
  if (prior) priors_.push_back(prior);
  points_.removeFrame(window_, old_id);
  lines_.removeFrame(window_, old_id);
  window_.popOldest();
}

void EstimatorCore::dropFrame(int index) {
  // Drop the frame's visual measurements; its IMU information survives in the merged preintegration. Priors that
  // touch its blocks marginalise them (prior only), as the frame's pose leaves the window.
  const FrameId id = window_[index].id;
  const std::vector<BlockKey> drop = {frameBlockKey(id, BlockKind::kPose), frameBlockKey(id, BlockKind::kSpeedBias)};
  std::vector<std::shared_ptr<const MarginalizationPrior>> next;
  for (const auto& prior : priors_) {
    std::vector<BlockKey> d;
    for (BlockKey k : drop)
      if (prior->indexOf(k) >= 0) d.push_back(k);
    if (d.empty()) {
      next.push_back(prior);
      continue;
    }
    Marginaliser m;
    for (BlockKey k : prior->keys) m.addParameterBlock(k, blockOf(k), ambientSizeOf(k), manifoldOf(k));
    m.addResidual(std::make_shared<PriorFactor>(prior), nullptr, prior->keys);
    if (auto p = m.marginalise(d)) next.push_back(p);
  }
  priors_ = std::move(next);
  points_.removeFrame(window_, id);
  lines_.removeFrame(window_, id);
  window_.removeMerging(index);
}

void EstimatorCore::slideWindow() {
  const int n = window_.size();
  if (n >= 3 && !window_[n - 2].keyframe) dropFrame(n - 2);
  // Usually one frame; a moving (re-)initialisation starts from init.moving_frames frames, more than a small window
  // holds, and the surplus goes at once (one frame per slide would keep the window at that size for the whole run).
  while (window_.size() > options_.window_size + 1) marginaliseOldest();
}

}  // namespace linnet
