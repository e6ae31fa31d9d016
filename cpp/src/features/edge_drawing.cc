// Edge Drawing edge chains and EDLines line pieces (see edge_drawing.h).
#include "linnet/features/edge_drawing.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include <opencv2/imgproc.hpp>

#include "linnet/core/simd_clones.h"

namespace linnet {
namespace {

// One inner row of gradient(): the 3x3 Sobel derivatives of the smoothed rows a, b, c (above, at, below) and the
// word of each inner pixel: magnitude |gx| + |gy| (0 below `threshold`), `dir_bit` where |gx| >= |gy|. In 16 bits
// (|gx| + |gy| <= 2040), so that the compiler vectorises it eight (SSE2) or sixteen (AVX2) pixels at a time.
LINNET_SIMD_CLONES void gradientRow(const std::uint8_t* a, const std::uint8_t* b, const std::uint8_t* c, int cols,
                                    std::int16_t threshold, std::uint16_t dir_bit, std::uint16_t* p) {
  using I16 = std::int16_t;
  for (int x = 1; x < cols - 1; ++x) {
    const auto gx = static_cast<I16>(static_cast<I16>(a[x + 1] - a[x - 1]) + 2 * static_cast<I16>(b[x + 1] - b[x - 1]) +
                                     static_cast<I16>(c[x + 1] - c[x - 1]));
    const auto gy = static_cast<I16>(static_cast<I16>(c[x - 1] - a[x - 1]) + 2 * static_cast<I16>(c[x] - a[x]) +
                                     static_cast<I16>(c[x + 1] - a[x + 1]));
    const auto ax = static_cast<I16>(gx < 0 ? -gx : gx), ay = static_cast<I16>(gy < 0 ? -gy : gy);
    const auto g = static_cast<I16>(ax + ay);
    p[x] = static_cast<std::uint16_t>((g >= threshold ? g : 0) | (ax >= ay ? dir_bit : 0));
  }
}

// One scanned row of link()'s ridge test (branch-free, vectorised): ridge[x] = 1 where the magnitude (word & mag_mask)
// exceeds both neighbours across the edge by at least A (left and right on a vertical edge, word & dir_bit; above and
// below otherwise) and scan[x] is 1.
LINNET_SIMD_CLONES void ridgeRow(const std::uint16_t* m, const std::uint16_t* up, const std::uint16_t* dn,
                                 const std::uint8_t* scan, int cols, int A, std::uint16_t mag_mask,
                                 std::uint16_t dir_bit, std::uint8_t* ridge) {
  for (int x = 1; x < cols - 1; ++x) {
    const int g = m[x] & mag_mask;
    const bool across_x = (g - (m[x - 1] & mag_mask) >= A) & (g - (m[x + 1] & mag_mask) >= A);
    const bool across_y = (g - (up[x] & mag_mask) >= A) & (g - (dn[x] & mag_mask) >= A);
    ridge[x] = static_cast<std::uint8_t>((g != 0) & ((m[x] & dir_bit) ? across_x : across_y)) & scan[x];
  }
}

// Least-squares line through a set of points given by its sums (count, x, y, xx, yy, xy): centroid, unit direction
// and the mean squared distance of the points from the line (the covariance's smaller eigenvalue).
struct LineFit {
  double cx = 0.0, cy = 0.0, dx = 1.0, dy = 0.0, mse = 0.0;
};

LineFit fitFromSums(double n, double sx, double sy, double sxx, double syy, double sxy) {
  LineFit f;
  f.cx = sx / n;
  f.cy = sy / n;
  const double a = sxx / n - f.cx * f.cx, c = syy / n - f.cy * f.cy, b = sxy / n - f.cx * f.cy;
  const double half = 0.5 * (a - c), root = std::sqrt(half * half + b * b);
  f.mse = std::max(0.0, 0.5 * (a + c) - root);
  // Eigenvector of the larger eigenvalue a + c over 2 + root: (b, lambda - a) or (lambda - c, b), the better scaled.
  const double lambda = 0.5 * (a + c) + root;
  double vx = b, vy = lambda - a;
  if (std::abs(lambda - c) > std::abs(vy)) {
    vx = lambda - c;
    vy = b;
  }
  const double norm = std::sqrt(vx * vx + vy * vy);  // no over/underflow here: std::hypot's care is slow
  if (norm > 1e-12) {
    f.dx = vx / norm;
    f.dy = vy / norm;
  } else {  // isotropic (a single point or a perfect square): any direction, take x
    f.dx = 1.0;
    f.dy = 0.0;
  }
  return f;
}

// True only where fitFromSums' mse is certainly above tol2 (a window that is not straight), with neither its divisions
// nor its square roots, for sums of integer coordinates (the chain's pixels relative to its first one). Then
// A = n sxx - sx^2, C = n syy - sy^2 and B = n sxy - sx sy are exact, and n^2 times the exact mse is
// M - sqrt(S) with M = (A + C) / 2, S = ((A - C) / 2)^2 + B^2. fitFromSums' rounded mse is within
// 34 u (sxx + syy + |sxy|) / n of the exact one (u = 2^-53: each of a, b, c within 10 u of the second moments, the
// smaller eigenvalue 1-Lipschitz in each, and the last few roundings); the test adds 1e-13 of them to tol2, 1e-12
// relative to its own products and 1e-9 relative to its square, so that whenever it says yes, fitFromSums' mse is
// above tol2 as well. Near the boundary it says no and the full fit decides: the decisions stay the same.
bool surelyNotStraight(double n, double sx, double sy, double sxx, double syy, double sxy, double tol2) {
  constexpr double kExact = 0x1p50;  // the products below are exact integers while the sums stay this small
  if (!(n * std::max(sxx, syy) < kExact) || !(sx * sx + sy * sy < kExact) || !(n * std::abs(sxy) < kExact))
    return false;
  const double A = n * sxx - sx * sx, C = n * syy - sy * sy, B = n * sxy - sx * sy;
  const double M = 0.5 * (A + C), D = 0.5 * (A - C), S = D * D + B * B;
  const double slack = 1e-13 * (sxx + syy + std::abs(sxy)) * n;  // n^2 times the bound on fitFromSums' error
  const double x = M - (n * n * tol2 * (1.0 + 1e-12) + slack);
  return x > 0.0 && x * x > S * (1.0 + 1e-9);
}

inline double distance(const LineFit& f, double x, double y) { return std::abs((x - f.cx) * f.dy - (y - f.cy) * f.dx); }

}  // namespace

void EdgeDrawing::detect(const cv::Mat& gray, std::vector<cv::Vec4f>* lines) {
  lines->clear();
  if (gray.cols < 8 || gray.rows < 8) {
    chains_.clear();
    return;
  }
  gradient(gray);
  link();
  for (const std::vector<cv::Point>& chain : chains_) fitLines(chain, lines);
}

void EdgeDrawing::gradient(const cv::Mat& gray) {
  const cv::Mat* src = &gray;
  if (options_.sigma > 0.0) {
    const int k = 2 * static_cast<int>(std::ceil(2.0 * options_.sigma)) + 1;
    cv::GaussianBlur(gray, smooth_, cv::Size(k, k), options_.sigma, options_.sigma, cv::BORDER_REPLICATE);
    src = &smooth_;
  }
  // The two 3x3 Sobel derivatives and the word of each inner pixel in one pass over the smoothed image (the border
  // words are 0, so no border rule is needed): 25 % faster than cv::spatialGradient and a second pass with SSE2
  // alone, the same words (test OnePassGradientEqualsTheSobelFilters); in 32 bits it was half as fast.
  const int rows = gray.rows, cols = gray.cols;
  px_.create(rows, cols, CV_16U);
  const auto threshold = static_cast<std::int16_t>(std::min(options_.gradient_threshold, 4096));
  for (int y = 1; y < rows - 1; ++y) {
    std::uint16_t* p = px_.ptr<std::uint16_t>(y);
    gradientRow(src->ptr<std::uint8_t>(y - 1), src->ptr<std::uint8_t>(y), src->ptr<std::uint8_t>(y + 1), cols,
                threshold, kDirBit, p);
    p[0] = p[cols - 1] = 0;  // the walk never steps onto the border, so its neighbours are always inside
  }
  std::fill_n(px_.ptr<std::uint16_t>(0), cols, 0);
  std::fill_n(px_.ptr<std::uint16_t>(rows - 1), cols, 0);
}

void EdgeDrawing::link() {
  const int rows = px_.rows, cols = px_.cols;
  const int step = std::max(1, options_.scan_interval), A = options_.anchor_threshold;
  anchors_.clear();
  int max_mag = 0;
  ridge_.resize(static_cast<std::size_t>(cols) + 8);
  std::uint8_t* ridge = ridge_.data();
  std::fill_n(ridge + cols, 8, 0);  // the tail read by the word scan (a wider previous image may have set it)
  // 1 on the scanned columns (every step-th, the borders excluded): the ridge test keeps only those, so that the
  // word scan below visits anchors only.
  scan_cols_.assign(static_cast<std::size_t>(cols), 0);
  for (int x = step; x < cols - 1; x += step) scan_cols_[static_cast<std::size_t>(x)] = 1;
  const std::uint8_t* scan = scan_cols_.data();
  for (int y = 1; y < rows - 1; y += step) {
    const std::uint16_t* m = px_.ptr<std::uint16_t>(y);
    const std::uint16_t* up = px_.ptr<std::uint16_t>(y - 1);
    const std::uint16_t* dn = px_.ptr<std::uint16_t>(y + 1);
    // Branch-free ridge test over the row, then a sparse pass over the hits.
    ridgeRow(m, up, dn, scan, cols, A, kMagMask, kDirBit, ridge);
    ridge[0] = ridge[cols - 1] = 0;
    // ridge[] holds 0 / 1 bytes, so each hit is the lowest set bit of its byte: walk the set bits of each 8-byte
    // word in ascending order (the 8 bytes past the row are zero).
    static_assert(std::endian::native == std::endian::little, "the word scan maps bit 8k to byte k");
    for (int x = 0; x < cols; x += 8) {
      std::uint64_t word;
      std::memcpy(&word, ridge + x, 8);
      while (word != 0) {
        const int k = x + (std::countr_zero(word) >> 3);
        word &= word - 1;
        anchors_.push_back(y * cols + k);
        max_mag = std::max(max_mag, magnitude(m[k]));
      }
    }
  }
  // Strongest anchors first (counting sort on the magnitude): chains grow from the clearest edges.
  bucket_start_.assign(static_cast<std::size_t>(max_mag) + 2, 0);
  std::uint16_t* px = px_.ptr<std::uint16_t>(0);
  for (int a : anchors_) ++bucket_start_[max_mag - magnitude(px[a]) + 1];
  for (std::size_t i = 1; i < bucket_start_.size(); ++i) bucket_start_[i] += bucket_start_[i - 1];
  sorted_.resize(anchors_.size());
  for (int a : anchors_) sorted_[bucket_start_[max_mag - magnitude(px[a])]++] = a;

  const std::size_t min_chain = static_cast<std::size_t>(std::max(2, options_.min_line_px));
  // The chains of the previous image are reused in place (their memory kept): no allocation per chain once warm.
  std::size_t n_chains = 0;
  for (int a : sorted_) {
    if (px[a] & kEdgeBit) continue;
    const int x = a % cols, y = a / cols;
    px[a] |= kEdgeBit;
    left_.clear();
    right_.clear();
    if (px[a] & kDirBit) {  // vertical edge: walk up and down
      walk(x, y, 0, -1, &left_);
      walk(x, y, 0, 1, &right_);
    } else {
      walk(x, y, -1, 0, &left_);
      walk(x, y, 1, 0, &right_);
    }
    if (left_.size() + right_.size() + 1 < min_chain) continue;
    if (n_chains == chains_.size()) chains_.emplace_back();
    std::vector<cv::Point>& chain = chains_[n_chains++];
    chain.clear();
    chain.insert(chain.end(), left_.rbegin(), left_.rend());
    chain.emplace_back(x, y);
    chain.insert(chain.end(), right_.begin(), right_.end());
  }
  chains_.resize(n_chains);
}

void EdgeDrawing::walk(int x, int y, int dx, int dy, std::vector<cv::Point>* out) {
  const int cols = px_.cols;
  std::uint16_t* px = px_.ptr<std::uint16_t>(0);
  // The position as an index and the direction as two offsets (one step on, one step sideways), kept up to date as
  // the walk turns, so that a step costs no multiplication and reads each word once.
  int at = y * cols + x;
  int forward = dy * cols + dx, across = dx == 0 ? 1 : cols;
  for (;;) {
    // The three pixels ahead: straight on first, so that it wins ties, then side -1, then side +1 (a later one wins
    // only when strictly stronger). Selected without branches: which neighbour wins is unpredictable.
    const int ahead = at + forward;
    const std::uint16_t w0 = px[ahead], wm = px[ahead - across], wp = px[ahead + across];
    const int g0 = magnitude(w0), gm = magnitude(wm), gp = magnitude(wp);
    int side = 0, g = g0;
    std::uint16_t w = w0;
    side = gm > g ? -1 : side;
    w = gm > g ? wm : w;
    g = std::max(g, gm);
    side = gp > g ? 1 : side;
    w = gp > g ? wp : w;
    g = std::max(g, gp);
    if (g == 0 || (w & kEdgeBit)) return;  // below threshold, or ran into a chain already drawn
    at = ahead + side * across;
    px[at] = static_cast<std::uint16_t>(w | kEdgeBit);
    if (dx == 0) {
      x += side;
      y += dy;
    } else {
      x += dx;
      y += side;
    }
    out->emplace_back(x, y);
    // The edge turned: continue along its new orientation, away from where the step came from.
    const bool vertical = (w & kDirBit) != 0;
    if (vertical && dx != 0) {
      dy = side != 0 ? side : (magnitude(px[at - cols]) >= magnitude(px[at + cols]) ? -1 : 1);
      dx = 0;
      forward = dy * cols;
      across = 1;
    } else if (!vertical && dy != 0) {
      dx = side != 0 ? side : (magnitude(px[at - 1]) >= magnitude(px[at + 1]) ? -1 : 1);
      dy = 0;
      forward = dx;
      across = cols;
    }
  }
}

void EdgeDrawing::fitLines(const std::vector<cv::Point>& chain, std::vector<cv::Vec4f>* lines) const {
  const int n = static_cast<int>(chain.size()), L = std::max(2, options_.min_line_px);
  if (n < L) return;
  const double tol = options_.fit_error_px, tol2 = tol * tol;
  // Coordinates relative to the chain's first pixel keep the sums well conditioned.
  const double ox = chain[0].x, oy = chain[0].y;
  // The sums of the window [i, i + L) slide along the chain: the terms are integers far below 2^53, so adding the
  // pixel entering and subtracting the one leaving gives exactly the sums recomputed from scratch.
  double wx = 0, wy = 0, wxx = 0, wyy = 0, wxy = 0;
  const auto addPixel = [&](int k, double sign) {
    const double x = chain[k].x - ox, y = chain[k].y - oy;
    wx += sign * x, wy += sign * y, wxx += sign * (x * x), wyy += sign * (y * y), wxy += sign * (x * y);
  };
  int i = 0;
  for (int k = 0; k < std::min(n, L); ++k) addPixel(k, 1.0);
  while (n - i >= L) {
    double sx = wx, sy = wy, sxx = wxx, syy = wyy, sxy = wxy;
    // Most windows tried are not straight: those that surely are not skip the fit (the same decision, see
    // surelyNotStraight).
    bool straight = !surelyNotStraight(L, sx, sy, sxx, syy, sxy, tol2);
    LineFit f;
    if (straight) {
      f = fitFromSums(L, sx, sy, sxx, syy, sxy);
      straight = f.mse <= tol2;  // cheap test first, then every pixel of the window within tol
    }
    for (int k = i; straight && k < i + L; ++k) straight = distance(f, chain[k].x - ox, chain[k].y - oy) <= tol;
    if (!straight) {
      addPixel(i, -1.0);
      if (i + L < n) addPixel(i + L, 1.0);
      ++i;
      continue;
    }
    double cnt = L;
    int last = i + L - 1, misses = 0, since_fit = 0;
    for (int j = i + L; j < n; ++j) {
      const double x = chain[j].x - ox, y = chain[j].y - oy;
      if (distance(f, x, y) > tol) {
        if (++misses > options_.max_outliers) break;
        continue;
      }
      misses = 0;
      last = j;
      cnt += 1.0, sx += x, sy += y, sxx += x * x, syy += y * y, sxy += x * y;
      if (++since_fit >= 8) {  // refit as the piece grows, so that a slow bend is followed only a little
        f = fitFromSums(cnt, sx, sy, sxx, syy, sxy);
        since_fit = 0;
      }
    }
    f = fitFromSums(cnt, sx, sy, sxx, syy, sxy);
    const double t0 = (chain[i].x - ox - f.cx) * f.dx + (chain[i].y - oy - f.cy) * f.dy;
    const double t1 = (chain[last].x - ox - f.cx) * f.dx + (chain[last].y - oy - f.cy) * f.dy;
    lines->emplace_back(static_cast<float>(ox + f.cx + t0 * f.dx), static_cast<float>(oy + f.cy + t0 * f.dy),
                        static_cast<float>(ox + f.cx + t1 * f.dx), static_cast<float>(oy + f.cy + t1 * f.dy));
    i = last + 1;
    wx = wy = wxx = wyy = wxy = 0;
    for (int k = i; k < std::min(n, i + L); ++k) addPixel(k, 1.0);
  }
}

}  // namespace linnet
