#include "linnet/estimator/point_landmarks.h"

#include <cmath>

#include "linnet/estimator/factors/point_factors.h"
#include "linnet/geometry/triangulation.h"

namespace linnet {

namespace {
constexpr double kDegToRad = M_PI / 180.0;
}

PointLandmarks::PointLandmarks(const SolverOptions& options, const Pose& T_B_C0, std::optional<Pose> T_B_C1)
    : options_(options), T_B_C0_(T_B_C0), T_B_C1_(std::move(T_B_C1)) {}

void PointLandmarks::observe(FrameId frame, const std::vector<PointObservation>& points) {
  for (const PointObservation& p : points) {
    PointLandmark& lm = landmarks_[p.id];
    if (lm.id < 0) lm.id = p.id;
    PointFrameObs o;
    o.uv0 = p.uv0;
    o.has_right = p.has_right && T_B_C1_.has_value();
    o.uv1 = p.uv1;
    lm.obs[frame] = o;
  }
}

Vec3 PointLandmarks::worldPosition(const Window& window, const PointLandmark& lm) const {
  const WindowFrame* host = window.find(lm.host);
  const PointFrameObs& o = lm.obs.at(lm.host);
  const Vec3 p_C = Vec3(o.uv0.x(), o.uv0.y(), 1.0) / lm.inv_depth;
  return host->T_W_B() * (T_B_C0_ * p_C);
}

bool PointLandmarks::triangulateOne(const Window& window, PointLandmark& lm) const {
  const FrameId host_id = lm.obs.begin()->first;
  const WindowFrame* host = window.find(host_id);
  if (host == nullptr) return false;
  const PointFrameObs& ho = lm.obs.begin()->second;
  const Pose T_W_C0 = host->T_W_B() * T_B_C0_;
  Vec3 p_W;
  bool ok = false;
  if (ho.has_right) {
    double parallax = 0.0;
    ok = triangulateTwoView(T_W_C0, ho.uv0, host->T_W_B() * *T_B_C1_, ho.uv1, &p_W, &parallax);
  }
  if (!ok && lm.obs.size() >= 2) {
    std::vector<Pose> T_W_C;
    std::vector<Vec2> uv;
    for (const auto& [fid, o] : lm.obs) {
      const WindowFrame* f = window.find(fid);
      if (f == nullptr) continue;
      T_W_C.push_back(f->T_W_B() * T_B_C0_);
      uv.push_back(o.uv0);
    }
    if (T_W_C.size() >= 2 && maxParallaxRad(T_W_C, uv) >= options_.min_triangulation_deg * kDegToRad)
      ok = triangulateDlt(T_W_C, uv, &p_W);
  }
  if (!ok) return false;
  const double depth = depthInCamera(T_W_C0, p_W);
  if (!depthOk(depth)) return false;
  lm.host = host_id;
  lm.inv_depth = 1.0 / depth;
  lm.triangulated = true;
  return true;
}

int PointLandmarks::triangulate(const Window& window) {
  int n = 0;
  for (auto& [id, lm] : landmarks_)
    if (!lm.triangulated && triangulateOne(window, lm)) ++n;
  return n;
}

std::vector<ResidualSpec> PointLandmarks::residuals(const Window& window, FrameId host_only, bool all_right,
                                                    const std::map<FrameId, double>& frame_weight) {
  reprojection_factors_.begin();
  stereo_factors_.begin();
  std::vector<ResidualSpec> out;
  const double base_sqrt_info = pointSqrtInformation(options_.focal_length, options_.pixel_sigma);
  const auto sqrtInfo = [&](FrameId f) {
    if (frame_weight.empty()) return base_sqrt_info;
    const auto w = frame_weight.find(f);
    return w == frame_weight.end() ? base_sqrt_info : base_sqrt_info * std::sqrt(w->second);
  };
  for (auto& [id, lm] : landmarks_) {
    if (host_only < 0) lm.used = false;
    if (!usable(lm)) continue;
    if (host_only >= 0 && lm.host != host_only) continue;
    WindowFrame* host = const_cast<Window&>(window).find(lm.host);
    if (host == nullptr) continue;
    const PointFrameObs& ho = lm.obs.at(lm.host);
    const std::int64_t lm_key = pointBlockKey(id);
    for (const auto& [fid, o] : lm.obs) {
      WindowFrame* f = const_cast<Window&>(window).find(fid);
      if (f == nullptr) continue;
      if (fid == lm.host) {
        if (!ho.has_right) continue;
        // Kind 3: left -> right in the host frame; constrains the inverse depth only.
        ResidualSpec r;
        r.cost = stereo_factors_.make(ho.uv0, ho.uv1, T_B_C0_, *T_B_C1_, sqrtInfo(fid));  // no shift
        r.robust = true;
        r.blocks = {&lm.inv_depth};
        r.keys = {lm_key};
        r.cam1 = ResidualSpec::kCam1Pair;
        out.push_back(std::move(r));
        continue;
      }
      // Kind 1: host cam0 -> this frame's cam0.
      const double sqrt_info = sqrtInfo(fid);
      ResidualSpec r1;
      const Pose T_B_Ch = host->capture_shift * T_B_C0_;
      r1.cost = reprojection_factors_.make(ho.uv0, o.uv0, T_B_Ch, f->capture_shift * T_B_C0_, sqrt_info);
      r1.robust = true;
      r1.blocks = {host->pose.data(), f->pose.data(), &lm.inv_depth};
      r1.keys = {frameBlockKey(lm.host, BlockKind::kPose), frameBlockKey(fid, BlockKind::kPose), lm_key};
      if (o.has_right && (all_right || options_.right_residuals_all_frames)) {
        // Kind 2: host cam0 -> this frame's cam1.
        ResidualSpec r2;
        r2.cost =
            reprojection_factors_.make(ho.uv0, o.uv1, T_B_Ch, f->capture_shift * *T_B_C1_, sqrt_info);
        r2.robust = true;
        r2.blocks = r1.blocks;
        r2.keys = r1.keys;
        r2.cam1 = 1;
        out.push_back(std::move(r1));
        out.push_back(std::move(r2));
      } else {
        out.push_back(std::move(r1));
      }
    }
    if (host_only < 0) lm.used = true;
  }
  return out;
}

std::vector<std::int64_t> PointLandmarks::hostedUsable(FrameId frame) const {
  std::vector<std::int64_t> ids;
  for (const auto& [id, lm] : landmarks_)
    if (usable(lm) && lm.host == frame) ids.push_back(id);
  return ids;
}

void PointLandmarks::removeFrame(const Window& window, FrameId frame) {
  for (auto it = landmarks_.begin(); it != landmarks_.end();) {
    PointLandmark& lm = it->second;
    auto o = lm.obs.find(frame);
    if (o == lm.obs.end()) {
      ++it;
      continue;
    }
    if (lm.obs.size() == 1) {
      it = landmarks_.erase(it);
      continue;
    }
    if (lm.triangulated && lm.host == frame) {
      // Re-anchor in the next observing frame: same world point, new host.
      const Vec3 p_W = worldPosition(window, lm);
      lm.obs.erase(o);
      const FrameId new_host = lm.obs.begin()->first;
      const WindowFrame* nh = window.find(new_host);
      lm.triangulated = false;
      if (nh != nullptr) {
        const double depth = depthInCamera(nh->T_W_B() * T_B_C0_, p_W);
        if (depthOk(depth)) {
          lm.host = new_host;
          lm.inv_depth = 1.0 / depth;
          lm.triangulated = true;
        }
      }
    } else {
      lm.obs.erase(o);
      if (!lm.triangulated) lm.host = lm.obs.begin()->first;
    }
    ++it;
  }
}

double PointLandmarks::meanErrorPx(const Window& window, const WindowCameras& cams, const PointLandmark& lm) const {
  const Vec3 p_W = worldPosition(window, lm);
  double sum = 0.0;
  int n = 0;
  auto add = [&](const Pose& T_C_W, const Vec2& uv) {
    const Vec3 p_C = T_C_W * p_W;
    if (p_C.z() <= 1e-6) {
      sum += 1e6;
    } else {
      sum += (p_C.head<2>() / p_C.z() - uv).norm() * options_.focal_length;
    }
    ++n;
  };
  for (const auto& [fid, o] : lm.obs) {
    const Pose* c0 = cams.cam0(fid);
    if (c0 == nullptr) continue;
    if (fid != lm.host) add(*c0, o.uv0);
    if (o.has_right) add(*cams.cam1(fid), o.uv1);
  }
  return n == 0 ? 0.0 : sum / n;
}

int PointLandmarks::rejectOutliers(const Window& window) {
  const WindowCameras cams(window, T_B_C0_, T_B_C1_);
  int removed = 0;
  for (auto it = landmarks_.begin(); it != landmarks_.end();) {
    const PointLandmark& lm = it->second;
    if (lm.used && (lm.inv_depth <= 0.0 || !depthOk(1.0 / lm.inv_depth) ||
                    meanErrorPx(window, cams, lm) > options_.outlier_px)) {
      it = landmarks_.erase(it);
      ++removed;
    } else {
      ++it;
    }
  }
  return removed;
}

int PointLandmarks::countTriangulatedIn(FrameId frame) const {
  int n = 0;
  for (const auto& [id, lm] : landmarks_)
    if (lm.triangulated && lm.obs.count(frame)) ++n;
  return n;
}

int PointLandmarks::countObservedIn(FrameId frame) const {
  int n = 0;
  for (const auto& [id, lm] : landmarks_) n += lm.obs.count(frame) ? 1 : 0;
  return n;
}

int PointLandmarks::countUsed() const {
  int n = 0;
  for (const auto& [id, lm] : landmarks_) n += lm.used ? 1 : 0;
  return n;
}

std::vector<std::pair<Vec2, Vec2>> PointLandmarks::correspondences(FrameId a, FrameId b) const {
  std::vector<std::pair<Vec2, Vec2>> out;
  for (const auto& [id, lm] : landmarks_) {
    auto ia = lm.obs.find(a), ib = lm.obs.find(b);
    if (ia != lm.obs.end() && ib != lm.obs.end()) out.emplace_back(ia->second.uv0, ib->second.uv0);
  }
  return out;
}

void PointLandmarks::triangulatedIn(const Window& window, FrameId frame, std::vector<Vec3>* p_W,
                                    std::vector<Vec2>* uv0) const {
  p_W->clear();
  uv0->clear();
  for (const auto& [id, lm] : landmarks_) {
    if (!lm.triangulated || lm.host == frame) continue;
    auto o = lm.obs.find(frame);
    if (o == lm.obs.end()) continue;
    p_W->push_back(worldPosition(window, lm));
    uv0->push_back(o->second.uv0);
  }
}

int PointLandmarks::countTriangulatedFromElsewhere(FrameId frame) const {
  int n = 0;
  for (const auto& [id, lm] : landmarks_) n += lm.triangulated && lm.host != frame && lm.obs.count(frame) ? 1 : 0;
  return n;
}

std::vector<Vec3> PointLandmarks::positions(const Window& window) const {
  std::vector<Vec3> out;
  for (const auto& [id, lm] : landmarks_)
    if (lm.triangulated && window.find(lm.host) != nullptr) out.push_back(worldPosition(window, lm));
  return out;
}

}  // namespace linnet
