// The command-line layer the placedb binary and the ROS nodes share: flag
// groups bound straight onto the library's options structs (so --help and
// the code cannot drift apart), and output helpers. Commands are thin: they
// parse flags, call the library, print.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "placedb/dataset/frame.h"
#include "placedb/dataset/tum.h"
#include "placedb/eval/evaluate.h"
#include "placedb/eval/ground_truth.h"
#include "placedb/feature/extractor.h"
#include "placedb/image/feature_rich_crop.h"
#include "placedb/session/place_database.h"
#include "placedb/query/query.h"
#include "placedb/util/pose.h"

namespace placedb {
namespace cli {

// Where frames come from: an image folder / list, or a TUM RGB-D folder,
// with an id range and optionally a simulated camera size.
struct SourceArgs {
  std::string images;
  std::string tum;
  // A ROS bag: --bag FILE --topic T, poses from --bag-groundtruth or --bag-tf.
  std::string bag, topic, bag_groundtruth, bag_tf;
  int first = 1;
  int last = 0;
  std::string frame_size;  // "WxH" or ""
  TumOptions tum_options;
  ImageReadOptions image_read;  // --max-image-pixels

  void Add(CLI::App* cmd, const std::string& what);
  std::vector<Frame> Read() const;
  // "images:DIR [41..84]", "tum:DIR [5..]".
  std::string Describe() const;
};

// How correctness is judged: --truth CSV (a match list) or, without it, the
// frames' poses (--max-dist, --max-angle).
struct TruthArgs {
  std::string csv;
  PoseThresholds thresholds;

  void Add(CLI::App* cmd);
  // The ground truth for queries from `source`: a match list is required for
  // an image folder (InvalidArgument naming `command`).
  GroundTruth Get(const SourceArgs& source, const std::string& command) const;
};

// --queries N / --all / --seed S: which validation queries.
void AddQuerySelectionOptions(CLI::App* cmd, EvalOptions& options);

// --max-image-pixels N: the largest image decoded (ImageReadOptions).
void AddImageReadOptions(CLI::App* cmd, ImageReadOptions& options);

// --threads T for every command: 0 = one thread per core.
void AddThreadsOption(CLI::App* cmd, int& threads, const std::string& what);
void AddExtractorOptions(CLI::App* cmd, ExtractorOptions& options);
void AddCropOptions(CLI::App* cmd, CropOptions& options);
// Every field of QueryOptions (retrieve, match, verify, decide) as flags.
struct QueryArgs {
  QueryOptions options;
  std::string search = RetrievalMethodName(options.retrieval.method);
  std::string model = GeometricModelName(options.verify.model);

  // `for_queries` false leaves out what only running a query uses (the
  // deadline and the prior): for a voter, which only merges, and has a
  // deadline of its own.
  void Add(CLI::App* cmd, bool for_queries = true);
  // The options with the named choices applied.
  QueryOptions Get() const;
};

// --db DIR, --features (the type the caller expects), the subset to open
// (--partition I/N with --partition-scheme, or --keyframes ID,ID,...) and,
// when `threads_what` is not empty, --threads: the database a command opens.
struct DatabaseArgs {
  std::string dir;
  std::string features;
  std::string partition;  // "I/N" or ""
  std::string scheme = "contiguous";
  std::string keyframes;  // "ID,ID,..." or ""
  OpenOptions open;

  void Add(CLI::App* cmd, const std::string& threads_what);
  PlaceDatabase Open() const;
};

// Writes JSON to `path` atomically ("-": stdout; "": nothing).
void WriteJson(const std::string& path, const nlohmann::json& j);
// "t = (x, y, z) m, q = (x, y, z, w)" or "(no pose)".
std::string FormatPose(const std::optional<Pose>& pose);
// "WxH" -> size; throws InvalidArgument naming the option `name` (frame_size).
cv::Size ParseSize(const std::string& text, const std::string& name);

}  // namespace cli
}  // namespace placedb
