// Re-identification of window lines (LineLandmarks::reidentify): the front-end keeps a lost line's id for only a few
// frames, so a line that flickers out of detection for longer (blur, an exposure change, a segment broken in two)
// comes back under a new id. Left alone, each comeback is a new landmark, triangulated again from a short baseline
// and archived as one more map line. Here the window's solved lines are projected into the newest frame at its
// predicted pose, and a new track's first sighting that lies on exactly one of them continues it, as a local map
// search by projection does for points in keyframe-based SLAM (ORB-SLAM, Mur-Artal et al., T-RO 2015).
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "linnet/estimator/line_landmarks.h"

namespace linnet {
namespace {

constexpr double kDegToRad = M_PI / 180.0;

/// The signed distances (pixels) of the endpoints of segment s-e (normalised) to the projection of L_W in the camera
/// T_C_W, the projected line oriented along s -> e (so that the sides of two lines compare); NaN if degenerate.
Vec2 signedEndpointPx(const Vec6& L_W, const Pose& T_C_W, const Vec2& s, const Vec2& e, double focal_px) {
  Vec3 l = transformPlucker(T_C_W, L_W).head<3>();
  if (Vec2(-l.y(), l.x()).dot(e - s) < 0.0) l = -l;
  const Vec2 d = focal_px * lineEndpointDistances(l, s, e);
  return d.allFinite() ? d : Vec2::Constant(std::numeric_limits<double>::quiet_NaN());
}

}  // namespace

std::int64_t LineLandmarks::landmarkId(std::int64_t frontend_id) {
  const auto a = alias_.find(frontend_id);
  if (a == alias_.end()) return frontend_id;
  if (landmarks_.count(a->second)) return a->second;
  alias_.erase(a);  // its line has left the window since: the id is a line of its own again
  return frontend_id;
}

double LineLandmarks::extentGap(const Vec6& L, const Vec3& ext_a, const Vec3& ext_b, const Vec3& a, const Vec3& b) {
  const Vec3 u = pluckerDirection(L), P0 = pluckerClosestPointToOrigin(L);
  const double ta = (ext_a - P0).dot(u), tb = (ext_b - P0).dot(u);
  const double na = (a - P0).dot(u), nb = (b - P0).dot(u);
  return std::max({0.0, std::min(na, nb) - std::max(ta, tb), std::min(ta, tb) - std::max(na, nb)});
}

LineLandmark& LineLandmarks::restore(std::size_t index) {
  const MapLine m = map_[index].line();
  LineLandmark& lm = landmarks_[m.id];
  lm.id = m.id;
  lm.setL(normalisePlucker(pluckerFromPoints(m.a, m.b)));
  lm.triangulated = lm.solved = lm.has_extent = true;
  lm.observations = m.observations;
  lm.t_last = m.t_last;
  lm.max_sin_angle = std::sin(m.angle_deg * kDegToRad);
  lm.a = m.a;
  lm.b = m.b;
  const auto s = map_sightings_.find(m.id);
  if (s != map_sightings_.end()) {
    lm.left_window = std::move(s->second);
    map_sightings_.erase(s);
  }
  map_.erase(map_.begin() + static_cast<std::ptrdiff_t>(index));
  return lm;
}

int LineLandmarks::reidentify(const Window& window) {
  if (!options_.reidentify || window.empty()) return 0;
  const FrameId newest = window.newest().id;
  const WindowCameras cams(window, T_B_C0_, T_B_C1_);
  const Pose* c0 = cams.cam0(newest);
  const Pose* c1 = cams.cam1(newest);
  if (c0 == nullptr) return 0;
  const Pose T_W_C0 = c0->inverse();

  // A line the sighting may continue: a solved window line the newest frame did not see, or a map line (with its
  // sightings) in front of the camera. `ref` is a sighting of it (camera pose, oriented endpoints) for the polarity.
  struct Candidate {
    LineLandmark* lm = nullptr;
    std::size_t map_index = 0;
    Vec6 L;
    Vec3 a, b;
    Pose ref_T_W_C;
    Vec2 ref_s, ref_e;
  };
  std::vector<Candidate> known;
  std::vector<LineLandmark*> fresh;
  for (auto& [id, lm] : landmarks_) {
    if (!lm.obs.count(newest)) {
      if (!lm.solved || !lm.triangulated || !lm.has_extent) continue;
      const auto& [frame, o] = *lm.obs.rbegin();
      if (const Pose* c = cams.cam0(frame)) known.push_back({&lm, 0, lm.L(), lm.a, lm.b, c->inverse(), o.s0, o.e0});
    } else if (!lm.triangulated && lm.obs.size() == 1 && lm.observations == 1) {
      fresh.push_back(&lm);
    }
  }
  if (fresh.empty()) return 0;
  for (std::size_t i = 0; options_.reid_map && i < map_.size(); ++i) {
    const MapLine m = map_[i].line();
    const auto sightings = map_sightings_.find(m.id);
    if (sightings == map_sightings_.end() || sightings->second.empty() || landmarks_.count(m.id)) continue;
    const double za = (*c0 * m.a).z(), zb = (*c0 * m.b).z();
    if (std::max(za, zb) < options_.min_depth_m || std::min(za, zb) > options_.max_depth_m) continue;
    const LineSighting& r = sightings->second.back();
    known.push_back({nullptr, i, normalisePlucker(pluckerFromPoints(m.a, m.b)), m.a, m.b, r.T_W_C, r.s, r.e});
  }
  if (known.empty()) return 0;

  // Per fresh sighting, the candidates whose projection lies within near_px of it (cam0 and, if matched, cam1) with
  // the same polarity (the segments are oriented by their gradient, so the two sides of a bar run opposite ways)
  // and touching its extent. The nearest, within reid_px, is the line found again, unless another one lies on a
  // different side of the sighting or farther than reid_px from it: two lines, not one line twice in the map.
  const double near_px = options_.reid_ambiguity * options_.reid_px;
  struct Near {
    std::size_t k;
    Eigen::Vector4d d;  // signed endpoint distances, cam0 then cam1 (0 without cam1), pixels
    double worst;
  };
  std::vector<Near> near;
  std::vector<std::pair<LineLandmark*, std::size_t>> joins;  // (fresh line, index in known)
  for (LineLandmark* f : fresh) {
    const LineFrameObs& o = f->obs.begin()->second;
    const bool right = o.has_right && c1 != nullptr;
    near.clear();
    for (std::size_t k = 0; k < known.size(); ++k) {
      Eigen::Vector4d d = Eigen::Vector4d::Zero();
      d.head<2>() = signedEndpointPx(known[k].L, *c0, o.s0, o.e0, focal_length_);
      if (!(d.head<2>().cwiseAbs().maxCoeff() <= near_px)) continue;
      if (right) d.tail<2>() = signedEndpointPx(known[k].L, *c1, o.s1, o.e1, focal_length_);
      const double worst = d.cwiseAbs().maxCoeff();
      if (!(worst <= near_px)) continue;
      const Candidate& c = known[k];
      Vec3 a, b, a_ref, b_ref;
      if (!backProject(c.L, T_W_C0, o.s0, o.e0, &a, &b) || !backProject(c.L, c.ref_T_W_C, c.ref_s, c.ref_e, &a_ref, &b_ref))
        continue;
      if (!((b - a).dot(b_ref - a_ref) > 0.0) || extentGap(c.L, c.a, c.b, a, b) > options_.max_extent_gap_m) continue;
      near.push_back({k, d, worst});
    }
    if (near.empty()) continue;
    const Near& best = *std::min_element(near.begin(), near.end(),
                                         [](const Near& x, const Near& y) { return x.worst < y.worst; });
    if (best.worst > options_.reid_px) continue;
    const bool unique = std::all_of(near.begin(), near.end(), [&](const Near& n) {
      return (n.d - best.d).cwiseAbs().maxCoeff() <= options_.reid_px;
    });
    if (unique) joins.emplace_back(f, best.k);
  }

  // A line claimed by two fresh ones is left alone (which of them is it?). Map lines are restored from the back of
  // the map so that the indices of the others stay valid.
  std::sort(joins.begin(), joins.end(), [&](const auto& x, const auto& y) {
    return known[x.second].map_index > known[y.second].map_index;
  });
  int joined = 0;
  std::vector<std::int64_t> merged;
  for (const auto& [f, k] : joins) {
    const auto claims = std::count_if(joins.begin(), joins.end(), [k = k](const auto& j) { return j.second == k; });
    if (claims != 1) continue;
    LineLandmark& line = known[k].lm != nullptr ? *known[k].lm : restore(known[k].map_index);
    const auto& [frame, o] = *f->obs.begin();
    line.obs.emplace(frame, o);
    ++line.observations;
    line.t_last = std::max(line.t_last, f->t_last);
    alias_[f->id] = line.id;
    merged.push_back(f->id);
    ++joined;
  }
  for (const std::int64_t id : merged) landmarks_.erase(id);
  return joined;
}

}  // namespace linnet
