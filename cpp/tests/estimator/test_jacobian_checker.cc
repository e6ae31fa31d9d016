// The shared Jacobian checker must pass correct Jacobians and FAIL on wrong ones (DESIGN A5).
#include <cmath>
#include <memory>
#include <random>

#include <ceres/sized_cost_function.h>
#include <gtest/gtest.h>

#include "imu/imu_test_motion.h"
#include "linnet/estimator/factors/imu_factor.h"
#include "linnet/estimator/factors/point_factors.h"
#include "linnet/estimator/manifolds.h"
#include "support/jacobian_check.h"

namespace linnet {
namespace {

using testing::checkJacobians;
using testing::jacobiansMatch;

// Ways to get a Jacobian wrong, injected into an otherwise correct factor.
enum class Bug {
  kNone,
  kOneEntry,          // one ambient entry off by 10%
  kOneColumn,         // a whole tangent column zeroed
  kRotationSign,      // d r / d dtheta with the wrong sign
  kLeftPerturbation,  // Jacobian derived for q <- Exp(dtheta) q instead of q <- q Exp(dtheta)
  kSkipsResidual,     // a residual change when Jacobians are requested
  kUnwritten,         // leaves one Jacobian entry untouched
};

// Test factor with a pose block (7) and a landmark block (3): r = [R^T (l - p); 2 vec(q_ref^-1 q)].
class PoseLandmarkFactor : public ceres::SizedCostFunction<6, 7, 3> {
 public:
  PoseLandmarkFactor(const Quat& q_ref, Bug bug) : q_ref_(q_ref), bug_(bug) {}

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const Vec3 p = posePosition(parameters[0]);
    const Quat q = poseRotation(parameters[0]);
    const Eigen::Map<const Vec3> l(parameters[1]);
    const Mat3 Rt = q.toRotationMatrix().transpose();
    const Vec3 pb = Rt * (l - p);
    const Quat e = q_ref_.conjugate() * q;
    Eigen::Map<Vec6> r(residuals);
    r.head<3>() = pb;
    r.tail<3>() = 2.0 * e.vec();
    if (bug_ == Bug::kSkipsResidual && jacobians != nullptr) r[0] += 1e-3;
    if (jacobians == nullptr) return true;
    if (jacobians[0] != nullptr) {
      Eigen::Matrix<double, 6, 6> J = Eigen::Matrix<double, 6, 6>::Zero();
      J.block<3, 3>(0, 0) = -Rt;
      J.block<3, 3>(0, 3) = skew(pb);
      // 2 vec(e Exp(dtheta)) ~= 2 vec(e) + (e.w I + [e.vec]x) dtheta
      J.block<3, 3>(3, 3) = e.w() * Mat3::Identity() + skew(e.vec());
      if (bug_ == Bug::kRotationSign) J.block<3, 3>(0, 3) *= -1.0;
      if (bug_ == Bug::kLeftPerturbation) J.block<3, 3>(0, 3) = Rt * skew(l - p);
      if (bug_ == Bug::kOneColumn) J.col(4).setZero();
      tangentToAmbientPose<6>(J, parameters[0], jacobians[0]);
      if (bug_ == Bug::kOneEntry) jacobians[0][2 * 7 + 1] *= 1.1;
    }
    if (jacobians[1] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 6, 3, Eigen::RowMajor>> Jl(jacobians[1]);
      Jl.setZero();
      Jl.topRows<3>() = Rt;
      if (bug_ == Bug::kUnwritten) jacobians[1][5] = std::nan("");
    }
    return true;
  }

 private:
  Quat q_ref_;
  Bug bug_;
};

// Wraps a correct cost function and corrupts its ambient Jacobian of one block after the fact: one entry
// scaled, or one ambient column zeroed.
class CorruptingWrapper : public ceres::CostFunction {
 public:
  enum class Mode { kScaleEntry, kZeroColumn };
  CorruptingWrapper(const ceres::CostFunction& inner, int block, int row, int col, Mode mode)
      : inner_(inner), block_(block), row_(row), col_(col), mode_(mode) {
    set_num_residuals(inner.num_residuals());
    *mutable_parameter_block_sizes() = inner.parameter_block_sizes();
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    if (!inner_.Evaluate(parameters, residuals, jacobians)) return false;
    if (jacobians == nullptr || jacobians[block_] == nullptr) return true;
    const int cols = parameter_block_sizes()[block_];
    if (mode_ == Mode::kScaleEntry) {
      jacobians[block_][row_ * cols + col_] *= 1.01;
    } else {
      for (int r = 0; r < num_residuals(); ++r) jacobians[block_][r * cols + col_] = 0.0;
    }
    return true;
  }

 private:
  const ceres::CostFunction& inner_;
  int block_, row_, col_;
  Mode mode_;
};

struct Fixture {
  double pose[7];
  double landmark[3] = {1.5, -2.0, 4.0};
  Quat q_ref;
  explicit Fixture(unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, 1.0);
    const Quat q = Quat(n(rng), n(rng), n(rng), n(rng)).normalized();
    setPose(Pose(q, Vec3(n(rng), n(rng), n(rng))), pose);
    q_ref = q * expSO3(Vec3(0.3 * n(rng), 0.3 * n(rng), 0.3 * n(rng)));
  }
};

TEST(JacobianChecker, PassesCorrectJacobians) {
  const PoseManifold pm;
  for (unsigned seed = 1; seed <= 5; ++seed) {
    Fixture fx(seed);
    const PoseLandmarkFactor f(fx.q_ref, Bug::kNone);
    const auto res = checkJacobians(f, {fx.pose, fx.landmark}, {&pm, nullptr});
    EXPECT_TRUE(res.ok(1e-7)) << res.describe(1e-7, true);
    EXPECT_TRUE(res.residuals_consistent);
    ASSERT_EQ(res.blocks.size(), 2u);
    EXPECT_EQ(res.blocks[0].tangent_size, 6);
    EXPECT_EQ(res.blocks[1].tangent_size, 3);
    EXPECT_LT(res.maxAbsError(), 1e-7);
    EXPECT_TRUE(jacobiansMatch(f, {fx.pose, fx.landmark}, {&pm, nullptr}, 1e-7));
  }
}

TEST(JacobianChecker, LeavesParametersUntouched) {
  const PoseManifold pm;
  Fixture fx(3);
  double copy[7];
  std::copy(fx.pose, fx.pose + 7, copy);
  const PoseLandmarkFactor f(fx.q_ref, Bug::kNone);
  (void)checkJacobians(f, {fx.pose, fx.landmark}, {&pm, nullptr});
  for (int i = 0; i < 7; ++i) EXPECT_EQ(copy[i], fx.pose[i]);
}

TEST(JacobianChecker, FailsOnEveryInjectedBug) {
  const PoseManifold pm;
  Fixture fx(11);
  for (Bug bug : {Bug::kOneEntry, Bug::kOneColumn, Bug::kRotationSign, Bug::kLeftPerturbation,
                  Bug::kSkipsResidual, Bug::kUnwritten}) {
    const PoseLandmarkFactor f(fx.q_ref, bug);
    const auto res = checkJacobians(f, {fx.pose, fx.landmark}, {&pm, nullptr});
    EXPECT_FALSE(res.ok(1e-4)) << "bug " << static_cast<int>(bug) << " not detected:\n" << res.describe();
    EXPECT_FALSE(jacobiansMatch(f, {fx.pose, fx.landmark}, {&pm, nullptr}, 1e-4));
  }
}

TEST(JacobianChecker, LocatesTheWrongBlockAndEntry) {
  const PoseManifold pm;
  Fixture fx(5);
  {
    const PoseLandmarkFactor f(fx.q_ref, Bug::kOneColumn);
    const auto res = checkJacobians(f, {fx.pose, fx.landmark}, {&pm, nullptr});
    ASSERT_EQ(res.blocks.size(), 2u);
    EXPECT_GT(res.blocks[0].max_rel_error, 1e-3);
    EXPECT_EQ(res.blocks[0].worst_col, 4);
    EXPECT_LT(res.blocks[1].max_rel_error, 1e-7);
  }
  {
    const PoseLandmarkFactor f(fx.q_ref, Bug::kUnwritten);
    const auto res = checkJacobians(f, {fx.pose, fx.landmark}, {&pm, nullptr});
    EXPECT_TRUE(res.blocks[0].finite);
    EXPECT_FALSE(res.blocks[1].finite);
    EXPECT_NE(res.describe().find("NON-FINITE"), std::string::npos);
  }
  {
    const PoseLandmarkFactor f(fx.q_ref, Bug::kSkipsResidual);
    const auto res = checkJacobians(f, {fx.pose, fx.landmark}, {&pm, nullptr});
    EXPECT_FALSE(res.residuals_consistent);
    EXPECT_FALSE(res.problem.empty());
  }
}

TEST(JacobianChecker, AmbientPoseJacobianIsAlsoTheEuclideanDerivative) {
  // tangentToAmbientPose() yields a Jacobian with no component along q itself, which is exactly the Euclidean
  // derivative of a residual that normalises q (as poseRotation() does). So the check passes even through the
  // Euclidean "manifold"; with a wrong rotation Jacobian it must still fail.
  Fixture fx(9);
  EXPECT_TRUE(checkJacobians(PoseLandmarkFactor(fx.q_ref, Bug::kNone), {fx.pose, fx.landmark}, {}).ok(1e-7));
  EXPECT_FALSE(
      checkJacobians(PoseLandmarkFactor(fx.q_ref, Bug::kRotationSign), {fx.pose, fx.landmark}, {}).ok(1e-4));
}

TEST(JacobianChecker, ReportsStructuralMisuse) {
  Fixture fx(2);
  const PoseLandmarkFactor f(fx.q_ref, Bug::kNone);
  const PoseManifold pm;
  EXPECT_FALSE(checkJacobians(f, {fx.pose}, {}).ok(1.0));
  EXPECT_FALSE(checkJacobians(f, {fx.pose, fx.landmark}, {&pm}).ok(1.0));
  EXPECT_FALSE(checkJacobians(f, {fx.pose, fx.landmark}, {nullptr, &pm}).ok(1.0));  // ambient 7 on a 3-block
}

TEST(JacobianChecker, CatchesCorruptionsOfTheRealImuFactor) {
  const testing::SmoothMotion m;
  constexpr Timestamp kMs = 1'000'000;
  const Vec3 b_a(0.05, -0.03, 0.1), b_g(0.004, 0.002, -0.006);
  const auto pre = std::make_shared<Preintegration>(m.samples(0, 400 * kMs, 5 * kMs, b_a, b_g), ImuNoise(),
                                                    Vec3::Zero(), Vec3::Zero());
  const ImuFactor factor(pre, 9.81);
  const ImuState si = m.state(0, b_a, b_g), sj = m.state(400 * kMs, 1.1 * b_a, 0.9 * b_g);
  double pose_i[7], pose_j[7], sb_i[9], sb_j[9];
  setPose(si.T_W_B, pose_i);
  setPose(Pose(sj.T_W_B.q * expSO3(Vec3(0.02, -0.01, 0.03)), sj.T_W_B.p + Vec3(0.05, 0.0, -0.02)), pose_j);
  for (int k = 0; k < 3; ++k) {
    sb_i[k] = si.v_W[k];
    sb_i[3 + k] = si.b_a[k];
    sb_i[6 + k] = si.b_g[k];
    sb_j[k] = sj.v_W[k] + 0.01;
    sb_j[3 + k] = sj.b_a[k];
    sb_j[6 + k] = sj.b_g[k];
  }
  const std::vector<double*> params = {pose_i, sb_i, pose_j, sb_j};
  const PoseManifold pm;
  const std::vector<const ceres::Manifold*> manifolds = {&pm, nullptr, &pm, nullptr};
  EXPECT_TRUE(jacobiansMatch(factor, params, manifolds, 1e-5, 1e-5));
  using Mode = CorruptingWrapper::Mode;
  struct Case {
    int block, row, col;
    Mode mode;
  };
  // A rotation-residual entry of pose_i's quaternion part, a velocity column of speed-bias_i, the gyro-bias
  // entry of the rotation residual (the bias-correction Jacobian), and pose_j's position column.
  for (const Case& c : {Case{0, 3, 4, Mode::kScaleEntry}, Case{1, 0, 1, Mode::kZeroColumn},
                        Case{1, 4, 7, Mode::kScaleEntry}, Case{2, 0, 0, Mode::kZeroColumn}}) {
    const CorruptingWrapper bad(factor, c.block, c.row, c.col, c.mode);
    const auto res = checkJacobians(bad, params, manifolds, 1e-5);
    EXPECT_FALSE(res.ok(1e-5)) << "corruption of block " << c.block << " (" << c.row << ", " << c.col
                               << ") not detected:\n"
                               << res.describe();
    EXPECT_GT(res.blocks[static_cast<size_t>(c.block)].max_rel_error, 1e-4);
  }
}

/// A point factor whose Ceres path is right and whose tangent-space path (the Schur solver's) has one entry of block
/// `block` scaled by 1.001.
class CorruptTangentPath : public ceres::SizedCostFunction<2, 7, 7, 1>, public TangentJacobians {
 public:
  CorruptTangentPath(const PointReprojectionFactor& f, int block, int entry) : f_(f), block_(block), entry_(entry) {}
  bool Evaluate(double const* const* p, double* r, double** J) const override { return f_.Evaluate(p, r, J); }
  bool evaluateTangentSpace(double const* const* p, double* r, double** J) const override {
    if (!f_.evaluateTangentSpace(p, r, J)) return false;
    if (J != nullptr && J[block_] != nullptr) J[block_][entry_] *= 1.0 + 1e-3;
    return true;
  }

 private:
  const PointReprojectionFactor& f_;
  int block_, entry_;
};

TEST(JacobianChecker, ChecksTheTangentSpacePathToo) {
  const Pose T_B_C(expSO3(Vec3(-1.2, 0.1, -1.5)), Vec3(-0.02, -0.06, 0.01));
  const Pose T_W_Bi(expSO3(Vec3(0.3, -0.2, 0.5)), Vec3(1.0, 2.0, 0.5));
  const Pose T_W_Bj = T_W_Bi * Pose(expSO3(Vec3(0.02, 0.05, -0.03)), Vec3(0.1, -0.05, 0.02));
  const Vec2 uv_host(0.1, -0.05);
  const double depth = 4.0;
  const Vec3 p_C = (T_W_Bj * T_B_C).inverse() * ((T_W_Bi * T_B_C) * (depth * Vec3(uv_host.x(), uv_host.y(), 1.0)));
  const PointReprojectionFactor f(uv_host, p_C.head<2>() / p_C.z() + Vec2(0.002, -0.001), T_B_C, T_B_C, 300.0);
  double pi[7], pj[7], rho = 1.0 / depth;
  setPose(T_W_Bi, pi);
  setPose(T_W_Bj, pj);
  const PoseManifold pm;
  const std::vector<double*> params = {pi, pj, &rho};
  const std::vector<const ceres::Manifold*> manifolds = {&pm, &pm, nullptr};
  EXPECT_TRUE(jacobiansMatch(f, params, manifolds, 1e-6));
  // Tangent entries: pose i's dp_x of row 0, pose j's dtheta_z of row 1, the inverse depth of row 0.
  for (const auto& [block, entry] : {std::pair{0, 0}, std::pair{1, 11}, std::pair{2, 0}}) {
    const CorruptTangentPath bad(f, block, entry);
    const auto res = checkJacobians(bad, params, manifolds);
    EXPECT_FALSE(res.ok(1e-6)) << "block " << block << " entry " << entry << ":\n" << res.describe();
  }
}

}  // namespace
}  // namespace linnet
