#include "placedb/storage/database.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <thread>

#include "placedb/feature/extractor.h"
#include "placedb/feature/testing.h"
#include "placedb/feature/whole_image.h"
#include "placedb/match/ratio_matcher.h"
#include "placedb/query/query.h"
#include "placedb/storage/compact_keypoint.h"
#include "placedb/storage/keyframe_file.h"
#include "placedb/util/checksum.h"
#include "placedb/util/file_io.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
using testing_util::TempDir;
using testing_util::ThrowsWith;
namespace fs = std::filesystem;
using testing_util::RtabmapImage;

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

// A database of `n` real images (ids 1..n): each keyframe a crop of the
// image resized to half size, features extracted on the stored image. Odd
// ids get a pose when `with_poses`. With the options' whole-image channel
// (the default: 768 values per keyframe).
Database MakeDatabase(const ExtractorOptions& options, int n, bool with_poses) {
  const auto extractor = FeatureExtractor::Create(options);
  const int bytes = options.type == FeatureType::kOrb ? 32 : (options.surf.extended ? 128 : 64) * 4;
  Database db(options.type, bytes, WholeImageDims(options));
  for (int i = 1; i <= n; ++i) {
    const cv::Mat image = cv::imread(RtabmapImage(i));
    EXPECT_FALSE(image.empty());
    Keyframe k;
    k.id = i * 10;  // ids need not be positions
    k.timestamp = with_poses ? 100.0 + 0.25 * i : -1.0;
    k.crop = cv::Rect(8 * i, 4 * i, 320, 240);
    k.crop_channel = i % 3;
    k.original_size = image.size();
    cv::Mat stored;
    cv::resize(image(k.crop), stored, cv::Size(160, 120), 0, 0, cv::INTER_AREA);
    k.stored_size = stored.size();
    k.scale = 0.5;
    k.source = RtabmapImage(i);
    k.source_hash = i == 3 ? 0 : 0x8000000000000000ull + 77 * i;          // 0: not recorded
    k.image_file = i == 2 ? "" : "images/" + std::to_string(i) + ".png";  // one without image
    if (with_poses && i % 2 == 1) {
      Pose pose;
      pose.translation = Eigen::Vector3d(0.1 * i, -2.5, 3.0 + i);
      pose.rotation =
          Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d(1, 2, 3).normalized()));
      k.pose = pose;
    }
    db.AddKeyframe(k, extractor->Extract(stored));
  }
  db.info()["settings"] = {{"crop", "chroma"}, {"resize", 4}};
  db.info()["source"] = "database_test";
  db.info()["counts"]["frames"] = n;
  return db;
}

void ExpectKeyframesEqual(const Keyframe& a, const Keyframe& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.timestamp, b.timestamp);
  EXPECT_EQ(a.crop, b.crop);
  EXPECT_EQ(a.crop_channel, b.crop_channel);
  EXPECT_EQ(a.original_size, b.original_size);
  EXPECT_EQ(a.stored_size, b.stored_size);
  EXPECT_EQ(a.scale, b.scale);
  EXPECT_EQ(a.source, b.source);
  EXPECT_EQ(a.image_file, b.image_file);
  EXPECT_EQ(a.source_hash, b.source_hash);
  ASSERT_EQ(a.pose.has_value(), b.pose.has_value()) << "keyframe " << a.id;
  if (a.pose) {
    EXPECT_EQ(a.pose->translation, b.pose->translation);
    EXPECT_EQ(a.pose->rotation.coeffs(), b.pose->rotation.coeffs());
  }
}

// Opens a database and checks every byte of it: a version 3 file checks a
// keyframe's features on first use, and this uses them all (VerifyAll).
Database LoadVerified(const std::string& dir, const KeyframeSubset& subset = KeyframeSubset()) {
  Database db = Database::Load(dir, subset);
  db.VerifyAll();
  return db;
}

void ExpectDatabasesEqual(const Database& a, const Database& b) {
  EXPECT_EQ(a.feature_type(), b.feature_type());
  EXPECT_EQ(a.descriptor_bytes(), b.descriptor_bytes());
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.num_features(), b.num_features());
  for (size_t i = 0; i < a.size(); ++i) {
    ExpectKeyframesEqual(a.keyframe(i), b.keyframe(i));
    ASSERT_EQ(a.FeatureCount(i), b.FeatureCount(i));
    testing_util::ExpectSameKeypoints(a.Keypoints(i), b.Keypoints(i));
    const DescriptorBlock da = a.Descriptors(i), dbk = b.Descriptors(i);
    EXPECT_EQ(da.type, dbk.type);
    ASSERT_EQ(da.rows, dbk.rows);
    ASSERT_EQ(da.row_bytes, dbk.row_bytes);
    if (da.rows > 0) {
      EXPECT_EQ(0, std::memcmp(da.data, dbk.data, static_cast<size_t>(da.rows) * da.row_bytes));
    }
    EXPECT_EQ(da.positive_rows, dbk.positive_rows);
  }
  ASSERT_EQ(a.whole_image_dims(), b.whole_image_dims());
  if (a.whole_image_dims() > 0 && a.size() > 0) {
    EXPECT_EQ(0, std::memcmp(a.WholeImageData(), b.WholeImageData(),
                             a.size() * static_cast<size_t>(a.whole_image_dims())));
  } else if (a.whole_image_dims() == 0) {
    EXPECT_EQ(b.WholeImageData(), nullptr);
  }
}

// Every key the builder put in info() comes back with the same value (Save
// adds its own keys: format, counts, files...).
void ExpectInfoPreserved(const nlohmann::json& original, const nlohmann::json& loaded) {
  for (const auto& [key, value] : original.items()) {
    ASSERT_TRUE(loaded.contains(key)) << key;
    if (key == "counts") {
      for (const auto& [k, v] : value.items()) EXPECT_EQ(loaded["counts"][k], v) << k;
    } else {
      EXPECT_EQ(loaded[key], value) << key;
    }
  }
}

void RoundTrip(const ExtractorOptions& options, bool with_poses) {
  TempDir tmp;
  const Database db = MakeDatabase(options, 3, with_poses);
  ASSERT_EQ(db.size(), 3u);
  EXPECT_GT(db.num_features(), 30u);  // real features, not an empty database
  for (size_t i = 0; i < db.size(); ++i) EXPECT_GT(db.FeatureCount(i), 10u) << i;
  db.Save(tmp.Path());
  EXPECT_TRUE(fs::exists(tmp.Path("manifest.json")));
  const Database loaded = LoadVerified(tmp.Path());
  ExpectDatabasesEqual(db, loaded);
  ExpectInfoPreserved(db.info(), loaded.info());
  // Features read from the file (LoadOptions::read_features), not mapped:
  // the same keypoints and rows, in the caller's buffer, checked as read.
  LoadOptions read;
  read.read_features = true;
  const Database reader = Database::Load(tmp.Path(), read);
  EXPECT_TRUE(reader.reads_features());
  EXPECT_FALSE(loaded.reads_features());
  std::vector<uint8_t> buffer;
  for (size_t i = 0; i < db.size(); ++i) {
    EXPECT_FALSE(reader.FeaturesChecked(i));
    const DescriptorBlock r = reader.Descriptors(i, &buffer), e = db.Descriptors(i);
    EXPECT_TRUE(reader.FeaturesChecked(i));
    EXPECT_EQ(r.data, buffer.data());
    EXPECT_EQ(r.type, e.type);
    ASSERT_EQ(r.rows, e.rows);
    ASSERT_EQ(r.row_bytes, e.row_bytes);
    EXPECT_EQ(r.positive_rows, e.positive_rows);
    EXPECT_EQ(0, std::memcmp(r.data, e.data, static_cast<size_t>(r.rows) * r.row_bytes));
    testing_util::ExpectSameKeypoints(reader.Keypoints(i), db.Keypoints(i));
  }
  // The size decides (LoadOptions::read_features_above_bytes): a file
  // larger than the threshold is read, one of the threshold's size is not.
  const uint64_t file_bytes = FileSize(tmp.Path(loaded.keyframes_file()));
  LoadOptions by_size;
  by_size.read_features_above_bytes = file_bytes - 1;
  EXPECT_TRUE(Database::Load(tmp.Path(), by_size).reads_features());
  by_size.read_features_above_bytes = file_bytes;
  EXPECT_FALSE(Database::Load(tmp.Path(), by_size).reads_features());
  // Without the option, the buffer is not used: the rows are the mapping's.
  std::vector<uint8_t> unused;
  EXPECT_EQ(loaded.Descriptors(0, &unused).data, loaded.Descriptors(0).data);
  EXPECT_TRUE(unused.empty());
  EXPECT_EQ(loaded.info()["format"], "placedb-database");
  EXPECT_EQ(loaded.info()["format_version"], kDatabaseFormatVersion);
  EXPECT_EQ(loaded.info()["feature_type"], FeatureTypeName(options.type));
  EXPECT_EQ(loaded.info()["counts"]["keyframes"], 3u);
  EXPECT_EQ(loaded.info()["counts"]["features"], db.num_features());
  const std::string bin_name = loaded.keyframes_file();
  EXPECT_TRUE(Database::IsKeyframesFileName(bin_name)) << bin_name;
  EXPECT_EQ(loaded.info()["files"]["keyframes"], bin_name);
  EXPECT_EQ(loaded.info()["files"]["keyframes_bytes"], FileSize(tmp.Path(bin_name)));
  EXPECT_EQ(loaded.keyframes_bytes(), FileSize(tmp.Path(bin_name)));
  EXPECT_EQ(loaded.IndexOfId(20), 1);
  EXPECT_EQ(loaded.IndexOfId(2), -1);
  EXPECT_EQ(loaded.keyframe(0).pose.has_value(), with_poses);
  EXPECT_FALSE(loaded.keyframe(1).pose.has_value());

  // Saving the loaded database again gives the same bytes and manifest.
  const std::string bin1 = ReadFileToString(tmp.Path(bin_name));
  const std::string dir2 = tmp.Path("again");
  fs::create_directories(dir2);
  EXPECT_EQ(loaded.Save(dir2).keyframes_file, bin_name);  // named by its content
  EXPECT_EQ(ReadFileToString(dir2 + "/" + bin_name), bin1);
  const Database loaded2 = LoadVerified(dir2);
  ExpectDatabasesEqual(db, loaded2);
  EXPECT_EQ(loaded2.info(), loaded.info());
}

TEST(DatabaseTest, RoundTripOrbWithPoses) { RoundTrip(testing::ModelFreeExtractorOptions(), /*with_poses=*/true); }

TEST(DatabaseTest, RoundTripOrbWithoutPoses) {
  RoundTrip(testing::ModelFreeExtractorOptions(), /*with_poses=*/false);
}

TEST(DatabaseTest, RoundTripSurf) {
  ExtractorOptions options = testing::ModelFreeExtractorOptions();
  options.type = FeatureType::kSurf;
  options.surf.max_features = 200;
  RoundTrip(options, /*with_poses=*/true);
  // Laplacian signs come back and both signs are present.
  TempDir tmp;
  const Database db = MakeDatabase(options, 1, false);
  EXPECT_EQ(db.descriptor_bytes(), 256);
  db.Save(tmp.Path());
  const Database loaded = LoadVerified(tmp.Path());
  EXPECT_EQ(loaded.feature_type(), FeatureType::kSurf);
  // Rows grouped by sign: the first positive_rows have class_id >= 0.
  const DescriptorBlock block = loaded.Descriptors(0);
  const std::vector<cv::KeyPoint> kp = loaded.Keypoints(0);
  EXPECT_GT(block.positive_rows, 0);
  EXPECT_LT(block.positive_rows, block.rows);
  for (int r = 0; r < block.rows; ++r) EXPECT_EQ(kp[r].class_id >= 0, r < block.positive_rows) << r;
}

TEST(DatabaseTest, LoadedDatabaseGrowsAndOutlivesItsFiles) {
  // A loaded database uses its descriptors in place in the mapped file; the
  // first added keyframe copies them, and a rebuild replacing the files on
  // disk does not disturb a database already open.
  TempDir tmp;
  const Database three = MakeDatabase(testing::ModelFreeExtractorOptions(), 3, true);
  three.Save(tmp.Path());
  Database loaded = LoadVerified(tmp.Path());
  MakeDatabase(testing::ModelFreeExtractorOptions(), 1, false).Save(tmp.Path());  // files replaced
  ExpectDatabasesEqual(three, loaded);

  const Database four = MakeDatabase(testing::ModelFreeExtractorOptions(), 4, true);
  FeatureSet extra;
  extra.type = FeatureType::kOrb;
  extra.keypoints = four.Keypoints(3);
  const DescriptorBlock block = four.Descriptors(3);
  extra.descriptors = cv::Mat(block.rows, 32, CV_8U, const_cast<uint8_t*>(block.data)).clone();
  extra.whole_image = four.Features(3).whole_image;
  loaded.AddKeyframe(four.keyframe(3), extra);
  loaded.info() = four.info();
  ExpectDatabasesEqual(four, loaded);
  TempDir again;
  loaded.Save(again.Path());
  ExpectDatabasesEqual(four, LoadVerified(again.Path()));
}

TEST(DatabaseTest, EmptyDatabaseRoundTrip) {
  TempDir tmp;
  Database db(FeatureType::kOrb, 32);
  db.Save(tmp.Path());
  const Database loaded = LoadVerified(tmp.Path());
  EXPECT_TRUE(loaded.empty());
  EXPECT_EQ(loaded.num_features(), 0u);
  EXPECT_EQ(loaded.feature_type(), FeatureType::kOrb);
  EXPECT_EQ(loaded.whole_image_dims(), 0);
  // With a whole-image channel and no rows: the section is its preamble.
  TempDir with;
  Database channel(FeatureType::kOrb, 32, 768);
  channel.Save(with.Path());
  const Database back = LoadVerified(with.Path());
  EXPECT_TRUE(back.empty());
  EXPECT_EQ(back.whole_image_dims(), 768);
}

TEST(DatabaseTest, KeyframeToOriginal) {
  Keyframe k;
  k.crop = cv::Rect(100, 50, 200, 160);
  k.scale = 0.5;
  const cv::Point2f p = k.ToOriginal({10.f, 20.f});
  EXPECT_FLOAT_EQ(p.x, 120.f);
  EXPECT_FLOAT_EQ(p.y, 90.f);
  const cv::Point2f origin = k.ToOriginal({0.f, 0.f});
  EXPECT_FLOAT_EQ(origin.x, 100.f);
  EXPECT_FLOAT_EQ(origin.y, 50.f);
  k.scale = 0.25;
  const cv::Point2f far = k.ToOriginal({50.f, 40.f});  // stored corner -> crop corner
  EXPECT_FLOAT_EQ(far.x, 300.f);
  EXPECT_FLOAT_EQ(far.y, 210.f);
  Keyframe whole;  // no crop, scale 1: identity
  const cv::Point2f same = whole.ToOriginal({33.5f, 7.25f});
  EXPECT_FLOAT_EQ(same.x, 33.5f);
  EXPECT_FLOAT_EQ(same.y, 7.25f);
}

// A subset opened from the file holds exactly those keyframes, with the same
// records, keypoints, descriptors and Laplacian signs as the whole file has
// for them; the others are not there. Partitions of every scheme cover the
// file once.
void ExpectSubsetOf(const Database& whole, const Database& part) {
  for (size_t i = 0; i < part.size(); ++i) {
    const int w = whole.IndexOfId(part.keyframe(i).id);
    ASSERT_GE(w, 0);
    ExpectKeyframesEqual(whole.keyframe(w), part.keyframe(i));
    testing_util::ExpectSameKeypoints(whole.Keypoints(w), part.Keypoints(i));
    const DescriptorBlock a = whole.Descriptors(w), b = part.Descriptors(i);
    ASSERT_EQ(a.rows, b.rows);
    if (a.rows > 0) {
      EXPECT_EQ(0, std::memcmp(a.data, b.data, static_cast<size_t>(a.rows) * a.row_bytes));
    }
    EXPECT_EQ(a.positive_rows, b.positive_rows);
    ASSERT_EQ(whole.whole_image_dims(), part.whole_image_dims());
    if (whole.whole_image_dims() > 0) {
      EXPECT_EQ(0, std::memcmp(whole.WholeImage(w), part.WholeImage(i),
                               static_cast<size_t>(whole.whole_image_dims())));
    }
  }
}

TEST(DatabaseTest, SubsetsOpenOnlyTheirKeyframes) {
  ExtractorOptions surf = testing::ModelFreeExtractorOptions();
  surf.type = FeatureType::kSurf;
  surf.surf.max_features = 60;
  for (const ExtractorOptions& options : {testing::ModelFreeExtractorOptions(), surf}) {
    TempDir tmp;
    MakeDatabase(options, 7, true).Save(tmp.Path());
    const Database whole = LoadVerified(tmp.Path());
    ASSERT_EQ(whole.size(), 7u);
    for (const PartitionScheme scheme :
         {PartitionScheme::kContiguous, PartitionScheme::kInterleaved}) {
      for (int parts : {1, 2, 3, 7, 9}) {
        size_t keyframes = 0, features = 0;
        for (int p = 0; p < parts; ++p) {
          const Database part =
              LoadVerified(tmp.Path(), KeyframeSubset::Partition(p, parts, scheme));
          EXPECT_EQ(part.keyframes_in_file(), 7u);
          ExpectSubsetOf(whole, part);
          for (size_t i = 0; i < part.size(); ++i) {
            EXPECT_TRUE(InPartition(whole.IndexOfId(part.keyframe(i).id), 7, p, parts, scheme));
          }
          keyframes += part.size();
          features += part.num_features();
        }
        EXPECT_EQ(keyframes, 7u) << parts << " parts";
        EXPECT_EQ(features, whole.num_features());
      }
    }
    // Contiguous partition 1 of 3 of 7 keyframes: indices [7/3, 14/3) = 2, 3
    // (ids 30, 40).
    const Database middle = LoadVerified(tmp.Path(), KeyframeSubset::Partition(1, 3));
    ASSERT_EQ(middle.size(), 2u);
    EXPECT_EQ(middle.keyframe(0).id, 30);
    EXPECT_EQ(middle.keyframe(1).id, 40);
    // An id list, in any order, duplicates ignored.
    const Database ids = LoadVerified(tmp.Path(), KeyframeSubset::Ids({60, 10, 60}));
    ASSERT_EQ(ids.size(), 2u);
    EXPECT_EQ(ids.keyframe(0).id, 10);
    EXPECT_EQ(ids.keyframe(1).id, 60);
    EXPECT_EQ(ids.IndexOfId(60), 1);
    EXPECT_EQ(ids.IndexOfId(20), -1);
    ExpectSubsetOf(whole, ids);
    EXPECT_TRUE(ThrowsWith<InvalidArgument>(
        [&] {
          LoadVerified(tmp.Path(), KeyframeSubset::Ids({10, 15}));
        },
        "keyframe id 15 is not in the database"));
    EXPECT_TRUE(ThrowsWith<InvalidArgument>(
        [&] { LoadVerified(tmp.Path(), KeyframeSubset::Partition(3, 3)); }, "part must be in"));
    // A subset saved is a database of that subset; it grows like any other.
    TempDir saved;
    Database copy = ids;
    copy.Save(saved.Path());
    const Database reloaded = LoadVerified(saved.Path());
    ExpectDatabasesEqual(ids, reloaded);
    FeatureSet extra;
    extra.type = options.type;
    extra.keypoints = whole.Keypoints(3);
    const DescriptorBlock block = whole.Descriptors(3);
    extra.descriptors =
        options.type == FeatureType::kOrb
            ? cv::Mat(block.rows, 32, CV_8U, const_cast<uint8_t*>(block.data)).clone()
            : cv::Mat(block.rows, 64, CV_32F, const_cast<uint8_t*>(block.data)).clone();
    extra.whole_image = whole.Features(3).whole_image;
    copy.AddKeyframe(whole.keyframe(3), extra);  // copy on write of a mapped subset
    ASSERT_EQ(copy.size(), 3u);
    ExpectSubsetOf(whole, copy);
  }
}

// A saved 3-keyframe ORB database each corruption test starts from, and
// ways to damage it: raw (the checksums catch it) or resealed (checksums
// recomputed and the manifest updated, so the parser itself must catch it).

// Offset of section `kind` in the bytes of a keyframe file (its section
// table), or 0 with a test failure when there is none.
uint64_t SectionOffsetIn(const std::string& bytes, uint32_t kind) {
  uint32_t sections;
  std::memcpy(&sections, &bytes[24], 4);
  for (uint32_t s = 0; s < sections && s < 16; ++s) {
    uint32_t k;
    uint64_t offset;
    std::memcpy(&k, &bytes[64 + 32 * s], 4);
    std::memcpy(&offset, &bytes[64 + 32 * s + 8], 8);
    if (k == kind) return offset;
  }
  ADD_FAILURE() << "no section " << kind;
  return 0;
}

class DatabaseFileTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { db_ = new Database(MakeDatabase(testing::ModelFreeExtractorOptions(), 3, true)); }
  static void TearDownTestSuite() {
    delete db_;
    db_ = nullptr;
  }
  void SetUp() override {
    name_ = db_->Save(tmp_.Path()).keyframes_file;
    bin_ = tmp_.Path(name_);
    bytes_ = ReadFileToString(bin_);
    manifest_ = nlohmann::json::parse(ReadFileToString(Dir() + "/manifest.json"));
    ASSERT_GT(bytes_.size(), 1000u);
  }
  std::string Dir() const { return tmp_.Path(); }
  auto LoadFn() const {
    return [dir = Dir()] { LoadVerified(dir); };
  }
  void WriteManifest(const nlohmann::json& m) const {
    WriteBytes(Dir() + "/manifest.json", m.dump(2));
  }
  // Writes `bytes` as the keyframe file with fresh checksums, and a manifest
  // that agrees with its size and checksum.
  void WriteResealed(std::string bytes, bool fix_size = true) const {
    const uint64_t checksum = keyframe_file::Reseal(&bytes, fix_size);
    WriteBytes(bin_, bytes);
    nlohmann::json m = manifest_;
    m["files"]["keyframes_bytes"] = bytes.size();
    m["files"]["keyframes_checksum"] = ChecksumHex(checksum);
    WriteManifest(m);
  }
  // Offset of section `kind` in the saved file.
  uint64_t SectionOffset(uint32_t kind) const { return SectionOffsetIn(bytes_, kind); }
  template <typename T>
  static void Put(std::string* bytes, size_t at, T value) {
    std::memcpy(&(*bytes)[at], &value, sizeof(T));
  }

  static Database* db_;
  TempDir tmp_;
  std::string name_, bin_, bytes_;
  nlohmann::json manifest_;
};
Database* DatabaseFileTest::db_ = nullptr;

TEST_F(DatabaseFileTest, TruncatedKeyframesFile) {
  const size_t size = bytes_.size();
  for (size_t cut : {size_t{0}, size_t{4}, size_t{10}, size_t{63}, size_t{100}, size_t{200},
                     size / 2, size - 5, size - 1}) {
    // As the manifest says: the size disagrees.
    WriteBytes(bin_, bytes_.substr(0, cut));
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "bytes but manifest.json records"))
        << "cut at " << cut;
    // With the manifest updated: the file itself says it is short.
    nlohmann::json m = manifest_;
    m["files"]["keyframes_bytes"] = cut;
    WriteManifest(m);
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "truncated")) << "cut at " << cut;
  }
  WriteBytes(bin_, bytes_);
  WriteManifest(manifest_);
  EXPECT_EQ(LoadVerified(Dir()).size(), 3u);
}

TEST_F(DatabaseFileTest, CorruptedBytesFailTheirChecksum) {
  for (const auto& [at, what] : std::vector<std::pair<size_t, std::string>>{
           {20, "header checksum mismatch"},
           {64 + 8, "header checksum mismatch"},  // the section table
           {SectionOffset(keyframe_file::kKeyframes) + 5, "keyframe section checksum mismatch"},
           {SectionOffset(keyframe_file::kStrings) + 3, "string section checksum mismatch"},
           {SectionOffset(keyframe_file::kCompactKeypoints) + 77,
            "keypoint section checksum mismatch"},
           {SectionOffset(keyframe_file::kSourceHashes) + 9,
            "source hash section checksum mismatch"},
           {SectionOffset(keyframe_file::kDescriptors) + 5, "descriptor section checksum mismatch"},
           {bytes_.size() - 10, "feature block section checksum mismatch"}}) {
    std::string bad = bytes_;
    bad[at] = static_cast<char>(bad[at] ^ 0x10);
    WriteBytes(bin_, bad);
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), what)) << "byte " << at;
  }
  WriteBytes(bin_, bytes_ + "xyz");
  nlohmann::json m = manifest_;
  m["files"]["keyframes_bytes"] = bytes_.size() + 3;
  WriteManifest(m);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "unexpected trailing bytes"));
}

// A keyframe table (a voter's view) reads neither keypoints nor descriptors:
// damage there does not stop it, and the features cannot be asked for.
// The source hash section is optional: a file without it (an earlier
// placedb's) reads with every hash 0, "not recorded"; one of another size
// than the keyframes' is refused.
TEST_F(DatabaseFileTest, SourceHashesAreOptional) {
  const Database saved = LoadVerified(Dir());
  ASSERT_EQ(saved.size(), 3u);
  EXPECT_EQ(saved.keyframe(0).source_hash, 0x8000000000000000ull + 77);
  EXPECT_EQ(saved.keyframe(2).source_hash, 0u);
  // The sixth entry of the table is the hashes': a table of five drops it.
  uint32_t kind;
  std::memcpy(&kind, &bytes_[64 + 5 * 32], 4);
  ASSERT_EQ(kind, keyframe_file::kSourceHashes);
  std::string old = bytes_;
  Put<uint32_t>(&old, 24, 5);  // the whole-image section (the seventh) goes too
  manifest_.erase("whole_image_dims");
  WriteResealed(old);
  const Database earlier = LoadVerified(Dir());
  ASSERT_EQ(earlier.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(earlier.keyframe(i).source_hash, 0u);
    Keyframe k = saved.keyframe(i);
    k.source_hash = 0;
    ExpectKeyframesEqual(earlier.keyframe(i), k);
  }
  std::string short_section = bytes_;
  Put<uint64_t>(&short_section, 64 + 5 * 32 + 16, 16);
  WriteResealed(short_section);
  EXPECT_TRUE(
      ThrowsWith<CorruptDatabase>(LoadFn(), "the source hash section's size does not match"));
}

// The whole-image section is optional too: a file without it (an earlier
// placedb's, or built with --no-whole-image) opens with no channel; the
// manifest's whole_image_dims must agree with the file; a damaged section
// (size, preamble, values) is refused.
TEST_F(DatabaseFileTest, WholeImageSectionIsOptionalAndChecked) {
  const Database saved = LoadVerified(Dir());
  ASSERT_EQ(saved.whole_image_dims(), 768);
  EXPECT_EQ(manifest_["whole_image_dims"], 768);
  for (size_t i = 0; i < 3; ++i)
    EXPECT_EQ(0, std::memcmp(saved.WholeImage(i), db_->WholeImage(i), 768)) << i;
  uint32_t kind;
  std::memcpy(&kind, &bytes_[64 + 6 * 32], 4);
  ASSERT_EQ(kind, keyframe_file::kWholeImage);
  std::string without = bytes_;
  Put<uint32_t>(&without, 24, 6);  // drops the seventh entry
  WriteResealed(without);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "disagree on the whole-image channel"));
  manifest_.erase("whole_image_dims");
  WriteResealed(without);
  const Database earlier = LoadVerified(Dir());
  EXPECT_EQ(earlier.whole_image_dims(), 0);
  EXPECT_EQ(earlier.WholeImageData(), nullptr);
  EXPECT_EQ(earlier.keyframe(0).source_hash, saved.keyframe(0).source_hash);
  EXPECT_TRUE(earlier.Features(0).whole_image.empty());
  // The section present, the manifest without the key: they disagree too.
  WriteResealed(bytes_);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "disagree on the whole-image channel"));
  manifest_["whole_image_dims"] = 768;
  const size_t at = SectionOffset(keyframe_file::kWholeImage);
  for (const auto& [what, edit] :
       std::vector<std::pair<std::string, std::function<void(std::string*)>>>{
           {"whole-image rows of 0 values", [&](std::string* b) { Put<uint32_t>(b, at, 0); }},
           {"whole-image rows of 5000 values", [&](std::string* b) { Put<uint32_t>(b, at, 5000); }},
           {"size does not match 3 keyframes of 769",
            [&](std::string* b) { Put<uint32_t>(b, at, 769); }},
           {"reserved bytes are not 0", [&](std::string* b) { (*b)[at + 63] = 1; }},
           {"holds -128", [&](std::string* b) { (*b)[at + 64 + 700] = static_cast<char>(0x80); }},
           {"shorter than its preamble",
            [&](std::string* b) { Put<uint64_t>(b, 64 + 6 * 32 + 16, 63); }},
       }) {
    std::string bad = bytes_;
    edit(&bad);
    WriteResealed(bad);
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), what)) << what;
  }
  std::string flipped = bytes_;
  flipped[at + 100] ^= 0x10;
  WriteBytes(bin_, flipped);
  WriteManifest(manifest_);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "whole-image section checksum mismatch"));
  // A keyframe table says the dims but gives no rows.
  LoadOptions table;
  table.contents = LoadContents::kKeyframeTable;
  const Database t = Database::Load(Dir(), table);
  EXPECT_EQ(t.whole_image_dims(), 768);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { t.WholeImageData(); }, "keyframe table"));
}

// AddKeyframe holds a database with the channel to rows of its size and
// values; one without the channel ignores rows. Compacted and a grown copy
// keep every row with its keyframe.
TEST(DatabaseRowsTest, WholeImageRowsAreCheckedAndFollowTheirKeyframes) {
  const Database built = MakeDatabase(testing::ModelFreeExtractorOptions(), 4, false);
  ASSERT_EQ(built.whole_image_dims(), 768);
  Database db(FeatureType::kOrb, 32, 768);
  EXPECT_THROW(Database(FeatureType::kOrb, 32, 8), InvalidArgument);
  EXPECT_THROW(Database(FeatureType::kOrb, 32, 5000), InvalidArgument);
  const Keyframe k = built.keyframe(0);
  FeatureSet f = built.Features(0);
  ASSERT_EQ(f.whole_image.cols, 768);
  FeatureSet bad = f;
  bad.whole_image.release();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(k, bad); }, "no whole-image"));
  bad.whole_image = f.whole_image.colRange(0, 767).clone();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(k, bad); }, "1 x 767"));
  f.whole_image.convertTo(bad.whole_image, CV_8U);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(k, bad); }, "CV_8SC1"));
  bad.whole_image = f.whole_image.clone();
  bad.whole_image.at<int8_t>(5) = -128;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(k, bad); }, "-128"));
  EXPECT_EQ(db.size(), 0u);
  for (size_t i = 0; i < built.size(); ++i) db.AddKeyframe(built.keyframe(i), built.Features(i));
  for (size_t i = 0; i < db.size(); ++i)
    EXPECT_EQ(0, std::memcmp(db.WholeImage(i), built.WholeImage(i), 768)) << i;
  const Database kept = db.Compacted({1, 0, 0, 1});
  ASSERT_EQ(kept.size(), 2u);
  EXPECT_EQ(0, std::memcmp(kept.WholeImage(0), built.WholeImage(0), 768));
  EXPECT_EQ(0, std::memcmp(kept.WholeImage(1), built.WholeImage(3), 768));
  Database grown = kept;
  grown.Reserve(16, 4096);
  EXPECT_TRUE(grown.HasRoomFor(1, 500));
  grown.AddKeyframe(built.keyframe(1), built.Features(1));
  EXPECT_EQ(0, std::memcmp(grown.WholeImage(2), built.WholeImage(1), 768));
  // A loaded database grows by copy on write, rows included.
  TempDir tmp;
  kept.Save(tmp.Path());
  Database loaded = LoadVerified(tmp.Path());
  loaded.AddKeyframe(built.keyframe(2), built.Features(2));
  EXPECT_EQ(0, std::memcmp(loaded.WholeImage(0), built.WholeImage(0), 768));
  EXPECT_EQ(0, std::memcmp(loaded.WholeImage(2), built.WholeImage(2), 768));
  // Without a channel, rows given are ignored.
  Database plain(FeatureType::kOrb, 32);
  plain.AddKeyframe(built.keyframe(0), built.Features(0));
  EXPECT_EQ(plain.whole_image_dims(), 0);
  EXPECT_EQ(plain.WholeImageData(), nullptr);
  EXPECT_TRUE(plain.Features(0).whole_image.empty());
}

TEST_F(DatabaseFileTest, KeyframeTableSkipsTheFeatures) {
  std::string bad = bytes_;
  bad[bytes_.size() - 10] ^= 0x10;
  WriteBytes(bin_, bad);
  LoadOptions table;
  table.contents = LoadContents::kKeyframeTable;
  const Database db = Database::Load(Dir(), table);
  EXPECT_FALSE(db.has_features());
  ASSERT_EQ(db.size(), 3u);
  EXPECT_EQ(db.keyframe(0).id, 10);
  EXPECT_TRUE(db.keyframe(0).pose.has_value());
  EXPECT_EQ(db.FeatureCount(0), db_->FeatureCount(0));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.Descriptors(0); }, "keyframe table"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.Keypoints(0); }, "keyframe table"));
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "feature block section checksum mismatch"));
}

// Version 3 opens without reading the features, and checks each keyframe's
// the first time they are used: damage there does not stop the open, but
// no damaged byte reaches a caller (the accessors throw), the other
// keyframes answer, and VerifyAll finds it.
TEST_F(DatabaseFileTest, FeaturesAreCheckedOnFirstUse) {
  const size_t kp0 = SectionOffset(keyframe_file::kCompactKeypoints) +
                     keyframe_file::kCompactKeypointPreambleBytes;
  const size_t rows = SectionOffset(keyframe_file::kDescriptors);
  const size_t second = db_->FeatureCount(0);  // keyframe 20's first row
  struct Case {
    size_t at;
    std::string what;
  };
  for (const Case& c : std::vector<Case>{
           {kp0 + 10 * second + 3, "keyframe 20: its keypoints fail their block checksum"},
           {rows + 32 * second + 7, "keyframe 20: its descriptors fail their block checksum"}}) {
    std::string bad = bytes_;
    bad[c.at] = static_cast<char>(bad[c.at] ^ 0x04);
    WriteBytes(bin_, bad);  // not resealed: the section checksum is wrong too
    const Database db = Database::Load(Dir());
    ASSERT_EQ(db.size(), 3u);
    for (size_t i = 0; i < 3; ++i) EXPECT_FALSE(db.FeaturesChecked(i));
    EXPECT_EQ(db.Keypoints(0).size(), db_->FeatureCount(0));  // keyframe 10 is fine
    EXPECT_TRUE(db.FeaturesChecked(0));
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { db.Descriptors(1); }, c.what)) << c.what;
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { db.Keypoints(1); }, c.what)) << c.what;
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { db.Features(1); }, c.what)) << c.what;
    EXPECT_FALSE(db.FeaturesChecked(1));
    EXPECT_NO_THROW(db.Descriptors(2));
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { db.VerifyAll(); }, "section checksum mismatch"));
    // Read rather than mapped (LoadOptions::read_features): the bytes read
    // are checked, whichever of the keyframe's blocks the use asks for.
    LoadOptions read;
    read.read_features = true;
    const Database reader = Database::Load(Dir(), read);
    std::vector<uint8_t> buffer;
    EXPECT_NO_THROW(reader.Descriptors(0, &buffer));
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { reader.Descriptors(1, &buffer); }, c.what))
        << c.what;
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { reader.Keypoints(1); }, c.what)) << c.what;
    EXPECT_FALSE(reader.FeaturesChecked(1));
    EXPECT_EQ(reader.Keypoints(2).size(), db_->FeatureCount(2));
    EXPECT_TRUE(reader.FeaturesChecked(2));
    // Copying the database (the first added keyframe) reads every keyframe.
    Database grown = db;
    EXPECT_THROW(grown.Reserve(4, 1000), CorruptDatabase);
  }
  // The whole-image rows: checked on the first call.
  std::string bad = bytes_;
  const size_t rows_at = SectionOffset(keyframe_file::kWholeImage) + 64;
  bad[rows_at + 5] = static_cast<char>(bad[rows_at + 5] ^ 0x02);
  WriteBytes(bin_, bad);
  const Database db = Database::Load(Dir());
  EXPECT_NO_THROW(db.Descriptors(0));
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { db.WholeImageData(); },
                                          "whole-image section checksum mismatch"));
  // Undamaged: every keyframe is checked once used, and VerifyAll passes.
  WriteBytes(bin_, bytes_);
  const Database good = Database::Load(Dir());
  EXPECT_EQ(good.file_format_version(), keyframe_file::kVersion);
  EXPECT_FALSE(good.FeaturesChecked(2));
  good.VerifyAll();
  for (size_t i = 0; i < 3; ++i) EXPECT_TRUE(good.FeaturesChecked(i));
  ExpectDatabasesEqual(*db_, good);
}

// The background check (a session's prefetch thread) marks what passes the
// first-use check, a few keyframes a call, reading the file without mapping
// it, and leaves a damaged keyframe for its first use to report.
TEST_F(DatabaseFileTest, BackgroundCheckLeavesDamageToTheFirstUse) {
  const size_t rows = SectionOffset(keyframe_file::kDescriptors);
  const size_t second = db_->FeatureCount(0);  // keyframe 20's first row
  std::string bad = bytes_;
  bad[rows + 32 * second + 9] = static_cast<char>(bad[rows + 32 * second + 9] ^ 0x10);
  WriteBytes(bin_, bad);
  const Database db = Database::Load(Dir());
  std::vector<uint8_t> buffer;
  size_t next = 0;
  EXPECT_TRUE(db.CheckSomeInBackground(&next, 1, &buffer));
  EXPECT_EQ(next, 1u);
  EXPECT_TRUE(db.FeaturesChecked(0));
  EXPECT_FALSE(db.FeaturesChecked(1));
  EXPECT_FALSE(db.CheckSomeInBackground(&next, 5, &buffer));
  EXPECT_EQ(next, 3u);
  EXPECT_FALSE(db.FeaturesChecked(1));
  EXPECT_TRUE(db.FeaturesChecked(2));
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(
      [&] { db.Descriptors(1); }, "keyframe 20: its descriptors fail their block checksum"));
  EXPECT_NO_THROW(db.Descriptors(2));
  // Undamaged: everything is marked; a built database has nothing to check.
  WriteBytes(bin_, bytes_);
  const Database good = Database::Load(Dir());
  next = 0;
  while (good.CheckSomeInBackground(&next, 2, &buffer)) {
  }
  for (size_t i = 0; i < 3; ++i) EXPECT_TRUE(good.FeaturesChecked(i));
  next = 0;
  EXPECT_FALSE(db_->CheckSomeInBackground(&next, 5, &buffer));
}

TEST_F(DatabaseFileTest, WrongVersions) {
  std::string bad = bytes_;
  Put<uint32_t>(&bad, 8, kDatabaseFormatVersion + 1);
  WriteResealed(bad);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(
      LoadFn(),
      "format version " + std::to_string(kDatabaseFormatVersion + 1) + " is not supported"));
  WriteBytes(bin_, bytes_);
  nlohmann::json m = manifest_;
  m["format_version"] = kDatabaseFormatVersion + 1;
  WriteManifest(m);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "database format version " +
                                                        std::to_string(kDatabaseFormatVersion + 1) +
                                                        " is not supported"));
  // A version 1 database says how to rebuild it.
  m["format_version"] = 1;
  m["source"] = "images:/data/loop [1..40]";
  WriteManifest(m);
  EXPECT_TRUE(
      ThrowsWith<CorruptDatabase>(LoadFn(), {"format version 1 is no longer read", "placedb build",
                                             "--overwrite", "images:/data/loop [1..40]"}));
}

TEST_F(DatabaseFileTest, WrongMagic) {
  std::string bad = bytes_;
  bad[0] = 'X';
  WriteBytes(bin_, bad);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "wrong magic"));
  WriteResealed("this is a text file, not a database\n");
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "wrong magic"));
}

// Every field the manifest records of the keyframe file is checked against it.
TEST_F(DatabaseFileTest, ManifestMustAgreeWithTheKeyframeFile) {
  auto fails = [&](const std::function<void(nlohmann::json&)>& edit, const std::string& part) {
    nlohmann::json m = manifest_;
    edit(m);
    WriteManifest(m);
    return ThrowsWith<CorruptDatabase>(LoadFn(), part);
  };
  EXPECT_TRUE(
      fails([](nlohmann::json& m) { m["feature_type"] = "surf"; }, "disagree on the feature type"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["descriptor_bytes"] = 64; },
                    "disagree on the descriptor width"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["counts"]["keyframes"] = 4; },
                    "disagree on the number of keyframes"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["counts"]["features"] = 5; },
                    "disagree on the number of features"));
  EXPECT_TRUE(
      fails([](nlohmann::json& m) { m["files"]["keyframes_checksum"] = "0123456789abcdef"; },
            "disagree on the file's checksum"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["files"]["keyframes_bytes"] = 12; }, "records 12"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["files"]["keyframes"] = "../../etc/passwd"; },
                    "not a keyframe file name"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["counts"]["features"] = true; },
                    "features is not an integer"));
  EXPECT_TRUE(
      fails([](nlohmann::json& m) { m["counts"]["keyframes"] = -1; }, "keyframes is out of range"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["format_version"] = "2"; },
                    "format_version is not an integer"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m.erase("files"); }, "files is missing"));
  WriteManifest(manifest_);
  EXPECT_EQ(LoadVerified(Dir()).size(), 3u);
}

TEST_F(DatabaseFileTest, MissingFiles) {
  fs::remove(bin_);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), {name_, "is missing"}));
  fs::remove(Dir() + "/manifest.json");
  // The keyframe file and the manifest are gone: no database there at all.
  EXPECT_TRUE(ThrowsWith<NotFound>(LoadFn(), {"no database at", "manifest.json is missing"}));
  EXPECT_TRUE(ThrowsWith<NotFound>([&] { LoadVerified(Dir() + "/nothing_here"); },
                                   {"no database at", "(no such directory)"}));
  WriteBytes(Dir() + "/a_file", "x");
  EXPECT_TRUE(ThrowsWith<NotFound>([&] { LoadVerified(Dir() + "/a_file"); }, "(not a directory)"));
}

// The kind of each error, which decides the CLI's exit code and the Python
// exception: no database is NotFound, a damaged one CorruptDatabase, a save
// the system refuses IoError, a bad argument InvalidArgument. Messages name
// the path but never a source file.
TEST_F(DatabaseFileTest, ErrorKinds) {
  EXPECT_THROW(LoadVerified(Dir() + "/missing"), NotFound);
  std::string flipped = bytes_;
  flipped[flipped.size() / 2] ^= 0x01;
  WriteBytes(bin_, flipped);
  try {
    LoadVerified(Dir());
    ADD_FAILURE() << "a flipped byte loaded";
  } catch (const CorruptDatabase& e) {
    EXPECT_NE(std::string(e.what()).find(name_), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find(".cc:"), std::string::npos) << e.what();
    EXPECT_EQ(e.where().rfind("storage/", 0), 0u) << e.where();
  }
  WriteBytes(bin_, bytes_);
  // /proc takes no new files, even from root.
  EXPECT_THROW(db_->Save("/proc"), IoError);
  // A file where the database folder should be: no database there.
  EXPECT_THROW(db_->Save(bin_), NotFound);
  EXPECT_THROW(LoadVerified(Dir(), KeyframeSubset::Partition(3, 2)), InvalidArgument);
  EXPECT_EQ(LoadVerified(Dir()).size(), 3u);
}

TEST_F(DatabaseFileTest, ManifestNotJson) {
  WriteBytes(Dir() + "/manifest.json", "{ not json");
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "not valid JSON"));
  WriteBytes(Dir() + "/manifest.json", "{\"format\": \"something-else\"}");
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "not a placedb database manifest"));
  WriteBytes(Dir() + "/manifest.json", "[1, 2, 3]");
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "not a placedb database manifest"));
  WriteBytes(Dir() + "/manifest.json", std::string("\x89PNG\r\n\x1a\n\0\0", 10));
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "not valid JSON"));
  WriteManifest(manifest_);
  EXPECT_EQ(LoadVerified(Dir()).size(), 3u);
}

// The mutation family of manifest nesting (issue 46): unknown keys holding
// arrays and objects nested to every depth up to past the limit, at the top
// and inside the known objects, with brackets inside strings too. A
// manifest within the limits loads, keeps its unknown keys and dumps and
// copies safely; one nested deeper than kMaxJsonDepth, or larger than
// kMaxManifestBytes, is CorruptDatabase, never a crash or a long walk.
TEST_F(DatabaseFileTest, MutatedManifestNesting) {
  std::mt19937_64 rng(20261246);
  const std::string text = manifest_.dump();
  int loaded = 0, refused = 0;
  for (int i = 0; i < 300; ++i) {
    const int depth = i < 200   ? 1 + static_cast<int>(rng() % 80)
                      : i < 290 ? static_cast<int>(rng() % 5000)
                                : 100000 + static_cast<int>(rng() % 1000000);
    std::string open, close;
    for (int d = 0; d < depth; ++d) {
      const bool object = rng() % 3 == 0;
      open += object ? "{\"k\":" : "[";
      close += object ? "}" : "]";
    }
    std::reverse(close.begin(), close.end());
    const std::string value = open + (rng() % 2 ? "\"[{\\\"]}\"" : "0") + close;
    // Inside "counts" (one level down) or at the top.
    const bool inside = rng() % 2;
    std::string mutated = text;
    const size_t at = inside ? mutated.find("\"counts\":{") + 10 : 1;
    mutated.insert(at, "\"x\":" + value + ",");
    WriteBytes(Dir() + "/manifest.json", mutated);
    const int levels = depth + 1 + (inside ? 1 : 0);  // the manifest's own object(s) too
    try {
      const Database db = LoadVerified(Dir());
      ++loaded;
      EXPECT_LE(levels, kMaxJsonDepth) << depth;
      EXPECT_TRUE((inside ? db.info()["counts"] : db.info()).contains("x"));
      const nlohmann::json copy = db.info();
      EXPECT_FALSE(DumpJson(copy).empty());
    } catch (const CorruptDatabase& e) {
      ++refused;
      EXPECT_GT(levels, kMaxJsonDepth) << e.what();
      const std::string what = e.what();
      EXPECT_TRUE(what.find("nested deeper than 64 levels") != std::string::npos ||
                  what.find("larger than") != std::string::npos)
          << what;
    }
  }
  EXPECT_GT(loaded, 100);
  EXPECT_GT(refused, 100);
}

// The defects found with hostile input, each with its regression test:
// values that are impossible although every checksum is right.
TEST_F(DatabaseFileTest, ImpossibleValuesWithValidChecksums) {
  const size_t k0 = SectionOffset(keyframe_file::kKeyframes);
  const size_t kp = SectionOffset(keyframe_file::kCompactKeypoints);
  const size_t kp0 = kp + keyframe_file::kCompactKeypointPreambleBytes;  // the first record
  struct Case {
    std::string what;
    std::function<void(std::string*)> edit;
  };
  const std::vector<Case> cases = {
      {"features outside its range",
       [&](std::string* b) {
         Put<uint64_t>(b, k0 + 152 + 120, ~uint64_t{0} - 3);
       }},  // offset wraps
      {"features outside its range",
       [&](std::string* b) { Put<uint32_t>(b, k0 + 128, 0xffffffffu); }},
      {"strings outside the string section",
       [&](std::string* b) {
         Put<uint64_t>(b, k0 + 136, ~uint64_t{0} - 2);
       }},  // string offset wraps
      {"strings outside the string section",
       [&](std::string* b) { Put<uint32_t>(b, k0 + 132, 60000); }},
      {"id 0 is not >= 1", [&](std::string* b) { Put<int32_t>(b, k0, 0); }},
      {"id -5 is not >= 1", [&](std::string* b) { Put<int32_t>(b, k0, -5); }},
      {"appears twice", [&](std::string* b) { Put<int32_t>(b, k0 + 152, 10); }},
      {"crop rectangle is negative", [&](std::string* b) { Put<int32_t>(b, k0 + 16, -3); }},
      {"image size is negative", [&](std::string* b) { Put<int32_t>(b, k0 + 24, -640); }},
      {"leaves the original image", [&](std::string* b) { Put<int32_t>(b, k0 + 8, 600); }},
      {"crop channel 7", [&](std::string* b) { Put<int32_t>(b, k0 + 4, 7); }},
      {"scale is not in (0, 64]", [&](std::string* b) { Put<double>(b, k0 + 48, std::nan("")); }},
      {"scale is not in (0, 64]",
       [&](std::string* b) { Put<double>(b, k0 + 48, std::numeric_limits<double>::infinity()); }},
      {"scale is not in (0, 64]", [&](std::string* b) { Put<double>(b, k0 + 48, 0.0); }},
      {"timestamp is not finite", [&](std::string* b) { Put<double>(b, k0 + 40, std::nan("")); }},
      {"pose is not finite", [&](std::string* b) { Put<double>(b, k0 + 64, std::nan("")); }},
      {"not of unit length",
       [&](std::string* b) {
         for (int c = 0; c < 4; ++c) Put<double>(b, k0 + 88 + 8 * c, 0.0);  // zero quaternion
       }},
      {"bad pose flag", [&](std::string* b) { Put<uint32_t>(b, k0 + 56, 7); }},
      {"bad Laplacian split",
       [&](std::string* b) { Put<uint32_t>(b, k0 + 60, 2); }},  // ORB has none
      {"keypoint 1 has an impossible angle code",
       [&](std::string* b) { Put<uint16_t>(b, kp0 + 10 + 6, 46080); }},
      {"keyframe 10 has a keypoint outside its stored image",
       [&](std::string* b) { Put<uint16_t>(b, kp0 + 2, 0xffff); }},
      {"compact keypoints of 12 bytes", [&](std::string* b) { Put<uint32_t>(b, kp, 12); }},
      {"position scheme 4", [&](std::string* b) { Put<uint32_t>(b, kp + 4, 4); }},
      {"a stored image wider than 65533 px holds keypoints",
       [&](std::string* b) {
         Put<int32_t>(b, k0 + 32, 70000);  // stored width (the original is unknown: 0 x 0)
         Put<int32_t>(b, k0 + 24, 0);
         Put<int32_t>(b, k0 + 28, 0);
       }},
      {"compact keypoint section's reserved bytes",
       [&](std::string* b) { Put<uint32_t>(b, kp + 60, 1); }},
      {"section kind 3 does not belong in a version 3 file",
       [&](std::string* b) { Put<uint32_t>(b, 64 + 32 * 6, keyframe_file::kKeypoints); }},
      {"cannot be 0 bytes wide", [&](std::string* b) { Put<uint32_t>(b, 20, 0); }},
      {"cannot be 1 bytes wide", [&](std::string* b) { Put<uint32_t>(b, 20, 1); }},
      {"cannot be 16 bytes wide", [&](std::string* b) { Put<uint32_t>(b, 20, 16); }},
      {"unknown feature type 9", [&](std::string* b) { Put<uint32_t>(b, 16, 9); }},
      {"keyframe count", [&](std::string* b) { Put<uint64_t>(b, 32, ~uint64_t{0} / 2); }},
      {"feature count", [&](std::string* b) { Put<uint64_t>(b, 40, uint64_t{1} << 62); }},
      {"bad section count", [&](std::string* b) { Put<uint32_t>(b, 24, 1000); }},
      {"lies outside the file",
       [&](std::string* b) { Put<uint64_t>(b, 64 + 8, ~uint64_t{0} - 63); }},
      {"lies outside the file", [&](std::string* b) { Put<uint64_t>(b, 64 + 16, ~uint64_t{0}); }},
      {"is not aligned", [&](std::string* b) { Put<uint64_t>(b, 64 + 32 + 8, 65); }},
      {"appears twice",
       [&](std::string* b) { Put<uint32_t>(b, 64 + 32, 1); }},  // two keyframe sections
      {"sections overlap",
       [&](std::string* b) {
         uint64_t first;
         std::memcpy(&first, &(*b)[64 + 8], 8);
         Put<uint64_t>(b, 64 + 32 + 8, first);
       }},
      {"size does not match", [&](std::string* b) { Put<uint64_t>(b, 64 + 16, 152); }},
  };
  for (const Case& c : cases) {
    std::string bad = bytes_;
    c.edit(&bad);
    WriteResealed(bad);
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), c.what)) << c.what;
  }
  WriteResealed(bytes_);
  EXPECT_EQ(LoadVerified(Dir()).size(), 3u);
}

// The mutation test of the reader: 12 000 damaged keyframe files (bit flips,
// byte runs, truncations, huge counts, offsets and lengths, swapped fields),
// each resealed so the checksums pass and the parser itself is tested, and
// 1 000 damaged manifests. Each either loads (the damage hit a descriptor
// bit or a value that is still possible), and then answers a query, or fails
// with CorruptDatabase (never another kind: damage is never a bug nor the
// caller's fault); never a crash, a hang or (under the sanitizers) a bad read.
TEST_F(DatabaseFileTest, MutatedFilesNeverCrash) {
  std::mt19937_64 rng(20261201);
  const FeatureSet query =
      FeatureExtractor::Create(testing::ModelFreeExtractorOptions())->Extract(cv::imread(RtabmapImage(42)));
  int loaded = 0, rejected = 0;
  auto attempt = [&] {
    try {
      const Database db = LoadVerified(Dir());
      // A database that loads must be safe to use.
      std::vector<int8_t> lap;
      const DescriptorBlock q = MakeDescriptorBlock(query, &lap);
      for (size_t i = 0; i < db.size(); ++i) {
        MatchDescriptors(q, db.Descriptors(i), MatchOptions());
        for (const cv::KeyPoint& kp : db.Keypoints(i)) ASSERT_TRUE(std::isfinite(kp.pt.x));
      }
      if (db.whole_image_dims() > 0) {
        const int dims = db.whole_image_dims();
        const std::vector<int8_t> q_row(static_cast<size_t>(dims), 5);
        std::vector<float> similarity(db.size());
        WholeImageSimilarities(q_row.data(), db.WholeImageData(), db.size(), dims,
                               similarity.data());
        for (const float v : similarity) ASSERT_TRUE(v >= -1.0f && v <= 1.0f);
      }
      ++loaded;
    } catch (const CorruptDatabase&) {
      ++rejected;
    }
  };
  const uint64_t interesting[] = {0,
                                  1,
                                  2,
                                  3,
                                  63,
                                  64,
                                  65,
                                  151,
                                  152,
                                  0x7fffffff,
                                  0x80000000,
                                  0xffffffff,
                                  uint64_t{1} << 32,
                                  uint64_t{1} << 62,
                                  ~uint64_t{0} / 2,
                                  ~uint64_t{0} - 1,
                                  ~uint64_t{0}};
  constexpr int kFiles = 12000;
  uint32_t kSections;
  std::memcpy(&kSections, &bytes_[24], 4);
  ASSERT_EQ(kSections, 7u);  // the fixture has every section, the whole image's too
  for (int i = 0; i < kFiles; ++i) {
    std::string bad = bytes_;
    const int kind = static_cast<int>(rng() % 6);
    // Aim at the fields: the header and section table, the keyframe records,
    // strings, source hashes and whole-image section, the keypoints; now
    // and then anywhere (descriptor bits are data, any value is possible).
    const size_t table_end = 64 + kSections * 32;
    const size_t records_end = SectionOffset(keyframe_file::kCompactKeypoints);
    const size_t features_at = SectionOffset(keyframe_file::kDescriptors);
    const int region = static_cast<int>(rng() % 10);
    const size_t from = region < 4 ? 0 : region < 7 ? table_end : region < 9 ? records_end : 0;
    const size_t to = region < 4   ? table_end
                      : region < 7 ? records_end
                      : region < 9 ? features_at
                                   : bad.size();
    const size_t span = to - from;
    auto at_in_region = [&](size_t alignment) {
      return from + (rng() % (span / alignment)) * alignment;
    };
    if (kind == 0) {  // bit flips
      for (int f = 0, n = 1 + static_cast<int>(rng() % 4); f < n; ++f) {
        bad[at_in_region(1)] ^= static_cast<char>(1 << (rng() % 8));
      }
    } else if (kind == 1) {  // a run of random bytes
      const size_t at = at_in_region(1), n = 1 + rng() % 16;
      for (size_t j = at; j < std::min(bad.size(), at + n); ++j) bad[j] = static_cast<char>(rng());
    } else if (kind == 2) {  // an interesting 8-byte value at an 8-aligned offset
      const size_t at = at_in_region(8);
      Put<uint64_t>(&bad, at, interesting[rng() % (sizeof(interesting) / 8)]);
    } else if (kind == 3) {  // an interesting 4-byte value at a 4-aligned offset
      const size_t at = (rng() % (span / 4)) * 4;
      Put<uint32_t>(&bad, at,
                    static_cast<uint32_t>(interesting[rng() % (sizeof(interesting) / 8)]));
    } else if (kind == 4) {  // truncation, or growth
      if (rng() % 2) {
        bad.resize(rng() % bad.size());
      } else {
        bad.append(1 + rng() % 200, static_cast<char>(rng()));
      }
    } else {  // a header or table field
      const size_t at = (rng() % ((64 + kSections * 32) / 4)) * 4;
      Put<uint32_t>(&bad, at, static_cast<uint32_t>(rng()));
    }
    WriteResealed(bad, /*fix_size=*/rng() % 8 != 0);
    attempt();
  }
  // Manifests: every field replaced by a value of another type or range.
  const std::vector<nlohmann::json> values = {nullptr,
                                              true,
                                              -1,
                                              0,
                                              2147483648LL,
                                              1.5,
                                              "x",
                                              nlohmann::json::array(),
                                              nlohmann::json::object()};
  std::vector<std::vector<std::string>> paths = {{"format"},
                                                 {"format_version"},
                                                 {"feature_type"},
                                                 {"descriptor_bytes"},
                                                 {"whole_image_dims"},
                                                 {"counts"},
                                                 {"counts", "keyframes"},
                                                 {"counts", "features"},
                                                 {"files"},
                                                 {"files", "keyframes"},
                                                 {"files", "keyframes_bytes"},
                                                 {"files", "keyframes_checksum"}};
  WriteBytes(bin_, bytes_);
  constexpr int kManifests = 1000;
  for (int i = 0; i < kManifests; ++i) {
    nlohmann::json m = manifest_;
    const auto& path = paths[rng() % paths.size()];
    nlohmann::json* field = &m;
    for (const std::string& key : path) field = &(*field)[key];
    *field = values[rng() % values.size()];
    if (rng() % 10 == 0) {
      std::string text = m.dump();
      text.resize(rng() % text.size());
      WriteBytes(Dir() + "/manifest.json", text);
    } else {
      WriteManifest(m);
    }
    attempt();
  }
  std::printf("mutations: %d loaded, %d rejected of %d\n", loaded, rejected, kFiles + kManifests);
  EXPECT_EQ(loaded + rejected, kFiles + kManifests);
  EXPECT_GT(rejected, kFiles / 2);  // most damage to the fields is caught
  EXPECT_GT(loaded, 0);             // and descriptor bits are just data
}

// Saving in place over a database, killed (SIGKILL) at random moments: the
// directory always holds a database that loads, the old one or the new one.
TEST(DatabaseSaveTest, KilledInPlaceSaveLeavesALoadableDatabase) {
  if (testing_util::kThreadSanitizer) GTEST_SKIP() << "forks: not under ThreadSanitizer";
  TempDir tmp;
  const Database small = MakeDatabase(testing::ModelFreeExtractorOptions(), 2, false);
  const Database large = MakeDatabase(testing::ModelFreeExtractorOptions(), 6, true);
  small.Save(tmp.Path());
  std::mt19937 rng(7);
  int survived = 0;
  for (int trial = 0; trial < 30; ++trial) {
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      for (int n = 0;; ++n) (n % 2 ? small : large).Save(tmp.Path());  // until killed
    }
    std::this_thread::sleep_for(std::chrono::microseconds(500 + rng() % 20000));
    ::kill(child, SIGKILL);
    int status = 0;
    ::waitpid(child, &status, 0);
    const Database db = LoadVerified(tmp.Path());
    EXPECT_TRUE(db.size() == 2 || db.size() == 6) << db.size();
    ExpectDatabasesEqual(db.size() == 2 ? small : large, db);
    ++survived;
  }
  EXPECT_EQ(survived, 30);
  // No stale generation is left once a save completes.
  small.Save(tmp.Path());
  int keyframe_files = 0;
  for (const auto& e : fs::directory_iterator(tmp.Path())) {
    keyframe_files += Database::IsKeyframesFileName(e.path().filename().string());
  }
  EXPECT_EQ(keyframe_files, 1);
}

// A reader never pairs one generation's manifest with another's keyframe
// file, while a writer keeps replacing the database in place: every load
// sees the keyframes the manifest it read describes. Bounded by counts, not
// by time: the writer saves kSaves times (b, a, b, ...) and after each save
// waits until the reader has completed two more loads, so at least one load
// runs wholly between two saves (it must see the generation just saved)
// while the others overlap the saves, however slow the machine.
TEST(DatabaseSaveTest, ReadersSeeOneGenerationWhileAWriterSaves) {
  TempDir tmp;
  Database a = MakeDatabase(testing::ModelFreeExtractorOptions(), 3, false);
  Database b = MakeDatabase(testing::ModelFreeExtractorOptions(), 3, true);  // same counts, other content
  a.info()["generation"] = "a";
  b.info()["generation"] = "b";
  a.Save(tmp.Path());
  constexpr int kSaves = 40;
  std::atomic<int> loads{0};
  std::atomic<bool> writer_done{false}, reader_failed{false};
  std::string writer_error, reader_error;
  std::thread writer([&] {
    try {
      for (int n = 0; n < kSaves && !reader_failed; ++n) {
        (n % 2 ? a : b).Save(tmp.Path());
        const int target = loads.load() + 2;
        while (loads.load() < target && !reader_failed) std::this_thread::yield();
      }
    } catch (const std::exception& e) {
      writer_error = e.what();
    }
    writer_done = true;
  });
  int mixed = 0, seen_a = 0, seen_b = 0;
  try {
    while (!writer_done) {
      const Database db = LoadVerified(tmp.Path());
      const bool with_poses = db.keyframe(0).pose.has_value();
      const bool is_b = db.info()["generation"] == "b";
      mixed += with_poses != is_b;
      ++(is_b ? seen_b : seen_a);
      ++loads;
    }
  } catch (const std::exception& e) {
    reader_error = e.what();
    reader_failed = true;
  }
  writer.join();
  std::printf("%d loads during %d in-place saves (%d a, %d b), %d mixed\n", loads.load(), kSaves,
              seen_a, seen_b, mixed);
  EXPECT_EQ(writer_error, "");
  EXPECT_EQ(reader_error, "");
  EXPECT_EQ(mixed, 0);
  EXPECT_GE(loads.load(), 2 * kSaves);
  // Each save was followed by a load that saw just that generation.
  EXPECT_GE(seen_a, kSaves / 2);
  EXPECT_GE(seen_b, kSaves / 2);
}

TEST(DatabaseTest, AddingSurfFeaturesToOrbDatabaseThrows) {
  Database db = MakeDatabase(testing::ModelFreeExtractorOptions(), 1, false);
  ASSERT_EQ(db.size(), 1u);
  ExtractorOptions surf = testing::ModelFreeExtractorOptions();
  surf.type = FeatureType::kSurf;
  surf.surf.max_features = 50;
  const FeatureSet features = FeatureExtractor::Create(surf)->Extract(cv::imread(RtabmapImage(5)));
  ASSERT_FALSE(features.empty());
  Keyframe k;
  k.id = 99;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(k, features); },
                                          "cannot add surf features to a database of orb"));
  EXPECT_EQ(db.size(), 1u);  // unchanged
  // A SURF database refuses ORB features the same way.
  Database surf_db(FeatureType::kSurf, 256);
  const FeatureSet orb =
      FeatureExtractor::Create(testing::ModelFreeExtractorOptions())->Extract(cv::imread(RtabmapImage(5)));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { surf_db.AddKeyframe(k, orb); },
                                          "cannot add orb features to a database of surf"));
  EXPECT_TRUE(surf_db.empty());
}

TEST(DatabaseTest, DuplicateKeyframeIdThrows) {
  Database db = MakeDatabase(testing::ModelFreeExtractorOptions(), 2, false);  // ids 10, 20
  const size_t features = db.num_features();
  const FeatureSet set =
      FeatureExtractor::Create(testing::ModelFreeExtractorOptions())->Extract(cv::imread(RtabmapImage(7)));
  Keyframe k;
  k.id = 20;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(k, set); },
                                          "keyframe id 20 is already in the database"));
  EXPECT_EQ(db.size(), 2u);
  EXPECT_EQ(db.num_features(), features);
  k.id = 21;
  db.AddKeyframe(k, set);
  EXPECT_EQ(db.size(), 3u);
  EXPECT_EQ(db.num_features(), features + set.size());
}

// ---- names, strings, keypoints and rows from a hostile file ------------------
// (issue 17's hostile-input probe: each family crafted checksum-valid, so the
// decoder's own checks must catch it).

// A database saved in `dir` from `bytes` (a keyframe file image) resealed,
// with a manifest that agrees with it: the checksums pass.
void WriteResealedDatabase(const std::string& dir, const std::string& name,
                           const nlohmann::json& manifest, std::string bytes) {
  const uint64_t checksum = keyframe_file::Reseal(&bytes, true);
  WriteBytes(dir + "/" + name, bytes);
  nlohmann::json m = manifest;
  m["files"]["keyframes_bytes"] = bytes.size();
  m["files"]["keyframes_checksum"] = ChecksumHex(checksum);
  WriteBytes(dir + "/manifest.json", m.dump(2));
}

// Where things lie in a saved keyframe file.
struct FileLayout {
  explicit FileLayout(const std::string& bytes) : bytes_(bytes) {}
  uint64_t Section(uint32_t kind) const { return SectionOffsetIn(bytes_, kind); }
  size_t Record(size_t i) const { return Section(keyframe_file::kKeyframes) + 152 * i; }
  template <typename T>
  T Get(size_t at) const {
    T v;
    std::memcpy(&v, &bytes_[at], sizeof(T));
    return v;
  }
  const std::string& bytes_;
};

template <typename T>
void PutAt(std::string* bytes, size_t at, T value) {
  std::memcpy(&(*bytes)[at], &value, sizeof(T));
}

// Keyframe i's source and stored-image name replaced (they must fit in the
// bytes its strings take now).
// The bytes record `i`'s source and stored-image name take in the strings
// section, which SetStrings may fill.
size_t StringRoom(const std::string& bytes, size_t i) {
  const FileLayout f(bytes);
  const size_t r = f.Record(i);
  return f.Get<uint32_t>(r + 132) + f.Get<uint32_t>(r + 144);
}

bool SetStrings(std::string* bytes, size_t i, const std::string& source, const std::string& image) {
  const FileLayout f(*bytes);
  const size_t r = f.Record(i);
  const uint64_t offset = f.Get<uint64_t>(r + 136);
  if (source.size() + image.size() > StringRoom(*bytes, i)) return false;
  const size_t at = f.Section(keyframe_file::kStrings) + offset;
  std::memcpy(&(*bytes)[at], source.data(), source.size());
  std::memcpy(&(*bytes)[at + source.size()], image.data(), image.size());
  PutAt<uint32_t>(bytes, r + 132, static_cast<uint32_t>(source.size()));
  PutAt<uint32_t>(bytes, r + 144, static_cast<uint32_t>(image.size()));
  return true;
}

// Whether `name`, joined to `dir`, names a file directly inside dir/images:
// the oracle the decoder's rule is held to (lexically, as a path).
bool InsideImages(const std::string& dir, const std::string& name) {
  if (name.empty()) return true;
  const fs::path joined = (fs::path(dir) / name).lexically_normal();
  return joined.parent_path() == (fs::path(dir) / "images").lexically_normal() &&
         joined.filename() != "." && joined.filename() != "..";
}

TEST_F(DatabaseFileTest, StoredImageNamesStayInsideTheDatabase) {
  const std::string source = db_->keyframe(0).source.substr(0, 8);
  for (const std::string& name : {std::string("../victim.txt"),
                                  std::string("../../victim.txt"),
                                  std::string("/tmp/victim"),
                                  std::string("/etc/passwd"),
                                  std::string("images/../../victim"),
                                  std::string("images/../manifest.json"),
                                  std::string("images/a/b.png"),
                                  std::string("images//x.png"),
                                  std::string("images/"),
                                  std::string("images/."),
                                  std::string("images/.."),
                                  std::string("images/.hidden.png"),
                                  std::string("images/x\x1b[31m.png"),
                                  std::string("images/x\n.png"),
                                  std::string("images/x\0.png", 13),
                                  std::string("images/caf\xe9.png"),
                                  std::string("images\\x.png"),
                                  std::string("imagesx.png"),
                                  std::string("images/x.png/"),
                                  std::string("./images/1.png"),
                                  std::string("images/ x.png"),
                                  std::string("IMAGES/1.png"),
                                  std::string("images/x\x7f.png"),
                                  std::string("x.png")}) {
    std::string bad = bytes_;
    ASSERT_TRUE(SetStrings(&bad, 0, source, name));
    WriteResealed(bad);
    EXPECT_TRUE(
        ThrowsWith<CorruptDatabase>(LoadFn(), {"keyframe record 0 (id 10)", "stored image name"}))
        << EscapeForTerminal(name);
  }
  // Plain names load; so does a keyframe without a stored image.
  for (const std::string& name :
       std::vector<std::string>{"images/000001.png", "images/a-b_c.D9.png", ""}) {
    std::string good = bytes_;
    ASSERT_TRUE(SetStrings(&good, 0, source, name));
    WriteResealed(good);
    EXPECT_EQ(LoadVerified(Dir()).keyframe(0).image_file, name);
  }
  // A NUL cannot be in a path.
  std::string nul = bytes_;
  ASSERT_TRUE(SetStrings(&nul, 0, std::string("/data/a\0b.png", 13), "images/1.png"));
  WriteResealed(nul);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(LoadFn(), "source path holds a NUL byte"));
}

// Source paths are the user's bytes: not UTF-8, control characters, they
// open; JSON of them is valid UTF-8 and terminal text is escaped.
TEST_F(DatabaseFileTest, SourcePathsOfAnyBytesOpenAndPrintSafely) {
  const std::string source = std::string("/data/caf\xe9/\x1b[2J\n\x80\xff.png");
  std::string bytes = bytes_;
  ASSERT_TRUE(SetStrings(&bytes, 0, source, "images/1.png"));
  WriteResealed(bytes);
  const Database db = LoadVerified(Dir());
  ASSERT_EQ(db.keyframe(0).source, source);
  const std::string text = DumpJson(nlohmann::json{{"source", db.keyframe(0).source}});
  EXPECT_TRUE(IsValidUtf8(text));
  const std::string dumped = nlohmann::json::parse(text)["source"].get<std::string>();
  EXPECT_EQ(dumped.compare(0, 9, "/data/caf"), 0) << dumped;
  EXPECT_NE(dumped.find("\xef\xbf\xbd"), std::string::npos) << dumped;  // U+FFFD
  EXPECT_NE(dumped.find("\x1b[2J\n"), std::string::npos) << dumped;     // valid UTF-8 kept
  EXPECT_EQ(EscapeForTerminal(source), "/data/caf\\xe9/\\x1b[2J\\x0a\\x80\\xff.png");
}

// A compact keypoint's position code c (u16) in a 160 x 120 stored image is
// c / 256 - 1 px (8 fraction bits).
uint16_t PositionCode(float px) { return static_cast<uint16_t>(std::lround((px + 1.0f) * 256.0f)); }

TEST_F(DatabaseFileTest, KeypointsLieInsideTheStoredImage) {
  const FileLayout f(bytes_);
  // Keyframe 0's first compact keypoint: x at +0, y at +2.
  const size_t kp =
      f.Section(keyframe_file::kCompactKeypoints) + keyframe_file::kCompactKeypointPreambleBytes;
  ASSERT_EQ(db_->keyframe(0).stored_size, cv::Size(160, 120));
  // Positions below -1 px cannot be written (code 0 is -1 px), nor above
  // 65535 / 256 - 1 = 254.996 px.
  for (const auto& [at, value] :
       std::vector<std::pair<size_t, float>>{{kp, 161.5f},
                                             {kp + 2, 121.125f},
                                             {kp, 254.99609375f},
                                             {kp + 2, 200.0f},
                                             {kp + 10 * 3 + 2, 121.00390625f}}) {
    std::string bad = bytes_;
    PutAt<uint16_t>(&bad, at, PositionCode(value));
    WriteResealed(bad);
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>(
        LoadFn(), {"keyframe 10 has a keypoint outside its stored image (160x120)"}))
        << value;
  }
  // On the border and within the tolerance of a pixel: loads.
  for (const auto& [at, value] : std::vector<std::pair<size_t, float>>{
           {kp, 0.0f}, {kp, -1.0f}, {kp, 160.0f}, {kp, 161.0f}, {kp + 2, 121.0f}}) {
    std::string good = bytes_;
    PutAt<uint16_t>(&good, at, PositionCode(value));
    WriteResealed(good);
    const Database db = LoadVerified(Dir());
    EXPECT_EQ(db.Keypoints(0)[0].pt.x, at == kp ? value : db_->Keypoints(0)[0].pt.x);
  }
  // A keyframe of unknown stored size (0 x 0): positions in 1/8 px, which
  // every code is inside (the largest image bounds them).
  std::string unknown = bytes_;
  PutAt<int32_t>(&unknown, f.Record(0) + 32, 0);
  PutAt<int32_t>(&unknown, f.Record(0) + 36, 0);
  PutAt<uint16_t>(&unknown, kp, 0xffff);
  WriteResealed(unknown);
  EXPECT_EQ(LoadVerified(Dir()).Keypoints(0)[0].pt.x, 8190.875f);
}

// The compact keypoint: what is kept, at which precision, and what cannot
// be kept (refused when added).
TEST(CompactKeypointTest, KeepsWhatTheStagesUse) {
  namespace ckp = compact_keypoint;
  EXPECT_EQ(ckp::FractionBits(cv::Size(160, 120)), 8);
  EXPECT_EQ(ckp::FractionBits(cv::Size(253, 10)), 8);
  EXPECT_EQ(ckp::FractionBits(cv::Size(254, 10)), 7);
  EXPECT_EQ(ckp::FractionBits(cv::Size(640, 480)), 6);
  EXPECT_EQ(ckp::FractionBits(cv::Size(0, 0)), 3);  // unknown
  EXPECT_EQ(ckp::FractionBits(cv::Size(8189, 100)), 3);
  EXPECT_EQ(ckp::FractionBits(cv::Size(65533, 100)), 0);
  EXPECT_EQ(ckp::FractionBits(cv::Size(65534, 100)), -1);
  std::mt19937_64 rng(33);
  std::uniform_real_distribution<float> angle(0.0f, 359.99f);
  for (const int bits : {0, 3, 6, 8}) {
    std::uniform_real_distribution<float> position(-1.0f, ckp::MaxPosition(bits));
    const float step = 1.0f / static_cast<float>(1 << bits);
    for (int i = 0; i < 5000; ++i) {
      cv::KeyPoint kp(
          position(rng), position(rng), 31.0f * std::pow(1.2f, static_cast<float>(rng() % 8)),
          i % 50 == 0 ? -1.0f : angle(rng), 1e-3f, static_cast<int>(rng() % 8), i % 2 ? 1 : -1);
      ASSERT_EQ(ckp::WhyNotEncodable(kp, bits), "");
      const cv::KeyPoint q = ckp::Quantized(kp, bits);
      EXPECT_LE(std::abs(q.pt.x - kp.pt.x), step / 2 * 1.001f) << kp.pt.x;
      EXPECT_LE(std::abs(q.pt.y - kp.pt.y), step / 2 * 1.001f) << kp.pt.y;
      EXPECT_LE(std::abs(q.size - kp.size), 1.0f / 16);
      if (kp.angle < 0) {
        EXPECT_EQ(q.angle, -1.0f);
      } else {
        const float d = std::abs(q.angle - kp.angle);
        EXPECT_LE(std::min(d, 360.0f - d), 1.0f / 256 + 1e-4f) << kp.angle;
      }
      EXPECT_EQ(q.response, 0.0f);
      EXPECT_EQ(q.octave, kp.octave);
      EXPECT_EQ(q.class_id, kp.class_id);
      testing_util::ExpectSameKeypoints(std::vector<cv::KeyPoint>{ckp::Quantized(q, bits)},
                                        std::vector<cv::KeyPoint>{q});  // idempotent
    }
  }
  EXPECT_EQ(ckp::Quantized(cv::KeyPoint(3.0f, 4.0f, 7.0f, 360.0f), 3).angle, 0.0f);
  EXPECT_EQ(ckp::Quantized(cv::KeyPoint(3.0f, 4.0f, 7.0f, 725.0f), 3).angle, 5.0f);
  for (const cv::KeyPoint& bad :
       {cv::KeyPoint(-1.01f, 0, 1), cv::KeyPoint(8191.0f, 0, 1), cv::KeyPoint(0, 9000.0f, 1),
        cv::KeyPoint(0, 0, -1.0f), cv::KeyPoint(0, 0, 8192.0f), cv::KeyPoint(0, 0, 1, 0, 0, 256),
        cv::KeyPoint(0, 0, 1, 0, 0, -1), cv::KeyPoint(0, 0, 1, 0, 0, 0, 128),
        cv::KeyPoint(0, 0, 1, std::nanf("")), cv::KeyPoint(std::nanf(""), 0, 1)}) {
    EXPECT_NE(ckp::WhyNotEncodable(bad, 3), "") << bad.pt << " " << bad.size << " " << bad.octave;
  }
  EXPECT_NE(ckp::WhyNotEncodable(cv::KeyPoint(255.0f, 0, 1), 8), "");
  char record[ckp::kRecordBytes] = {};
  const uint16_t angle_code = 46080;
  std::memcpy(record + 6, &angle_code, 2);
  cv::KeyPoint out;
  EXPECT_FALSE(ckp::Decode(record, 3, &out));
  // A database keeps added keypoints quantized (a 160 x 120 stored image:
  // 1/256 px), and refuses those it cannot keep.
  Database db = MakeDatabase(testing::ModelFreeExtractorOptions(), 1, false);
  FeatureSet f = db.Features(0);
  Keyframe k = db.keyframe(0);
  ASSERT_EQ(k.stored_size, cv::Size(160, 120));
  k.id = 99;
  f.keypoints[0].pt.x = 3.333f;
  f.keypoints[0].octave = 300;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(k, f); },
                                          "keypoint octave outside [0, 255] (keypoint 0)"));
  f.keypoints[0].octave = 2;
  db.AddKeyframe(k, f);
  EXPECT_EQ(db.Keypoints(1)[0].pt.x, 3.33203125f);  // 1109 / 256 - 1
  EXPECT_EQ(db.Keypoints(1)[0].response, 0.0f);
  Keyframe huge = k;
  huge.id = 100;
  huge.stored_size = cv::Size(70000, 70000);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(huge, f); }, "65533 px"));
}

ExtractorOptions SmallSurf() {
  ExtractorOptions options = testing::ModelFreeExtractorOptions();
  options.type = FeatureType::kSurf;
  options.surf.max_features = 60;
  return options;
}

TEST(DatabaseRowsTest, NonFiniteSurfRowsAreRefused) {
  TempDir tmp;
  const Database surf = MakeDatabase(SmallSurf(), 2, false);
  const std::string name = surf.Save(tmp.Path()).keyframes_file;
  const std::string bytes = ReadFileToString(tmp.Path(name));
  const nlohmann::json manifest =
      nlohmann::json::parse(ReadFileToString(tmp.Path("manifest.json")));
  const size_t rows = FileLayout(bytes).Section(keyframe_file::kDescriptors);
  const size_t second = rows + surf.FeatureCount(0) * 256;  // keyframe 20's first row
  for (const auto& [at, value] : std::vector<std::pair<size_t, float>>{
           {rows, std::nanf("")},
           {rows + 4 * 63, std::numeric_limits<float>::infinity()},
           {second + 8, -std::numeric_limits<float>::infinity()},
           {rows + surf.num_features() * 256 - 4, std::nanf("7")}}) {
    std::string bad = bytes;
    PutAt<float>(&bad, at, value);
    WriteResealedDatabase(tmp.Path(), name, manifest, bad);
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { LoadVerified(tmp.Path()); },
                                            "has a SURF descriptor value that is not finite"));
  }
  // A subset that leaves the damaged keyframe out opens; the checksum still
  // covers every row.
  std::string bad = bytes;
  PutAt<float>(&bad, second + 8, std::nanf(""));
  WriteResealedDatabase(tmp.Path(), name, manifest, bad);
  EXPECT_EQ(LoadVerified(tmp.Path(), KeyframeSubset::Ids({10})).size(), 1u);
  keyframe_file::Reseal(&bad, true);  // as written: the manifest agrees with its header
  bad[second + 100] ^= 1;
  WriteBytes(tmp.Path(name), bad);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { LoadVerified(tmp.Path()); },
                                          "descriptor section checksum mismatch"));
  // Large but finite values are data.
  std::string big = bytes;
  PutAt<float>(&big, rows, 3e38f);
  WriteResealedDatabase(tmp.Path(), name, manifest, big);
  EXPECT_EQ(LoadVerified(tmp.Path()).size(), 2u);
}

// The same rules for features from outside: AddKeyframe and a query's.
TEST(DatabaseRowsTest, AddedAndQueryFeaturesAreChecked) {
  Database db = MakeDatabase(SmallSurf(), 1, false);
  const Keyframe model = db.keyframe(0);
  const FeatureSet features = db.Features(0);
  ASSERT_GT(features.size(), 3u);
  Keyframe k = model;
  k.id = 77;
  for (const std::string& name :
       std::vector<std::string>{"../victim.png", "/tmp/x.png", "images/a/b.png"}) {
    k.image_file = name;
    EXPECT_TRUE(
        ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(k, features); }, "stored image name"))
        << name;
  }
  k.image_file = "images/000077.png";
  FeatureSet outside = features;
  outside.keypoints[2].pt.x = -5.0f;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(k, outside); },
                                          "keypoint outside its stored image"));
  outside.keypoints[2].pt = {1e30f, 3.0f};
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(k, outside); },
                                          "keypoint outside its stored image"));
  FeatureSet nan_row = features;
  nan_row.descriptors = features.descriptors.clone();
  nan_row.descriptors.at<float>(1, 5) = std::nanf("");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddKeyframe(k, nan_row); },
                                          "SURF descriptor value that is not finite"));
  EXPECT_EQ(db.size(), 1u);
  db.AddKeyframe(k, features);
  EXPECT_EQ(db.size(), 2u);

  // A query's features: no image size to hold them to but the largest.
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ValidateQueryFeatures(nan_row, db); },
                                          "SURF descriptor value that is not finite"));
  FeatureSet far = features;
  far.keypoints[0].pt.y = 1e30f;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ValidateQueryFeatures(far, db); },
                                          "largest possible image"));
  ValidateQueryFeatures(features, db);
}

// The mutation families of issue 17, each database checksum-valid: stored
// image names, source strings of any bytes, keypoint positions, SURF rows.
// What loads must hold to the rules (names inside images/, strings that
// print and dump safely, keypoints within a pixel of the stored image,
// finite rows); what breaks them must be refused, with
// CorruptDatabase.
TEST_F(DatabaseFileTest, MutatedNamesStringsKeypointsAndRows) {
  std::mt19937_64 rng(20261717);
  const FileLayout f(bytes_);
  const std::vector<std::string> pieces = {"images/",
                                           "images",
                                           "../",
                                           "..",
                                           ".",
                                           "/",
                                           "//",
                                           "a",
                                           "000001.png",
                                           "\x1b",
                                           "\n",
                                           "\r",
                                           std::string(1, '\0'),
                                           "\xe9",
                                           "\xc3\xa9",
                                           "\\",
                                           " ",
                                           "-",
                                           "_",
                                           "~",
                                           "$HOME",
                                           "*",
                                           "\x7f",
                                           "\xc2\x9b",
                                           "%2e%2e"};
  int names_loaded = 0, names_refused = 0;
  for (int i = 0; i < 400; ++i) {
    std::string name;
    if (rng() % 4 == 0) {
      name = "images/";
      for (size_t n = rng() % 12; n > 0; --n) name += static_cast<char>(rng() % 256);
    } else {
      for (size_t n = 1 + rng() % 5; n > 0; --n) name += pieces[rng() % pieces.size()];
    }
    const size_t k = rng() % 3;
    std::string bad = bytes_;
    if (!SetStrings(&bad, k, "", name)) continue;
    WriteResealed(bad);
    try {
      const Database db = LoadVerified(Dir());
      ++names_loaded;
      for (const Keyframe& kf : db.keyframes()) {
        EXPECT_TRUE(InsideImages(Dir(), kf.image_file)) << EscapeForTerminal(kf.image_file);
        for (const char c : kf.image_file) EXPECT_TRUE(c > 0x20 && c < 0x7f) << int{c};
      }
    } catch (const CorruptDatabase& e) {
      ++names_refused;
      EXPECT_FALSE(InsideImages(Dir(), name) && IsPlainFileName(name.substr(7)) &&
                   name.compare(0, 7, "images/") == 0)
          << e.what();
    }
  }
  EXPECT_GT(names_refused, 300);
  // Strings of any bytes but NUL: always open, dump and print safely.
  for (int i = 0; i < 200; ++i) {
    // Up to 40 bytes, within the record's room: the fixture's source is a
    // path into the checkout, as short as the checkout's own path.
    const size_t k = rng() % 3;
    std::string source;
    for (size_t n = 1 + rng() % std::min<size_t>(40, StringRoom(bytes_, k)); n > 0; --n)
      source += static_cast<char>(1 + rng() % 255);
    std::string bytes = bytes_;
    ASSERT_TRUE(SetStrings(&bytes, k, source, ""));
    WriteResealed(bytes);
    const Database db = LoadVerified(Dir());
    EXPECT_EQ(db.keyframe(k).source, source);
    nlohmann::json j = nlohmann::json::object();
    for (const Keyframe& kf : db.keyframes()) j["sources"].push_back(kf.source);
    const std::string text = DumpJson(j, i % 2 ? 2 : -1);
    EXPECT_TRUE(IsValidUtf8(text));
    EXPECT_NO_THROW(nlohmann::json::parse(text));
    const std::string shown = EscapeForTerminal(source);
    EXPECT_TRUE(IsValidUtf8(shown));
    for (const char c : shown) EXPECT_FALSE((c >= 0 && c < 0x20) || c == 0x7f);
  }
  // Keypoint positions (compact codes of a 160 x 120 stored image,
  // c / 256 - 1 px): refused exactly when outside [-1, side + 1].
  const size_t kp =
      f.Section(keyframe_file::kCompactKeypoints) + keyframe_file::kCompactKeypointPreambleBytes;
  const uint64_t features = db_->num_features();
  const uint16_t specials[] = {0,     1,     255,   256,   257,    41216,  41472,
                               41473, 30976, 31232, 31233, 0x7fff, 0xfffe, 0xffff};
  int kp_loaded = 0, kp_refused = 0;
  for (int i = 0; i < 400; ++i) {
    const uint64_t row = rng() % features;
    const bool y = rng() % 2;
    const uint16_t code = rng() % 3 == 0 ? specials[rng() % (sizeof(specials) / 2)]
                                         : static_cast<uint16_t>(rng() % 45000);
    std::string bad = bytes_;
    PutAt<uint16_t>(&bad, kp + row * 10 + (y ? 2 : 0), code);
    WriteResealed(bad);
    const float value = code / 256.0f - 1.0f;
    const float side = y ? 120.0f : 160.0f;
    const bool possible = value >= -1.0f && value <= side + 1.0f;
    try {
      LoadVerified(Dir());
      ++kp_loaded;
      EXPECT_TRUE(possible) << value;
    } catch (const CorruptDatabase& e) {
      ++kp_refused;
      EXPECT_FALSE(possible) << value << ": " << e.what();
    }
  }
  EXPECT_GT(kp_loaded, 50);
  EXPECT_GT(kp_refused, 50);
}

TEST(DatabaseRowsTest, MutatedSurfRows) {
  TempDir tmp;
  const Database surf = MakeDatabase(SmallSurf(), 3, false);
  const std::string name = surf.Save(tmp.Path()).keyframes_file;
  const std::string bytes = ReadFileToString(tmp.Path(name));
  const nlohmann::json manifest =
      nlohmann::json::parse(ReadFileToString(tmp.Path("manifest.json")));
  const size_t rows = FileLayout(bytes).Section(keyframe_file::kDescriptors);
  const size_t floats = surf.num_features() * 64;
  std::mt19937_64 rng(1717);
  int loaded = 0, refused = 0;
  for (int i = 0; i < 300; ++i) {
    std::string bad = bytes;
    const size_t at = rows + 4 * (rng() % floats);
    uint32_t bits = static_cast<uint32_t>(rng());
    if (rng() % 2) bits |= 0x7f800000u;  // inf or NaN, any sign and payload
    PutAt<uint32_t>(&bad, at, bits);
    float value;
    std::memcpy(&value, &bits, 4);
    WriteResealedDatabase(tmp.Path(), name, manifest, bad);
    try {
      LoadVerified(tmp.Path());
      ++loaded;
      EXPECT_TRUE(std::isfinite(value)) << bits;
    } catch (const CorruptDatabase& e) {
      ++refused;
      EXPECT_FALSE(std::isfinite(value)) << e.what();
    }
  }
  EXPECT_GT(loaded, 50);
  EXPECT_GT(refused, 50);
}

}  // namespace
}  // namespace placedb
