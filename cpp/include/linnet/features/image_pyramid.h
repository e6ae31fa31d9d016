// Image pyramids for KLT: what cv::buildOpticalFlowPyramid builds without derivatives, with the halving done by
// row kernels built for AVX2 as well (OpenCV's pyrDown has only its SSE2 code in Debian's build).
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace linnet {

/// dst = src blurred by the 5 x 5 binomial kernel ([1 4 6 4 1] / 16 each way) and halved: dst(x, y) = (sum of the
/// weighted src(2x + i, 2y + j), i, j in -2..2, + 128) >> 8, src reflected without its edge pixel beyond its borders;
/// dst is ((cols + 1) / 2) x ((rows + 1) / 2). The bytes of cv::pyrDown(src, dst) with its default border. 8-bit grey
/// only; dst may be a view into a larger matrix (it is written in place when it has that size).
void pyramidDown(const cv::Mat& src, cv::Mat& dst);

/// The pyramid of cv::buildOpticalFlowPyramid(img, *pyramid, window, max_level, false, cv::BORDER_REFLECT_101,
/// cv::BORDER_CONSTANT, false), byte for byte, padding included: level l is a view with `window` pixels of reflected
/// border on each side, and the pyramid stops early where a level would be no larger than the window. Reuses
/// *pyramid's buffers when their sizes fit (as OpenCV does). Returns the number of levels above full resolution.
int buildPyramid(const cv::Mat& img, cv::Size window, int max_level, std::vector<cv::Mat>* pyramid);

/// The number of levels (full resolution included) of a buildPyramid or cv::buildOpticalFlowPyramid result, and the
/// step between two levels' images in it: 2 when each level is followed by its derivative image (OpenCV's rule).
struct PyramidLayout {
  int levels = 0;
  int step = 1;
};
PyramidLayout pyramidLayout(const std::vector<cv::Mat>& pyramid);

/// Level `level` of such a pyramid (the coarsest one when it holds fewer); the pyramid must not be empty.
const cv::Mat& pyramidLevel(const std::vector<cv::Mat>& pyramid, int level);

}  // namespace linnet
