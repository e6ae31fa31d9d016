#include "linnet/estimator/factors/pose_wrappers.h"

#include <algorithm>
#include <array>
#include <span>
#include <string>

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

// T'_k = T_W_Bk * L * X * Rr (RigCorrectedFactor) and its maps from the body's and X's tangents.
Pose rigTransform(const Pose& body, const Pose& L, const Mat3& R_L, const Pose& Rr, const Mat3& R_Rr_t,
                  const Mat3& skew_t_Rr, const double* extra, Mat6* d_body, ExtraMap* d_extra) {
  const Pose X = poseFromBlock(extra);
  const Pose N = L * X * Rr;
  if (d_body != nullptr) {
    const Mat3 R_B = body.R();
    const Mat3 R_BL = R_B * R_L;
    d_body->setIdentity();
    d_body->topRightCorner<3, 3>() = -R_B * skew(N.p);
    d_body->bottomRightCorner<3, 3>() = N.R().transpose();
    d_extra->setZero(6, 6);
    d_extra->topLeftCorner(3, 3) = R_BL;
    d_extra->topRightCorner(3, 3) = -(R_BL * X.R()) * skew_t_Rr;
    d_extra->bottomRightCorner(3, 3) = R_Rr_t;
  }
  return body * N;
}

// The body at t - t_d to first order (TimeShiftedFactor) and its maps from the body's tangent and from t_d.
Pose timeShift(const Pose& body, double td, const Vec3& v_W, const Vec3& w_B, Mat6* d_body, ExtraMap* d_extra) {
  const Quat E = expSO3(-td * w_B);
  if (d_body != nullptr) {
    d_body->setIdentity();
    d_body->bottomRightCorner<3, 3>() = E.toRotationMatrix().transpose();
    d_extra->resize(6, 1);
    d_extra->topRows(3) = -v_W;
    d_extra->bottomRows(3) = -w_B;
  }
  return Pose(body.q * E, body.p - td * v_W);
}

// A time-shifting wrapper's rates: one velocity and one angular rate per pose block.
void copyRates(std::size_t n_poses, std::span<const Vec3> v_W, std::span<const Vec3> w_B, const char* who,
               std::array<Vec3, kMaxPoses>* v_out, std::array<Vec3, kMaxPoses>* w_out) {
  if (v_W.size() != n_poses || w_B.size() != n_poses)
    throw UsageError(std::string(who) + ": one velocity and one angular rate per pose block");
  std::copy(v_W.begin(), v_W.end(), v_out->begin());
  std::copy(w_B.begin(), w_B.end(), w_out->begin());
}
}  // namespace

bool PoseTransformMemo::matches(std::size_t i, std::int64_t tag, const double* body, const double* extra,
                                int extra_size, bool derivatives) const {
  if (tags_[i] != tag) return false;
  const Entry& e = entries_[i];
  if (derivatives && !e.derivatives) return false;
  return std::equal(body, body + kPoseAmbientSize, e.body.begin()) &&
         std::equal(extra, extra + extra_size, e.extra.begin());
}

const PoseTransformMemo::Entry* PoseTransformMemo::find(std::int64_t tag, const double* body, const double* extra,
                                                       int extra_size, bool derivatives) const {
  const int hint = last_of_tag_[static_cast<std::size_t>(tag) % kHints];
  if (hint >= 0 && matches(static_cast<std::size_t>(hint), tag, body, extra, extra_size, derivatives))
    return &entries_[static_cast<std::size_t>(hint)];
  for (std::size_t i = 0; i < tags_.size(); ++i)
    if (matches(i, tag, body, extra, extra_size, derivatives)) return &entries_[i];
  return nullptr;
}

void PoseTransformMemo::store(const Entry& entry) {
  std::size_t at = next_;
  if (entries_.size() < kCapacity) {
    at = entries_.size();
    entries_.push_back(entry);
    tags_.push_back(entry.tag);
  } else {
    entries_[next_] = entry;
    tags_[next_] = entry.tag;
    next_ = (next_ + 1) % kCapacity;
  }
  last_of_tag_[static_cast<std::size_t>(entry.tag) % kHints] = static_cast<int>(at);
}

PoseWrappedFactor::PoseWrappedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks,
                                     int extra_size, bool extra_is_pose)
    : inner_(std::move(inner)),
      inner_tangent_(dynamic_cast<const TangentJacobians*>(inner_.get())),
      n_poses_(pose_blocks.size()) {
  if (extra_is_pose && extra_size != kPoseAmbientSize) throw UsageError("PoseWrappedFactor: a pose block has 7 values");
  if (!extra_is_pose && (extra_size < 1 || extra_size > kPoseTangentSize))
    throw UsageError("PoseWrappedFactor: a Euclidean extra block has 1 to 6 values");
  n_extra_ = 1;
  extra_ambient_ = {extra_size, 0};
  extra_tangents_ = {extra_is_pose ? kPoseTangentSize : extra_size, 0};
  init(pose_blocks);
}

PoseWrappedFactor::PoseWrappedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks,
                                     int second_size)
    : inner_(std::move(inner)),
      inner_tangent_(dynamic_cast<const TangentJacobians*>(inner_.get())),
      n_poses_(pose_blocks.size()) {
  if (second_size < 1 || second_size > kMaxExtraTangent - kPoseTangentSize)
    throw UsageError("PoseWrappedFactor: the second extra block has 1 value");
  n_extra_ = 2;
  extra_ambient_ = {kPoseAmbientSize, second_size};
  extra_tangents_ = {kPoseTangentSize, second_size};
  init(pose_blocks);
}

void PoseWrappedFactor::init(std::span<const int> pose_blocks) {
  extra_tangent_ = extra_tangents_[0] + extra_tangents_[1];
  extra_ambient_total_ = extra_ambient_[0] + extra_ambient_[1];
  if (inner_tangent_ == nullptr)
    throw UsageError("PoseWrappedFactor: the inner factor gives no tangent-space Jacobians (TangentJacobians)");
  if (pose_blocks.size() > kMaxPoses || inner_->num_residuals() > kMaxRows ||
      static_cast<int>(inner_->parameter_block_sizes().size()) + n_extra_ > kMaxBlocks)
    throw UsageError("PoseWrappedFactor: a visual residual has at most 2 poses, 4 rows and 8 blocks");
  std::copy(pose_blocks.begin(), pose_blocks.end(), pose_blocks_.begin());
  set_num_residuals(inner_->num_residuals());
  const std::vector<int32_t>& inner_sizes = inner_->parameter_block_sizes();
  std::vector<int32_t>* sizes = mutable_parameter_block_sizes();
  sizes->reserve(inner_sizes.size() + static_cast<std::size_t>(n_extra_));
  sizes->assign(inner_sizes.begin(), inner_sizes.end());
  for (int e = 0; e < n_extra_; ++e) sizes->push_back(extra_ambient_[static_cast<std::size_t>(e)]);
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
  // The extra blocks' values, one after the other (copied only when there are two).
  std::array<double, kMaxExtraAmbient> extra_values;
  const double* extra = parameters[n_inner];
  if (n_extra_ == 2) {
    std::copy(parameters[n_inner], parameters[n_inner] + extra_ambient_[0], extra_values.begin());
    std::copy(parameters[n_inner + 1], parameters[n_inner + 1] + extra_ambient_[1],
              extra_values.begin() + extra_ambient_[0]);
    extra = extra_values.data();
  }
  const std::size_t n_poses = n_poses_;

  // Inner parameters with the body poses replaced by the transformed poses (and their derivatives when wanted).
  std::array<std::array<double, kPoseAmbientSize>, kMaxPoses> moved;
  std::array<Mat6, kMaxPoses> d_body;
  std::array<ExtraMap, kMaxPoses> d_extra;
  std::array<const double*, kMaxBlocks> inner_params{};
  std::copy(parameters, parameters + n_inner, inner_params.begin());
  // The transform's derivatives only when a pose's or the extra block's Jacobian is wanted (not for a landmark's
  // alone, as in the solver's landmark iterations).
  bool want_extra = false;
  for (int e = 0; e < n_extra_ && jacobians != nullptr; ++e) want_extra = want_extra || jacobians[n_inner + e] != nullptr;
  bool derivatives = want_extra;
  for (std::size_t k = 0; k < n_poses && jacobians != nullptr; ++k)
    derivatives = derivatives || jacobians[pose_blocks_[k]] != nullptr;
  const int extra_size = extra_ambient_total_;
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
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor, kMaxRows, kMaxExtraTangent> J_extra =
      Eigen::MatrixXd::Zero(rows, extra_tangent_);
  for (std::size_t k = 0; k < n_poses; ++k) {
    const int b = pose_blocks_[k];
    if (jacobians[b] != nullptr) TangentMap(jacobians[b], rows, kPoseTangentSize).noalias() = J_t[k] * d_body[k];
    if (want_extra) J_extra.noalias() += J_t[k] * d_extra[k];
  }
  if (!want_extra) return true;
  for (int e = 0, col = 0; e < n_extra_; col += extra_tangents_[static_cast<std::size_t>(e)], ++e) {
    const int t = extra_tangents_[static_cast<std::size_t>(e)];
    if (jacobians[n_inner + e] != nullptr) TangentMap(jacobians[n_inner + e], rows, t) = J_extra.middleCols(col, t);
  }
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
  return rigTransform(body, L_, R_L_, Rr_, R_Rr_t_, skew_t_Rr_, extra, d_body, d_extra);
}

TimeShiftedFactor::TimeShiftedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks,
                                     std::span<const Vec3> v_W, std::span<const Vec3> w_B)
    : PoseWrappedFactor(std::move(inner), pose_blocks, 1, false) {
  copyRates(pose_blocks.size(), v_W, w_B, "TimeShiftedFactor", &v_W_, &w_B_);
}

Pose TimeShiftedFactor::transform(std::size_t k, const Pose& body, const double* extra, Mat6* d_body,
                                  ExtraMap* d_extra) const {
  return timeShift(body, extra[0], v_W_[k], w_B_[k], d_body, d_extra);
}

RigTimeShiftedFactor::RigTimeShiftedFactor(std::shared_ptr<ceres::CostFunction> inner, std::span<const int> pose_blocks,
                                           const Pose& T_B_R0, std::span<const Vec3> v_W, std::span<const Vec3> w_B)
    : PoseWrappedFactor(std::move(inner), pose_blocks, 1),
      Rr_(T_B_R0.inverse()),
      R_Rr_t_(Rr_.R().transpose()),
      skew_t_Rr_(skew(Rr_.p)) {
  copyRates(pose_blocks.size(), v_W, w_B, "RigTimeShiftedFactor", &v_W_, &w_B_);
}

Pose RigTimeShiftedFactor::transform(std::size_t k, const Pose& body, const double* extra, Mat6* d_body,
                                     ExtraMap* d_extra) const {
  // extra: T_B_R (7), then t_d. The time shift first (the outer wrapper when nested), then the rig correction.
  const double td = extra[kPoseAmbientSize];
  const bool derivatives = d_body != nullptr;
  Mat6 A_time, A_rig;
  ExtraMap B_time(6, 1), B_rig(6, 6);
  const Pose shifted =
      timeShift(body, td, v_W_[k], w_B_[k], derivatives ? &A_time : nullptr, derivatives ? &B_time : nullptr);
  const Pose out = rigTransform(shifted, Pose::identity(), Mat3::Identity(), Rr_, R_Rr_t_, skew_t_Rr_, extra,
                                derivatives ? &A_rig : nullptr, derivatives ? &B_rig : nullptr);
  if (!derivatives) return out;
  d_body->noalias() = A_rig * A_time;
  d_extra->resize(6, kPoseTangentSize + 1);
  d_extra->leftCols(kPoseTangentSize) = B_rig;
  d_extra->col(kPoseTangentSize).noalias() = A_rig * B_time;
  return out;
}

}  // namespace linnet
