// Schur-complement marginalisation into a square-root prior (see marginaliser.h for the method and
// references).
#include "linnet/estimator/marginaliser.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>
#include <string>
#include <utility>

#include <Eigen/Dense>

#include "linnet/core/error.h"
#include "linnet/estimator/factors/tangent_jacobians.h"
#include "linnet/estimator/manifolds.h"

namespace linnet {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

std::string keyName(BlockKey key) { return "parameter block key " + std::to_string(key); }

/// Eigenvalues at or below this count as zero, for a matrix whose largest eigenvalue is `largest` (or a bound on
/// it): the absolute and the relative threshold.
double thresholdFor(double largest, const MarginaliserOptions& o) {
  return std::max(o.eigenvalue_threshold, o.relative_eigenvalue_threshold * largest);
}

/// The same from the eigenvalues (ascending).
double effectiveThreshold(const Eigen::VectorXd& eigenvalues, const MarginaliserOptions& o) {
  return thresholdFor(eigenvalues.size() > 0 ? eigenvalues(eigenvalues.size() - 1) : 0.0, o);
}

/// Symmetric pseudo-inverse through the eigen-decomposition; eigenvalues at or below the effective threshold
/// are treated as zero. `deficiency` receives how many were.
Eigen::MatrixXd symmetricPseudoInverse(const Eigen::MatrixXd& A, const MarginaliserOptions& options,
                                       int* deficiency) {
  const Eigen::MatrixXd S = 0.5 * (A + A.transpose());
  if (S.rows() == 1) {  // a scalar (an inverse depth) is its own eigenvalue: the decomposition below, without its cost
    const double s = S(0, 0);
    const bool kept = s > thresholdFor(s, options);
    if (deficiency != nullptr) *deficiency = kept ? 0 : 1;
    return Eigen::MatrixXd::Constant(1, 1, kept ? 1.0 / s : 0.0);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(S);
  const double threshold = effectiveThreshold(es.eigenvalues(), options);
  Eigen::VectorXd inv = es.eigenvalues();
  int zeros = 0;
  for (Eigen::Index i = 0; i < inv.size(); ++i) {
    if (inv(i) > threshold) {
      inv(i) = 1.0 / inv(i);
    } else {
      inv(i) = 0.0;
      ++zeros;
    }
  }
  if (deficiency != nullptr) *deficiency = zeros;
  return es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose();
}

/// H(ra + i, cb + j) += Ja(0, i) Jb(0, j) + Ja(1, i) Jb(1, j): the product J_a^T J_b of a two-row residual (every
/// point and line residual) without the general product's dispatch, which cost more than these few multiplications.
/// Each entry is summed as Eigen's product sums it (the two terms, then onto H), so H comes out bit for bit the same.
void addTwoRowProduct(const Eigen::MatrixXd& Ja, const Eigen::MatrixXd& Jb, int ra, int cb, Eigen::MatrixXd* H) {
  const Eigen::Index na = Ja.cols(), nb = Jb.cols();
  for (Eigen::Index j = 0; j < nb; ++j) {
    const double b0 = Jb(0, j), b1 = Jb(1, j);
    double* col = &(*H)(ra, cb + j);
    for (Eigen::Index i = 0; i < na; ++i) col[i] += Ja(0, i) * b0 + Ja(1, i) * b1;
  }
}

/// Makes H symmetric from what was summed into it. Between two column ranges of `dense` (offset, size), which residuals
/// of other than two rows reach (IMU, prior), the two entries of a pair may differ: each pair is averaged from its two
/// old values. Everywhere else only the two-row residuals sum, into the upper entry alone (the lower one would take
/// the same products, commuted, in the same order): the lower entry takes its value.
void symmetrise(const std::vector<std::pair<int, int>>& dense, Eigen::MatrixXd* H) {
  const Eigen::Index n = H->rows();
  std::vector<unsigned char> in_dense(static_cast<std::size_t>(n), 0);
  for (const auto& [o, s] : dense) std::fill_n(in_dense.begin() + o, s, 1);
  for (Eigen::Index j = 0; j < n; ++j) {
    const bool dj = in_dense[static_cast<std::size_t>(j)] != 0;
    for (Eigen::Index i = j + 1; i < n; ++i) {
      if (dj && in_dense[static_cast<std::size_t>(i)]) {
        const double v = 0.5 * ((*H)(j, i) + (*H)(i, j));
        (*H)(j, i) = v;
        (*H)(i, j) = v;
      } else {
        (*H)(i, j) = (*H)(j, i);
      }
    }
  }
}

/// Applies the loss function's correction to one residual block (residual r, tangent Jacobians per parameter
/// block, empty for constant blocks), in place. Same algebra as Ceres' trust-region solver (Triggs et al.
/// 2000).
void applyLoss(const ceres::LossFunction& loss, Eigen::VectorXd* r, std::vector<Eigen::MatrixXd>* J) {
  const double sq_norm = r->squaredNorm();
  double rho[3];
  loss.Evaluate(sq_norm, rho);
  const double sqrt_rho1 = std::sqrt(std::max(rho[1], 0.0));
  if (sq_norm == 0.0 || rho[2] <= 0.0) {
    *r *= sqrt_rho1;
    for (Eigen::MatrixXd& Jk : *J) Jk *= sqrt_rho1;
    return;
  }
  const double D = 1.0 + 2.0 * sq_norm * rho[2] / rho[1];
  const double alpha = 1.0 - std::sqrt(D);
  for (Eigen::MatrixXd& Jk : *J) {
    if (Jk.size() == 0) continue;
    const Eigen::RowVectorXd rtJ = r->transpose() * Jk;
    Jk = sqrt_rho1 * (Jk - (alpha / sq_norm) * (*r) * rtJ);
  }
  *r *= sqrt_rho1 / (1.0 - alpha);
}

}  // namespace

std::vector<BlockKey> Marginaliser::orderForElimination(const std::vector<BlockKey>& dropped,
                                                        const std::vector<const Residual*>& used,
                                                        int* num_decoupled) const {
  // The residuals of each dropped block (indexed as `dropped`), as one flat list (counts, offsets, entries): two
  // dropped blocks are coupled when one residual touches both.
  const std::size_t nd = dropped.size();
  std::vector<int> first_of(nd + 1, 0);
  for (const Residual* res : used)
    for (const Block* b : blocksOf(*res))
      if (b->drop_index >= 0) ++first_of[static_cast<std::size_t>(b->drop_index) + 1];
  for (std::size_t i = 1; i <= nd; ++i) first_of[i] += first_of[i - 1];
  std::vector<const Residual*> touching(static_cast<std::size_t>(first_of.back()));
  std::vector<int> filled(first_of.begin(), first_of.end() - 1);
  for (const Residual* res : used)
    for (const Block* b : blocksOf(*res))
      if (b->drop_index >= 0) {
        int& at = filled[static_cast<std::size_t>(b->drop_index)];
        touching[static_cast<std::size_t>(at++)] = res;
      }
  // Greedy independent set, smallest blocks first (stable: ties keep the caller's order). A block coupled to one
  // chosen before it is ruled out.
  std::vector<int> sizes(nd);
  for (std::size_t i = 0; i < nd; ++i) sizes[i] = blocks_.at(dropped[i]).tangent_size;
  std::vector<int> by_size(nd);
  std::iota(by_size.begin(), by_size.end(), 0);
  std::stable_sort(by_size.begin(), by_size.end(), [&](int a, int b) {
    return sizes[static_cast<std::size_t>(a)] < sizes[static_cast<std::size_t>(b)];
  });
  std::vector<BlockKey> first;
  std::vector<unsigned char> chosen(nd, 0);
  for (const int i : by_size) {
    const auto coupled = [&](const Residual* res) {
      return std::ranges::any_of(blocksOf(*res), [&](const Block* b) {
        const int j = b->drop_index;
        return j >= 0 && j != i && chosen[static_cast<std::size_t>(j)];
      });
    };
    if (std::any_of(touching.begin() + first_of[static_cast<std::size_t>(i)],
                    touching.begin() + first_of[static_cast<std::size_t>(i) + 1], coupled))
      continue;
    first.push_back(dropped[static_cast<std::size_t>(i)]);
    chosen[static_cast<std::size_t>(i)] = 1;
  }
  // A single decoupled block gains nothing over the dense stage.
  if (first.size() < 2) {
    *num_decoupled = 0;
    return dropped;
  }
  *num_decoupled = static_cast<int>(first.size());
  for (std::size_t i = 0; i < nd; ++i)
    if (!chosen[i]) first.push_back(dropped[i]);
  return first;
}

Marginaliser::Marginaliser(MarginaliserOptions options) : options_(options) {}

void Marginaliser::addParameterBlock(BlockKey key, const double* values, int ambient_size,
                                     const ceres::Manifold* manifold) {
  if (blocks_.count(key) != 0)
    throw UsageError("Marginaliser::addParameterBlock: " + keyName(key) + " added twice");
  if (values == nullptr || ambient_size <= 0)
    throw UsageError("Marginaliser::addParameterBlock: " + keyName(key) + " has no values or size " +
                     std::to_string(ambient_size));
  if (manifold != nullptr && manifold->AmbientSize() != ambient_size)
    throw UsageError("Marginaliser::addParameterBlock: " + keyName(key) + " has ambient size " +
                     std::to_string(ambient_size) + " but its manifold expects " +
                     std::to_string(manifold->AmbientSize()));
  Block b;
  b.values.assign(values, values + ambient_size);
  b.ambient_size = ambient_size;
  b.tangent_size = manifold != nullptr ? manifold->TangentSize() : ambient_size;
  b.manifold = manifold;
  b.pose = isPoseBlock(ambient_size, manifold);
  b.order = static_cast<int>(blocks_.size());
  blocks_.emplace(key, std::move(b));
}

void Marginaliser::setParameterBlockConstant(BlockKey key) {
  auto it = blocks_.find(key);
  if (it == blocks_.end())
    throw UsageError("Marginaliser::setParameterBlockConstant: unknown " + keyName(key));
  it->second.constant = true;
}

void Marginaliser::addResidual(std::shared_ptr<ceres::CostFunction> cost, ceres::LossFunction* loss,
                               std::span<const BlockKey> keys) {
  if (!cost) throw UsageError("Marginaliser::addResidual: null cost function");
  const std::vector<int32_t>& sizes = cost->parameter_block_sizes();
  if (sizes.size() != keys.size())
    throw UsageError("Marginaliser::addResidual: cost function has " + std::to_string(sizes.size()) +
                     " parameter blocks but " + std::to_string(keys.size()) + " keys were given");
  const std::size_t first = key_store_.size();
  for (std::size_t k = 0; k < keys.size(); ++k) {
    auto it = blocks_.find(keys[k]);
    if (it == blocks_.end() || it->second.ambient_size != sizes[k]) {
      key_store_.resize(first);
      block_store_.resize(first);
      if (it == blocks_.end()) throw UsageError("Marginaliser::addResidual: unknown " + keyName(keys[k]));
      throw UsageError("Marginaliser::addResidual: " + keyName(keys[k]) + " has size " +
                       std::to_string(it->second.ambient_size) + " but the cost function's block " +
                       std::to_string(k) + " has size " + std::to_string(sizes[k]));
    }
    key_store_.push_back(keys[k]);
    block_store_.push_back(&it->second);
  }
  const TangentJacobians* tangent = tangent_of_.of(cost.get());
  residuals_.push_back(Residual{std::move(cost), loss, first, keys.size(), tangent});
}

std::shared_ptr<const MarginalizationPrior> Marginaliser::marginalise(const std::vector<BlockKey>& drop) {
  stats_ = MarginalisationStats{};
  for (auto& [key, block] : blocks_) {
    block.drop_index = -1;
    block.offset = -1;
  }
  // Dropped blocks (in the order given, duplicates ignored) come first in the linear system.
  std::vector<BlockKey> dropped;
  for (BlockKey key : drop) {
    auto it = blocks_.find(key);
    if (it == blocks_.end()) throw UsageError("Marginaliser::marginalise: unknown " + keyName(key));
    if (it->second.constant) continue;  // a constant block has no columns to eliminate
    if (it->second.drop_index >= 0) continue;
    it->second.drop_index = static_cast<int>(dropped.size());
    dropped.push_back(key);
  }

  // Residuals touching a dropped block, and the kept blocks they reach (registration order).
  std::vector<const Residual*> used;
  std::set<BlockKey> kept_set;
  for (const Residual& res : residuals_) {
    const std::span<Block* const> blocks = blocksOf(res);
    if (!std::ranges::any_of(blocks, [](const Block* b) { return b->drop_index >= 0; })) continue;
    used.push_back(&res);
    for (std::size_t k = 0; k < blocks.size(); ++k)
      if (blocks[k]->drop_index < 0 && !blocks[k]->constant) kept_set.insert(keysOf(res)[k]);
  }
  if (used.empty()) return nullptr;
  // Two-stage elimination: first a set of dropped blocks with no residual between any two of them (typically
  // the inverse depths hosted by the dropped frame), whose H block is block-diagonal and cheap to invert;
  // then the rest of the dropped blocks densely. In exact arithmetic this is the same Schur complement as one
  // joint elimination.
  dropped = orderForElimination(dropped, used, &stats_.decoupled_blocks);
  std::vector<BlockKey> kept(kept_set.begin(), kept_set.end());
  std::sort(kept.begin(), kept.end(),
            [&](BlockKey a, BlockKey b) { return blocks_.at(a).order < blocks_.at(b).order; });

  // Column offsets in the joint system [dropped | kept].
  int m = 0;
  for (BlockKey k : dropped) {
    Block& b = blocks_.at(k);
    b.offset = m;
    m += b.tangent_size;
  }
  int n = 0;
  for (BlockKey k : kept) {
    Block& b = blocks_.at(k);
    b.offset = m + n;
    n += b.tangent_size;
  }
  const int total = m + n;

  // Accumulate H = sum J^T J and g = sum J^T r (tangent space, loss-corrected).
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(total, total);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(total);
  // Scratch reused across residuals (a marginalisation linearises a few thousand).
  std::vector<const double*> params;
  std::vector<RowMatrix> jac_amb;
  std::vector<double*> jac_ptr;
  std::vector<Eigen::MatrixXd> J;
  RowMatrix plus;
  Eigen::VectorXd r;
  // The column ranges (offset, size) of the blocks that residuals of other than two rows reach (IMU, prior): only
  // between those can H come out unsymmetric (addTwoRowProduct's mirror entries are the same products).
  std::vector<std::pair<int, int>> dense;
  for (auto& [key, block] : blocks_) block.dense = false;
  for (const Residual* res : used) {
    if (res->cost->num_residuals() == 2) continue;
    for (Block* b : blocksOf(*res))
      if (!b->constant && !b->dense) {
        b->dense = true;
        dense.emplace_back(b->offset, b->tangent_size);
      }
  }
  for (const Residual* res : used) {
    const int nr = res->cost->num_residuals();
    const std::span<const BlockKey> keys = keysOf(*res);
    const std::span<Block* const> blocks = blocksOf(*res);
    const std::size_t nb = keys.size();
    params.assign(nb, nullptr);
    jac_amb.resize(nb);
    jac_ptr.assign(nb, nullptr);
    // A TangentJacobians factor gives its pose blocks' Jacobians in the tangent space: they are used as they come
    // (Ceres' ambient ones would be converted there and back).
    const auto tangentGiven = [&](const Block& b) { return res->tangent != nullptr && b.pose; };
    for (std::size_t k = 0; k < nb; ++k) {
      const Block& b = *blocks[k];
      params[k] = b.values.data();
      if (!b.constant) {
        jac_amb[k].resize(nr, tangentGiven(b) ? b.tangent_size : b.ambient_size);
        jac_ptr[k] = jac_amb[k].data();
      }
    }
    r.resize(nr);
    const bool evaluated = res->tangent != nullptr
                               ? res->tangent->evaluateTangentSpace(params.data(), r.data(), jac_ptr.data())
                               : res->cost->Evaluate(params.data(), r.data(), jac_ptr.data());
    if (!evaluated)
      throw InputError("Marginaliser::marginalise: a cost function over " + keyName(keys.front()) +
                       " failed to evaluate at the linearisation point");
    // Tangent Jacobian per non-constant block.
    J.resize(nb);
    bool finite = r.allFinite();
    for (std::size_t k = 0; k < nb; ++k) {
      const Block& b = *blocks[k];
      if (b.constant) {
        J[k].resize(0, 0);
        continue;
      }
      if (b.manifold == nullptr || tangentGiven(b)) {
        J[k] = jac_amb[k];
      } else {
        plus.resize(b.ambient_size, b.tangent_size);
        if (!b.manifold->PlusJacobian(b.values.data(), plus.data()))
          throw InputError("Marginaliser::marginalise: PlusJacobian failed for " + keyName(keys[k]));
        J[k].noalias() = jac_amb[k] * plus;
      }
      finite = finite && J[k].allFinite();
    }
    if (!finite)
      throw InputError("Marginaliser::marginalise: non-finite residual or Jacobian over " +
                       keyName(keys.front()));
    if (res->loss != nullptr) applyLoss(*res->loss, &r, &J);
    // Block-wise accumulation: only the touched blocks of H and g change. A two-row residual fills the lower block
    // of two blocks that are not both dense by symmetrise below.
    for (std::size_t a = 0; a < nb; ++a) {
      if (J[a].size() == 0) continue;
      const int oa = blocks[a]->offset;
      if (nr == 2)  // as Eigen's product sums it (the two terms, then onto g), without its dispatch
        for (Eigen::Index i = 0; i < J[a].cols(); ++i) g(oa + i) += J[a](0, i) * r(0) + J[a](1, i) * r(1);
      else
        g.segment(oa, J[a].cols()).noalias() += J[a].transpose() * r;
      for (std::size_t b = 0; b < nb; ++b) {
        if (J[b].size() == 0) continue;
        const int ob = blocks[b]->offset;
        if (nr != 2)
          H.block(oa, ob, J[a].cols(), J[b].cols()).noalias() += J[a].transpose() * J[b];
        else if (oa <= ob || (blocks[a]->dense && blocks[b]->dense))
          addTwoRowProduct(J[a], J[b], oa, ob, &H);
      }
    }
  }
  symmetrise(dense, &H);

  // Stage 1: the decoupled blocks (H_PP block-diagonal).
  int deficiency = 0, m1 = 0;
  std::vector<int> p_sizes;
  for (int i = 0; i < stats_.decoupled_blocks; ++i) {
    p_sizes.push_back(blocks_.at(dropped[static_cast<std::size_t>(i)]).tangent_size);
    m1 += p_sizes.back();
  }
  if (m1 > 0) {
    const int rest = total - m1;
    Eigen::MatrixXd X(rest, m1);  // H_RP H_PP^+
    Eigen::VectorXd y(m1);        // H_PP^+ g_P
    for (int i = 0, o = 0; i < static_cast<int>(p_sizes.size());
         o += p_sizes[static_cast<std::size_t>(i)], ++i) {
      const int t = p_sizes[static_cast<std::size_t>(i)];
      int def = 0;
      const Eigen::MatrixXd inv = symmetricPseudoInverse(H.block(o, o, t, t), options_, &def);
      deficiency += def;
      X.middleCols(o, t).noalias() = H.block(m1, o, rest, t) * inv;
      y.segment(o, t).noalias() = inv * g.segment(o, t);
    }
    Eigen::MatrixXd H_rest = H.bottomRightCorner(rest, rest);
    H_rest.noalias() -= X * H.topRightCorner(m1, rest);
    Eigen::VectorXd g_rest = g.tail(rest);
    g_rest.noalias() -= H.bottomLeftCorner(rest, m1) * y;
    H = 0.5 * (H_rest + H_rest.transpose());
    g = g_rest;
  }
  // Stage 2: H* = H_rr - H_rm H_mm^+ H_mr, g* = g_r - H_rm H_mm^+ g_m over the remaining dropped blocks.
  const int m2 = m - m1;
  int def2 = 0;
  // (Empty when the first stage took every dropped block: Eigen's eigen-solver does not take a 0 x 0 matrix.)
  const Eigen::MatrixXd Hmm_inv =
      m2 > 0 ? symmetricPseudoInverse(H.topLeftCorner(m2, m2), options_, &def2) : Eigen::MatrixXd(0, 0);
  deficiency += def2;
  const Eigen::MatrixXd Hrm_Hmm_inv = H.bottomLeftCorner(n, m2) * Hmm_inv;
  Eigen::MatrixXd H_star = H.bottomRightCorner(n, n) - Hrm_Hmm_inv * H.topRightCorner(m2, n);
  const Eigen::VectorXd g_star = g.tail(n) - Hrm_Hmm_inv * g.head(m2);
  H_star = (0.5 * (H_star + H_star.transpose())).eval();  // evaluated first: the sum reads H_star's transpose

  stats_.residuals_used = static_cast<int>(used.size());
  stats_.dropped_size = m;
  stats_.kept_size = n;
  stats_.dropped_rank_deficiency = deficiency;
  if (n == 0) return nullptr;

  auto prior = std::make_shared<MarginalizationPrior>();
  // The usual case, a prior of full rank: H* = L L^T -> J = L^T, r = L^-1 g* (J^T J = H*, J^T r = g*), the same
  // prior as the eigen-decomposition's below with every eigenvalue kept, at a fraction of the cost. Taken only when
  // the decomposition would keep every eigenvalue for certain: lambda_min >= 1 / trace(H*^-1) = 1 / |L^-1|_F^2 and
  // lambda_max <= trace(H*) bound the two sides of the threshold test.
  const Eigen::LLT<Eigen::MatrixXd> llt(H_star);
  if (llt.info() == Eigen::Success) {
    const Eigen::MatrixXd L_inv =
        llt.matrixL().solve(Eigen::MatrixXd::Identity(n, n));  // lower triangular, as L
    const double lambda_min_bound = 1.0 / L_inv.squaredNorm();
    const double bound = thresholdFor(H_star.trace(), options_);
    if (std::isfinite(lambda_min_bound) && lambda_min_bound > bound) {
      stats_.prior_rank = n;
      prior->J = llt.matrixU();
      prior->r.noalias() = L_inv * g_star;
    }
  }
  if (prior->J.size() == 0) {
    // H* = V S V^T  ->  J = sqrt(S) V^T, r = sqrt(S)^-1 V^T g*, keeping eigenvalues above the threshold.
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(H_star);
    std::vector<int> keep;
    const double threshold = effectiveThreshold(es.eigenvalues(), options_);
    for (int i = 0; i < n; ++i)
      if (es.eigenvalues()(i) > threshold) keep.push_back(i);
    stats_.prior_rank = static_cast<int>(keep.size());
    if (keep.empty()) return nullptr;
    prior->J.resize(static_cast<Eigen::Index>(keep.size()), n);
    prior->r.resize(static_cast<Eigen::Index>(keep.size()));
    for (std::size_t row = 0; row < keep.size(); ++row) {
      const double s = es.eigenvalues()(keep[row]);
      const auto v = es.eigenvectors().col(keep[row]);
      prior->J.row(static_cast<Eigen::Index>(row)) = std::sqrt(s) * v.transpose();
      prior->r(static_cast<Eigen::Index>(row)) = v.dot(g_star) / std::sqrt(s);
    }
  }
  prior->dropped_tangent_size = m;
  for (BlockKey k : kept) {
    const Block& b = blocks_.at(k);
    prior->keys.push_back(k);
    prior->ambient_sizes.push_back(b.ambient_size);
    prior->tangent_sizes.push_back(b.tangent_size);
    prior->tangent_offsets.push_back(b.offset - m);
    prior->x0.push_back(b.values);
    prior->manifolds.push_back(b.manifold);
  }
  return prior;
}

}  // namespace linnet
