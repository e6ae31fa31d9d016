// Binary LBD descriptor (see line_lbd.h).
#include "linnet/features/line_lbd.h"

#include <algorithm>
#include <cmath>
#include <utility>

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

}  // namespace

std::array<float, kLbdFloats> computeLbdFloat(const cv::Mat& gray, const LbdOptions& options, const LineSegment& seg) {
  static_assert(kRows == 63);
  static const Weights kWeights;  // immutable tables, built once (not mutable state)
  std::array<float, kLbdFloats> out{};
  const double len = seg.length();
  if (!(len > 1.0) || gray.cols < 3 || gray.rows < 3) return out;
  const Vec2 d = seg.direction();
  const Vec2 n(-d.y(), d.x());
  const int ns = std::clamp(static_cast<int>(len), 2, options.max_samples);
  const float step = static_cast<float>(len / ns);
  const float dx = static_cast<float>(d.x()), dy = static_cast<float>(d.y());
  const float nx = static_cast<float>(n.x()), ny = static_cast<float>(n.y());
  const std::size_t stride = gray.step[0];
  // 1. Resample the support region into a rectified patch by nearest neighbour: patch row q (0..kRows+1) lies at
  //    offset q - kHalf - 1 along n, patch column c (0..ns+1) at (c - 0.5) * step along d from s. The walk is in
  //    16.16 fixed point; rows leaving the image are clamped to the border.
  // 2. Gradients in the patch frame are the projections LBD needs: g_perp = P(q+1, c) - P(q-1, c) (along n),
  //    g_L = (P(q, c+1) - P(q, c-1)) / step (along d); rows sum them split by sign (branch-free, vectorisable).
  constexpr int kPatchRows = kRows + 2;
  const int cols = ns + 2;
  std::uint8_t patch[kPatchRows][1024 + 2];
  const int max_xi = gray.cols - 1, max_yi = gray.rows - 1;
  const std::ptrdiff_t sstride = static_cast<std::ptrdiff_t>(stride);
  const float sx = step * dx, sy = step * dy;
  for (int q = 0; q < kPatchRows; ++q) {
    const float off = static_cast<float>(q - kHalf - 1);
    const float bx = static_cast<float>(seg.s.x()) + off * nx - 0.5f * sx;
    const float by = static_cast<float>(seg.s.y()) + off * ny - 0.5f * sy;
    const float ex = bx + static_cast<float>(cols - 1) * sx, ey = by + static_cast<float>(cols - 1) * sy;
    const bool inside = std::min(bx, ex) >= 0.f && std::min(by, ey) >= 0.f &&
                        std::max(bx, ex) <= static_cast<float>(max_xi) && std::max(by, ey) <= static_cast<float>(max_yi);
    std::uint8_t* row = patch[q];
    if (inside) {
      std::int32_t fx = static_cast<std::int32_t>((bx + 0.5f) * 65536.f);
      std::int32_t fy = static_cast<std::int32_t>((by + 0.5f) * 65536.f);
      const std::int32_t fsx = static_cast<std::int32_t>(sx * 65536.f), fsy = static_cast<std::int32_t>(sy * 65536.f);
      for (int c = 0; c < cols; ++c, fx += fsx, fy += fsy)
        row[c] = gray.data[static_cast<std::ptrdiff_t>(fy >> 16) * sstride + (fx >> 16)];
    } else {
      for (int c = 0; c < cols; ++c) {
        const int xi = std::clamp(static_cast<int>(std::floor(bx + static_cast<float>(c) * sx + 0.5f)), 0, max_xi);
        const int yi = std::clamp(static_cast<int>(std::floor(by + static_cast<float>(c) * sy + 0.5f)), 0, max_yi);
        row[c] = gray.data[static_cast<std::ptrdiff_t>(yi) * sstride + xi];
      }
    }
  }
  // Row sums: (g_perp > 0, -g_perp < 0, g_L > 0, -g_L < 0), each a mean over the row's samples, times the global weight.
  std::array<std::array<float, 4>, kRows> rows{};
  const float inv_step = 1.f / step;
  for (int r = 0; r < kRows; ++r) {
    const std::uint8_t* up = patch[r];
    const std::uint8_t* mid = patch[r + 1];
    const std::uint8_t* down = patch[r + 2];
    std::int32_t b0 = 0, b1 = 0, b2 = 0, b3 = 0;
    for (int c = 1; c <= ns; ++c) {
      const std::int32_t gp = static_cast<std::int32_t>(down[c]) - static_cast<std::int32_t>(up[c]);
      const std::int32_t gl = static_cast<std::int32_t>(mid[c + 1]) - static_cast<std::int32_t>(mid[c - 1]);
      b0 += std::max(gp, 0);
      b1 += std::max(-gp, 0);
      b2 += std::max(gl, 0);
      b3 += std::max(-gl, 0);
    }
    const float w = kWeights.global[r] / static_cast<float>(ns);
    rows[r] = {static_cast<float>(b0) * w, static_cast<float>(b1) * w, static_cast<float>(b2) * w * inv_step,
               static_cast<float>(b3) * w * inv_step};
  }
  // Band descriptors: weighted mean and standard deviation over the rows of bands j-1..j+1.
  for (int j = 0; j < kLbdBands; ++j) {
    const int r0 = std::max(0, (j - 1) * kLbdBandWidth), r1 = std::min(kRows, (j + 2) * kLbdBandWidth);
    float mean[4] = {0, 0, 0, 0}, sq[4] = {0, 0, 0, 0};
    const int cnt = r1 - r0;
    for (int r = r0; r < r1; ++r) {
      const float wl = kWeights.local[j][r];
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
