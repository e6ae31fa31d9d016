#include "linnet/loop/pose_graph.h"

#include <algorithm>
#include <cmath>

#include <ceres/ceres.h>

#include "linnet/estimator/manifolds.h"

namespace linnet {

double yawOf(const Mat3& R, int axis) { return std::atan2(R(1, axis), R(0, axis)); }

int horizontalAxis(const Mat3& R) {
  int best = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(R(2, a)) < std::abs(R(2, best))) best = a;
  return best;
}

Mat3 rotZ(double yaw) {
  const double c = std::cos(yaw), s = std::sin(yaw);
  Mat3 R;
  R << c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0;
  return R;
}

namespace {

template <typename T>
T wrapAngle(const T& a) {
  const T two_pi = T(2.0 * M_PI);
  T r = a;
  while (r > T(M_PI)) r -= two_pi;
  while (r < T(-M_PI)) r += two_pi;
  return r;
}

// r = [ (R_i^T (p_j - p_i) - t_ij) / sigma_t ; wrap(yaw_j - yaw_i - yaw_ij) / sigma_yaw ], R_i = rotZ(yaw_i) R_tilt_i.
struct EdgeCost {
  EdgeCost(const PoseGraphEdge& e, const Mat3& R_tilt_i) : e_(e), R_tilt_i_(R_tilt_i) {}

  template <typename T>
  bool operator()(const T* p_i, const T* yaw_i, const T* p_j, const T* yaw_j, T* r) const {
    const T c = cos(yaw_i[0]), s = sin(yaw_i[0]);
    // d = rotZ(yaw_i)^T (p_j - p_i), then R_tilt^T d.
    const T dx = p_j[0] - p_i[0], dy = p_j[1] - p_i[1], dz = p_j[2] - p_i[2];
    const T d[3] = {c * dx + s * dy, -s * dx + c * dy, dz};
    for (int k = 0; k < 3; ++k) {
      const T tk = R_tilt_i_(0, k) * d[0] + R_tilt_i_(1, k) * d[1] + R_tilt_i_(2, k) * d[2];
      r[k] = (tk - T(e_.t_ij[k])) / T(e_.sigma_t);
    }
    r[3] = wrapAngle(yaw_j[0] - yaw_i[0] - T(e_.yaw_ij)) / T(e_.sigma_yaw);
    return true;
  }

  PoseGraphEdge e_;
  Mat3 R_tilt_i_;
};

// A line sighting from node k: the camera in the corrected world is C_k * T_Wo_C, with the node's correction
// C_k = (rotZ(yaw - yaw_odo), p - rotZ(yaw - yaw_odo) p_odo) (PoseGraph::correction). The line L = [n; v] in the
// corrected world, in the camera: n_C = R_WC^T (n - t_WC x v) (the image line in normalised coordinates), and
// r = [s~ . n_C, e~ . n_C] / |n_C,xy| (the endpoints' distances to it), scaled to whitened pixels.
struct LineSightingCost {
  LineSightingCost(const GraphLine::Sighting& o, const Vec3& p_odo, double yaw_odo, double scale)
      : R_oc_(o.T_Wo_C.R()), q_(o.T_Wo_C.p - p_odo), yaw_odo_(yaw_odo), s_(o.s), e_(o.e), scale_(scale) {}
  template <typename T>
  bool operator()(const T* p, const T* yaw, const T* L, T* r) const {
    const T d = yaw[0] - T(yaw_odo_);
    const T c = cos(d), s = sin(d);
    // t_WC = rotZ(d) (t_oc - p_odo) + p.
    const T t[3] = {c * T(q_.x()) - s * T(q_.y()) + p[0], s * T(q_.x()) + c * T(q_.y()) + p[1], T(q_.z()) + p[2]};
    const T* n = L;
    const T* v = L + 3;
    const T m[3] = {n[0] - (t[1] * v[2] - t[2] * v[1]), n[1] - (t[2] * v[0] - t[0] * v[2]),
                    n[2] - (t[0] * v[1] - t[1] * v[0])};
    // R_WC^T m = R_oc^T rotZ(d)^T m.
    const T m2[3] = {c * m[0] + s * m[1], -s * m[0] + c * m[1], m[2]};
    T l[3];
    for (int k = 0; k < 3; ++k) l[k] = R_oc_(0, k) * m2[0] + R_oc_(1, k) * m2[1] + R_oc_(2, k) * m2[2];
    const T norm = sqrt(l[0] * l[0] + l[1] * l[1]);
    r[0] = (T(s_.x()) * l[0] + T(s_.y()) * l[1] + l[2]) / norm * T(scale_);
    r[1] = (T(e_.x()) * l[0] + T(e_.y()) * l[1] + l[2]) / norm * T(scale_);
    return true;
  }
  Mat3 R_oc_;
  Vec3 q_;
  double yaw_odo_;
  Vec2 s_, e_;
  double scale_;
};

}  // namespace

std::size_t PoseGraph::addNode(const Pose& T_W_B) {
  Node n;
  n.odometry = T_W_B;
  const Mat3 R = T_W_B.R();
  n.axis = horizontalAxis(R);
  n.yaw = yawOf(R, n.axis);
  n.odometry_yaw = n.yaw;
  n.R_tilt = rotZ(-n.yaw) * R;
  for (int k = 0; k < 3; ++k) n.p[k] = T_W_B.p[k];
  nodes_.push_back(n);
  return nodes_.size() - 1;
}

PoseGraphEdge PoseGraph::odometryEdge(std::size_t i, std::size_t j, double sigma_t, double sigma_yaw) const {
  const Pose& a = nodes_[i].odometry;
  const Pose& b = nodes_[j].odometry;
  PoseGraphEdge e;
  e.i = i;
  e.j = j;
  e.t_ij = a.q.conjugate() * (b.p - a.p);
  e.yaw_ij = wrapAngle(nodes_[j].odometry_yaw - nodes_[i].odometry_yaw);
  e.sigma_t = sigma_t;
  e.sigma_yaw = sigma_yaw;
  return e;
}

PoseGraphEdge PoseGraph::loopEdge(std::size_t i, std::size_t j, const Pose& T_Bi_Bj, double sigma_t,
                                  double sigma_yaw) const {
  PoseGraphEdge e;
  e.i = i;
  e.j = j;
  e.t_ij = T_Bi_Bj.p;
  // j's yaw if it had i's odometry attitude composed with the measured relative rotation, against i's odometry yaw
  // (both in the odometry's frame: i's estimate has moved by its correction since).
  e.yaw_ij = wrapAngle(yawOf(nodes_[i].odometry.R() * T_Bi_Bj.R(), nodes_[j].axis) - nodes_[i].odometry_yaw);
  e.sigma_t = sigma_t;
  e.sigma_yaw = sigma_yaw;
  e.loop = true;
  return e;
}

void PoseGraph::addEdge(const PoseGraphEdge& e) { edges_.push_back(e); }

void PoseGraph::removeLastNode() {
  if (nodes_.empty()) return;
  const std::size_t k = nodes_.size() - 1;
  std::erase_if(edges_, [k](const PoseGraphEdge& e) { return e.i == k || e.j == k; });
  nodes_.pop_back();
}

bool PoseGraph::optimise(const PoseGraphOptions& options) { return optimise(options, nullptr, GraphLineOptions()); }

bool PoseGraph::optimise(const PoseGraphOptions& options, std::vector<GraphLine>* lines,
                         const GraphLineOptions& line_options) {
  const bool with_lines = lines != nullptr && !lines->empty();
  if (nodes_.size() < 2 || (edges_.empty() && !with_lines)) return true;
  // Nodes before `first` are held: only edges to a free node enter the problem (the others' cost is constant).
  const std::size_t first = std::min(options.first_free_node, nodes_.size() - 1);
  std::vector<Node> backup(nodes_.begin() + static_cast<std::ptrdiff_t>(first), nodes_.end());
  ceres::Problem::Options po;
  po.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  for (const PoseGraphEdge& e : edges_) {
    if (std::max(e.i, e.j) < first) continue;
    auto* cost = new ceres::AutoDiffCostFunction<EdgeCost, 4, 3, 1, 3, 1>(new EdgeCost(e, nodes_[e.i].R_tilt));
    ceres::LossFunction* loss =
        e.loop && options.loop_huber > 0.0 ? new ceres::HuberLoss(options.loop_huber) : nullptr;
    problem.AddResidualBlock(cost, loss, nodes_[e.i].p, &nodes_[e.i].yaw, nodes_[e.j].p, &nodes_[e.j].yaw);
  }
  LineManifold line_manifold;
  std::vector<std::array<double, 6>> line_backup;
  if (with_lines) {
    const double scale = line_options.focal_px / line_options.pixel_sigma;
    for (GraphLine& g : *lines) {
      line_backup.push_back(g.L);
      problem.AddParameterBlock(g.L.data(), 6, &line_manifold);
      for (const GraphLine::Sighting& o : g.sightings) {
        Node& n = nodes_[o.node];
        auto* cost = new ceres::AutoDiffCostFunction<LineSightingCost, 2, 3, 1, 6>(
            new LineSightingCost(o, n.odometry.p, n.odometry_yaw, scale));
        problem.AddResidualBlock(cost, new ceres::HuberLoss(line_options.huber), n.p, &n.yaw, g.L.data());
      }
    }
  }
  // Node 0 fixes the gauge, or the held nodes do.
  for (std::size_t k = 0; k < std::max<std::size_t>(first, 1); ++k) {
    if (!problem.HasParameterBlock(nodes_[k].p)) continue;
    problem.SetParameterBlockConstant(nodes_[k].p);
    problem.SetParameterBlockConstant(&nodes_[k].yaw);
  }
  ceres::Solver::Options so;
  so.max_num_iterations = options.max_iterations;
  so.num_threads = 1;
  // With lines, Schur elimination of the line blocks (the nodes form the reduced system).
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  if (!ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)) {
    so.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
    if (!ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE))
      so.linear_solver_type = with_lines ? ceres::DENSE_SCHUR : ceres::DENSE_QR;
  }
  so.logging_type = ceres::SILENT;
  if (with_lines) {
    // The lines eliminated (each is independent of the others given the nodes), the reduced system over the nodes
    // solved by preconditioned conjugate gradients: a line couples every node that saw it, which fills a factorisation.
    so.linear_solver_type = ceres::ITERATIVE_SCHUR;
    so.preconditioner_type = ceres::SCHUR_JACOBI;
    so.max_linear_solver_iterations = 50;
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    for (GraphLine& g : *lines) ordering->AddElementToGroup(g.L.data(), 0);
    for (Node& n : nodes_) {
      if (!problem.HasParameterBlock(n.p)) continue;
      ordering->AddElementToGroup(n.p, 1);
      ordering->AddElementToGroup(&n.yaw, 1);
    }
    so.linear_solver_ordering = ordering;
  }
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  if (!summary.IsSolutionUsable()) {
    std::copy(backup.begin(), backup.end(), nodes_.begin() + static_cast<std::ptrdiff_t>(first));
    for (std::size_t i = 0; i < line_backup.size(); ++i) (*lines)[i].L = line_backup[i];
    return false;
  }
  for (std::size_t k = first; k < nodes_.size(); ++k) nodes_[k].yaw = wrapAngle(nodes_[k].yaw);
  return true;
}

Pose PoseGraph::pose(std::size_t k) const {
  const Node& n = nodes_[k];
  return Pose(Mat3(rotZ(n.yaw) * n.R_tilt), Vec3(n.p[0], n.p[1], n.p[2]));
}

Pose PoseGraph::correction(std::size_t k) const { return pose(k) * nodes_[k].odometry.inverse(); }

void PoseGraph::setEstimate(std::size_t k, const Pose& T_W_B) {
  for (int i = 0; i < 3; ++i) nodes_[k].p[i] = T_W_B.p[i];
  nodes_[k].yaw = yawOf(T_W_B.R(), nodes_[k].axis);
}

}  // namespace linnet
