// Line segment detection and sub-pixel refinement (see line_detector.h).
#include "linnet/features/line_detector.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "linnet/core/error.h"
#include "linnet/core/options.h"

namespace linnet {
namespace {

// Bilinear grey value at (x, y); the caller guarantees 0 <= x < cols - 1, 0 <= y < rows - 1.
inline float bilinear(const cv::Mat& img, float x, float y) {
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const float ax = x - static_cast<float>(x0), ay = y - static_cast<float>(y0);
  const std::uint8_t* r0 = img.ptr<std::uint8_t>(y0) + x0;
  const std::uint8_t* r1 = r0 + img.step[0];
  const float top = static_cast<float>(r0[0]) + ax * (static_cast<float>(r0[1]) - static_cast<float>(r0[0]));
  const float bot = static_cast<float>(r1[0]) + ax * (static_cast<float>(r1[1]) - static_cast<float>(r1[0]));
  return top + ay * (bot - top);
}

}  // namespace

LineDetector::LineDetector(const LineDetectorOptions& options) : options_(options) {
  validateOptions(options_, "lines.detector");
  if (options_.fld_canny_low > options_.fld_canny_high)
    throw ConfigError("config key 'lines.detector.fld_canny_low' must not exceed 'fld_canny_high'");
  if (options_.detector == "lsd") {
    lsd_ = cv::createLineSegmentDetector(cv::LSD_REFINE_NONE, options_.lsd_scale);
  } else if (options_.detector == "fld") {
    const float min_len = static_cast<float>(options_.min_length_px / options_.downsample * 0.7);
    fld_ = cv::ximgproc::createFastLineDetector(static_cast<int>(std::max(4.0f, min_len)), 1.41421356f,
                                                options_.fld_canny_low, options_.fld_canny_high, 3, false);
  } else {
    ed_ = cv::ximgproc::createEdgeDrawing();
    cv::ximgproc::EdgeDrawing::Params p;
    p.GradientThresholdValue = options_.edlines_gradient_threshold;
    p.AnchorThresholdValue = options_.edlines_anchor_threshold;
    p.Sigma = static_cast<float>(options_.edlines_sigma);
    p.MinLineLength = std::max(4, static_cast<int>(options_.min_length_px / options_.downsample * 0.7));
    p.NFAValidation = false;
    ed_->setParams(p);
  }
}

void LineDetector::detectRaw(const cv::Mat& gray, std::vector<cv::Vec4f>* raw) {
  raw->clear();
  const int f = options_.downsample;
  const cv::Mat* input = &gray;
  if (f > 1) {
    cv::resize(gray, small_, cv::Size(gray.cols / f, gray.rows / f), 0.0, 0.0, cv::INTER_AREA);
    input = &small_;
  }
  if (input->cols < 8 || input->rows < 8) return;
  if (lsd_) {
    lsd_->detect(*input, *raw);
  } else if (fld_) {
    fld_->detect(*input, *raw);
  } else {
    ed_->detectEdges(*input);
    ed_->detectLines(*raw);
  }
  if (f > 1) {
    // INTER_AREA: pixel u of the small image covers full-resolution pixels f*u .. f*u + f - 1.
    const float scale = static_cast<float>(f), offset = 0.5f * static_cast<float>(f - 1);
    for (cv::Vec4f& l : *raw)
      for (int k = 0; k < 4; ++k) l[k] = l[k] * scale + offset;
  }
}

void LineDetector::detect(const cv::Mat& gray, std::vector<LineSegment>* segments, bool refine) {
  segments->clear();
  if (gray.empty()) return;
  if (gray.type() != CV_8UC1) throw UsageError("LineDetector::detect: expected an 8-bit single-channel image");
  detectRaw(gray, &raw_);
  const double slack = refine ? 0.8 : 1.0;  // refinement may lengthen nothing, but shorten by projection
  segments->reserve(raw_.size());
  for (const cv::Vec4f& l : raw_) {
    LineSegment seg;
    seg.s = Vec2(l[0], l[1]);
    seg.e = Vec2(l[2], l[3]);
    if (!std::isfinite(seg.s.sum() + seg.e.sum())) continue;
    if (seg.length() < slack * options_.min_length_px) continue;
    segments->push_back(seg);
  }
  std::stable_sort(segments->begin(), segments->end(),
                   [](const LineSegment& a, const LineSegment& b) { return a.length() > b.length(); });
  // Refine the longest first; keep refining until max_segments long-enough segments are collected.
  std::vector<LineSegment> kept;
  kept.reserve(std::min<std::size_t>(segments->size(), options_.max_segments));
  for (LineSegment& seg : *segments) {
    if (static_cast<int>(kept.size()) >= options_.max_segments) break;
    if (refine)
      refineSegment(gray, options_, &seg);
    else
      orientSegment(gray, options_, &seg);
    if (seg.length() >= options_.min_length_px) kept.push_back(seg);
  }
  std::stable_sort(kept.begin(), kept.end(),
                   [](const LineSegment& a, const LineSegment& b) { return a.length() > b.length(); });
  segments->swap(kept);
}

void orientSegment(const cv::Mat& gray, const LineDetectorOptions& options, LineSegment* segment) {
  const double len = segment->length();
  if (!(len > 1.0)) return;
  const Vec2 d = segment->direction();
  const Vec2 n(-d.y(), d.x());
  const int ns = std::clamp(static_cast<int>(len / options.refine_step_px), 2, options.refine_max_samples);
  const double hi_x = gray.cols - 2.0, hi_y = gray.rows - 2.0;
  double sum = 0.0;
  for (int i = 0; i < ns; ++i) {
    const Vec2 p = segment->s + ((i + 0.5) * len / ns) * d;
    const Vec2 qa = p - 0.5 * n, qb = p + 0.5 * n;
    if (std::min(qa.x(), qb.x()) < 1.0 || std::min(qa.y(), qb.y()) < 1.0 || std::max(qa.x(), qb.x()) > hi_x ||
        std::max(qa.y(), qb.y()) > hi_y)
      continue;
    sum += bilinear(gray, static_cast<float>(qb.x()), static_cast<float>(qb.y())) -
           bilinear(gray, static_cast<float>(qa.x()), static_cast<float>(qa.y()));
  }
  if (sum < 0.0) std::swap(segment->s, segment->e);
}

bool refineSegment(const cv::Mat& gray, const LineDetectorOptions& options, LineSegment* segment) {
  const double len = segment->length();
  if (!(len > 1.0)) return false;
  Vec2 d = segment->direction();
  Vec2 n(-d.y(), d.x());
  const int r = options.refine_search_px;
  const float lo_x = 1.0f, lo_y = 1.0f;
  const float hi_x = static_cast<float>(gray.cols) - 2.0f, hi_y = static_cast<float>(gray.rows) - 2.0f;
  const int samples = std::max(2, static_cast<int>(len / options.refine_step_px));
  // Directional derivative across the segment at offset o (pixels along n) from point p: I(p + (o+.5)n) - I(p + (o-.5)n).
  float prof[24];
  struct Sample {
    double t, o, w;  // position along the segment from s, offset along n, weight
  };
  Sample pts[1024];
  int count = 0;
  double signed_sum = 0.0;
  const int nsamples = std::min(samples, options.refine_max_samples);
  for (int pass = 0; pass < 2; ++pass) {
    count = 0;
    for (int i = 0; i < nsamples; ++i) {
      const double t = (i + 0.5) * len / nsamples;
      const Vec2 p = segment->s + t * d;
      if (pass == 0) {  // orientation only needs the derivative on the segment itself
        const Vec2 qa = p - 0.5 * n, qb = p + 0.5 * n;
        if (std::min(qa.x(), qb.x()) < lo_x || std::min(qa.y(), qb.y()) < lo_y || std::max(qa.x(), qb.x()) > hi_x ||
            std::max(qa.y(), qb.y()) > hi_y)
          continue;
        signed_sum += bilinear(gray, static_cast<float>(qb.x()), static_cast<float>(qb.y())) -
                      bilinear(gray, static_cast<float>(qa.x()), static_cast<float>(qa.y()));
        continue;
      }
      bool inside = true;
      for (int o = -r - 1; o <= r + 1; ++o) {
        const Vec2 q = p + (o + 0.5) * n;
        if (q.x() < lo_x || q.y() < lo_y || q.x() > hi_x || q.y() > hi_y) {
          inside = false;
          break;
        }
        prof[o + r + 1] = bilinear(gray, static_cast<float>(q.x()), static_cast<float>(q.y()));
      }
      if (!inside) continue;
      // prof[k] is the value at offset k - r - 1 + 0.5; derivative at offset o = prof[o + r + 1] - prof[o + r].
      int best = 0;
      float best_g = -1e9f;
      float g[24];
      for (int o = -r; o <= r; ++o) {
        g[o + r] = prof[o + r + 1] - prof[o + r];
        if (g[o + r] > best_g) {
          best_g = g[o + r];
          best = o;
        }
      }
      if (best_g < options.refine_min_gradient) continue;
      double off = best;
      if (best > -r && best < r) {  // parabola through the peak and its neighbours
        const double gm = g[best + r - 1], g0 = g[best + r], gp = g[best + r + 1];
        const double den = gm - 2.0 * g0 + gp;
        if (den < -1e-9) off += std::clamp(0.5 * (gm - gp) / den, -0.5, 0.5);
      } else {
        continue;  // peak at the border of the search window: not this edge
      }
      pts[count++] = Sample{t, off, best_g};
    }
    if (pass == 0) {
      if (signed_sum < 0.0) {  // orient: gradient along +n
        std::swap(segment->s, segment->e);
        d = -d;
        n = -n;
      }
    }
  }
  if (count < 3) return false;
  // Weighted total least squares in the (t, o) frame of the segment.
  double sw = 0.0, st = 0.0, so = 0.0;
  for (int i = 0; i < count; ++i) {
    sw += pts[i].w;
    st += pts[i].w * pts[i].t;
    so += pts[i].w * pts[i].o;
  }
  const double mt = st / sw, mo = so / sw;
  double ctt = 0.0, cto = 0.0, coo = 0.0;
  for (int i = 0; i < count; ++i) {
    const double dt = pts[i].t - mt, dof = pts[i].o - mo;
    ctt += pts[i].w * dt * dt;
    cto += pts[i].w * dt * dof;
    coo += pts[i].w * dof * dof;
  }
  // Principal direction of the 2x2 covariance.
  const double angle = 0.5 * std::atan2(2.0 * cto, ctt - coo);
  if (std::abs(angle) > 0.2) return false;  // more than ~11 degrees off: refinement found another structure
  // A bent edge (lens distortion bends straight scene lines): a weighted quadratic o(u) = c0 + c1 u + c2 u^2,
  // u = 2 t / len - 1, through the edge offsets. When its sagitta |c2| exceeds refine_bend_px, the endpoints are put
  // on the fitted curve (the segment becomes a chord of the edge: both endpoints on the edge, so that they undistort
  // onto the straight scene line) instead of on the straight total-least-squares fit, which passes a sagitta's
  // fraction off the edge at both ends. Only when the samples span most of the segment (no long extrapolation).
  if (count >= 6 && options.refine_bend_px < 50.0) {
    double t_lo = len, t_hi = 0.0;
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    for (int i = 0; i < count; ++i) {
      t_lo = std::min(t_lo, pts[i].t);
      t_hi = std::max(t_hi, pts[i].t);
      const double u = 2.0 * pts[i].t / len - 1.0;
      const Eigen::Vector3d phi(1.0, u, u * u);
      A += pts[i].w * phi * phi.transpose();
      rhs += pts[i].w * pts[i].o * phi;
    }
    if (t_lo < 0.2 * len && t_hi > 0.8 * len) {
      const Eigen::Vector3d c = A.ldlt().solve(rhs);
      if (c.allFinite() && std::abs(c(2)) > options.refine_bend_px && std::abs(c(2)) < 0.05 * len) {
        const Vec2 s0 = segment->s;
        segment->s = s0 + (c(0) - c(1) + c(2)) * n;
        segment->e = s0 + len * d + (c(0) + c(1) + c(2)) * n;
        return true;
      }
    }
  }
  const Vec2 centre = segment->s + mt * d + mo * n;
  const Vec2 new_d = std::cos(angle) * d + std::sin(angle) * n;
  const double ts = (segment->s - centre).dot(new_d), te = (segment->e - centre).dot(new_d);
  segment->s = centre + ts * new_d;
  segment->e = centre + te * new_d;
  return true;
}

}  // namespace linnet
