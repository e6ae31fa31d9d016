// The line front-end (see line_tracker.h).
#include "linnet/features/line_tracker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <functional>
#include <limits>
#include <numbers>
#include <numeric>
#include <string>

#include "linnet/core/cpu_clock.h"
#include "linnet/core/error.h"
#include "linnet/core/options.h"
#include "linnet/geometry/plucker.h"

namespace linnet {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// True when `seg` lies on `other` (same direction within 5 degrees, both endpoints within 3 px of its line,
// overlapping it).
bool liesOn(const LineSegment& seg, const LineSegment& other) {
  const Vec2 td = other.direction();
  if (std::abs(td.dot(seg.direction())) < 0.996) return false;
  const Vec2 n(-td.y(), td.x());
  if (std::abs((seg.s - other.s).dot(n)) > 3.0 || std::abs((seg.e - other.s).dot(n)) > 3.0) return false;
  const double a = (seg.s - other.s).dot(td), b = (seg.e - other.s).dot(td);
  return !(std::max(a, b) < -5.0 || std::min(a, b) > other.length() + 5.0);
}

// True when `seg` lies on one of the tracks: a second detection of a tracked edge must not start a new id.
bool duplicatesTrack(const LineSegment& seg, const std::vector<LineTracker::Track>& tracks) {
  return std::any_of(tracks.begin(), tracks.end(), [&](const LineTracker::Track& t) { return liesOn(seg, t.px); });
}

// Keeps the part of a pixel segment inside the image less `margin` pixels (Liang-Barsky clipping); false when none is.
bool clipToImage(const CameraModel& cam, double margin, LineSegment* seg) {
  const Vec2 lo(margin, margin), hi(cam.width() - 1.0 - margin, cam.height() - 1.0 - margin);
  const Vec2 d = seg->e - seg->s;
  double t0 = 0.0, t1 = 1.0;
  for (int ax = 0; ax < 2; ++ax) {
    if (std::abs(d[ax]) < 1e-12) {
      if (seg->s[ax] < lo[ax] || seg->s[ax] > hi[ax]) return false;
      continue;
    }
    double ta = (lo[ax] - seg->s[ax]) / d[ax], tb = (hi[ax] - seg->s[ax]) / d[ax];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (!(t1 > t0)) return false;
  const Vec2 s0 = seg->s;
  seg->s = s0 + t0 * d;
  seg->e = s0 + t1 * d;
  return true;
}

}  // namespace

LineTracker::LineTracker(const LineTrackerOptions& options, const CameraModel& cam0, const CameraModel* cam1,
                         const Pose& T_C1_C0)
    : options_(options), cam0_(cam0), cam1_(cam1), T_C1_C0_(T_C1_C0), detector_(options.detection) {
  validateOptions(options_, "lines");
  guided_refine_ = options_.detection;
  guided_refine_.refine_search_px = options_.stereo.guided_search_px;
  predicted_refine_ = options_.detection;
  predicted_refine_.refine_search_px = options_.temporal.predicted_search_px;
  if (options_.stereo.min_depth_m >= options_.stereo.max_depth_m)
    throw ConfigError("config key 'lines.stereo.min_depth_m' must be below 'lines.stereo.max_depth_m'");
  if (cam1_ != nullptr && T_C1_C0_.p.norm() < 1e-6)
    throw ConfigError("LineTracker: stereo extrinsics T_C1_C0 have no baseline");
}

void LineTracker::checkImage(const cv::Mat& img, const CameraModel& cam, const char* which) const {
  if (img.type() != CV_8UC1)
    throw UsageError(std::string("LineTracker::track: ") + which + " image is not 8-bit grey (CV_8UC1)");
  if (img.cols != cam.width() || img.rows != cam.height())
    throw UsageError(std::string("LineTracker::track: ") + which + " image is " + std::to_string(img.cols) + "x" +
                     std::to_string(img.rows) + ", the camera is " + std::to_string(cam.width()) + "x" +
                     std::to_string(cam.height()));
}

void LineTracker::detectAndMerge(const cv::Mat& img, std::vector<LineSegment>* segs,
                                 std::vector<LbdDescriptor>* descs, std::vector<char>* described,
                                 LineFrameTimings* tm) {
  auto t0 = Clock::now();
  detector_.detect(img, segs, /*refine=*/false);  // refined lazily: only the segments delivered
  tm->detect_ms += msSince(t0);
  descs->clear();
  described->clear();
  t0 = Clock::now();
  double describe_ms = 0.0;
  const SegmentDescriber describe = [&](const LineSegment& seg) {
    const auto td = Clock::now();
    const LbdDescriptor d = binarizeLbd(computeLbdFloat(img, options_.lbd, seg));
    describe_ms += msSince(td);
    return d;
  };
  mergeSegments(options_.merge, describe, segs, descs, described);
  tm->merge_ms += msSince(t0) - describe_ms;
  tm->describe_ms += describe_ms;
}

void LineTracker::refine(const cv::Mat& img, LineSegment* seg) const {
  if (options_.detection.refine) refineSegment(img, options_.detection, seg);
}

bool LineTracker::undistortSegment(const CameraModel& cam, const LineSegment& px, LineSegment* uv) const {
  return cam.undistort(px.s, &uv->s) && cam.undistort(px.e, &uv->e) && (uv->e - uv->s).norm() > 1e-9;
}

bool LineTracker::rotateSegment(const Mat3& R_Ccur_Cprev, LineSegment* px, const LineSegment* uv_known) const {
  LineSegment uv;
  if (uv_known != nullptr)
    uv = *uv_known;
  else if (!undistortSegment(cam0_, *px, &uv))
    return false;
  LineSegment out;
  if (!cam0_.project(R_Ccur_Cprev * Vec3(uv.s.x(), uv.s.y(), 1.0), &out.s) ||
      !cam0_.project(R_Ccur_Cprev * Vec3(uv.e.x(), uv.e.y(), 1.0), &out.e) || !std::isfinite(out.s.sum() + out.e.sum()))
    return false;
  *px = out;
  return true;
}

void LineTracker::track(Timestamp t, const cv::Mat& left, const cv::Mat& right, std::vector<LineObservation>* lines) {
  const auto t_start = Clock::now();
  const double cpu_start = threadCpuMs();
  if (has_last_ && t < last_t_)
    throw UsageError("LineTracker::track: time stamp " + std::to_string(t) + " ns is before the previous " +
                     std::to_string(last_t_) + " ns");
  checkImage(left, cam0_, "left");
  const bool stereo = options_.match_stereo && cam1_ != nullptr && !right.empty();
  if (stereo) checkImage(right, *cam1_, "right");
  LineFrameTimings tm;

  // Left image: detect, merge (or predict the previous frame's lines, temporal.detect_interval); descriptors on
  // demand (temporal candidates and the segments chosen as new tracks).
  double describe_left_ms = 0.0;
  auto leftDesc = [&](int i) -> const LbdDescriptor& {
    if (!described_l_[i]) {
      const auto td = Clock::now();
      desc_l_[i] = binarizeLbd(computeLbdFloat(left, options_.lbd, segs_l_[i]));
      described_l_[i] = 1;
      describe_left_ms += msSince(td);
    }
    return desc_l_[i];
  };

  // Temporal matching against the lines delivered last frame.
  auto t0 = Clock::now();
  const double stages_at_t0 = tm.detect_ms + tm.merge_ms + tm.describe_ms;
  // Candidates: the lines delivered last frame, then the recently lost ones (missed for <= max_missed frames).
  std::vector<const Track*> prev;
  prev.reserve(tracks_.size() + lost_.size() + tentative_.size());
  for (const Track& tr : tracks_) prev.push_back(&tr);
  for (const Track& tr : lost_) prev.push_back(&tr);
  for (const Track& tr : tentative_) prev.push_back(&tr);
  std::vector<LineSegment> prev_segs(prev.size());
  std::vector<LbdDescriptor> prev_desc(prev.size());
  std::optional<Mat3> R_pred;
  R_pred.swap(R_pred_);
  for (std::size_t k = 0; k < prev.size(); ++k) {
    prev_segs[k] = prev[k]->px;
    prev_desc[k] = prev[k]->desc;
    const Track& tr = *prev[k];
    const bool uv_known = tr.has_uv && tr.uv_of.s == tr.px.s && tr.uv_of.e == tr.px.e;
    if (R_pred) rotateSegment(*R_pred, &prev_segs[k], uv_known ? &tr.uv : nullptr);
  }
  std::vector<int> match_of_cur;
  const double dt = has_last_ ? toSeconds(t - last_t_) : 0.0;
  const TemporalMatchOptions& to = options_.temporal;
  bool detect_left = true;
  if (to.detect_interval > 1 && frames_since_left_detection_ + 1 < to.detect_interval && !tracks_.empty()) {
    const int found = predictLeft(left, prev, prev_segs, dt, &match_of_cur, &tm);
    detect_left = found < to.predicted_min_fraction * static_cast<double>(tracks_.size());
    if (!detect_left) tm.tracked = tm.left_predicted = found;
  }
  if (detect_left) {
    frames_since_left_detection_ = 0;
    detectAndMerge(left, &segs_l_, &desc_l_, &described_l_, &tm);
    tm.detected_left = static_cast<int>(segs_l_.size());
    const Vec2 centre(0.5 * (left.cols - 1), 0.5 * (left.rows - 1));
    match_of_cur.clear();
    tm.tracked = matchTemporal(to, prev_segs, prev_desc, segs_l_, std::function<const LbdDescriptor&(int)>(leftDesc),
                               centre, &match_of_cur);
  } else {
    ++frames_since_left_detection_;
    tm.left_detected = false;
  }
  std::vector<Track> next;
  next.reserve(options_.max_lines);
  std::vector<char> used(segs_l_.size(), 0), prev_matched(prev.size(), 0);
  for (std::size_t i = 0; i < segs_l_.size(); ++i) {
    if (match_of_cur[i] < 0) continue;
    const Track& old = *prev[match_of_cur[i]];
    Track t = old;  // keeps its stereo prior, turned into this frame
    rotatePrior(R_pred, &t);
    // Its motion beyond the rotation since it was last seen (the rotation-predicted segment stands for that).
    const double span = dt * (1 + old.missed);
    t.flow = span > 0.0 ? Vec2((segs_l_[i].midpoint() - prev_segs[match_of_cur[i]].midpoint()) / span) : Vec2::Zero();
    t.px = segs_l_[i];
    t.desc = leftDesc(static_cast<int>(i));
    ++t.length;
    t.missed = 0;
    t.tentative = false;
    next.push_back(t);
    if (old.tentative) {  // confirmed: delivered from now on
      --tm.tracked;
      ++tm.new_lines;
    }
    used[i] = 1;
    prev_matched[match_of_cur[i]] = 1;
  }
  // Unmatched tracks wait up to max_missed frames to be found again (detections flicker).
  // A new line that a predicted frame misses (it has no flow yet) stays tentative until the next detection.
  std::vector<Track> lost, still_tentative;
  for (std::size_t k = 0; k < prev.size(); ++k) {
    if (prev_matched[k] || prev[k]->missed + 1 > options_.max_missed) continue;
    if (prev[k]->tentative && detect_left) continue;
    Track t = *prev[k];
    rotatePrior(R_pred, &t);
    t.px = prev_segs[k];  // where the rotation prediction put it (unchanged without one)
    ++t.missed;
    (t.tentative ? still_tentative : lost).push_back(t);
  }
  lost_.swap(lost);
  // Keep the longest-lived tracks if more matched than max_lines (only when max_lines shrank).
  if (static_cast<int>(next.size()) > options_.max_lines) {
    std::stable_sort(next.begin(), next.end(), [](const Track& a, const Track& b) { return a.length > b.length; });
    next.resize(options_.max_lines);
    tm.tracked = options_.max_lines;
  }
  // Replenishment: unmatched segments, longest first, spread over a grid.
  const int gc = options_.grid_cols, gr = options_.grid_rows;
  std::vector<int> cell_new(gc * gr, 0);
  auto cellOf = [&](const LineSegment& s) {
    const Vec2 m = s.midpoint();
    const int cx = std::clamp(static_cast<int>(m.x() * gc / left.cols), 0, gc - 1);
    const int cy = std::clamp(static_cast<int>(m.y() * gr / left.rows), 0, gr - 1);
    return cy * gc + cx;
  };
  // With confirm_new, a new segment is a tentative track (not delivered) until it is matched in the next frame.
  std::vector<Track> tentative;
  for (std::size_t i = 0; i < segs_l_.size(); ++i) {
    if (static_cast<int>(next.size() + tentative.size()) >= options_.max_lines) break;
    if (used[i] || segs_l_[i].length() < options_.min_new_length_px) continue;
    const int c = cellOf(segs_l_[i]);
    if (cell_new[c] >= options_.max_new_per_cell) continue;
    if (duplicatesTrack(segs_l_[i], next) || duplicatesTrack(segs_l_[i], tentative)) continue;
    ++cell_new[c];
    Track t{next_id_++, segs_l_[i], leftDesc(static_cast<int>(i)), 1, 0, options_.confirm_new};
    if (options_.confirm_new) {
      tentative.push_back(t);
    } else {
      next.push_back(t);
      ++tm.new_lines;
    }
  }
  tentative.insert(tentative.end(), still_tentative.begin(), still_tentative.end());
  tentative_.swap(tentative);
  std::sort(next.begin(), next.end(), [](const Track& a, const Track& b) { return a.id < b.id; });
  tracks_.swap(next);
  tm.temporal_ms = msSince(t0) - describe_left_ms - (tm.detect_ms + tm.merge_ms + tm.describe_ms - stages_at_t0);
  tm.describe_ms += describe_left_ms;
  t0 = Clock::now();
  for (Track& tr : tracks_) refine(left, &tr.px);
  tm.detect_ms += msSince(t0);
  tm.left_ms = msSince(t_start);
  tm.cpu_left_ms = threadCpuMs() - cpu_start;

  // Observations in cam0.
  t0 = Clock::now();
  std::vector<LineObservation> out;
  out.reserve(tracks_.size());
  std::vector<LineSegment> left_uv;
  std::vector<LbdDescriptor> left_desc;
  std::vector<int> track_of_left;
  for (std::size_t ti = 0; ti < tracks_.size(); ++ti) {
    Track& tr = tracks_[ti];
    LineObservation ob;
    LineSegment uv;
    tr.has_uv = false;
    if (!undistortSegment(cam0_, tr.px, &uv)) continue;
    tr.uv = uv;
    tr.uv_of = tr.px;
    tr.has_uv = true;
    ob.id = tr.id;
    ob.ps0 = tr.px.s;
    ob.pe0 = tr.px.e;
    ob.s0 = uv.s;
    ob.e0 = uv.e;
    ob.track_length = tr.length;
    track_of_left.push_back(static_cast<int>(ti));
    left_uv.push_back(uv);
    left_desc.push_back(tr.desc);
    out.push_back(ob);
  }
  tm.stereo_ms = msSince(t0);
  if (stereo) matchRight(right, left_uv, left_desc, track_of_left, &out, &tm);
  lines->insert(lines->end(), out.begin(), out.end());
  last_t_ = t;
  has_last_ = true;
  ++frame_index_;
  tm.total_ms = msSince(t_start);
  tm.cpu_total_ms = threadCpuMs() - cpu_start;
  timings_ = tm;
}

int LineTracker::predictLeft(const cv::Mat& left, const std::vector<const Track*>& prev,
                             const std::vector<LineSegment>& prev_segs, double dt, std::vector<int>* match_of_cur,
                             LineFrameTimings* tm) {
  const TemporalMatchOptions& to = options_.temporal;
  segs_l_.clear();
  desc_l_.clear();
  described_l_.clear();
  match_of_cur->clear();
  // Lines delivered last frame with a measured flow lend it to those without one (new last frame).
  std::vector<LineSegment> donor_segs;
  std::vector<Vec2> donor_flows;
  for (std::size_t k = 0; k < prev.size(); ++k) {
    if (prev[k]->length < 2 || prev[k]->missed > 0 || prev[k]->tentative) continue;
    donor_segs.push_back(prev_segs[k]);
    donor_flows.push_back(prev[k]->flow);
  }
  for (std::size_t k = 0; k < prev.size(); ++k) {
    const Track& tr = *prev[k];
    LineSegment seg = prev_segs[k];
    if (!(seg.length() > 1.0)) continue;
    // Moved across itself by its last flow (along the line a segment's ends are not observed: that part is noise).
    const Vec2 flow =
        tr.length >= 2 ? tr.flow : neighbourFlow(seg, donor_segs, donor_flows, to.predicted_flow_neighbours);
    const Vec2 d = seg.direction(), n(-d.y(), d.x());
    const Vec2 shift = n * (n.dot(flow) * dt * (1 + tr.missed));
    seg.s += shift;
    seg.e += shift;
    const auto tr0 = Clock::now();
    double support = 0.0;
    const bool ok = clipToImage(cam0_, 2.0, &seg) && seg.length() >= options_.detection.min_length_px &&
                    refineSegment(left, predicted_refine_, &seg, &support, /*trim=*/true) &&
                    support >= to.predicted_min_support;
    tm->detect_ms += msSince(tr0);
    if (!ok) continue;
    // Two lines refined onto one edge: the first (the older delivered track) keeps it. Refined segments are oriented
    // by their gradient, so the two sides of a thin bar (opposite directions) are two edges.
    if (std::any_of(segs_l_.begin(), segs_l_.end(),
                    [&](const LineSegment& o) { return o.direction().dot(seg.direction()) > 0.0 && liesOn(seg, o); }))
      continue;
    const auto td = Clock::now();
    const LbdDescriptor desc = binarizeLbd(computeLbdFloat(left, options_.lbd, seg));
    tm->describe_ms += msSince(td);
    if (to.predicted_max_hamming < 256 && hammingDistance(desc, tr.desc) > to.predicted_max_hamming) continue;
    segs_l_.push_back(seg);
    desc_l_.push_back(desc);
    described_l_.push_back(1);
    match_of_cur->push_back(static_cast<int>(k));
  }
  return static_cast<int>(segs_l_.size());
}

void LineTracker::rotatePrior(const std::optional<Mat3>& R_Ccur_Cprev, Track* track) const {
  if (!R_Ccur_Cprev || track->stereo_frame < 0) return;
  track->stereo_s = *R_Ccur_Cprev * track->stereo_s;
  track->stereo_e = *R_Ccur_Cprev * track->stereo_e;
}

bool LineTracker::predictRight(const Track& track, const LineSegment& left_uv, LineSegment* px) const {
  // The line as triangulated at its last match, turned into this frame; each current left endpoint takes the depth of
  // its ray's closest point to it (the line's current image is the left segment, so only depths are needed).
  const Vec6 L = pluckerFromPoints(track.stereo_s, track.stereo_e);
  const Vec2 ends[2] = {left_uv.s, left_uv.e};
  Vec2 out[2];
  for (int k = 0; k < 2; ++k) {
    // The ray is (x, y, 1) from the camera centre, so its parameter is the depth.
    const std::optional<RayLinePoint> p = closestPointToRay(L, Vec3::Zero(), Vec3(ends[k].x(), ends[k].y(), 1.0));
    const double z = p ? p->ray_t : std::numeric_limits<double>::quiet_NaN();
    if (!(z >= options_.stereo.min_depth_m && z <= options_.stereo.max_depth_m)) return false;
    const Vec3 p1 = T_C1_C0_ * (z * Vec3(ends[k].x(), ends[k].y(), 1.0));
    if (!cam1_->project(p1, &out[k]) || !std::isfinite(out[k].sum())) return false;
  }
  // Keep the part inside cam1's image (the right camera sees less of the scene on one side).
  px->s = out[0];
  px->e = out[1];
  return clipToImage(*cam1_, 2.0, px) && px->length() >= options_.detection.min_length_px;
}

void LineTracker::matchRight(const cv::Mat& right, const std::vector<LineSegment>& left_uv, const std::vector<LbdDescriptor>& left_desc,
                             const std::vector<int>& track_of_left, std::vector<LineObservation>* out,
                             LineFrameTimings* tm) {
  const auto t_begin = Clock::now();
  const LineFrameTimings before = *tm;
  const StereoMatchOptions& so = options_.stereo;
  const Mat3 E = skew(T_C1_C0_.p) * T_C1_C0_.R();
  const double cos_stereo = std::cos(so.max_angle_deg * std::numbers::pi / 180.0);
  auto describeRight = [&](const LineSegment& seg) {
    const auto td = Clock::now();
    const LbdDescriptor d = binarizeLbd(computeLbdFloat(right, options_.lbd, seg));
    tm->describe_ms += msSince(td);
    return d;
  };
  // A right segment for left line k passes the direction and epipolar tests; then it is the line's observation in
  // cam1, and its triangulated endpoints are the track's prior for the next frame's guided pass.
  auto accept = [&](std::size_t k, const LineSegment& px) {
    LineSegment uv;
    double overlap = 0.0;
    Vec2 depth;
    if (!undistortSegment(*cam1_, px, &uv) || uv.direction().dot(left_uv[k].direction()) < cos_stereo ||
        !stereoGeometryOk(so, E, T_C1_C0_, left_uv[k], uv, &overlap, nullptr, nullptr, &depth))
      return false;
    LineObservation& ob = (*out)[k];
    ob.has_right = true;
    ob.ps1 = px.s;
    ob.pe1 = px.e;
    ob.s1 = uv.s;
    ob.e1 = uv.e;
    Track& tr = tracks_[track_of_left[k]];
    tr.stereo_frame = frame_index_;
    tr.stereo_s = depth.x() * Vec3(left_uv[k].s.x(), left_uv[k].s.y(), 1.0);
    tr.stereo_e = depth.y() * Vec3(left_uv[k].e.x(), left_uv[k].e.y(), 1.0);
    ++tm->stereo_matched;
    return true;
  };

  // The right image's full detection every detect_interval frames; in between, the guided pass: the lines matched
  // in the last frames, predicted and refined on the right image's edge. A frame where too few lines have such a
  // prior, against the matches of the last detection (the first frames, a view that changed), is detected instead.
  auto hasPrior = [&](const Track& tr) {
    return tr.stereo_frame >= 0 && frame_index_ - tr.stereo_frame <= so.guided_max_age;
  };
  const auto with_prior = std::count_if(track_of_left.begin(), track_of_left.end(),
                                        [&](int ti) { return hasPrior(tracks_[ti]); });
  // Staggered with predicted left lines: the right image is detected on the frames whose left lines are predicted
  // and guided on those whose left image is detected, so that every frame has one full detection.
  const bool due = so.stagger_with_left && options_.temporal.detect_interval > 1
                       ? !tm->left_detected
                       : frames_since_detection_ + 1 >= so.detect_interval;
  const bool guided_frame =
      !due && with_prior > 0 &&
      static_cast<double>(with_prior) >= so.guided_min_prior_fraction * detection_matches_;
  if (left_uv.empty()) {
    ++frames_since_detection_;
  } else if (guided_frame) {
    ++frames_since_detection_;
    for (std::size_t k = 0; k < left_uv.size(); ++k) {
      const Track& tr = tracks_[track_of_left[k]];
      if (!hasPrior(tr)) continue;
      LineSegment px;
      double support = 0.0;
      if (!predictRight(tr, left_uv[k], &px)) continue;
      if (!refineSegment(right, guided_refine_, &px, &support) || support < so.guided_min_support) continue;
      if (so.guided_max_hamming < 256 && hammingDistance(left_desc[k], describeRight(px)) > so.guided_max_hamming)
        continue;
      if (accept(k, px)) ++tm->stereo_guided;
    }
  } else {
    frames_since_detection_ = 0;
    tm->right_detected = true;
    detectAndMerge(right, &segs_r_, &desc_r_, &described_r_, tm);
    tm->detected_right = static_cast<int>(segs_r_.size());
    std::vector<LineSegment> right_uv;
    std::vector<int> right_index;
    for (std::size_t j = 0; j < segs_r_.size(); ++j) {
      LineSegment uv;
      if (!undistortSegment(*cam1_, segs_r_[j], &uv)) continue;
      right_uv.push_back(uv);
      right_index.push_back(static_cast<int>(j));
    }
    std::vector<LineMatchCandidate> cands;
    stereoCandidates(so, T_C1_C0_, left_uv, right_uv, &cands);
    for (LineMatchCandidate& c : cands) {
      const int j = right_index[c.j];
      if (!described_r_[j]) {
        desc_r_[j] = describeRight(segs_r_[j]);
        described_r_[j] = 1;
      }
      c.distance = hammingDistance(left_desc[c.i], desc_r_[j]);
    }
    std::vector<int> match_of_left;
    detection_matches_ = selectMutualBest(static_cast<int>(left_uv.size()), static_cast<int>(right_uv.size()), cands,
                                          so.max_hamming, so.ratio, &match_of_left);
    for (std::size_t k = 0; k < match_of_left.size(); ++k) {
      if (match_of_left[k] < 0) continue;
      const auto tr = Clock::now();
      LineSegment px = segs_r_[right_index[match_of_left[k]]];
      refine(right, &px);
      tm->detect_ms += msSince(tr);
      accept(k, px);  // the refined segment must still pass the tests
    }
  }
  tm->stereo_ms += msSince(t_begin) - (tm->detect_ms - before.detect_ms) - (tm->merge_ms - before.merge_ms) -
                   (tm->describe_ms - before.describe_ms);
}

}  // namespace linnet
