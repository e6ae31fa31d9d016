// Marginaliser on linear-Gaussian problems, where the Schur complement is exact: the prior plus the remaining
// residuals must reproduce the batch solution and marginal covariance of the full problem, also when a prior
// is itself re-marginalised. Plus the robust-loss correction and the API's error handling.
#include "linnet/estimator/marginaliser.h"

#include <cstring>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include <ceres/ceres.h>
#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "linnet/core/error.h"
#include "linnet/core/options.h"
#include "linnet/core/types.h"
#include "linnet/estimator/factors/prior_factor.h"

namespace linnet {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// r = sum_k A_k x_k - z over Euclidean blocks.
class LinearResidual : public ceres::CostFunction {
 public:
  LinearResidual(std::vector<Eigen::MatrixXd> A, Eigen::VectorXd z) : A_(std::move(A)), z_(std::move(z)) {
    set_num_residuals(static_cast<int>(z_.size()));
    for (const auto& a : A_) mutable_parameter_block_sizes()->push_back(static_cast<int>(a.cols()));
  }
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Eigen::Map<Eigen::VectorXd> r(residuals, z_.size());
    r = -z_;
    for (std::size_t k = 0; k < A_.size(); ++k) {
      r += A_[k] * Eigen::Map<const Eigen::VectorXd>(x[k], A_[k].cols());
      if (jacobians != nullptr && jacobians[k] != nullptr)
        Eigen::Map<RowMatrix>(jacobians[k], A_[k].rows(), A_[k].cols()) = A_[k];
    }
    return true;
  }

 private:
  std::vector<Eigen::MatrixXd> A_;
  Eigen::VectorXd z_;
};

struct Term {
  std::shared_ptr<ceres::CostFunction> cost;
  std::vector<BlockKey> keys;
};

/// A random linear problem: block sizes by key, residual terms over given key sets.
struct LinearProblem {
  std::map<BlockKey, int> sizes;
  std::map<BlockKey, std::vector<double>> x_lin;  // linearisation point (arbitrary: the problem is linear)
  std::vector<Term> terms;

  LinearProblem(std::mt19937& rng, const std::map<BlockKey, int>& block_sizes,
                const std::vector<std::vector<BlockKey>>& structure)
      : sizes(block_sizes) {
    std::normal_distribution<double> n(0.0, 1.0);
    for (auto [key, size] : sizes) {
      std::vector<double> v(size);
      for (double& e : v) e = n(rng);
      x_lin[key] = v;
    }
    for (const auto& keys : structure) {
      const int rows = 2 + static_cast<int>(keys.size());
      std::vector<Eigen::MatrixXd> A;
      for (BlockKey k : keys)
        A.push_back(Eigen::MatrixXd::NullaryExpr(rows, sizes.at(k), [&] { return n(rng); }));
      const Eigen::VectorXd z = Eigen::VectorXd::NullaryExpr(rows, [&] { return n(rng); });
      terms.push_back({std::make_shared<LinearResidual>(A, z), keys});
    }
  }
};

/// Solves the (linear, Euclidean) least-squares problem given by `terms` over the blocks `order` exactly:
/// x* = x_lin - H^-1 g. Returns x* stacked in `order` and the covariance H^-1.
void denseSolve(const std::vector<Term>& terms, const std::vector<BlockKey>& order,
                const std::map<BlockKey, std::vector<double>>& x_lin, const std::map<BlockKey, int>& sizes,
                Eigen::VectorXd* x_star, Eigen::MatrixXd* cov) {
  std::map<BlockKey, int> offset;
  int total = 0;
  for (BlockKey k : order) {
    offset[k] = total;
    total += sizes.at(k);
  }
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(total, total);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(total), x0(total);
  for (BlockKey k : order)
    x0.segment(offset[k], sizes.at(k)) = Eigen::Map<const Eigen::VectorXd>(x_lin.at(k).data(), sizes.at(k));
  for (const Term& t : terms) {
    const int nr = t.cost->num_residuals();
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(nr, total);
    std::vector<const double*> params;
    std::vector<RowMatrix> jac(t.keys.size());
    std::vector<double*> jac_ptr;
    for (std::size_t i = 0; i < t.keys.size(); ++i) {
      params.push_back(x_lin.at(t.keys[i]).data());
      jac[i].resize(nr, sizes.at(t.keys[i]));
      jac_ptr.push_back(jac[i].data());
    }
    Eigen::VectorXd r(nr);
    ASSERT_TRUE(t.cost->Evaluate(params.data(), r.data(), jac_ptr.data()));
    for (std::size_t i = 0; i < t.keys.size(); ++i)
      J.middleCols(offset.at(t.keys[i]), sizes.at(t.keys[i])) = jac[i];
    H += J.transpose() * J;
    g += J.transpose() * r;
  }
  *cov = H.inverse();
  *x_star = x0 - *cov * g;
}

/// Registers the blocks a set of terms touches, adds the terms, marginalises `drop`.
std::shared_ptr<const MarginalizationPrior> marginaliseTerms(
    const std::vector<Term>& terms, const std::map<BlockKey, std::vector<double>>& x_lin,
    const std::vector<BlockKey>& drop, const MarginaliserOptions& options = {}) {
  Marginaliser m(options);
  for (const auto& [key, values] : x_lin)
    m.addParameterBlock(key, values.data(), static_cast<int>(values.size()), nullptr);
  for (const Term& t : terms) m.addResidual(t.cost, nullptr, t.keys);
  return m.marginalise(drop);
}

// Largest magnitude below the diagonal: 0 for the Cholesky path's upper-triangular square root.
double belowDiagonal(const Eigen::MatrixXd& J) {
  return J.triangularView<Eigen::StrictlyLower>().toDenseMatrix().cwiseAbs().maxCoeff();
}

bool touchesAny(const Term& t, const std::vector<BlockKey>& keys) {
  for (BlockKey k : t.keys)
    for (BlockKey d : keys)
      if (k == d) return true;
  return false;
}

TEST(Marginaliser, LinearGaussianMatchesBatchSolutionAndCovariance) {
  std::mt19937 rng(21);
  const LinearProblem lp(rng, {{10, 2}, {11, 3}, {12, 2}, {13, 1}, {14, 2}},
                         {{10}, {10, 11}, {11, 12}, {10, 13}, {12, 13, 14}, {14}, {11}});
  const std::vector<BlockKey> drop = {10, 11};
  auto prior = marginaliseTerms(lp.terms, lp.x_lin, drop);
  ASSERT_TRUE(prior);
  EXPECT_EQ(prior->keys,
            (std::vector<BlockKey>{12, 13}));  // connected to a dropped block, registration order
  EXPECT_EQ(prior->J.cols(), 3);
  EXPECT_EQ(prior->J.rows(), 3);  // full rank
  // ... so the square root is the Cholesky factor's (upper triangular), the path the window's priors take.
  EXPECT_EQ(belowDiagonal(prior->J), 0.0);

  // Batch over everything.
  Eigen::VectorXd x_full;
  Eigen::MatrixXd cov_full;
  denseSolve(lp.terms, {10, 11, 12, 13, 14}, lp.x_lin, lp.sizes, &x_full, &cov_full);

  // Reduced: the prior plus the residuals not touching a dropped block.
  std::vector<Term> reduced = {{std::make_shared<PriorFactor>(prior), prior->keys}};
  for (const Term& t : lp.terms)
    if (!touchesAny(t, drop)) reduced.push_back(t);
  Eigen::VectorXd x_red;
  Eigen::MatrixXd cov_red;
  denseSolve(reduced, {12, 13, 14}, lp.x_lin, lp.sizes, &x_red, &cov_red);

  EXPECT_LT((x_red - x_full.tail(5)).cwiseAbs().maxCoeff(), 1e-9) << x_red.transpose() << "\n"
                                                                  << x_full.tail(5).transpose();
  EXPECT_LT((cov_red - cov_full.bottomRightCorner(5, 5)).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Marginaliser, CholeskyAndEigenSquareRootsGiveTheSamePrior) {
  // A full-rank prior takes the Cholesky factor; an eigenvalue threshold between the certain bound 1 / trace(H*^-1)
  // and the smallest eigenvalue sends the same problem down the eigen-decomposition path, which still keeps every
  // eigenvalue. Both square roots must give the same H* = J^T J and g* = J^T r.
  std::mt19937 rng(5);
  const LinearProblem lp(rng, {{10, 2}, {11, 3}, {12, 3}, {13, 2}, {14, 2}},
                         {{10}, {10, 11}, {11, 12}, {10, 13}, {12, 13, 14}, {10, 14}, {11, 14}});
  const std::vector<BlockKey> drop = {10, 11};
  const auto chol = marginaliseTerms(lp.terms, lp.x_lin, drop);
  ASSERT_TRUE(chol);
  ASSERT_EQ(chol->J.rows(), chol->J.cols());
  EXPECT_EQ(belowDiagonal(chol->J), 0.0);
  const Eigen::MatrixXd H = chol->J.transpose() * chol->J;
  const Eigen::VectorXd g = chol->J.transpose() * chol->r;
  const double lambda_min = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(H).eigenvalues()(0);
  const double certain = 1.0 / H.inverse().trace();
  ASSERT_LT(certain, lambda_min);
  MarginaliserOptions o;
  o.eigenvalue_threshold = 0.5 * (certain + lambda_min);
  const auto eig = marginaliseTerms(lp.terms, lp.x_lin, drop, o);
  ASSERT_TRUE(eig);
  ASSERT_EQ(eig->J.rows(), chol->J.rows());  // every eigenvalue kept
  EXPECT_GT(belowDiagonal(eig->J), 0.0);
  const double scale = H.cwiseAbs().maxCoeff();
  EXPECT_LT((eig->J.transpose() * eig->J - H).cwiseAbs().maxCoeff(), 1e-10 * scale);
  EXPECT_LT((eig->J.transpose() * eig->r - g).cwiseAbs().maxCoeff(), 1e-10 * std::max(1.0, g.cwiseAbs().maxCoeff()));
  EXPECT_NEAR(eig->costAtX0(), chol->costAtX0(), 1e-10 * std::max(1.0, chol->costAtX0()));
}

TEST(Marginaliser, LandmarkHeavyDropMatchesBatch) {
  // A dropped "frame" (6) hosting 30 dropped 1-D "inverse depths", each seen from two kept frames (6 each):
  // the depths share no residual, so they go through the block-diagonal first stage.
  std::mt19937 rng(24);
  std::map<BlockKey, int> sizes = {{0, 6}, {1, 6}, {2, 6}};
  std::vector<std::vector<BlockKey>> structure = {{0}, {0, 1}, {1, 2}, {2}};
  std::vector<BlockKey> drop = {0};
  for (BlockKey p = 100; p < 130; ++p) {
    sizes[p] = 1;
    structure.push_back({0, 1, p});
    structure.push_back({0, 2, p});
    drop.push_back(p);
  }
  const LinearProblem lp(rng, sizes, structure);
  Marginaliser m;
  for (const auto& [key, values] : lp.x_lin)
    m.addParameterBlock(key, values.data(), static_cast<int>(values.size()), nullptr);
  std::vector<Term> rest;
  for (const Term& t : lp.terms) {
    if (touchesAny(t, drop)) {
      m.addResidual(t.cost, nullptr, t.keys);
    } else {
      rest.push_back(t);
    }
  }
  auto prior = m.marginalise(drop);
  ASSERT_TRUE(prior);
  EXPECT_EQ(m.lastStats().decoupled_blocks, 30);
  EXPECT_EQ(m.lastStats().dropped_size, 36);
  EXPECT_EQ(prior->keys, (std::vector<BlockKey>{1, 2}));

  std::vector<BlockKey> all;
  for (const auto& kv : sizes) all.push_back(kv.first);
  Eigen::VectorXd x_full, x_red;
  Eigen::MatrixXd cov_full, cov_red;
  denseSolve(lp.terms, all, lp.x_lin, lp.sizes, &x_full, &cov_full);  // keys 0, 1, 2, 100.. in map order
  rest.push_back({std::make_shared<PriorFactor>(prior), prior->keys});
  denseSolve(rest, {1, 2}, lp.x_lin, lp.sizes, &x_red, &cov_red);
  EXPECT_LT((x_red - x_full.segment(6, 12)).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((cov_red - cov_full.block(6, 6, 12, 12)).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Marginaliser, RemarginalisingAPriorMatchesBatch) {
  std::mt19937 rng(22);
  // A chain 0-1-2-3-4 with a loop (1,3): marginalise 0, then 1 through the first prior.
  const LinearProblem lp(rng, {{0, 3}, {1, 3}, {2, 3}, {3, 3}, {4, 3}},
                         {{0}, {0, 1}, {1, 2}, {2, 3}, {3, 4}, {1, 3}, {4}, {0, 2}});
  std::vector<Term> step1, rest1;
  for (const Term& t : lp.terms) (touchesAny(t, {0}) ? step1 : rest1).push_back(t);
  auto p1 = marginaliseTerms(step1, lp.x_lin, {0});
  ASSERT_TRUE(p1);
  EXPECT_EQ(p1->keys, (std::vector<BlockKey>{1, 2}));

  std::vector<Term> step2 = {{std::make_shared<PriorFactor>(p1), p1->keys}}, rest2;
  for (const Term& t : rest1) (touchesAny(t, {1}) ? step2 : rest2).push_back(t);
  auto p2 = marginaliseTerms(step2, lp.x_lin, {1});
  ASSERT_TRUE(p2);
  EXPECT_EQ(p2->keys, (std::vector<BlockKey>{2, 3}));

  Eigen::VectorXd x_full, x_red;
  Eigen::MatrixXd cov_full, cov_red;
  denseSolve(lp.terms, {0, 1, 2, 3, 4}, lp.x_lin, lp.sizes, &x_full, &cov_full);
  rest2.push_back({std::make_shared<PriorFactor>(p2), p2->keys});
  denseSolve(rest2, {2, 3, 4}, lp.x_lin, lp.sizes, &x_red, &cov_red);
  EXPECT_LT((x_red - x_full.tail(9)).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((cov_red - cov_full.bottomRightCorner(9, 9)).cwiseAbs().maxCoeff(), 1e-9);

  // Same prior as eliminating {0, 1} at once.
  auto p_once = marginaliseTerms(
      [&] {
        std::vector<Term> v;
        for (const Term& t : lp.terms)
          if (touchesAny(t, {0, 1})) v.push_back(t);
        return v;
      }(),
      lp.x_lin, {0, 1});
  ASSERT_TRUE(p_once);
  ASSERT_EQ(p_once->keys, p2->keys);
  const Eigen::MatrixXd H2 = p2->J.transpose() * p2->J, H1 = p_once->J.transpose() * p_once->J;
  EXPECT_LT((H2 - H1).cwiseAbs().maxCoeff(), 1e-9 * H1.cwiseAbs().maxCoeff());
  EXPECT_LT((p2->J.transpose() * p2->r - p_once->J.transpose() * p_once->r).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Marginaliser, RankDeficientPriorKeepsOnlyObservableDirections) {
  // Block 1 (2-D) seen by the dropped block 0 through a 1-row residual: the prior has rank 1.
  Marginaliser m;
  const double x0[1] = {0.5}, x1[2] = {1.0, -1.0};
  m.addParameterBlock(0, x0, 1, nullptr);
  m.addParameterBlock(1, x1, 2, nullptr);
  Eigen::MatrixXd A0(1, 1), A1(1, 2), B0(1, 1);
  A0 << 1.0;
  A1 << 1.0, 2.0;
  B0 << 3.0;
  m.addResidual(std::make_shared<LinearResidual>(std::vector<Eigen::MatrixXd>{A0, A1},
                                                 Eigen::VectorXd::Constant(1, 0.3)),
                nullptr, {0, 1});
  m.addResidual(
      std::make_shared<LinearResidual>(std::vector<Eigen::MatrixXd>{B0}, Eigen::VectorXd::Constant(1, 1.0)),
      nullptr, {0});
  auto prior = m.marginalise({0});
  ASSERT_TRUE(prior);
  EXPECT_EQ(prior->J.rows(), 1);
  EXPECT_EQ(m.lastStats().prior_rank, 1);
  // H* = a1 a1^T (1 - 1/(1+9)) = 0.9 a1 a1^T.
  const Eigen::MatrixXd H = prior->J.transpose() * prior->J;
  EXPECT_LT((H - 0.9 * A1.transpose() * A1).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Marginaliser, RelativeThresholdDropsRoundOffLevelDirections) {
  // Kept block b (2-D): one direction with information ~1e8, one with 9e-8 (above the absolute 1e-8 threshold
  // but 1e-15 of the largest: numerically meaningless). The relative threshold removes it; without it, it
  // stays.
  Eigen::MatrixXd Aa(2, 1), Ab(2, 2), one = Eigen::MatrixXd::Ones(1, 1);
  Aa << 0.0, 0.0;  // a is only structurally connected: H* is exactly H_bb
  Ab << 1e4, 0.0, 0.0, 3e-4;
  const double a[1] = {0.0}, b[2] = {0.0, 0.0};
  for (double relative : {1e-13, 0.0}) {
    MarginaliserOptions options;
    options.relative_eigenvalue_threshold = relative;
    Marginaliser m(options);
    m.addParameterBlock(0, a, 1, nullptr);
    m.addParameterBlock(1, b, 2, nullptr);
    m.addResidual(
        std::make_shared<LinearResidual>(std::vector<Eigen::MatrixXd>{Aa, Ab}, Eigen::VectorXd::Ones(2)),
        nullptr, {0, 1});
    m.addResidual(
        std::make_shared<LinearResidual>(std::vector<Eigen::MatrixXd>{one}, Eigen::VectorXd::Zero(1)),
        nullptr, {0});
    auto prior = m.marginalise({0});
    ASSERT_TRUE(prior);
    EXPECT_EQ(prior->J.rows(), relative > 0.0 ? 1 : 2) << "relative threshold " << relative;
  }
}

/// r = M b - z over blocks (a[1], b[2]) with no dependence on a, so that the prior on b is exactly the
/// robustified Gauss-Newton system of this one residual.
class DecoupledResidual : public ceres::SizedCostFunction<2, 1, 2> {
 public:
  DecoupledResidual(const Mat2& M, const Vec2& z) : M_(M), z_(z) {}
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Eigen::Map<Vec2> r(residuals);
    r = M_ * Eigen::Map<const Vec2>(x[1]) - z_;
    if (jacobians != nullptr) {
      if (jacobians[0] != nullptr) jacobians[0][0] = jacobians[0][1] = 0.0;
      if (jacobians[1] != nullptr) {
        Eigen::Map<Eigen::Matrix<double, 2, 2, Eigen::RowMajor>> J(jacobians[1]);
        J = M_;
      }
    }
    return true;
  }

 private:
  Mat2 M_;
  Vec2 z_;
};

void robustSystem(ceres::LossFunction* loss, Mat2* H, Vec2* g, Vec2* r, Mat2* M) {
  *M << 1.0, 0.5, -0.3, 2.0;
  const double a[1] = {0.0}, b[2] = {0.7, -0.4};
  const Vec2 z(3.0, -1.0);
  *r = *M * Vec2(b[0], b[1]) - z;
  Marginaliser m;
  m.addParameterBlock(1, a, 1, nullptr);
  m.addParameterBlock(2, b, 2, nullptr);
  m.addResidual(std::make_shared<DecoupledResidual>(*M, z), loss, {1, 2});
  Eigen::MatrixXd one = Eigen::MatrixXd::Ones(1, 1);
  m.addResidual(std::make_shared<LinearResidual>(std::vector<Eigen::MatrixXd>{one}, Eigen::VectorXd::Zero(1)),
                nullptr, {1});
  auto prior = m.marginalise({1});
  ASSERT_TRUE(prior);
  *H = prior->J.transpose() * prior->J;
  *g = prior->J.transpose() * prior->r;
}

TEST(Marginaliser, RobustLossScalesLikeTheSolver) {
  Mat2 H, M;
  Vec2 g, r;
  // Huber (rho'' <= 0 outside the quadratic zone): plain sqrt(rho') scaling.
  ceres::HuberLoss huber(0.5);
  robustSystem(&huber, &H, &g, &r, &M);
  double rho[3];
  huber.Evaluate(r.squaredNorm(), rho);
  ASSERT_LT(rho[1], 0.9);  // the residual is in the linear zone
  EXPECT_LT((H - rho[1] * M.transpose() * M).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((g - rho[1] * M.transpose() * r).cwiseAbs().maxCoeff(), 1e-12);

  // A loss with rho'' > 0 takes the Triggs correction: H = rho' J^T J + 2 rho'' J^T r r^T J, g = rho' J^T r.
  ceres::TolerantLoss tolerant(5.0, 2.0);
  robustSystem(&tolerant, &H, &g, &r, &M);
  tolerant.Evaluate(r.squaredNorm(), rho);
  ASSERT_GT(rho[2], 0.0);
  const Vec2 Jtr = M.transpose() * r;
  EXPECT_LT((H - (rho[1] * M.transpose() * M + 2.0 * rho[2] * Jtr * Jtr.transpose())).cwiseAbs().maxCoeff(),
            1e-10);
  EXPECT_LT((g - rho[1] * Jtr).cwiseAbs().maxCoeff(), 1e-12);

  // No loss: plain Gauss-Newton.
  robustSystem(nullptr, &H, &g, &r, &M);
  EXPECT_LT((H - M.transpose() * M).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Marginaliser, ConstantBlocksAndDisconnectedDrops) {
  std::mt19937 rng(23);
  const LinearProblem lp(rng, {{1, 2}, {2, 2}, {3, 2}}, {{1, 2}, {1, 3}, {3}});
  Marginaliser m;
  for (const auto& [key, values] : lp.x_lin) m.addParameterBlock(key, values.data(), 2, nullptr);
  for (const Term& t : lp.terms) m.addResidual(t.cost, nullptr, t.keys);
  m.setParameterBlockConstant(3);
  auto prior = m.marginalise({1});
  ASSERT_TRUE(prior);
  EXPECT_EQ(prior->keys, (std::vector<BlockKey>{2}));  // block 3 is constant: not in the prior

  Marginaliser lonely;
  const double v[2] = {0.0, 0.0};
  lonely.addParameterBlock(7, v, 2, nullptr);
  EXPECT_EQ(lonely.marginalise({7}), nullptr);  // nothing touches it
}

TEST(Marginaliser, ApiMisuseThrowsUsageError) {
  Marginaliser m;
  const double v[3] = {0.0, 0.0, 0.0};
  EXPECT_FALSE(m.hasParameterBlock(1));
  m.addParameterBlock(1, v, 3, nullptr);
  EXPECT_TRUE(m.hasParameterBlock(1));
  EXPECT_THROW(m.addParameterBlock(1, v, 3, nullptr), UsageError);
  ceres::EuclideanManifold<2> e2;
  EXPECT_THROW(m.addParameterBlock(2, v, 3, &e2), UsageError);
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(3, 3);
  auto cost = std::make_shared<LinearResidual>(std::vector<Eigen::MatrixXd>{A}, Eigen::VectorXd::Zero(3));
  EXPECT_THROW(m.addResidual(cost, nullptr, {5}), UsageError);
  EXPECT_THROW(m.addResidual(cost, nullptr, {1, 1}), UsageError);
  m.addParameterBlock(4, v, 2, nullptr);
  EXPECT_THROW(m.addResidual(cost, nullptr, {4}), UsageError);  // size 2 vs 3
  EXPECT_THROW(m.marginalise({99}), UsageError);
  try {
    m.addResidual(cost, nullptr, {42});
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("key 42"), std::string::npos) << e.what();
  }
}

TEST(Marginaliser, UnobservedScalarIsDroppedAsRankDeficient) {
  // Two scalar landmarks, decoupled from each other (the block-diagonal first stage): x1 seen with the kept k, x2
  // with no information of its own. x2's zero block counts as a rank deficiency and leaves k's information alone.
  Marginaliser m;
  const double x1 = 0.5, x2 = -1.0, k = 2.0;
  m.addParameterBlock(1, &x1, 1, nullptr);
  m.addParameterBlock(2, &x2, 1, nullptr);
  m.addParameterBlock(3, &k, 1, nullptr);
  const Eigen::MatrixXd one = Eigen::MatrixXd::Ones(1, 1), zero = Eigen::MatrixXd::Zero(1, 1);
  m.addResidual(std::make_shared<LinearResidual>(std::vector<Eigen::MatrixXd>{one, one}, Eigen::VectorXd::Zero(1)),
                nullptr, {1, 3});
  m.addResidual(std::make_shared<LinearResidual>(std::vector<Eigen::MatrixXd>{zero, one}, Eigen::VectorXd::Zero(1)),
                nullptr, {2, 3});
  m.addResidual(std::make_shared<LinearResidual>(std::vector<Eigen::MatrixXd>{one}, Eigen::VectorXd::Zero(1)), nullptr,
                {3});
  const auto prior = m.marginalise({1, 2});
  ASSERT_NE(prior, nullptr);
  EXPECT_EQ(m.lastStats().decoupled_blocks, 2);
  EXPECT_EQ(m.lastStats().dropped_rank_deficiency, 1);
  // The prior holds what the dropped blocks' residuals say of k: 1 (x2's residual) + 1 - 1 * 1 / 1 (x1's, with x1
  // eliminated) = 1. k's own residual touches no dropped block and stays out of it.
  ASSERT_EQ(prior->J.rows(), 1);
  EXPECT_NEAR((prior->J.transpose() * prior->J)(0, 0), 1.0, 1e-12);
}

TEST(Marginaliser, SameInputGivesBitIdenticalPrior) {
  std::mt19937 rng(25);
  const LinearProblem lp(rng, {{1, 3}, {2, 3}, {3, 2}, {4, 1}, {5, 1}},
                         {{1, 2}, {1, 3}, {1, 4}, {1, 5}, {2, 3}, {1}});
  auto a = marginaliseTerms(lp.terms, lp.x_lin, {1, 4, 5});
  auto b = marginaliseTerms(lp.terms, lp.x_lin, {1, 4, 5});
  ASSERT_TRUE(a && b);
  ASSERT_EQ(a->J.rows(), b->J.rows());
  EXPECT_EQ(std::memcmp(a->J.data(), b->J.data(), sizeof(double) * static_cast<std::size_t>(a->J.size())), 0);
  EXPECT_EQ(std::memcmp(a->r.data(), b->r.data(), sizeof(double) * static_cast<std::size_t>(a->r.size())), 0);
}

TEST(Marginaliser, OptionsValidate) {
  MarginaliserOptions opt;
  EXPECT_NO_THROW(validateOptions(opt, "marginaliser"));
  opt.eigenvalue_threshold = -1.0;
  EXPECT_THROW(validateOptions(opt, "marginaliser"), ConfigError);
}

}  // namespace
}  // namespace linnet
