// Static gravity alignment and stillness detection.
#include "linnet/imu/gravity_alignment.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "linnet/core/error.h"

namespace linnet {

ImuStatistics imuStatistics(const std::vector<ImuSample>& samples, int averaging_samples) {
  ImuStatistics st;
  st.count = static_cast<int>(samples.size());
  if (samples.empty()) return st;
  for (const ImuSample& s : samples) {
    st.acc_mean += s.acc;
    st.gyr_mean += s.gyr;
  }
  st.acc_mean /= static_cast<double>(samples.size());
  st.gyr_mean /= static_cast<double>(samples.size());

  // Block means (the raw samples when averaging_samples == 1).
  const size_t block = static_cast<size_t>(std::max(1, averaging_samples));
  const size_t blocks = samples.size() / block;
  if (blocks < 2) return st;
  std::vector<Vec3> acc(blocks, Vec3::Zero()), gyr(blocks, Vec3::Zero());
  Vec3 acc_mean = Vec3::Zero(), gyr_mean = Vec3::Zero();
  for (size_t b = 0; b < blocks; ++b) {
    for (size_t k = b * block; k < (b + 1) * block; ++k) {
      acc[b] += samples[k].acc;
      gyr[b] += samples[k].gyr;
    }
    acc[b] /= static_cast<double>(block);
    gyr[b] /= static_cast<double>(block);
    acc_mean += acc[b];
    gyr_mean += gyr[b];
  }
  const double n = static_cast<double>(blocks);
  acc_mean /= n;
  gyr_mean /= n;
  Vec3 acc_var = Vec3::Zero(), gyr_var = Vec3::Zero();
  for (size_t b = 0; b < blocks; ++b) {
    acc_var += (acc[b] - acc_mean).cwiseAbs2();
    gyr_var += (gyr[b] - gyr_mean).cwiseAbs2();
  }
  st.acc_std = (acc_var / (n - 1.0)).cwiseSqrt();
  st.gyr_std = (gyr_var / (n - 1.0)).cwiseSqrt();
  return st;
}

bool isStatic(const std::vector<ImuSample>& samples, const StaticDetectionOptions& options, double gravity) {
  if (static_cast<int>(samples.size()) < std::max(options.min_samples, 2 * options.averaging_samples))
    return false;
  const ImuStatistics st = imuStatistics(samples, options.averaging_samples);
  return st.acc_std.maxCoeff() <= options.max_acc_std && st.gyr_std.maxCoeff() <= options.max_gyr_std &&
         st.gyr_mean.norm() <= options.max_gyr_mean &&
         std::abs(st.acc_mean.norm() - gravity) <= options.max_gravity_error;
}

double yawOf(const Quat& q_W_B) {
  const Mat3 R = q_W_B.toRotationMatrix();
  return std::atan2(R(1, 0), R(0, 0));
}

Quat gravityAlignedRotation(const Vec3& mean_specific_force_B) {
  const double norm = mean_specific_force_B.norm();
  if (!(norm > 1e-6)) {
    std::ostringstream os;
    os << "gravity alignment: mean specific force (" << mean_specific_force_B.transpose()
       << ") m/s^2 is too small to define the vertical";
    throw InputError(os.str());
  }
  // At rest the accelerometer measures -g in B, i.e. "up": rotate it onto +z, then remove the yaw.
  const Quat q0 = Quat::FromTwoVectors(mean_specific_force_B / norm, Vec3::UnitZ());
  const double yaw = yawOf(q0);
  return (Quat(Eigen::AngleAxisd(-yaw, Vec3::UnitZ())) * q0).normalized();
}

Quat gravityAlignedRotation(const std::vector<ImuSample>& samples) {
  if (samples.empty()) throw InputError("gravity alignment: no IMU samples");
  return gravityAlignedRotation(imuStatistics(samples).acc_mean);
}

}  // namespace linnet
