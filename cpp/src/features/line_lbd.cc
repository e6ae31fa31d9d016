// Binary LBD descriptor (see line_lbd.h).
#include "linnet/features/line_lbd.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <utility>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "linnet/core/error.h"

namespace linnet {
namespace {

constexpr int kRows = kLbdBands * kLbdBandWidth;  // 63
constexpr int kHalf = kRows / 2;                  // 31

// Band pairs compared by the binary descriptor: all 36 pairs sorted by band distance, the first 32 kept.
std::array<std::pair<int, int>, 32> makeBandPairs() {
  std::array<std::pair<int, int>, 32> pairs{};
  int k = 0;
  for (int dist = 1; dist < kLbdBands && k < 32; ++dist)
    for (int i = 0; i + dist < kLbdBands && k < 32; ++i) pairs[k++] = {i, i + dist};
  return pairs;
}

struct Weights {
  std::array<float, kRows> global{};
  // local[j][r]: weight of row r for band j (0 outside bands j-1..j+1).
  std::array<std::array<float, kRows>, kLbdBands> local{};
  Weights() {
    const double sg = 0.5 * (kRows - 1);
    const double sl = kLbdBandWidth;
    for (int r = 0; r < kRows; ++r) global[r] = static_cast<float>(std::exp(-0.5 * (r - kHalf) * (r - kHalf) / (sg * sg)));
    for (int j = 0; j < kLbdBands; ++j) {
      const double centre = j * kLbdBandWidth + 0.5 * (kLbdBandWidth - 1);
      for (int r = 0; r < kRows; ++r) {
        const int band = r / kLbdBandWidth;
        local[j][r] = (std::abs(band - j) <= 1)
                          ? static_cast<float>(std::exp(-0.5 * (r - centre) * (r - centre) / (sl * sl)))
                          : 0.0f;
      }
    }
  }
};

// Where computeLbdFloat samples a segment's support region: patch row q (0..kRows+1) lies at offset q - kHalf - 1
// along the normal n, patch column c (0..ns+1) at (c - 0.5) * step along the direction d from the start s.
struct Sampling {
  int ns = 0;         // samples along the segment per row
  int cols = 0;       // ns + 2: one more each side for the along-line gradient
  float step = 0.f;   // pixels between samples
  float sx = 0.f, sy = 0.f, nx = 0.f, ny = 0.f, x0 = 0.f, y0 = 0.f;  // step * d, n, s
};

constexpr int kPatchRows = kRows + 2;
constexpr int kPatchSlack = 16;  // bytes past each patch row that rowSad may read (masked out)
using Patch = std::uint8_t[kPatchRows][1024 + 2 + kPatchSlack];
using RowSums = std::array<std::array<float, 4>, kRows>;

// Patch row q, nearest pixel. Rows inside the image are walked in 16.16 fixed point; rows leaving it are clamped to
// the border. `fast`: the inside rows' pixel offsets four at a time (SSE2; the same integers, so the same pixels).
void sampleRow(const cv::Mat& gray, const Sampling& g, int q, bool fast, std::uint8_t* row) {
  const int max_xi = gray.cols - 1, max_yi = gray.rows - 1;
  const std::ptrdiff_t stride = static_cast<std::ptrdiff_t>(gray.step[0]);
  const float off = static_cast<float>(q - kHalf - 1);
  const float bx = g.x0 + off * g.nx - 0.5f * g.sx;
  const float by = g.y0 + off * g.ny - 0.5f * g.sy;
  const float ex = bx + static_cast<float>(g.cols - 1) * g.sx, ey = by + static_cast<float>(g.cols - 1) * g.sy;
  const bool inside = std::min(bx, ex) >= 0.f && std::min(by, ey) >= 0.f &&
                      std::max(bx, ex) <= static_cast<float>(max_xi) && std::max(by, ey) <= static_cast<float>(max_yi);
  if (!inside) {
    for (int c = 0; c < g.cols; ++c) {
      const int xi = std::clamp(static_cast<int>(std::floor(bx + static_cast<float>(c) * g.sx + 0.5f)), 0, max_xi);
      const int yi = std::clamp(static_cast<int>(std::floor(by + static_cast<float>(c) * g.sy + 0.5f)), 0, max_yi);
      row[c] = gray.data[static_cast<std::ptrdiff_t>(yi) * stride + xi];
    }
    return;
  }
  std::int32_t fx = static_cast<std::int32_t>((bx + 0.5f) * 65536.f);
  std::int32_t fy = static_cast<std::int32_t>((by + 0.5f) * 65536.f);
  const std::int32_t fsx = static_cast<std::int32_t>(g.sx * 65536.f), fsy = static_cast<std::int32_t>(g.sy * 65536.f);
  int c = 0;
#if defined(__SSE2__)
  // x = fx >> 16 and y = fy >> 16 (both >= 0 inside the image) packed as 16-bit halves of a lane, so that one
  // multiply-add gives x + y * stride (coordinates and the row step below 2^15).
  if (fast && stride < 32768 && gray.cols < 32768 && gray.rows < 32768) {
    alignas(16) std::int32_t offsets[4];
    __m128i vx = _mm_setr_epi32(fx, fx + fsx, fx + 2 * fsx, fx + 3 * fsx);
    __m128i vy = _mm_setr_epi32(fy, fy + fsy, fy + 2 * fsy, fy + 3 * fsy);
    const __m128i step_x = _mm_set1_epi32(4 * fsx), step_y = _mm_set1_epi32(4 * fsy);
    const __m128i high = _mm_set1_epi32(static_cast<std::int32_t>(0xFFFF0000u));
    const __m128i weights = _mm_set1_epi32(static_cast<std::int32_t>((static_cast<std::uint32_t>(stride) << 16) | 1u));
    for (; c + 4 <= g.cols; c += 4) {
      const __m128i xy = _mm_or_si128(_mm_srli_epi32(vx, 16), _mm_and_si128(vy, high));
      _mm_store_si128(reinterpret_cast<__m128i*>(offsets), _mm_madd_epi16(xy, weights));
      row[c] = gray.data[offsets[0]];
      row[c + 1] = gray.data[offsets[1]];
      row[c + 2] = gray.data[offsets[2]];
      row[c + 3] = gray.data[offsets[3]];
      vx = _mm_add_epi32(vx, step_x);
      vy = _mm_add_epi32(vy, step_y);
    }
    fx += c * fsx;
    fy += c * fsy;
  }
#endif
  for (; c < g.cols; ++c, fx += fsx, fy += fsy)
    row[c] = gray.data[static_cast<std::ptrdiff_t>(fy >> 16) * stride + (fx >> 16)];
}

#if defined(__SSE2__)
// 16 x 0xFF, then 16 x 0: a load at kTailMask + 16 - k keeps the first k lanes.
constexpr std::array<std::uint8_t, 32> kTailMask = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,
                                                    0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
#endif

// Sum over i < n of |a[i] - b[i]|. With SSE2, 16 bytes at a time (PSADBW), reading up to 15 bytes past a + n and
// b + n (masked out).
std::int32_t rowSad(const std::uint8_t* a, const std::uint8_t* b, int n) {
  std::int32_t total = 0;
  int i = 0;
#if defined(__SSE2__)
  __m128i acc = _mm_setzero_si128();
  for (; i + 16 <= n; i += 16)
    acc = _mm_add_epi64(acc, _mm_sad_epu8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a + i)),
                                          _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + i))));
  if (i < n) {  // the first n - i lanes
    const __m128i mask = _mm_loadu_si128(reinterpret_cast<const __m128i*>(kTailMask.data() + 16 - (n - i)));
    const __m128i va = _mm_and_si128(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a + i)), mask);
    const __m128i vb = _mm_and_si128(_mm_loadu_si128(reinterpret_cast<const __m128i*>(b + i)), mask);
    acc = _mm_add_epi64(acc, _mm_sad_epu8(va, vb));
    i = n;
  }
  total = _mm_cvtsi128_si32(acc) + _mm_cvtsi128_si32(_mm_unpackhi_epi64(acc, acc));
#endif
  for (; i < n; ++i) total += std::abs(static_cast<std::int32_t>(a[i]) - static_cast<std::int32_t>(b[i]));
  return total;
}

// Sum over i < n of a[i] (n <= 1024, the largest max_samples): rowSad against a row of zeros.
std::int32_t rowSum(const std::uint8_t* a, int n) {
  static constexpr std::array<std::uint8_t, 1024 + kPatchSlack> kZeros{};  // rowSad reads up to 15 bytes past n
  return rowSad(a, kZeros.data(), n);
}

// Gradients in the patch frame are the projections LBD needs: g_perp = P(q+1, c) - P(q-1, c) (along n),
// g_L = (P(q, c+1) - P(q, c-1)) / step (along d). Each row sums (g_perp > 0, -g_perp < 0, g_L > 0, -g_L < 0), as a
// mean over its samples times the global weight. `fast`: the sums split by sign through
// sum(max(g, 0)) = (sum|g| + sum g) / 2 and sum(max(-g, 0)) = (sum|g| - sum g) / 2, exact in integers: sum g is a
// difference of two row sums (g_perp) or telescopes to four pixels (g_L), sum|g| a sum of absolute differences of two
// byte rows; the first, a difference of the two rows' byte sums, each patch row's sum taken once.
void rowSums(const Patch& patch, const Sampling& g, bool fast, const Weights& weights, RowSums* rows) {
  const int ns = g.ns;
  const float inv_step = 1.f / g.step;
  std::array<std::int32_t, kPatchRows> byte_sums{};
  if (fast)
    for (int q = 0; q < kPatchRows; ++q) byte_sums[static_cast<std::size_t>(q)] = rowSum(patch[q] + 1, ns);
  for (int r = 0; r < kRows; ++r) {
    const std::uint8_t* up = patch[r];
    const std::uint8_t* mid = patch[r + 1];
    const std::uint8_t* down = patch[r + 2];
    std::int32_t b0 = 0, b1 = 0, b2 = 0, b3 = 0;
    if (fast) {
      const std::int32_t sum_p = byte_sums[static_cast<std::size_t>(r + 2)] - byte_sums[static_cast<std::size_t>(r)];
      const std::int32_t sum_l = static_cast<std::int32_t>(mid[ns + 1]) + mid[ns] - mid[1] - mid[0];
      const std::int32_t abs_p = rowSad(down + 1, up + 1, ns), abs_l = rowSad(mid + 2, mid, ns);
      b0 = (abs_p + sum_p) / 2;
      b1 = (abs_p - sum_p) / 2;
      b2 = (abs_l + sum_l) / 2;
      b3 = (abs_l - sum_l) / 2;
    } else {
      for (int c = 1; c <= ns; ++c) {
        const std::int32_t gp = static_cast<std::int32_t>(down[c]) - static_cast<std::int32_t>(up[c]);
        const std::int32_t gl = static_cast<std::int32_t>(mid[c + 1]) - static_cast<std::int32_t>(mid[c - 1]);
        b0 += std::max(gp, 0);
        b1 += std::max(-gp, 0);
        b2 += std::max(gl, 0);
        b3 += std::max(-gl, 0);
      }
    }
    const float w = weights.global[r] / static_cast<float>(ns);
    (*rows)[r] = {static_cast<float>(b0) * w, static_cast<float>(b1) * w, static_cast<float>(b2) * w * inv_step,
                  static_cast<float>(b3) * w * inv_step};
  }
}

// The 72 floats from the row sums: band means and deviations, normalised, clamped and renormalised.
// `fast`: the four sums of a row at once (SSE2: the same products and sums per lane, so the same floats).
std::array<float, kLbdFloats> bandsOf(const RowSums& rows, const LbdOptions& options, const Weights& weights,
                                      bool fast) {
  std::array<float, kLbdFloats> out{};
  // Band descriptors: weighted mean and standard deviation over the rows of bands j-1..j+1.
  for (int j = 0; j < kLbdBands; ++j) {
    const int r0 = std::max(0, (j - 1) * kLbdBandWidth), r1 = std::min(kRows, (j + 2) * kLbdBandWidth);
    alignas(16) float mean[4] = {0, 0, 0, 0}, sq[4] = {0, 0, 0, 0};
    const int cnt = r1 - r0;
    int r = r0;
#if defined(__SSE2__)
    if (fast) {
      __m128 m4 = _mm_setzero_ps(), s4 = _mm_setzero_ps();
      for (; r < r1; ++r) {
        const __m128 v = _mm_mul_ps(_mm_set1_ps(weights.local[j][r]), _mm_loadu_ps(rows[r].data()));
        m4 = _mm_add_ps(m4, v);
        s4 = _mm_add_ps(s4, _mm_mul_ps(v, v));
      }
      _mm_store_ps(mean, m4);
      _mm_store_ps(sq, s4);
    }
#endif
    for (; r < r1; ++r) {
      const float wl = weights.local[j][r];
      for (int c = 0; c < 4; ++c) {
        const float v = wl * rows[r][c];
        mean[c] += v;
        sq[c] += v * v;
      }
    }
    for (int c = 0; c < 4; ++c) {
      const float m = mean[c] / static_cast<float>(cnt);
      const float var = std::max(0.f, sq[c] / static_cast<float>(cnt) - m * m);
      out[j * 8 + c] = m;
      out[j * 8 + 4 + c] = std::sqrt(var);
    }
  }
  // Normalise the means and the deviations separately, clamp, renormalise.
  float nm = 0.f, nsd = 0.f;
  for (int j = 0; j < kLbdBands; ++j)
    for (int c = 0; c < 4; ++c) {
      nm += out[j * 8 + c] * out[j * 8 + c];
      nsd += out[j * 8 + 4 + c] * out[j * 8 + 4 + c];
    }
  if (nm <= 1e-12f) return std::array<float, kLbdFloats>{};
  nm = 1.f / std::sqrt(nm);
  nsd = nsd > 1e-12f ? 1.f / std::sqrt(nsd) : 0.f;
  float total = 0.f;
  const float cl = static_cast<float>(options.clamp);
  for (int j = 0; j < kLbdBands; ++j)
    for (int c = 0; c < 4; ++c) {
      float& m = out[j * 8 + c];
      float& s = out[j * 8 + 4 + c];
      m = std::min(m * nm, cl);
      s = std::min(s * nsd, cl);
      total += m * m + s * s;
    }
  const float inv = 1.f / std::sqrt(total);
  for (float& v : out) v *= inv;
  return out;
}

std::array<float, kLbdFloats> lbdFloat(const cv::Mat& gray, const LbdOptions& options, const LineSegment& seg,
                                       bool fast) {
  static_assert(kRows == 63);
  static const Weights kWeights;  // immutable tables, built once (not mutable state)
  const double len = seg.length();
  if (!(len > 1.0) || gray.cols < 3 || gray.rows < 3) return {};
  const Vec2 d = seg.direction();
  Sampling g;
  g.ns = std::clamp(static_cast<int>(len), 2, options.max_samples);
  g.cols = g.ns + 2;
  g.step = static_cast<float>(len / g.ns);
  g.sx = g.step * static_cast<float>(d.x());
  g.sy = g.step * static_cast<float>(d.y());
  g.nx = static_cast<float>(-d.y());
  g.ny = static_cast<float>(d.x());
  g.x0 = static_cast<float>(seg.s.x());
  g.y0 = static_cast<float>(seg.s.y());
  Patch patch;
  for (int q = 0; q < kPatchRows; ++q) sampleRow(gray, g, q, fast, patch[q]);
  RowSums rows;
  rowSums(patch, g, fast, kWeights, &rows);
  return bandsOf(rows, options, kWeights, fast);
}

}  // namespace

std::array<float, kLbdFloats> computeLbdFloat(const cv::Mat& gray, const LbdOptions& options, const LineSegment& seg) {
  return lbdFloat(gray, options, seg, /*fast=*/true);
}

std::array<float, kLbdFloats> computeLbdFloatPlain(const cv::Mat& gray, const LbdOptions& options,
                                                   const LineSegment& seg) {
  return lbdFloat(gray, options, seg, /*fast=*/false);
}

LbdDescriptor binarizeLbd(const std::array<float, kLbdFloats>& f) {
  static const std::array<std::pair<int, int>, 32> kPairs = makeBandPairs();
  LbdDescriptor desc{0, 0, 0, 0};
  int bit = 0;
  for (const auto& [a, b] : kPairs)
    for (int c = 0; c < 8; ++c, ++bit)  // branch-free: the comparisons' outcomes are unpredictable
      desc[bit >> 6] |= static_cast<std::uint64_t>(f[a * 8 + c] > f[b * 8 + c]) << (bit & 63);
  return desc;
}

void computeLbd(const cv::Mat& gray, const LbdOptions& options, const std::vector<LineSegment>& segments,
                std::vector<LbdDescriptor>* out) {
  if (!gray.empty() && gray.type() != CV_8UC1) throw UsageError("computeLbd: expected an 8-bit single-channel image");
  out->resize(segments.size());
  for (std::size_t i = 0; i < segments.size(); ++i)
    (*out)[i] = gray.empty() ? LbdDescriptor{0, 0, 0, 0} : binarizeLbd(computeLbdFloat(gray, options, segments[i]));
}

}  // namespace linnet
