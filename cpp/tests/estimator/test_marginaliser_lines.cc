// Marginaliser with line blocks (LineManifold, 4-D tangent) next to poses (PoseManifold) and inverse depths: the
// prior's information H* = J^T J and gradient must equal the Schur complement of the full system assembled here
// from the factors' tangent Jacobians; and, marginalising at the batch optimum, the reduced problem (prior plus the
// remaining residuals) keeps the batch solution of the kept blocks, including a line kept in the prior.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include <ceres/autodiff_cost_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>
#include <Eigen/Dense>

#include "linnet/estimator/factors/line_factor.h"
#include "linnet/estimator/factors/point_factors.h"
#include "linnet/estimator/factors/prior_factor.h"
#include "estimator/pose_prior_cost.h"
#include "linnet/estimator/manifolds.h"
#include "linnet/estimator/marginaliser.h"
#include "linnet/estimator/residual_spec.h"
#include "linnet/estimator/window.h"
#include "linnet/geometry/plucker.h"

namespace linnet {
namespace {

using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

using testing::PosePrior;

struct Term {
  std::shared_ptr<ceres::CostFunction> cost;
  std::vector<BlockKey> keys;
};

BlockKey poseKey(int i) { return frameBlockKey(i, BlockKind::kPose); }

// Three stereo frames; line 1 (to drop) and line 2 (kept) seen in cam0 and cam1 of every frame; 8 points hosted in
// frame 0 (dropped with it) or frame 1 and seen in the other frames; a prior on frame 0. Small observation noise,
// starting values slightly off the truth.
struct Scene {
  PoseManifold pose_manifold;
  LineManifold line_manifold;
  std::map<BlockKey, std::vector<double>> x;
  std::map<BlockKey, const ceres::Manifold*> manifold;
  std::vector<BlockKey> order;  // registration order
  std::vector<Term> terms;
  std::vector<BlockKey> drop;

  void add(BlockKey key, const double* v, int size, const ceres::Manifold* m) {
    x[key].assign(v, v + size);
    manifold[key] = m;
    order.push_back(key);
  }

  explicit Scene(unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    std::normal_distribution<double> N(0.0, 1.0);
    const double f = 460.0, sqrt_info = f / 1.5, noise = 0.3 / f;
    const Pose T_B_C0(expSO3(Vec3(0.01, -0.02, 0.015)), Vec3(-0.02, -0.06, 0.01));
    const Pose cams[2] = {T_B_C0, T_B_C0 * Pose(Quat::Identity(), Vec3(0.11, 0.0, 0.0))};
    const auto project = [&](const Pose& T_W_B, const Pose& T_B_C, const Vec3& p_W) {
      const Vec3 p = (T_W_B * T_B_C).inverse() * p_W;
      return Vec2(p.head<2>() / p.z() + noise * Vec2(N(rng), N(rng)));
    };
    std::vector<Pose> truth;
    for (int i = 0; i < 3; ++i) {
      truth.emplace_back(expSO3(Vec3(0.01 * U(rng), 0.05 * i, 0.01 * U(rng))),
                         Vec3(0.3 * i, 0.05 * U(rng), 0.05 * i));
      double b[7];
      setPose(Pose(truth.back().q * expSO3(0.005 * Vec3(U(rng), U(rng), U(rng))),
                   truth.back().p + 0.01 * Vec3(U(rng), U(rng), U(rng))),
              b);
      add(poseKey(i), b, 7, &pose_manifold);
    }
    drop.push_back(poseKey(0));
    for (int id = 1; id <= 2; ++id) {
      const Vec3 mid(U(rng), 0.5 * U(rng), 4.0 + U(rng));
      const Vec3 half(0.5 * U(rng), 0.8 + 0.2 * U(rng), 0.3 * U(rng));
      const Vec6 L = normalisePlucker(pluckerFromPoints(mid - half, mid + half));
      const double delta[4] = {0.005 * U(rng), 0.005 * U(rng), 0.005 * U(rng), 0.005 * U(rng)};
      double b[6];
      line_manifold.Plus(L.data(), delta, b);
      add(lineBlockKey(id), b, 6, &line_manifold);
      for (int j = 0; j < 3; ++j)
        for (const Pose& T_B_C : cams)
          terms.push_back({std::make_shared<LineReprojectionFactor>(project(truth[j], T_B_C, mid - half),
                                                                    project(truth[j], T_B_C, mid + half), T_B_C,
                                                                    sqrt_info),
                           {poseKey(j), lineBlockKey(id)}});
    }
    drop.push_back(lineBlockKey(1));
    for (int id = 0; id < 8; ++id) {
      const int host = id % 2;
      const Vec3 p_C(0.8 * U(rng), 0.6 * U(rng), 4.0 + 1.5 * U(rng));
      const Vec3 p_W = truth[host] * (T_B_C0 * p_C);
      const double rho = (1.0 / p_C.z()) * (1.0 + 0.02 * U(rng));
      add(pointBlockKey(id), &rho, 1, nullptr);
      if (host == 0) drop.push_back(pointBlockKey(id));
      const Vec2 uv_host = project(truth[host], T_B_C0, p_W);
      for (int j = 0; j < 3; ++j) {
        if (j == host) continue;
        for (const Pose& T_B_C : cams)
          terms.push_back({std::make_shared<PointReprojectionFactor>(uv_host, project(truth[j], T_B_C, p_W), T_B_C0,
                                                                     T_B_C, sqrt_info),
                           {poseKey(host), poseKey(j), pointBlockKey(id)}});
      }
    }
    using PriorCost = ceres::AutoDiffCostFunction<PosePrior, 6, 7>;
    terms.push_back({std::make_shared<PriorCost>(new PosePrior(truth[0], 100.0)), {poseKey(0)}});
  }

  bool dropped(BlockKey k) const { return std::find(drop.begin(), drop.end(), k) != drop.end(); }
  bool touchesDrop(const Term& t) const {
    return std::any_of(t.keys.begin(), t.keys.end(), [&](BlockKey k) { return dropped(k); });
  }
  int tangent(BlockKey k) const { return manifold.at(k) != nullptr ? manifold.at(k)->TangentSize() : 1; }

  /// H = sum J^T J, g = sum J^T r over `terms` (tangent space), block columns at `offset`.
  void normalEquations(const std::vector<Term>& ts, const std::map<BlockKey, int>& offset, int n, Eigen::MatrixXd* H,
                       Eigen::VectorXd* g) const {
    *H = Eigen::MatrixXd::Zero(n, n);
    *g = Eigen::VectorXd::Zero(n);
    for (const Term& t : ts) {
      const int nr = t.cost->num_residuals();
      std::vector<const double*> params;
      std::vector<RowMajor> jac;
      std::vector<double*> jac_ptr;
      for (BlockKey k : t.keys) {
        params.push_back(x.at(k).data());
        jac.emplace_back(nr, static_cast<int>(x.at(k).size()));
      }
      for (RowMajor& j : jac) jac_ptr.push_back(j.data());
      Eigen::VectorXd r(nr);
      ASSERT_TRUE(t.cost->Evaluate(params.data(), r.data(), jac_ptr.data()));
      Eigen::MatrixXd J = Eigen::MatrixXd::Zero(nr, n);
      for (std::size_t i = 0; i < t.keys.size(); ++i) {
        const ceres::Manifold* m = manifold.at(t.keys[i]);
        RowMajor plus = RowMajor::Identity(jac[i].cols(), tangent(t.keys[i]));
        if (m != nullptr) m->PlusJacobian(params[i], plus.data());
        J.middleCols(offset.at(t.keys[i]), plus.cols()) += jac[i] * plus;
      }
      *H += J.transpose() * J;
      *g += J.transpose() * r;
    }
  }

  std::shared_ptr<const MarginalizationPrior> marginalise(MarginalisationStats* stats) const {
    Marginaliser m;
    for (BlockKey k : order)
      m.addParameterBlock(k, x.at(k).data(), static_cast<int>(x.at(k).size()), manifold.at(k));
    for (const Term& t : terms) m.addResidual(t.cost, nullptr, t.keys);
    auto prior = m.marginalise(drop);
    *stats = m.lastStats();
    return prior;
  }

  /// Ceres over the blocks `ts` touch, from the current values, to convergence.
  void solve(const std::vector<Term>& ts) {
    ceres::Problem::Options po;
    po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;  // the terms own them
    ceres::Problem problem(po);
    for (const Term& t : ts) {
      std::vector<double*> blocks;
      for (BlockKey k : t.keys) {
        double* data = x.at(k).data();
        if (!problem.HasParameterBlock(data))
          problem.AddParameterBlock(data, static_cast<int>(x.at(k).size()),
                                    const_cast<ceres::Manifold*>(manifold.at(k)));
        blocks.push_back(data);
      }
      problem.AddResidualBlock(t.cost.get(), nullptr, blocks);
    }
    ceres::Solver::Options o;
    o.linear_solver_type = ceres::DENSE_QR;
    o.max_num_iterations = 100;
    o.function_tolerance = o.gradient_tolerance = o.parameter_tolerance = 1e-16;
    ceres::Solver::Summary s;
    ceres::Solve(o, &problem, &s);
    ASSERT_TRUE(s.IsSolutionUsable()) << s.BriefReport();
  }
};

TEST(MarginaliserLines, PriorIsTheSchurComplementOfTheFullSystem) {
  Scene sc(31);
  MarginalisationStats stats;
  const auto prior = sc.marginalise(&stats);
  ASSERT_TRUE(prior);
  // The line and the points hosted in frame 0 share no residual: block-diagonal first stage.
  EXPECT_EQ(stats.decoupled_blocks, 4 + 1);
  EXPECT_EQ(stats.dropped_size, 6 + 4 + 4);
  // Kept blocks touched by the dropped ones, in registration order: frames 1 and 2, line 2, points of frame 1.
  std::vector<BlockKey> expected_keys = {poseKey(1), poseKey(2), lineBlockKey(2)};
  for (int id = 1; id < 8; id += 2) expected_keys.push_back(pointBlockKey(id));
  EXPECT_EQ(prior->keys, expected_keys);
  EXPECT_EQ(prior->tangent_sizes[2], 4);
  EXPECT_EQ(prior->J.rows(), prior->J.cols());  // full rank

  // Full system over [dropped | kept] from every residual.
  std::map<BlockKey, int> offset;
  int m = 0;
  for (BlockKey k : sc.order) {
    if (!sc.dropped(k)) continue;
    offset[k] = m;
    m += sc.tangent(k);
  }
  int n = 0;
  for (BlockKey k : sc.order) {
    if (sc.dropped(k)) continue;
    offset[k] = m + n;
    n += sc.tangent(k);
  }
  Eigen::MatrixXd H, H_rest;
  Eigen::VectorXd g, g_rest;
  sc.normalEquations(sc.terms, offset, m + n, &H, &g);
  std::vector<Term> rest;
  for (const Term& t : sc.terms)
    if (!sc.touchesDrop(t)) rest.push_back(t);
  sc.normalEquations(rest, offset, m + n, &H_rest, &g_rest);
  const Eigen::MatrixXd Hdd_inv = H.topLeftCorner(m, m).inverse();
  const Eigen::MatrixXd S =
      H.bottomRightCorner(n, n) - H.bottomLeftCorner(n, m) * Hdd_inv * H.topRightCorner(m, n);
  const Eigen::VectorXd gS = g.tail(n) - H.bottomLeftCorner(n, m) * Hdd_inv * g.head(m);

  // The prior, placed in the kept layout, plus the residuals that do not touch a dropped block.
  Eigen::MatrixXd J_kept = Eigen::MatrixXd::Zero(prior->J.rows(), n);
  for (std::size_t i = 0; i < prior->keys.size(); ++i)
    J_kept.middleCols(offset.at(prior->keys[i]) - m, prior->tangent_sizes[i]) =
        prior->J.middleCols(prior->tangent_offsets[i], prior->tangent_sizes[i]);
  const Eigen::MatrixXd H_red = J_kept.transpose() * J_kept + H_rest.bottomRightCorner(n, n);
  const Eigen::VectorXd g_red = J_kept.transpose() * prior->r + g_rest.tail(n);
  EXPECT_LT((H_red - S).cwiseAbs().maxCoeff(), 1e-8 * S.cwiseAbs().maxCoeff())
      << (H_red - S).cwiseAbs().maxCoeff() << " of " << S.cwiseAbs().maxCoeff();
  EXPECT_LT((g_red - gS).cwiseAbs().maxCoeff(), 1e-8 * g.cwiseAbs().maxCoeff())
      << (g_red - gS).cwiseAbs().maxCoeff() << " of " << g.cwiseAbs().maxCoeff();
}

// A factor seen only through ceres::CostFunction::Evaluate (ambient pose Jacobians): the marginaliser's plain path.
class AmbientOnly final : public ceres::CostFunction {
 public:
  explicit AmbientOnly(std::shared_ptr<ceres::CostFunction> inner) : inner_(std::move(inner)) {
    set_num_residuals(inner_->num_residuals());
    *mutable_parameter_block_sizes() = inner_->parameter_block_sizes();
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    return inner_->Evaluate(parameters, residuals, jacobians);
  }

 private:
  std::shared_ptr<ceres::CostFunction> inner_;
};

TEST(MarginaliserLines, TangentJacobiansGiveThePriorOfTheAmbientPath) {
  // The visual factors hand the marginaliser their pose Jacobians in the tangent space; the same factors behind
  // Ceres' ambient interface (converted there and back through PlusJacobian) must give the same prior.
  for (unsigned seed : {33u, 34u}) {
    Scene tangent(seed), ambient(seed);
    for (Term& t : ambient.terms) t.cost = std::make_shared<AmbientOnly>(t.cost);
    MarginalisationStats st, sa;
    const auto pt = tangent.marginalise(&st);
    const auto pa = ambient.marginalise(&sa);
    ASSERT_TRUE(pt && pa);
    ASSERT_EQ(pt->keys, pa->keys);
    const Eigen::MatrixXd Ht = pt->J.transpose() * pt->J, Ha = pa->J.transpose() * pa->J;
    const Eigen::VectorXd gt = pt->J.transpose() * pt->r, ga = pa->J.transpose() * pa->r;
    EXPECT_LT((Ht - Ha).cwiseAbs().maxCoeff(), 1e-9 * Ha.cwiseAbs().maxCoeff()) << "seed " << seed;
    EXPECT_LT((gt - ga).cwiseAbs().maxCoeff(), 1e-9 * ga.cwiseAbs().maxCoeff()) << "seed " << seed;
  }
}

TEST(MarginaliserLines, ReducedProblemKeepsTheBatchMinimum) {
  Scene sc(32);
  sc.solve(sc.terms);  // the batch optimum x*
  const std::map<BlockKey, std::vector<double>> x_star = sc.x;
  MarginalisationStats stats;
  const auto prior = sc.marginalise(&stats);  // linearised at x*
  ASSERT_TRUE(prior);
  ASSERT_NE(prior->indexOf(lineBlockKey(2)), -1);
  // Reduced problem: the prior and the residuals that do not touch a dropped block, from a perturbed start.
  std::vector<Term> reduced = {{std::make_shared<PriorFactor>(prior), prior->keys}};
  for (const Term& t : sc.terms)
    if (!sc.touchesDrop(t)) reduced.push_back(t);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (auto& [k, v] : sc.x) {
    if (sc.dropped(k)) continue;
    std::vector<double> delta(static_cast<std::size_t>(sc.tangent(k)));
    for (double& d : delta) d = 0.01 * U(rng);
    std::vector<double> out(v.size());
    if (sc.manifold.at(k) != nullptr) {
      sc.manifold.at(k)->Plus(v.data(), delta.data(), out.data());
      v = out;
    } else {
      v[0] += delta[0];
    }
  }
  sc.solve(reduced);
  // Tolerance: the prior's Jacobian for the line block is a central difference of LineManifold (prior_factor.h).
  for (const auto& [k, v] : sc.x) {
    if (sc.dropped(k)) continue;
    std::vector<double> diff(static_cast<std::size_t>(sc.tangent(k)));
    if (sc.manifold.at(k) != nullptr)
      sc.manifold.at(k)->Minus(v.data(), x_star.at(k).data(), diff.data());
    else
      diff[0] = v[0] - x_star.at(k)[0];
    EXPECT_LT(Eigen::Map<Eigen::VectorXd>(diff.data(), static_cast<Eigen::Index>(diff.size())).norm(), 1e-7)
        << "block " << k;
  }
}

}  // namespace
}  // namespace linnet
