// Visual residuals seen through a change of their body poses: the online camera-IMU extrinsics and time offset.
//
// PoseWrappedFactor takes a residual (the "inner" factor) whose blocks `pose_blocks` are body poses T_W_Bk (7,
// PoseManifold), replaces each by a transformed pose T'_k = f(T_W_Bk, x) of it and one extra block x, and chains
// the inner factor's tangent Jacobians through f. With PoseManifold's tangent convention (p <- p + dp,
// R <- R Exp(dth)) a subclass gives, per pose, T'_k and the 6 x 6 / 6 x n maps from the body's and x's tangents to
// T'_k's tangent. Residuals without a pose block (the same-frame stereo point residual) are never wrapped.
//
// RigCorrectedFactor: the stereo pair is calibrated well relative to itself (the target is seen by both cameras at
// once) and less well relative to the IMU (that part is observed only through the motion). The estimator refines one
// rigid correction T_B_R of the whole rig on the body side, common to both cameras (as OKVIS and VINS-Mono refine
// T_B_C, with the stereo baseline kept): the cameras' extrinsics are T_B_R * T_B_Ci. An inner factor built with the
// extrinsics of an earlier correction T_B_R0 sees T'_k = T_W_Bk * T_B_R * T_B_R0^-1.
// The same form, T'_k = T_W_Bk * L * X * Rr with constants L and Rr and the correction X (a pose block), also refines
// cam1 relative to cam0 (the stereo correction S, cam1 at T_B_C1 * S; see stereoCorrected()): a hundredth of a degree
// of relative yaw biases every disparity by about 0.08 px, which is a 0.6 % depth error at 4 m. With N = L X Rr:
//     body:       dp' = dp - R_Bk [t_N]x dth,                dth' = R_N^T dth
//     correction: dp' = R_Bk R_L dt - R_Bk R_L R_X [t_Rr]x dth,  dth' = R_Rr^T dth
// (for the rig, L = I and Rr = T_B_R0^-1).
//
// TimeShiftedFactor: a camera stamp t is the capture time on the IMU clock plus an offset t_d (Kalibr's
// timeshift_cam_imu is -t_d). The image was taken at t - t_d, when the body was at
//     T'_k = (p_k - t_d v_k, R_k Exp(-t_d w_k))
// to first order, with v_k (velocity in W) and w_k (bias-corrected angular rate in B) taken at frame k when the
// residual is built (as constants: the residuals are rebuilt at every solve). This is the pose-side form of the
// feature-velocity correction of Qin and Shen, "Online temporal calibration for monocular visual-inertial
// systems", IROS 2018. With E = Exp(-t_d w_k):
//     body:   dp' = dp,  dth' = E^T dth;      offset: dp' = -v_k dt_d,  dth' = -w_k dt_d
#pragma once

#include <array>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <span>
#include <vector>

#include <ceres/cost_function.h>

#include "linnet/core/pose.h"
#include "linnet/estimator/factors/tangent_jacobians.h"
#include "linnet/estimator/manifolds.h"

namespace linnet {

using Mat6 = Eigen::Matrix<double, 6, 6>;
/// Tangent size of a wrapper's extra blocks together: a pose correction (6) and the time offset (1).
inline constexpr int kMaxExtraTangent = 7;
inline constexpr int kMaxExtraAmbient = 8;
using ExtraMap = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxExtraTangent>;  // extra tangent -> transformed pose
                                                                                   // tangent

/// Transformed poses shared by the wrappers of one solve. A frame's residuals all see the same body pose and
/// calibration blocks, so with a memo each transform (and its derivatives) is computed once per frame and evaluation
/// point instead of once per residual. An entry is found by a tag naming the wrapper's constants (the same tag must
/// mean the same constants: one memo per kind of wrapper, tagged by frame where the constants are the frame's) and by
/// the exact values of the body pose and the extra block, so it never goes stale. Not thread-safe: the window's
/// solvers and marginaliser evaluate on one thread.
class PoseTransformMemo {
 public:
  struct Entry {
    std::int64_t tag = 0;
    std::array<double, kPoseAmbientSize> body{};
    std::array<double, kMaxExtraAmbient> extra{};
    bool derivatives = false;
    Pose T;
    Mat6 d_body;
    ExtraMap d_extra;
  };
  /// The entry for these inputs (`extra_size` values at `extra`), or nullptr; one without derivatives does not answer
  /// a call that wants them.
  const Entry* find(std::int64_t tag, const double* body, const double* extra, int extra_size,
                    bool derivatives) const;
  /// Stores an entry; beyond kCapacity entries the oldest one is replaced.
  void store(const Entry& entry);

  static constexpr std::size_t kCapacity = 64;

 private:
  bool matches(std::size_t i, std::int64_t tag, const double* body, const double* extra, int extra_size,
               bool derivatives) const;

  std::vector<Entry> entries_;
  std::vector<std::int64_t> tags_;  // entries_[i].tag, contiguous: a lookup scans these, not the large entries
  std::size_t next_ = 0;
  // The entry stored last for a tag (by the tag's low bits; -1: none), tried before the scan: the residuals of one
  // evaluation pass ask for the same few transforms in turn. Any matching entry holds the same transform, so which
  // one answers does not change a result.
  static constexpr std::size_t kHints = 16;
  std::array<int, kHints> last_of_tag_ = [] {
    std::array<int, kHints> a{};
    a.fill(-1);
    return a;
  }();
};

class PoseWrappedFactor : public ceres::CostFunction, public TangentJacobians {
 public:
  /// The wrapped factor takes inner's blocks followed by the extra block (`extra_size` doubles; a pose block on
  /// PoseManifold when `extra_is_pose`, else Euclidean). `inner` must implement TangentJacobians (the visual factors
  /// and the wrappers do), and every 7-double block of it is a pose block.
  /// At most kMaxPoses pose blocks (a visual residual has one or two).
  PoseWrappedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks, int extra_size,
                    bool extra_is_pose);
  /// Two extra blocks: a pose (7, PoseManifold), then `second_size` Euclidean values. transform() then gets both
  /// blocks' values one after the other, and its extra map has the pose's 6 tangent columns, then the second's.
  PoseWrappedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks, int second_size);

  static constexpr std::size_t kMaxPoses = 2;

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const final;
  bool evaluateTangentSpace(double const* const* parameters, double* residuals, double** jacobians) const final;

  const ceres::CostFunction& inner() const { return *inner_; }

  /// Shares transforms through `memo`; tags[k] names the constants of the k-th pose block's transform (see
  /// PoseTransformMemo).
  void useMemo(std::shared_ptr<PoseTransformMemo> memo, std::span<const std::int64_t> tags);
  void useMemo(std::shared_ptr<PoseTransformMemo> memo, std::initializer_list<std::int64_t> tags) {
    useMemo(std::move(memo), std::span<const std::int64_t>(tags.begin(), tags.size()));
  }

 protected:
  /// The pose handed to the inner factor for the k-th pose block, and the maps from the body's tangent (6 x 6) and
  /// the extra block's tangent (6 x tangent size, already sized) to its tangent; the maps are nullptr when only the
  /// residual is wanted.
  virtual Pose transform(std::size_t k, const Pose& body, const double* extra, Mat6* d_body,
                         ExtraMap* d_extra) const = 0;

 private:
  void init(std::span<const int> pose_blocks);

  std::shared_ptr<ceres::CostFunction> inner_;
  const TangentJacobians* inner_tangent_;  // inner_, seen through its tangent-space interface
  // Fixed capacity, not vectors: the window builds a wrapper per visual residual and solve.
  std::array<int, kMaxPoses> pose_blocks_{};
  std::size_t n_poses_ = 0;
  int n_extra_ = 1;                    // extra blocks (1 or 2)
  std::array<int, 2> extra_ambient_{};  // per extra block
  std::array<int, 2> extra_tangents_{};
  int extra_tangent_ = 0;               // all extra blocks together
  int extra_ambient_total_ = 0;
  std::shared_ptr<PoseTransformMemo> memo_;
  std::array<std::int64_t, kMaxPoses> memo_tags_{};
};

class RigCorrectedFactor final : public PoseWrappedFactor {
 public:
  /// T_B_R0: the correction that inner's extrinsics already contain. Extra block: T_B_R (7, PoseManifold).
  RigCorrectedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks, const Pose& T_B_R0);
  /// The general form: each pose block k becomes T_W_Bk * left * X * right, X the extra block (7, PoseManifold).
  RigCorrectedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks, const Pose& left,
                     const Pose& right);

  /// cam1 seen through the stereo correction S (cam1 at T_B_C1 * S): `pose_block` is the pose of the frame whose
  /// cam1 observation inner describes, T_B_Ct the extrinsics inner uses for it (T_B_C1 * S0 with the correction S0 it
  /// was built with, and whatever else is already in it: the rig correction, a held time shift), S0 that correction.
  static std::shared_ptr<RigCorrectedFactor> stereoCorrected(std::shared_ptr<ceres::CostFunction> inner,
                                                             int pose_block, const Pose& T_B_Ct, const Pose& S0);

 protected:
  Pose transform(std::size_t k, const Pose& body, const double* extra, Mat6* d_body,
                 ExtraMap* d_extra) const override;

 private:
  Pose L_, Rr_;
  Mat3 R_L_;           // R_L
  Mat3 R_Rr_t_;        // R_Rr^T
  Mat3 skew_t_Rr_;     // [t_Rr]x
};

class TimeShiftedFactor final : public PoseWrappedFactor {
 public:
  /// v_W[k], w_B[k]: velocity (W, m/s) and angular rate (B, rad/s) at the k-th pose block's frame. Extra block: t_d
  /// (1, seconds).
  TimeShiftedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks,
                    std::span<const Vec3> v_W, std::span<const Vec3> w_B);

 protected:
  Pose transform(std::size_t k, const Pose& body, const double* extra, Mat6* d_body,
                 ExtraMap* d_extra) const override;

 private:
  std::array<Vec3, kMaxPoses> v_W_, w_B_;
};

/// The rig correction inside the time shift, as the estimator nests RigCorrectedFactor in TimeShiftedFactor while
/// both are estimated, in one wrapper: each pose block k becomes T'_k = shift(T_W_Bk, t_d) * T_B_R * T_B_R0^-1, and
/// the two transforms' maps are composed once per pose (and shared through the memo, tagged by frame: v and w are the
/// frame's) instead of being chained residual by residual, level by level. Extra blocks: T_B_R (7, PoseManifold),
/// then t_d (1, seconds).
class RigTimeShiftedFactor final : public PoseWrappedFactor {
 public:
  RigTimeShiftedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks, const Pose& T_B_R0,
                       std::span<const Vec3> v_W, std::span<const Vec3> w_B);

 protected:
  Pose transform(std::size_t k, const Pose& body, const double* extra, Mat6* d_body,
                 ExtraMap* d_extra) const override;

 private:
  Pose Rr_;          // T_B_R0^-1
  Mat3 R_Rr_t_;      // R_Rr^T
  Mat3 skew_t_Rr_;   // [t_Rr]x
  std::array<Vec3, kMaxPoses> v_W_, w_B_;
};

}  // namespace linnet
