#include "linnet/loop/line_adjustment.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "linnet/core/cpu_clock.h"
#include "linnet/geometry/plucker.h"
#include "linnet/loop/loop_closer.h"

namespace linnet {
namespace {

constexpr double kPi = 3.14159265358979323846;
// The solve's cost grows with the square of the keyframes a line couples: each joined line keeps at most this many
// (V1_02 lowtex, before the iterative Schur solver: the solve 2.3 -> 1.6 s, APE 0.0067 -> 0.0062 m).
constexpr std::size_t kMaxNodesPerLine = 24;
// A join is verified on at most this many sightings of each side (the joins 1.15 -> 0.22 s on V2_02 lowtex).
constexpr std::size_t kJoinSightings = 32;

/// A group of map lines taken for one physical line: its members (indices), its current line in the corrected world
/// and its sightings at the corrected poses (with their nodes and odometry poses).
struct Group {
  std::vector<std::size_t> members;
  Vec6 L = Vec6::Zero();
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();  // the best member's segment (candidate search)
  std::vector<LineSighting> corrected;      // sightings at the corrected poses
  std::vector<LineSighting> odometry;       // the same at the odometry's poses
  std::vector<std::size_t> nodes;
};

/// At most `n` of the sightings, evenly spread (all if fewer).
std::vector<LineSighting> spread(const std::vector<LineSighting>& all, std::size_t n) {
  if (all.size() <= n) return all;
  std::vector<LineSighting> out;
  for (std::size_t k = 0; k < n; ++k) out.push_back(all[k * all.size() / n]);
  return out;
}

/// True if the boxes of segments a0-b0 and a1-b1, grown by `margin`, overlap.
bool boxesOverlap(const Vec3& a0, const Vec3& b0, const Vec3& a1, const Vec3& b1, double margin) {
  for (int k = 0; k < 3; ++k)
    if (std::min(a0[k], b0[k]) - margin > std::max(a1[k], b1[k]) ||
        std::min(a1[k], b1[k]) - margin > std::max(a0[k], b0[k]))
      return false;
  return true;
}

bool nearAndParallel(const Group& g, const MapLine& m, const LineAdjustmentOptions& o) {
  if (!boxesOverlap(g.a, g.b, m.a, m.b, o.join_distance_m + o.join_gap_m)) return false;
  const Vec3 dg = (g.b - g.a).normalized(), dm = (m.b - m.a).normalized();
  if (std::abs(dg.dot(dm)) < std::cos(o.join_angle_deg * kPi / 180.0)) return false;
  if (pluckerPointDistance(g.L, m.a) > o.join_distance_m || pluckerPointDistance(g.L, m.b) > o.join_distance_m)
    return false;
  const double len = (g.b - g.a).norm();
  const double ta = dg.dot(m.a - g.a), tb = dg.dot(m.b - g.a);
  return std::max(ta, tb) >= -o.join_gap_m && std::min(ta, tb) <= len + o.join_gap_m;
}

}  // namespace

std::vector<MapLine> LoopCloser::adjustLines(const std::vector<MapLine>& lines,
                                             const std::map<std::int64_t, std::vector<LineSighting>>& sightings,
                                             const LineAdjustmentOptions& options, LineAdjustmentStats* stats) {
  const double cpu0 = threadCpuMs();
  LineAdjustmentStats st;
  st.lines = lines.size();
  const auto nodeAt = [&](Timestamp t) -> std::size_t {
    const auto it = std::upper_bound(keyframes_.begin(), keyframes_.end(), t,
                                     [](Timestamp x, const Keyframe& kf) { return x < kf.t; });
    return it == keyframes_.begin() ? 0 : static_cast<std::size_t>(it - keyframes_.begin()) - 1;
  };
  LineRefinementOptions ro;
  ro.focal_px = options.focal_px;
  ro.huber_px = options.pixel_sigma;
  std::vector<MapLine> out;
  if (keyframes_.empty()) {
    for (const MapLine& l : lines) out.push_back(l);
    if (stats) *stats = st;
    return out;
  }
  // Each line with sightings as a group of one, in the corrected world; the others only corrected.
  std::vector<Group> singles;
  std::vector<const MapLine*> single_lines, unseen;
  for (const MapLine& l : lines) {
    const auto s = sightings.find(l.id);
    if (s == sightings.end() || s->second.size() < 2) {
      unseen.push_back(&l);  // corrected once the graph is solved
      continue;
    }
    Group g;
    g.members = {single_lines.size()};
    const MapLine m = correctedLine(l);
    g.a = m.a;
    g.b = m.b;
    g.L = normalisePlucker(pluckerFromPoints(m.a, m.b));
    for (const LineSighting& o : s->second) {
      const std::size_t node = nodeAt(o.t);
      g.nodes.push_back(node);
      g.odometry.push_back(o);
      LineSighting c = o;
      c.T_W_C = graph_.correction(node) * o.T_W_C;
      g.corrected.push_back(c);
    }
    single_lines.push_back(&l);
    singles.push_back(std::move(g));
  }
  // Join: best-constrained first, each line into the first group whose line explains both sets of sightings.
  std::vector<std::size_t> order(singles.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
    return single_lines[x]->sigma_m < single_lines[y]->sigma_m;
  });
  const std::vector<Group> originals = singles;  // each line's own sightings (the groups take them over)
  std::vector<Group> groups;
  for (std::size_t i : order) {
    Group& s = singles[i];
    const MapLine probe{single_lines[i]->id, s.a, s.b};
    bool joined = false;
    for (Group& g : groups) {
      if (!nearAndParallel(g, probe, options)) continue;
      // Verified on up to kJoinSightings of each (the cost of a candidate stays bounded as groups grow).
      const std::vector<LineSighting> sg = spread(g.corrected, kJoinSightings);
      const std::vector<LineSighting> ss = spread(s.corrected, kJoinSightings);
      std::vector<LineSighting> both = sg;
      both.insert(both.end(), ss.begin(), ss.end());
      Vec6 L = g.L;
      refineLine(both, ro, &L);
      if (meanSightingErrorPx(L, sg, options.focal_px) > options.join_px ||
          meanSightingErrorPx(L, ss, options.focal_px) > options.join_px)
        continue;
      both = g.corrected;
      both.insert(both.end(), s.corrected.begin(), s.corrected.end());
      g.L = L;
      g.members.push_back(i);
      g.corrected = std::move(both);
      g.odometry.insert(g.odometry.end(), s.odometry.begin(), s.odometry.end());
      g.nodes.insert(g.nodes.end(), s.nodes.begin(), s.nodes.end());
      joined = true;
      break;
    }
    if (!joined) groups.push_back(std::move(s));
  }
  // The pose graph again, with the joined lines.
  std::vector<GraphLine> graph_lines;
  std::vector<std::size_t> graph_group;
  for (std::size_t k = 0; k < groups.size(); ++k) {
    if (groups[k].members.size() < 2) continue;
    st.joined += groups[k].members.size();
    GraphLine gl;
    for (int j = 0; j < 6; ++j) gl.L[j] = groups[k].L[j];
    // One frame per node (its cam0 and cam1 sightings): the frames between two keyframes hang on the same node's
    // correction, so more of them add cost, not constraints on the correction.
    std::map<std::size_t, Timestamp> frame_of_node;
    for (std::size_t q = 0; q < groups[k].odometry.size(); ++q)
      frame_of_node.emplace(groups[k].nodes[q], groups[k].odometry[q].t);
    // At most kMaxNodesPerLine nodes, spread evenly over them: each line couples its nodes in the solve, so its cost
    // grows with their square.
    std::map<std::size_t, Timestamp> kept;
    const std::size_t n = frame_of_node.size();
    std::size_t idx = 0;
    for (const auto& [node, t] : frame_of_node) {
      if (n <= kMaxNodesPerLine || (idx * kMaxNodesPerLine) / n != ((idx + 1) * kMaxNodesPerLine) / n)
        kept.emplace(node, t);
      ++idx;
    }
    for (std::size_t q = 0; q < groups[k].odometry.size(); ++q) {
      const LineSighting& o = groups[k].odometry[q];
      const auto it = kept.find(groups[k].nodes[q]);
      if (it == kept.end() || it->second != o.t) continue;
      gl.sightings.push_back({groups[k].nodes[q], o.T_W_C, o.s, o.e});
    }
    graph_lines.push_back(std::move(gl));
    graph_group.push_back(k);
  }
  st.groups = graph_lines.size();
  if (!graph_lines.empty()) {
    GraphLineOptions lo;
    lo.focal_px = options.focal_px;
    lo.pixel_sigma = options.pixel_sigma;
    st.solved = graph_.optimise(solveOptions(), &graph_lines, lo);
    if (st.solved)
      for (std::size_t k = 0; k < graph_lines.size(); ++k)
        groups[graph_group[k]].L = Eigen::Map<const Vec6>(graph_lines[k].L.data());
  }
  // The lines re-estimated on their sightings at the corrected poses, with their extents and sigmas: each joined
  // group as one line (options.publish_joined), or each map line on its own sightings.
  const auto estimate = [&](MapLine m, const std::vector<LineSighting>& odometry, const std::vector<std::size_t>& nodes,
                            Vec6 L) {
    std::vector<LineSighting> corrected = odometry;
    for (std::size_t q = 0; q < corrected.size(); ++q)
      corrected[q].T_W_C = graph_.correction(nodes[q]) * odometry[q].T_W_C;
    refineLine(corrected, ro, &L);
    Vec3 a, b;
    if (!extentOnSightings(L, corrected, options.min_depth_m, options.max_depth_m, &a, &b) || !((b - a).norm() > 0.0) ||
        (b - a).norm() > options.max_length_m)
      return correctedLine(m);  // no extent at the corrected poses: the line as it was, moved by its correction
    m.a = a;
    m.b = b;
    m.sigma_m = lineEndpointSigmaM(L, corrected, m.a, m.b, options.focal_px, options.pixel_sigma);
    return m;
  };
  // A line's Plücker coordinates moved by the change of the correction of its last sighting's node.
  const auto moved = [&](const Group& g) {
    const Pose& T_o = g.odometry.back().T_W_C;
    const Pose C_old = g.corrected.back().T_W_C * T_o.inverse();
    const Pose C_new = graph_.correction(g.nodes.back());
    return normalisePlucker(transformPlucker(C_new * C_old.inverse(), g.L));
  };
  for (const Group& g : groups) {
    if (g.members.size() == 1 || !options.publish_joined) {
      for (std::size_t i : g.members) {
        const Group& own = originals[i];
        const Vec6 L0 = g.members.size() == 1 ? moved(own) : g.L;
        out.push_back(estimate(*single_lines[i], own.odometry, own.nodes, L0));
      }
      continue;
    }
    MapLine m = *single_lines[g.members.front()];
    m.observations = 0;
    for (std::size_t i : g.members) {
      const MapLine& l = *single_lines[i];
      m.observations += l.observations;
      m.t_last = std::max(m.t_last, l.t_last);
      m.angle_deg = std::max(m.angle_deg, l.angle_deg);
    }
    out.push_back(estimate(m, g.odometry, g.nodes, g.L));
  }
  for (const MapLine* l : unseen) out.push_back(correctedLine(*l));
  std::sort(out.begin(), out.end(), [](const MapLine& x, const MapLine& y) { return x.id < y.id; });
  st.cpu_s = 1e-3 * (threadCpuMs() - cpu0);
  if (stats) *stats = st;
  return out;
}

}  // namespace linnet
