#include "placedb/index/database.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "placedb/feature/extractor.h"
#include "placedb/util/file_io.h"
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
// ids get a pose when `with_poses`.
Database MakeDatabase(const ExtractorOptions& options, int n, bool with_poses) {
  const auto extractor = FeatureExtractor::Create(options);
  const int bytes = options.type == FeatureType::kOrb ? 32 : (options.surf.extended ? 128 : 64) * 4;
  Database db(options.type, bytes);
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
  ASSERT_EQ(a.pose.has_value(), b.pose.has_value()) << "keyframe " << a.id;
  if (a.pose) {
    EXPECT_EQ(a.pose->translation, b.pose->translation);
    EXPECT_EQ(a.pose->rotation.coeffs(), b.pose->rotation.coeffs());
  }
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
    ASSERT_EQ(da.laplacian == nullptr, dbk.laplacian == nullptr);
    if (da.laplacian != nullptr && da.rows > 0) {
      EXPECT_EQ(0, std::memcmp(da.laplacian, dbk.laplacian, da.rows));
    }
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
  EXPECT_TRUE(fs::exists(tmp.Path("keyframes.bin")));
  const Database loaded = Database::Load(tmp.Path());
  ExpectDatabasesEqual(db, loaded);
  ExpectInfoPreserved(db.info(), loaded.info());
  EXPECT_EQ(loaded.info()["format"], "placedb-database");
  EXPECT_EQ(loaded.info()["format_version"], kDatabaseFormatVersion);
  EXPECT_EQ(loaded.info()["feature_type"], FeatureTypeName(options.type));
  EXPECT_EQ(loaded.info()["counts"]["keyframes"], 3u);
  EXPECT_EQ(loaded.info()["counts"]["features"], db.num_features());
  EXPECT_EQ(loaded.info()["files"]["keyframes_bytes"], FileSize(tmp.Path("keyframes.bin")));
  EXPECT_EQ(loaded.IndexOfId(20), 1);
  EXPECT_EQ(loaded.IndexOfId(2), -1);
  EXPECT_EQ(loaded.keyframe(0).pose.has_value(), with_poses);
  EXPECT_FALSE(loaded.keyframe(1).pose.has_value());

  // Saving the loaded database again gives the same bytes and manifest.
  const std::string bin1 = ReadFileToString(tmp.Path("keyframes.bin"));
  const std::string dir2 = tmp.Path("again");
  fs::create_directories(dir2);
  loaded.Save(dir2);
  EXPECT_EQ(ReadFileToString(dir2 + "/keyframes.bin"), bin1);
  const Database loaded2 = Database::Load(dir2);
  ExpectDatabasesEqual(db, loaded2);
  EXPECT_EQ(loaded2.info(), loaded.info());
}

TEST(DatabaseTest, RoundTripOrbWithPoses) { RoundTrip(ExtractorOptions(), /*with_poses=*/true); }

TEST(DatabaseTest, RoundTripOrbWithoutPoses) {
  RoundTrip(ExtractorOptions(), /*with_poses=*/false);
}

TEST(DatabaseTest, RoundTripSurf) {
  ExtractorOptions options;
  options.type = FeatureType::kSurf;
  options.surf.max_features = 200;
  RoundTrip(options, /*with_poses=*/true);
  // Laplacian signs come back and both signs are present.
  TempDir tmp;
  const Database db = MakeDatabase(options, 1, false);
  EXPECT_EQ(db.descriptor_bytes(), 256);
  db.Save(tmp.Path());
  const Database loaded = Database::Load(tmp.Path());
  EXPECT_EQ(loaded.feature_type(), FeatureType::kSurf);
  const DescriptorBlock block = loaded.Descriptors(0);
  ASSERT_NE(block.laplacian, nullptr);
  int positive = 0, negative = 0;
  for (int r = 0; r < block.rows; ++r) (block.laplacian[r] > 0 ? positive : negative)++;
  EXPECT_GT(positive, 0);
  EXPECT_GT(negative, 0);
}

TEST(DatabaseTest, LoadedDatabaseGrowsAndOutlivesItsFiles) {
  // A loaded database uses its descriptors in place in the mapped file; the
  // first added keyframe copies them, and a rebuild replacing the files on
  // disk does not disturb a database already open.
  TempDir tmp;
  const Database three = MakeDatabase(ExtractorOptions(), 3, true);
  three.Save(tmp.Path());
  Database loaded = Database::Load(tmp.Path());
  MakeDatabase(ExtractorOptions(), 1, false).Save(tmp.Path());  // files replaced
  ExpectDatabasesEqual(three, loaded);

  const Database four = MakeDatabase(ExtractorOptions(), 4, true);
  FeatureSet extra;
  extra.type = FeatureType::kOrb;
  extra.keypoints = four.Keypoints(3);
  const DescriptorBlock block = four.Descriptors(3);
  extra.descriptors = cv::Mat(block.rows, 32, CV_8U, const_cast<uint8_t*>(block.data)).clone();
  loaded.AddKeyframe(four.keyframe(3), extra);
  loaded.info() = four.info();
  ExpectDatabasesEqual(four, loaded);
  TempDir again;
  loaded.Save(again.Path());
  ExpectDatabasesEqual(four, Database::Load(again.Path()));
}

TEST(DatabaseTest, EmptyDatabaseRoundTrip) {
  TempDir tmp;
  Database db(FeatureType::kOrb, 32);
  db.Save(tmp.Path());
  const Database loaded = Database::Load(tmp.Path());
  EXPECT_TRUE(loaded.empty());
  EXPECT_EQ(loaded.num_features(), 0u);
  EXPECT_EQ(loaded.feature_type(), FeatureType::kOrb);
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
    if (a.laplacian != nullptr && a.rows > 0) {
      EXPECT_EQ(0, std::memcmp(a.laplacian, b.laplacian, a.rows));
    }
  }
}

TEST(DatabaseTest, SubsetsOpenOnlyTheirKeyframes) {
  ExtractorOptions surf;
  surf.type = FeatureType::kSurf;
  surf.surf.max_features = 60;
  for (const ExtractorOptions& options : {ExtractorOptions(), surf}) {
    TempDir tmp;
    MakeDatabase(options, 7, true).Save(tmp.Path());
    const Database whole = Database::Load(tmp.Path());
    ASSERT_EQ(whole.size(), 7u);
    for (const PartitionScheme scheme :
         {PartitionScheme::kContiguous, PartitionScheme::kInterleaved}) {
      for (int parts : {1, 2, 3, 7, 9}) {
        size_t keyframes = 0, features = 0;
        for (int p = 0; p < parts; ++p) {
          const Database part =
              Database::Load(tmp.Path(), KeyframeSubset::Partition(p, parts, scheme));
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
    const Database middle = Database::Load(tmp.Path(), KeyframeSubset::Partition(1, 3));
    ASSERT_EQ(middle.size(), 2u);
    EXPECT_EQ(middle.keyframe(0).id, 30);
    EXPECT_EQ(middle.keyframe(1).id, 40);
    // An id list, in any order, duplicates ignored.
    const Database ids = Database::Load(tmp.Path(), KeyframeSubset::Ids({60, 10, 60}));
    ASSERT_EQ(ids.size(), 2u);
    EXPECT_EQ(ids.keyframe(0).id, 10);
    EXPECT_EQ(ids.keyframe(1).id, 60);
    EXPECT_EQ(ids.IndexOfId(60), 1);
    EXPECT_EQ(ids.IndexOfId(20), -1);
    ExpectSubsetOf(whole, ids);
    EXPECT_TRUE(ThrowsWith<std::invalid_argument>(
        [&] {
          Database::Load(tmp.Path(), KeyframeSubset::Ids({10, 15}));
        },
        "keyframe id 15 is not in the database"));
    EXPECT_TRUE(ThrowsWith<std::invalid_argument>(
        [&] { Database::Load(tmp.Path(), KeyframeSubset::Partition(3, 3)); }, "part must be in"));
    // A subset saved is a database of that subset; it grows like any other.
    TempDir saved;
    Database copy = ids;
    copy.Save(saved.Path());
    const Database reloaded = Database::Load(saved.Path());
    ExpectDatabasesEqual(ids, reloaded);
    FeatureSet extra;
    extra.type = options.type;
    extra.keypoints = whole.Keypoints(3);
    const DescriptorBlock block = whole.Descriptors(3);
    extra.descriptors =
        options.type == FeatureType::kOrb
            ? cv::Mat(block.rows, 32, CV_8U, const_cast<uint8_t*>(block.data)).clone()
            : cv::Mat(block.rows, 64, CV_32F, const_cast<uint8_t*>(block.data)).clone();
    copy.AddKeyframe(whole.keyframe(3), extra);  // copy on write of a mapped subset
    ASSERT_EQ(copy.size(), 3u);
    ExpectSubsetOf(whole, copy);
  }
}

// A saved 3-keyframe ORB database each corruption test starts from.
class DatabaseFileTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { db_ = new Database(MakeDatabase(ExtractorOptions(), 3, true)); }
  static void TearDownTestSuite() {
    delete db_;
    db_ = nullptr;
  }
  void SetUp() override {
    db_->Save(tmp_.Path());
    bin_ = tmp_.Path("keyframes.bin");
    bytes_ = ReadFileToString(bin_);
    ASSERT_GT(bytes_.size(), 1000u);
  }
  std::string Dir() const { return tmp_.Path(); }
  auto LoadFn() const {
    return [dir = Dir()] { Database::Load(dir); };
  }

  static Database* db_;
  TempDir tmp_;
  std::string bin_;
  std::string bytes_;
};
Database* DatabaseFileTest::db_ = nullptr;

TEST_F(DatabaseFileTest, TruncatedKeyframesFile) {
  const size_t header = 8 + 4 * 4 + 3 * 8;  // magic, 4 x u32, 3 x u64
  const size_t size = bytes_.size();
  for (size_t cut : {size_t{0}, size_t{4}, size_t{10}, size_t{20}, header, header + 100,
                     header + 3 * 152 + 50, size / 2, size - 5, size - 1}) {
    WriteBytes(bin_, bytes_.substr(0, cut));
    EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "truncated")) << "cut at " << cut;
  }
  // The intact file loads again.
  WriteBytes(bin_, bytes_);
  EXPECT_EQ(Database::Load(Dir()).size(), 3u);
}

TEST_F(DatabaseFileTest, CorruptedByteFailsChecksum) {
  for (size_t at : {bytes_.size() / 2, bytes_.size() / 3, bytes_.size() - 10}) {
    std::string bad = bytes_;
    bad[at] = static_cast<char>(bad[at] ^ 0x10);
    WriteBytes(bin_, bad);
    EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "checksum mismatch")) << "byte " << at;
  }
  // Trailing garbage is caught too.
  WriteBytes(bin_, bytes_ + "xyz");
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "unexpected trailing bytes"));
}

TEST_F(DatabaseFileTest, WrongVersionInBinary) {
  std::string bad = bytes_;
  const uint32_t version = kDatabaseFormatVersion + 1;
  std::memcpy(&bad[8], &version, 4);
  const uint32_t crc = Crc32(bad.data(), bad.size() - 4);  // only the version is wrong
  std::memcpy(&bad[bad.size() - 4], &crc, 4);
  WriteBytes(bin_, bad);
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(
      LoadFn(), "format version " + std::to_string(version) + " is not supported"));
}

TEST_F(DatabaseFileTest, DuplicateKeyframeIdInFile) {
  // Keyframe records start after the 48-byte header, 152 bytes each, id first.
  std::string bad = bytes_;
  std::memcpy(&bad[48 + 152], &bad[48], 4);  // record 1 gets record 0's id
  const uint32_t crc = Crc32(bad.data(), bad.size() - 4);
  std::memcpy(&bad[bad.size() - 4], &crc, 4);
  WriteBytes(bin_, bad);
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "appears twice"));
}

TEST_F(DatabaseFileTest, WrongVersionInManifest) {
  nlohmann::json manifest = nlohmann::json::parse(ReadFileToString(Dir() + "/manifest.json"));
  manifest["format_version"] = kDatabaseFormatVersion + 1;
  WriteBytes(Dir() + "/manifest.json", manifest.dump(2));
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(
      LoadFn(), "database format version " + std::to_string(kDatabaseFormatVersion + 1) +
                    " is not supported"));
}

TEST_F(DatabaseFileTest, WrongMagic) {
  std::string bad = bytes_;
  bad[0] = 'X';
  WriteBytes(bin_, bad);
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "wrong magic"));
  WriteBytes(bin_, "this is a text file, not a database\n");
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "wrong magic"));
}

TEST_F(DatabaseFileTest, ManifestFeatureTypeDisagreesWithBinary) {
  nlohmann::json manifest = nlohmann::json::parse(ReadFileToString(Dir() + "/manifest.json"));
  ASSERT_EQ(manifest["feature_type"], "orb");
  manifest["feature_type"] = "surf";
  WriteBytes(Dir() + "/manifest.json", manifest.dump(2));
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "manifest says 'surf' features but"));
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "holds 'orb' features"));
}

TEST_F(DatabaseFileTest, ManifestCountDisagreesWithBinary) {
  nlohmann::json manifest = nlohmann::json::parse(ReadFileToString(Dir() + "/manifest.json"));
  manifest["counts"]["keyframes"] = 4;
  WriteBytes(Dir() + "/manifest.json", manifest.dump(2));
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "disagree on the number of keyframes"));
}

TEST_F(DatabaseFileTest, MissingManifest) {
  fs::remove(Dir() + "/manifest.json");
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "manifest.json is missing"));
}

TEST_F(DatabaseFileTest, MissingKeyframesFile) {
  fs::remove(bin_);
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "keyframes.bin is missing"));
}

TEST_F(DatabaseFileTest, NotADirectory) {
  EXPECT_TRUE(ThrowsWith<std::runtime_error>([&] { Database::Load(Dir() + "/nothing_here"); },
                                             "(not a directory)"));
  EXPECT_TRUE(ThrowsWith<std::runtime_error>([&] { Database::Load(bin_); }, "(not a directory)"));
}

TEST_F(DatabaseFileTest, ManifestNotJson) {
  fs::copy_file(Dir() + "/manifest.json", Dir() + "/manifest.json.bak");
  WriteBytes(Dir() + "/manifest.json", "{ not json");
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "not valid JSON"));
  WriteBytes(Dir() + "/manifest.json", "{\"format\": \"something-else\"}");
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "not a placedb database manifest"));
  WriteBytes(Dir() + "/manifest.json", "[1, 2, 3]");
  EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "not a placedb database manifest"));
  // Fields of the wrong JSON type: a runtime_error, not nlohmann's type_error.
  const nlohmann::json good = nlohmann::json::parse(ReadFileToString(Dir() + "/manifest.json.bak"));
  for (const char* field : {"format", "format_version", "feature_type", "counts"}) {
    nlohmann::json bad = good;
    bad[field] = field == std::string("format") ? nlohmann::json(7) : nlohmann::json("x");
    if (field == std::string("feature_type")) bad[field] = 3;
    WriteBytes(Dir() + "/manifest.json", bad.dump());
    EXPECT_TRUE(ThrowsWith<std::runtime_error>(LoadFn(), "malformed manifest")) << field;
  }
  WriteBytes(Dir() + "/manifest.json", good.dump());
  EXPECT_EQ(Database::Load(Dir()).size(), 3u);
}

TEST(DatabaseTest, AddingSurfFeaturesToOrbDatabaseThrows) {
  Database db = MakeDatabase(ExtractorOptions(), 1, false);
  ASSERT_EQ(db.size(), 1u);
  ExtractorOptions surf;
  surf.type = FeatureType::kSurf;
  surf.surf.max_features = 50;
  const FeatureSet features = FeatureExtractor::Create(surf)->Extract(cv::imread(RtabmapImage(5)));
  ASSERT_FALSE(features.empty());
  Keyframe k;
  k.id = 99;
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { db.AddKeyframe(k, features); },
                                                "cannot add surf features to a database of orb"));
  EXPECT_EQ(db.size(), 1u);  // unchanged
  // A SURF database refuses ORB features the same way.
  Database surf_db(FeatureType::kSurf, 256);
  const FeatureSet orb =
      FeatureExtractor::Create(ExtractorOptions())->Extract(cv::imread(RtabmapImage(5)));
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { surf_db.AddKeyframe(k, orb); },
                                                "cannot add orb features to a database of surf"));
  EXPECT_TRUE(surf_db.empty());
}

TEST(DatabaseTest, DuplicateKeyframeIdThrows) {
  Database db = MakeDatabase(ExtractorOptions(), 2, false);  // ids 10, 20
  const size_t features = db.num_features();
  const FeatureSet set =
      FeatureExtractor::Create(ExtractorOptions())->Extract(cv::imread(RtabmapImage(7)));
  Keyframe k;
  k.id = 20;
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { db.AddKeyframe(k, set); },
                                                "duplicate keyframe id 20"));
  EXPECT_EQ(db.size(), 2u);
  EXPECT_EQ(db.num_features(), features);
  k.id = 21;
  db.AddKeyframe(k, set);
  EXPECT_EQ(db.size(), 3u);
  EXPECT_EQ(db.num_features(), features + set.size());
}

}  // namespace
}  // namespace placedb
