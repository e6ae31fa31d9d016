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

}  // namespace

void SchurLmSolver::addParameterBlock(double* data, int ambient_size, const ceres::Manifold* manifold,
                                      bool eliminate) {
  if (data == nullptr || ambient_size <= 0) throw UsageError("SchurLmSolver: a parameter block needs data and a size");
  if (manifold != nullptr && manifold->AmbientSize() != ambient_size)
    throw UsageError("SchurLmSolver: the manifold's ambient size differs from the block's");
  if (index_.count(data)) throw UsageError("SchurLmSolver: a parameter block was added twice");
  Block b;
  b.data = data;
  b.ambient = ambient_size;
  b.tangent = manifold != nullptr ? manifold->TangentSize() : ambient_size;
  b.manifold = manifold;
  b.eliminate = eliminate;
  b.offset = -1;
  index_.emplace(data, static_cast<int>(blocks_.size()));
  blocks_.push_back(b);
  prepared_ = false;
}

void SchurLmSolver::addResidual(const ceres::CostFunction* cost, const ceres::LossFunction* loss,
                                const std::vector<double*>& blocks) {
  const std::vector<int32_t>& sizes = cost->parameter_block_sizes();
  if (sizes.size() != blocks.size())
    throw UsageError("SchurLmSolver: a residual got " + std::to_string(blocks.size()) + " blocks, its cost function " +
                     std::to_string(sizes.size()));
  Residual r;
  r.cost = cost;
  r.loss = loss;
  r.rows = cost->num_residuals();
  int eliminated = 0;
  for (std::size_t k = 0; k < blocks.size(); ++k) {
    const auto it = index_.find(blocks[k]);
    if (it == index_.end()) throw UsageError("SchurLmSolver: a residual uses an unregistered parameter block");
    const Block& b = blocks_[static_cast<std::size_t>(it->second)];
    if (b.ambient != sizes[k]) throw UsageError("SchurLmSolver: a residual's block size differs from the block's");
    eliminated += b.eliminate ? 1 : 0;
    r.blocks.push_back(it->second);
  }
  if (eliminated > 1) throw UsageError("SchurLmSolver: a residual joins two eliminated blocks");
  residuals_.push_back(std::move(r));
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
      landmarks_.push_back(std::move(lm));
    } else {
      b.offset = reduced_size_;
      reduced_size_ += b.tangent;
    }
  }
  std::size_t arena = 0;
  for (Residual& r : residuals_) {
    r.arena = arena;
    arena += static_cast<std::size_t>(r.rows);
    for (int bi : r.blocks) {
      const Block& b = blocks_[static_cast<std::size_t>(bi)];
      arena += static_cast<std::size_t>(r.rows) * static_cast<std::size_t>(b.ambient + b.tangent);
    }
    r.landmark = -1;
    r.slots.assign(r.blocks.size(), -1);
    for (int bi : r.blocks)
      if (blocks_[static_cast<std::size_t>(bi)].eliminate) r.landmark = blocks_[static_cast<std::size_t>(bi)].offset;
    if (r.landmark < 0) continue;
    Landmark& lm = landmarks_[static_cast<std::size_t>(r.landmark)];
    for (std::size_t k = 0; k < r.blocks.size(); ++k) {
      const int bi = r.blocks[k];
      if (blocks_[static_cast<std::size_t>(bi)].eliminate) continue;
      const auto it = std::find(lm.kept.begin(), lm.kept.end(), bi);
      r.slots[k] = static_cast<int>(it - lm.kept.begin());
      if (it == lm.kept.end()) lm.kept.push_back(bi);
    }
  }
  arena_.assign(arena, 0.0);
  for (Landmark& lm : landmarks_) {
    lm.H_ee.setZero(lm.size, lm.size);
    lm.H_ek.resize(lm.kept.size());
    for (std::size_t i = 0; i < lm.kept.size(); ++i)
      lm.H_ek[i].setZero(lm.size, blocks_[static_cast<std::size_t>(lm.kept[i])].tangent);
  }
  H_.setZero(reduced_size_, reduced_size_);
  g_.setZero(reduced_size_);
  g_e_.setZero(eliminated_size_);
  plus_jacobians_.resize(blocks_.size());
  prepared_ = true;
}

double SchurLmSolver::evaluate(bool linearise) {
  using Map = Eigen::Map<RowMajor>;
  using VecMap = Eigen::Map<Eigen::VectorXd>;
  if (linearise) {
    H_.setZero();
    g_.setZero();
    g_e_.setZero();
    for (Landmark& lm : landmarks_) {
      lm.H_ee.setZero();
      for (Eigen::MatrixXd& m : lm.H_ek) m.setZero();
    }
    // Manifold Jacobians at the linearisation point, once per block.
    for (std::size_t i = 0; i < blocks_.size(); ++i) {
      const Block& b = blocks_[i];
      if (b.manifold == nullptr) continue;
      plus_jacobians_[i].resize(b.ambient, b.tangent);
      b.manifold->PlusJacobian(b.data, plus_jacobians_[i].data());
    }
  }
  double total = 0.0;
  std::vector<double*> J_ptrs;
  for (const Residual& res : residuals_) {
    const std::size_t nb = res.blocks.size();
    const int rows = res.rows;
    double* scratch = arena_.data() + res.arena;
    VecMap r(scratch, rows);
    param_ptrs_.resize(nb);
    J_ptrs.resize(nb);
    double* p = scratch + rows;
    for (std::size_t k = 0; k < nb; ++k) {
      const Block& b = blocks_[static_cast<std::size_t>(res.blocks[k])];
      param_ptrs_[k] = b.data;
      J_ptrs[k] = p;  // ambient Jacobian, then the tangent one
      p += static_cast<std::ptrdiff_t>(rows) * (b.ambient + b.tangent);
    }
    const double* const* params = param_ptrs_.data();
    if (!res.cost->Evaluate(params, scratch, linearise ? J_ptrs.data() : nullptr) || !r.allFinite())
      return std::numeric_limits<double>::infinity();
    const double s = r.squaredNorm();
    double rho[3] = {s, 1.0, 0.0};
    if (res.loss != nullptr) res.loss->Evaluate(s, rho);
    total += 0.5 * rho[0];
    if (!linearise) continue;

    // Tangent Jacobians (row-major, rows x tangent), right after each ambient one.
    for (std::size_t k = 0; k < nb; ++k) {
      const std::size_t bi = static_cast<std::size_t>(res.blocks[k]);
      const Block& b = blocks_[bi];
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
      const Block& b = blocks_[static_cast<std::size_t>(res.blocks[k])];
      return Map(J_ptrs[k] + static_cast<std::ptrdiff_t>(rows) * b.ambient, rows, b.tangent);
    };
    // Robustification as Ceres' corrector (Triggs et al. 2000, sec. 4.3): scale r and J so that the Gauss-Newton
    // model of the robust cost matches it to second order.
    if (res.loss != nullptr && s > 0.0 && rho[1] > 0.0) {
      const double sqrt_rho1 = std::sqrt(rho[1]);
      double alpha = 0.0;
      if (rho[2] > 0.0) alpha = 1.0 - std::sqrt(std::max(0.0, 1.0 + 2.0 * s * rho[2] / rho[1]));
      for (std::size_t k = 0; k < nb; ++k) {
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
      const Block& ba = blocks_[static_cast<std::size_t>(res.blocks[a])];
      const Map Ja = tangent(a);
      if (ba.eliminate) {
        if (!addJtJFixed(rows, ba.tangent, ba.tangent, lm->H_ee.data(), lm->size, Ja.data(), Ja.data()))
          lm->H_ee.noalias() += Ja.transpose() * Ja;
        if (!addJtJFixed(rows, ba.tangent, 1, g_e_.data() + lm->offset, lm->size, Ja.data(), r.data()))
          g_e_.segment(lm->offset, lm->size).noalias() += Ja.transpose() * r;
        for (std::size_t b = 0; b < nb; ++b) {
          if (res.slots[b] < 0) continue;
          Eigen::MatrixXd& Hek = lm->H_ek[static_cast<std::size_t>(res.slots[b])];
          const Map Jb = tangent(b);
          if (!addJtJFixed(rows, ba.tangent, static_cast<int>(Jb.cols()), Hek.data(), Hek.rows(), Ja.data(), Jb.data()))
            Hek.noalias() += Ja.transpose() * Jb;
        }
        continue;
      }
      if (!addJtJFixed(rows, ba.tangent, 1, g_.data() + ba.offset, reduced_size_, Ja.data(), r.data()))
        g_.segment(ba.offset, ba.tangent).noalias() += Ja.transpose() * r;
      for (std::size_t b = a; b < nb; ++b) {
        const Block& bb = blocks_[static_cast<std::size_t>(res.blocks[b])];
        if (bb.eliminate) continue;
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
    const Eigen::MatrixXd At = H_.transpose();
    H_ += At;
    for (const Block& b : blocks_)
      if (!b.eliminate) H_.block(b.offset, b.offset, b.tangent, b.tangent) *= 0.5;
  }
  return total;
}
bool SchurLmSolver::computeStep(double mu, Eigen::VectorXd* dx_kept, Eigen::VectorXd* dx_elim,
                                double* model_decrease) {
  const auto damping = [&](const Eigen::VectorXd& diag) {
    return diag.cwiseMax(options_.min_diagonal).cwiseMin(options_.max_diagonal).eval();
  };
  const Eigen::VectorXd D = damping(H_.diagonal());
  Eigen::MatrixXd S = H_;
  S.diagonal() += mu * D;
  Eigen::VectorXd rhs = -g_;
  Eigen::VectorXd D_e(eliminated_size_);
  std::vector<Eigen::MatrixXd> inv_general(landmarks_.size());  // damped H_ee^-1 of landmarks with e > 1
  Eigen::VectorXd inv_scalar(static_cast<Eigen::Index>(landmarks_.size()));
  for (std::size_t l = 0; l < landmarks_.size(); ++l) {
    const Landmark& lm = landmarks_[l];
    D_e.segment(lm.offset, lm.size) = damping(lm.H_ee.diagonal());
    if (lm.size == 1) {
      // The common case (inverse depth): scalar elimination, rank-one updates of the reduced system.
      const double a = lm.H_ee(0, 0) + mu * D_e(lm.offset);
      if (!(a > 0.0)) return false;
      const double inv = 1.0 / a;
      inv_scalar(static_cast<Eigen::Index>(l)) = inv;
      const double g = g_e_(lm.offset);
      for (std::size_t i = 0; i < lm.kept.size(); ++i) {
        const Block& bi = blocks_[static_cast<std::size_t>(lm.kept[i])];
        const auto hi = lm.H_ek[i].row(0);
        rhs.segment(bi.offset, bi.tangent) += (inv * g) * hi.transpose();
        for (std::size_t j = 0; j < lm.kept.size(); ++j) {
          const Block& bj = blocks_[static_cast<std::size_t>(lm.kept[j])];
          if (bi.tangent == 6 && bj.tangent == 6) {
            const Eigen::Matrix<double, 6, 1> u = inv * Eigen::Map<const Eigen::Matrix<double, 6, 1>>(lm.H_ek[i].data());
            S.block<6, 6>(bi.offset, bj.offset).noalias() -=
                u * Eigen::Map<const Eigen::Matrix<double, 1, 6>>(lm.H_ek[j].data());
          } else {
            S.block(bi.offset, bj.offset, bi.tangent, bj.tangent).noalias() -=
                (inv * hi.transpose()) * lm.H_ek[j].row(0);
          }
        }
      }
      continue;
    }
    if (lm.size == 4) {
      // Lines (orthonormal 4-DoF): fixed-size elimination, 4 x 6 couplings to the poses.
      Eigen::Matrix4d A = lm.H_ee;
      A.diagonal() += mu * D_e.segment<4>(lm.offset) + Eigen::Vector4d::Constant(options_.landmark_damping);
      const Eigen::LLT<Eigen::Matrix4d> llt4(A);
      if (llt4.info() != Eigen::Success) return false;
      const Eigen::Matrix4d inv = llt4.solve(Eigen::Matrix4d::Identity());
      inv_general[l] = inv;
      const Eigen::Vector4d inv_g = inv * g_e_.segment<4>(lm.offset);
      for (std::size_t i = 0; i < lm.kept.size(); ++i) {
        const Block& bi = blocks_[static_cast<std::size_t>(lm.kept[i])];
        if (bi.tangent != 6) {
          rhs.segment(bi.offset, bi.tangent).noalias() += lm.H_ek[i].transpose() * inv_g;
          const Eigen::MatrixXd HtInv = lm.H_ek[i].transpose() * inv;
          for (std::size_t j = 0; j < lm.kept.size(); ++j) {
            const Block& bj = blocks_[static_cast<std::size_t>(lm.kept[j])];
            S.block(bi.offset, bj.offset, bi.tangent, bj.tangent).noalias() -= HtInv * lm.H_ek[j];
          }
          continue;
        }
        const Eigen::Map<const Eigen::Matrix<double, 4, 6>> Hi(lm.H_ek[i].data());
        rhs.segment<6>(bi.offset).noalias() += Hi.transpose() * inv_g;
        const Eigen::Matrix<double, 6, 4> HtInv = Hi.transpose() * inv;
        for (std::size_t j = 0; j < lm.kept.size(); ++j) {
          const Block& bj = blocks_[static_cast<std::size_t>(lm.kept[j])];
          if (bj.tangent == 6)
            S.block<6, 6>(bi.offset, bj.offset).noalias() -=
                HtInv * Eigen::Map<const Eigen::Matrix<double, 4, 6>>(lm.H_ek[j].data());
          else
            S.block(bi.offset, bj.offset, 6, bj.tangent).noalias() -= HtInv * lm.H_ek[j];
        }
      }
      continue;
    }
    Eigen::MatrixXd A = lm.H_ee;
    A.diagonal() += mu * D_e.segment(lm.offset, lm.size) +
                    Eigen::VectorXd::Constant(lm.size, options_.landmark_damping);
    Eigen::LLT<Eigen::MatrixXd> llt(A);
    if (llt.info() != Eigen::Success) return false;
    inv_general[l] = llt.solve(Eigen::MatrixXd::Identity(lm.size, lm.size));
    const Eigen::VectorXd inv_g = inv_general[l] * g_e_.segment(lm.offset, lm.size);
    for (std::size_t i = 0; i < lm.kept.size(); ++i) {
      const Block& bi = blocks_[static_cast<std::size_t>(lm.kept[i])];
      rhs.segment(bi.offset, bi.tangent).noalias() += lm.H_ek[i].transpose() * inv_g;
      const Eigen::MatrixXd HtInv = lm.H_ek[i].transpose() * inv_general[l];
      for (std::size_t j = 0; j < lm.kept.size(); ++j) {
        const Block& bj = blocks_[static_cast<std::size_t>(lm.kept[j])];
        S.block(bi.offset, bj.offset, bi.tangent, bj.tangent).noalias() -= HtInv * lm.H_ek[j];
      }
    }
  }
  Eigen::LLT<Eigen::MatrixXd> llt(S);
  if (llt.info() != Eigen::Success) return false;
  *dx_kept = llt.solve(rhs);
  if (!dx_kept->allFinite()) return false;
  // Back-substitution: dx_e = A^-1 (-g_e - H_ek dx_k).
  dx_elim->resize(eliminated_size_);
  for (std::size_t l = 0; l < landmarks_.size(); ++l) {
    const Landmark& lm = landmarks_[l];
    Eigen::VectorXd b = -g_e_.segment(lm.offset, lm.size);
    for (std::size_t i = 0; i < lm.kept.size(); ++i) {
      const Block& bi = blocks_[static_cast<std::size_t>(lm.kept[i])];
      b.noalias() -= lm.H_ek[i] * dx_kept->segment(bi.offset, bi.tangent);
    }
    if (lm.size == 1)
      (*dx_elim)(lm.offset) = inv_scalar(static_cast<Eigen::Index>(l)) * b(0);
    else
      dx_elim->segment(lm.offset, lm.size) = inv_general[l] * b;
  }
  // Decrease of the undamped quadratic model: with (H + mu D) dx = -g it is 0.5 (mu dx'D dx - g'dx).
  double dec = mu * dx_kept->dot(D.cwiseProduct(*dx_kept)) - g_.dot(*dx_kept) +
               mu * dx_elim->dot(D_e.cwiseProduct(*dx_elim)) - g_e_.dot(*dx_elim);
  for (const Landmark& lm : landmarks_)
    if (lm.size > 1) dec += options_.landmark_damping * dx_elim->segment(lm.offset, lm.size).squaredNorm();
  *model_decrease = 0.5 * dec;
  return dx_elim->allFinite();
}

void SchurLmSolver::applyStep(const Eigen::VectorXd& dx_kept, const Eigen::VectorXd& dx_elim) {
  std::vector<double> out;
  for (const Block& b : blocks_) {
    const double* delta = b.eliminate ? dx_elim.data() + landmarks_[static_cast<std::size_t>(b.offset)].offset
                                      : dx_kept.data() + b.offset;
    if (b.manifold != nullptr) {
      out.resize(static_cast<std::size_t>(b.ambient));
      b.manifold->Plus(b.data, delta, out.data());
      std::copy(out.begin(), out.end(), b.data);
    } else {
      for (int k = 0; k < b.ambient; ++k) b.data[k] += delta[k];
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
        evaluate(true);
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
