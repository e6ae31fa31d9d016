// Jacobians in the tangent space of the pose blocks, for solvers that work there.
//
// Ceres asks a cost function for ambient Jacobians (R x 7 for a pose block) and multiplies them by the manifold's
// PlusJacobian. The visual factors compute the tangent Jacobian (R x 6, w.r.t. [dp, dtheta] of PoseManifold) and
// convert it to an ambient one that maps back to it (tangentToAmbientPose), so a tangent-space solver would undo a
// conversion per residual and pose block. A factor implementing TangentJacobians gives the tangent Jacobians directly:
// the Schur solver uses them, Ceres keeps using Evaluate. Both describe the same function.
#pragma once

#include <cstdint>
#include <vector>

namespace linnet {

class TangentJacobians {
 public:
  virtual ~TangentJacobians() = default;

  /// As ceres::CostFunction::Evaluate, except that the Jacobian of every pose block (7 doubles on PoseManifold) is
  /// w.r.t. its tangent [dp, dtheta]: rows x 6, row-major. Other blocks' Jacobians are as Evaluate gives them.
  /// `jacobians` and any of its entries may be nullptr.
  virtual bool evaluateTangentSpace(double const* const* parameters, double* residuals, double** jacobians) const = 0;
};

/// ceres::CostFunction::Evaluate of a TangentJacobians factor (`block_sizes`, `rows`: its shape): evaluateTangentSpace
/// with the pose blocks' Jacobians in scratch, then converted to ambient ones as tangentToAmbientPose does. For visual
/// residuals: at most 4 rows and 8 blocks (UsageError otherwise); no heap allocation.
bool evaluateThroughTangent(const TangentJacobians& f, const std::vector<std::int32_t>& block_sizes, int rows,
                            double const* const* parameters, double* residuals, double** jacobians);

}  // namespace linnet
