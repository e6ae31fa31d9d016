// Line segment detection: LSD (the thesis' detector), EDLines (OpenCV ximgproc EdgeDrawing) or FastLineDetector,
// optionally on a downsampled image, followed by a sub-pixel refinement of every segment at full resolution.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc.hpp>

#include "linnet/features/edge_drawing.h"
#include "linnet/features/line_types.h"

namespace linnet {

struct LineDetectorOptions {
  // "ed" (Edge Drawing + EDLines' fit written here, see edge_drawing.h) | "edlines" (OpenCV ximgproc EdgeDrawing) |
  // "fld" (OpenCV FastLineDetector) | "lsd" (von Gioi et al. 2012, the thesis' detector)
  std::string detector = "ed";
  double downsample = 1.0;           // detect on the image shrunk by this factor (1 = full resolution; integers: pixel
                                     // averaging, otherwise bilinear); 2 suits "edlines" and "fld"
  double lsd_scale = 0.8;            // LSD's own gaussian downsampling (thesis 3.1.1), used by "lsd" only
  int edlines_gradient_threshold = 20;  // EDLines gradient threshold, grey levels
  int edlines_anchor_threshold = 0;     // EDLines anchor threshold, grey levels
  double edlines_sigma = 1.0;           // EDLines gaussian smoothing, pixels of the detection image
  double ed_sigma = 1.0;                // "ed": gaussian smoothing, pixels of the detection image
  int ed_gradient_threshold = 27;       // "ed": weakest 3x3 Sobel |gx| + |gy| on an edge (4x grey-level steps)
  int ed_anchor_threshold = 8;          // "ed": anchor's excess over its neighbours across the edge
  int ed_scan_interval = 2;             // "ed": anchors looked for on every n-th row and column
  double ed_fit_error_px = 1.5;         // "ed": largest distance of an edge pixel from its line, detection pixels
  int fld_canny_low = 50;               // FastLineDetector Canny thresholds, grey levels
  int fld_canny_high = 100;
  double min_length_px = 25.0;       // shortest segment kept, full-resolution pixels
  int max_segments = 300;            // the longest this many are kept per image
  bool refine = true;                // sub-pixel refinement on the full-resolution image
  int refine_search_px = 2;          // +- search across the segment, pixels
  double refine_step_px = 3.0;       // spacing of refinement samples along the segment, pixels
  int refine_max_samples = 24;       // refinement samples per segment (spread evenly when the segment is long)
  double refine_min_gradient = 4.0;  // weakest edge response used by the refinement, grey levels per pixel
  double refine_bend_px = 0.25;      // sagitta of a bent edge above which endpoints follow the bend, pixels (>= 50: off)
  // Look beside each segment for a parallel edge that detection on a downsampled image fused with it (thin bars).
  // Off by default: "ed" at full resolution finds both edges itself (test
  // FullResolutionEdgeDrawingSeparatesThinBarEdges), and the search cost about 0.4 ms per stereo frame on real EuRoC
  // images. Meant for "edlines" and "fld" on the half-size image.
  bool parallel_edges = false;
  int parallel_search_px = 6;        // +- search across the segment for a parallel edge, full-resolution pixels
  double parallel_min_votes = 0.6;   // fraction of samples along the segment that must see the parallel edge
  double parallel_min_ratio = 0.3;   // its gradient relative to the segment's own edge at the same sample

  template <class V>
  void visit(V& v) {
    v.choice("detector", detector, "line detector", {"ed", "edlines", "fld", "lsd"});
    v("downsample", downsample, "detection on the image shrunk by this factor", 1.0, 4.0);
    v("lsd_scale", lsd_scale, "LSD gaussian downsampling factor", 0.1, 1.0);
    v("edlines_gradient_threshold", edlines_gradient_threshold, "EDLines gradient threshold, grey levels", 1, 255);
    v("edlines_anchor_threshold", edlines_anchor_threshold, "EDLines anchor threshold, grey levels", 0, 255);
    v("edlines_sigma", edlines_sigma, "EDLines gaussian sigma, pixels", 0.0, 5.0);
    v("ed_sigma", ed_sigma, "ed: gaussian sigma, pixels", 0.0, 5.0);
    v("ed_gradient_threshold", ed_gradient_threshold, "ed: Sobel |gx|+|gy| threshold", 1, 4080);
    v("ed_anchor_threshold", ed_anchor_threshold, "ed: anchor threshold", 0, 4080);
    v("ed_scan_interval", ed_scan_interval, "ed: anchor scan interval, pixels", 1, 8);
    v("ed_fit_error_px", ed_fit_error_px, "ed: line fit tolerance, pixels", 0.2, 5.0);
    v("fld_canny_low", fld_canny_low, "FLD Canny low threshold", 1, 1000);
    v("fld_canny_high", fld_canny_high, "FLD Canny high threshold", 1, 1000);
    v("min_length_px", min_length_px, "minimum segment length, pixels", 2.0, 10000.0);
    v("max_segments", max_segments, "segments kept per image (longest first)", 1, 10000);
    v("refine", refine, "sub-pixel refinement at full resolution");
    v("refine_search_px", refine_search_px, "refinement search half-width, pixels", 1, 10);
    v("refine_step_px", refine_step_px, "refinement sample spacing, pixels", 0.5, 50.0);
    v("refine_max_samples", refine_max_samples, "refinement samples per segment", 3, 1024);
    v("refine_min_gradient", refine_min_gradient, "weakest edge used by refinement, grey levels/pixel", 0.0, 255.0);
    v("refine_bend_px", refine_bend_px, "sagitta above which endpoints follow a bent edge, pixels", 0.0, 1000.0);
    v("parallel_edges", parallel_edges, "recover parallel edges fused by detection at downsample > 1");
    v("parallel_search_px", parallel_search_px, "parallel-edge search half-width, pixels", 2, 10);
    v("parallel_min_votes", parallel_min_votes, "fraction of samples that must see the parallel edge", 0.1, 1.0);
    v("parallel_min_ratio", parallel_min_ratio, "parallel edge gradient / own edge gradient", 0.05, 10.0);
  }
};

/// Detects segments in 8-bit grey images. Holds OpenCV detector objects and scratch buffers: one instance per thread.
class LineDetector {
 public:
  /// Validates the options (ConfigError naming the key) and builds the OpenCV detector.
  explicit LineDetector(const LineDetectorOptions& options);

  /// Appends nothing and clears `segments` for an empty image; throws UsageError for a non-CV_8UC1 image.
  /// Output: at most max_segments segments, longest first, oriented as LineSegment documents.
  void detect(const cv::Mat& gray, std::vector<LineSegment>* segments) { detect(gray, segments, options_.refine); }
  /// As above; refine = false only orients the segments (the caller may refine the ones it keeps).
  void detect(const cv::Mat& gray, std::vector<LineSegment>* segments, bool refine);

  const LineDetectorOptions& options() const { return options_; }

 private:
  void detectRaw(const cv::Mat& gray, std::vector<cv::Vec4f>* raw);

  LineDetectorOptions options_;
  cv::Ptr<cv::LineSegmentDetector> lsd_;
  cv::Ptr<cv::ximgproc::FastLineDetector> fld_;
  cv::Ptr<cv::ximgproc::EdgeDrawing> ed_;
  std::unique_ptr<EdgeDrawing> own_ed_;
  cv::Mat small_;
  std::vector<cv::Vec4f> raw_;
};

/// Orients a segment by the mean sign of the gradient across it (see LineSegment); cheap (2 samples per position).
void orientSegment(const cv::Mat& gray, const LineDetectorOptions& options, LineSegment* segment);

/// Sub-pixel refinement of one segment on a full-resolution 8-bit image: samples the directional derivative across
/// the segment, locates the edge with a parabola fit, and fits a weighted total-least-squares line; endpoints are
/// projected onto it. Also orients the segment by the sign of the gradient (see LineSegment). Returns false when too
/// few samples respond (the segment is then left as it was, only oriented). support (optional): the fraction of the
/// samples along the segment that found an edge within refine_search_px (0 when the refinement failed).
/// trim (for a segment whose extent is only predicted): the samples more than kRefineTrimPx off the first fit are
/// dropped and the line refitted on the rest; the segment then ends at the outermost kept samples, and support counts
/// the kept ones only. No bent-edge endpoints in that case.
bool refineSegment(const cv::Mat& gray, const LineDetectorOptions& options, LineSegment* segment,
                   double* support = nullptr, bool trim = false);
inline constexpr double kRefineTrimPx = 1.0;

/// Parallel edges beside an oriented segment, on the full-resolution image: thin bars (frames, trims, the two sides of
/// a narrow gap) have two edges 2-6 px apart that a detector on a downsampled image fuses into one. The directional
/// derivative across the segment is sampled along it; an extremum of either sign, at least 2 px from the segment's
/// own edge and within parallel_search_px, seen at a consistent offset by parallel_min_votes of the samples, becomes
/// a segment (fitted through those offsets, spanning the samples that saw it, oriented by its polarity). Appends at
/// most one per side; returns how many.
int findParallelEdges(const cv::Mat& gray, const LineDetectorOptions& options, const LineSegment& segment,
                      std::vector<LineSegment>* out);

}  // namespace linnet
