// Left -> right point matching for an unrectified stereo pair.
#include "linnet/features/point_stereo.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "linnet/core/error.h"
#include "linnet/core/simd_clones.h"
#include "linnet/features/image_pyramid.h"
#include "linnet/features/klt_round_trip.h"

namespace linnet {

namespace {

// Zero-mean, unit-norm patch of (2h+1)^2 pixels at an integer centre into out (resized by the caller); false when
// it leaves the image or is flat. Built for AVX2 as well (the same sums and the same float operations per pixel).
LINNET_SIMD_CLONES bool patch(const cv::Mat& img, int cx, int cy, int h, float* out) {
  if (cx - h < 0 || cy - h < 0 || cx + h >= img.cols || cy + h >= img.rows) return false;
  const int side = 2 * h + 1, count = side * side;
  int sum = 0, sum2 = 0;
  float* o = out;
  for (int y = cy - h; y <= cy + h; ++y) {
    const unsigned char* row = img.ptr<unsigned char>(y) + (cx - h);
    for (int x = 0; x < side; ++x) {
      const int v = row[x];
      sum += v;
      sum2 += v * v;
      *o++ = static_cast<float>(v);
    }
  }
  const float mean = static_cast<float>(sum) / count;
  const double ss = static_cast<double>(sum2) - static_cast<double>(sum) * sum / count;
  if (ss < 1e-6 * count) return false;
  const float inv = static_cast<float>(1.0 / std::sqrt(ss));
  for (int k = 0; k < count; ++k) out[k] = (out[k] - mean) * inv;
  return true;
}

// Bilinear samples of the (2h+1)^2 patch centred on c (sub-pixel; pixels beyond the border replicated), as
// cv::getRectSubPix places them: its top-left sample at c - (h, h).
LINNET_SIMD_CLONES void samplePatch(const cv::Mat& img, const cv::Point2f& c, int h, double* out) {
  const int side = 2 * h + 1;
  const float x0 = c.x - static_cast<float>(h), y0 = c.y - static_cast<float>(h);
  const int ix = cvFloor(x0), iy = cvFloor(y0);
  const double a = static_cast<double>(x0 - static_cast<float>(ix));
  const double b = static_cast<double>(y0 - static_cast<float>(iy));
  const double w00 = (1.0 - a) * (1.0 - b), w01 = a * (1.0 - b), w10 = (1.0 - a) * b, w11 = a * b;
  if (ix >= 0 && iy >= 0 && ix + side < img.cols && iy + side < img.rows) {
    for (int y = 0; y < side; ++y) {
      const unsigned char* r0 = img.ptr<unsigned char>(iy + y) + ix;
      const unsigned char* r1 = img.ptr<unsigned char>(iy + y + 1) + ix;
      for (int x = 0; x < side; ++x)
        *out++ = w00 * r0[x] + w01 * r0[x + 1] + w10 * r1[x] + w11 * r1[x + 1];
    }
    return;
  }
  const auto at = [&](int x, int y) -> double {
    return img.at<unsigned char>(std::clamp(y, 0, img.rows - 1), std::clamp(x, 0, img.cols - 1));
  };
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x)
      *out++ = w00 * at(ix + x, iy + y) + w01 * at(ix + x + 1, iy + y) + w10 * at(ix + x, iy + y + 1) +
               w11 * at(ix + x + 1, iy + y + 1);
}

}  // namespace

double subpixelZncc(const cv::Mat& img0, const cv::Point2f& c0, const cv::Mat& img1, const cv::Point2f& c1, int h) {
  // Per verification about 3 k instructions; through cv::getRectSubPix, cv::meanStdDev and cv::Mat arithmetic on
  // the small patches it was about 25 k (1.9 % of a run's instructions, one verification per stereo match).
  constexpr int kMaxSide = 2 * 16 + 1;
  if (h < 0 || h > 16) throw UsageError("subpixelZncc: patch half size must be in [0, 16]");
  const int n = (2 * h + 1) * (2 * h + 1);
  std::array<double, kMaxSide * kMaxSide> a, b;
  samplePatch(img0, c0, h, a.data());
  samplePatch(img1, c1, h, b.data());
  double ma = 0.0, mb = 0.0;
  for (int k = 0; k < n; ++k) {
    ma += a[k];
    mb += b[k];
  }
  ma /= n;
  mb /= n;
  double saa = 0.0, sbb = 0.0, sab = 0.0;
  for (int k = 0; k < n; ++k) {
    const double da = a[k] - ma, db = b[k] - mb;
    saa += da * da;
    sbb += db * db;
    sab += da * db;
  }
  // Flat: a standard deviation below 1e-3 grey levels.
  const double sa = std::sqrt(saa / n), sb = std::sqrt(sbb / n);
  if (sa < 1e-3 || sb < 1e-3) return -1.0;
  return sab / (sa * sb * n);
}

std::vector<StereoPointResult> matchStereoPoints(const std::vector<cv::Mat>& pyr0, const std::vector<cv::Mat>& pyr1,
                                                 const CameraModel& cam0, const CameraModel& cam1,
                                                 const Pose& T_C1_C0, const std::vector<cv::Point2f>& px0,
                                                 const std::vector<Vec2>& uv0,
                                                 const std::vector<cv::Point2f>* prior, const StereoPointParams& p,
                                                 StereoPointStats* stats) {
  const std::size_t n = px0.size();
  if (uv0.size() != n || (prior && prior->size() != n))
    throw UsageError("matchStereoPoints: point lists differ in length");
  StereoPointStats st;
  std::vector<StereoPointResult> res(n);
  if (n == 0 || pyr0.empty() || pyr1.empty()) {
    if (stats) *stats = st;
    return res;
  }
  const Mat3 R = T_C1_C0.R();
  const Vec3 t = T_C1_C0.p;
  const double baseline = t.norm();

  // 1. Initial guesses: the prior, else the best ZNCC along the epipolar curve between depth search_min_depth_m and
  //    infinity, sampled about one pixel apart at the search level.
  const int lvl = std::clamp(p.search_level, 0, pyramidLayout(pyr0).levels - 1);
  const double scale = 1.0 / static_cast<double>(1 << lvl);
  const cv::Mat& img0 = pyramidLevel(pyr0, lvl);
  const cv::Mat& img1 = pyramidLevel(pyr1, lvl);
  const double rho_search = 1.0 / std::max(1e-3, p.search_min_depth_m);
  const int samples = std::max(2, static_cast<int>(std::ceil(cam1.fx() * baseline * rho_search * scale)) + 1);
  std::vector<cv::Point2f> guess(n);
  std::vector<unsigned char> have(n, 0);
  const int patch_len = (2 * p.search_half_patch + 1) * (2 * p.search_half_patch + 1);
  std::vector<float> a(static_cast<std::size_t>(patch_len)), b(static_cast<std::size_t>(patch_len));
  for (std::size_t i = 0; i < n; ++i) {
    if (prior && std::isfinite((*prior)[i].x) && std::isfinite((*prior)[i].y)) {
      guess[i] = (*prior)[i];
      have[i] = 1;
      continue;
    }
    ++st.searched;
    if (!patch(img0, cvRound(px0[i].x * scale), cvRound(px0[i].y * scale), p.search_half_patch, a.data())) {
      ++st.search_failed;
      continue;
    }
    const Vec3 ray = R * Vec3(uv0[i].x(), uv0[i].y(), 1.0);
    double best = -2.0;
    cv::Point2f best_px;
    for (int k = 0; k < samples; ++k) {
      const Vec3 q = ray + (rho_search * k / (samples - 1)) * t;
      if (q.z() <= 1e-6) continue;
      const Vec2 px1 = cam1.distort(Vec2(q.x() / q.z(), q.y() / q.z()));
      if (!cam1.inImage(px1)) continue;
      if (!patch(img1, cvRound(px1.x() * scale), cvRound(px1.y() * scale), p.search_half_patch, b.data())) continue;
      double zncc = 0.0;
      for (std::size_t j = 0; j < a.size(); ++j) zncc += static_cast<double>(a[j]) * b[j];
      if (zncc > best) {
        best = zncc;
        best_px = cv::Point2f(static_cast<float>(px1.x()), static_cast<float>(px1.y()));
      }
    }
    if (best < p.search_min_zncc) {
      ++st.search_failed;
      continue;
    }
    guess[i] = best_px;
    have[i] = 1;
  }

  // 2. KLT refinement from the guesses (only the levels up to the search level: the guess is good to a pixel there),
  //    then the right -> left round trip. Points with a prior may take fewer levels, and skip the round trip when the
  //    forward pass ends where the prior said (their last match, carried by the left flow, confirms them).
  std::vector<std::size_t> idx;
  std::vector<cv::Point2f> left, right;
  std::vector<unsigned char> from_prior;
  for (std::size_t i = 0; i < n; ++i)
    if (have[i]) {
      idx.push_back(i);
      left.push_back(px0[i]);
      right.push_back(guess[i]);
      from_prior.push_back(prior && std::isfinite((*prior)[i].x) && std::isfinite((*prior)[i].y) ? 1 : 0);
    }
  if (!idx.empty()) {
    const int levels = std::min(p.klt_levels, std::max(1, lvl));
    const int prior_levels = p.prior_levels < 0 ? levels : std::min(levels, p.prior_levels);
    const double agree2 = p.prior_agree_px * p.prior_agree_px;
    std::vector<unsigned char> round_trip(idx.size(), 0);
    // Forward and round trip for the points of one group (with a prior or not), each on its own levels. KLT treats
    // every point alone, so the split does not change a point's result.
    enum class Group { kAll, kPrior, kSearched };
    const auto refine = [&](Group group, int group_levels) {
      std::vector<std::size_t> ks;
      std::vector<cv::Point2f> l, r;
      for (std::size_t k = 0; k < idx.size(); ++k)
        if (group == Group::kAll || (from_prior[k] != 0) == (group == Group::kPrior)) {
          ks.push_back(k);
          l.push_back(left[k]);
          r.push_back(right[k]);
        }
      const KltRoundTripParams kp = kltRoundTripParams(p.klt_window_px, p.klt_max_iterations, p.klt_epsilon,
                                                       p.klt_min_eigen, group_levels, group_levels, p.fb_threshold_px);
      const std::vector<unsigned char> kept =
          kltRoundTrip(pyr0, pyr1, l, &r, kp, [&](std::size_t j, const cv::Point2f& q) {
            const std::size_t k = ks[j];
            if (!cam1.inImage(Vec2(q.x, q.y), p.border_px)) return RoundTrip::kDrop;
            const cv::Point2f moved = q - guess[idx[k]];
            if (from_prior[k] && agree2 > 0.0 && moved.dot(moved) <= agree2) {
              ++st.round_trip_skipped;
              return RoundTrip::kKeep;
            }
            return RoundTrip::kCheck;
          });
      for (std::size_t j = 0; j < ks.size(); ++j) {
        right[ks[j]] = r[j];
        round_trip[ks[j]] = kept[j];
      }
    };
    if (prior_levels == levels) {
      refine(Group::kAll, levels);
    } else {
      refine(Group::kPrior, prior_levels);
      refine(Group::kSearched, levels);
    }

    // 3. Geometric checks in normalised coordinates.
    const Mat3 E = skew(t) * R;
    const double epi_th = p.epipolar_threshold_px / cam1.fx();
    // Tolerance below zero inverse depth: the epipolar threshold seen along the baseline (points near infinity).
    const double rho_tol = baseline > 1e-9 ? epi_th / baseline : 0.0;
    const double rho_max = p.min_depth_m > 0.0 ? 1.0 / p.min_depth_m : 1e12;
    for (std::size_t k = 0; k < idx.size(); ++k) {
      const std::size_t i = idx[k];
      Vec2 uv1;
      if (!round_trip[k] || !cam1.undistort(Vec2(right[k].x, right[k].y), &uv1)) {
        ++st.klt_failed;
        continue;
      }
      const Vec3 x0(uv0[i].x(), uv0[i].y(), 1.0), x1(uv1.x(), uv1.y(), 1.0);
      const Vec3 l = E * x0;  // epipolar line of x0 in cam1
      const double ln = std::hypot(l.x(), l.y());
      if (ln > 1e-12 && std::abs(x1.dot(l)) / ln > epi_th) {
        ++st.epipolar_rejected;
        continue;
      }
      // Signed inverse depth along the cam0 ray: x1 x (R x0 + rho t) = 0 => rho = -((x1 x R x0).(x1 x t)) / |x1 x t|^2.
      const Vec3 c_a = x1.cross(R * x0), c_t = x1.cross(t);
      const double ct2 = c_t.squaredNorm();
      const double rho = ct2 > 1e-18 ? -c_a.dot(c_t) / ct2 : 0.0;
      if (rho < -rho_tol || rho > rho_max) {
        ++st.depth_rejected;
        continue;
      }
      // Last check at full resolution: KLT can settle on a look-alike further along the epipolar line.
      if (p.verify_min_zncc > -1.0 &&
          subpixelZncc(pyramidLevel(pyr0, 0), left[k], pyramidLevel(pyr1, 0), right[k], p.verify_half_patch) <
              p.verify_min_zncc) {
        ++st.verify_rejected;
        continue;
      }
      res[i].ok = true;
      res[i].px1 = right[k];
      res[i].uv1 = uv1;
      res[i].inverse_depth = std::max(0.0, rho);
      ++st.matched;
    }
  }
  if (stats) *stats = st;
  return res;
}

}  // namespace linnet
