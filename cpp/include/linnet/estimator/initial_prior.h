// The prior that starts a window: it fixes the gauge (position and yaw of the first frame, unobservable in VIO)
// and states what the initialiser knows about velocity and biases. Without it the accelerometer bias and the tilt
// trade off freely while the motion is poor (a static start), and the solver wanders along that valley.
// It is a MarginalizationPrior, so it is carried into the marginalisation prior like any other residual.
#pragma once

#include <memory>

#include <ceres/manifold.h>

#include "linnet/estimator/factors/prior_factor.h"
#include "linnet/estimator/window.h"

namespace linnet {

struct InitialPriorSigmas {
  double position_m = 1e-3;   // gauge: first position, m
  double yaw_rad = 1e-3;      // gauge: first yaw (rotation about z of W), rad
  double velocity = 0.0;      // m/s; <= 0: no velocity prior
  double acc_bias = 0.2;      // m/s^2
  double gyr_bias = 0.01;     // rad/s
};

/// Prior on frame f's pose (position + yaw) and speed-bias at their current values. `pose_manifold` must be the
/// PoseManifold used in the problem and outlive the prior.
std::shared_ptr<const MarginalizationPrior> makeInitialPrior(const WindowFrame& f, const InitialPriorSigmas& sigmas,
                                                             const ceres::Manifold* pose_manifold);

}  // namespace linnet
