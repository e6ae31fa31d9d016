// 8-bit greyscale PNG decoding straight through libpng (see png_gray.h).
#include "linnet/io/png_gray.h"

#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <vector>

#include <png.h>

namespace linnet {
namespace {

// libpng reports errors by longjmp. The functions that call it hold only trivially destructible locals, so that the
// jump skips no destructor; everything with a destructor lives in decodeGray8Png, outside the jumps.
struct PngSource {
  const unsigned char* data = nullptr;
  std::size_t size = 0, pos = 0;
  char message[160] = {0};
};

void readFromMemory(png_structp png, png_bytep out, std::size_t n) {
  auto* src = static_cast<PngSource*>(png_get_io_ptr(png));
  if (n > src->size - src->pos) png_error(png, "file ends inside the image data");
  std::memcpy(out, src->data + src->pos, n);
  src->pos += n;
}

void onError(png_structp png, png_const_charp message) {
  auto* src = static_cast<PngSource*>(png_get_error_ptr(png));
  std::snprintf(src->message, sizeof(src->message), "%s", message);
  png_longjmp(png, 1);
}

void onWarning(png_structp, png_const_charp) {}

struct Header {
  png_uint_32 width = 0, height = 0;
  int bit_depth = 0, color_type = 0, interlace = 0;
  bool transparency = false;
};

// Reads the chunks before the image data. Returns false on a libpng error (message in the source).
bool readHeader(png_structp png, png_infop info, Header* h) {
  if (setjmp(png_jmpbuf(png))) return false;
  // The checksums are what this decoder saves: CRC errors are neither reported nor acted on, and inflate does not
  // compute the Adler-32 of the image data.
  png_set_crc_action(png, PNG_CRC_QUIET_USE, PNG_CRC_QUIET_USE);
#ifdef PNG_IGNORE_ADLER32
  png_set_option(png, PNG_IGNORE_ADLER32, PNG_OPTION_ON);
#endif
  png_read_info(png, info);
  int compression = 0, filter = 0;
  png_get_IHDR(png, info, &h->width, &h->height, &h->bit_depth, &h->color_type, &h->interlace, &compression, &filter);
  h->transparency = png_get_valid(png, info, PNG_INFO_tRNS) != 0;
  return true;
}

bool readRows(png_structp png, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_image(png, rows);
  return true;
}

struct PngReader {
  png_structp png = nullptr;
  png_infop info = nullptr;
  ~PngReader() { png_destroy_read_struct(&png, info != nullptr ? &info : nullptr, nullptr); }
};

}  // namespace

PngGrayResult decodeGray8Png(const unsigned char* data, std::size_t size, cv::Mat* image, std::string* error) {
  if (size < 8 || png_sig_cmp(data, 0, 8) != 0) return PngGrayResult::kNotHandled;
  PngSource src;
  src.data = data;
  src.size = size;
  src.pos = 8;
  PngReader r;
  r.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &src, onError, onWarning);
  if (r.png == nullptr) return PngGrayResult::kNotHandled;
  r.info = png_create_info_struct(r.png);
  if (r.info == nullptr) return PngGrayResult::kNotHandled;
  png_set_read_fn(r.png, &src, readFromMemory);
  png_set_sig_bytes(r.png, 8);
  Header h;
  if (!readHeader(r.png, r.info, &h)) {
    *error = src.message;
    return PngGrayResult::kCorrupt;
  }
  if (h.bit_depth != 8 || h.color_type != PNG_COLOR_TYPE_GRAY || h.interlace != PNG_INTERLACE_NONE || h.transparency)
    return PngGrayResult::kNotHandled;
  // Sizes checked before the allocation: at most 2^30 pixels (OpenCV's decoders' default bound), and no more than
  // deflate can have packed into this file (at most 1032 bytes out per byte in, each row one filter byte longer).
  const double pixels = static_cast<double>(h.width) * static_cast<double>(h.height);
  const double packed = (static_cast<double>(h.width) + 1.0) * static_cast<double>(h.height);
  if (h.width == 0 || h.height == 0 || h.width > (1u << 20) || h.height > (1u << 20) || pixels > 1073741824.0) {
    *error = "image size " + std::to_string(h.width) + " x " + std::to_string(h.height) + " out of range";
    return PngGrayResult::kCorrupt;
  }
  if (packed > 1032.0 * static_cast<double>(size)) {
    *error = "image size " + std::to_string(h.width) + " x " + std::to_string(h.height) + " needs more data than the " +
             std::to_string(size) + " bytes of the file";
    return PngGrayResult::kCorrupt;
  }
  cv::Mat out(static_cast<int>(h.height), static_cast<int>(h.width), CV_8UC1);
  std::vector<png_bytep> rows(h.height);
  for (int y = 0; y < out.rows; ++y) rows[static_cast<std::size_t>(y)] = out.ptr<png_byte>(y);
  if (!readRows(r.png, rows.data())) {
    *error = src.message;
    return PngGrayResult::kCorrupt;
  }
  *image = std::move(out);
  return PngGrayResult::kDecoded;
}

}  // namespace linnet
