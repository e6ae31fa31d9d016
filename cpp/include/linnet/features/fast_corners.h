// FAST corners (Rosten & Drummond, "Machine learning for high-speed corner detection", ECCV 2006): the 9-16 test
// with non-maximum suppression, giving exactly what cv::FAST(image, keypoints, threshold, true,
// FastFeatureDetector::TYPE_9_16) gives (OpenCV 4.6): the same keypoints in the same order, with the same responses.
//
// OpenCV tests each pixel's ring with vector code but scores every corner it finds with scalar code (the ring's 25
// differences gathered one by one), and on the noisy images of the hard replays a frame holds thousands of corners,
// so that the scoring and the suppression's branches took most of its time. Here each block of 32 pixels gets its test
// and, when it holds a corner, its 32 scores at once, in AVX2: a pixel is a corner when 9 contiguous ring pixels are
// all brighter than v + t or all darker than v - t, and its score is the largest t' for which it still is, minus 1
// (OpenCV's cornerScore: the largest, over the 16 arcs of 9, of the arc's smallest difference, either sign).
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace linnet {

/// FAST 9-16 corners of an 8-bit single-channel image with non-maximum suppression, at `threshold` (0..255).
/// `simd`: the AVX2 kernel where the CPU has it (else, and for images narrower than 38 pixels or shorter than 7,
/// cv::FAST itself, whose results these are). An empty image has none. Throws UsageError for another image type or a
/// threshold outside 0..255.
void fastCorners(const cv::Mat& image, int threshold, std::vector<cv::KeyPoint>* keypoints, bool simd = true);

}  // namespace linnet
