// Image pyramids for KLT (see image_pyramid.h).
#include "linnet/features/image_pyramid.h"

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/core/error.h"
#include "linnet/core/simd_clones.h"

namespace linnet {

namespace {

using U8 = std::uint8_t;
using U16 = std::uint16_t;

// The binomial kernel down five source rows: v[x] = r0 + 4 r1 + 6 r2 + 4 r3 + r4 (at most 16 x 255).
LINNET_SIMD_CLONES void columnSums(const U8* __restrict r0, const U8* __restrict r1, const U8* __restrict r2,
                                   const U8* __restrict r3, const U8* __restrict r4, int n, U16* __restrict v) {
  for (int x = 0; x < n; ++x)
    v[x] = static_cast<U16>(r0[x] + r4[x] + 4 * (r1[x] + r3[x]) + 6 * r2[x]);
}

// The kernel along the row of column sums, every other column: out[x] = (v[2x] + 4 v[2x + 1] + 6 v[2x + 2] +
// 4 v[2x + 3] + v[2x + 4] + 128) >> 8, v starting two columns left of the row (at most 65280 + 128: 16 bits).
LINNET_SIMD_CLONES void rowSums(const U16* __restrict v, int n, U8* __restrict out) {
  for (int x = 0; x < n; ++x) {
    const U16* p = v + 2 * x;
    out[x] = static_cast<U8>((p[0] + p[4] + 4 * (p[1] + p[3]) + 6 * p[2] + 128) >> 8);
  }
}

void checkGrey(const cv::Mat& m, const char* what) {
  if (m.type() != CV_8UC1 || m.empty())
    throw UsageError(std::string(what) + ": the image must be 8-bit grey and not empty");
}

}  // namespace

void pyramidDown(const cv::Mat& src, cv::Mat& dst) {
  checkGrey(src, "pyramidDown");
  const int w = src.cols, h = src.rows, dw = (w + 1) / 2, dh = (h + 1) / 2;
  dst.create(dh, dw, CV_8UC1);
  // Column sums with two reflected columns on each side; the rows reflected at the borders.
  std::vector<U16> v(static_cast<std::size_t>(w) + 4);
  const auto row = [&](int y) { return src.ptr<U8>(cv::borderInterpolate(y, h, cv::BORDER_REFLECT_101)); };
  const int cols[4] = {cv::borderInterpolate(-2, w, cv::BORDER_REFLECT_101),
                       cv::borderInterpolate(-1, w, cv::BORDER_REFLECT_101),
                       cv::borderInterpolate(w, w, cv::BORDER_REFLECT_101),
                       cv::borderInterpolate(w + 1, w, cv::BORDER_REFLECT_101)};
  for (int y = 0; y < dh; ++y) {
    const U8* r[5] = {row(2 * y - 2), row(2 * y - 1), row(2 * y), row(2 * y + 1), row(2 * y + 2)};
    U16* in = v.data() + 2;
    columnSums(r[0], r[1], r[2], r[3], r[4], w, in);
    in[-2] = in[cols[0]];
    in[-1] = in[cols[1]];
    in[w] = in[cols[2]];
    in[w + 1] = in[cols[3]];
    rowSums(v.data(), dw, dst.ptr<U8>(y));
  }
}

int buildPyramid(const cv::Mat& img, cv::Size window, int max_level, std::vector<cv::Mat>* pyramid) {
  checkGrey(img, "buildPyramid");
  if (window.width <= 2 || window.height <= 2 || max_level < 0)
    throw UsageError("buildPyramid: the window's sides must exceed 2 pixels and max_level must not be negative");
  pyramid->resize(static_cast<std::size_t>(max_level) + 1);
  const int bw = window.width, bh = window.height;
  // A level's padded buffer, reused when its size fits; returns the view of the level itself.
  const auto level = [&](int l, cv::Size sz) -> cv::Mat& {
    cv::Mat& m = (*pyramid)[static_cast<std::size_t>(l)];
    if (!m.empty()) m.adjustROI(bh, bh, bw, bw);
    if (m.type() != CV_8UC1 || m.cols != sz.width + 2 * bw || m.rows != sz.height + 2 * bh)
      m.create(sz.height + 2 * bh, sz.width + 2 * bw, CV_8UC1);
    return m;
  };
  cv::Size sz = img.size();
  cv::Mat& base = level(0, sz);
  cv::copyMakeBorder(img, base, bh, bh, bw, bw, cv::BORDER_REFLECT_101);
  base.adjustROI(-bh, -bh, -bw, -bw);
  cv::Mat prev = base;
  for (int l = 0; l <= max_level; ++l) {
    if (l != 0) {
      cv::Mat& padded = level(l, sz);
      cv::Mat view = padded(cv::Rect(bw, bh, sz.width, sz.height));
      pyramidDown(prev, view);
      cv::copyMakeBorder(view, padded, bh, bh, bw, bw, cv::BORDER_REFLECT_101 | cv::BORDER_ISOLATED);
      padded.adjustROI(-bh, -bh, -bw, -bw);
      prev = padded;
    }
    sz = cv::Size((sz.width + 1) / 2, (sz.height + 1) / 2);
    if (sz.width <= bw || sz.height <= bh) {
      pyramid->resize(static_cast<std::size_t>(l) + 1);
      return l;
    }
  }
  return max_level;
}

PyramidLayout pyramidLayout(const std::vector<cv::Mat>& pyramid) {
  PyramidLayout l;
  l.levels = static_cast<int>(pyramid.size());
  if (l.levels % 2 == 0 && l.levels > 0 && pyramid[1].type() == CV_16SC2 && pyramid[0].channels() == 1) {
    l.step = 2;
    l.levels /= 2;
  }
  return l;
}

const cv::Mat& pyramidLevel(const std::vector<cv::Mat>& pyramid, int level) {
  const PyramidLayout l = pyramidLayout(pyramid);
  if (l.levels == 0) throw UsageError("pyramidLevel: the pyramid is empty");
  return pyramid[static_cast<std::size_t>(std::clamp(level, 0, l.levels - 1) * l.step)];
}

}  // namespace linnet
