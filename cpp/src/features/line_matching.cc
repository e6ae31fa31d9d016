// Temporal and stereo line matching (see line_matching.h).
#include "linnet/features/line_matching.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include <Eigen/Dense>

#include "linnet/core/error.h"

namespace linnet {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

// Overlap of intervals [a0, a1] and [b0, b1] (any order) divided by the shorter length.
double overlapRatio(double a0, double a1, double b0, double b1) {
  if (a0 > a1) std::swap(a0, a1);
  if (b0 > b1) std::swap(b0, b1);
  const double inter = std::min(a1, b1) - std::max(a0, b0);
  const double shorter = std::min(a1 - a0, b1 - b0);
  if (shorter <= 1e-12) return 0.0;
  return std::max(0.0, inter) / shorter;
}

// Rejects matches whose normal displacement disagrees with a 4-DoF similarity flow fitted by RANSAC:
// flow(m) = [a -b; b a] m + t, observed only along each line's normal: n . flow(m) = n . (mid_cur - mid_prev).
constexpr double kFlowScale = 1.0 / 400.0;  // conditions the rotation / scale columns of the flow model

// One row of the flow model for the pair (p, c): A.row . x = y, with x = (a, b, tx, ty).
void flowRow(const LineSegment& p, const LineSegment& c, const Vec2& centre, Eigen::Vector4d* a, double* y) {
  // The previous midpoint, moved by the flow, must lie on the current line: cn . flow(m) = cn . (mid_cur - mid_prev).
  const Vec2 cn = c.normal();
  const Vec2 m = (p.midpoint() - centre) * kFlowScale;
  *a << cn.dot(m), cn.dot(Vec2(-m.y(), m.x())), cn.x(), cn.y();
  *y = (c.midpoint() - p.midpoint()).dot(cn);
}

// Returns true and the fitted flow when there were enough matches to fit it.
bool rejectFlowOutliers(const TemporalMatchOptions& options, const std::vector<LineSegment>& prev,
                        const std::vector<LineSegment>& cur, const Vec2& centre, std::vector<int>* match_of_cur,
                        Eigen::Vector4d* flow) {
  std::vector<int> idx;
  for (int k = 0; k < static_cast<int>(match_of_cur->size()); ++k)
    if ((*match_of_cur)[k] >= 0) idx.push_back(k);
  const int n = static_cast<int>(idx.size());
  if (n < 8) return false;  // too few to tell outliers from motion
  Eigen::MatrixXd A(n, 4);
  Eigen::VectorXd y(n);
  for (int r = 0; r < n; ++r) {
    Eigen::Vector4d a;
    flowRow(prev[(*match_of_cur)[idx[r]]], cur[idx[r]], centre, &a, &y(r));
    A.row(r) = a.transpose();
  }
  std::mt19937 rng(static_cast<std::uint32_t>(options.ransac_seed));
  std::uniform_int_distribution<int> pick(0, n - 1);
  int best_inliers = -1;
  Eigen::Vector4d best = Eigen::Vector4d::Zero();
  for (int it = 0; it < options.ransac_iterations; ++it) {
    int s[4];
    for (int k = 0; k < 4; ++k) {
      bool again = true;
      while (again) {
        s[k] = pick(rng);
        again = false;
        for (int q = 0; q < k; ++q) again = again || s[q] == s[k];
      }
    }
    Eigen::Matrix4d As;
    Eigen::Vector4d ys;
    for (int k = 0; k < 4; ++k) {
      As.row(k) = A.row(s[k]);
      ys(k) = y(s[k]);
    }
    Eigen::FullPivLU<Eigen::Matrix4d> lu(As);
    if (lu.rank() < 4) continue;
    const Eigen::Vector4d x = lu.solve(ys);
    const int inl = static_cast<int>(((A * x - y).array().abs() < options.outlier_px).count());
    if (inl > best_inliers) {
      best_inliers = inl;
      best = x;
    }
  }
  if (best_inliers < 4) return false;
  // Refit on the inliers, then classify.
  const Eigen::ArrayXd res0 = (A * best - y).array().abs();
  const int ni = static_cast<int>((res0 < options.outlier_px).count());
  Eigen::MatrixXd Ai(ni, 4);
  Eigen::VectorXd yi(ni);
  for (int r = 0, q = 0; r < n; ++r)
    if (res0(r) < options.outlier_px) {
      Ai.row(q) = A.row(r);
      yi(q++) = y(r);
    }
  const Eigen::Vector4d refit = Ai.colPivHouseholderQr().solve(yi);
  const Eigen::ArrayXd res = (A * refit - y).array().abs();
  for (int r = 0; r < n; ++r)
    if (!(res(r) < options.outlier_px)) (*match_of_cur)[idx[r]] = -1;
  if (!refit.allFinite()) return false;
  *flow = refit;
  return true;
}

}  // namespace

int selectMutualBest(int n_a, int n_b, const std::vector<LineMatchCandidate>& candidates, int max_distance,
                     double ratio, std::vector<int>* match_of_a) {
  constexpr int kNone = std::numeric_limits<int>::max();
  std::vector<int> best_a(n_a, kNone), second_a(n_a, kNone), arg_a(n_a, -1);
  std::vector<int> best_b(n_b, kNone), arg_b(n_b, -1);
  for (const LineMatchCandidate& c : candidates) {
    if (c.distance < best_a[c.i] || (c.distance == best_a[c.i] && c.j < arg_a[c.i])) {
      second_a[c.i] = best_a[c.i];
      best_a[c.i] = c.distance;
      arg_a[c.i] = c.j;
    } else if (c.distance < second_a[c.i]) {
      second_a[c.i] = c.distance;
    }
    if (c.distance < best_b[c.j] || (c.distance == best_b[c.j] && c.i < arg_b[c.j])) {
      best_b[c.j] = c.distance;
      arg_b[c.j] = c.i;
    }
  }
  match_of_a->assign(n_a, -1);
  int count = 0;
  for (int i = 0; i < n_a; ++i) {
    const int j = arg_a[i];
    if (j < 0 || arg_b[j] != i || best_a[i] > max_distance) continue;
    if (second_a[i] != kNone && !(best_a[i] < ratio * second_a[i])) continue;
    (*match_of_a)[i] = j;
    ++count;
  }
  return count;
}

int matchTemporal(const TemporalMatchOptions& options, const std::vector<LineSegment>& prev,
                  const std::vector<LbdDescriptor>& prev_desc, const std::vector<LineSegment>& cur,
                  const std::vector<LbdDescriptor>& cur_desc, const Vec2& centre, std::vector<int>* match_of_cur) {
  if (cur.size() != cur_desc.size()) throw UsageError("matchTemporal: segments and descriptors differ in size");
  return matchTemporal(options, prev, prev_desc, cur, [&](int i) -> const LbdDescriptor& { return cur_desc[i]; },
                       centre, match_of_cur);
}

int matchTemporal(const TemporalMatchOptions& options, const std::vector<LineSegment>& prev,
                  const std::vector<LbdDescriptor>& prev_desc, const std::vector<LineSegment>& cur,
                  const std::function<const LbdDescriptor&(int)>& cur_desc, const Vec2& centre,
                  std::vector<int>* match_of_cur) {
  if (prev.size() != prev_desc.size()) throw UsageError("matchTemporal: segments and descriptors differ in size");
  const double cos_max = std::cos(options.max_angle_deg * kDegToRad);
  const double shift2 = options.max_shift_px * options.max_shift_px;
  std::vector<LineMatchCandidate> cands;
  for (int i = 0; i < static_cast<int>(cur.size()); ++i) {
    const LineSegment& c = cur[i];
    const Vec2 dc = c.direction(), mc = c.midpoint();
    for (int j = 0; j < static_cast<int>(prev.size()); ++j) {
      const LineSegment& p = prev[j];
      if ((p.midpoint() - mc).squaredNorm() > shift2) continue;
      const Vec2 dp = p.direction();
      if (dp.dot(dc) < cos_max) continue;
      const double lp = p.length();
      if (overlapRatio(0.0, lp, (c.s - p.s).dot(dp), (c.e - p.s).dot(dp)) < options.min_overlap) continue;
      const int dist = hammingDistance(cur_desc(i), prev_desc[j]);
      if (dist > options.max_hamming) continue;
      cands.push_back({i, j, dist});
    }
  }
  selectMutualBest(static_cast<int>(cur.size()), static_cast<int>(prev.size()), cands, options.max_hamming,
                   options.ratio, match_of_cur);
  Eigen::Vector4d flow;
  if (options.reject_outliers && rejectFlowOutliers(options, prev, cur, centre, match_of_cur, &flow) &&
      options.guided_max_hamming > 0) {
    // Guided pass: lines left unmatched on both sides, paired under the flow fitted on the confident matches with a
    // tight gate (guided_px on the normal displacement, the angle and overlap gates as above) and a looser descriptor
    // bound: LBD changes most where the view changes fast, which is where tracks were lost.
    std::vector<char> prev_used(prev.size(), 0);
    for (int m : *match_of_cur)
      if (m >= 0) prev_used[m] = 1;
    cands.clear();
    for (int i = 0; i < static_cast<int>(cur.size()); ++i) {
      if ((*match_of_cur)[i] >= 0) continue;
      const LineSegment& c = cur[i];
      const Vec2 dc = c.direction();
      for (int j = 0; j < static_cast<int>(prev.size()); ++j) {
        if (prev_used[j]) continue;
        const LineSegment& p = prev[j];
        const Vec2 dp = p.direction();
        if (dp.dot(dc) < cos_max) continue;
        Eigen::Vector4d a;
        double y = 0.0;
        flowRow(p, c, centre, &a, &y);
        if (!(std::abs(a.dot(flow) - y) < options.guided_px)) continue;
        if ((p.midpoint() - c.midpoint()).squaredNorm() > shift2) continue;
        if (overlapRatio(0.0, p.length(), (c.s - p.s).dot(dp), (c.e - p.s).dot(dp)) < options.min_overlap) continue;
        const int dist = hammingDistance(cur_desc(i), prev_desc[j]);
        if (dist > options.guided_max_hamming) continue;
        cands.push_back({i, j, dist});
      }
    }
    std::vector<int> guided;
    selectMutualBest(static_cast<int>(cur.size()), static_cast<int>(prev.size()), cands, options.guided_max_hamming,
                     options.ratio, &guided);
    for (int i = 0; i < static_cast<int>(cur.size()); ++i)
      if (guided[i] >= 0) (*match_of_cur)[i] = guided[i];
  }
  return static_cast<int>(std::count_if(match_of_cur->begin(), match_of_cur->end(), [](int m) { return m >= 0; }));
}

bool stereoGeometryOk(const StereoMatchOptions& options, const Mat3& E, const Pose& T_C1_C0, const LineSegment& left,
                      const LineSegment& right, double* overlap, Vec2* q_s, Vec2* q_e, Vec2* depth) {
  const Vec3 xs(left.s.x(), left.s.y(), 1.0), xe(left.e.x(), left.e.y(), 1.0);
  const Vec3 rs(right.s.x(), right.s.y(), 1.0), re(right.e.x(), right.e.y(), 1.0);
  const Vec3 lr = rs.cross(re);  // the right segment's line
  const double sin_min = std::sin(options.min_epipolar_angle_deg * kDegToRad);
  const Vec3 ends[2] = {xs, xe};
  Vec2 q[2];
  double z[2];
  const Mat3 R = T_C1_C0.R();
  for (int k = 0; k < 2; ++k) {
    const Vec3 epi = E * ends[k];  // epipolar line of the left endpoint in cam1
    const double ne = epi.head<2>().norm(), nr = lr.head<2>().norm();
    if (ne < 1e-12 || nr < 1e-12) return false;
    // Angle between the two lines through their normals.
    const double sin_ang = std::abs(epi.x() * lr.y() - epi.y() * lr.x()) / (ne * nr);
    if (sin_ang < sin_min) return false;
    const Vec3 h = lr.cross(epi);
    if (std::abs(h.z()) < 1e-12) return false;
    q[k] = h.head<2>() / h.z();
    // Depth of the left endpoint triangulated with q: lambda R x + t parallel to (q, 1).
    const Vec3 qh(q[k].x(), q[k].y(), 1.0);
    const Vec3 a = qh.cross(R * ends[k]), b = qh.cross(T_C1_C0.p);
    const double aa = a.squaredNorm();
    if (aa < 1e-18) return false;
    z[k] = -a.dot(b) / aa;
    if (!(z[k] >= options.min_depth_m && z[k] <= options.max_depth_m)) return false;
  }
  const Vec2 u = right.e - right.s;
  const double lu = u.norm();
  if (lu < 1e-12) return false;
  const Vec2 dir = u / lu;
  const double ts = (q[0] - right.s).dot(dir), te = (q[1] - right.s).dot(dir);
  if (te <= ts) return false;  // orientation (gradient polarity) must agree
  const double ov = overlapRatio(ts, te, 0.0, lu);
  if (ov < options.min_overlap) return false;
  if (overlap) *overlap = ov;
  if (q_s) *q_s = q[0];
  if (q_e) *q_e = q[1];
  if (depth) *depth = Vec2(z[0], z[1]);
  return true;
}

void stereoCandidates(const StereoMatchOptions& options, const Pose& T_C1_C0, const std::vector<LineSegment>& left,
                      const std::vector<LineSegment>& right, std::vector<LineMatchCandidate>* candidates) {
  candidates->clear();
  const Mat3 E = skew(T_C1_C0.p) * T_C1_C0.R();
  const double cos_max = std::cos(options.max_angle_deg * kDegToRad);
  std::vector<Vec2> right_dir(right.size());
  for (std::size_t j = 0; j < right.size(); ++j) right_dir[j] = right[j].direction();
  for (int i = 0; i < static_cast<int>(left.size()); ++i) {
    const Vec2 dl = left[i].direction();
    for (int j = 0; j < static_cast<int>(right.size()); ++j) {
      if (right_dir[j].dot(dl) < cos_max) continue;
      double ov = 0.0;
      if (!stereoGeometryOk(options, E, T_C1_C0, left[i], right[j], &ov)) continue;
      candidates->push_back({i, j, 0});
    }
  }
}

int matchStereo(const StereoMatchOptions& options, const Pose& T_C1_C0, const std::vector<LineSegment>& left,
                const std::vector<LbdDescriptor>& left_desc, const std::vector<LineSegment>& right,
                const std::vector<LbdDescriptor>& right_desc, std::vector<int>* match_of_left) {
  if (left.size() != left_desc.size() || right.size() != right_desc.size())
    throw UsageError("matchStereo: segments and descriptors differ in size");
  std::vector<LineMatchCandidate> cands;
  stereoCandidates(options, T_C1_C0, left, right, &cands);
  for (LineMatchCandidate& c : cands) c.distance = hammingDistance(left_desc[c.i], right_desc[c.j]);
  return selectMutualBest(static_cast<int>(left.size()), static_cast<int>(right.size()), cands, options.max_hamming,
                          options.ratio, match_of_left);
}

Vec2 neighbourFlow(const LineSegment& seg, const std::vector<LineSegment>& donor_segs,
                   const std::vector<Vec2>& donor_flows, int count) {
  if (donor_segs.size() != donor_flows.size())
    throw UsageError("neighbourFlow: donor segments and flows differ in size");
  if (count <= 0 || donor_segs.empty()) return Vec2::Zero();
  const Vec2 m = seg.midpoint();
  std::vector<std::pair<double, std::size_t>> near(donor_segs.size());
  for (std::size_t j = 0; j < donor_segs.size(); ++j) near[j] = {(donor_segs[j].midpoint() - m).squaredNorm(), j};
  const std::size_t k = std::min(near.size(), static_cast<std::size_t>(count));
  std::partial_sort(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(k), near.end());
  constexpr double kRidge = 0.05;  // in units of one donor's weight
  Mat2 A = kRidge * Mat2::Identity();
  Vec2 b = Vec2::Zero();
  for (std::size_t q = 0; q < k; ++q) {
    const LineSegment& d = donor_segs[near[q].second];
    const Vec2 u = d.direction(), n(-u.y(), u.x());
    A += n * n.transpose();
    b += n * n.dot(donor_flows[near[q].second]);
  }
  return A.ldlt().solve(b);
}

}  // namespace linnet
