#pragma once
// A direct libpng decoder for the one image kind that dataset replays are made of: 8-bit greyscale, not
// interlaced, no transparency. It gives the same pixels as cv::imdecode(..., IMREAD_GRAYSCALE) on such files but skips
// the chunk CRCs and the zlib stream's Adler-32 checksum, which took about half of the decoding time (a third of it
// is inflate itself). Damage to the compressed stream's structure (truncation, a broken header, bad deflate codes,
// too little image data) is still an error; a flipped bit inside the pixel data is not noticed.
#include <cstddef>
#include <string>

#include <opencv2/core/mat.hpp>

namespace linnet {

enum class PngGrayResult {
  kDecoded,       // *image holds the pixels (CV_8UC1)
  kNotHandled,    // not an 8-bit greyscale, non-interlaced PNG without transparency: decode it some other way
  kCorrupt,       // a PNG that libpng could not read; *error says why
};

/// Decodes data[0, size) into *image when it is an 8-bit greyscale PNG (see above).
PngGrayResult decodeGray8Png(const unsigned char* data, std::size_t size, cv::Mat* image, std::string* error);

}  // namespace linnet
