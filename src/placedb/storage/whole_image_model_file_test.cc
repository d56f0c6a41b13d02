// The whole-image model file's reader: a saved model reads back the same;
// damaged files (random damage, and damage behind recomputed checksums, so
// that the parser itself must catch it) are refused as CorruptDatabase or
// give a model that is safe to use, never a crash.
#include "placedb/storage/whole_image_model_file.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "placedb/storage/flat_file.h"
#include "placedb/util/check.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {

using testing_util::TempDir;

// A model of 16 x 16 thumbnails (144 raw values) fitted on random rows.
WholeImageModel SmallModel(int output_dims) {
  std::mt19937 rng(7);
  std::vector<cv::Mat> raw;
  for (int i = 0; i < 12; ++i) {
    cv::Mat row(1, HogRawDims(16, 16), CV_8U);
    for (int j = 0; j < row.cols; ++j) row.at<uint8_t>(0, j) = static_cast<uint8_t>(rng() % 256);
    raw.push_back(row);
  }
  return WholeImageModel::Fit(raw, 16, 16, output_dims);
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::shared_ptr<const WholeImageModel> ReadBytesAsModel(const TempDir& dir,
                                                        const std::string& bytes) {
  const std::string path = dir.Write("model.bin", bytes);
  return ReadWholeImageModel(MappedFile::Open(path), "model.bin");
}

TEST(WholeImageModelFileTest, SavedModelReadsBackTheSame) {
  TempDir dir;
  const WholeImageModel model = SmallModel(8);
  SaveWholeImageModel(model, dir.Path("model.bin"));
  const auto back = ReadWholeImageModel(MappedFile::Open(dir.Path("model.bin")), "model.bin");
  EXPECT_EQ(back->width(), 16);
  EXPECT_EQ(back->height(), 16);
  EXPECT_EQ(back->input_dims(), 144);
  EXPECT_EQ(back->output_dims(), 8);
  EXPECT_EQ(back->mean(), model.mean());
  EXPECT_EQ(back->projection(), model.projection());
  cv::Mat raw(1, 144, CV_8U, cv::Scalar(40));
  EXPECT_EQ(cv::norm(back->Project(raw), model.Project(raw), cv::NORM_INF), 0);
  // The file is what the header promises: no byte more.
  const std::string bytes = ReadBytes(dir.Path("model.bin"));
  EXPECT_TRUE(testing_util::ThrowsWith<CorruptDatabase>(
      [&] { ReadBytesAsModel(dir, bytes + std::string(64, '\0')); }, "model.bin"));
  EXPECT_TRUE(testing_util::ThrowsWith<CorruptDatabase>(
      [&] { ReadBytesAsModel(dir, bytes.substr(0, bytes.size() - 64)); }, "model.bin"));
  EXPECT_TRUE(testing_util::ThrowsWith<CorruptDatabase>(
      [&] { ReadBytesAsModel(dir, bytes.substr(0, 100)); }, "model.bin"));
  EXPECT_TRUE(
      testing_util::ThrowsWith<CorruptDatabase>([&] { ReadBytesAsModel(dir, ""); }, "model.bin"));
}

// Each header field set to a value the reader must refuse, behind valid
// checksums, says what is wrong.
TEST(WholeImageModelFileTest, BadHeaderFieldsAreNamed) {
  TempDir dir;
  SaveWholeImageModel(SmallModel(8), dir.Path("model.bin"));
  const std::string bytes = ReadBytes(dir.Path("model.bin"));
  auto refused = [&](uint64_t offset, uint32_t value, const std::string& says) {
    std::string bad = flat_file::Patched(bytes, offset, value);
    flat_file::Reseal(&bad);
    return testing_util::ThrowsWith<CorruptDatabase>([&] { ReadBytesAsModel(dir, bad); }, says);
  };
  EXPECT_TRUE(refused(32, 20, "thumbnails of 20 x 16"));
  EXPECT_TRUE(refused(36, 0, "thumbnails of 16 x 0"));
  EXPECT_TRUE(refused(32, 24, "input values"));  // 24 x 16 has 288
  EXPECT_TRUE(refused(40, 145, "145 input values"));
  EXPECT_TRUE(refused(44, 0, "0 output values"));
  EXPECT_TRUE(refused(44, 5000, "5000 output values"));
  EXPECT_TRUE(refused(44, 9, "size does not fit"));
  EXPECT_TRUE(refused(48, 1, "reserved"));
  // A value that is not finite.
  std::string nan = bytes;
  const float v = std::nanf("");
  std::memcpy(&nan[128], &v, sizeof(v));
  flat_file::Reseal(&nan);
  EXPECT_TRUE(
      testing_util::ThrowsWith<CorruptDatabase>([&] { ReadBytesAsModel(dir, nan); }, "finite"));
}

// Random damage: bit flips, runs of random bytes, interesting 4-byte values,
// truncation and growth, half the time behind recomputed checksums. Every
// file is refused as CorruptDatabase or reads as a model whose projection
// of any raw row is a row of output_dims values.
TEST(WholeImageModelFileTest, MutatedFilesNeverCrash) {
  TempDir dir;
  SaveWholeImageModel(SmallModel(8), dir.Path("model.bin"));
  const std::string bytes = ReadBytes(dir.Path("model.bin"));
  std::mt19937_64 rng(20261207);
  const uint32_t interesting[] = {0,   1,   7,    8,    15,         16,         128,
                                  136, 144, 4096, 4097, 0x7fffffff, 0x80000000, 0xffffffff};
  int loaded = 0, rejected = 0;
  for (int i = 0; i < 3000; ++i) {
    std::string bad = bytes;
    const int kind = static_cast<int>(rng() % 4);
    // Mostly the header, now and then anywhere.
    const size_t span = rng() % 3 == 0 ? bad.size() : 128;
    if (kind == 0) {
      for (int f = 0, n = 1 + static_cast<int>(rng() % 4); f < n; ++f) {
        bad[rng() % span] ^= static_cast<char>(1 << (rng() % 8));
      }
    } else if (kind == 1) {
      const size_t at = rng() % span, n = 1 + rng() % 16;
      for (size_t j = at; j < std::min(bad.size(), at + n); ++j) bad[j] = static_cast<char>(rng());
    } else if (kind == 2) {
      const size_t at = (rng() % (span / 4)) * 4;
      const uint32_t value = interesting[rng() % (sizeof(interesting) / sizeof(uint32_t))];
      std::memcpy(&bad[at], &value, sizeof(value));
    } else if (rng() % 2) {
      bad.resize(rng() % bad.size());
    } else {
      bad.append(1 + rng() % 200, static_cast<char>(rng()));
    }
    if (rng() % 2) flat_file::Reseal(&bad);
    try {
      const auto model = ReadBytesAsModel(dir, bad);
      const cv::Mat row = model->Project(cv::Mat(1, model->input_dims(), CV_8U, cv::Scalar(90)));
      ASSERT_EQ(row.cols, model->output_dims());
      ASSERT_EQ(row.type(), CV_8SC1);
      ++loaded;
    } catch (const CorruptDatabase&) {
      ++rejected;
    }
  }
  // Both outcomes happen: damage to the values behind valid checksums reads.
  EXPECT_GT(loaded, 0);
  EXPECT_GT(rejected, 2000);
}

}  // namespace
}  // namespace placedb
