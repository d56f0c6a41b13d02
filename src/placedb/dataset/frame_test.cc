// Image decoding: PNGs through placedb's libpng reader give OpenCV's pixels
// for every kind of PNG, and a broken one is one line of placedb's, with
// nothing of libpng's on stderr.
#include "placedb/dataset/frame.h"

#include <gtest/gtest.h>
#include <png.h>

#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

#include "placedb/util/testing.h"

namespace placedb {
namespace {

// A PNG written by libpng: any colour type, bit depth, interlacing, palette
// and transparency (cv::imencode writes only some of them).
struct PngSpec {
  int color_type;
  int bit_depth;
  bool interlaced;
  bool transparency;
};

void AppendBytes(png_structp png, png_bytep data, png_size_t n) {
  auto* out = static_cast<std::vector<uint8_t>*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + n);
}
void NoFlush(png_structp) {}

std::vector<uint8_t> WritePng(const PngSpec& spec, int width, int height, std::mt19937* rng) {
  std::vector<uint8_t> out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  png_set_write_fn(png, &out, AppendBytes, NoFlush);
  png_set_IHDR(png, info, width, height, spec.bit_depth, spec.color_type,
               spec.interlaced ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  std::vector<png_color> palette(256);
  std::vector<png_byte> alphas(256);
  for (int i = 0; i < 256; ++i) {
    palette[i] = {static_cast<png_byte>((*rng)()), static_cast<png_byte>((*rng)()),
                  static_cast<png_byte>((*rng)())};
    alphas[i] = static_cast<png_byte>((*rng)());
  }
  const int entries = 1 << std::min(spec.bit_depth, 8);
  if (spec.color_type == PNG_COLOR_TYPE_PALETTE) png_set_PLTE(png, info, palette.data(), entries);
  if (spec.transparency) {
    if (spec.color_type == PNG_COLOR_TYPE_PALETTE) {
      png_set_tRNS(png, info, alphas.data(), entries, nullptr);
    } else {
      png_color_16 key{};
      key.gray = key.red = 1;
      png_set_tRNS(png, info, nullptr, 0, &key);
    }
  }
  png_write_info(png, info);
  const size_t row_bytes = png_get_rowbytes(png, info);
  std::vector<std::vector<png_byte>> rows(height, std::vector<png_byte>(row_bytes));
  std::vector<png_bytep> pointers;
  for (auto& row : rows) {
    for (auto& b : row) b = static_cast<png_byte>((*rng)());
    // A palette index above the palette's entries is an error: keep them in.
    if (spec.color_type == PNG_COLOR_TYPE_PALETTE && spec.bit_depth == 8) {
      for (auto& b : row) b = static_cast<png_byte>(b % entries);
    }
    pointers.push_back(row.data());
  }
  png_write_image(png, pointers.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

cv::Mat Decode(const std::vector<uint8_t>& bytes) {
  const DecodedImage d = DecodeImage(bytes.data(), bytes.size(), ImageReadOptions(), "test image");
  EXPECT_TRUE(d.error.empty()) << d.error;
  return d.image;
}

TEST(PngDecodeTest, PixelsAreOpenCvsForEveryKindOfPng) {
  std::mt19937 rng(20261207);
  const std::vector<PngSpec> specs = {
      {PNG_COLOR_TYPE_GRAY, 1, false, false},       {PNG_COLOR_TYPE_GRAY, 2, true, false},
      {PNG_COLOR_TYPE_GRAY, 4, false, true},        {PNG_COLOR_TYPE_GRAY, 8, false, false},
      {PNG_COLOR_TYPE_GRAY, 8, true, true},         {PNG_COLOR_TYPE_GRAY, 16, false, false},
      {PNG_COLOR_TYPE_GRAY_ALPHA, 8, false, false}, {PNG_COLOR_TYPE_GRAY_ALPHA, 16, true, false},
      {PNG_COLOR_TYPE_RGB, 8, false, false},        {PNG_COLOR_TYPE_RGB, 8, true, true},
      {PNG_COLOR_TYPE_RGB, 16, false, false},       {PNG_COLOR_TYPE_RGB_ALPHA, 8, false, false},
      {PNG_COLOR_TYPE_RGB_ALPHA, 16, true, false},  {PNG_COLOR_TYPE_PALETTE, 1, false, false},
      {PNG_COLOR_TYPE_PALETTE, 4, true, true},      {PNG_COLOR_TYPE_PALETTE, 8, false, true},
      {PNG_COLOR_TYPE_PALETTE, 8, true, false},
  };
  for (const PngSpec& spec : specs) {
    for (const cv::Size size : {cv::Size(1, 1), cv::Size(7, 3), cv::Size(33, 17)}) {
      const std::vector<uint8_t> png = WritePng(spec, size.width, size.height, &rng);
      const cv::Mat ours = Decode(png);
      const cv::Mat opencv = cv::imdecode(png, cv::IMREAD_COLOR);
      ASSERT_FALSE(opencv.empty());
      ASSERT_EQ(ours.size(), opencv.size());
      ASSERT_EQ(ours.type(), CV_8UC3);
      EXPECT_EQ(cv::norm(ours, opencv, cv::NORM_INF), 0)
          << "colour type " << spec.color_type << ", depth " << spec.bit_depth << ", interlaced "
          << spec.interlaced << ", tRNS " << spec.transparency << ", " << size;
    }
  }
  // And what OpenCV writes (the stored images of every database).
  cv::Mat bgr(48, 64, CV_8UC3);
  cv::randu(bgr, cv::Scalar::all(0), cv::Scalar::all(255));
  std::vector<uint8_t> png;
  cv::imencode(".png", bgr, png);
  EXPECT_EQ(cv::norm(Decode(png), bgr, cv::NORM_INF), 0);
}

// Broken PNGs (cut short, a damaged byte anywhere): placedb's one line, and
// nothing on stderr from libpng.
TEST(PngDecodeTest, ABrokenPngSaysSoOnceAndLibpngSaysNothing) {
  cv::Mat bgr(48, 64, CV_8UC3);
  cv::randu(bgr, cv::Scalar::all(0), cv::Scalar::all(255));
  std::vector<uint8_t> png;
  cv::imencode(".png", bgr, png);
  std::mt19937 rng(7);
  int refused = 0;
  for (int i = 0; i < 300; ++i) {
    std::vector<uint8_t> bad = png;
    if (i % 3 == 0) {
      bad.resize(33 + rng() % (bad.size() - 33));
    } else {
      bad[33 + rng() % (bad.size() - 33)] ^= static_cast<uint8_t>(1 << (rng() % 8));
    }
    ::testing::internal::CaptureStderr();
    const DecodedImage d = DecodeImage(bad.data(), bad.size(), ImageReadOptions(), "image x.png");
    const std::string printed = ::testing::internal::GetCapturedStderr();
    EXPECT_EQ(printed, "") << i;
    if (!d.error.empty()) {
      ++refused;
      EXPECT_EQ(d.error.find('\n'), std::string::npos);
      EXPECT_EQ(d.error.rfind("cannot read image x.png: the png data cannot be decoded (", 0), 0u)
          << d.error;
    }
  }
  EXPECT_GT(refused, 200);
}

}  // namespace
}  // namespace placedb
