// Builds a keyframe database from a sequence of frames: read, crop
// (feature-rich or none), resize, extract features once, store PNGs, write
// the database directory atomically.
#pragma once

#include <string>
#include <vector>

#include "placedb/builder/build.h"
#include "placedb/dataset/frame.h"
#include "placedb/feature/extractor.h"
#include "placedb/image/feature_rich_crop.h"
#include "placedb/retrieval/bow_index.h"
#include "placedb/retrieval/vocabulary.h"
#include "placedb/storage/database.h"
#include "placedb/util/option_table.h"

namespace placedb {

// The bag-of-words files of a database built with index bow (named in its
// manifest's "index").
constexpr const char* kVocabularyFile = "vocabulary.bin";
// The index file is named by its content, bow.<checksum>.bin, so that a
// database saved in place (online mapping) never overwrites the file the
// current manifest names. Returns the name written inside `dir`.
std::string SaveBowIndexFile(const BowIndex& index, const std::string& dir);
bool IsBowIndexFileName(const std::string& name);

// The report as JSON (the database's path included).
nlohmann::json BuildReportToJson(const BuildReport& report, const std::string& database);

// The time now, "2026-12-03T11:40:09Z" (UTC).
std::string NowIso8601();

// The manifest's "ids" entry: `next_free`, the id after the largest a
// keyframe of the database ever had (what `add` gives the next new frame by
// default: ids of removed keyframes are not given again), and `removed`,
// the keyframes removed since `removed_since` (the build, or the first save
// by a placedb that counts removals). Manifests of earlier versions lack it
// (session/place_database.cc reads them).
nlohmann::json IdsEntry(int64_t next_free, uint64_t removed, const std::string& removed_since);

// What one frame becomes: the stored image and its keyframe with features.
struct ProcessedFrame {
  Keyframe keyframe;
  FeatureSet features;
  cv::Mat stored_image;
};

// Crop + resize + extract for one decoded image (no I/O), then the feature
// budget (stored_features) when it is spread alone (track_neighbours 0; see
// KeepTrackedOnline below for a budget ranked by tracks). With
// options.features.whole_image.enabled, features.whole_image is the whole
// image's descriptor (ComputeWholeImageDescriptor of `image`: before crop
// and resize), also for a cropped keyframe.
ProcessedFrame ProcessFrame(const Frame& frame, const cv::Mat& image, const BuildOptions& options,
                            const FeatureExtractor& extractor);

// ProcessFrame keeps every feature when the budget is ranked by tracks
// (options.stored_features and track_neighbours both above 0): the build
// ranks them once every frame is extracted, and a keyframe added to an
// existing database (online mapping) is ranked here, against the stored
// features of its track_neighbours neighbours in `db`
// (TrackNeighboursOfNew), before it keeps its budget. Otherwise nothing
// to do.
void KeepTrackedOnline(const Database& db, const BuildOptions& options, ProcessedFrame* frame);

// JSON of the settings a database was built with (stored in the manifest,
// "settings"), and the settings read back from a manifest: every field is
// type-checked strictly and the whole is Check()ed; a bad one is
// CorruptDatabase naming `dir` and the field. (The run-time fields
// threads, strict, progress and overwrite are not stored.)
nlohmann::json BuildSettingsToJson(const BuildOptions& options);
BuildOptions BuildOptionsFromManifest(const nlohmann::json& manifest, const std::string& dir);

}  // namespace placedb
