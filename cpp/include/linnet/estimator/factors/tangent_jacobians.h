// Jacobians in the tangent space of the pose blocks, for solvers that work there.
//
// Ceres asks a cost function for ambient Jacobians (R x 7 for a pose block) and multiplies them by the manifold's
// PlusJacobian. The visual factors compute the tangent Jacobian (R x 6, w.r.t. [dp, dtheta] of PoseManifold) and
// convert it to an ambient one that maps back to it (tangentToAmbientPose), so a tangent-space solver would undo a
// conversion per residual and pose block. A factor implementing TangentJacobians gives the tangent Jacobians directly:
// the Schur solver uses them, Ceres keeps using Evaluate. Both describe the same function.
#pragma once

#include <cstddef>
#include <cstdint>
#include <typeinfo>
#include <vector>

#include <ceres/cost_function.h>

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

/// dynamic_cast<const TangentJacobians*>(cost), remembered per dynamic type. The cast is a cross-cast, which walks
/// the class hierarchy; a window solve asks it for each of its ~2000 residuals, of a handful of types (about 1 % of a
/// run's instructions). A base subobject sits at the same offset in every object of one complete type, so the offset
/// found by the first cast serves the others. One per solve or marginalisation (not thread-safe).
class TangentJacobiansCache {
 public:
  const TangentJacobians* of(const ceres::CostFunction* cost);

 private:
  struct Entry {
    const std::type_info* type;
    std::ptrdiff_t offset;  // of the TangentJacobians subobject from the CostFunction one, bytes
    bool is_tangent;
  };
  std::vector<Entry> entries_;
};

}  // namespace linnet
