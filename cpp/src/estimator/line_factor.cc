// Line residual (DESIGN B1) with analytic Jacobians; the derivation is in the comments of evaluate().
#include "linnet/estimator/factors/line_factor.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "linnet/core/error.h"
#include "linnet/estimator/manifolds.h"
#include "linnet/geometry/plucker.h"

namespace linnet {

LineProjection::LineProjection(const Vec2& s, const Vec2& e, const Pose& T_B_C, double sqrt_info)
    : s_(s.x(), s.y(), 1.0),
      e_(e.x(), e.y(), 1.0),
      R_C_B_(T_B_C.R().transpose()),
      t_B_C_(T_B_C.p),
      sqrt_info_(sqrt_info) {}

void LineProjection::poseTerms(const Pose& T_W_B, PoseTerms* terms) const {
  terms->Rt = T_W_B.R().transpose();
  terms->p = T_W_B.p;
  // The image line is linear in L_W: l = R_C_B (n_B - t x v_B) = M_n n_W + M_v v_W, with n_B = R^T (n_W - p x v_W)
  // and v_B = R^T v_W, so M_n = R_C_B R^T and M_v = R_C_B K, K = -R^T [p]x - [t]x R^T.
  const Mat3 K = -terms->Rt * skew(terms->p) - skew(t_B_C_) * terms->Rt;
  terms->M_n = R_C_B_ * terms->Rt;
  terms->M_v = R_C_B_ * K;
}

bool LineProjection::evaluate(const Pose& T_W_B, const Vec6& L_W, Vec2* residual, Eigen::Matrix<double, 2, 6>* J_pose,
                              Eigen::Matrix<double, 2, 6>* J_line) const {
  PoseTerms terms;
  poseTerms(T_W_B, &terms);
  return evaluateWith(terms, L_W, residual, J_pose, J_line);
}

bool LineProjection::evaluateWith(const PoseTerms& terms, const Vec6& L_W, Vec2* residual,
                                  Eigen::Matrix<double, 2, 6>* J_pose, Eigen::Matrix<double, 2, 6>* J_line) const {
  // Plücker W -> B -> C:  n_B = R^T (n_W - p x v_W), v_B = R^T v_W;  n_C = R_C_B (n_B - t_B_C x v_B), which is
  // M_n n_W + M_v v_W (poseTerms).
  const Vec3 n_W = L_W.head<3>(), v_W = L_W.tail<3>();
  const Vec3 l = terms.M_n * n_W + terms.M_v * v_W;  // image line, normalised coordinates
  const double ln2 = l.x() * l.x() + l.y() * l.y();
  if (!(ln2 > 1e-30)) return false;
  const double ln = std::sqrt(ln2);
  const double ds = s_.dot(l), de = e_.dot(l);
  const Vec2 r = sqrt_info_ * Vec2(ds, de) / ln;
  if (!r.allFinite()) return false;
  if (residual != nullptr) *residual = r;
  if (J_pose == nullptr && J_line == nullptr) return true;

  // d r / d l: r_k = x_k . l / |l_12|  ->  x_k^T / |l_12| - (x_k . l) [l1, l2, 0] / |l_12|^3.
  const Vec3 l12(l.x(), l.y(), 0.0);
  Eigen::Matrix<double, 2, 3> A;
  A.row(0) = (s_ / ln - ds / (ln2 * ln) * l12).transpose();
  A.row(1) = (e_ / ln - de / (ln2 * ln) * l12).transpose();
  A *= sqrt_info_;
  if (J_pose != nullptr) {
    // p <- p + dp:             d n_B / dp = R^T [v_W]x,  d v_B / dp = 0.
    // R <- R Exp(dtheta):      R^T -> (I - [dtheta]x) R^T, so d n_B / dtheta = [n_B]x, d v_B / dtheta = [v_B]x.
    const Vec3 n_B = terms.Rt * (n_W - terms.p.cross(v_W));
    const Vec3 v_B = terms.Rt * v_W;
    const Eigen::Matrix<double, 2, 3> A_B = A * R_C_B_;  // d r / d(n_B - t x v_B)
    J_pose->leftCols<3>() = A * terms.M_n * skew(v_W);
    J_pose->rightCols<3>() = A_B * (skew(n_B) - skew(t_B_C_) * skew(v_B));
  }
  if (J_line != nullptr) {
    // d l / d n_W = M_n, d l / d v_W = M_v (poseTerms).
    J_line->leftCols<3>() = A * terms.M_n;
    J_line->rightCols<3>() = A * terms.M_v;
  }
  return true;
}

namespace {
// `shared`, after checking that its terms are for these extrinsics: terms computed with others would give a wrong
// residual without any sign of it.
std::shared_ptr<SharedLinePoseTerms> checkedShared(const Pose& T_B_C, std::shared_ptr<SharedLinePoseTerms> shared) {
  if (shared && (shared->T_B_C.p != T_B_C.p || shared->T_B_C.q.coeffs() != T_B_C.q.coeffs()))
    throw UsageError("LineReprojectionFactor: shared pose terms of other extrinsics than the factor's");
  return shared;
}
}  // namespace

LineReprojectionFactor::LineReprojectionFactor(const Vec2& s, const Vec2& e, const Pose& T_B_C, double sqrt_info,
                                               std::shared_ptr<SharedLinePoseTerms> shared)
    : projection_(s, e, T_B_C, sqrt_info), shared_(checkedShared(T_B_C, std::move(shared))) {}

void LineReprojectionFactor::reset(const Vec2& s, const Vec2& e, const Pose& T_B_C, double sqrt_info,
                                   std::shared_ptr<SharedLinePoseTerms> shared) {
  shared_ = checkedShared(T_B_C, std::move(shared));
  projection_ = LineProjection(s, e, T_B_C, sqrt_info);
  cache_.valid = false;
}

bool LineReprojectionFactor::evaluateTangentSpace(double const* const* parameters, double* residuals,
                                                  double** jacobians) const {
  const bool want_pose = jacobians != nullptr && jacobians[0] != nullptr;
  const bool want_line = jacobians != nullptr && jacobians[1] != nullptr;
  Vec2 r;
  Eigen::Matrix<double, 2, 6> Jp, Jl;
  // The pose's terms from the cache when the pose block holds the same values (the line iterations, and the other
  // lines of the frame camera when shared), else anew.
  const double* pose = parameters[0];
  LineProjection::PoseTerms& cache = shared_ ? shared_->terms : cache_;
  if (!cache.valid || !std::equal(pose, pose + 7, cache.block.begin())) {
    projection_.poseTerms(poseFromBlock(pose), &cache);
    std::copy(pose, pose + 7, cache.block.begin());
    cache.valid = true;
  }
  if (!projection_.evaluateWith(cache, Eigen::Map<const Vec6>(parameters[1]), &r, want_pose ? &Jp : nullptr,
                                want_line ? &Jl : nullptr))
    return false;
  residuals[0] = r.x();
  residuals[1] = r.y();
  using RowMajor26 = Eigen::Matrix<double, 2, 6, Eigen::RowMajor>;
  if (want_pose) Eigen::Map<RowMajor26>{jacobians[0]} = Jp;
  if (want_line) Eigen::Map<RowMajor26>{jacobians[1]} = Jl;
  return true;
}

bool LineReprojectionFactor::Evaluate(double const* const* parameters, double* residuals,
                                      double** jacobians) const {
  return evaluateThroughTangent(*this, parameter_block_sizes(), num_residuals(), parameters, residuals, jacobians);
}

double lineReprojectionErrorPx(const Vec6& L_W, const Pose& T_W_C, const Vec2& s, const Vec2& e, double focal_px) {
  return lineReprojectionErrorPxFromCw(L_W, T_W_C.inverse(), s, e, focal_px);
}

double lineReprojectionErrorPxFromCw(const Vec6& L_W, const Pose& T_C_W, const Vec2& s, const Vec2& e,
                                     double focal_px) {
  const Vec3 l = transformPlucker(T_C_W, L_W).head<3>();
  const Vec2 d = lineEndpointDistances(l, s, e);
  if (!d.allFinite()) return std::numeric_limits<double>::infinity();
  return 0.5 * focal_px * (std::abs(d.x()) + std::abs(d.y()));
}

}  // namespace linnet
