// FAST 9-16 corners with cv::FAST's results (see fast_corners.h).
#include "linnet/features/fast_corners.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <vector>

#include <opencv2/features2d.hpp>

#include "linnet/core/error.h"

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define LINNET_FAST_AVX2 1
#endif

namespace linnet {
namespace {

using U8 = std::uint8_t;

// The Bresenham circle of radius 3 (dx, dy), in order around it: the test and the score only need the ring's order.
constexpr int kRing[16][2] = {{0, 3},  {1, 3},   {2, 2},   {3, 1},   {3, 0},  {3, -1}, {2, -2}, {1, -3},
                              {0, -3}, {-1, -3}, {-2, -2}, {-3, -1}, {-3, 0}, {-3, 1}, {-2, 2}, {-1, 3}};

#ifdef LINNET_FAST_AVX2

// Helpers inlined into the row kernel (a call would pass their vectors through memory).
#define LINNET_FAST_AVX2_HELPER __attribute__((target("avx2"), always_inline)) inline

LINNET_FAST_AVX2_HELPER __m256i load32(const U8* p) { return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p)); }

// Per lane, the largest over the 16 arcs of 9 contiguous ring entries of the arc's smallest e[k] (unsigned bytes), by
// doubling: runs of 2, 4, 8, then 9.
LINNET_FAST_AVX2_HELPER __m256i bestArc(const __m256i* e) {
  __m256i m2[16], m4[16];
  for (int k = 0; k < 16; ++k) m2[k] = _mm256_min_epu8(e[k], e[(k + 1) & 15]);
  for (int k = 0; k < 16; ++k) m4[k] = _mm256_min_epu8(m2[k], m2[(k + 2) & 15]);
  __m256i best = _mm256_setzero_si256();
  for (int k = 0; k < 16; ++k)
    best = _mm256_max_epu8(best, _mm256_min_epu8(_mm256_min_epu8(m4[k], m4[(k + 4) & 15]), e[(k + 8) & 15]));
  return best;
}

// One image row (`row`: its column 0): columns 3..cols - 4 tested 32 at a time (the last block moved back to end at
// cols - 4; cols >= 38), each corner's score written to `scores` (0 elsewhere: the caller zeroes the row). True if
// the row holds a corner.
//
// With the differences clamped at 0, v -sat x and x -sat v, an arc's smallest is max(true smallest, 0), and the largest
// over the arcs max(true largest, 0): the same as cornerScore's wherever it exceeds t >= 0. So the best arc b (either
// sign) decides both: a corner where b > t, its score b - 1 (cornerScore: max(t, b) - 1), all in bytes.
__attribute__((target("avx2"))) bool rowAvx2(const U8* row, const int* ring, int cols, int threshold, U8* scores) {
  const __m256i bias = _mm256_set1_epi8(static_cast<char>(0x80));  // unsigned order through signed compares
  const __m256i t8 = _mm256_set1_epi8(static_cast<char>(threshold));
  const __m256i one = _mm256_set1_epi8(1);
  const int last = cols - 4;
  bool any = false;
  for (int done = 3; done <= last;) {
    const int j = std::min(done, last - 31);
    const U8* c = row + j;
    const std::uint32_t fresh = ~0u << (done - j);  // lanes before `done` were tested by the previous block
    done = j + 32;
    const __m256i v = load32(c);
    // A 9-arc holds two neighbouring ones of the four compass pixels (0, 4, 8, 12): a block where no such pair is
    // brighter than v + t or darker than v - t (saturated: then no pixel is) holds no corner.
    const __m256i hi = _mm256_xor_si256(_mm256_adds_epu8(v, t8), bias);
    const __m256i lo = _mm256_xor_si256(_mm256_subs_epu8(v, t8), bias);
    __m256i x[16], brighter[4], darker[4];
    for (int k = 0; k < 16; k += 4) {
      x[k] = load32(c + ring[k]);
      const __m256i xs = _mm256_xor_si256(x[k], bias);
      brighter[k / 4] = _mm256_cmpgt_epi8(xs, hi);
      darker[k / 4] = _mm256_cmpgt_epi8(lo, xs);
    }
    __m256i pair = _mm256_setzero_si256();
    for (int k = 0; k < 4; ++k) {
      const int n = (k + 1) & 3;
      pair = _mm256_or_si256(pair, _mm256_or_si256(_mm256_and_si256(brighter[k], brighter[n]),
                                                   _mm256_and_si256(darker[k], darker[n])));
    }
    if ((static_cast<std::uint32_t>(_mm256_movemask_epi8(pair)) & fresh) == 0) continue;
    __m256i below[16], above[16];  // v -sat x, x -sat v
    for (int k = 0; k < 16; ++k) {
      if (k % 4 != 0) x[k] = load32(c + ring[k]);
      below[k] = _mm256_subs_epu8(v, x[k]);
      above[k] = _mm256_subs_epu8(x[k], v);
    }
    const __m256i best = _mm256_max_epu8(bestArc(below), bestArc(above));
    const __m256i corner = _mm256_xor_si256(_mm256_cmpeq_epi8(_mm256_min_epu8(best, t8), best),
                                            _mm256_set1_epi8(-1));  // best > t
    if ((static_cast<std::uint32_t>(_mm256_movemask_epi8(corner)) & fresh) == 0) continue;
    // Lanes the previous block tested are written again, with the same scores.
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(scores + j), _mm256_and_si256(_mm256_sub_epi8(best, one), corner));
    any = true;
  }
  return any;
}

// Non-maximum suppression of row y (scores `mid`, with `up` and `down` above and below), as cv::FAST's: a corner is
// kept where its score is above all eight neighbours' (lanes without a corner have 0, above nothing). Keypoints in
// increasing column order, 32 columns at a time as in rowAvx2.
__attribute__((target("avx2"))) void suppressRowAvx2(const U8* up, const U8* mid, const U8* down, int cols, int y,
                                                     std::vector<cv::KeyPoint>* keypoints) {
  const int last = cols - 4;
  for (int done = 3; done <= last;) {
    const int j = std::min(done, last - 31);
    const std::uint32_t fresh = ~0u << (done - j);
    done = j + 32;
    const __m256i s = load32(mid + j);
    // s > n for unsigned bytes: not (max(n, s) == n).
    __m256i not_above = _mm256_setzero_si256();
    for (const U8* n : {up + j - 1, up + j, up + j + 1, mid + j - 1, mid + j + 1, down + j - 1, down + j, down + j + 1})
      not_above = _mm256_or_si256(not_above, _mm256_cmpeq_epi8(_mm256_max_epu8(load32(n), s), load32(n)));
    for (std::uint32_t keep = ~static_cast<std::uint32_t>(_mm256_movemask_epi8(not_above)) & fresh; keep != 0;
         keep &= keep - 1) {
      const int x = j + std::countr_zero(keep);
      keypoints->emplace_back(static_cast<float>(x), static_cast<float>(y), 7.f, -1.f, static_cast<float>(mid[x]));
    }
  }
}

#endif  // LINNET_FAST_AVX2

}  // namespace

void fastCorners(const cv::Mat& image, int threshold, std::vector<cv::KeyPoint>* keypoints, bool simd) {
  if (image.type() != CV_8UC1) throw UsageError("fastCorners: needs an 8-bit single-channel image");
  // cv::FAST takes others, but its vector and scalar paths disagree about them (300 acts as 44 in one of them).
  if (threshold < 0 || threshold > 255) throw UsageError("fastCorners: the threshold must be 0..255");
  if (image.empty()) {
    keypoints->clear();
    return;
  }
  const int rows = image.rows, cols = image.cols;
#ifdef LINNET_FAST_AVX2
  const bool avx2 = simd && cols >= 38 && rows >= 7 && __builtin_cpu_supports("avx2");
#else
  const bool avx2 = false;
#endif
  if (!avx2) {
    cv::FAST(image, *keypoints, threshold, true, cv::FastFeatureDetector::TYPE_9_16);
    return;
  }
#ifdef LINNET_FAST_AVX2
  keypoints->clear();
  const auto step = static_cast<int>(image.step[0]);
  int ring[16];
  for (int k = 0; k < 16; ++k) ring[k] = kRing[k][0] + kRing[k][1] * step;
  // Scores (0: no corner) of three rows, cyclically: row y is detected into its buffer, then row y - 1's corners are
  // suppressed against rows y - 2..y (cv::FAST's order). Rows 2 and rows - 3 stay 0.
  std::vector<U8> scores(3 * static_cast<std::size_t>(cols), 0);
  const auto rowOf = [&](int y) { return scores.data() + static_cast<std::size_t>(y % 3) * cols; };
  bool previous = false;  // row y - 1 holds a corner
  for (int y = 3; y <= rows - 3; ++y) {
    U8* cur = rowOf(y);
    std::fill_n(cur, cols, U8{0});
    const bool current = y < rows - 3 && rowAvx2(image.ptr<U8>(y), ring, cols, threshold, cur);
    if (previous) suppressRowAvx2(rowOf(y - 2), rowOf(y - 1), cur, cols, y - 1, keypoints);
    previous = current;
  }
#endif
}

}  // namespace linnet
