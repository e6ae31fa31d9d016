// Levenberg-Marquardt with Schur elimination of the landmark blocks (see schur_lm_solver.h).
#include "linnet/estimator/schur_lm_solver.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "linnet/core/error.h"
#include "linnet/estimator/manifolds.h"

namespace linnet {

namespace {

using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Fixed-size kernels for the common residual: 2 rows (a point observation) over pose (tangent 6) and inverse-depth
// (1) blocks. Jacobians are row-major R x C; single columns are stored the same either way.
template <int R, int C>
using RowMat = Eigen::Matrix<double, R, C, (C == 1 && R != 1) ? Eigen::ColMajor : Eigen::RowMajor>;
using Stride = Eigen::OuterStride<>;

// dst (A x B, column-major with leading dimension ld) += Ja^T Jb.
template <int R, int A, int B>
void addJtJ(double* dst, Eigen::Index ld, const double* Ja, const double* Jb) {
  Eigen::Map<Eigen::Matrix<double, A, B>, 0, Stride> D(dst, Stride(ld));
  D.noalias() += Eigen::Map<const RowMat<R, A>>(Ja).transpose() * Eigen::Map<const RowMat<R, B>>(Jb);
}

// The fixed-size dispatch for 2-row residuals (points: pose 6 / inverse depth 1; lines: pose 6 / line 4); false if
// the sizes have no kernel.
bool addJtJFixed(int rows, int ta, int tb, double* dst, Eigen::Index ld, const double* Ja, const double* Jb) {
  if (rows != 2) return false;
  if (ta == 4 && tb == 4) {
    addJtJ<2, 4, 4>(dst, ld, Ja, Jb);
  } else if (ta == 4 && tb == 6) {
    addJtJ<2, 4, 6>(dst, ld, Ja, Jb);
  } else if (ta == 4 && tb == 1) {
    addJtJ<2, 4, 1>(dst, ld, Ja, Jb);
  } else if (ta == 6 && tb == 6) {
    addJtJ<2, 6, 6>(dst, ld, Ja, Jb);
  } else if (ta == 1 && tb == 6) {
    addJtJ<2, 1, 6>(dst, ld, Ja, Jb);
  } else if (ta == 1 && tb == 1) {
    addJtJ<2, 1, 1>(dst, ld, Ja, Jb);
  } else if (ta == 6 && tb == 1) {
    addJtJ<2, 6, 1>(dst, ld, Ja, Jb);
  } else {
    return false;
  }
  return true;
}

// One residual (and the Jacobians `jac` asks for; tangent ones for poses when the factor gives them) and its loss:
// rho as ceres::LossFunction::Evaluate gives it (rho = {s, 1, 0} without a loss). False if the evaluation fails or a
// residual is not finite.
bool evaluateResidual(const ceres::CostFunction* cost, const TangentJacobians* tangent, const ceres::LossFunction* loss,
                      int rows, const double* const* params, double* r, double** jac, double rho[3]) {
  const bool ok = tangent != nullptr ? tangent->evaluateTangentSpace(params, r, jac) : cost->Evaluate(params, r, jac);
  const Eigen::Map<const Eigen::VectorXd> res(r, rows);
  if (!ok || !res.allFinite()) return false;
  const double s = res.squaredNorm();
  rho[0] = s;
  rho[1] = 1.0;
  rho[2] = 0.0;
  if (loss != nullptr) loss->Evaluate(s, rho);
  return true;
}

}  // namespace

void SchurLmSolver::addParameterBlock(double* data, int ambient_size, const ceres::Manifold* manifold,
                                      bool eliminate) {
  if (data == nullptr || ambient_size <= 0) throw UsageError("SchurLmSolver: a parameter block needs data and a size");
  if (manifold != nullptr && manifold->AmbientSize() != ambient_size)
    throw UsageError("SchurLmSolver: the manifold's ambient size differs from the block's");
  if (!index_.insert(data, static_cast<int>(blocks_.size())))
    throw UsageError("SchurLmSolver: a parameter block was added twice");
  Block b;
  b.data = data;
  b.ambient = ambient_size;
  b.tangent = manifold != nullptr ? manifold->TangentSize() : ambient_size;
  b.manifold = manifold;
  b.eliminate = eliminate;
  b.pose = isPoseBlock(ambient_size, manifold);
  b.offset = -1;
  blocks_.push_back(b);
  prepared_ = false;
}

void SchurLmSolver::addConstantBlock(double* data, int ambient_size) {
  addParameterBlock(data, ambient_size, nullptr, false);
  Block& b = blocks_.back();
  b.constant = true;
  b.tangent = 0;
}

void SchurLmSolver::addResidual(const ceres::CostFunction* cost, const ceres::LossFunction* loss,
                                std::span<double* const> blocks) {
  const std::vector<int32_t>& sizes = cost->parameter_block_sizes();
  if (sizes.size() != blocks.size())
    throw UsageError("SchurLmSolver: a residual got " + std::to_string(blocks.size()) + " blocks, its cost function " +
                     std::to_string(sizes.size()));
  Residual r;
  r.cost = cost;
  r.loss = loss;
  r.tangent = tangent_of_.of(cost);
  r.rows = cost->num_residuals();
  r.first = static_cast<int>(res_blocks_.size());
  r.count = static_cast<int>(blocks.size());
  const auto fail = [&](const char* what) {
    res_blocks_.resize(static_cast<std::size_t>(r.first));  // nothing of a rejected residual stays
    throw UsageError(std::string("SchurLmSolver: ") + what);
  };
  int eliminated = 0;
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const int index = index_.find(blocks[k]);
    if (index < 0) fail("a residual uses an unregistered parameter block");
    const Block& b = blocks_[static_cast<std::size_t>(index)];
    if (b.ambient != sizes[k]) fail("a residual's block size differs from the block's");
    if (b.eliminate && ++eliminated > 1) fail("a residual joins two eliminated blocks");
    res_blocks_.push_back(index);
  }
  residuals_.push_back(r);
  prepared_ = false;
}

void SchurLmSolver::prepare() {
  if (prepared_) return;
  reduced_size_ = 0;
  eliminated_size_ = 0;
  landmarks_.clear();
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    Block& b = blocks_[i];
    if (b.eliminate) {
      b.offset = static_cast<int>(landmarks_.size());
      Landmark lm;
      lm.block = static_cast<int>(i);
      lm.size = b.tangent;
      lm.offset = eliminated_size_;
      eliminated_size_ += b.tangent;
      landmarks_.push_back(lm);
    } else if (b.constant) {
      b.offset = -1;
    } else {
      b.offset = reduced_size_;
      reduced_size_ += b.tangent;
    }
  }
  // Each landmark's kept list gets room for every kept block its residuals name (an upper bound), then is filled in
  // residual order without repeats, as the slots are assigned.
  std::size_t arena = 0, max_count = 0;
  for (Residual& r : residuals_) {
    max_count = std::max(max_count, static_cast<std::size_t>(r.count));
    r.arena = arena;
    arena += static_cast<std::size_t>(r.rows);
    r.landmark = -1;
    for (int k = 0; k < r.count; ++k) {
      const Block& b = blocks_[static_cast<std::size_t>(res_blocks_[static_cast<std::size_t>(r.first + k)])];
      arena += static_cast<std::size_t>(r.rows) * static_cast<std::size_t>(b.ambient + b.tangent);
      if (b.eliminate) {
        r.landmark = b.offset;
        r.landmark_pos = k;
      }
    }
    if (r.landmark >= 0) {
      Landmark& lm = landmarks_[static_cast<std::size_t>(r.landmark)];
      lm.kept_count += r.count - 1;
      ++lm.res_count;
    }
  }
  // The flat lists' offsets (kept blocks and residuals of each landmark); the counts are refilled below.
  int kept_total = 0, res_total = 0;
  for (Landmark& lm : landmarks_) {
    lm.kept_first = kept_total;
    kept_total += lm.kept_count;
    lm.kept_count = 0;
    lm.res_first = res_total;
    res_total += lm.res_count;
    lm.res_count = 0;
  }
  // Each landmark's residuals, in residual order.
  lm_residuals_.assign(static_cast<std::size_t>(res_total), -1);
  for (std::size_t i = 0; i < residuals_.size(); ++i) {
    if (residuals_[i].landmark < 0) continue;
    Landmark& lm = landmarks_[static_cast<std::size_t>(residuals_[i].landmark)];
    lm_residuals_[static_cast<std::size_t>(lm.res_first + lm.res_count++)] = static_cast<int>(i);
  }
  kept_.assign(static_cast<std::size_t>(kept_total), -1);
  res_slots_.assign(res_blocks_.size(), -1);
  for (const Residual& r : residuals_) {
    if (r.landmark < 0) continue;
    Landmark& lm = landmarks_[static_cast<std::size_t>(r.landmark)];
    int* kept = kept_.data() + lm.kept_first;
    for (int k = 0; k < r.count; ++k) {
      const int bi = res_blocks_[static_cast<std::size_t>(r.first + k)];
      if (blocks_[static_cast<std::size_t>(bi)].eliminate || blocks_[static_cast<std::size_t>(bi)].constant) continue;
      const int slot = static_cast<int>(std::find(kept, kept + lm.kept_count, bi) - kept);
      res_slots_[static_cast<std::size_t>(r.first + k)] = slot;
      if (slot == lm.kept_count) kept[lm.kept_count++] = bi;
    }
  }
  // Matrix storage: H_ee and each H_ek at even offsets (16-byte aligned), inverse storage for e > 1.
  const auto even = [](std::size_t n) { return (n + 1) & ~std::size_t{1}; };
  hek_offset_.assign(kept_.size(), 0);
  std::size_t data = 0, inv = 0;
  for (Landmark& lm : landmarks_) {
    const std::size_t e = static_cast<std::size_t>(lm.size);
    lm.hee = data;
    data += even(e * e);
    for (int i = 0; i < lm.kept_count; ++i) {
      const std::size_t k = static_cast<std::size_t>(lm.kept_first + i);
      hek_offset_[k] = data;
      data += even(e * static_cast<std::size_t>(blocks_[static_cast<std::size_t>(kept_[k])].tangent));
    }
    lm.inv = inv;
    if (lm.size > 1) inv += even(e * e);
  }
  // Sized only: a linearisation zeroes the H blocks before it sums into them, and every residual writes its rows
  // and Jacobians in the arena before they are read (zeroing the arena, a few MB, cost 1 % of a run's instructions).
  lm_data_.resize(static_cast<Eigen::Index>(data));
  inv_data_.setZero(static_cast<Eigen::Index>(inv));
  arena_.resize(arena);
  // The evaluations' pointer lists, sized once for the residual with the most blocks.
  param_ptrs_.assign(max_count, nullptr);
  jacobian_ptrs_.assign(max_count, nullptr);
  H_.resize(reduced_size_, reduced_size_);  // zeroed by each linearisation, as lm_data_
  g_.resize(reduced_size_);
  g_e_.resize(eliminated_size_);
  plus_jacobians_.resize(blocks_.size());
  block_of_row_.resize(static_cast<std::size_t>(reduced_size_));
  for (const Block& b : blocks_)
    if (!b.eliminate && !b.constant) std::fill_n(block_of_row_.begin() + b.offset, b.tangent, b.offset);
  prepared_ = true;
}

double SchurLmSolver::evaluate(bool linearise) {
  using Map = Eigen::Map<RowMajor>;
  using VecMap = Eigen::Map<Eigen::VectorXd>;
  if (linearise) {
    H_.setZero();
    g_.setZero();
    g_e_.setZero();
    lm_data_.setZero();
    // Manifold Jacobians at the linearisation point, once per block.
    for (std::size_t i = 0; i < blocks_.size(); ++i) {
      const Block& b = blocks_[i];
      if (b.manifold == nullptr || b.constant) continue;
      plus_jacobians_[i].resize(b.ambient, b.tangent);
      b.manifold->PlusJacobian(b.data, plus_jacobians_[i].data());
    }
  }
  double total = 0.0;
  for (const Residual& res : residuals_) {
    const std::size_t nb = static_cast<std::size_t>(res.count);
    const int* res_blocks = res_blocks_.data() + res.first;
    const int* res_slots = res_slots_.data() + res.first;
    const int rows = res.rows;
    double* scratch = arena_.data() + res.arena;
    VecMap r(scratch, rows);
    double** J_ptrs = jacobian_ptrs_.data();
    double* p = scratch + rows;
    for (std::size_t k = 0; k < nb; ++k) {
      const Block& b = blocks_[static_cast<std::size_t>(res_blocks[k])];
      param_ptrs_[k] = b.data;
      // Scratch: ambient Jacobian, then the tangent one (where a TangentJacobians factor writes a pose's directly).
      // None for a constant block.
      J_ptrs[k] = b.constant ? nullptr
                             : p + (res.tangent != nullptr && b.pose ? static_cast<std::ptrdiff_t>(rows) * b.ambient : 0);
      p += static_cast<std::ptrdiff_t>(rows) * (b.ambient + b.tangent);
    }
    double rho[3];
    if (!evaluateResidual(res.cost, res.tangent, res.loss, rows, param_ptrs_.data(), scratch,
                          linearise ? J_ptrs : nullptr, rho))
      return std::numeric_limits<double>::infinity();
    const double s = r.squaredNorm();
    total += 0.5 * rho[0];
    if (!linearise) continue;

    // Tangent Jacobians (row-major, rows x tangent), right after each ambient one.
    for (std::size_t k = 0; k < nb; ++k) {
      const std::size_t bi = static_cast<std::size_t>(res_blocks[k]);
      const Block& b = blocks_[bi];
      if (b.constant || (res.tangent != nullptr && b.pose)) continue;  // none, or given in the tangent space
      Map Ja(J_ptrs[k], rows, b.ambient);
      Map Jt(J_ptrs[k] + static_cast<std::ptrdiff_t>(rows) * b.ambient, rows, b.tangent);
      if (b.manifold != nullptr && rows == 2 && b.ambient == 7 && b.tangent == 6)
        Eigen::Map<RowMat<2, 6>>(Jt.data()).noalias() =
            Eigen::Map<const RowMat<2, 7>>(Ja.data()) * Eigen::Map<const RowMat<7, 6>>(plus_jacobians_[bi].data());
      else if (b.manifold != nullptr && rows == 2 && b.ambient == 6 && b.tangent == 4)
        Eigen::Map<RowMat<2, 4>>(Jt.data()).noalias() =
            Eigen::Map<const RowMat<2, 6>>(Ja.data()) * Eigen::Map<const RowMat<6, 4>>(plus_jacobians_[bi].data());
      else if (b.manifold != nullptr)
        Jt.noalias() = Ja * plus_jacobians_[bi];
      else
        Jt = Ja;
    }
    const auto tangent = [&](std::size_t k) {
      const Block& b = blocks_[static_cast<std::size_t>(res_blocks[k])];
      const std::ptrdiff_t skip = res.tangent != nullptr && b.pose ? 0 : static_cast<std::ptrdiff_t>(rows) * b.ambient;
      return Map(J_ptrs[k] + skip, rows, b.tangent);
    };
    // Robustification as Ceres' corrector (Triggs et al. 2000, sec. 4.3): scale r and J so that the Gauss-Newton
    // model of the robust cost matches it to second order.
    if (res.loss != nullptr && s > 0.0 && rho[1] > 0.0) {
      const double sqrt_rho1 = std::sqrt(rho[1]);
      double alpha = 0.0;
      if (rho[2] > 0.0) alpha = 1.0 - std::sqrt(std::max(0.0, 1.0 + 2.0 * s * rho[2] / rho[1]));
      for (std::size_t k = 0; k < nb; ++k) {
        if (blocks_[static_cast<std::size_t>(res_blocks[k])].constant) continue;
        Map Jt = tangent(k);
        if (alpha != 0.0) {
          const Eigen::RowVectorXd rJ = r.transpose() * Jt;
          Jt -= (alpha / s) * r * rJ;
        }
        Jt *= sqrt_rho1;
      }
      r *= sqrt_rho1 / (1.0 - alpha);
    }

    Landmark* lm = res.landmark >= 0 ? &landmarks_[static_cast<std::size_t>(res.landmark)] : nullptr;
    for (std::size_t a = 0; a < nb; ++a) {
      const Block& ba = blocks_[static_cast<std::size_t>(res_blocks[a])];
      if (ba.constant) continue;
      const Map Ja = tangent(a);
      if (ba.eliminate) {
        MatMap H_ee = Hee(*lm);
        if (!addJtJFixed(rows, ba.tangent, ba.tangent, H_ee.data(), lm->size, Ja.data(), Ja.data()))
          H_ee.noalias() += Ja.transpose() * Ja;
        if (!addJtJFixed(rows, ba.tangent, 1, g_e_.data() + lm->offset, lm->size, Ja.data(), r.data()))
          g_e_.segment(lm->offset, lm->size).noalias() += Ja.transpose() * r;
        for (std::size_t b = 0; b < nb; ++b) {
          if (res_slots[b] < 0) continue;
          MatMap H_ek = Hek(*lm, res_slots[b]);
          const Map Jb = tangent(b);
          if (!addJtJFixed(rows, ba.tangent, static_cast<int>(Jb.cols()), H_ek.data(), H_ek.rows(), Ja.data(), Jb.data()))
            H_ek.noalias() += Ja.transpose() * Jb;
        }
        continue;
      }
      if (!addJtJFixed(rows, ba.tangent, 1, g_.data() + ba.offset, reduced_size_, Ja.data(), r.data()))
        g_.segment(ba.offset, ba.tangent).noalias() += Ja.transpose() * r;
      for (std::size_t b = a; b < nb; ++b) {
        const Block& bb = blocks_[static_cast<std::size_t>(res_blocks[b])];
        if (bb.eliminate || bb.constant) continue;
        const Map Jb = tangent(b);
        double* dst = H_.data() + ba.offset + static_cast<Eigen::Index>(bb.offset) * reduced_size_;
        if (!addJtJFixed(rows, ba.tangent, bb.tangent, dst, reduced_size_, Ja.data(), Jb.data()))
          H_.block(ba.offset, bb.offset, ba.tangent, bb.tangent).noalias() += Ja.transpose() * Jb;
      }
    }
  }
  if (linearise) {
    // Each pair of distinct blocks was accumulated once, at (first, second) in its residual's block order, which
    // may fall in either triangle; each block's own diagonal block is complete. H = A + A^T with the diagonal blocks
    // halved back.
    // In place (no temporary): each pair (r, c), r < c, gets the same sum on both sides; inside a diagonal block
    // that sum is halved, as 0.5 (A + A^T) there. The diagonal entries keep their value (2x, then halved: exact).
    for (Eigen::Index c = 0; c < reduced_size_; ++c)
      for (Eigen::Index r = 0; r < c; ++r) {
        double v = H_(r, c) + H_(c, r);
        if (block_of_row_[static_cast<std::size_t>(r)] == block_of_row_[static_cast<std::size_t>(c)]) v *= 0.5;
        H_(r, c) = H_(c, r) = v;
      }
  }
  return total;
}
bool SchurLmSolver::computeStep(double mu, Eigen::VectorXd* dx_kept, Eigen::VectorXd* dx_elim,
                                double* model_decrease) {
  const double lo = options_.min_diagonal, hi = options_.max_diagonal;  // the damping's clamp of diag(J^T J)
  // The reduced system S = H - sum H_ke H_ee^-1 H_ek. Its Cholesky factorisation reads the lower triangle only, so
  // the coupling updates are made for the blocks on or below the diagonal (row offset >= column offset).
  D_ = H_.diagonal().cwiseMax(lo).cwiseMin(hi);
  S_ = H_;
  S_.diagonal() += mu * D_;
  rhs_ = -g_;
  D_e_.resize(eliminated_size_);
  inv_scalar_.resize(static_cast<Eigen::Index>(landmarks_.size()));
  const auto lower = [](const Block& bi, const Block& bj) { return bi.offset >= bj.offset; };
  for (std::size_t l = 0; l < landmarks_.size(); ++l) {
    const Landmark& lm = landmarks_[l];
    const MatMap H_ee = Hee(lm);
    D_e_.segment(lm.offset, lm.size) = H_ee.diagonal().cwiseMax(lo).cwiseMin(hi);
    if (lm.size == 1) {
      // The common case (inverse depth): scalar elimination, rank-one updates of the reduced system.
      const double a = H_ee(0, 0) + mu * D_e_(lm.offset);
      if (!(a > 0.0)) return false;
      const double inv = 1.0 / a;
      inv_scalar_(static_cast<Eigen::Index>(l)) = inv;
      const double g = g_e_(lm.offset);
      for (int i = 0; i < lm.kept_count; ++i) {
        const Block& bi = blocks_[static_cast<std::size_t>(keptBlock(lm, i))];
        const MatMap Hi = Hek(lm, i);
        const auto hi = Hi.row(0);
        rhs_.segment(bi.offset, bi.tangent) += (inv * g) * hi.transpose();
        for (int j = 0; j < lm.kept_count; ++j) {
          const Block& bj = blocks_[static_cast<std::size_t>(keptBlock(lm, j))];
          if (!lower(bi, bj)) continue;
          const MatMap Hj = Hek(lm, j);
          if (bi.tangent == 6 && bj.tangent == 6) {
            const Eigen::Matrix<double, 6, 1> u = inv * Eigen::Map<const Eigen::Matrix<double, 6, 1>>(Hi.data());
            S_.block<6, 6>(bi.offset, bj.offset).noalias() -= u * Eigen::Map<const Eigen::Matrix<double, 1, 6>>(Hj.data());
          } else {
            S_.block(bi.offset, bj.offset, bi.tangent, bj.tangent).noalias() -= (inv * hi.transpose()) * Hj.row(0);
          }
        }
      }
      continue;
    }
    MatMap inv_map(inv_data_.data() + lm.inv, lm.size, lm.size);
    if (lm.size == 4) {
      // Lines (orthonormal 4-DoF): fixed-size elimination, 4 x 6 couplings to the poses.
      Eigen::Matrix4d A = H_ee;
      A.diagonal() += mu * D_e_.segment<4>(lm.offset) + Eigen::Vector4d::Constant(options_.landmark_damping);
      const Eigen::LLT<Eigen::Matrix4d> llt4(A);
      if (llt4.info() != Eigen::Success) return false;
      const Eigen::Matrix4d inv = llt4.solve(Eigen::Matrix4d::Identity());
      inv_map = inv;
      const Eigen::Vector4d inv_g = inv * g_e_.segment<4>(lm.offset);
      for (int i = 0; i < lm.kept_count; ++i) {
        const Block& bi = blocks_[static_cast<std::size_t>(keptBlock(lm, i))];
        const MatMap Hi_dyn = Hek(lm, i);
        if (bi.tangent != 6) {
          rhs_.segment(bi.offset, bi.tangent).noalias() += Hi_dyn.transpose() * inv_g;
          const Eigen::MatrixXd HtInv = Hi_dyn.transpose() * inv;  // rare (a kept block other than a pose)
          for (int j = 0; j < lm.kept_count; ++j) {
            const Block& bj = blocks_[static_cast<std::size_t>(keptBlock(lm, j))];
            if (!lower(bi, bj)) continue;
            S_.block(bi.offset, bj.offset, bi.tangent, bj.tangent).noalias() -= HtInv * Hek(lm, j);
          }
          continue;
        }
        const Eigen::Map<const Eigen::Matrix<double, 4, 6>> Hi(Hi_dyn.data());
        rhs_.segment<6>(bi.offset).noalias() += Hi.transpose() * inv_g;
        const Eigen::Matrix<double, 6, 4> HtInv = Hi.transpose() * inv;
        for (int j = 0; j < lm.kept_count; ++j) {
          const Block& bj = blocks_[static_cast<std::size_t>(keptBlock(lm, j))];
          if (!lower(bi, bj)) continue;
          const MatMap Hj = Hek(lm, j);
          if (bj.tangent == 6)
            S_.block<6, 6>(bi.offset, bj.offset).noalias() -= HtInv * Eigen::Map<const Eigen::Matrix<double, 4, 6>>(Hj.data());
          else
            S_.block(bi.offset, bj.offset, 6, bj.tangent).noalias() -= HtInv * Hj;
        }
      }
      continue;
    }
    Eigen::MatrixXd A = H_ee;
    A.diagonal() += mu * D_e_.segment(lm.offset, lm.size) +
                    Eigen::VectorXd::Constant(lm.size, options_.landmark_damping);
    Eigen::LLT<Eigen::MatrixXd> llt(A);
    if (llt.info() != Eigen::Success) return false;
    inv_map = llt.solve(Eigen::MatrixXd::Identity(lm.size, lm.size));
    const Eigen::VectorXd inv_g = inv_map * g_e_.segment(lm.offset, lm.size);
    for (int i = 0; i < lm.kept_count; ++i) {
      const Block& bi = blocks_[static_cast<std::size_t>(keptBlock(lm, i))];
      const MatMap Hi = Hek(lm, i);
      rhs_.segment(bi.offset, bi.tangent).noalias() += Hi.transpose() * inv_g;
      const Eigen::MatrixXd HtInv = Hi.transpose() * inv_map;
      for (int j = 0; j < lm.kept_count; ++j) {
        const Block& bj = blocks_[static_cast<std::size_t>(keptBlock(lm, j))];
        if (!lower(bi, bj)) continue;
        S_.block(bi.offset, bj.offset, bi.tangent, bj.tangent).noalias() -= HtInv * Hek(lm, j);
      }
    }
  }
  llt_.compute(S_);
  if (llt_.info() != Eigen::Success) return false;
  *dx_kept = llt_.solve(rhs_);
  if (!dx_kept->allFinite()) return false;
  // Back-substitution: dx_e = A^-1 (-g_e - H_ek dx_k).
  dx_elim->resize(eliminated_size_);
  for (std::size_t l = 0; l < landmarks_.size(); ++l) {
    const Landmark& lm = landmarks_[l];
    back_ = -g_e_.segment(lm.offset, lm.size);
    for (int i = 0; i < lm.kept_count; ++i) {
      const Block& bi = blocks_[static_cast<std::size_t>(keptBlock(lm, i))];
      back_.noalias() -= Hek(lm, i) * dx_kept->segment(bi.offset, bi.tangent);
    }
    if (lm.size == 1)
      (*dx_elim)(lm.offset) = inv_scalar_(static_cast<Eigen::Index>(l)) * back_(0);
    else
      dx_elim->segment(lm.offset, lm.size) = MatMap(inv_data_.data() + lm.inv, lm.size, lm.size) * back_;
  }
  // Decrease of the undamped quadratic model: with (H + mu D) dx = -g it is 0.5 (mu dx'D dx - g'dx).
  double dec = mu * dx_kept->dot(D_.cwiseProduct(*dx_kept)) - g_.dot(*dx_kept) +
               mu * dx_elim->dot(D_e_.cwiseProduct(*dx_elim)) - g_e_.dot(*dx_elim);
  for (const Landmark& lm : landmarks_)
    if (lm.size > 1) dec += options_.landmark_damping * dx_elim->segment(lm.offset, lm.size).squaredNorm();
  *model_decrease = 0.5 * dec;
  return dx_elim->allFinite();
}

void SchurLmSolver::plusBlock(const Block& b, const double* delta) {
  if (b.manifold != nullptr) {
    plus_out_.resize(static_cast<std::size_t>(b.ambient));
    b.manifold->Plus(b.data, delta, plus_out_.data());
    std::copy(plus_out_.begin(), plus_out_.end(), b.data);
  } else {
    for (int k = 0; k < b.ambient; ++k) b.data[k] += delta[k];
  }
}

void SchurLmSolver::applyStep(const Eigen::VectorXd& dx_kept, const Eigen::VectorXd& dx_elim) {
  for (const Block& b : blocks_)
    if (!b.constant)
      plusBlock(b, b.eliminate ? dx_elim.data() + landmarks_[static_cast<std::size_t>(b.offset)].offset
                             : dx_kept.data() + b.offset);
}

double SchurLmSolver::landmarkCost(const Landmark& lm, Eigen::MatrixXd* H, Eigen::VectorXd* g) {
  const Block& b = blocks_[static_cast<std::size_t>(lm.block)];
  const bool linearise = H != nullptr && g != nullptr;
  if (linearise) {
    H->setZero(lm.size, lm.size);
    g->setZero(lm.size);
    plus_jacobians_[static_cast<std::size_t>(lm.block)].resize(b.ambient, b.tangent);
    if (b.manifold != nullptr) b.manifold->PlusJacobian(b.data, plus_jacobians_[static_cast<std::size_t>(lm.block)].data());
  }
  double total = 0.0;
  for (int q = 0; q < lm.res_count; ++q) {
    const Residual& res = residuals_[static_cast<std::size_t>(lm_residuals_[static_cast<std::size_t>(lm.res_first + q)])];
    const std::size_t nb = static_cast<std::size_t>(res.count);
    lm_scratch_.resize(static_cast<std::size_t>(res.rows) * static_cast<std::size_t>(1 + b.ambient + b.tangent));
    std::fill_n(jacobian_ptrs_.begin(), nb, nullptr);
    for (std::size_t k = 0; k < nb; ++k)
      param_ptrs_[k] = blocks_[static_cast<std::size_t>(res_blocks_[static_cast<std::size_t>(res.first) + k])].data;
    double* r_data = lm_scratch_.data();
    double* J_data = r_data + res.rows;  // ambient, then the tangent Jacobian
    if (linearise) jacobian_ptrs_[static_cast<std::size_t>(res.landmark_pos)] = J_data;
    double rho[3];
    if (!evaluateResidual(res.cost, res.tangent, res.loss, res.rows, param_ptrs_.data(), r_data,
                          linearise ? jacobian_ptrs_.data() : nullptr, rho))
      return std::numeric_limits<double>::infinity();
    total += 0.5 * rho[0];
    const Eigen::Map<const Eigen::VectorXd> r(r_data, res.rows);
    if (!linearise) continue;
    // Iteratively reweighted: the robust loss as the weight rho' of the squared residual.
    if (b.manifold != nullptr && res.rows == 2 && b.ambient == 6 && b.tangent == 4) {
      // The common case (a line's 2-row residual), with fixed sizes: the generic product's dispatch would cost more
      // than the arithmetic of these small matrices.
      RowMat<2, 4> Jt;
      Jt.noalias() = Eigen::Map<const RowMat<2, 6>>(J_data) *
                     Eigen::Map<const RowMat<6, 4>>(plus_jacobians_[static_cast<std::size_t>(lm.block)].data());
      Eigen::Map<Eigen::Matrix4d>(H->data()).noalias() += rho[1] * Jt.transpose() * Jt;
      Eigen::Map<Eigen::Vector4d>(g->data()).noalias() += rho[1] * Jt.transpose() * Eigen::Map<const Eigen::Vector2d>(r_data);
      continue;
    }
    const Eigen::Map<const RowMajor> Ja(J_data, res.rows, b.ambient);
    Eigen::Map<RowMajor> Jt(J_data + res.rows * b.ambient, res.rows, b.tangent);
    if (b.manifold != nullptr)
      Jt.noalias() = Ja * plus_jacobians_[static_cast<std::size_t>(lm.block)];
    else
      Jt = Ja;
    H->noalias() += rho[1] * Jt.transpose() * Jt;
    g->noalias() += rho[1] * Jt.transpose() * r;
  }
  return total;
}

// A landmark's own iterations stop once a step lowers its cost by less than this share (it then sits within a
// fraction of a pixel of its optimum given the poses).
constexpr double kLandmarkTolerance = 1e-3;

void SchurLmSolver::refineLandmarks() {
  if (options_.landmark_iterations <= 0) return;
  for (const Landmark& lm : landmarks_) {
    if (lm.size < 2 || lm.res_count == 0) continue;
    const Block& b = blocks_[static_cast<std::size_t>(lm.block)];
    double cost = landmarkCost(lm, &lm_H_, &lm_g_);
    if (!std::isfinite(cost)) continue;
    double lambda = 1e-3;  // Levenberg-Marquardt on the landmark alone: damping relative to diag(H)
    for (int it = 0; it < options_.landmark_iterations; ++it) {
      lm_A_ = lm_H_;
      lm_A_.diagonal() += lambda * lm_H_.diagonal().cwiseMax(options_.min_diagonal);
      lm_llt_.compute(lm_A_);
      if (lm_llt_.info() != Eigen::Success) break;
      lm_delta_ = -lm_g_;
      lm_llt_.solveInPlace(lm_delta_);
      if (!lm_delta_.allFinite()) break;
      lm_saved_.assign(b.data, b.data + b.ambient);
      plusBlock(b, lm_delta_.data());
      const double new_cost = landmarkCost(lm, nullptr, nullptr);
      if (!(new_cost < cost)) {
        std::copy(lm_saved_.begin(), lm_saved_.end(), b.data);
        lambda *= 10.0;
        continue;
      }
      const double relative = (cost - new_cost) / std::max(cost, std::numeric_limits<double>::min());
      lambda = std::max(1e-6, lambda / 10.0);
      if (relative < kLandmarkTolerance || it + 1 == options_.landmark_iterations) break;
      cost = landmarkCost(lm, &lm_H_, &lm_g_);
      if (!std::isfinite(cost)) break;
    }
  }
}

void SchurLmSolver::saveValues() {
  saved_.clear();
  for (const Block& b : blocks_) saved_.insert(saved_.end(), b.data, b.data + b.ambient);
}

void SchurLmSolver::restoreValues() {
  std::size_t k = 0;
  for (const Block& b : blocks_) {
    std::copy(saved_.begin() + static_cast<std::ptrdiff_t>(k), saved_.begin() + static_cast<std::ptrdiff_t>(k + b.ambient),
              b.data);
    k += static_cast<std::size_t>(b.ambient);
  }
}

double SchurLmSolver::cost() {
  prepare();
  return evaluate(false);
}

SchurLmSummary SchurLmSolver::solve(const SchurLmOptions& options) {
  options_ = options;
  const auto t0 = std::chrono::steady_clock::now();
  prepare();
  SchurLmSummary sum;
  refineLandmarks();
  double cost = evaluate(true);
  sum.jacobian_evaluations = 1;
  sum.initial_cost = sum.final_cost = cost;
  if (!std::isfinite(cost)) return sum;
  double radius = options_.initial_radius, v = 2.0;
  Eigen::VectorXd dx_kept, dx_elim;
  for (int it = 0; it < options_.max_iterations; ++it) {
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > options_.max_time_s) break;
    ++sum.iterations;
    double model_decrease = 0.0;
    if (!computeStep(1.0 / radius, &dx_kept, &dx_elim, &model_decrease) || !(model_decrease > 0.0)) {
      radius /= v;
      v *= 2.0;
      continue;
    }
    saveValues();
    applyStep(dx_kept, dx_elim);
    const double new_cost = evaluate(false);
    const double rho = (cost - new_cost) / model_decrease;
    if (std::isfinite(new_cost) && rho > options_.min_relative_decrease) {
      ++sum.successful_steps;
      const double relative = (cost - new_cost) / std::max(cost, std::numeric_limits<double>::min());
      cost = new_cost;
      radius /= std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3));
      v = 2.0;
      if (relative < options_.function_tolerance) {
        sum.converged = true;
        break;
      }
      if (it + 1 < options_.max_iterations) {
        refineLandmarks();
        cost = evaluate(true);
        ++sum.jacobian_evaluations;
      }
    } else {
      restoreValues();
      radius /= v;
      v *= 2.0;
    }
  }
  sum.final_cost = cost;
  return sum;
}

}  // namespace linnet
