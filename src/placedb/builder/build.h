// Building a database from frames: the settings (crop, resize, features,
// the retrieval index), the report, and BuildDatabase (part of the public
// face, placedb/placedb.h; the steps are builder/builder.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "placedb/dataset/frame.h"
#include "placedb/feature/options.h"
#include "placedb/image/crop_options.h"
#include "placedb/retrieval/options.h"
#include "placedb/util/option_table.h"

namespace placedb {

enum class CropMode { kNone, kChroma };

const char* CropModeName(CropMode mode);

// Parses "none" / "chroma"; throws InvalidArgument.
CropMode ParseCropMode(const std::string& name);

// The retrieval index built with a database.
enum class IndexKind { kNone, kBow };

// "none" / "bow".
const char* IndexKindName(IndexKind kind);

// Parses "none" / "bow"; throws InvalidArgument.
IndexKind ParseIndexKind(const std::string& name);

struct BuildOptions {
  // Feature-rich cropping (the paper's method) or none. Default none.
  CropMode crop = CropMode::kNone;
  CropOptions crop_options;
  // Stored image area divisor: 1, 4 or 16. Default 1 (full size).
  int resize = 1;
  ExtractorOptions features;
  // Most features a keyframe keeps of those extracted (0: all): those
  // matched in neighbouring keyframes first (track_neighbours), and chosen
  // spread over its stored image (feature/spread.h: every cell of an 8 x 6
  // grid's strongest before any cell's second). Queries keep every feature
  // extraction finds. Disk, memory and scoring time shrink with it, recall
  // can too (README, "Retrieval at scale": the scale benchmark). Range
  // [0, 100000]. Default 0.
  int stored_features = 0;
  // Under stored_features, the features matched in this many neighbouring
  // keyframes come first (builder/tracks.h: the nearest by camera position
  // when every frame has a pose, else the nearest in the frames' order), a
  // feature matched in more of them before one matched in fewer; within
  // that, spread as above. 0: spread alone. The build matches each keyframe
  // with its neighbours once (a few % of the extraction's time at 4).
  // Range [0, 32]. Default 4.
  int track_neighbours = 4;
  // Extract features on the whole (resized) frame and keep those inside the
  // crop, instead of on the stored crop alone. Descriptors near the crop's
  // border then see the real pixels around them, where on the crop alone ORB
  // drops every keypoint within its 31-pixel edge band (on a 150-pixel crop
  // that is most of it). Keypoints are stored in the stored image's frame
  // either way. Default true.
  bool extract_in_context = true;
  // Keep the stored images as PNGs in images/. Default true.
  bool store_images = true;
  // PNG compression level for stored images (and the whole-frame reference
  // size). Range [0, 9]. Default 3 (libpng's balance of size and speed).
  int png_compression = 3;
  // Retrieval index: none (exhaustive search only), or bow: a vocabulary
  // (trained on the keyframes' descriptors, or vocabulary_file) and its
  // inverted and direct index, stored beside the keyframes. Default none.
  IndexKind index = IndexKind::kNone;
  // Vocabulary training, for index bow without vocabulary_file.
  VocabularyOptions vocabulary;
  // A vocabulary file to use instead of training one (so that many databases
  // share one); it is copied into the database. "" = train. Default "".
  std::string vocabulary_file;
  // The direct index's level.
  BowIndexOptions bow;
  // Worker threads; 0 = one per core. Range [0, 1024]. Default 0.
  int threads = 0;
  // Abort on the first unreadable image instead of skipping it. Default false.
  bool strict = false;
  // Draw a progress bar on a terminal. Default true.
  bool progress = true;
  // Replace an existing database at the output path. Default false.
  bool overwrite = false;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<BuildOptions>& Table();
  std::string Check() const;
};

struct BuildReport {
  size_t num_frames = 0;             // frames given
  size_t num_keyframes = 0;          // stored
  size_t num_skipped = 0;            // unreadable images skipped
  std::vector<std::string> skipped;  // their paths
  size_t num_cropped = 0;            // keyframes kept as a crop (not whole)
  size_t num_features = 0;
  uint64_t image_bytes = 0;     // stored PNGs
  uint64_t feature_bytes = 0;   // the keyframe file
  uint64_t full_png_bytes = 0;  // every readable frame stored whole as PNG
  uint64_t index_bytes = 0;     // the vocabulary and bag-of-words index files
  double seconds = 0.0;
};

// Builds the database at `out_dir`. The database is assembled in a sibling
// temporary directory and moved into place only when complete, so a crash or
// kill leaves any previous database at `out_dir` intact. An existing
// database is replaced only with options.overwrite. Throws on bad options,
// an unusable output path, no readable frame (or, strict, any unreadable one).
BuildReport BuildDatabase(const std::vector<Frame>& frames, const BuildOptions& options,
                          const std::string& out_dir, const std::string& source_description);

// The report as the library's JSON text (the database's path included).
std::string BuildReportJson(const BuildReport& report, const std::string& database,
                            int indent = -1);

}  // namespace placedb
