// The direct greyscale PNG decoder against OpenCV's, on encoded images of every kind it handles or hands back.
#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "linnet/io/png_gray.h"

namespace linnet {
namespace {

cv::Mat noiseImage(int rows, int cols, int type, unsigned seed) {
  cv::Mat m(rows, cols, type);
  cv::RNG rng(seed);
  rng.fill(m, cv::RNG::UNIFORM, 0, type == CV_16UC1 ? 65535 : 255);
  // Some structure as well, so that the encoder's filters and matches are exercised.
  for (int y = 0; y < rows; y += 7) m.row(y).setTo(cv::Scalar::all(y % 256));
  return m;
}

std::vector<unsigned char> encode(const cv::Mat& m, std::vector<int> params = {}) {
  std::vector<unsigned char> bytes;
  EXPECT_TRUE(cv::imencode(".png", m, bytes, params));
  return bytes;
}

PngGrayResult decode(const std::vector<unsigned char>& bytes, cv::Mat* out, std::string* error) {
  return decodeGray8Png(bytes.data(), bytes.size(), out, error);
}

TEST(PngGray, GivesOpenCvsPixelsOnGreyscaleImages) {
  for (int level : {0, 1, 3, 9}) {
    for (const cv::Size size : {cv::Size(752, 480), cv::Size(1, 1), cv::Size(33, 17)}) {
      const cv::Mat img = noiseImage(size.height, size.width, CV_8UC1, 11u + static_cast<unsigned>(level));
      const std::vector<unsigned char> bytes = encode(img, {cv::IMWRITE_PNG_COMPRESSION, level});
      cv::Mat ours;
      std::string error;
      ASSERT_EQ(decode(bytes, &ours, &error), PngGrayResult::kDecoded) << error;
      const cv::Mat theirs = cv::imdecode(bytes, cv::IMREAD_GRAYSCALE);
      ASSERT_EQ(ours.type(), CV_8UC1);
      ASSERT_EQ(ours.size(), theirs.size());
      EXPECT_EQ(cv::norm(ours, theirs, cv::NORM_INF), 0.0) << "level " << level << ", " << size;
      EXPECT_EQ(cv::norm(ours, img, cv::NORM_INF), 0.0);
    }
  }
}

TEST(PngGray, HandsOtherKindsBack) {
  cv::Mat out;
  std::string error;
  EXPECT_EQ(decode(encode(noiseImage(20, 30, CV_16UC1, 1)), &out, &error), PngGrayResult::kNotHandled);
  EXPECT_EQ(decode(encode(noiseImage(20, 30, CV_8UC3, 2)), &out, &error), PngGrayResult::kNotHandled);
  std::vector<unsigned char> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", noiseImage(20, 30, CV_8UC1, 3), jpeg));
  EXPECT_EQ(decode(jpeg, &out, &error), PngGrayResult::kNotHandled);
  EXPECT_EQ(decodeGray8Png(jpeg.data(), 0, &out, &error), PngGrayResult::kNotHandled);
  EXPECT_TRUE(out.empty());
}

TEST(PngGray, ReportsBrokenFiles) {
  const std::vector<unsigned char> good = encode(noiseImage(64, 64, CV_8UC1, 4));
  cv::Mat out;
  std::string error;
  // Cut inside the image data.
  std::vector<unsigned char> cut(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(good.size() / 2));
  EXPECT_EQ(decode(cut, &out, &error), PngGrayResult::kCorrupt);
  EXPECT_FALSE(error.empty());
  // Cut inside the header.
  error.clear();
  std::vector<unsigned char> header(good.begin(), good.begin() + 20);
  EXPECT_EQ(decode(header, &out, &error), PngGrayResult::kCorrupt);
  EXPECT_FALSE(error.empty());
  // The signature followed by garbage.
  error.clear();
  std::vector<unsigned char> garbage(good.begin(), good.begin() + 8);
  for (int k = 0; k < 200; ++k) garbage.push_back(static_cast<unsigned char>(k * 37));
  EXPECT_EQ(decode(garbage, &out, &error), PngGrayResult::kCorrupt);
  EXPECT_FALSE(error.empty());
  EXPECT_TRUE(out.empty());
}

TEST(PngGray, RejectsSizesTheFileCannotHold) {
  // A valid header claiming 65535 x 65535 pixels, then the start of a small image's data: refused before any
  // allocation of 4 GB.
  std::vector<unsigned char> png = encode(noiseImage(8, 8, CV_8UC1, 5));
  const auto put32 = [&](std::size_t at, std::uint32_t v) {
    for (int k = 0; k < 4; ++k) png[at + static_cast<std::size_t>(k)] = static_cast<unsigned char>(v >> (24 - 8 * k));
  };
  put32(16, 65535);  // IHDR width (the CRC is not checked)
  put32(20, 65535);  // IHDR height
  cv::Mat out;
  std::string error;
  EXPECT_EQ(decode(png, &out, &error), PngGrayResult::kCorrupt);
  EXPECT_NE(error.find("65535 x 65535"), std::string::npos) << error;
  put32(16, 2000);  // 2000 x 2000 from a file of a hundred-odd bytes: more than deflate can pack into it
  put32(20, 2000);
  error.clear();
  EXPECT_EQ(decode(png, &out, &error), PngGrayResult::kCorrupt);
  EXPECT_NE(error.find("needs more data"), std::string::npos) << error;
}

}  // namespace
}  // namespace linnet
