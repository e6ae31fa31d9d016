// The window kernels of lucasKanade (see lucas_kanade_kernels.h). The integer parts are exact, and the float sums are
// taken in one fixed order, so the plain and the AVX2 versions give the same bits.
#include "linnet/features/lucas_kanade_kernels.h"

#include <vector>

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define LINNET_LK_AVX2 1
#endif

namespace linnet::lk {

namespace {

using I16 = std::int16_t;
using I32 = std::int32_t;
using U8 = std::uint8_t;

// Pixel x of two rows sampled at the weights' offset and rounded off by `shift` bits: kSampleShift for image rows
// (5 fractional bits kept), kWeightBits for derivative rows (kept at their scale).
template <typename T>
int sample(const T* r0, const T* r1, int x, const Weights& w, int shift) {
  return (r0[x] * w.w00 + r0[x + 1] * w.w01 + r1[x] * w.w10 + r1[x + 1] * w.w11 + (1 << (shift - 1))) >> shift;
}

// Scharr derivatives of pixel (i, j) of the window (img at its top-left pixel): 0 outside the image.
void scharr(const U8* img, std::ptrdiff_t step, int i, int j, const WindowPlace& pl, I16* dx, I16* dy) {
  const int X = pl.x + i, Y = pl.y + j;
  if (X < 0 || X >= pl.cols || Y < 0 || Y >= pl.rows) {
    *dx = *dy = 0;
    return;
  }
  const U8* mid = img + j * step + i;
  const U8* up = mid - step;
  const U8* dn = mid + step;
  const auto across = [&](int o) { return 3 * (up[o] + dn[o]) + 10 * mid[o]; };
  const auto along = [&](int o) { return dn[o] - up[o]; };
  *dx = static_cast<I16>(across(1) - across(-1));
  *dy = static_cast<I16>(3 * (along(-1) + along(1)) + 10 * along(0));
}

// The float sums' order, shared by both versions: lanes of whole blocks of 8, then the scalar rest.
GradientSums finishGradient(const float* q11, const float* q12, const float* q22, float s11, float s12, float s22) {
  GradientSums g;
  g.a11 = s11 + ((q11[0] + q11[2]) + (q11[1] + q11[3]));
  g.a12 = s12 + ((q12[0] + q12[2]) + (q12[1] + q12[3]));
  g.a22 = s22 + ((q22[0] + q22[2]) + (q22[1] + q22[3]));
  return g;
}

void finishResidual(const float* q, float s1, float s2, float* b1, float* b2) {
  const float c0 = q[0] + q[4], c1 = q[1] + q[5], c2 = q[2] + q[6], c3 = q[3] + q[7];
  *b1 = s1 + (c0 + c2);
  *b2 = s2 + (c1 + c3);
}

}  // namespace

GradientSums templatePlain(const U8* img, std::ptrdiff_t img_step, WindowShape shape, WindowPlace place, Weights w,
                           I16* t, I16* gx, I16* gy) {
  float q11[4] = {0.f, 0.f, 0.f, 0.f}, q12[4] = {0.f, 0.f, 0.f, 0.f}, q22[4] = {0.f, 0.f, 0.f, 0.f};
  float s11 = 0.f, s12 = 0.f, s22 = 0.f;
  const int stride = shape.chunks * kLanes, blocks = shape.width / 8, n = stride + 1;
  std::vector<I16> dx(static_cast<std::size_t>(n * (shape.rows + 1))), dy(dx.size());
  for (int j = 0; j <= shape.rows; ++j)
    for (int i = 0; i < n; ++i) scharr(img, img_step, i, j, place, &dx[j * n + i], &dy[j * n + i]);
  for (int y = 0; y < shape.rows; ++y) {
    const U8* r0 = img + y * img_step;
    I16* tr = t + y * stride;
    I16* xr = gx + y * stride;
    I16* yr = gy + y * stride;
    for (int x = 0; x < stride; ++x) {
      tr[x] = static_cast<I16>(sample(r0, r0 + img_step, x, w, kSampleShift));
      xr[x] = static_cast<I16>(sample(&dx[y * n], &dx[(y + 1) * n], x, w, kWeightBits));
      yr[x] = static_cast<I16>(sample(&dy[y * n], &dy[(y + 1) * n], x, w, kWeightBits));
    }
    for (int x = 0; x < 8 * blocks; x += 4) {
      for (int k = 0; k < 4; ++k) {
        const float fx = xr[x + k], fy = yr[x + k];
        q22[k] = fy * fy + q22[k];
        q12[k] = fx * fy + q12[k];
        q11[k] = fx * fx + q11[k];
      }
    }
    for (int x = 8 * blocks; x < shape.width; ++x) {
      s11 += static_cast<float>(xr[x] * xr[x]);
      s12 += static_cast<float>(xr[x] * yr[x]);
      s22 += static_cast<float>(yr[x] * yr[x]);
    }
  }
  return finishGradient(q11, q12, q22, s11, s12, s22);
}

void residualPlain(const U8* img, std::ptrdiff_t img_step, WindowShape shape, Weights w, const I16* t, const I16* gx,
                   const I16* gy, float* b1, float* b2) {
  I32 X[kMaxStride], Y[kMaxStride];
  float q[8] = {0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f, 0.f};
  float s1 = 0.f, s2 = 0.f;
  const int stride = shape.chunks * kLanes, blocks = shape.width / 8;
  for (int y = 0; y < shape.rows; ++y) {
    const U8* r0 = img + y * img_step;
    const int o = y * stride;
    for (int x = 0; x < shape.width; ++x) {
      const int r = sample(r0, r0 + img_step, x, w, kSampleShift) - t[o + x];
      X[x] = r * gx[o + x];
      Y[x] = r * gy[o + x];
    }
    for (int x = 0; x < 8 * blocks; x += 8) {
      for (int k = 0; k < 4; ++k) {
        q[2 * k] += static_cast<float>(X[x + k] + X[x + k + 4]);
        q[2 * k + 1] += static_cast<float>(Y[x + k] + Y[x + k + 4]);
      }
    }
    for (int x = 8 * blocks; x < shape.width; ++x) {
      s1 += static_cast<float>(X[x]);
      s2 += static_cast<float>(Y[x]);
    }
  }
  finishResidual(q, s1, s2, b1, b2);
}

#ifdef LINNET_LK_AVX2

namespace {

// The AVX2 kernels' helpers, inlined into them (a call would pass their vectors through memory).
#define LINNET_LK_AVX2_HELPER __attribute__((target("avx2"), always_inline)) inline

// Pairs (a, b) of int16 for _mm256_madd_epi16: a in the low half of each 32-bit lane.
LINNET_LK_AVX2_HELPER __m256i weightPair(int a, int b) {
  return _mm256_set1_epi32(static_cast<int>((static_cast<unsigned>(b) << 16) | (static_cast<unsigned>(a) & 0xffffu)));
}

// 16 samples x0..x0+15 of two image rows, each (r[x] w_0 + r[x + 1] w_1) per row, rounded off by `shift` bits, as
// int16 in their natural order. a0, a1: the rows' samples at x and x + 1 (as int16), likewise b0, b1.
LINNET_LK_AVX2_HELPER __m256i bilinear16(__m256i a0, __m256i a1, __m256i b0, __m256i b1, __m256i wa, __m256i wb,
                                         int shift) {
  const __m256i round = _mm256_set1_epi32(1 << (shift - 1));
  __m256i lo = _mm256_add_epi32(_mm256_madd_epi16(_mm256_unpacklo_epi16(a0, a1), wa),
                                _mm256_madd_epi16(_mm256_unpacklo_epi16(b0, b1), wb));
  __m256i hi = _mm256_add_epi32(_mm256_madd_epi16(_mm256_unpackhi_epi16(a0, a1), wa),
                                _mm256_madd_epi16(_mm256_unpackhi_epi16(b0, b1), wb));
  lo = _mm256_sra_epi32(_mm256_add_epi32(lo, round), _mm_cvtsi32_si128(shift));
  hi = _mm256_sra_epi32(_mm256_add_epi32(hi, round), _mm_cvtsi32_si128(shift));
  return _mm256_packs_epi32(lo, hi);  // lanes 0-3, 4-7 | 8-11, 12-15: the natural order
}

LINNET_LK_AVX2_HELPER __m256i loadBytes16(const U8* p) {
  return _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
}

// Scharr derivatives of 16 pixels of a row (mid at the first; up, dn the rows above and below): *dx, *dy of pixels
// 0..15 and *dx1, *dy1 of pixels 1..16, masked by the lanes inside the image (in0, in1). Reads pixels -1 .. 17.
struct Derivatives16 {
  __m256i dx, dy, dx1, dy1;
};

LINNET_LK_AVX2_HELPER Derivatives16 scharr16(const U8* up, const U8* mid, const U8* dn, __m256i in0, __m256i in1) {
  const __m256i three = _mm256_set1_epi16(3), ten = _mm256_set1_epi16(10);
  __m256i across[4], along[4];  // offsets -1, 0, 1, 2
  for (int o = 0; o < 4; ++o) {
    const __m256i a = loadBytes16(up + o - 1), b = loadBytes16(mid + o - 1), c = loadBytes16(dn + o - 1);
    across[o] = _mm256_add_epi16(_mm256_mullo_epi16(_mm256_add_epi16(a, c), three), _mm256_mullo_epi16(b, ten));
    along[o] = _mm256_sub_epi16(c, a);
  }
  Derivatives16 d;
  d.dx = _mm256_and_si256(_mm256_sub_epi16(across[2], across[0]), in0);
  d.dx1 = _mm256_and_si256(_mm256_sub_epi16(across[3], across[1]), in1);
  d.dy = _mm256_and_si256(_mm256_add_epi16(_mm256_mullo_epi16(_mm256_add_epi16(along[0], along[2]), three),
                                           _mm256_mullo_epi16(along[1], ten)),
                          in0);
  d.dy1 = _mm256_and_si256(_mm256_add_epi16(_mm256_mullo_epi16(_mm256_add_epi16(along[1], along[3]), three),
                                            _mm256_mullo_epi16(along[2], ten)),
                           in1);
  return d;
}

// The derivatives of chunk c of window row j (0 on rows outside the image).
LINNET_LK_AVX2_HELPER Derivatives16 windowRowDerivatives(const U8* img, std::ptrdiff_t img_step, int j, int c,
                                                         const WindowPlace& pl, __m256i in0, __m256i in1) {
  const int Y = pl.y + j;
  if (Y < 0 || Y >= pl.rows) {
    const __m256i z = _mm256_setzero_si256();
    return Derivatives16{z, z, z, z};
  }
  const U8* mid = img + j * img_step + c * kLanes;
  return scharr16(mid - img_step, mid, mid + img_step, in0, in1);
}

// Lanes k of 16 whose column x + k lies in [0, cols).
LINNET_LK_AVX2_HELPER __m256i columnsInside(int x, int cols) {
  const __m256i c = _mm256_add_epi16(_mm256_set1_epi16(static_cast<I16>(x)),
                                     _mm256_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15));
  return _mm256_and_si256(_mm256_cmpgt_epi16(c, _mm256_set1_epi16(-1)),
                          _mm256_cmpgt_epi16(_mm256_set1_epi16(static_cast<I16>(cols)), c));
}

// Sample k, then k + 4, of a block of 8 int16 (the low or high half of v) into the four float lanes of *q.
LINNET_LK_AVX2_HELPER void addSquares(__m128i u, __m128i v, __m128* q) {
  const __m256 fu = _mm256_cvtepi32_ps(_mm256_cvtepi16_epi32(u));
  const __m256 fv = _mm256_cvtepi32_ps(_mm256_cvtepi16_epi32(v));
  const __m256 p = _mm256_mul_ps(fu, fv);  // exact: |products| < 2^24
  *q = _mm_add_ps(_mm256_castps256_ps128(p), *q);
  *q = _mm_add_ps(_mm256_extractf128_ps(p, 1), *q);
}

// The rest of a row (the samples after its whole blocks of 8) lies in one group of 8 lanes; its products are summed
// sequentially in floats. When the magnitudes of all the values of a window's rests sum below 2^24, every partial sum
// of that sequence is an integer below 2^24, so each float addition is exact and the result is the integer sum:
// taken then from integer vectors without the chain of dependent float additions. Lane sums stay within int32 for
// windows of up to kExactRows rows (|value| < 2^25).
constexpr int kExactRows = 60;
constexpr std::int64_t kExactLimit = std::int64_t{1} << 24;

// Lanes j of a group of 8 with j < n set.
LINNET_LK_AVX2_HELPER __m256i firstLanes(int n) {
  return _mm256_cmpgt_epi32(_mm256_set1_epi32(n), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
}

LINNET_LK_AVX2_HELPER std::int64_t laneSum(__m256i v) {
  alignas(32) I32 l[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(l), v);
  std::int64_t s = 0;
  for (const I32 x : l) s += x;
  return s;
}

// The sequential float sum of the rests (rows of 8 stored values, the first n of each row), or its exact value.
float restSum(const I32* v, int rows, int n, std::int64_t exact, std::int64_t magnitude) {
  if (magnitude < kExactLimit && rows <= kExactRows) return static_cast<float>(exact);
  float s = 0.f;
  for (int y = 0; y < rows; ++y)
    for (int j = 0; j < n; ++j) s += static_cast<float>(v[8 * y + j]);
  return s;
}

__attribute__((target("avx2"))) GradientSums templateAvx2Impl(const U8* img, std::ptrdiff_t img_step,
                                                              WindowShape shape, WindowPlace pl, Weights w, I16* t,
                                                              I16* gx, I16* gy) {
  const __m256i wa = weightPair(w.w00, w.w01), wb = weightPair(w.w10, w.w11);
  __m128 q11 = _mm_setzero_ps(), q12 = _mm_setzero_ps(), q22 = _mm_setzero_ps();
  const int stride = shape.chunks * kLanes, blocks = shape.width / 8, rest = shape.width - 8 * blocks;
  const __m256i rest_mask = firstLanes(rest);
  __m256i e11 = _mm256_setzero_si256(), e12 = e11, e22 = e11, m12 = e11;  // the rests' sums, |a12|'s
  alignas(32) I32 p11[8 * kMaxStride], p12[8 * kMaxStride], p22[8 * kMaxStride];
  constexpr int kMaxChunks = kMaxStride / kLanes;
  __m256i in0[kMaxChunks], in1[kMaxChunks];
  Derivatives16 above[kMaxChunks];  // the derivatives of the window row being sampled; those of the next come below
  for (int c = 0; c < shape.chunks; ++c) {
    in0[c] = columnsInside(pl.x + c * kLanes, pl.cols);
    in1[c] = columnsInside(pl.x + c * kLanes + 1, pl.cols);
    above[c] = windowRowDerivatives(img, img_step, 0, c, pl, in0[c], in1[c]);
  }
  for (int y = 0; y < shape.rows; ++y) {
    const U8* r0 = img + y * img_step;
    I16* tr = t + y * stride;
    I16* xr = gx + y * stride;
    I16* yr = gy + y * stride;
    for (int c = 0; c < shape.chunks; ++c) {
      const int x0 = c * kLanes;
      const __m256i v = bilinear16(loadBytes16(r0 + x0), loadBytes16(r0 + x0 + 1), loadBytes16(r0 + img_step + x0),
                                   loadBytes16(r0 + img_step + x0 + 1), wa, wb, kSampleShift);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(tr + x0), v);
      const Derivatives16 a = above[c], b = windowRowDerivatives(img, img_step, y + 1, c, pl, in0[c], in1[c]);
      above[c] = b;
      const __m256i ex = bilinear16(a.dx, a.dx1, b.dx, b.dx1, wa, wb, kWeightBits);
      const __m256i ey = bilinear16(a.dy, a.dy1, b.dy, b.dy1, wa, wb, kWeightBits);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(xr + x0), ex);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(yr + x0), ey);
      for (int half = 0; half < 2; ++half) {
        if (2 * c + half >= blocks) break;
        const __m128i hx = half == 0 ? _mm256_castsi256_si128(ex) : _mm256_extracti128_si256(ex, 1);
        const __m128i hy = half == 0 ? _mm256_castsi256_si128(ey) : _mm256_extracti128_si256(ey, 1);
        addSquares(hy, hy, &q22);
        addSquares(hx, hy, &q12);
        addSquares(hx, hx, &q11);
      }
      if (rest > 0 && blocks / 2 == c) {
        const bool high = blocks % 2 == 1;
        const __m256i ix = _mm256_cvtepi16_epi32(high ? _mm256_extracti128_si256(ex, 1) : _mm256_castsi256_si128(ex));
        const __m256i iy = _mm256_cvtepi16_epi32(high ? _mm256_extracti128_si256(ey, 1) : _mm256_castsi256_si128(ey));
        const __m256i a = _mm256_and_si256(_mm256_mullo_epi32(ix, ix), rest_mask);
        const __m256i b = _mm256_and_si256(_mm256_mullo_epi32(ix, iy), rest_mask);
        const __m256i e = _mm256_and_si256(_mm256_mullo_epi32(iy, iy), rest_mask);
        _mm256_store_si256(reinterpret_cast<__m256i*>(p11 + 8 * y), a);
        _mm256_store_si256(reinterpret_cast<__m256i*>(p12 + 8 * y), b);
        _mm256_store_si256(reinterpret_cast<__m256i*>(p22 + 8 * y), e);
        e11 = _mm256_add_epi32(e11, a);
        e12 = _mm256_add_epi32(e12, b);
        e22 = _mm256_add_epi32(e22, e);
        m12 = _mm256_add_epi32(m12, _mm256_abs_epi32(b));
      }
    }
  }
  alignas(16) float a11[4], a12[4], a22[4];
  _mm_store_ps(a11, q11);
  _mm_store_ps(a12, q12);
  _mm_store_ps(a22, q22);
  const std::int64_t x11 = laneSum(e11), x22 = laneSum(e22);
  return finishGradient(a11, a12, a22, restSum(p11, shape.rows, rest, x11, x11),
                        restSum(p12, shape.rows, rest, laneSum(e12), laneSum(m12)),
                        restSum(p22, shape.rows, rest, x22, x22));
}

__attribute__((target("avx2"))) void residualAvx2Impl(const U8* img, std::ptrdiff_t img_step, WindowShape shape,
                                                      Weights w, const I16* t, const I16* gx, const I16* gy, float* b1,
                                                      float* b2) {
  const __m256i wa = weightPair(w.w00, w.w01), wb = weightPair(w.w10, w.w11);
  __m256 q = _mm256_setzero_ps();
  const int stride = shape.chunks * kLanes, blocks = shape.width / 8, rest = shape.width - 8 * blocks;
  const __m256i rest_mask = firstLanes(rest);
  __m256i ex1 = _mm256_setzero_si256(), ex2 = ex1, mx1 = ex1, mx2 = ex1;  // the rests' sums and magnitudes
  alignas(32) I32 rx[8 * kMaxStride], ry[8 * kMaxStride];
  for (int y = 0; y < shape.rows; ++y) {
    const U8* r0 = img + y * img_step;
    const int o = y * stride;
    for (int c = 0; c < shape.chunks; ++c) {
      const int x0 = c * kLanes;
      const __m256i v = bilinear16(loadBytes16(r0 + x0), loadBytes16(r0 + x0 + 1), loadBytes16(r0 + img_step + x0),
                                   loadBytes16(r0 + img_step + x0 + 1), wa, wb, kSampleShift);
      const __m256i r = _mm256_sub_epi16(v, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(t + o + x0)));
      const __m256i ex = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(gx + o + x0));
      const __m256i ey = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(gy + o + x0));
      const __m256i xl = _mm256_mullo_epi16(r, ex), xh = _mm256_mulhi_epi16(r, ex);
      const __m256i yl = _mm256_mullo_epi16(r, ey), yh = _mm256_mulhi_epi16(r, ey);
      // int32 products: lanes 0-3 | 8-11 and 4-7 | 12-15.
      const __m256i x_lo = _mm256_unpacklo_epi16(xl, xh), x_hi = _mm256_unpackhi_epi16(xl, xh);
      const __m256i y_lo = _mm256_unpacklo_epi16(yl, yh), y_hi = _mm256_unpackhi_epi16(yl, yh);
      // Pair sums (k, k + 4) of the blocks 2c | 2c + 1, interleaved x, y: pairs 0-1 in pl, 2-3 in ph.
      const __m256i px = _mm256_add_epi32(x_lo, x_hi), py = _mm256_add_epi32(y_lo, y_hi);
      const __m256i pl = _mm256_unpacklo_epi32(px, py), ph = _mm256_unpackhi_epi32(px, py);
      if (2 * c < blocks) q = _mm256_add_ps(q, _mm256_cvtepi32_ps(_mm256_permute2x128_si256(pl, ph, 0x20)));
      if (2 * c + 1 < blocks) q = _mm256_add_ps(q, _mm256_cvtepi32_ps(_mm256_permute2x128_si256(pl, ph, 0x31)));
      if (rest > 0 && blocks / 2 == c) {
        const int sel = blocks % 2 == 1 ? 0x31 : 0x20;  // the rest's group of 8 in natural order
        const __m256i gx8 = _mm256_and_si256(
            sel == 0x31 ? _mm256_permute2x128_si256(x_lo, x_hi, 0x31) : _mm256_permute2x128_si256(x_lo, x_hi, 0x20),
            rest_mask);
        const __m256i gy8 = _mm256_and_si256(
            sel == 0x31 ? _mm256_permute2x128_si256(y_lo, y_hi, 0x31) : _mm256_permute2x128_si256(y_lo, y_hi, 0x20),
            rest_mask);
        _mm256_store_si256(reinterpret_cast<__m256i*>(rx + 8 * y), gx8);
        _mm256_store_si256(reinterpret_cast<__m256i*>(ry + 8 * y), gy8);
        ex1 = _mm256_add_epi32(ex1, gx8);
        ex2 = _mm256_add_epi32(ex2, gy8);
        mx1 = _mm256_add_epi32(mx1, _mm256_abs_epi32(gx8));
        mx2 = _mm256_add_epi32(mx2, _mm256_abs_epi32(gy8));
      }
    }
  }
  alignas(32) float lanes[8];
  _mm256_store_ps(lanes, q);
  finishResidual(lanes, restSum(rx, shape.rows, rest, laneSum(ex1), laneSum(mx1)),
                 restSum(ry, shape.rows, rest, laneSum(ex2), laneSum(mx2)), b1, b2);
}

}  // namespace

TemplateKernel templateAvx2() { return __builtin_cpu_supports("avx2") ? &templateAvx2Impl : nullptr; }
ResidualKernel residualAvx2() { return __builtin_cpu_supports("avx2") ? &residualAvx2Impl : nullptr; }

#else

TemplateKernel templateAvx2() { return nullptr; }
ResidualKernel residualAvx2() { return nullptr; }

#endif

}  // namespace linnet::lk
