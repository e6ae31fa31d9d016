#include "linnet/estimator/factors/pose_wrappers.h"

#include <algorithm>
#include <array>

#include "linnet/core/error.h"
#include "linnet/estimator/manifolds.h"

namespace linnet {

namespace {
// Visual residuals have at most 2 pose blocks, 4 rows and (nested wrappers included) a handful of blocks: fixed
// capacities keep Evaluate free of heap allocation.
constexpr std::size_t kMaxPoses = PoseWrappedFactor::kMaxPoses;
constexpr int kMaxRows = 4;
constexpr int kMaxBlocks = 8;
using TangentJ = Eigen::Matrix<double, Eigen::Dynamic, kPoseTangentSize, Eigen::RowMajor, kMaxRows, kPoseTangentSize>;
using TangentMap = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;
}  // namespace

const PoseTransformMemo::Entry* PoseTransformMemo::find(std::int64_t tag, const double* body, const double* extra,
                                                       int extra_size, bool derivatives) const {
  for (const Entry& e : entries_) {
    if (e.tag != tag || (derivatives && !e.derivatives)) continue;
    if (std::equal(body, body + kPoseAmbientSize, e.body.begin()) &&
        std::equal(extra, extra + extra_size, e.extra.begin()))
      return &e;
  }
  return nullptr;
}

void PoseTransformMemo::store(const Entry& entry) {
  if (entries_.size() < kCapacity) {
    entries_.push_back(entry);
    return;
  }
  entries_[next_] = entry;
  next_ = (next_ + 1) % kCapacity;
}

PoseWrappedFactor::PoseWrappedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks,
                                     int extra_size, bool extra_is_pose)
    : inner_(std::move(inner)),
      inner_tangent_(dynamic_cast<const TangentJacobians*>(inner_.get())),
      n_poses_(pose_blocks.size()),
      extra_tangent_(extra_is_pose ? kPoseTangentSize : extra_size),
      extra_is_pose_(extra_is_pose) {
  if (extra_is_pose && extra_size != kPoseAmbientSize) throw UsageError("PoseWrappedFactor: a pose block has 7 values");
  if (inner_tangent_ == nullptr)
    throw UsageError("PoseWrappedFactor: the inner factor gives no tangent-space Jacobians (TangentJacobians)");
  if (pose_blocks.size() > kMaxPoses || inner_->num_residuals() > kMaxRows ||
      static_cast<int>(inner_->parameter_block_sizes().size()) >= kMaxBlocks || extra_tangent_ > kPoseTangentSize)
    throw UsageError("PoseWrappedFactor: a visual residual has at most 2 poses, 4 rows and 7 blocks");
  std::copy(pose_blocks.begin(), pose_blocks.end(), pose_blocks_.begin());
  set_num_residuals(inner_->num_residuals());
  const std::vector<int32_t>& inner_sizes = inner_->parameter_block_sizes();
  std::vector<int32_t>* sizes = mutable_parameter_block_sizes();
  sizes->reserve(inner_sizes.size() + 1);
  sizes->assign(inner_sizes.begin(), inner_sizes.end());
  sizes->push_back(extra_size);
}

void PoseWrappedFactor::useMemo(std::shared_ptr<PoseTransformMemo> memo, std::span<const std::int64_t> tags) {
  if (tags.size() != n_poses_) throw UsageError("PoseWrappedFactor::useMemo: one tag per pose block");
  memo_ = std::move(memo);
  std::copy(tags.begin(), tags.end(), memo_tags_.begin());
}

bool PoseWrappedFactor::evaluateTangentSpace(double const* const* parameters, double* residuals,
                                             double** jacobians) const {
  const int n_inner = static_cast<int>(inner_->parameter_block_sizes().size());
  const int rows = num_residuals();
  const double* extra = parameters[n_inner];
  const std::size_t n_poses = n_poses_;

  // Inner parameters with the body poses replaced by the transformed poses (and their derivatives when wanted).
  std::array<std::array<double, kPoseAmbientSize>, kMaxPoses> moved;
  std::array<Mat6, kMaxPoses> d_body;
  std::array<ExtraMap, kMaxPoses> d_extra;
  std::array<const double*, kMaxBlocks> inner_params{};
  std::copy(parameters, parameters + n_inner, inner_params.begin());
  // The transform's derivatives only when a pose's or the extra block's Jacobian is wanted (not for a landmark's
  // alone, as in the solver's landmark iterations).
  bool derivatives = jacobians != nullptr && jacobians[n_inner] != nullptr;
  for (std::size_t k = 0; k < n_poses && jacobians != nullptr; ++k)
    derivatives = derivatives || jacobians[pose_blocks_[k]] != nullptr;
  const int extra_size = parameter_block_sizes()[static_cast<std::size_t>(n_inner)];
  for (std::size_t k = 0; k < n_poses; ++k) {
    const double* body = parameters[pose_blocks_[k]];
    const PoseTransformMemo::Entry* memo =
        memo_ != nullptr ? memo_->find(memo_tags_[k], body, extra, extra_size, derivatives) : nullptr;
    Pose T;
    if (memo != nullptr) {
      T = memo->T;
      if (derivatives) {
        d_body[k] = memo->d_body;
        d_extra[k] = memo->d_extra;
      }
    } else {
      if (derivatives) d_extra[k].resize(6, extra_tangent_);
      T = transform(k, poseFromBlock(body), extra, derivatives ? &d_body[k] : nullptr,
                    derivatives ? &d_extra[k] : nullptr);
      if (memo_ != nullptr) {
        PoseTransformMemo::Entry e;
        e.tag = memo_tags_[k];
        std::copy(body, body + kPoseAmbientSize, e.body.begin());
        std::copy(extra, extra + extra_size, e.extra.begin());
        e.derivatives = derivatives;
        e.T = T;
        if (derivatives) {
          e.d_body = d_body[k];
          e.d_extra = d_extra[k];
        }
        memo_->store(e);
      }
    }
    setPose(T, moved[k].data());
    inner_params[static_cast<std::size_t>(pose_blocks_[k])] = moved[k].data();
  }
  // Without the transform's derivatives the other blocks' Jacobians (if any) come straight from the inner factor.
  if (!derivatives) return inner_tangent_->evaluateTangentSpace(inner_params.data(), residuals, jacobians);

  // Inner Jacobians: straight into the output for the other blocks, into J_t for the transformed poses.
  const bool want_extra = jacobians[n_inner] != nullptr;
  std::array<TangentJ, kMaxPoses> J_t;
  std::array<double*, kMaxBlocks> inner_jac{};
  std::copy(jacobians, jacobians + n_inner, inner_jac.begin());
  for (std::size_t k = 0; k < n_poses; ++k) {
    const auto b = static_cast<std::size_t>(pose_blocks_[k]);
    J_t[k].resize(rows, kPoseTangentSize);
    inner_jac[b] = jacobians[b] != nullptr || want_extra ? J_t[k].data() : nullptr;
  }
  if (!inner_tangent_->evaluateTangentSpace(inner_params.data(), residuals, inner_jac.data())) return false;

  // Chain rule through the transform: body tangent -> transformed tangent <- extra tangent.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor, kMaxRows, 6> J_extra =
      Eigen::MatrixXd::Zero(rows, extra_tangent_);
  for (std::size_t k = 0; k < n_poses; ++k) {
    const int b = pose_blocks_[k];
    if (jacobians[b] != nullptr) TangentMap(jacobians[b], rows, kPoseTangentSize).noalias() = J_t[k] * d_body[k];
    if (want_extra) J_extra.noalias() += J_t[k] * d_extra[k];
  }
  if (want_extra) TangentMap(jacobians[n_inner], rows, extra_tangent_) = J_extra;
  return true;
}

bool PoseWrappedFactor::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  return evaluateThroughTangent(*this, parameter_block_sizes(), num_residuals(), parameters, residuals, jacobians);
}

RigCorrectedFactor::RigCorrectedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks,
                                       const Pose& T_B_R0)
    : RigCorrectedFactor(std::move(inner), pose_blocks, Pose::identity(), T_B_R0.inverse()) {}

RigCorrectedFactor::RigCorrectedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks,
                                       const Pose& left, const Pose& right)
    : PoseWrappedFactor(std::move(inner), pose_blocks, kPoseAmbientSize, true),
      L_(left),
      Rr_(right),
      R_L_(left.R()),
      R_Rr_t_(right.R().transpose()),
      skew_t_Rr_(skew(right.p)) {}

std::shared_ptr<RigCorrectedFactor> RigCorrectedFactor::stereoCorrected(std::shared_ptr<ceres::CostFunction> inner,
                                                                        int pose_block, const Pose& T_B_Ct,
                                                                        const Pose& S0) {
  // T'_Bj * T_B_Ct = T_W_Bj * T_B_Ct * S0^-1 * S: the camera at its uncorrected pose, then S.
  const std::array<int, 1> blocks{pose_block};
  return std::make_shared<RigCorrectedFactor>(std::move(inner), std::span<const int>(blocks), T_B_Ct * S0.inverse(),
                                              T_B_Ct.inverse());
}

Pose RigCorrectedFactor::transform(std::size_t /*k*/, const Pose& body, const double* extra, Mat6* d_body,
                                   ExtraMap* d_extra) const {
  const Pose X = poseFromBlock(extra);
  const Pose N = L_ * X * Rr_;
  if (d_body != nullptr) {
    const Mat3 R_B = body.R();
    const Mat3 R_BL = R_B * R_L_;
    d_body->setIdentity();
    d_body->topRightCorner<3, 3>() = -R_B * skew(N.p);
    d_body->bottomRightCorner<3, 3>() = N.R().transpose();
    d_extra->setZero(6, 6);
    d_extra->topLeftCorner(3, 3) = R_BL;
    d_extra->topRightCorner(3, 3) = -(R_BL * X.R()) * skew_t_Rr_;
    d_extra->bottomRightCorner(3, 3) = R_Rr_t_;
  }
  return body * N;
}

TimeShiftedFactor::TimeShiftedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks,
                                     std::span<const Vec3> v_W, std::span<const Vec3> w_B)
    : PoseWrappedFactor(std::move(inner), pose_blocks, 1, false) {
  if (v_W.size() != pose_blocks.size() || w_B.size() != pose_blocks.size())
    throw UsageError("TimeShiftedFactor: one velocity and one angular rate per pose block");
  std::copy(v_W.begin(), v_W.end(), v_W_.begin());
  std::copy(w_B.begin(), w_B.end(), w_B_.begin());
}

Pose TimeShiftedFactor::transform(std::size_t k, const Pose& body, const double* extra, Mat6* d_body,
                                  ExtraMap* d_extra) const {
  const double td = extra[0];
  const Quat E = expSO3(-td * w_B_[k]);
  if (d_body != nullptr) {
    d_body->setIdentity();
    d_body->bottomRightCorner<3, 3>() = E.toRotationMatrix().transpose();
    d_extra->resize(6, 1);
    d_extra->topRows(3) = -v_W_[k];
    d_extra->bottomRows(3) = -w_B_[k];
  }
  return Pose(body.q * E, body.p - td * v_W_[k]);
}

}  // namespace linnet
