// FAST / Shi-Tomasi corner detection with grid bucketing and a minimum-distance mask.
#include "linnet/features/point_detection.h"

#include <algorithm>
#include <cmath>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "linnet/core/error.h"
#include "linnet/features/fast_corners.h"

namespace linnet {

namespace {

struct Candidate {
  cv::Point2f pt;
  float response;
};

// FAST corners (9-16, non-maximum suppression) where the mask is set. One search of the whole image: searching
// only the free part of each grid cell (with a margin for FAST's ring and the suppression) gave the same corners for
// 15 % more instructions (48 small searches per round; 150 frames of V1_02 room hard: 1.35 -> 1.15 G).
// `whole` (may be null) receives the image's corners before the mask.
std::vector<Candidate> fastCandidates(const cv::Mat& image, const cv::Mat& mask, int threshold, FastCorners* whole) {
  std::vector<Candidate> c;
  std::vector<cv::KeyPoint> kps;
  fastCorners(image, threshold, &kps);  // cv::FAST's 9-16 corners with suppression, bit for bit
  for (const cv::KeyPoint& k : kps) {
    const cv::Point ip(cvRound(k.pt.x), cvRound(k.pt.y));
    if (mask.at<unsigned char>(ip)) c.push_back({k.pt, k.response});
  }
  if (whole != nullptr) {
    whole->threshold = threshold;
    whole->keypoints = std::move(kps);
  }
  return c;
}

std::vector<Candidate> shiTomasiCandidates(const cv::Mat& image, const cv::Mat& mask, double quality) {
  cv::Mat eig;
  cv::cornerMinEigenVal(image, eig, 3, 3);
  double max_val = 0.0;
  cv::minMaxLoc(eig, nullptr, &max_val, nullptr, nullptr, mask);
  std::vector<Candidate> c;
  if (!(max_val > 0.0)) return c;
  const float th = static_cast<float>(max_val * quality);
  // 3x3 non-maximum suppression.
  cv::Mat dil;
  cv::dilate(eig, dil, cv::Mat());
  for (int y = 1; y < eig.rows - 1; ++y) {
    const float* e = eig.ptr<float>(y);
    const float* d = dil.ptr<float>(y);
    const unsigned char* m = mask.ptr<unsigned char>(y);
    for (int x = 1; x < eig.cols - 1; ++x)
      if (m[x] && e[x] > th && e[x] == d[x]) c.push_back({cv::Point2f(float(x), float(y)), e[x]});
  }
  return c;
}

}  // namespace

cv::Mat detectionMask(const cv::Size& size, const std::vector<cv::Point2f>& points, double min_distance_px,
                      int border_px, std::vector<unsigned char>* keep) {
  cv::Mat occupied(size, CV_8UC1, cv::Scalar(0));  // discs only, so that border points are still kept
  const int radius = std::max(1, static_cast<int>(std::lround(min_distance_px)));
  if (keep) keep->assign(points.size(), 1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const cv::Point c(cvRound(points[i].x), cvRound(points[i].y));
    const bool inside = c.x >= 0 && c.y >= 0 && c.x < size.width && c.y < size.height;
    if (keep && inside && occupied.at<unsigned char>(c)) {
      (*keep)[i] = 0;
      continue;
    }
    cv::circle(occupied, c, radius, cv::Scalar(255), cv::FILLED);
  }
  // The mask: the image inside the border, without the discs (each disc drawn once, not into both images).
  const int b = std::max(0, border_px);
  if (size.width <= 2 * b || size.height <= 2 * b) return cv::Mat(size, CV_8UC1, cv::Scalar(0));
  cv::Mat mask;
  cv::bitwise_not(occupied, mask);
  if (b > 0) {
    mask.rowRange(0, b).setTo(0);
    mask.rowRange(size.height - b, size.height).setTo(0);
    mask.colRange(0, b).setTo(0);
    mask.colRange(size.width - b, size.width).setTo(0);
  }
  return mask;
}

std::vector<cv::Point2f> detectCorners(const cv::Mat& image, cv::Mat* mask, int max_new,
                                       const PointDetectorParams& p, FastCorners* first_round) {
  if (image.type() != CV_8UC1) throw UsageError("detectCorners: needs an 8-bit single-channel image");
  if (mask->size() != image.size() || mask->type() != CV_8UC1)
    throw UsageError("detectCorners: the mask must be 8-bit and of the image's size");
  std::vector<cv::Point2f> out;
  if (max_new <= 0) return out;

  const int cols = std::max(1, p.grid_cols), rows = std::max(1, p.grid_rows);
  const int cells = cols * rows;
  const int cap = std::max(1, (2 * max_new + cells - 1) / cells);
  std::vector<int> per_cell(cells, 0);
  const int radius = std::max(1, static_cast<int>(std::lround(p.min_distance_px)));
  const double cw = static_cast<double>(image.cols) / cols, ch = static_cast<double>(image.rows) / rows;

  // FAST: when the corners at the threshold do not fill the quota, take weaker ones (threshold halved, down to 5)
  // in the space that is still free. Shi-Tomasi: one round (its threshold is relative to the strongest corner).
  const bool fast = p.detector != "shi_tomasi";
  for (int th = std::max(1, p.fast_threshold);; th /= 2) {
    const bool first = th == std::max(1, p.fast_threshold);
    std::vector<Candidate> cand = fast ? fastCandidates(image, *mask, th, first ? first_round : nullptr)
                                       : shiTomasiCandidates(image, *mask, p.shi_tomasi_quality);
    std::sort(cand.begin(), cand.end(), [](const Candidate& a, const Candidate& b) {
      if (a.response != b.response) return a.response > b.response;
      if (a.pt.y != b.pt.y) return a.pt.y < b.pt.y;
      return a.pt.x < b.pt.x;
    });
    std::vector<unsigned char> taken(cand.size(), 0);
    for (int pass = 0; pass < 2 && static_cast<int>(out.size()) < max_new; ++pass) {
      for (std::size_t i = 0; i < cand.size() && static_cast<int>(out.size()) < max_new; ++i) {
        if (taken[i]) continue;
        const cv::Point c(cvRound(cand[i].pt.x), cvRound(cand[i].pt.y));
        if (!mask->at<unsigned char>(c)) continue;
        const int cell = std::min(rows - 1, int(c.y / ch)) * cols + std::min(cols - 1, int(c.x / cw));
        if (pass == 0 && per_cell[cell] >= cap) continue;
        taken[i] = 1;
        ++per_cell[cell];
        out.push_back(cand[i].pt);
        cv::circle(*mask, c, radius, cv::Scalar(0), cv::FILLED);
      }
    }
    if (!fast || static_cast<int>(out.size()) >= max_new || th / 2 < 5) break;
  }
  return out;
}

}  // namespace linnet
