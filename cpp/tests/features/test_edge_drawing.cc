// Edge Drawing chains and EDLines pieces on images with known edges.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "features/test_line_scene.h"
#include "linnet/features/edge_drawing.h"

namespace linnet {
namespace {

// Area-sampled (4x4 per pixel) image of a predicate, then a light blur: edges sit exactly on the predicate's border.
template <class Inside>
cv::Mat render(Inside inside, int dark, int bright) {
  cv::Mat img = testing::coverageImage([&](double x, double y) { return inside(x, y) ? bright : dark; }, 4);
  cv::GaussianBlur(img, img, cv::Size(5, 5), 0.7);
  return img;
}

// A square rotated by `angle` around (cx, cy) with half-side h.
struct Square {
  double cx = 380.0, cy = 240.0, h = 120.0, angle = 0.3;
  bool operator()(double x, double y) const {
    const double c = std::cos(angle), s = std::sin(angle);
    const double u = c * (x - cx) + s * (y - cy), v = -s * (x - cx) + c * (y - cy);
    return std::abs(u) < h && std::abs(v) < h;
  }
  // Distance of (x, y) from the nearest side's line.
  double sideDistance(double x, double y) const {
    const double c = std::cos(angle), s = std::sin(angle);
    const double u = c * (x - cx) + s * (y - cy), v = -s * (x - cx) + c * (y - cy);
    return std::min(std::abs(std::abs(u) - h), std::abs(std::abs(v) - h));
  }
};

TEST(EdgeDrawing, FindsTheFourSidesOfARotatedSquare) {
  const Square sq;
  const cv::Mat img = render(sq, 50, 180);
  EdgeDrawing ed{EdgeDrawingOptions{}};
  std::vector<cv::Vec4f> lines;
  ed.detect(img, &lines);
  double long_total = 0.0;
  int long_count = 0;
  for (const cv::Vec4f& l : lines) {
    EXPECT_LT(sq.sideDistance(l[0], l[1]), 1.0) << l;
    EXPECT_LT(sq.sideDistance(l[2], l[3]), 1.0) << l;
    const double len = std::hypot(l[2] - l[0], l[3] - l[1]);
    if (len > 100.0) {
      long_total += len;
      ++long_count;
    }
  }
  // Each side (240 px) comes out whole or in very few pieces; the corners cost a few pixels each.
  EXPECT_GE(long_count, 4);
  EXPECT_LE(long_count, 6);
  EXPECT_GT(long_total, 0.9 * 4 * 2 * sq.h);
}

TEST(EdgeDrawing, ChainsAreConnectedAndDisjoint) {
  const Square sq;
  const cv::Mat img = render([&](double x, double y) { return sq(x, y) || std::hypot(x - 120, y - 120) < 60; }, 40, 200);
  EdgeDrawing ed{EdgeDrawingOptions{}};
  std::vector<cv::Vec4f> lines;
  ed.detect(img, &lines);
  ASSERT_FALSE(ed.chains().empty());
  std::set<std::pair<int, int>> seen;
  for (const std::vector<cv::Point>& chain : ed.chains()) {
    for (std::size_t k = 0; k < chain.size(); ++k) {
      EXPECT_TRUE(seen.insert({chain[k].x, chain[k].y}).second) << "pixel in two chains: " << chain[k];
      if (k > 0) {
        const cv::Point d = chain[k] - chain[k - 1];
        EXPECT_LE(std::max(std::abs(d.x), std::abs(d.y)), 1) << "gap in a chain at " << chain[k];
      }
    }
  }
}

TEST(EdgeDrawing, ACircleGivesOnlyShortChords) {
  const double r = 100.0;
  const cv::Mat img = render([&](double x, double y) { return std::hypot(x - 376, y - 240) < r; }, 60, 190);
  EdgeDrawingOptions opt;
  EdgeDrawing ed(opt);
  std::vector<cv::Vec4f> lines;
  ed.detect(img, &lines);
  EXPECT_FALSE(lines.empty());
  // A chord whose sagitta stays within the fit tolerance: 2 sqrt(2 r tol), with a pixel of quantisation slack.
  const double longest = 2.0 * std::sqrt(2.0 * r * (opt.fit_error_px + 1.0));
  for (const cv::Vec4f& l : lines) EXPECT_LT(std::hypot(l[2] - l[0], l[3] - l[1]), longest) << l;
}

TEST(EdgeDrawing, FlatNoiseAndTinyImages) {
  EdgeDrawing ed{EdgeDrawingOptions{}};
  std::vector<cv::Vec4f> lines;
  ed.detect(cv::Mat(480, 752, CV_8UC1, cv::Scalar(128)), &lines);
  EXPECT_TRUE(lines.empty());
  ed.detect(cv::Mat(5, 5, CV_8UC1, cv::Scalar(0)), &lines);
  EXPECT_TRUE(lines.empty());
  cv::Mat noise(480, 752, CV_8UC1);
  cv::RNG rng(3);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  ed.detect(noise, &lines);  // must terminate; pure noise gives few and short pieces
  for (const cv::Vec4f& l : lines) EXPECT_LT(std::hypot(l[2] - l[0], l[3] - l[1]), 60.0);
}

// The plain EDLines fit (sums recomputed for every window position): the detector's sliding sums must give exactly
// the same pieces.
void plainFitLines(const std::vector<cv::Point>& chain, const EdgeDrawingOptions& o, std::vector<cv::Vec4f>* lines) {
  const int n = static_cast<int>(chain.size()), L = std::max(2, o.min_line_px);
  const double tol = o.fit_error_px;
  const double ox = chain.empty() ? 0.0 : chain[0].x, oy = chain.empty() ? 0.0 : chain[0].y;
  struct Fit {
    double cx, cy, dx, dy, mse;
  };
  const auto fit = [](double cnt, double sx, double sy, double sxx, double syy, double sxy) {
    Fit f{sx / cnt, sy / cnt, 1.0, 0.0, 0.0};
    const double a = sxx / cnt - f.cx * f.cx, c = syy / cnt - f.cy * f.cy, b = sxy / cnt - f.cx * f.cy;
    const double half = 0.5 * (a - c), root = std::sqrt(half * half + b * b);
    f.mse = std::max(0.0, 0.5 * (a + c) - root);
    const double lambda = 0.5 * (a + c) + root;
    double vx = b, vy = lambda - a;
    if (std::abs(lambda - c) > std::abs(vy)) {
      vx = lambda - c;
      vy = b;
    }
    const double norm = std::sqrt(vx * vx + vy * vy);
    if (norm > 1e-12) {
      f.dx = vx / norm;
      f.dy = vy / norm;
    }
    return f;
  };
  const auto dist = [](const Fit& f, double x, double y) { return std::abs((x - f.cx) * f.dy - (y - f.cy) * f.dx); };
  int i = 0;
  while (n - i >= L) {
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    for (int k = i; k < i + L; ++k) {
      const double x = chain[k].x - ox, y = chain[k].y - oy;
      sx += x, sy += y, sxx += x * x, syy += y * y, sxy += x * y;
    }
    Fit f = fit(L, sx, sy, sxx, syy, sxy);
    bool straight = f.mse <= tol * tol;
    for (int k = i; straight && k < i + L; ++k) straight = dist(f, chain[k].x - ox, chain[k].y - oy) <= tol;
    if (!straight) {
      ++i;
      continue;
    }
    double cnt = L;
    int last = i + L - 1, misses = 0, since_fit = 0;
    for (int j = i + L; j < n; ++j) {
      const double x = chain[j].x - ox, y = chain[j].y - oy;
      if (dist(f, x, y) > tol) {
        if (++misses > o.max_outliers) break;
        continue;
      }
      misses = 0;
      last = j;
      cnt += 1.0, sx += x, sy += y, sxx += x * x, syy += y * y, sxy += x * y;
      if (++since_fit >= 8) {
        f = fit(cnt, sx, sy, sxx, syy, sxy);
        since_fit = 0;
      }
    }
    f = fit(cnt, sx, sy, sxx, syy, sxy);
    const double t0 = (chain[i].x - ox - f.cx) * f.dx + (chain[i].y - oy - f.cy) * f.dy;
    const double t1 = (chain[last].x - ox - f.cx) * f.dx + (chain[last].y - oy - f.cy) * f.dy;
    lines->emplace_back(static_cast<float>(ox + f.cx + t0 * f.dx), static_cast<float>(oy + f.cy + t0 * f.dy),
                        static_cast<float>(ox + f.cx + t1 * f.dx), static_cast<float>(oy + f.cy + t1 * f.dy));
    i = last + 1;
  }
}

// A cluttered scene: blurred noise (many short, bent chains) with rotated squares and a circle on top.
cv::Mat clutter(int rows, int cols, int seed) {
  cv::Mat img(rows, cols, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 2.0);
  cv::normalize(img, img, 0, 255, cv::NORM_MINMAX);
  for (int k = 0; k < 12; ++k) {
    const cv::RotatedRect r(cv::Point2f(rng.uniform(0.f, static_cast<float>(cols)), rng.uniform(0.f, static_cast<float>(rows))),
                            cv::Size2f(rng.uniform(20.f, 200.f), rng.uniform(20.f, 200.f)), rng.uniform(0.f, 180.f));
    cv::Point2f p[4];
    r.points(p);
    std::vector<cv::Point> poly(p, p + 4);
    cv::fillConvexPoly(img, poly, cv::Scalar(rng.uniform(0, 256)), cv::LINE_AA);
  }
  cv::circle(img, cv::Point(cols / 2, rows / 2), rows / 5, cv::Scalar(230), 3, cv::LINE_AA);
  return img;
}

// Also covers the fit's shortcut for windows that are surely not straight (no fit, the same decision): three
// tolerances, so that many windows fall near each boundary.
TEST(EdgeDrawing, SlidingFitEqualsThePlainFitBitForBit) {
  for (double tol : {1.5, 0.75, 3.0}) {
    EdgeDrawingOptions opt;
    opt.fit_error_px = tol;
    opt.min_line_px = tol == 0.75 ? 8 : opt.min_line_px;
    EdgeDrawing ed(opt);
    for (int seed : {1, 2, 3}) {
      std::vector<cv::Vec4f> lines, plain;
      ed.detect(clutter(480, 752, seed), &lines);
      ASSERT_GT(ed.chains().size(), 100u);
      for (const std::vector<cv::Point>& chain : ed.chains()) plainFitLines(chain, opt, &plain);
      ASSERT_EQ(lines.size(), plain.size()) << "seed " << seed << ", tolerance " << tol;
      for (std::size_t i = 0; i < lines.size(); ++i)
        for (int k = 0; k < 4; ++k)
          ASSERT_EQ(lines[i][k], plain[i][k]) << "seed " << seed << ", tolerance " << tol << ", line " << i;
    }
  }
}

// The plain Edge Drawing linking (Topal & Akinlar 2012) on separate magnitude, direction and edge images, with (x, y)
// positions: the detector's packed words, anchor bit scan, counting sort and index walk must give exactly its chains.
std::vector<std::vector<cv::Point>> plainChains(const cv::Mat& gray, const EdgeDrawingOptions& o) {
  cv::Mat smooth = gray, gx, gy;
  if (o.sigma > 0.0) {
    const int k = 2 * static_cast<int>(std::ceil(2.0 * o.sigma)) + 1;
    cv::GaussianBlur(gray, smooth, cv::Size(k, k), o.sigma, o.sigma, cv::BORDER_REPLICATE);
  }
  cv::Sobel(smooth, gx, CV_16S, 1, 0, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  cv::Sobel(smooth, gy, CV_16S, 0, 1, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
  const int rows = gray.rows, cols = gray.cols;
  cv::Mat mag(rows, cols, CV_32S, cv::Scalar(0)), vert(rows, cols, CV_8U, cv::Scalar(0)),
      edge(rows, cols, CV_8U, cv::Scalar(0));
  for (int y = 1; y < rows - 1; ++y)
    for (int x = 1; x < cols - 1; ++x) {
      const int ax = std::abs(gx.at<short>(y, x)), ay = std::abs(gy.at<short>(y, x));
      mag.at<int>(y, x) = ax + ay >= o.gradient_threshold ? ax + ay : 0;
      vert.at<uchar>(y, x) = ax >= ay;
    }
  const auto m = [&](int x, int y) { return mag.at<int>(y, x); };
  // Anchors: ridge points across the edge on the scan grid, strongest first, ties in raster order.
  const int step = std::max(1, o.scan_interval), A = o.anchor_threshold;
  std::vector<std::pair<int, cv::Point>> anchors;
  for (int y = 1; y < rows - 1; y += step)
    for (int x = step; x < cols - 1; x += step) {
      const int g = m(x, y);
      const bool ridge = vert.at<uchar>(y, x) ? g - m(x - 1, y) >= A && g - m(x + 1, y) >= A
                                              : g - m(x, y - 1) >= A && g - m(x, y + 1) >= A;
      if (g != 0 && ridge) anchors.push_back({g, cv::Point(x, y)});
    }
  std::stable_sort(anchors.begin(), anchors.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  const auto walk = [&](int x, int y, int dx, int dy, std::vector<cv::Point>* out) {
    for (;;) {
      // Straight on, then the side -1, then +1; a later candidate wins only when strictly stronger.
      const int ax = x + dx, ay = y + dy, sx = dx == 0 ? 1 : 0, sy = dx == 0 ? 0 : 1;
      int side = 0, best = m(ax, ay);
      for (int s : {-1, 1})
        if (m(ax + s * sx, ay + s * sy) > best) {
          side = s;
          best = m(ax + s * sx, ay + s * sy);
        }
      const int nx = ax + side * sx, ny = ay + side * sy;
      if (best == 0 || edge.at<uchar>(ny, nx)) return;
      x = nx;
      y = ny;
      edge.at<uchar>(y, x) = 1;
      out->emplace_back(x, y);
      if (vert.at<uchar>(y, x) && dx != 0) {
        dy = side != 0 ? side : (m(x, y - 1) >= m(x, y + 1) ? -1 : 1);
        dx = 0;
      } else if (!vert.at<uchar>(y, x) && dy != 0) {
        dx = side != 0 ? side : (m(x - 1, y) >= m(x + 1, y) ? -1 : 1);
        dy = 0;
      }
    }
  };
  std::vector<std::vector<cv::Point>> chains;
  for (const auto& [g, a] : anchors) {
    if (edge.at<uchar>(a.y, a.x)) continue;
    edge.at<uchar>(a.y, a.x) = 1;
    std::vector<cv::Point> back, ahead;
    const bool v = vert.at<uchar>(a.y, a.x);
    walk(a.x, a.y, v ? 0 : -1, v ? -1 : 0, &back);
    walk(a.x, a.y, v ? 0 : 1, v ? 1 : 0, &ahead);
    if (back.size() + ahead.size() + 1 < static_cast<std::size_t>(std::max(2, o.min_line_px))) continue;
    std::vector<cv::Point> chain(back.rbegin(), back.rend());
    chain.push_back(a);
    chain.insert(chain.end(), ahead.begin(), ahead.end());
    chains.push_back(std::move(chain));
  }
  return chains;
}

TEST(EdgeDrawing, ChainsEqualThePlainLinking) {
  EdgeDrawingOptions shipped;  // the line front-end's settings (config: lines.detection.ed_*)
  shipped.anchor_threshold = 8;
  shipped.scan_interval = 2;
  shipped.min_line_px = 17;
  for (const EdgeDrawingOptions& opt : {EdgeDrawingOptions{}, shipped}) {
    EdgeDrawing ed(opt);
    for (int seed : {1, 2, 3}) {
      std::vector<cv::Vec4f> lines;
      const cv::Mat img = clutter(480, 752, seed);
      ed.detect(img, &lines);
      ASSERT_GT(ed.chains().size(), 50u);
      EXPECT_EQ(ed.chains(), plainChains(img, opt)) << "seed " << seed << ", scan interval " << opt.scan_interval;
    }
  }
}

TEST(EdgeDrawing, ReusedDetectorGivesWhatAFreshOneGives) {
  // Scratch kept from a larger image (chains, anchor buffers, the ridge row) must not change a smaller one's result.
  EdgeDrawing reused{EdgeDrawingOptions{}};
  std::vector<cv::Vec4f> lines, fresh_lines;
  reused.detect(clutter(480, 1003, 7), &lines);
  const cv::Mat narrow = clutter(300, 749, 8);
  reused.detect(narrow, &lines);
  EdgeDrawing fresh{EdgeDrawingOptions{}};
  fresh.detect(narrow, &fresh_lines);
  ASSERT_EQ(lines.size(), fresh_lines.size());
  for (std::size_t i = 0; i < lines.size(); ++i) EXPECT_EQ(lines[i], fresh_lines[i]) << i;
  EXPECT_EQ(reused.chains(), fresh.chains());
}

TEST(EdgeDrawing, OnePassGradientEqualsTheSobelFilters) {
  // The detector's own pass against the plain version: cv::Sobel's 3x3 derivatives of the smoothed image, each inner
  // pixel's word |gx| + |gy| (0 below the threshold) with the direction bit where |gx| >= |gy|, the border 0.
  cv::Mat stripes(64, 90, CV_8UC1);  // the largest derivatives: 0 / 255 columns and rows
  for (int y = 0; y < stripes.rows; ++y)
    for (int x = 0; x < stripes.cols; ++x) stripes.at<uchar>(y, x) = ((x / 2 + y / 3) % 2) ? 255 : 0;
  for (double sigma : {0.0, 1.0}) {
    for (const cv::Mat& img : {clutter(97, 131, 5), clutter(480, 752, 6), stripes}) {
      EdgeDrawingOptions opt;
      opt.sigma = sigma;
      EdgeDrawing ed(opt);
      std::vector<cv::Vec4f> lines;
      ed.detect(img, &lines);
      cv::Mat smooth = img, gx, gy;
      if (sigma > 0.0) cv::GaussianBlur(img, smooth, cv::Size(5, 5), sigma, sigma, cv::BORDER_REPLICATE);
      cv::Sobel(smooth, gx, CV_16S, 1, 0, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
      cv::Sobel(smooth, gy, CV_16S, 0, 1, 3, 1.0, 0.0, cv::BORDER_REPLICATE);
      const cv::Mat& words = ed.pixelWords();
      ASSERT_EQ(words.size(), img.size());
      int wrong = 0;
      for (int y = 0; y < img.rows; ++y)
        for (int x = 0; x < img.cols; ++x) {
          int want = 0;
          if (y > 0 && x > 0 && y < img.rows - 1 && x < img.cols - 1) {
            const int ax = std::abs(gx.at<short>(y, x)), ay = std::abs(gy.at<short>(y, x));
            want = (ax + ay >= opt.gradient_threshold ? ax + ay : 0) | (ax >= ay ? 0x4000 : 0);
          }
          wrong += (words.at<std::uint16_t>(y, x) & 0x7FFF) != want;  // the linked bit (0x8000) left out
        }
      EXPECT_EQ(wrong, 0) << img.rows << " x " << img.cols << ", sigma " << sigma;
    }
  }
}

}  // namespace
}  // namespace linnet
