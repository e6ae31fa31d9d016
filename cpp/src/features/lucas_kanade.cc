// Pyramidal Lucas-Kanade point tracking (see lucas_kanade.h).
//
// Per level and point: the window around the point in the previous image is sampled once (its values and its
// derivatives, bilinear with fixed-point weights) and its gradient matrix A summed; each iteration samples the next
// image at the current estimate, sums the residual times the derivatives (b) and steps by -A^-1 b. The window kernels
// (lucas_kanade_kernels.h) do the sampling and the sums, in AVX2 where the CPU has it.
#include "linnet/features/lucas_kanade.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdint>
#include <sstream>

#include "linnet/core/error.h"
#include "linnet/features/image_pyramid.h"
#include "linnet/features/lucas_kanade_kernels.h"

namespace linnet {

namespace {

using I16 = std::int16_t;
using U8 = std::uint8_t;

constexpr float kSumScale = 1.f / (1 << 20);  // scale of the kernels' float sums of products

lk::Weights bilinear(float a, float b) {
  lk::Weights w;
  w.w00 = cvRound((1.f - a) * (1.f - b) * (1 << lk::kWeightBits));
  w.w01 = cvRound(a * (1.f - b) * (1 << lk::kWeightBits));
  w.w10 = cvRound((1.f - a) * b * (1 << lk::kWeightBits));
  w.w11 = (1 << lk::kWeightBits) - w.w00 - w.w01 - w.w10;
  return w;
}

// The window may reach `border` samples beyond every side of the level image: the pyramid must hold them.
void checkLevel(const cv::Mat& m, int type, cv::Size border, const char* which) {
  cv::Size whole;
  cv::Point ofs;
  m.locateROI(whole, ofs);
  if (m.type() != type || ofs.x < border.width || ofs.y < border.height ||
      ofs.x + m.cols + border.width > whole.width || ofs.y + m.rows + border.height > whole.height) {
    std::ostringstream os;
    os << "lucasKanade: the " << which << " pyramid must come from cv::buildOpticalFlowPyramid (8-bit grey) with a "
       << "window of at least " << border.width << " x " << border.height;
    throw UsageError(os.str());
  }
}

// Byte offset of element (x, y) of m (relative to its ROI; negative and beyond its size in the padding) from the
// start of m's allocation.
std::ptrdiff_t offsetOf(const cv::Mat& m, int x, int y) {
  return (m.data - m.datastart) + static_cast<std::ptrdiff_t>(y) * static_cast<std::ptrdiff_t>(m.step[0]) +
         static_cast<std::ptrdiff_t>(x) * static_cast<std::ptrdiff_t>(m.elemSize());
}

// Element (x, y) of an 8-bit m, anywhere in its padded allocation.
const U8* pixelAt(const cv::Mat& m, int x, int y) { return m.datastart + offsetOf(m, x, y); }

// True when elements (x0, y0) to (x1, y1) of m and every byte between them lie inside m's allocation.
bool readable(const cv::Mat& m, int x0, int y0, int x1, int y1) {
  return offsetOf(m, x0, y0) >= 0 && offsetOf(m, x1 + 1, y1) <= m.datalimit - m.datastart;
}

struct Buffers {
  lk::TemplateKernel sample_template = &lk::templatePlain;
  lk::ResidualKernel residual = &lk::residualPlain;
  lk::WindowShape shape;
  std::vector<I16> t, gx, gy;  // the template
  std::vector<U8> img;         // a copied image window, when reading it in place could pass the allocation
};

// What a window kernel may read around pixel (x, y) of m, rows y - 1 .. y + rows + 1 and pixels x - 1 .. x + len + 1,
// copied into *buf with every position clamped into m's padded allocation, for a window near its end. The window's
// own pixels (rows and `width` + 1 pixels from (x, y)) lie in the padding; the clamped ones only feed derivatives
// outside the image (0) or samples past the window's width (not summed). Returns the copy's pixel (x, y), rows
// len + 3 apart.
const U8* copyClamped(const cv::Mat& m, int x, int y, int rows, int len, std::vector<U8>* buf) {
  cv::Size whole;
  cv::Point ofs;
  m.locateROI(whole, ofs);
  const int row_len = len + 3;
  buf->resize(static_cast<std::size_t>(row_len) * static_cast<std::size_t>(rows + 3));
  for (int r = 0; r < rows + 3; ++r) {
    const int yy = std::clamp(y - 1 + r, -ofs.y, whole.height - ofs.y - 1);
    const U8* src = pixelAt(m, 0, yy);
    U8* dst = buf->data() + static_cast<std::size_t>(r) * static_cast<std::size_t>(row_len);
    for (int i = 0; i < row_len; ++i) dst[i] = src[std::clamp(x - 1 + i, -ofs.x, whole.width - ofs.x - 1)];
  }
  return buf->data() + row_len + 1;
}

struct Level {
  const cv::Mat* I;  // previous image
  const cv::Mat* J;  // next image
};

// One level of one point. prev_pt and *next_stored are in the level's pixels; *next_stored is the point's stored
// result (the window's centre). Returns false when the point is lost at this level.
bool trackLevel(const Level& lv, const LucasKanadeParams& p, int max_count, double eps2, float min_eig,
                cv::Point2f prev_pt, cv::Point2f* next_stored, Buffers* buf) {
  const cv::Size win = p.window;
  const cv::Point2f half((win.width - 1) * 0.5f, (win.height - 1) * 0.5f);
  const cv::Mat& I = *lv.I;
  const cv::Mat& J = *lv.J;
  prev_pt -= half;
  const cv::Point ip(cvFloor(prev_pt.x), cvFloor(prev_pt.y));
  if (ip.x < -win.width || ip.x >= I.cols || ip.y < -win.height || ip.y >= I.rows) return false;

  const int stride = buf->shape.chunks * lk::kLanes;
  const U8* img = pixelAt(I, ip.x, ip.y);
  std::ptrdiff_t img_step = static_cast<std::ptrdiff_t>(I.step[0]);
  if (!readable(I, ip.x - 1, ip.y - 1, ip.x + stride + 1, ip.y + win.height + 1)) {
    img = copyClamped(I, ip.x, ip.y, win.height, stride, &buf->img);
    img_step = stride + 3;
  }
  lk::WindowPlace place;
  place.x = ip.x;
  place.y = ip.y;
  place.cols = I.cols;
  place.rows = I.rows;
  lk::GradientSums g = buf->sample_template(img, img_step, buf->shape, place,
                                            bilinear(prev_pt.x - ip.x, prev_pt.y - ip.y), buf->t.data(),
                                            buf->gx.data(), buf->gy.data());
  g.a11 *= kSumScale;
  g.a12 *= kSumScale;
  g.a22 *= kSumScale;

  float det = g.a11 * g.a22 - g.a12 * g.a12;
  const float min_eigen = (g.a22 + g.a11 - std::sqrt((g.a11 - g.a22) * (g.a11 - g.a22) + 4.f * g.a12 * g.a12)) /
                          static_cast<float>(2 * win.width * win.height);
  if (min_eigen < min_eig || det < FLT_EPSILON) return false;
  det = 1.f / det;

  cv::Point2f next_pt = *next_stored - half;
  cv::Point2f prev_delta;
  for (int j = 0; j < max_count; ++j) {
    const cv::Point in(cvFloor(next_pt.x), cvFloor(next_pt.y));
    if (in.x < -win.width || in.x >= J.cols || in.y < -win.height || in.y >= J.rows) return false;
    const U8* next = pixelAt(J, in.x, in.y);
    std::ptrdiff_t next_step = static_cast<std::ptrdiff_t>(J.step[0]);
    if (!readable(J, in.x, in.y, in.x + stride, in.y + win.height)) {
      next = copyClamped(J, in.x, in.y, win.height, stride, &buf->img);
      next_step = stride + 3;
    }
    float b1 = 0.f, b2 = 0.f;
    buf->residual(next, next_step, buf->shape, bilinear(next_pt.x - in.x, next_pt.y - in.y), buf->t.data(),
                  buf->gx.data(), buf->gy.data(), &b1, &b2);
    b1 *= kSumScale;
    b2 *= kSumScale;
    const cv::Point2f delta((g.a12 * b2 - g.a22 * b1) * det, (g.a12 * b1 - g.a11 * b2) * det);
    next_pt += delta;
    *next_stored = next_pt + half;
    if (delta.ddot(delta) <= eps2) break;
    if (j > 0 && std::abs(delta.x + prev_delta.x) < 0.01 && std::abs(delta.y + prev_delta.y) < 0.01) {
      *next_stored -= delta * 0.5f;
      break;
    }
    prev_delta = delta;
  }
  return true;
}

}  // namespace

void lucasKanade(const std::vector<cv::Mat>& prev, const std::vector<cv::Mat>& next,
                 const std::vector<cv::Point2f>& from, std::vector<cv::Point2f>* to,
                 std::vector<unsigned char>* status, const LucasKanadeParams& p) {
  if (p.window.width <= 2 || p.window.height <= 2 || p.window.width >= lk::kMaxStride ||
      p.window.height >= lk::kMaxStride || p.max_level < 0) {
    std::ostringstream os;
    os << "lucasKanade: the window's sides must be 3 to " << lk::kMaxStride - 1 << " pixels (got " << p.window.width
       << " x " << p.window.height << ") and max_level must not be negative (got " << p.max_level << ")";
    throw UsageError(os.str());
  }
  if (to->size() != from.size()) throw UsageError("lucasKanade: *to must hold one initial position per point");
  status->assign(from.size(), 1);
  if (from.empty()) return;
  if (prev.empty() || next.empty()) throw UsageError("lucasKanade: a pyramid is empty");
  const PyramidLayout lp = pyramidLayout(prev), ln = pyramidLayout(next);
  const int max_level = std::min({p.max_level, lp.levels - 1, ln.levels - 1});
  std::vector<Level> levels(static_cast<std::size_t>(max_level) + 1);
  for (int l = 0; l <= max_level; ++l) {
    Level& lv = levels[static_cast<std::size_t>(l)];
    lv.I = &prev[static_cast<std::size_t>(l * lp.step)];
    lv.J = &next[static_cast<std::size_t>(l * ln.step)];
    checkLevel(*lv.I, CV_8UC1, p.window, "previous");
    checkLevel(*lv.J, CV_8UC1, p.window, "next");
    if (lv.I->size() != lv.J->size()) throw UsageError("lucasKanade: the two pyramids' levels differ in size");
  }
  const int max_count = std::min(std::max(p.max_iterations, 0), 100);
  const double eps = std::min(std::max(p.epsilon, 0.0), 10.0);
  const float min_eig = static_cast<float>(p.min_eigen);

  Buffers buf;
  if (const lk::TemplateKernel k = lk::templateAvx2(); k != nullptr && p.simd) buf.sample_template = k;
  if (const lk::ResidualKernel k = lk::residualAvx2(); k != nullptr && p.simd) buf.residual = k;
  buf.shape.rows = p.window.height;
  buf.shape.width = p.window.width;
  buf.shape.chunks = (p.window.width + lk::kLanes - 1) / lk::kLanes;
  const std::size_t cells =
      static_cast<std::size_t>(buf.shape.chunks * lk::kLanes) * static_cast<std::size_t>(p.window.height);
  buf.t.resize(cells);
  buf.gx.resize(cells);
  buf.gy.resize(cells);
  for (std::size_t i = 0; i < from.size(); ++i) {
    cv::Point2f stored = (*to)[i];
    for (int l = max_level; l >= 0; --l) {
      const float scale = static_cast<float>(1.0 / (1 << l));
      stored = l == max_level ? stored * scale : stored * 2.f;
      const bool ok = trackLevel(levels[static_cast<std::size_t>(l)], p, max_count, eps * eps, min_eig,
                                 from[i] * scale, &stored, &buf);
      if (!ok && l == 0) (*status)[i] = 0;
    }
    (*to)[i] = stored;
  }
}

}  // namespace linnet
