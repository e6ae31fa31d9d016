// Line Band Descriptor (LBD), binary 256-bit form, written for speed (Zhang & Koch, JVCI 2013; thesis 3.1.3).
//
// The line support region is m = 9 bands of w = 7 rows each, parallel to the segment and centred on it. Every
// row accumulates the image gradient projected on (d_perp, d_L), split by sign into 4 sums, weighted by a global
// gaussian across the region (sigma = (m w - 1) / 2). Band j is described by the mean and standard deviation of
// the rows of bands j-1, j, j+1, weighted by a local gaussian (sigma = w) around band j's centre: 8 floats per band,
// 72 in all. Means and deviations are normalised separately, clamped at 0.4 and renormalised. The binary descriptor
// compares the 8 values of 32 band pairs (nearest pairs first): 256 bits.
#pragma once

#include <array>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/features/line_types.h"

namespace linnet {

inline constexpr int kLbdBands = 9;      // m
inline constexpr int kLbdBandWidth = 7;  // w, pixels
inline constexpr int kLbdFloats = 8 * kLbdBands;

struct LbdOptions {
  int max_samples = 16;     // samples along the segment per row (evenly spaced; fewer when the segment is shorter)
  double clamp = 0.4;       // clamp of the normalised float descriptor (Zhang & Koch)

  template <class V>
  void visit(V& v) {
    v("max_samples", max_samples, "samples along a segment per row", 4, 1024);
    v("clamp", clamp, "clamp of normalised descriptor entries", 0.05, 1.0);
  }
};

/// The 72-float LBD of one segment on an 8-bit grey image (unit norm; zeros if the region holds no gradient).
std::array<float, kLbdFloats> computeLbdFloat(const cv::Mat& gray, const LbdOptions& options, const LineSegment& seg);

/// The same descriptor without SIMD: the plain reference computeLbdFloat is held to, bit for bit (tests).
std::array<float, kLbdFloats> computeLbdFloatPlain(const cv::Mat& gray, const LbdOptions& options,
                                                   const LineSegment& seg);

/// Binary form of a float LBD.
LbdDescriptor binarizeLbd(const std::array<float, kLbdFloats>& f);

/// Binary LBD of every segment (resizes `out`). Throws UsageError for a non-CV_8UC1 image.
void computeLbd(const cv::Mat& gray, const LbdOptions& options, const std::vector<LineSegment>& segments,
                std::vector<LbdDescriptor>* out);

}  // namespace linnet
