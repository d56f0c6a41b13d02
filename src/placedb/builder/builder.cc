#include "placedb/builder/builder.h"

#include <fcntl.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <stdio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <mutex>
#include <opencv2/imgcodecs.hpp>

#include "placedb/builder/tracks.h"
#include "placedb/feature/spread.h"
#include "placedb/feature/whole_image.h"
#include "placedb/image/resize.h"
#include "placedb/feature/whole_image_model.h"
#include "placedb/storage/folder.h"
#include "placedb/storage/whole_image_model_file.h"
#include "placedb/util/check.h"
#include "placedb/util/checksum.h"
#include "placedb/util/file_io.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/options.h"
#include "placedb/util/progress.h"
#include "placedb/util/thread_pool.h"
#include "placedb/util/timer.h"
#include "placedb/util/version.h"

namespace placedb {
namespace fs = std::filesystem;

const char* CropModeName(CropMode mode) { return mode == CropMode::kChroma ? "chroma" : "none"; }

CropMode ParseCropMode(const std::string& name) {
  if (name == "none") return CropMode::kNone;
  if (name == "chroma") return CropMode::kChroma;
  PLACEDB_THROW_INVALID("unknown crop mode '", name, "' (expected none or chroma)");
}

const char* IndexKindName(IndexKind kind) { return kind == IndexKind::kBow ? "bow" : "none"; }

IndexKind ParseIndexKind(const std::string& name) {
  if (name == "none") return IndexKind::kNone;
  if (name == "bow") return IndexKind::kBow;
  PLACEDB_THROW_INVALID("unknown index '", name, "' (expected none or bow)");
}

namespace {

// The features of a processed frame (crop and stored image settled in
// `out`): on the stored image, or, in context, those of the resized whole
// frame inside the crop.
void ExtractStored(const cv::Mat& image, const BuildOptions& options,
                   const FeatureExtractor& extractor, ProcessedFrame* processed) {
  ProcessedFrame& out = *processed;
  const Keyframe& k = out.keyframe;
  const bool whole = k.crop == cv::Rect(0, 0, image.cols, image.rows);
  if (!options.extract_in_context || whole) {
    out.features = extractor.Extract(out.stored_image);
    return;
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
  if (keep.empty()) return;
  out.features.descriptors.create(static_cast<int>(keep.size()), all.descriptors.cols,
                                  all.descriptors.type());
  for (size_t j = 0; j < keep.size(); ++j) {
    cv::KeyPoint kp = all.keypoints[keep[j]];
    kp.pt.x -= static_cast<float>(roi.x);
    kp.pt.y -= static_cast<float>(roi.y);
    out.features.keypoints.push_back(kp);
    all.descriptors.row(keep[j]).copyTo(out.features.descriptors.row(static_cast<int>(j)));
  }
}

}  // namespace

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
  ExtractStored(image, options, extractor, &out);
  // A budget ranked by tracks needs the neighbours' features: the caller's.
  if (options.track_neighbours == 0) {
    KeepSpread(&out.features, static_cast<size_t>(options.stored_features), k.stored_size);
  }
  // The whole-image row is the whole frame's (as given: before crop and
  // resize), also for a cropped keyframe: what a query's Extract gives.
  // The extractor computed it on the stored image already when that is
  // the frame itself.
  const bool frame_as_given =
      k.crop == cv::Rect(0, 0, image.cols, image.rows) && options.resize == 1;
  if (!options.features.whole_image.enabled) {
    out.features.whole_image.release();
  } else if (!frame_as_given || out.features.whole_image.empty()) {
    out.features.whole_image = extractor.WholeImage(image);
  }
  return out;
}

void KeepTrackedOnline(const Database& db, const BuildOptions& options, ProcessedFrame* frame) {
  if (options.stored_features == 0 || options.track_neighbours == 0) return;
  std::vector<std::optional<Pose>> poses;
  poses.reserve(db.size());
  for (const Keyframe& k : db.keyframes()) poses.push_back(k.pose);
  std::vector<FeatureSet> stored;
  for (const size_t i : TrackNeighboursOfNew(poses, frame->keyframe.pose,
                                             static_cast<size_t>(options.track_neighbours))) {
    stored.push_back(db.Features(i));
  }
  std::vector<const FeatureSet*> others;
  for (const FeatureSet& f : stored) others.push_back(&f);
  KeepSpread(&frame->features, static_cast<size_t>(options.stored_features),
             frame->keyframe.stored_size, TrackCounts(frame->features, others));
}

std::string BuildReportJson(const BuildReport& report, const std::string& database, int indent) {
  return DumpJson(BuildReportToJson(report, database), indent);
}

nlohmann::json BuildReportToJson(const BuildReport& r, const std::string& database) {
  return {{"database", database},
          {"num_frames", r.num_frames},
          {"num_keyframes", r.num_keyframes},
          {"num_skipped", r.num_skipped},
          {"skipped", r.skipped},
          {"num_cropped", r.num_cropped},
          {"num_features", r.num_features},
          {"image_bytes", r.image_bytes},
          {"feature_bytes", r.feature_bytes},
          {"full_png_bytes", r.full_png_bytes},
          {"index_bytes", r.index_bytes},
          {"seconds", r.seconds}};
}

std::string NowIso8601() {
  const std::time_t now = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  return buf;
}

nlohmann::json IdsEntry(int64_t next_free, uint64_t removed, const std::string& removed_since) {
  return {{"next_free", next_free}, {"removed", removed}, {"removed_since", removed_since}};
}

namespace {

bool LooksLikeDatabase(const fs::path& dir) {
  std::error_code ec;
  if (fs::exists(dir / Database::kManifestFile, ec)) return true;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (Database::IsKeyframesFileName(entry.path().filename().string())) return true;
  }
  return false;
}

// The output directory as one absolute path with a file name: "db/", "db/."
// and "x/../db" all mean db.
fs::path NormalizeOutputPath(const std::string& out_dir) {
  fs::path p = fs::absolute(out_dir).lexically_normal();
  while (!p.has_filename() && p.has_parent_path() && p != p.root_path()) p = p.parent_path();
  if (p.filename() == "." || p.filename() == "..") {
    std::error_code ec;
    const fs::path canonical = fs::weakly_canonical(p, ec);
    if (ec) PLACEDB_THROW_READ_ERROR(ec.value(), "cannot resolve the output path ", out_dir);
    p = canonical;
  }
  if (p == p.root_path() || p.filename().empty()) {
    PLACEDB_THROW_INVALID("cannot build a database at ", out_dir, " (", p.string(), ")");
  }
  return p;
}

// Moves the finished temporary directory to `out`. With an existing
// database at `out`, the two directories are exchanged atomically
// (renameat2 RENAME_EXCHANGE) and the old one is then deleted.
void CommitDirectory(const fs::path& tmp, const fs::path& out) {
  SyncDirectory(tmp.string());
  std::error_code ec;
  if (!fs::exists(out, ec)) {
    fs::rename(tmp, out, ec);
    if (ec) PLACEDB_THROW_IO("cannot move the new database to ", out.string(), ": ", ec.message());
  } else {
#ifdef RENAME_EXCHANGE
    if (::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, out.c_str(), RENAME_EXCHANGE) != 0) {
      PLACEDB_THROW_IO("cannot replace ", out.string(), ": ", std::strerror(errno));
    }
    // Now holds the old database; the new one is in place whatever happens here.
    fs::remove_all(tmp, ec);
    if (ec) spdlog::warn("cannot remove the old database {}: {}", tmp.string(), ec.message());
#else
    const fs::path old = out.string() + ".old";
    fs::rename(out, old, ec);
    if (!ec) fs::rename(tmp, out, ec);
    if (ec) PLACEDB_THROW_IO("cannot replace ", out.string(), ": ", ec.message());
    fs::remove_all(old, ec);
#endif
  }
  SyncDirectory(out.parent_path().empty() ? "." : out.parent_path().string());
}

}  // namespace

std::string SaveBowIndexFile(const BowIndex& index, const std::string& dir) {
  const std::string name = "bow." + ChecksumHex(index.checksum()) + ".bin";
  index.Save((fs::path(dir) / name).string());
  return name;
}

bool IsBowIndexFileName(const std::string& name) {
  if (name.size() != 24 || name.compare(0, 4, "bow.") != 0 || name.compare(20, 4, ".bin") != 0)
    return false;
  return std::all_of(name.begin() + 4, name.begin() + 20,
                     [](char c) { return std::isdigit(c) || (c >= 'a' && c <= 'f'); });
}

namespace {

// The bag-of-words index files of a database, written into its directory.
struct IndexFiles {
  nlohmann::json manifest;  // the manifest's "index" entry
  uint64_t bytes = 0;
};

// The feature budget ranked by tracks (builder/tracks.h) over every
// keyframe built: the matches are counted against the neighbours' whole
// sets, then each keyframe keeps its budget.
void KeepTracked(const BuildOptions& options, std::vector<std::optional<ProcessedFrame>>* results,
                 ThreadPool* pool) {
  std::vector<ProcessedFrame*> built;
  for (std::optional<ProcessedFrame>& r : *results) {
    if (r) built.push_back(&*r);
  }
  std::vector<std::optional<Pose>> poses;
  poses.reserve(built.size());
  for (const ProcessedFrame* p : built) poses.push_back(p->keyframe.pose);
  const std::vector<std::vector<size_t>> neighbours =
      TrackNeighbours(poses, static_cast<size_t>(options.track_neighbours));
  std::vector<std::vector<int>> counts(built.size());
  ProgressBar progress("tracks", built.size(), options.progress);
  pool->ParallelFor(built.size(), [&](size_t i) {
    std::vector<const FeatureSet*> others;
    for (const size_t j : neighbours[i]) others.push_back(&built[j]->features);
    counts[i] = TrackCounts(built[i]->features, others);
    progress.Advance();
  });
  progress.Finish();
  pool->ParallelFor(built.size(), [&](size_t i) {
    KeepSpread(&built[i]->features, static_cast<size_t>(options.stored_features),
               built[i]->keyframe.stored_size, counts[i]);
  });
}

IndexFiles WriteBowIndex(const Database& db, const BuildOptions& options, const std::string& dir,
                         ThreadPool* pool) {
  std::shared_ptr<const Vocabulary> vocabulary;
  if (!options.vocabulary_file.empty()) {
    auto given = std::make_shared<Vocabulary>(Vocabulary::Open(options.vocabulary_file));
    if (given->type() != db.feature_type() || given->row_bytes() != db.descriptor_bytes()) {
      PLACEDB_THROW_INVALID("vocabulary ", options.vocabulary_file, " is for ",
                            FeatureTypeName(given->type()), " descriptors of ", given->row_bytes(),
                            " bytes, the database holds ", FeatureTypeName(db.feature_type()),
                            " descriptors of ", db.descriptor_bytes(), " bytes");
    }
    vocabulary = std::move(given);
  } else {
    std::vector<DescriptorBlock> blocks;
    blocks.reserve(db.size());
    for (size_t i = 0; i < db.size(); ++i) blocks.push_back(db.Descriptors(i));
    ProgressBar progress("vocabulary", Vocabulary::TrainingWork(blocks, options.vocabulary),
                         options.progress);
    vocabulary = std::make_shared<Vocabulary>(
        Vocabulary::Train(blocks, options.vocabulary, pool, &progress));
    progress.Finish();
  }
  ProgressBar progress("bow index", db.size(), options.progress);
  const BowIndex index = BowIndex::Build(vocabulary, db, options.bow, pool, &progress);
  progress.Finish();
  const fs::path vocabulary_path = fs::path(dir) / kVocabularyFile;
  vocabulary->Save(vocabulary_path.string());
  const std::string index_name = SaveBowIndexFile(index, dir);
  const fs::path index_path = fs::path(dir) / index_name;
  IndexFiles files;
  files.bytes = FileSize(vocabulary_path.string()) + FileSize(index_path.string());
  files.manifest = {{"kind", "bow"},
                    {"vocabulary", kVocabularyFile},
                    {"vocabulary_words", vocabulary->num_words()},
                    {"bow", index_name}};
  return files;
}

}  // namespace

namespace {

// The options as the build uses and records them: a HOG whole-image channel
// without a thumbnail height gets the one that keeps the first readable
// frame's aspect.
BuildOptions ResolveOptions(const BuildOptions& given, const std::vector<Frame>& frames) {
  BuildOptions options = given;
  WholeImageOptions& w = options.features.whole_image;
  if (!w.enabled || w.kind != WholeImageKind::kHog || w.hog_height != 0) return options;
  for (const Frame& f : frames) {
    const cv::Mat image = LoadFrameImage(f);
    if (image.empty()) continue;
    w.hog_height = HogHeightForFrame(w.hog_width, image.size());
    return options;
  }
  w.hog_height = HogHeightForFrame(w.hog_width, cv::Size(4, 3));
  return options;
}

// Fits the HOG channel's model on the keyframes' raw rows and replaces each
// with its projection; writes the model into `dir`. Returns false (the
// channel left out, said so) when fewer than 2 keyframes were read.
bool FitWholeImageModel(std::vector<std::optional<ProcessedFrame>>* results,
                        const WholeImageOptions& w, const fs::path& dir, ThreadPool* pool) {
  std::vector<cv::Mat> raw;
  for (const auto& r : *results) {
    if (r) raw.push_back(r->features.whole_image);
  }
  if (raw.size() < 2) {
    spdlog::warn("the HOG whole-image channel needs 2 or more keyframes: the database has none");
    for (auto& r : *results) {
      if (r) r->features.whole_image.release();
    }
    return false;
  }
  const WholeImageModel model = WholeImageModel::Fit(raw, w.hog_width, w.hog_height, w.hog_dims);
  raw.clear();
  pool->ParallelFor(results->size(), [&](size_t i) {
    std::optional<ProcessedFrame>& r = (*results)[i];
    if (r) r->features.whole_image = model.Project(r->features.whole_image);
  });
  SaveWholeImageModel(model, (dir / kWholeImageModelFile).string());
  return true;
}

}  // namespace

BuildReport BuildDatabase(const std::vector<Frame>& frames, const BuildOptions& given,
                          const std::string& out_dir, const std::string& source_description) {
  PLACEDB_CHECK_OPTIONS(given);
  BuildOptions options = ResolveOptions(given, frames);
  if (out_dir.empty()) PLACEDB_THROW_INVALID("an output directory is needed");
  Timer timer;
  const fs::path out = NormalizeOutputPath(out_dir);
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
                            " (`overwrite` to replace it)");
    }
  }
  if (frames.empty()) PLACEDB_THROW_INVALID("no frames to build a database from");
  fs::create_directories(out.parent_path(), ec);
  if (ec) PLACEDB_THROW_IO("cannot create ", out.parent_path().string(), ": ", ec.message());
  // Folders of killed builds, and one of this process's left by an earlier
  // call that failed to remove it.
  RemoveAbandonedBuilds(out.string(), /*include_own=*/true);
  const fs::path tmp = out.string() + ".building." + std::to_string(::getpid());
  if (fs::exists(fs::symlink_status(tmp, ec))) {
    PLACEDB_THROW_INVALID(tmp.string(),
                          " is in the way of the build (a symlink or a file where "
                          "the build's temporary folder goes); move it away");
  }
  fs::create_directories(tmp / kStoredImageFolder, ec);
  if (ec) {
    PLACEDB_THROW_IO("cannot create ", (tmp / kStoredImageFolder).string(), ": ", ec.message());
  }

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
      uint64_t source_hash = 0;
      cv::Mat image = LoadFrameImage(frame, &source_hash);
      if (image.empty()) {
        if (options.strict) ThrowUnreadableFrame(frame, "; `strict`");
        progress.Advance();
        return;
      }
      ProcessedFrame processed = ProcessFrame(frame, image, options, *extractor);
      processed.keyframe.source_hash = source_hash;
      std::vector<uint8_t> buffer;
      cv::imencode(".png", image, buffer, png_params);
      full_png[i] = buffer.size();
      if (options.store_images) {
        buffer.clear();
        cv::imencode(".png", processed.stored_image, buffer, png_params);
        const std::string name = StoredImageFileName(frame.id);
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
    if (options.stored_features > 0 && options.track_neighbours > 0) {
      KeepTracked(options, &results, &pool);
    }
    WholeImageOptions& whole = options.features.whole_image;
    bool whole_image_model = false;
    if (whole.enabled && whole.kind == WholeImageKind::kHog) {
      whole_image_model = FitWholeImageModel(&results, whole, tmp, &pool);
      if (!whole_image_model) whole.enabled = false;
    }

    BuildReport report;
    report.num_frames = frames.size();
    Database db(options.features.type, DescriptorBytes(options.features),
                WholeImageDims(options.features));
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
      PLACEDB_THROW_INVALID("none of the ", frames.size(),
                            " images could be read; no database built");
    }
    if (!options.store_images) fs::remove_all(tmp / kStoredImageFolder, ec);

    nlohmann::json& info = db.info();
    info["settings"] = BuildSettingsToJson(options);
    info["source"] = source_description;
    info["created"] = NowIso8601();
    int32_t largest_id = 0;
    for (const Keyframe& k : db.keyframes()) largest_id = std::max(largest_id, k.id);
    info["ids"] = IdsEntry(int64_t{largest_id} + 1, 0, info["created"].get<std::string>());
    info["placedb_version"] = kPlacedbVersion;
    info["counts"]["frames"] = report.num_frames;
    info["counts"]["skipped_images"] = report.num_skipped;
    info["counts"]["cropped"] = report.num_cropped;
    info["bytes"]["images"] = report.image_bytes;
    info["bytes"]["full_frames_png"] = report.full_png_bytes;
    if (whole_image_model) info["whole_image_model"] = kWholeImageModelFile;
    if (options.index == IndexKind::kBow) {
      const IndexFiles files = WriteBowIndex(db, options, tmp.string(), &pool);
      info["index"] = files.manifest;
      info["bytes"]["index"] = files.bytes;
      report.index_bytes = files.bytes;
    }
    report.feature_bytes = db.Save(tmp.string()).keyframes_bytes;
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
