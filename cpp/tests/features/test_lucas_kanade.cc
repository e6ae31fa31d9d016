// lucasKanade against cv::calcOpticalFlowPyrLK, the plain version it replaces: the same results bit for bit.
#include <gtest/gtest.h>

#include <cstring>

#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "linnet/core/error.h"
#include "linnet/features/lucas_kanade.h"
#include "linnet/features/lucas_kanade_kernels.h"

namespace linnet {
namespace {

// A textured image and a second one moved by a smooth warp with a little noise, so that KLT iterates.
void imagePair(int seed, cv::Mat* a, cv::Mat* b) {
  cv::RNG rng(static_cast<std::uint64_t>(seed));
  cv::Mat f(360, 480, CV_32F), coarse(45, 60, CV_32F);
  rng.fill(f, cv::RNG::UNIFORM, 0.0, 255.0);
  rng.fill(coarse, cv::RNG::UNIFORM, 0.0, 255.0);
  cv::GaussianBlur(f, f, cv::Size(0, 0), 1.2);
  cv::resize(coarse, coarse, f.size(), 0, 0, cv::INTER_CUBIC);
  cv::Mat m = 0.5 * f + 0.5 * coarse;
  cv::normalize(m, m, 0, 255, cv::NORM_MINMAX);
  m.convertTo(*a, CV_8U);
  cv::Mat mx(m.size(), CV_32F), my(m.size(), CV_32F);
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x) {
      mx.at<float>(y, x) = static_cast<float>(x + 3.3 + 2.0 * std::sin(y * 0.01) + 0.004 * (y - 180));
      my.at<float>(y, x) = static_cast<float>(y - 1.7 + 1.5 * std::cos(x * 0.013));
    }
  cv::Mat warped, noise(m.size(), CV_32F);
  cv::remap(m, warped, mx, my, cv::INTER_LINEAR, cv::BORDER_REFLECT_101);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 2.0);
  cv::Mat out = warped + noise;
  out.convertTo(*b, CV_8U);
}

std::vector<cv::Point2f> points(int seed, const cv::Size& size) {
  cv::RNG rng(static_cast<std::uint64_t>(seed) + 100);
  std::vector<cv::Point2f> p;
  for (int i = 0; i < 400; ++i)
    p.emplace_back(rng.uniform(0.f, static_cast<float>(size.width)), rng.uniform(0.f, static_cast<float>(size.height)));
  // At and beyond the borders and the corners: the windows that reach past the pyramid's padding, lost points.
  const float w = static_cast<float>(size.width), h = static_cast<float>(size.height);
  for (const cv::Point2f& q : {cv::Point2f(0.f, 0.f), cv::Point2f(w - 1.f, h - 1.f), cv::Point2f(w - 0.3f, h - 0.6f),
                               cv::Point2f(w - 1.f, 0.5f), cv::Point2f(0.2f, h - 1.f), cv::Point2f(-3.f, 10.f),
                               cv::Point2f(w + 9.f, h + 9.f), cv::Point2f(w * 0.5f, h - 2.f)})
    p.push_back(q);
  // Windows in the bottom-right padding, whose rows end at the pyramid's last bytes (read from a copy).
  for (float d = 4.f; d < 8.f; d += 0.75f) {
    p.emplace_back(w + d, h + d);
    p.emplace_back(w - 5.f, h + d);
    p.emplace_back(w + d, h - 30.f);
    p.emplace_back(-d, -d);  // top-left: the derivatives' row and pixel before the padding
    p.emplace_back(-d, 50.f);
    p.emplace_back(60.f, -d);
  }
  return p;
}

bool sameBits(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }

void expectSameAsOpenCv(int seed, int window, int levels, int iterations, double eps, bool initial_offset,
                        bool derivatives = true, bool simd = true) {
  cv::Mat a, b;
  imagePair(seed, &a, &b);
  const cv::Size win(window, window);
  std::vector<cv::Mat> pa, pb;
  cv::buildOpticalFlowPyramid(a, pa, win, levels, derivatives, cv::BORDER_REFLECT_101, cv::BORDER_CONSTANT, false);
  cv::buildOpticalFlowPyramid(b, pb, win, levels, derivatives, cv::BORDER_REFLECT_101, cv::BORDER_CONSTANT, false);
  const std::vector<cv::Point2f> from = points(seed, a.size());
  std::vector<cv::Point2f> start = from;
  if (initial_offset)
    for (cv::Point2f& q : start) q += cv::Point2f(3.0f, -1.5f);
  std::vector<cv::Point2f> ref = start, ours = start;
  std::vector<unsigned char> st_ref, st_ours;
  const cv::TermCriteria crit(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, iterations, eps);
  cv::calcOpticalFlowPyrLK(pa, pb, from, ref, st_ref, cv::noArray(), win, levels, crit, cv::OPTFLOW_USE_INITIAL_FLOW,
                           1e-4);
  LucasKanadeParams p;
  p.window = win;
  p.max_level = levels;
  p.max_iterations = iterations;
  p.epsilon = eps;
  p.min_eigen = 1e-4;
  p.simd = simd;
  lucasKanade(pa, pb, from, &ours, &st_ours, p);
  ASSERT_EQ(ours.size(), ref.size());
  int tracked = 0;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    ASSERT_EQ(st_ours[i], st_ref[i]) << "point " << i << " at " << from[i];
    tracked += st_ref[i] ? 1 : 0;
    EXPECT_TRUE(sameBits(ours[i].x, ref[i].x) && sameBits(ours[i].y, ref[i].y))
        << "point " << i << " at " << from[i] << ": " << ours[i] << " against OpenCV's " << ref[i];
  }
  EXPECT_GT(tracked, static_cast<int>(ref.size()) / 2);
}

TEST(LucasKanade, EqualsOpenCvBitForBitWithTheDefaultWindow) {
  for (int seed = 0; seed < 3; ++seed) expectSameAsOpenCv(seed, 15, 3, 30, 0.01, seed == 1);
}

// lucasKanade computes the derivatives itself: pyramids without them give the same results.
TEST(LucasKanade, EqualsOpenCvBitForBitOnPyramidsWithoutDerivatives) {
  expectSameAsOpenCv(10, 15, 3, 30, 0.01, true, false);
  expectSameAsOpenCv(11, 21, 2, 30, 0.01, false, false);
}

// The plain kernels (what a CPU without AVX2 runs) end to end.
TEST(LucasKanade, PlainKernelsEqualOpenCvBitForBit) {
  expectSameAsOpenCv(12, 15, 3, 30, 0.01, true, false, false);
  expectSameAsOpenCv(13, 11, 2, 30, 0.01, false, true, false);
}

TEST(LucasKanade, EqualsOpenCvBitForBitWithOtherWindowsAndLevels) {
  expectSameAsOpenCv(4, 11, 2, 30, 0.01, true);
  expectSameAsOpenCv(5, 21, 3, 30, 0.01, false);
  expectSameAsOpenCv(6, 7, 1, 10, 0.03, true);
  expectSameAsOpenCv(7, 16, 0, 30, 0.01, false);
  expectSameAsOpenCv(8, 33, 4, 50, 0.001, true);
}

TEST(LucasKanade, RejectsPyramidsItCannotRead) {
  cv::Mat a, b;
  imagePair(9, &a, &b);
  std::vector<cv::Mat> pyr, colour, empty;
  cv::buildOpticalFlowPyramid(a, pyr, cv::Size(15, 15), 2, false);
  cv::Mat bgr;
  cv::cvtColor(b, bgr, cv::COLOR_GRAY2BGR);
  cv::buildOpticalFlowPyramid(bgr, colour, cv::Size(15, 15), 2, false);
  std::vector<cv::Point2f> from{cv::Point2f(100.f, 100.f)}, to = from;
  std::vector<unsigned char> st;
  LucasKanadeParams p;
  EXPECT_THROW(lucasKanade(pyr, colour, from, &to, &st, p), UsageError);
  EXPECT_THROW(lucasKanade(empty, pyr, from, &to, &st, p), UsageError);
  p.window = cv::Size(31, 31);  // more than the pyramids' padding of 15
  EXPECT_THROW(lucasKanade(pyr, pyr, from, &to, &st, p), UsageError);
  p.window = cv::Size(15, 15);
  to.clear();
  EXPECT_THROW(lucasKanade(pyr, pyr, from, &to, &st, p), UsageError);
}

// The AVX2 kernels against the plain ones on random windows: the same template, A and b, bit for bit.
TEST(LucasKanade, Avx2KernelsEqualThePlainOnes) {
  const lk::TemplateKernel fast_template = lk::templateAvx2();
  const lk::ResidualKernel fast_residual = lk::residualAvx2();
  if (fast_template == nullptr || fast_residual == nullptr) GTEST_SKIP() << "no AVX2 on this CPU";
  cv::RNG rng(21);
  for (const int width : {3, 7, 8, 11, 15, 16, 17, 24, 33, 64, 101}) {
    lk::WindowShape shape;
    shape.rows = width;
    shape.width = width;
    shape.chunks = (width + lk::kLanes - 1) / lk::kLanes;
    const int stride = shape.chunks * lk::kLanes;
    // The template reads one more row and pixel around the window on each side (derivatives), the residual one more
    // row and pixel after it.
    cv::Mat img(shape.rows + 3, stride + 3, CV_8UC1), next(shape.rows + 1, stride + 1, CV_8UC1);
    for (int trial = 0; trial < 20; ++trial) {
      rng.fill(img, cv::RNG::UNIFORM, 0, 256);
      rng.fill(next, cv::RNG::UNIFORM, 0, 256);
      // Half the trials on a dark, flat image (small derivatives, whose sums the kernels take exactly).
      if (trial % 2 == 1) img = img / 40 + 100;
      lk::Weights w;
      w.w00 = rng.uniform(0, 1 << 13);
      w.w01 = rng.uniform(0, 1 << 12);
      w.w10 = rng.uniform(0, 1 << 12);
      w.w11 = (1 << lk::kWeightBits) - w.w00 - w.w01 - w.w10;
      // The window somewhere on an image of 40 x 30 pixels, often across its edges (derivatives 0 outside).
      lk::WindowPlace place;
      place.cols = 40;
      place.rows = 30;
      place.x = rng.uniform(-width - 2, 42);
      place.y = rng.uniform(-width - 2, 32);
      const std::size_t cells = static_cast<std::size_t>(stride * shape.rows);
      std::vector<std::int16_t> t0(cells), gx0(cells), gy0(cells), t1(cells), gx1(cells), gy1(cells);
      const std::uint8_t* corner = img.ptr<std::uint8_t>(1) + 1;
      const std::ptrdiff_t step = static_cast<std::ptrdiff_t>(img.step[0]);
      const lk::GradientSums a = lk::templatePlain(corner, step, shape, place, w, t0.data(), gx0.data(), gy0.data());
      const lk::GradientSums b = fast_template(corner, step, shape, place, w, t1.data(), gx1.data(), gy1.data());
      ASSERT_TRUE(sameBits(a.a11, b.a11) && sameBits(a.a12, b.a12) && sameBits(a.a22, b.a22)) << "width " << width;
      for (int y = 0; y < shape.rows; ++y)
        for (int x = 0; x < width; ++x) {
          const std::size_t i = static_cast<std::size_t>(y * stride + x);
          ASSERT_EQ(t0[i], t1[i]);
          ASSERT_EQ(gx0[i], gx1[i]);
          ASSERT_EQ(gy0[i], gy1[i]);
        }
      float p1 = 0.f, p2 = 0.f, f1 = 0.f, f2 = 0.f;
      lk::residualPlain(next.ptr<std::uint8_t>(), static_cast<std::ptrdiff_t>(next.step[0]), shape, w, t0.data(),
                        gx0.data(), gy0.data(), &p1, &p2);
      fast_residual(next.ptr<std::uint8_t>(), static_cast<std::ptrdiff_t>(next.step[0]), shape, w, t0.data(),
                    gx0.data(), gy0.data(), &f1, &f2);
      ASSERT_TRUE(sameBits(p1, f1) && sameBits(p2, f2)) << "width " << width << ": " << p1 << " " << f1;
    }
  }
}

}  // namespace
}  // namespace linnet
