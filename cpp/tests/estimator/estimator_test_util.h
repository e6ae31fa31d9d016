// Runs an Estimator over a SyntheticVio sequence and scores it against the analytic ground truth.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Geometry>

#include "estimator/synthetic_vio.h"
#include "linnet/estimator/estimator.h"

namespace linnet::testing {

struct RunResult {
  std::vector<EstimatorOutput> outputs;
  int first_pose = -1;          // index of the first output with a pose
  double ape_rmse = 0.0;        // m, after SE3 alignment of the positions with a pose
  double max_step_m = 0.0;      // largest position change between consecutive outputs with a pose
  std::vector<double> errors;   // aligned position error of each output with a pose, m
  double median_ms = 0.0, p95_ms = 0.0, max_ms = 0.0;
};

inline ImuNoise syntheticNoise() { return ImuNoise(); }

/// Feeds the IMU up to (and including) the first sample at or after each frame, then the frame.
/// `edit` may change a frame before it is given to the estimator (failure injection); `after` sees the estimator and
/// its output after each frame.
template <class Edit, class After>
RunResult runEstimator(const SyntheticVio& sim, const EstimatorOptions& options, bool stereo, Edit edit,
                       After after) {
  const Pose& E = sim.options().calibration_error;
  Estimator est(options, syntheticNoise(), E * eurocTBC0(),
                stereo ? std::optional<Pose>(E * eurocTBC1() * sim.options().stereo_error) : std::nullopt);
  RunResult r;
  std::size_t next_imu = 0;
  const auto& imu = sim.imu();
  for (std::size_t k = 0; k < sim.frames().size(); ++k) {
    FrameObservations obs = sim.frames()[k];
    edit(static_cast<int>(k), &obs);
    while (next_imu < imu.size()) {
      est.addImu(imu[next_imu]);
      ++next_imu;
      if (imu[next_imu - 1].t >= obs.t) break;
    }
    r.outputs.push_back(est.addFrame(obs));
    after(static_cast<const Estimator&>(est), r.outputs.back());
  }
  // Scores.
  std::vector<Vec3> est_p, gt_p;
  std::vector<double> ms;
  const Vec3* prev = nullptr;
  for (std::size_t k = 0; k < r.outputs.size(); ++k) {
    const EstimatorOutput& o = r.outputs[k];
    ms.push_back(o.solve_ms);
    if (!o.has_pose) continue;
    if (r.first_pose < 0) r.first_pose = static_cast<int>(k);
    est_p.push_back(o.T_W_B.p);
    gt_p.push_back(sim.truth(o.t).T_W_B.p);
    if (prev != nullptr) r.max_step_m = std::max(r.max_step_m, (o.T_W_B.p - *prev).norm());
    prev = &r.outputs[k].T_W_B.p;
  }
  if (est_p.size() >= 3) {
    Eigen::Matrix3Xd A(3, static_cast<Eigen::Index>(est_p.size())), B(3, static_cast<Eigen::Index>(est_p.size()));
    for (std::size_t i = 0; i < est_p.size(); ++i) {
      A.col(static_cast<Eigen::Index>(i)) = est_p[i];
      B.col(static_cast<Eigen::Index>(i)) = gt_p[i];
    }
    const Eigen::Matrix4d T = Eigen::umeyama(A, B, false);
    double sq = 0.0;
    for (std::size_t i = 0; i < est_p.size(); ++i) {
      const Vec3 a = T.block<3, 3>(0, 0) * est_p[i] + T.block<3, 1>(0, 3);
      sq += (a - gt_p[i]).squaredNorm();
      r.errors.push_back((a - gt_p[i]).norm());
    }
    r.ape_rmse = std::sqrt(sq / static_cast<double>(est_p.size()));
  }
  std::sort(ms.begin(), ms.end());
  if (!ms.empty()) {
    r.median_ms = ms[ms.size() / 2];
    r.p95_ms = ms[std::min(ms.size() - 1, ms.size() * 95 / 100)];
    r.max_ms = ms.back();
  }
  return r;
}

template <class Edit>
RunResult runEstimator(const SyntheticVio& sim, const EstimatorOptions& options, bool stereo, Edit edit) {
  return runEstimator(sim, options, stereo, edit, [](const Estimator&, const EstimatorOutput&) {});
}

inline RunResult runEstimator(const SyntheticVio& sim, const EstimatorOptions& options, bool stereo = true) {
  return runEstimator(sim, options, stereo, [](int, FrameObservations*) {});
}

}  // namespace linnet::testing
