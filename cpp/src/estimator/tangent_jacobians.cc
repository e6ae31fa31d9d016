// Ceres' ambient Jacobians from a factor's tangent-space ones (see factors/tangent_jacobians.h).
#include "linnet/estimator/factors/tangent_jacobians.h"

#include <array>

#include "linnet/core/error.h"
#include "linnet/estimator/manifolds.h"

namespace linnet {

namespace {
constexpr int kMaxRows = 4;
constexpr int kMaxBlocks = 8;
using AmbientJ = Eigen::Matrix<double, Eigen::Dynamic, kPoseAmbientSize, Eigen::RowMajor, kMaxRows, kPoseAmbientSize>;
using TangentJ = Eigen::Matrix<double, Eigen::Dynamic, kPoseTangentSize, Eigen::RowMajor, kMaxRows, kPoseTangentSize>;
}  // namespace

bool evaluateThroughTangent(const TangentJacobians& f, const std::vector<std::int32_t>& block_sizes, int rows,
                            double const* const* parameters, double* residuals, double** jacobians) {
  if (jacobians == nullptr) return f.evaluateTangentSpace(parameters, residuals, nullptr);
  if (rows > kMaxRows || block_sizes.size() > static_cast<std::size_t>(kMaxBlocks))
    throw UsageError("evaluateThroughTangent: a visual residual has at most 4 rows and 8 blocks");
  // Tangent Jacobians of the pose blocks (every 7-double block) into scratch, the other blocks' straight out.
  std::array<TangentJ, kMaxBlocks> scratch;
  std::array<double*, kMaxBlocks> tangent{};
  for (std::size_t b = 0; b < block_sizes.size(); ++b) {
    tangent[b] = jacobians[b];
    if (jacobians[b] == nullptr || block_sizes[b] != kPoseAmbientSize) continue;
    scratch[b].resize(rows, kPoseTangentSize);
    tangent[b] = scratch[b].data();
  }
  if (!f.evaluateTangentSpace(parameters, residuals, tangent.data())) return false;
  // Ambient J = [J_dp, 4 J_dtheta Lq^T], so that J * PlusJacobian gives the tangent one back (manifolds.h).
  for (std::size_t b = 0; b < block_sizes.size(); ++b) {
    if (jacobians[b] == nullptr || block_sizes[b] != kPoseAmbientSize) continue;
    Eigen::Map<AmbientJ> J(jacobians[b], rows, kPoseAmbientSize);
    J.leftCols(3) = scratch[b].leftCols(3);
    J.rightCols(4) = 4.0 * scratch[b].rightCols(3) * quatPlusJacobian(poseRotation(parameters[b])).transpose();
  }
  return true;
}

const TangentJacobians* TangentJacobiansCache::of(const ceres::CostFunction* cost) {
  if (cost == nullptr) return nullptr;
  const std::type_info& type = typeid(*cost);
  const auto answer = [&](const Entry& e) {
    return e.is_tangent ? reinterpret_cast<const TangentJacobians*>(reinterpret_cast<const char*>(cost) + e.offset)
                        : nullptr;
  };
  // By the type_info object first: one type's typeid is one object within a binary, and a mismatch by name costs a
  // string comparison of the mangled names (each residual of a solve asks). Then by name, for a type whose typeid
  // another shared library gives as another object.
  for (const Entry& e : entries_)
    if (e.type == &type) return answer(e);
  for (const Entry& e : entries_)
    if (*e.type == type) return answer(e);
  const auto* tangent = dynamic_cast<const TangentJacobians*>(cost);
  entries_.push_back({&type,
                      tangent != nullptr
                          ? reinterpret_cast<const char*>(tangent) - reinterpret_cast<const char*>(cost)
                          : std::ptrdiff_t{0},
                      tangent != nullptr});
  return tangent;
}

}  // namespace linnet
