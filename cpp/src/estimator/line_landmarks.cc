// Line landmarks of the window (see line_landmarks.h).
#include "linnet/estimator/line_landmarks.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>

#include "linnet/estimator/factors/line_factor.h"

namespace linnet {

namespace {
constexpr double kDegToRad = M_PI / 180.0;

// A line as it stands (its last solve's estimate and extent), as a map line.
MapLine currentMapLine(std::int64_t id, const LineLandmark& lm) {
  return MapLine{id, lm.a, lm.b, lm.observations, lm.t_last, std::asin(std::min(1.0, lm.max_sin_angle)) / kDegToRad};
}

constexpr std::size_t kMaxSightings = 100;  // a line's sightings kept for the map's refinement (up to twice as many)
}

LineLandmarks::LineLandmarks(const LineOptions& options, double focal_length, const Pose& T_B_C0,
                             std::optional<Pose> T_B_C1)
    : options_(options), focal_length_(focal_length), T_B_C0_(T_B_C0), T_B_C1_(std::move(T_B_C1)) {}

void LineLandmarks::observe(FrameId frame, Timestamp t, const std::vector<LineObservation>& lines) {
  for (const LineObservation& l : lines) {
    const std::int64_t id = landmarkId(l.id);
    LineLandmark& lm = landmarks_[id];
    if (lm.id < 0) lm.id = id;
    LineFrameObs o;
    o.s0 = l.s0;
    o.e0 = l.e0;
    o.has_right = l.has_right && T_B_C1_.has_value();
    o.s1 = l.s1;
    o.e1 = l.e1;
    if (lm.obs.emplace(frame, o).second) ++lm.observations;
    lm.t_last = std::max(lm.t_last, t);
  }
}

bool LineLandmarks::backProject(const Vec6& L, const Pose& T_W_C, const Vec2& s, const Vec2& e, Vec3* a,
                                Vec3* b) const {
  return backProjectSegment(L, T_W_C, s, e, options_.min_depth_m, options_.max_depth_m, a, b);
}

void LineLandmarks::extend(LineLandmark& lm, const Vec3& a, const Vec3& b) const {
  extendOnLine(lm.L(), a, b, &lm.has_extent, &lm.a, &lm.b);
}

bool LineLandmarks::triangulateOne(const Window& window, LineLandmark& lm) const {
  return triangulateOne(window, WindowCameras(window, T_B_C0_, T_B_C1_), lm);
}

bool LineLandmarks::triangulateOne(const Window& window, const WindowCameras& cams, LineLandmark& lm) const {
  // Candidate plane pairs: the stereo pair of each observing frame, and cam0 of the oldest observation with cam0 of
  // every later one. The widest plane angle wins.
  double best_sin = -1.0;
  Vec6 best = Vec6::Zero();
  const auto consider = [&](const Eigen::Vector4d& p1, const Eigen::Vector4d& p2) {
    double sin_angle = 0.0;
    const Vec6 L = intersectPlanes(p1, p2, &sin_angle);
    if (sin_angle > best_sin && L.allFinite()) {
      best_sin = sin_angle;
      best = L;
    }
  };
  std::optional<Eigen::Vector4d> first;
  for (const auto& [fid, o] : lm.obs) {
    const WindowFrame* f = window.find(fid);
    if (f == nullptr) continue;
    const Pose T_W_B = f->T_W_B();
    const Eigen::Vector4d p0 = backProjectionPlane(T_W_B * T_B_C0_, o.s0, o.e0);
    if (o.has_right) consider(p0, backProjectionPlane(T_W_B * *T_B_C1_, o.s1, o.e1));
    if (first) consider(*first, p0);
    else first = p0;
  }
  if (best_sin < std::sin(options_.min_plane_angle_deg * kDegToRad)) return false;
  lm.max_sin_angle = std::max(lm.max_sin_angle, best_sin);
  if (first) {
    lm.first_plane = *first;
    lm.has_first_plane = true;
  }
  const Vec6 L = normalisePlucker(best);
  // Every cam0 observation must back-project in front of its camera, within the depth range; the segment short
  // enough. The extent starts from these. Checked on the landmark itself (no copy of its observations); a rejected
  // candidate leaves its geometry as it was.
  const std::array<double, 6> saved_plucker = lm.plucker;
  const bool saved_has_extent = lm.has_extent;
  const Vec3 saved_a = lm.a, saved_b = lm.b;
  const auto reject = [&] {
    lm.plucker = saved_plucker;
    lm.has_extent = saved_has_extent;
    lm.a = saved_a;
    lm.b = saved_b;
    lm.triangulated = false;
    return false;
  };
  lm.setL(L);
  lm.has_extent = false;
  for (const auto& [fid, o] : lm.obs) {
    const WindowFrame* f = window.find(fid);
    if (f == nullptr) continue;
    Vec3 a, b;
    if (!backProject(L, f->T_W_B() * T_B_C0_, o.s0, o.e0, &a, &b)) return reject();
    extend(lm, a, b);
  }
  if (!lm.has_extent || (lm.b - lm.a).norm() > options_.max_length_m) return reject();
  lm.triangulated = true;
  std::vector<std::array<double, 2>> errors;
  if (sightingErrorsPx(cams, lm, &errors) > options_.outlier_px) return reject();
  return true;
}

int LineLandmarks::triangulate(const Window& window) {
  const WindowCameras cams(window, T_B_C0_, T_B_C1_);
  int n = 0;
  for (auto& [id, lm] : landmarks_)
    if (!lm.triangulated && triangulateOne(window, cams, lm)) ++n;
  return n;
}

std::vector<ResidualSpec> LineLandmarks::residuals(const Window& window, FrameId host_only,
                                                   const std::map<FrameId, double>& frame_weight) {
  factors_.begin();
  std::vector<ResidualSpec> out;
  const double sqrt_info = focal_length_ / options_.pixel_sigma;
  // One set of pose terms per frame and camera (by window index, cam0 then cam1), shared by the factors of all
  // its lines.
  std::vector<std::shared_ptr<SharedLinePoseTerms>> shared_terms(2 * static_cast<std::size_t>(window.size()));
  for (auto& [id, lm] : landmarks_) {
    if (host_only < 0) lm.used = false;
    if (!usable(lm)) continue;
    if (host_only >= 0 && lm.obs.begin()->first != host_only) continue;
    const std::int64_t key = lineBlockKey(id);
    for (const auto& [fid, o] : lm.obs) {
      const int wi = window.indexOf(fid);
      if (wi < 0) continue;
      WindowFrame* f = &const_cast<Window&>(window)[wi];
      double s = sqrt_info;
      if (!frame_weight.empty()) {
        const auto w = frame_weight.find(fid);
        if (w != frame_weight.end()) s *= std::sqrt(w->second);
      }
      auto add = [&](const Vec2& a, const Vec2& b, const Pose& T_B_C, bool cam1) {
        ResidualSpec r;
        if (cam1) r.cam1 = 0;
        // The frame camera's extrinsics (capture shift included) are computed once, with its shared terms.
        std::shared_ptr<SharedLinePoseTerms>& terms = shared_terms[2 * static_cast<std::size_t>(wi) + (cam1 ? 1 : 0)];
        if (!terms) terms = std::make_shared<SharedLinePoseTerms>(f->capture_shift * T_B_C);
        r.cost = factors_.make(a, b, terms->T_B_C, s, terms);
        r.robust = true;
        r.line = true;
        r.blocks = {f->pose.data(), lm.plucker.data()};
        r.keys = {frameBlockKey(fid, BlockKind::kPose), key};
        out.push_back(std::move(r));
      };
      add(o.s0, o.e0, T_B_C0_, false);
      if (o.has_right && options_.right_residuals) add(o.s1, o.e1, *T_B_C1_, true);
    }
    if (host_only < 0) lm.used = lm.solved = true;
  }
  return out;
}

LineLandmarks::StoredMapLine LineLandmarks::StoredMapLine::of(const MapLine& m) {
  StoredMapLine s;
  s.id = m.id;
  s.t_last = m.t_last;
  for (int i = 0; i < 3; ++i) {
    s.a[static_cast<std::size_t>(i)] = static_cast<float>(m.a[i]);
    s.b[static_cast<std::size_t>(i)] = static_cast<float>(m.b[i]);
  }
  s.angle_deg = static_cast<float>(m.angle_deg);
  s.sigma_m = static_cast<float>(m.sigma_m);
  s.observations = m.observations;
  return s;
}

MapLine LineLandmarks::StoredMapLine::line() const {
  MapLine m;
  m.id = id;
  m.a = Vec3(a[0], a[1], a[2]);
  m.b = Vec3(b[0], b[1], b[2]);
  m.observations = observations;
  m.t_last = t_last;
  m.angle_deg = angle_deg;
  m.sigma_m = sigma_m;
  return m;
}

void LineLandmarks::archive(LineLandmark& lm) {
  if (!lm.triangulated || !lm.has_extent) return;
  const auto at = std::lower_bound(map_.begin(), map_.end(), lm.id,
                                   [](const StoredMapLine& m, std::int64_t id) { return m.id < id; });
  const StoredMapLine archived = StoredMapLine::of(mapLineOf(lm, lm.left_window));
  if ((options_.reidentify && options_.reid_map) || options_.map.adjust)
    map_sightings_[lm.id] = std::move(lm.left_window);
  // Lines leave the window roughly in the order of their ids: the insertion is near the end.
  if (at != map_.end() && at->id == lm.id) {
    *at = archived;
  } else {
    map_.insert(at, archived);
  }
}

MapLine LineLandmarks::mapLineOf(const LineLandmark& lm, const std::vector<LineSighting>& sightings) const {
  MapLine m = currentMapLine(lm.id, lm);
  Vec6 L = lm.L();
  LineRefinementOptions ro;
  ro.focal_px = focal_length_;
  ro.huber_px = options_.huber_px * options_.pixel_sigma;
  if (options_.map_refine && refineLine(sightings, ro, &L)) {
    // The extent again, on the refined line: the extreme back-projected endpoints of all its sightings.
    Vec3 a, b;
    if (extentOnSightings(L, sightings, options_.min_depth_m, options_.max_depth_m, &a, &b) &&
        (b - a).norm() <= options_.max_length_m) {
      m.a = a;
      m.b = b;
    }
  }
  m.sigma_m = lineEndpointSigmaM(L, sightings, m.a, m.b, focal_length_, options_.pixel_sigma);
  return m;
}

void LineLandmarks::appendSightings(const WindowFrame& f, const LineFrameObs& o,
                                   std::vector<LineSighting>* out) const {
  const Pose T_W_B = f.T_W_B() * f.capture_shift;
  out->push_back({T_W_B * T_B_C0_, o.s0, o.e0, f.t});
  if (o.has_right) out->push_back({T_W_B * *T_B_C1_, o.s1, o.e1, f.t});
}

void LineLandmarks::removeFrame(const Window& window, FrameId frame) {
  const WindowFrame* f = window.find(frame);
  for (auto it = landmarks_.begin(); it != landmarks_.end();) {
    LineLandmark& lm = it->second;
    const auto o = lm.obs.find(frame);
    if (o != lm.obs.end() && options_.map_refine && f != nullptr) {
      appendSightings(*f, o->second, &lm.left_window);
      // Bounded: a line tracked for long (a camera at rest drops a frame per image) keeps every other sighting once
      // it has 2 x kMaxSightings, so memory and the refinement's cost stay bounded; the first is always kept.
      if (lm.left_window.size() > 2 * kMaxSightings) {
        std::size_t n = 0;
        for (std::size_t k = 0; k < lm.left_window.size(); k += 2) lm.left_window[n++] = lm.left_window[k];
        lm.left_window.resize(n);
      }
    }
    if (o != lm.obs.end()) lm.obs.erase(o);
    if (lm.obs.empty()) {
      if (lm.solved) archive(lm);
      it = landmarks_.erase(it);
    } else {
      ++it;
    }
  }
  // Aliases of lines that left the window (or were removed) end: the id starts a line of its own if seen again.
  for (auto a = alias_.begin(); a != alias_.end();) a = landmarks_.count(a->second) ? std::next(a) : alias_.erase(a);
}

void LineLandmarks::clear() {
  for (auto& [id, lm] : landmarks_)
    if (lm.solved) archive(lm);
  landmarks_.clear();
  alias_.clear();
}

double LineLandmarks::sightingErrorsPx(const WindowCameras& cams, const LineLandmark& lm,
                                       std::vector<std::array<double, 2>>* errors) const {
  const Vec6 L = lm.L();
  errors->clear();
  double sum = 0.0;
  int n = 0;
  for (const auto& [fid, o] : lm.obs) {
    const Pose* c0 = cams.cam0(fid);
    if (c0 == nullptr) {
      errors->push_back({std::numeric_limits<double>::quiet_NaN(), 0.0});
      continue;
    }
    const double e0 = lineReprojectionErrorPxFromCw(L, *c0, o.s0, o.e0, focal_length_);
    const double e1 = o.has_right ? lineReprojectionErrorPxFromCw(L, *cams.cam1(fid), o.s1, o.e1, focal_length_) : 0.0;
    errors->push_back({e0, e1});
    sum += e0;
    ++n;
    if (o.has_right) {
      sum += e1;
      ++n;
    }
  }
  return n == 0 ? 0.0 : sum / n;
}

LineLandmarks::BadPart LineLandmarks::badPart(double cam0_px, double cam1_px, const LineFrameObs& o) const {
  if (cam0_px > options_.max_observation_px) return BadPart::kCam0;
  if (o.has_right && cam1_px > options_.max_observation_px) return BadPart::kCam1;
  return BadPart::kNone;
}

int LineLandmarks::gateNewest(const Window& window) {
  // Before the solve, at the newest frame's predicted pose: a bad sighting would pull that pose in the very solve
  // whose result is the output (the check after the solve comes too late for it). Only lines already solved have
  // geometry good enough to judge by.
  const WindowFrame& newest = window.newest();
  const Pose T_W_B = newest.T_W_B();
  const Pose T_C0_W = (T_W_B * T_B_C0_).inverse();
  const std::optional<Pose> T_C1_W = T_B_C1_ ? std::optional<Pose>((T_W_B * *T_B_C1_).inverse()) : std::nullopt;
  int dropped = 0;
  for (auto& [id, lm] : landmarks_) {
    if (!lm.solved || !lm.triangulated) continue;
    const auto it = lm.obs.find(newest.id);
    if (it == lm.obs.end()) continue;
    const Vec6 L = lm.L();
    const LineFrameObs& o = it->second;
    const double e0 = lineReprojectionErrorPxFromCw(L, T_C0_W, o.s0, o.e0, focal_length_);
    const double e1 = e0 <= options_.max_observation_px && o.has_right
                          ? lineReprojectionErrorPxFromCw(L, *T_C1_W, o.s1, o.e1, focal_length_)
                          : 0.0;
    const BadPart bad = badPart(e0, e1, o);
    if (bad != BadPart::kNone) ++dropped;
    if (bad == BadPart::kCam0)
      lm.obs.erase(it);
    else if (bad == BadPart::kCam1)
      it->second.has_right = false;
  }
  return dropped;
}

int LineLandmarks::rejectOutliers(const Window& window) {
  rejections_ = LineRejectionStats{};
  const WindowFrame& newest = window.newest();
  const Pose T_W_C = newest.T_W_B() * T_B_C0_;
  const double min_sin_view = std::sin(options_.min_view_angle_deg * kDegToRad);
  const WindowCameras cams(window, T_B_C0_, T_B_C1_);
  std::vector<std::array<double, 2>> errors;  // each window sighting's cam0 / cam1 error, pixels (NaN: not in it)
  int removed = 0;
  for (auto it = landmarks_.begin(); it != landmarks_.end();) {
    LineLandmark& lm = it->second;
    if (!lm.used) {
      ++it;
      continue;
    }
    const Vec6 L = lm.L();
    bool bad = false;
    // Each sighting's error once: their mean judges the line, each alone its sighting.
    if (!L.allFinite() || sightingErrorsPx(cams, lm, &errors) > options_.outlier_px) {
      ++rejections_.reprojection;
      bad = true;
    } else {
      // A good line with one bad frame keeps its other sightings: a frame's cam0 segment with its cam1 one, or only
      // cam1 (a segment matched to a neighbouring parallel edge, a stereo mismatch would keep pulling its frame's
      // pose through the robust loss' linear tail).
      std::size_t k = 0;
      for (auto o = lm.obs.begin(); o != lm.obs.end(); ++k) {
        const BadPart part = std::isnan(errors[k][0]) ? BadPart::kNone : badPart(errors[k][0], errors[k][1], o->second);
        if (part != BadPart::kNone) ++rejections_.sightings;
        if (part == BadPart::kCam0) {
          o = lm.obs.erase(o);
          continue;
        }
        if (part == BadPart::kCam1) o->second.has_right = false;
        ++o;
      }
      if (lm.obs.size() < 2) {
        ++rejections_.reprojection;
        bad = true;
      }
    }
    const auto o = lm.obs.find(newest.id);
    if (!bad && o != lm.obs.end()) {
      Vec3 a, b;
      if (!backProject(L, T_W_C, o->second.s0, o->second.e0, &a, &b)) {
        ++rejections_.depth;
        bad = true;
      } else {
        // End-on: the line's direction close to the viewing ray of the observed midpoint.
        const Vec3 mid = 0.5 * (a + b);
        const Vec3 ray = (mid - T_W_C.p).normalized();
        if (pluckerDirection(L).cross(ray).norm() < min_sin_view) {
          ++rejections_.end_on;
          bad = true;
        } else if (lm.has_extent) {
          // Drift: the new back-projected segment must touch the extent (within max_extent_gap_m).
          if (extentGap(L, lm.a, lm.b, a, b) > options_.max_extent_gap_m) {
            ++rejections_.drifted;
            bad = true;
          }
        }
        if (!bad) {
          // Triangulation quality so far: the newest cam0 plane against the first one, and the stereo pair.
          const Eigen::Vector4d p_new = backProjectionPlane(T_W_C, o->second.s0, o->second.e0);
          double sin_angle = 0.0;
          if (lm.has_first_plane) {
            intersectPlanes(lm.first_plane, p_new, &sin_angle);
            lm.max_sin_angle = std::max(lm.max_sin_angle, sin_angle);
          }
          if (o->second.has_right) {
            intersectPlanes(p_new, backProjectionPlane(newest.T_W_B() * *T_B_C1_, o->second.s1, o->second.e1),
                            &sin_angle);
            lm.max_sin_angle = std::max(lm.max_sin_angle, sin_angle);
          }
          extend(lm, a, b);
          if ((lm.b - lm.a).norm() > options_.max_length_m) {
            ++rejections_.depth;
            bad = true;
          }
        }
      }
    }
    if (bad) {
      it = landmarks_.erase(it);
      ++removed;
    } else {
      ++it;
    }
  }
  return removed;
}

int LineLandmarks::countTriangulatedIn(FrameId frame) const {
  int n = 0;
  for (const auto& [id, lm] : landmarks_)
    if (lm.triangulated && lm.obs.count(frame)) ++n;
  return n;
}

int LineLandmarks::countObservedIn(FrameId frame) const {
  int n = 0;
  for (const auto& [id, lm] : landmarks_) n += lm.obs.count(frame) ? 1 : 0;
  return n;
}

int LineLandmarks::countUsed() const {
  int n = 0;
  for (const auto& [id, lm] : landmarks_) n += lm.used ? 1 : 0;
  return n;
}

std::vector<MapLine> LineLandmarks::windowLines() const {
  std::vector<MapLine> out;
  for (const auto& [id, lm] : landmarks_)
    if (lm.triangulated && lm.has_extent) out.push_back(currentMapLine(id, lm));
  if (alias_.empty()) return out;
  // A re-identified front-end id names its line too (the loop closer looks lines up by the front-end's ids).
  const std::size_t n = out.size();
  for (const auto& [from, to] : alias_) {
    const auto it = std::lower_bound(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(n), to,
                                     [](const MapLine& m, std::int64_t id) { return m.id < id; });
    if (it == out.begin() + static_cast<std::ptrdiff_t>(n) || it->id != to) continue;
    MapLine copy = *it;
    copy.id = from;
    out.push_back(copy);
  }
  std::sort(out.begin(), out.end(), [](const MapLine& x, const MapLine& y) { return x.id < y.id; });
  return out;
}

std::map<std::int64_t, std::vector<LineSighting>> LineLandmarks::mapSightings(const Window& window) const {
  std::map<std::int64_t, std::vector<LineSighting>> out = map_sightings_;
  if (map_sightings_.empty() && !options_.map.adjust) return out;
  for (const auto& [id, lm] : landmarks_) {
    if (!lm.triangulated || !lm.has_extent) continue;
    std::vector<LineSighting>& s = out[id];
    s = lm.left_window;
    for (const auto& [fid, o] : lm.obs)
      if (const WindowFrame* f = window.find(fid)) appendSightings(*f, o, &s);
  }
  return out;
}

std::vector<MapLine> LineLandmarks::mapLines(const Window* window) const {
  // The window's lines, by increasing id (landmarks_ is ordered by id); they replace the map's of the same id.
  std::vector<MapLine> window_lines;
  for (const auto& [id, lm] : landmarks_) {
    if (!lm.triangulated || !lm.has_extent) continue;
    if (window == nullptr || !options_.map_refine) {
      window_lines.push_back(currentMapLine(id, lm));
      continue;
    }
    // Its sightings that left the window, then those in it (as removeFrame will add them).
    std::vector<LineSighting> sightings = lm.left_window;
    for (const auto& [fid, o] : lm.obs)
      if (const WindowFrame* f = window->find(fid)) appendSightings(*f, o, &sightings);
    window_lines.push_back(mapLineOf(lm, sightings));
  }
  std::vector<MapLine> out;
  out.reserve(map_.size() + window_lines.size());
  auto w = window_lines.begin();
  for (const StoredMapLine& m : map_) {
    for (; w != window_lines.end() && w->id < m.id; ++w) out.push_back(*w);
    if (w != window_lines.end() && w->id == m.id) {
      out.push_back(*w);
      ++w;
    } else {
      out.push_back(m.line());
    }
  }
  out.insert(out.end(), w, window_lines.end());
  return out;
}

}  // namespace linnet
