// Static gravity alignment and stillness detection.
#include "linnet/imu/gravity_alignment.h"

#include <cmath>
#include <sstream>

#include "linnet/core/error.h"

namespace linnet {

ImuStatistics imuStatistics(const std::vector<ImuSample>& samples) {
  ImuStatistics st;
  st.count = static_cast<int>(samples.size());
  if (samples.empty()) return st;
  for (const ImuSample& s : samples) {
    st.acc_mean += s.acc;
    st.gyr_mean += s.gyr;
  }
  const double n = static_cast<double>(samples.size());
  st.acc_mean /= n;
  st.gyr_mean /= n;
  if (samples.size() < 2) return st;
  Vec3 acc_var = Vec3::Zero(), gyr_var = Vec3::Zero();
  for (const ImuSample& s : samples) {
    acc_var += (s.acc - st.acc_mean).cwiseAbs2();
    gyr_var += (s.gyr - st.gyr_mean).cwiseAbs2();
  }
  st.acc_std = (acc_var / (n - 1.0)).cwiseSqrt();
  st.gyr_std = (gyr_var / (n - 1.0)).cwiseSqrt();
  return st;
}

bool isStatic(const std::vector<ImuSample>& samples, const StaticDetectionOptions& options, double gravity) {
  if (static_cast<int>(samples.size()) < options.min_samples) return false;
  const ImuStatistics st = imuStatistics(samples);
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
