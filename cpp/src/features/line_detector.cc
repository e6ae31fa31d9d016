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

// True when `seg` repeats one of `others`: same orientation within ~3 degrees, both endpoints within 1.5 px of its
// line, overlapping it by half of the shorter.
bool duplicatesAny(const LineSegment& seg, const std::vector<LineSegment>& others) {
  const Vec2 d = seg.direction(), m = seg.midpoint();
  const double len = seg.length();
  for (const LineSegment& o : others) {
    const double lo = o.length();
    if ((o.midpoint() - m).squaredNorm() > 0.25 * (len + lo) * (len + lo)) continue;
    const Vec2 od = o.direction();
    if (od.dot(d) < 0.9986) continue;
    const Vec2 on(-od.y(), od.x());
    if (std::abs((seg.s - o.s).dot(on)) > 1.5 || std::abs((seg.e - o.s).dot(on)) > 1.5) continue;
    const double a = (seg.s - o.s).dot(od), b = (seg.e - o.s).dot(od);
    const double inter = std::min(std::max(a, b), lo) - std::max(std::min(a, b), 0.0);
    if (inter > 0.5 * std::min(len, lo)) return true;
  }
  return false;
}

}  // namespace

int findParallelEdges(const cv::Mat& gray, const LineDetectorOptions& options, const LineSegment& segment,
                      std::vector<LineSegment>* out) {
  const double len = segment.length();
  if (!(len > 1.0) || gray.empty()) return 0;
  const Vec2 d = segment.direction(), n(-d.y(), d.x());
  const int R = options.parallel_search_px;
  const int K = std::clamp(static_cast<int>(len / 6.0), 4, 16);
  const float hi_x = static_cast<float>(gray.cols) - 2.0f, hi_y = static_cast<float>(gray.rows) - 2.0f;
  // Per side (0: -n, 1: +n) and polarity (0: gradient along -n, 1: along +n): the samples' (t, offset) hits.
  struct Hit {
    double t, o;
  };
  // [side][polarity][|offset| bin]: fixed storage (no allocation per segment). A sample adds at most one hit per
  // offset, so a bin holds at most 2 K <= 32 hits.
  constexpr int kBins = 11, kPerBin = 32;  // |offset| <= parallel_search_px <= 10; K <= 16
  Hit hits[2][2][kBins][kPerBin];
  int count[2][2][kBins] = {};
  int used = 0;
  float prof[24], g[24];
  for (int i = 0; i < K; ++i) {
    const double t = (i + 0.5) * len / K;
    const Vec2 p = segment.s + t * d;
    const Vec2 q0 = p + (-R - 0.5) * n, q1 = p + (R + 0.5) * n;
    if (std::min(q0.x(), q1.x()) < 1.0 || std::min(q0.y(), q1.y()) < 1.0 || std::max(q0.x(), q1.x()) > hi_x ||
        std::max(q0.y(), q1.y()) > hi_y)
      continue;
    for (int o = -R - 1; o <= R; ++o) {  // prof[o + R + 1]: value at offset o + 0.5
      const Vec2 q = p + (o + 0.5) * n;
      prof[o + R + 1] = bilinear(gray, static_cast<float>(q.x()), static_cast<float>(q.y()));
    }
    for (int o = -R; o <= R; ++o) g[o + R] = prof[o + R + 1] - prof[o + R];  // derivative at offset o
    int m = 0;
    for (int o = -2; o <= 2; ++o)
      if (g[o + R] > g[m + R]) m = o;
    const float gm = g[m + R];
    if (gm < options.refine_min_gradient) continue;
    ++used;
    const float thr = std::max(static_cast<float>(2.0 * options.refine_min_gradient),
                               static_cast<float>(options.parallel_min_ratio) * gm);
    for (int o = -R + 1; o <= R - 1; ++o) {
      if (std::abs(o - m) < 2) continue;
      const float a = std::abs(g[o + R]);
      if (a < thr || a < std::abs(g[o + R - 1]) || a < std::abs(g[o + R + 1])) continue;
      const double am = std::abs(g[o + R - 1]), ap = std::abs(g[o + R + 1]);
      const double den = am - 2.0 * a + ap;
      const double sub = den < -1e-9 ? std::clamp(0.5 * (am - ap) / den, -0.5, 0.5) : 0.0;
      const int side = o > m ? 1 : 0, pol = g[o + R] > 0 ? 1 : 0, bin = std::abs(o);
      if (count[side][pol][bin] < kPerBin) hits[side][pol][bin][count[side][pol][bin]++] = {t, o + sub};
    }
  }
  if (used < 3) return 0;
  const int need = std::max(3, static_cast<int>(std::ceil(options.parallel_min_votes * used)));
  int added = 0;
  for (int side = 0; side < 2; ++side) {
    int best_pol = -1, best_bin = -1;
    std::size_t best_count = 0;
    for (int pol = 0; pol < 2; ++pol)
      for (int b = 1; b <= R; ++b) {
        const std::size_t c = static_cast<std::size_t>(count[side][pol][b] + count[side][pol][b - 1] +
                                                       (b < R ? count[side][pol][b + 1] : 0));
        if (c > best_count) {
          best_count = c;
          best_pol = pol;
          best_bin = b;
        }
      }
    if (static_cast<int>(best_count) < need) continue;
    // Straight fit o = c0 + c1 t through the window's hits; extent: the span of the samples that saw it.
    double sw = 0.0, st = 0.0, so = 0.0, stt = 0.0, sto = 0.0, t_lo = len, t_hi = 0.0;
    for (int b = best_bin - 1; b <= std::min(R, best_bin + 1); ++b)
      for (int k = 0; k < count[side][best_pol][b]; ++k) {
        const Hit& h = hits[side][best_pol][b][k];
        sw += 1.0, st += h.t, so += h.o, stt += h.t * h.t, sto += h.t * h.o;
        t_lo = std::min(t_lo, h.t), t_hi = std::max(t_hi, h.t);
      }
    const double det = sw * stt - st * st;
    if (!(det > 1e-9)) continue;
    const double c1 = (sw * sto - st * so) / det, c0 = (so - c1 * st) / sw;
    if (std::abs(c1) > 0.05) continue;  // not parallel (about 3 degrees)
    const double half = 0.5 * len / K;
    const double ta = std::max(0.0, t_lo - half), tb = std::min(len, t_hi + half);
    LineSegment tw{segment.s + ta * d + (c0 + c1 * ta) * n, segment.s + tb * d + (c0 + c1 * tb) * n};
    if (best_pol == 0) std::swap(tw.s, tw.e);  // gradient along -n: reverse to keep the orientation convention
    out->push_back(tw);
    ++added;
  }
  return added;
}

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
  } else if (options_.detector == "ed") {
    EdgeDrawingOptions e;
    e.sigma = options_.ed_sigma;
    e.gradient_threshold = options_.ed_gradient_threshold;
    e.anchor_threshold = options_.ed_anchor_threshold;
    e.scan_interval = options_.ed_scan_interval;
    e.fit_error_px = options_.ed_fit_error_px;
    e.min_line_px = std::max(4, static_cast<int>(options_.min_length_px / options_.downsample * 0.7));
    own_ed_ = std::make_unique<EdgeDrawing>(e);
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
  const double f = options_.downsample;
  const bool integer = std::abs(f - std::round(f)) < 1e-9;
  const cv::Mat* input = &gray;
  if (f > 1.0) {
    const cv::Size size(static_cast<int>(gray.cols / f), static_cast<int>(gray.rows / f));
    cv::resize(gray, small_, size, 0.0, 0.0, integer ? cv::INTER_AREA : cv::INTER_LINEAR);
    input = &small_;
  }
  if (input->cols < 8 || input->rows < 8) return;
  if (lsd_) {
    lsd_->detect(*input, *raw);
  } else if (fld_) {
    fld_->detect(*input, *raw);
  } else if (own_ed_) {
    own_ed_->detect(*input, raw);
  } else {
    ed_->detectEdges(*input);
    ed_->detectLines(*raw);
  }
  if (f > 1.0) {
    // Pixel centres: small-image u sits at full-resolution x = f (u + 1/2) - 1/2 (INTER_AREA with an integer f: the
    // mean of pixels f u .. f u + f - 1; INTER_LINEAR: the same centre convention). The size was rounded down, so
    // the actual factor per axis is used.
    const float sx = static_cast<float>(gray.cols) / static_cast<float>(input->cols);
    const float sy = static_cast<float>(gray.rows) / static_cast<float>(input->rows);
    const float scale[2] = {integer ? static_cast<float>(f) : sx, integer ? static_cast<float>(f) : sy};
    for (cv::Vec4f& l : *raw)
      for (int k = 0; k < 4; ++k) l[k] = (l[k] + 0.5f) * scale[k % 2] - 0.5f;
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
  if (options_.parallel_edges) {
    std::vector<LineSegment> twins;
    for (const LineSegment& seg : kept) findParallelEdges(gray, options_, seg, &twins);
    for (LineSegment& tw : twins) {
      if (refine) refineSegment(gray, options_, &tw);
      if (tw.length() < options_.min_length_px || duplicatesAny(tw, kept)) continue;
      kept.push_back(tw);
    }
  }
  std::stable_sort(kept.begin(), kept.end(),
                   [](const LineSegment& a, const LineSegment& b) { return a.length() > b.length(); });
  if (static_cast<int>(kept.size()) > options_.max_segments) kept.resize(options_.max_segments);
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

bool refineSegment(const cv::Mat& gray, const LineDetectorOptions& options, LineSegment* segment, double* support,
                   bool trim) {
  if (support) *support = 0.0;
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
  // Weighted total least squares in the (t, o) frame of the segment: mean (mt, mo) and the principal direction of the
  // 2x2 covariance.
  double mt = 0.0, mo = 0.0, angle = 0.0;
  const auto fit = [&]() {
    double sw = 0.0, st = 0.0, so = 0.0;
    for (int i = 0; i < count; ++i) {
      sw += pts[i].w;
      st += pts[i].w * pts[i].t;
      so += pts[i].w * pts[i].o;
    }
    mt = st / sw;
    mo = so / sw;
    double ctt = 0.0, cto = 0.0, coo = 0.0;
    for (int i = 0; i < count; ++i) {
      const double dt = pts[i].t - mt, dof = pts[i].o - mo;
      ctt += pts[i].w * dt * dt;
      cto += pts[i].w * dt * dof;
      coo += pts[i].w * dof * dof;
    }
    angle = 0.5 * std::atan2(2.0 * cto, ctt - coo);
  };
  fit();
  if (std::abs(angle) > 0.2) return false;  // more than ~11 degrees off: refinement found another structure
  if (trim) {
    // A predicted extent may reach past the edge's end onto other structure: keep the samples within kRefineTrimPx
    // of the fit, refit on them, and end the segment at the outermost ones (half a sample step beyond).
    const double ca = std::cos(angle), sa = std::sin(angle);
    const double mt0 = mt, mo0 = mo;
    int kept = 0;
    for (int i = 0; i < count; ++i)
      if (std::abs((pts[i].o - mo0) * ca - (pts[i].t - mt0) * sa) <= kRefineTrimPx) pts[kept++] = pts[i];
    if (kept < 3) return false;
    count = kept;
    fit();
    if (std::abs(angle) > 0.2) return false;
    if (support) *support = static_cast<double>(count) / nsamples;
    double t_lo = len, t_hi = 0.0;
    for (int i = 0; i < count; ++i) {
      t_lo = std::min(t_lo, pts[i].t);
      t_hi = std::max(t_hi, pts[i].t);
    }
    const double half_step = 0.5 * len / nsamples;
    t_lo = std::max(0.0, t_lo - half_step);
    t_hi = std::min(len, t_hi + half_step);
    const Vec2 centre = segment->s + mt * d + mo * n;
    const Vec2 new_d = std::cos(angle) * d + std::sin(angle) * n;
    const Vec2 s0 = segment->s;
    segment->s = centre + (s0 + t_lo * d - centre).dot(new_d) * new_d;
    segment->e = centre + (s0 + t_hi * d - centre).dot(new_d) * new_d;
    return true;
  }
  if (support) *support = static_cast<double>(count) / nsamples;
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
