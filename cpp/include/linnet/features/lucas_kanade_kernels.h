// The window kernels of lucasKanade (lucas_kanade.h): a plain version and an AVX2 one that give the same bits. Exposed
// for the tests that hold the two against each other; lucasKanade picks one for the CPU.
#pragma once

#include <cstddef>
#include <cstdint>

namespace linnet::lk {

constexpr int kWeightBits = 14;                // the bilinear weights sum to 2^14
constexpr int kSampleShift = kWeightBits - 5;  // image samples keep 5 fractional bits
constexpr int kLanes = 16;                     // window rows are computed in whole multiples of 16 samples
constexpr int kMaxStride = 128;                // widest window row computed (so windows up to 127 pixels)

/// Fixed-point bilinear weights of a sub-pixel offset (w00 + w01 + w10 + w11 = 2^14).
struct Weights {
  int w00 = 1 << kWeightBits, w01 = 0, w10 = 0, w11 = 0;
};

/// The window's gradient matrix A (a11, a12, a22), before its scale of 2^-20.
struct GradientSums {
  float a11 = 0.f, a12 = 0.f, a22 = 0.f;
};

/// A window's shape: `rows` rows of which the first `width` samples count, computed `chunks` x kLanes wide (the
/// template's rows are that many samples apart).
struct WindowShape {
  int rows = 0, width = 0, chunks = 1;
};

/// Where a window lies: its top-left pixel (x, y) in the image, and the image's size (without its padding).
struct WindowPlace {
  int x = 0, y = 0, cols = 0, rows = 0;
};

/// The template: the window of an 8-bit image (its top-left pixel at img, rows img_step bytes apart) sampled at the
/// weights' offset with 5 fractional bits into t, and the image's Scharr derivatives (d/dx, d/dy: 3-10-3 smoothing
/// across, a central difference along; 0 at pixels outside the image, whose padding must be the image reflected
/// without its edge pixel, as cv::buildOpticalFlowPyramid pads) sampled the same way into gx and gy: what
/// cv::calcOpticalFlowPyrLK reads from its derivative images. Reads rows -1 .. rows + 1 and pixels -1 .. chunks x
/// kLanes + 1 around img. Returns A summed in floats in OpenCV 4.6's order (its SSE2 build): per row, the whole
/// blocks of 8 samples into four lanes (sample k, then k + 4 of a block into lane k), the rest of the row into a
/// scalar sum; at the end scalar + ((l0 + l2) + (l1 + l3)).
using TemplateKernel = GradientSums (*)(const std::uint8_t* img, std::ptrdiff_t img_step, WindowShape shape,
                                        WindowPlace place, Weights w, std::int16_t* t, std::int16_t* gx,
                                        std::int16_t* gy);

/// One iteration: the window of the next image (sampled as the template's image, reading as much) minus the template
/// t, times the template's derivatives, summed: *b1 = sum r gx, *b2 = sum r gy (unscaled), in OpenCV 4.6's order: per
/// row, each block of 8 samples adds the pair sums of samples (k, k + 4) to eight lanes (x and y interleaved, samples
/// 0-1 of the pairs in lanes 0-3, 2-3 in lanes 4-7), the rest of the row to scalar sums; at the end the scalar sum +
/// ((l0 + l4) + (l2 + l6)) for x, the same with lanes 1, 5, 3, 7 for y.
using ResidualKernel = void (*)(const std::uint8_t* img, std::ptrdiff_t img_step, WindowShape shape, Weights w,
                                const std::int16_t* t, const std::int16_t* gx, const std::int16_t* gy, float* b1,
                                float* b2);

GradientSums templatePlain(const std::uint8_t* img, std::ptrdiff_t img_step, WindowShape shape, WindowPlace place,
                           Weights w, std::int16_t* t, std::int16_t* gx, std::int16_t* gy);
void residualPlain(const std::uint8_t* img, std::ptrdiff_t img_step, WindowShape shape, Weights w,
                   const std::int16_t* t, const std::int16_t* gx, const std::int16_t* gy, float* b1, float* b2);

/// The AVX2 versions: nullptr where the build or the CPU has no AVX2.
TemplateKernel templateAvx2();
ResidualKernel residualAvx2();

}  // namespace linnet::lk
