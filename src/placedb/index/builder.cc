#include "placedb/index/builder.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <stdio.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <mutex>
#include <opencv2/imgcodecs.hpp>

#include "placedb/image/resize.h"
#include "placedb/util/check.h"
#include "placedb/util/file_io.h"
#include "placedb/util/progress.h"
#include "placedb/util/thread_pool.h"
#include "placedb/util/timer.h"

namespace placedb {
namespace fs = std::filesystem;

const char* CropModeName(CropMode mode) { return mode == CropMode::kChroma ? "chroma" : "none"; }

CropMode ParseCropMode(const std::string& name) {
  if (name == "none") return CropMode::kNone;
  if (name == "chroma") return CropMode::kChroma;
  PLACEDB_THROW_INVALID("unknown crop mode '", name, "' (expected none or chroma)");
}

std::string BuildOptions::Check() const {
  if (!IsValidAreaDivisor(resize)) return "resize must be 1, 4 or 16";
  if (png_compression < 0 || png_compression > 9) return "png_compression must be in [0, 9]";
  std::string reason = crop_options.Check();
  if (!reason.empty()) return "crop: " + reason;
  reason = features.Check();
  if (!reason.empty()) return "features: " + reason;
  return "";
}

ProcessedFrame ProcessFrame(const Frame& frame, const cv::Mat& image, const BuildOptions& options,
                            const FeatureExtractor& extractor) {
  ProcessedFrame out;
  Keyframe& k = out.keyframe;
  k.id = frame.id;
  k.timestamp = frame.timestamp;
  k.pose = frame.pose;
  k.source = frame.image_path;
  k.original_size = image.size();
  k.crop = cv::Rect(0, 0, image.cols, image.rows);
  if (options.crop == CropMode::kChroma) {
    const CropResult crop = SelectFeatureRichCrop(image, options.crop_options);
    k.crop = crop.roi;
    k.crop_channel = crop.channel;
  }
  const cv::Mat cropped = image(k.crop);
  out.stored_image = ResizeByArea(cropped, options.resize);
  if (out.stored_image.data == cropped.data && !cropped.isContinuous()) {
    out.stored_image = cropped.clone();
  }
  k.stored_size = out.stored_image.size();
  k.scale = cropped.cols > 0 ? static_cast<double>(k.stored_size.width) / cropped.cols : 1.0;
  const bool whole = k.crop == cv::Rect(0, 0, image.cols, image.rows);
  if (!options.extract_in_context || whole) {
    out.features = extractor.Extract(out.stored_image);
    return out;
  }
  // Features of the resized whole frame that fall inside the (resized) crop,
  // moved into the stored image's frame.
  const cv::Mat resized = ResizeByArea(image, options.resize);
  const double s = SideScaleForAreaDivisor(options.resize);
  const FeatureSet all = extractor.Extract(resized);
  out.features.type = all.type;
  out.features.descriptors = cv::Mat(0, all.descriptors.cols, all.descriptors.type());
  const cv::Rect_<double> roi(k.crop.x * s, k.crop.y * s, k.stored_size.width,
                              k.stored_size.height);
  std::vector<int> keep;
  for (size_t i = 0; i < all.keypoints.size(); ++i) {
    const cv::Point2f& p = all.keypoints[i].pt;
    if (p.x >= roi.x && p.y >= roi.y && p.x < roi.x + roi.width && p.y < roi.y + roi.height) {
      keep.push_back(static_cast<int>(i));
    }
  }
  if (keep.empty()) return out;
  out.features.descriptors.create(static_cast<int>(keep.size()), all.descriptors.cols,
                                  all.descriptors.type());
  for (size_t j = 0; j < keep.size(); ++j) {
    cv::KeyPoint kp = all.keypoints[keep[j]];
    kp.pt.x -= static_cast<float>(roi.x);
    kp.pt.y -= static_cast<float>(roi.y);
    out.features.keypoints.push_back(kp);
    all.descriptors.row(keep[j]).copyTo(out.features.descriptors.row(static_cast<int>(j)));
  }
  return out;
}

// JSON forms of the options structs (field names = member names).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(CropOptions, smooth_sigma, percentile, padding,
                                   min_fast_keypoints, fast_threshold, fast_nonmax,
                                   min_region_pixels)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(OrbOptions, max_features, scale_factor, num_levels,
                                   edge_threshold, fast_threshold, patch_size)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(SurfOptions, hessian_threshold, num_octaves, num_octave_layers,
                                   extended, upright, max_features)

nlohmann::json BuildSettingsToJson(const BuildOptions& o) {
  nlohmann::json j;
  j["crop"] = CropModeName(o.crop);
  j["crop_options"] = o.crop_options;
  j["resize"] = o.resize;
  j["store_images"] = o.store_images;
  j["extract_in_context"] = o.extract_in_context;
  j["png_compression"] = o.png_compression;
  j["features"]["type"] = FeatureTypeName(o.features.type);
  j["features"]["orb"] = o.features.orb;
  j["features"]["surf"] = o.features.surf;
  return j;
}

ExtractorOptions ExtractorOptionsFromManifest(const nlohmann::json& manifest) {
  ExtractorOptions o;
  if (!manifest.contains("settings") || !manifest["settings"].contains("features")) {
    PLACEDB_THROW_RUNTIME("the database manifest has no feature settings");
  }
  const nlohmann::json& f = manifest["settings"]["features"];
  try {
    o.type = ParseFeatureType(f.at("type").get<std::string>());
    o.orb = f.at("orb").get<OrbOptions>();
    o.surf = f.at("surf").get<SurfOptions>();
  } catch (const nlohmann::json::exception& e) {
    PLACEDB_THROW_RUNTIME("the database manifest's feature settings are malformed: ", e.what());
  }
  return o;
}

namespace {

std::string NowIso8601() {
  const std::time_t now = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  return buf;
}

bool LooksLikeDatabase(const fs::path& dir) {
  return fs::exists(dir / Database::kManifestFile) || fs::exists(dir / Database::kKeyframesFile);
}

// Moves the finished temporary directory to `out`. With an existing
// database at `out`, the two directories are exchanged atomically
// (renameat2 RENAME_EXCHANGE) and the old one is then deleted.
void CommitDirectory(const fs::path& tmp, const fs::path& out) {
  SyncDirectory(tmp.string());
  std::error_code ec;
  if (!fs::exists(out, ec)) {
    fs::rename(tmp, out);
  } else {
#ifdef RENAME_EXCHANGE
    if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, out.c_str(), RENAME_EXCHANGE) != 0) {
      PLACEDB_THROW_RUNTIME("cannot replace ", out.string(), ": ", std::strerror(errno));
    }
    fs::remove_all(tmp);  // now holds the old database
#else
    const fs::path old = out.string() + ".old";
    fs::rename(out, old);
    fs::rename(tmp, out);
    fs::remove_all(old);
#endif
  }
  SyncDirectory(out.parent_path().empty() ? "." : out.parent_path().string());
}

}  // namespace

BuildReport BuildDatabase(const std::vector<Frame>& frames, const BuildOptions& options,
                          const std::string& out_dir, const std::string& source_description) {
  PLACEDB_CHECK_OPTIONS(options);
  PLACEDB_CHECK(!out_dir.empty(), "an output directory is needed");
  Timer timer;
  const fs::path out = fs::absolute(out_dir).lexically_normal();
  std::error_code ec;
  if (fs::exists(out, ec)) {
    if (!fs::is_directory(out, ec)) {
      PLACEDB_THROW_INVALID("output path exists and is not a directory: ", out.string());
    }
    const bool empty = fs::is_empty(out, ec);
    if (!empty && !LooksLikeDatabase(out)) {
      PLACEDB_THROW_INVALID("output directory ", out.string(),
                            " is not empty and is not a placedb database; refusing to replace it");
    }
    if (!empty && !options.overwrite) {
      PLACEDB_THROW_INVALID("a database already exists at ", out.string(),
                            " (use --overwrite to replace it)");
    }
  }
  if (frames.empty()) PLACEDB_THROW_INVALID("no frames to build a database from");
  fs::create_directories(out.parent_path());
  const fs::path tmp = out.string() + ".building." + std::to_string(::getpid());
  fs::remove_all(tmp);
  fs::create_directories(tmp / "images");

  try {
    const auto extractor = FeatureExtractor::Create(options.features);
    const std::vector<int> png_params = {cv::IMWRITE_PNG_COMPRESSION, options.png_compression};
    std::vector<std::optional<ProcessedFrame>> results(frames.size());
    std::vector<uint64_t> full_png(frames.size(), 0);
    std::vector<uint64_t> stored_png(frames.size(), 0);
    ProgressBar progress("building", frames.size(), options.progress);
    ThreadPool pool(options.threads);
    pool.ParallelFor(frames.size(), [&](size_t i) {
      const Frame& frame = frames[i];
      cv::Mat image = cv::imread(frame.image_path, cv::IMREAD_COLOR);
      if (image.empty()) {
        if (options.strict) {
          PLACEDB_THROW_RUNTIME("cannot read image ", frame.image_path, " (frame ", frame.id,
                                "; --strict)");
        }
        progress.Advance();
        return;
      }
      ProcessedFrame processed = ProcessFrame(frame, image, options, *extractor);
      std::vector<uint8_t> buffer;
      cv::imencode(".png", image, buffer, png_params);
      full_png[i] = buffer.size();
      if (options.store_images) {
        buffer.clear();
        cv::imencode(".png", processed.stored_image, buffer, png_params);
        char name[32];
        std::snprintf(name, sizeof(name), "images/%06d.png", frame.id);
        processed.keyframe.image_file = name;
        WriteFileAtomic((tmp / name).string(),
                        std::string(reinterpret_cast<const char*>(buffer.data()), buffer.size()));
        stored_png[i] = buffer.size();
      }
      processed.stored_image.release();
      results[i] = std::move(processed);
      progress.Advance();
    });
    progress.Finish();

    BuildReport report;
    report.num_frames = frames.size();
    Database db(options.features.type, options.features.type == FeatureType::kOrb
                                           ? 32
                                           : (options.features.surf.extended ? 128 : 64) * 4);
    for (size_t i = 0; i < frames.size(); ++i) {
      if (!results[i]) {
        spdlog::warn("skipped unreadable image {} (frame {})", frames[i].image_path, frames[i].id);
        report.skipped.push_back(frames[i].image_path);
        continue;
      }
      if (results[i]->keyframe.crop_channel >= 0) ++report.num_cropped;
      report.full_png_bytes += full_png[i];
      report.image_bytes += stored_png[i];
      db.AddKeyframe(std::move(results[i]->keyframe), results[i]->features);
      results[i].reset();
    }
    report.num_skipped = report.skipped.size();
    report.num_keyframes = db.size();
    report.num_features = db.num_features();
    if (db.empty()) {
      PLACEDB_THROW_RUNTIME("none of the ", frames.size(),
                            " images could be read; no database built");
    }
    if (!options.store_images) fs::remove_all(tmp / "images");

    nlohmann::json& info = db.info();
    info["settings"] = BuildSettingsToJson(options);
    info["source"] = source_description;
    info["created"] = NowIso8601();
    info["placedb_version"] = "0.1.0";
    info["counts"]["frames"] = report.num_frames;
    info["counts"]["skipped_images"] = report.num_skipped;
    info["counts"]["cropped"] = report.num_cropped;
    info["bytes"]["images"] = report.image_bytes;
    info["bytes"]["full_frames_png"] = report.full_png_bytes;
    db.Save(tmp.string());
    report.feature_bytes = FileSize((tmp / Database::kKeyframesFile).string());
    CommitDirectory(tmp, out);
    report.seconds = timer.ElapsedSeconds();
    return report;
  } catch (...) {
    std::error_code ignore;
    fs::remove_all(tmp, ignore);
    throw;
  }
}

}  // namespace placedb
