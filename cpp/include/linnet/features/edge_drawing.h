// Edge Drawing and EDLines' line fit, written for the line front-end's speed budget at full resolution.
//
// Edge Drawing (Topal & Akinlar, "Edge Drawing: a combined real-time edge and segment detector", JVCI 2012): the
// image is smoothed, its gradient computed; "anchors" (ridge points of the gradient magnitude) are linked by walking
// along the ridge, always stepping to the strongest of the three pixels ahead, into one-pixel-wide edge chains.
// EDLines (Akinlar & Topal, "EDLines: a real-time line segment detector with a false detection control", PRL 2011)
// cuts every chain into straight pieces by least-squares fitting: a piece starts where min_line_px consecutive
// pixels fit a line within fit_error_px and grows while the next pixel stays within that distance.
// Smoothing uses OpenCV's vectorised filter, the gradient one vectorised pass; the walk touches only the edge pixels.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace linnet {

struct EdgeDrawingOptions {
  double sigma = 1.0;             // gaussian smoothing before the gradient, pixels (0: none)
  int gradient_threshold = 27;    // weakest |gx| + |gy| (3x3 Sobel, so 4x a one-pixel difference) on an edge
  int anchor_threshold = 0;       // how much an anchor's magnitude exceeds both neighbours across the edge
  int scan_interval = 1;          // anchors are looked for on every scan_interval-th row and column
  int min_line_px = 12;           // fewest chain pixels in a line piece
  double fit_error_px = 1.5;      // largest distance of a chain pixel from its piece's fitted line, pixels
  int max_outliers = 1;           // pixels beyond fit_error_px skipped inside a piece before it ends
};

/// Reusable detector: holds the scratch images (one instance per thread).
class EdgeDrawing {
 public:
  explicit EdgeDrawing(const EdgeDrawingOptions& options) : options_(options) {}

  /// Segments (x0, y0, x1, y1) in pixel coordinates of `gray` (CV_8UC1). Images smaller than 8x8 give none.
  void detect(const cv::Mat& gray, std::vector<cv::Vec4f>* lines);

  /// The edge chains of the last detect() (pixel coordinates, in walking order), for tests and debugging.
  const std::vector<std::vector<cv::Point>>& chains() const { return chains_; }
  /// The pixel words of the last detect() before linking (see px_; kEdgeBit set on the linked pixels), for tests.
  const cv::Mat& pixelWords() const { return px_; }

 private:
  void gradient(const cv::Mat& gray);
  void link();
  void walk(int x, int y, int dx, int dy, std::vector<cv::Point>* out);
  void fitLines(const std::vector<cv::Point>& chain, std::vector<cv::Vec4f>* lines) const;

  EdgeDrawingOptions options_;
  cv::Mat smooth_;
  // CV_16U, one word per pixel so that a step of the walk reads one array: bits 0-11 |gx| + |gy| (at most 2040; 0
  // below gradient_threshold and on the 1-pixel border), kDirBit where the edge runs vertically (|gx| >= |gy|),
  // kEdgeBit once the pixel is linked into a chain.
  cv::Mat px_;
  static constexpr std::uint16_t kMagMask = 0x0FFF, kDirBit = 0x4000, kEdgeBit = 0x8000;
  static int magnitude(std::uint16_t word) { return word & kMagMask; }
  std::vector<std::uint8_t> ridge_;  // one row of the ridge test
  std::vector<std::uint8_t> scan_cols_;  // 1 on the columns scanned for anchors
  std::vector<int> anchors_;      // y * cols + x
  std::vector<int> bucket_start_;
  std::vector<int> sorted_;
  std::vector<cv::Point> left_, right_;
  std::vector<std::vector<cv::Point>> chains_;
};

}  // namespace linnet
