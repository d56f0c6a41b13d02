#include "placedb/builder/builder.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <thread>

#include "placedb/builder/tracks.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/feature/whole_image.h"
#include "placedb/util/file_io.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
using testing_util::TempDir;
using testing_util::ThrowsWith;
namespace fs = std::filesystem;

const std::string kImages = PLACEDB_DATA_DIR "/rtabmap_loop/images";

BuildOptions SmallBuild() {
  BuildOptions options;
  options.threads = 2;
  options.progress = false;
  return options;
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// The bytes of the keyframe file the database at `dir` names.
std::string KeyframeFile(const std::string& dir) {
  const nlohmann::json m = nlohmann::json::parse(ReadFileToString(dir + "/manifest.json"));
  return ReadFileToString(dir + "/" + m["files"]["keyframes"].get<std::string>());
}

// Names of entries in `dir` containing ".building.".
std::vector<std::string> BuildingLeftovers(const std::string& dir) {
  std::vector<std::string> found;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    if (name.find(".building.") != std::string::npos) found.push_back(name);
  }
  return found;
}

TEST(BuilderTest, CropModesAndResizeFactors) {
  TempDir tmp;
  const std::vector<Frame> frames = ListImageFolder(kImages, 1, 10);
  ASSERT_EQ(frames.size(), 10u);
  for (CropMode crop : {CropMode::kNone, CropMode::kChroma}) {
    for (int resize : {1, 4, 16}) {
      SCOPED_TRACE(std::string("crop ") + CropModeName(crop) + " resize " + std::to_string(resize));
      BuildOptions options = SmallBuild();
      options.features.whole_image.kind = WholeImageKind::kThumbnail;  // rows without a model
      options.crop = crop;
      options.resize = resize;
      const std::string out =
          tmp.Path(std::string("db_") + CropModeName(crop) + "_" + std::to_string(resize));
      const BuildReport report = BuildDatabase(frames, options, out, "rtabmap 1..10");
      EXPECT_EQ(report.num_frames, 10u);
      EXPECT_EQ(report.num_keyframes, 10u);
      EXPECT_EQ(report.num_skipped, 0u);
      EXPECT_GT(report.num_features, 10u * (resize == 16 ? 5 : 50));
      const Database db = Database::Load(out);
      EXPECT_EQ(report.feature_bytes, FileSize(out + "/" + db.keyframes_file()));
      ASSERT_EQ(db.size(), 10u);
      EXPECT_EQ(db.num_features(), report.num_features);
      const double side = 1.0 / std::sqrt(static_cast<double>(resize));
      size_t cropped = 0;
      for (size_t i = 0; i < db.size(); ++i) {
        const Keyframe& k = db.keyframe(i);
        EXPECT_EQ(k.id, static_cast<int>(i) + 1);
        EXPECT_EQ(k.original_size, cv::Size(512, 384));
        EXPECT_EQ(k.source, frames[i].image_path);
        EXPECT_EQ(k.crop & cv::Rect(0, 0, 512, 384), k.crop);  // inside the image
        if (crop == CropMode::kNone) {
          EXPECT_EQ(k.crop, cv::Rect(0, 0, 512, 384));
          EXPECT_EQ(k.crop_channel, -1);
        }
        if (k.crop_channel >= 0) {
          ++cropped;
          EXPECT_LT(k.crop.area(), 512 * 384);
        }
        const cv::Size expected(static_cast<int>(std::lround(k.crop.width * side)),
                                static_cast<int>(std::lround(k.crop.height * side)));
        EXPECT_EQ(k.stored_size, expected) << "keyframe " << k.id;
        EXPECT_NEAR(k.scale, side, 0.02);
        // Keypoints lie in the stored image's frame.
        for (const cv::KeyPoint& kp : db.Keypoints(i)) {
          EXPECT_GE(kp.pt.x, 0.f);
          EXPECT_GE(kp.pt.y, 0.f);
          EXPECT_LT(kp.pt.x, k.stored_size.width);
          EXPECT_LT(kp.pt.y, k.stored_size.height);
        }
        char name[32];
        std::snprintf(name, sizeof(name), "images/%06d.png", k.id);
        EXPECT_EQ(k.image_file, name);
        // The whole-image row is the whole frame's, also when cropped or
        // resized.
        ASSERT_EQ(db.whole_image_dims(), 768);
        const cv::Mat row =
            ComputeWholeImageDescriptor(cv::imread(frames[i].image_path), WholeImageOptions());
        EXPECT_EQ(std::memcmp(db.WholeImage(i), row.data, 768), 0) << "keyframe " << k.id;
        const cv::Mat png = cv::imread(out + "/" + k.image_file, cv::IMREAD_UNCHANGED);
        ASSERT_FALSE(png.empty()) << k.image_file;
        EXPECT_EQ(png.size(), k.stored_size);
        EXPECT_EQ(png.channels(), 3);
      }
      EXPECT_EQ(report.num_cropped, cropped);
      if (crop == CropMode::kChroma) {
        EXPECT_GT(cropped, 0u);
      }

      const nlohmann::json& info = db.info();
      EXPECT_EQ(info["settings"]["crop"], CropModeName(crop));
      EXPECT_EQ(info["settings"]["resize"], resize);
      EXPECT_EQ(info["settings"]["features"]["type"], "orb");
      EXPECT_EQ(info["source"], "rtabmap 1..10");
      EXPECT_EQ(info["counts"]["frames"], 10);
      EXPECT_EQ(info["counts"]["skipped_images"], 0);
      EXPECT_EQ(info["bytes"]["images"], report.image_bytes);
      EXPECT_EQ(info["bytes"]["images"], DirectorySize(out + "/images"));
      EXPECT_EQ(info["bytes"]["full_frames_png"], report.full_png_bytes);
      if (crop == CropMode::kChroma || resize > 1) {
        EXPECT_GT(report.full_png_bytes, report.image_bytes);
      } else {
        EXPECT_EQ(report.full_png_bytes, report.image_bytes);  // the same PNGs
      }
      if (resize == 16) {
        EXPECT_LT(report.image_bytes * 4, report.full_png_bytes);
      }
      EXPECT_TRUE(BuildingLeftovers(tmp.Path()).empty());
    }
  }
}

TEST(BuilderTest, ExtractorOptionsRoundTripThroughManifest) {
  TempDir tmp;
  BuildOptions options = SmallBuild();
  options.features.orb.max_features = 123;
  options.features.orb.fast_threshold = 17;
  options.features.orb.num_levels = 5;
  options.features.orb.scale_factor = 1.3;
  options.features.surf.hessian_threshold = 321.5;
  options.features.surf.extended = true;
  options.features.surf.upright = true;
  options.features.surf.max_features = 77;
  options.features.surf.num_octaves = 3;
  options.store_images = false;
  const BuildReport report =
      BuildDatabase(ListImageFolder(kImages, 1, 3), options, tmp.Path("db"), "three images");
  EXPECT_EQ(report.num_keyframes, 3u);
  EXPECT_EQ(report.image_bytes, 0u);
  EXPECT_FALSE(fs::exists(tmp.Path("db/images")));
  const Database db = Database::Load(tmp.Path("db"));
  for (size_t i = 0; i < db.size(); ++i) {
    EXPECT_LE(db.FeatureCount(i), 123u);
    EXPECT_GT(db.FeatureCount(i), 50u);
    EXPECT_EQ(db.keyframe(i).image_file, "");
  }
  const BuildOptions all_back = BuildOptionsFromManifest(db.info(), "db");
  const ExtractorOptions& back = all_back.features;
  EXPECT_EQ(back.type, FeatureType::kOrb);
  EXPECT_EQ(back.orb.max_features, 123);
  EXPECT_EQ(back.orb.fast_threshold, 17);
  EXPECT_EQ(back.orb.num_levels, 5);
  EXPECT_EQ(back.orb.scale_factor, 1.3);
  EXPECT_EQ(back.orb.edge_threshold, options.features.orb.edge_threshold);
  EXPECT_EQ(back.orb.patch_size, options.features.orb.patch_size);
  EXPECT_EQ(back.surf.hessian_threshold, 321.5);
  EXPECT_TRUE(back.surf.extended);
  EXPECT_TRUE(back.surf.upright);
  EXPECT_EQ(back.surf.max_features, 77);
  EXPECT_EQ(back.surf.num_octaves, 3);
  EXPECT_EQ(back.surf.num_octave_layers, options.features.surf.num_octave_layers);
  EXPECT_EQ(back.upscale_below, options.features.upscale_below);
  EXPECT_EQ(all_back.crop, options.crop);
  EXPECT_EQ(all_back.resize, options.resize);
  EXPECT_EQ(all_back.store_images, false);
  EXPECT_EQ(all_back.crop_options.percentile, options.crop_options.percentile);

  // The SURF type round-trips too (manifest only, no build needed).
  BuildOptions surf = options;
  surf.features.type = FeatureType::kSurf;
  nlohmann::json manifest;
  manifest["settings"] = BuildSettingsToJson(surf);
  EXPECT_EQ(BuildOptionsFromManifest(manifest, "m").features.type, FeatureType::kSurf);
  // Every version 2 manifest has every setting but the index's: a missing
  // key is a damaged manifest, named.
  manifest["settings"]["features"].erase("upscale_below");
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { BuildOptionsFromManifest(manifest, "m"); },
                                          {"settings.features.upscale_below is missing"}));
}

// Every setting the manifest stores reads back as it was written, at both ends
// of its range (the vocabulary seed over all 64 bits: a seed above 2^63 was
// once written and then refused on open).
TEST(BuilderTest, EverySettingRoundTripsAtItsRangeLimits) {
  auto round_trip = [](const BuildOptions& o) {
    ASSERT_EQ(o.Check(), "");
    nlohmann::json manifest;
    manifest["settings"] = BuildSettingsToJson(o);
    const BuildOptions back = BuildOptionsFromManifest(manifest, "m");
    EXPECT_EQ(BuildSettingsToJson(back), manifest["settings"]);
    EXPECT_EQ(back.vocabulary.seed, o.vocabulary.seed);
    EXPECT_EQ(back.vocabulary.branching, o.vocabulary.branching);
    EXPECT_EQ(back.features.orb.scale_factor, o.features.orb.scale_factor);
    EXPECT_EQ(back.crop_options.min_region_pixels, o.crop_options.min_region_pixels);
  };
  BuildOptions lo;
  lo.crop = CropMode::kChroma;
  lo.resize = 1;
  lo.png_compression = 0;
  lo.store_images = false;
  lo.extract_in_context = false;
  lo.crop_options.smooth_sigma = 0.0;
  lo.crop_options.percentile = 0.0;
  lo.crop_options.padding = 0;
  lo.crop_options.min_fast_keypoints = 0;
  lo.crop_options.fast_threshold = 1;
  lo.crop_options.fast_nonmax = false;
  lo.crop_options.min_region_pixels = 1;
  lo.features.type = FeatureType::kSurf;
  lo.features.upscale_below = 0;
  lo.features.orb.max_features = 1;
  lo.features.orb.scale_factor = std::nextafter(1.0, 2.0);
  lo.features.orb.num_levels = 1;
  lo.features.orb.edge_threshold = 0;
  lo.features.orb.fast_threshold = 1;
  lo.features.orb.patch_size = 2;
  lo.features.surf.hessian_threshold = 0.0;
  lo.features.surf.num_octaves = 1;
  lo.features.surf.num_octave_layers = 1;
  lo.features.surf.extended = false;
  lo.features.surf.upright = false;
  lo.features.surf.max_features = 0;
  lo.index = IndexKind::kBow;
  lo.vocabulary.branching = 2;
  lo.vocabulary.depth = 1;
  lo.vocabulary.iterations = 1;
  lo.vocabulary.max_training_descriptors = 1000;
  lo.vocabulary.seed = 0;
  lo.bow.direct_level = 0;
  round_trip(lo);

  BuildOptions hi = lo;
  hi.crop = CropMode::kNone;
  hi.resize = 16;
  hi.png_compression = 9;
  hi.store_images = true;
  hi.extract_in_context = true;
  hi.crop_options.smooth_sigma = 50.0;
  hi.crop_options.percentile = 99.9;
  hi.crop_options.padding = 4096;
  hi.crop_options.min_fast_keypoints = 100000;
  hi.crop_options.fast_threshold = 255;
  hi.crop_options.fast_nonmax = true;
  hi.crop_options.min_region_pixels = 100000000;
  hi.features.type = FeatureType::kOrb;
  hi.features.upscale_below = 4096;
  hi.features.orb.max_features = 100000;
  hi.features.orb.scale_factor = 4.0;
  hi.features.orb.num_levels = 32;
  hi.features.orb.edge_threshold = 512;
  hi.features.orb.fast_threshold = 255;
  hi.features.orb.patch_size = 512;
  hi.features.surf.hessian_threshold = 1e6;
  hi.features.surf.num_octaves = 8;  // SurfOptions::Check's limits
  hi.features.surf.num_octave_layers = 8;
  hi.features.surf.extended = true;
  hi.features.surf.upright = true;
  hi.features.surf.max_features = 1000000;
  hi.vocabulary.branching = 64;
  hi.vocabulary.depth = 4;  // 64^4 = 2^24 words, the limit
  hi.vocabulary.iterations = 100;
  hi.vocabulary.max_training_descriptors = 100000000;
  hi.vocabulary.seed = UINT64_MAX;
  hi.bow.direct_level = 4;
  round_trip(hi);
  hi.vocabulary.seed = (uint64_t{1} << 63) + 1;
  round_trip(hi);

  // A negative or fractional seed is refused, naming the field.
  nlohmann::json manifest;
  manifest["settings"] = BuildSettingsToJson(hi);
  manifest["settings"]["vocabulary"]["seed"] = -1;
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(
      [&] { BuildOptionsFromManifest(manifest, "m"); },
      {"settings.vocabulary.seed", "vocabulary_seed must be in [0, 2^64) (got -1)"}));
  manifest["settings"]["vocabulary"]["seed"] = 1.5;
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { BuildOptionsFromManifest(manifest, "m"); },
                                          {"settings.vocabulary.seed is not a whole number"}));
}

// A manifest is input from outside: every field is type-checked strictly and
// range-checked; the error names the database and the field.
TEST(BuilderTest, MalformedManifestSettingsAreRejected) {
  nlohmann::json good;
  good["settings"] = BuildSettingsToJson(SmallBuild());
  EXPECT_NO_THROW(BuildOptionsFromManifest(good, "db"));
  auto fails = [&](const std::function<void(nlohmann::json&)>& edit, const std::string& part) {
    nlohmann::json bad = good;
    edit(bad);
    return ThrowsWith<CorruptDatabase>([&] { BuildOptionsFromManifest(bad, "db"); },
                                       {"db/manifest.json", part});
  };
  EXPECT_TRUE(fails([](nlohmann::json& m) { m.erase("settings"); }, "settings is missing"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["settings"]["features"].erase("orb"); },
                    "settings.features.orb.max_features is missing"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["settings"]["crop_options"].erase("padding"); },
                    "settings.crop_options.padding is missing"));
  // A setting this placedb does not know cannot be honoured: refused, named.
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["settings"]["features"]["orb"]["wta_k"] = 2; },
                    "settings.features.orb.wta_k is not a setting this placedb knows"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["settings"]["gamma"] = 1.0; },
                    "settings.gamma is not a setting this placedb knows"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["settings"]["resize"] = true; },
                    "settings.resize is not a whole number"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["settings"]["resize"] = 3; },
                    "resize must be 1, 4 or 16 (got 3)"));
  EXPECT_TRUE(fails(
      [](nlohmann::json& m) { m["settings"]["features"]["orb"]["num_levels"] = -2147483649LL; },
      "orb_levels must be in [1, 32] (got -2147483649)"));
  EXPECT_TRUE(
      fails([](nlohmann::json& m) { m["settings"]["features"]["orb"]["num_levels"] = 100000; },
            "orb_levels must be in [1, 32] (got 100000)"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["settings"]["features"]["surf"]["extended"] = 1; },
                    "extended is not true or false"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["settings"]["crop_options"]["smooth_sigma"] = 1e6; },
                    "crop_sigma must be in [0, 50] (got 1000000)"));
  EXPECT_TRUE(
      fails([](nlohmann::json& m) { m["settings"]["crop"] = "square"; }, "unknown crop mode"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m["settings"]["features"]["type"] = 2; },
                    "settings.features.type is not a string"));
  EXPECT_TRUE(fails([](nlohmann::json& m) { m = nlohmann::json::array(); }, "not a JSON object"));
}

// Build options are range-checked (NaN included) before any work starts.
TEST(BuilderTest, BuildOptionRanges) {
  BuildOptions o = SmallBuild();
  EXPECT_EQ(o.Check(), "");
  o.crop_options.smooth_sigma = std::nan("");
  EXPECT_NE(o.Check().find("`crop_sigma` must be in [0, 50] (got nan)"), std::string::npos);
  o = SmallBuild();
  o.crop_options.padding = 2147483647;
  EXPECT_NE(o.Check().find("`crop_padding` must be in [0, 4096]"), std::string::npos);
  o = SmallBuild();
  o.threads = -1;
  EXPECT_NE(o.Check().find("threads"), std::string::npos);
  o = SmallBuild();
  o.resize = 2;
  EXPECT_NE(o.Check().find("resize"), std::string::npos);
  o = SmallBuild();
  o.png_compression = 10;
  EXPECT_NE(o.Check().find("png_compression"), std::string::npos);
}

TEST(BuilderTest, SurfDatabase) {
  TempDir tmp;
  BuildOptions options = SmallBuild();
  options.features.type = FeatureType::kSurf;
  options.features.surf.max_features = 150;
  options.resize = 4;
  const BuildReport report =
      BuildDatabase(ListImageFolder(kImages, 1, 3), options, tmp.Path("db"), "surf");
  EXPECT_EQ(report.num_keyframes, 3u);
  const Database db = Database::Load(tmp.Path("db"));
  EXPECT_EQ(db.feature_type(), FeatureType::kSurf);
  EXPECT_EQ(db.descriptor_bytes(), 256);
  for (size_t i = 0; i < db.size(); ++i) {
    EXPECT_GT(db.FeatureCount(i), 20u);
    EXPECT_LE(db.FeatureCount(i), 150u);
  }
  EXPECT_EQ(db.info()["settings"]["features"]["type"], "surf");
}

TEST(BuilderTest, UnreadableImageIsSkippedOrFatalWhenStrict) {
  TempDir tmp;
  const std::string folder = tmp.Path("images");
  fs::create_directories(folder);
  for (const char* name : {"001.jpg", "002.jpg", "003.jpg"}) {
    fs::copy_file(kImages + "/" + name, folder + "/" + name);
  }
  WriteBytes(folder + "/x.jpg", "this is not a JPEG at all");
  const std::vector<Frame> frames = ListImageFolder(folder);
  ASSERT_EQ(frames.size(), 4u);

  const BuildReport report = BuildDatabase(frames, SmallBuild(), tmp.Path("db"), "mixed");
  EXPECT_EQ(report.num_frames, 4u);
  EXPECT_EQ(report.num_keyframes, 3u);
  EXPECT_EQ(report.num_skipped, 1u);
  ASSERT_EQ(report.skipped.size(), 1u);
  EXPECT_EQ(fs::path(report.skipped[0]).filename(), "x.jpg");
  const Database db = Database::Load(tmp.Path("db"));
  EXPECT_EQ(db.size(), 3u);
  EXPECT_EQ(db.IndexOfId(4), -1);  // x.jpg was frame 4
  EXPECT_EQ(db.info()["counts"]["skipped_images"], 1);
  EXPECT_EQ(db.info()["counts"]["frames"], 4);

  BuildOptions strict = SmallBuild();
  strict.strict = true;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { BuildDatabase(frames, strict, tmp.Path("strict_db"), "mixed"); },
      {"cannot read image", "x.jpg", "strict"}));
  EXPECT_FALSE(fs::exists(tmp.Path("strict_db")));
  EXPECT_TRUE(BuildingLeftovers(tmp.Path()).empty());
}

// Each keyframe records its source's content (the hash `add --skip-existing`
// compares), taken from the bytes decoded; the manifest records the next
// free id and that nothing was removed yet.
TEST(BuilderTest, KeyframesRecordTheirSourceHashAndTheManifestItsIds) {
  TempDir tmp;
  BuildDatabase(ListImageFolder(kImages, 3, 5), SmallBuild(), tmp.Path("db"), "rtabmap 3..5");
  const Database db = Database::Load(tmp.Path("db"));
  ASSERT_EQ(db.size(), 3u);
  for (const Keyframe& k : db.keyframes()) {
    const std::string bytes = ReadFileToString(k.source);
    EXPECT_EQ(k.source_hash, SourceHash(bytes.data(), bytes.size())) << k.id;
    EXPECT_NE(k.source_hash, 0u);
  }
  EXPECT_NE(db.keyframe(0).source_hash, db.keyframe(1).source_hash);
  const nlohmann::json& ids = db.info()["ids"];
  EXPECT_EQ(ids["next_free"], 6);
  EXPECT_EQ(ids["removed"], 0);
  EXPECT_EQ(ids["removed_since"], db.info()["created"]);
}

// The whole-image channel (the thumbnail here; HogChannelTest has the
// default HOG's): built by default (the manifest says so), of the size the
// options give; --no-whole-image builds a database without it,
// whose manifest says enabled false, and whose keyframe file is what an
// earlier placedb wrote (no whole-image section). Settings and file must
// agree: a manifest that says otherwise is a corrupt database.
TEST(BuilderTest, WholeImageChannel) {
  TempDir tmp;
  const std::vector<Frame> frames = ListImageFolder(kImages, 3, 6);
  BuildOptions options = SmallBuild();
  options.features.whole_image.kind = WholeImageKind::kThumbnail;
  options.features.whole_image.width = 16;
  options.features.whole_image.height = 12;
  options.features.whole_image.patch = 4;
  options.crop = CropMode::kChroma;
  options.extract_in_context = false;
  BuildDatabase(frames, options, tmp.Path("db"), "rtabmap 3..6");
  const Database db = Database::Load(tmp.Path("db"));
  ASSERT_EQ(db.whole_image_dims(), 192);
  EXPECT_EQ(db.info()["whole_image_dims"], 192);
  EXPECT_EQ(db.info()["settings"]["features"]["whole_image"]["enabled"], true);
  ASSERT_NE(db.WholeImageData(), nullptr);
  for (size_t i = 0; i < db.size(); ++i) {
    const cv::Mat row =
        ComputeWholeImageDescriptor(cv::imread(frames[i].image_path), options.features.whole_image);
    EXPECT_EQ(std::memcmp(db.WholeImage(i), row.data, 192), 0) << i;
    EXPECT_EQ(db.WholeImage(i), db.WholeImageData() + 192 * i);
  }
  BuildOptions without = SmallBuild();
  without.features.whole_image.enabled = false;
  BuildDatabase(frames, without, tmp.Path("plain"), "rtabmap 3..6");
  const Database plain = Database::Load(tmp.Path("plain"));
  EXPECT_EQ(plain.whole_image_dims(), 0);
  EXPECT_EQ(plain.WholeImageData(), nullptr);
  EXPECT_FALSE(plain.info().contains("whole_image_dims"));
  EXPECT_EQ(plain.info()["settings"]["features"]["whole_image"]["enabled"], false);
  // Settings read back; an older manifest (without the keys) reads as no
  // channel.
  EXPECT_EQ(BuildOptionsFromManifest(db.info(), "db").features.whole_image.width, 16);
  nlohmann::json old = plain.info();
  old["settings"]["features"].erase("whole_image");
  const BuildOptions read = BuildOptionsFromManifest(old, "plain");
  EXPECT_FALSE(read.features.whole_image.enabled);
  EXPECT_EQ(read.features.whole_image.width, 32);
  EXPECT_EQ(WholeImageDims(read.features), 0);
}

TEST(BuilderTest, StoredFeaturesKeepASubsetOfEachKeyframes) {
  TempDir tmp;
  const std::vector<Frame> frames = ListImageFolder(kImages, 3, 6);
  for (const CropMode crop : {CropMode::kNone, CropMode::kChroma}) {
    BuildOptions all = SmallBuild();
    all.crop = crop;
    BuildOptions budget = all;
    budget.stored_features = 20;
    const std::string tag = CropModeName(crop);
    BuildDatabase(frames, all, tmp.Path("all_" + tag), "rtabmap 3..6");
    BuildDatabase(frames, budget, tmp.Path("budget_" + tag), "rtabmap 3..6");
    const Database full = Database::Load(tmp.Path("all_" + tag));
    const Database kept = Database::Load(tmp.Path("budget_" + tag));
    ASSERT_EQ(full.size(), kept.size());
    size_t bitten = 0;
    for (size_t i = 0; i < full.size(); ++i) {
      ASSERT_EQ(kept.FeatureCount(i), std::min<size_t>(full.FeatureCount(i), 20)) << tag << i;
      bitten += full.FeatureCount(i) > 20;
      // Every kept feature is one of the full set's, in the same order.
      const FeatureSet a = full.Features(i), b = kept.Features(i);
      size_t j = 0;
      for (size_t k = 0; k < b.size(); ++k) {
        while (j < a.size() &&
               (a.keypoints[j].pt != b.keypoints[k].pt ||
                cv::norm(a.descriptors.row(static_cast<int>(j)),
                         b.descriptors.row(static_cast<int>(k)), cv::NORM_HAMMING) != 0))
          ++j;
        ASSERT_LT(j, a.size()) << tag << " keyframe " << i << " feature " << k;
        ++j;
      }
    }
    EXPECT_EQ(bitten, full.size()) << tag;  // the budget was smaller than each keyframe's features
    EXPECT_EQ(BuildOptionsFromManifest(kept.info(), "db").stored_features, 20);
    EXPECT_EQ(BuildOptionsFromManifest(kept.info(), "db").track_neighbours, 4);
    // A manifest written before the setting reads as keeping every feature,
    // one written before tracked budgets as spread alone.
    nlohmann::json old = kept.info();
    old["settings"].erase("stored_features");
    old["settings"].erase("track_neighbours");
    EXPECT_EQ(BuildOptionsFromManifest(old, "db").stored_features, 0);
    EXPECT_EQ(BuildOptionsFromManifest(old, "db").track_neighbours, 0);
  }
  BuildOptions bad = SmallBuild();
  bad.stored_features = -1;
  EXPECT_NE(bad.Check(), "");
  bad.stored_features = 100001;
  EXPECT_NE(bad.Check(), "");
  bad = SmallBuild();
  bad.track_neighbours = -1;
  EXPECT_NE(bad.Check(), "");
  bad.track_neighbours = 33;
  EXPECT_NE(bad.Check(), "");
}

// A budget ranked by tracks keeps more of the features the neighbouring
// keyframes also found than one spread alone, and the same count; a
// keyframe added online keeps its budget, ranked against the stored
// keyframes nearest in order.
TEST(BuilderTest, TrackedBudgetKeepsTheFeaturesNeighboursFound) {
  TempDir tmp;
  const std::vector<Frame> frames = ListImageFolder(kImages, 3, 8);
  BuildOptions all = SmallBuild();
  BuildOptions spread = all;
  spread.stored_features = 30;
  spread.track_neighbours = 0;
  BuildOptions tracked = spread;
  tracked.track_neighbours = 2;
  BuildDatabase(frames, all, tmp.Path("all"), "rtabmap 3..8");
  BuildDatabase(frames, spread, tmp.Path("spread"), "rtabmap 3..8");
  BuildDatabase(frames, tracked, tmp.Path("tracked"), "rtabmap 3..8");
  const Database full = Database::Load(tmp.Path("all"));
  const Database a = Database::Load(tmp.Path("spread"));
  const Database b = Database::Load(tmp.Path("tracked"));
  ASSERT_EQ(full.size(), frames.size());
  std::vector<FeatureSet> sets;
  for (size_t i = 0; i < full.size(); ++i) sets.push_back(full.Features(i));
  std::vector<std::optional<Pose>> no_poses(full.size());
  const std::vector<std::vector<size_t>> neighbours = TrackNeighbours(no_poses, 2);
  int tracked_a = 0, tracked_b = 0;
  for (size_t i = 0; i < full.size(); ++i) {
    ASSERT_EQ(a.FeatureCount(i), b.FeatureCount(i)) << i;
    std::vector<const FeatureSet*> others;
    for (const size_t j : neighbours[i]) others.push_back(&sets[j]);
    for (const int c : TrackCounts(a.Features(i), others)) tracked_a += c > 0;
    for (const int c : TrackCounts(b.Features(i), others)) tracked_b += c > 0;
  }
  EXPECT_GT(tracked_b, tracked_a + static_cast<int>(full.size()));

  // Online: the next frame, ranked against the last two stored keyframes.
  const std::vector<Frame> next = ListImageFolder(kImages, 9, 9);
  ASSERT_EQ(next.size(), 1u);
  ProcessedFrame online = ProcessFrame(next[0], LoadFrameImage(next[0]), tracked,
                                       *FeatureExtractor::Create(tracked.features));
  const size_t extracted = online.features.size();
  ASSERT_GT(extracted, 30u);
  FeatureSet whole = online.features;
  KeepTrackedOnline(b, tracked, &online);
  EXPECT_EQ(online.features.size(), 30u);
  std::vector<FeatureSet> last = {b.Features(b.size() - 1), b.Features(b.size() - 2)};
  const std::vector<int> counts = TrackCounts(whole, {&last[0], &last[1]});
  int matched = 0;
  for (const int c : counts) matched += c > 0;
  int kept_matched = 0;
  for (const int c : TrackCounts(online.features, {&last[0], &last[1]})) kept_matched += c > 0;
  EXPECT_EQ(kept_matched, std::min(matched, 30));
}

TEST(BuilderTest, ExistingDatabaseNeedsOverwrite) {
  TempDir tmp;
  const std::string out = tmp.Path("db");
  BuildOptions options = SmallBuild();
  EXPECT_EQ(BuildDatabase(ListImageFolder(kImages, 1, 5), options, out, "five").num_keyframes, 5u);
  const std::string bin5 = KeyframeFile(out);

  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { BuildDatabase(ListImageFolder(kImages, 1, 8), options, out, "eight"); },
      "a database already exists"));
  EXPECT_EQ(KeyframeFile(out), bin5);

  options.overwrite = true;
  EXPECT_EQ(BuildDatabase(ListImageFolder(kImages, 1, 8), options, out, "eight").num_keyframes, 8u);
  Database db = Database::Load(out);
  EXPECT_EQ(db.size(), 8u);
  EXPECT_EQ(db.info()["source"], "eight");
  EXPECT_TRUE(fs::exists(out + "/images/000008.png"));
  const std::string bin8 = KeyframeFile(out);
  const std::string manifest8 = ReadFileToString(out + "/manifest.json");

  // A failed overwrite (every image unreadable) leaves the old database as it was.
  const std::string junk = tmp.Path("junk");
  fs::create_directories(junk);
  WriteBytes(junk + "/a.jpg", "garbage");
  WriteBytes(junk + "/b.png", "more garbage");
  const std::vector<Frame> unreadable = ListImageFolder(junk);
  ASSERT_EQ(unreadable.size(), 2u);
  BuildOptions strict = options;
  strict.strict = true;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { BuildDatabase(unreadable, strict, out, "x"); },
                                          "cannot read image"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { BuildDatabase(unreadable, options, out, "x"); },
                                          "none of the 2 images could be read"));
  db = Database::Load(out);
  EXPECT_EQ(db.size(), 8u);
  EXPECT_EQ(KeyframeFile(out), bin8);
  EXPECT_EQ(ReadFileToString(out + "/manifest.json"), manifest8);
  EXPECT_TRUE(fs::exists(out + "/images/000008.png"));
  EXPECT_TRUE(BuildingLeftovers(tmp.Path()).empty());
}

TEST(BuilderTest, RefusesNonDatabaseOutputs) {
  TempDir tmp;
  const std::vector<Frame> frames = ListImageFolder(kImages, 1, 2);
  BuildOptions options = SmallBuild();
  options.overwrite = true;  // even with overwrite
  const std::string other = tmp.Path("my_documents");
  fs::create_directories(other);
  WriteBytes(other + "/notes.txt", "precious");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { BuildDatabase(frames, options, other, "x"); },
                                          "is not empty and is not a placedb database"));
  EXPECT_EQ(ReadFileToString(other + "/notes.txt"), "precious");
  EXPECT_FALSE(fs::exists(other + "/manifest.json"));

  const std::string file = tmp.Path("a_file");
  WriteBytes(file, "content");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { BuildDatabase(frames, options, file, "x"); },
                                          "is not a directory"));
  // Outputs the system refuses (root included): IoError, and no debris.
  EXPECT_TRUE(ThrowsWith<IoError>([&] { BuildDatabase(frames, options, file + "/db", "x"); },
                                  {"cannot create", "a_file"}));
  EXPECT_THROW(BuildDatabase(frames, options, "/proc/placedb_test_db", "x"), IoError);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { BuildDatabase({}, options, tmp.Path("empty_db"), "x"); }, "no frames"));
  BuildOptions bad = options;
  bad.resize = 2;
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { BuildDatabase(frames, bad, tmp.Path("bad_db"), "x"); },
                                  "resize must be 1, 4 or 16 (got 2)"));
  EXPECT_FALSE(fs::exists(tmp.Path("bad_db")));

  // An existing empty directory is fine.
  const std::string empty = tmp.Path("empty_dir");
  fs::create_directories(empty);
  EXPECT_EQ(BuildDatabase(frames, SmallBuild(), empty, "x").num_keyframes, 2u);
  EXPECT_EQ(Database::Load(empty).size(), 2u);
  EXPECT_TRUE(BuildingLeftovers(tmp.Path()).empty());

  // "db/", "db/." and "x/../db" name the directory db itself (they used to
  // fail after the whole build, leaving an empty folder).
  for (const std::string& spelled :
       {tmp.Path("slash") + "/", tmp.Path("dot") + "/.", tmp.Path("x") + "/../up"}) {
    EXPECT_EQ(BuildDatabase(frames, SmallBuild(), spelled, "x").num_keyframes, 2u) << spelled;
  }
  EXPECT_EQ(Database::Load(tmp.Path("slash")).size(), 2u);
  EXPECT_EQ(Database::Load(tmp.Path("dot")).size(), 2u);
  EXPECT_EQ(Database::Load(tmp.Path("up")).size(), 2u);
  EXPECT_TRUE(BuildingLeftovers(tmp.Path()).empty());
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { BuildDatabase(frames, SmallBuild(), "/", "x"); },
                                          "cannot build a database at /"));
}

TEST(BuilderTest, TinyImagesGiveKeyframesWithoutFeatures) {
  TempDir tmp;
  const std::string folder = tmp.Path("tiny");
  fs::create_directories(folder);
  cv::RNG rng(7);
  for (const char* name : {"a.png", "b.png"}) {
    cv::Mat img(15, 20, CV_8UC3);
    rng.fill(img, cv::RNG::UNIFORM, 0, 256);
    ASSERT_TRUE(cv::imwrite(folder + "/" + name, img));
  }
  for (CropMode crop : {CropMode::kNone, CropMode::kChroma}) {
    BuildOptions options = SmallBuild();
    options.crop = crop;
    options.resize = 4;
    const std::string out = tmp.Path(std::string("db_") + CropModeName(crop));
    const BuildReport report = BuildDatabase(ListImageFolder(folder), options, out, "tiny");
    EXPECT_EQ(report.num_keyframes, 2u);
    EXPECT_EQ(report.num_features, 0u);
    const Database db = Database::Load(out);
    ASSERT_EQ(db.size(), 2u);
    EXPECT_EQ(db.num_features(), 0u);
    for (size_t i = 0; i < db.size(); ++i) {
      EXPECT_EQ(db.FeatureCount(i), 0u);
      EXPECT_EQ(db.keyframe(i).original_size, cv::Size(20, 15));
      EXPECT_EQ(db.Descriptors(i).rows, 0);
    }
    if (crop == CropMode::kNone) {
      EXPECT_EQ(db.keyframe(0).stored_size, cv::Size(10, 8));
    }
  }
}

// Runs a 40-image overwrite build in a forked child and kills it (SIGKILL)
// mid-way: the database already at the path must still load, unchanged.
TEST(BuilderTest, KilledBuildLeavesPreviousDatabase) {
  if (testing_util::kThreadSanitizer) GTEST_SKIP() << "forks: not under ThreadSanitizer";
  TempDir tmp;
  const std::string out = tmp.Path("db");
  ASSERT_EQ(BuildDatabase(ListImageFolder(kImages, 1, 10), SmallBuild(), out, "old").num_keyframes,
            10u);
  const std::string old_bin = KeyframeFile(out);
  const std::vector<Frame> frames40 = ListImageFolder(kImages, 1, 40);
  ASSERT_EQ(frames40.size(), 40u);
  BuildOptions child_options = SmallBuild();
  child_options.overwrite = true;
  child_options.crop = CropMode::kChroma;

  // The child must not depend on thread pools of the parent (OpenCV's
  // TBB workers do not survive fork): run OpenCV sequentially meanwhile.
  struct SequentialOpenCv {
    const int saved = cv::getNumThreads();
    SequentialOpenCv() { cv::setNumThreads(0); }
    ~SequentialOpenCv() { cv::setNumThreads(saved); }
  } sequential;
  auto spawn = [&]() -> pid_t {
    const pid_t pid = ::fork();
    if (pid == 0) {
      int code = 0;
      try {
        BuildDatabase(frames40, child_options, out, "new");
      } catch (...) {
        code = 3;
      }
      ::_exit(code);
    }
    return pid;
  };

  // Kill the child at several points of its build: first wait until its
  // temporary directory exists (the build has started, whatever the load on
  // the machine), then let it run a little longer.
  for (int delay_ms : {0, 20, 60, 120}) {
    SCOPED_TRACE("kill " + std::to_string(delay_ms) + " ms into the build");
    const pid_t pid = spawn();
    ASSERT_GT(pid, 0);
    const std::string building = out + ".building." + std::to_string(pid);
    for (int waited = 0; waited < 20000 && !fs::exists(building); ++waited) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    const bool started = fs::exists(building);
    std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
    ASSERT_EQ(::kill(pid, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(started) << "the child never started building";
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL)
        << "the child finished before it was killed; the test needs a slower build";
    const Database db = Database::Load(out);
    EXPECT_EQ(db.size(), 10u);
    EXPECT_EQ(db.info()["source"], "old");
    EXPECT_EQ(KeyframeFile(out), old_bin);
    // What the killed build left behind goes with the next build of the
    // same database (its process is gone).
    if (delay_ms == 120) {
      EXPECT_FALSE(BuildingLeftovers(tmp.Path()).empty());
      BuildOptions again = SmallBuild();
      again.overwrite = true;
      BuildDatabase(ListImageFolder(kImages, 1, 10), again, out, "old");
      EXPECT_TRUE(BuildingLeftovers(tmp.Path()).empty());
    }
    for (const std::string& left : BuildingLeftovers(tmp.Path())) fs::remove_all(tmp.Path(left));
  }

  // Left alone, the same child replaces the database (so the kills above
  // did interrupt a build that would have succeeded).
  const pid_t pid = spawn();
  ASSERT_GT(pid, 0);
  int status = 0;
  pid_t done = 0;
  // A generous limit (sanitizers, a busy machine): it only ends a hang.
  for (int waited = 0; waited < 12000 && done == 0; ++waited) {
    done = ::waitpid(pid, &status, WNOHANG);
    if (done == 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  if (done == 0) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
    FAIL() << "the child build did not finish within 600 s";
  }
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  const Database db = Database::Load(out);
  EXPECT_EQ(db.size(), 40u);
  EXPECT_EQ(db.info()["source"], "new");
  EXPECT_TRUE(BuildingLeftovers(tmp.Path()).empty());
}

}  // namespace
}  // namespace placedb
