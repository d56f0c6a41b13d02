#include "placedb/cli/flags.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <iostream>

#include "placedb/dataset/image_folder.h"
#include "placedb/dataset/match_truth.h"
#ifdef PLACEDB_WITH_ROS
#include "placedb/dataset/bag/bag_source.h"
#endif
#include "placedb/util/check.h"
#include "placedb/util/file_io.h"
#include "placedb/util/json_reader.h"

namespace placedb {
namespace cli {

void SourceArgs::Add(CLI::App* cmd, const std::string& what) {
  auto* images_opt = cmd->add_option(
      "--images", images,
      what + ": a folder of images (sorted by name) or a text file listing image paths");
  auto* tum_opt =
      cmd->add_option("--tum", tum, what + ": a TUM RGB-D folder (rgb.txt, groundtruth.txt)");
  images_opt->excludes(tum_opt);
  auto* bag_opt = cmd->add_option(
      "--bag", bag, what + ": a ROS bag (needs a build with ROS); the images on --topic");
  bag_opt->excludes(images_opt)->excludes(tum_opt);
  cmd->add_option("--topic", topic, "bag: the image topic (sensor_msgs/Image or CompressedImage)");
  cmd->add_option("--bag-groundtruth", bag_groundtruth, "bag: poses from this TUM trajectory file");
  cmd->add_option("--bag-tf", bag_tf,
                  "bag: poses from /tf, the transform PARENT,CHILD (e.g. world,kinect)");
  cmd->add_option("--first", first, "first image id to use (1-based position in the listing)")
      ->capture_default_str();
  cmd->add_option("--last", last, "last image id to use (0: to the end)")->capture_default_str();
  cmd->add_option("--frame-size", frame_size,
                  "resize every frame to WxH as it is read, to see how a smaller camera "
                  "does (e.g. 160x120); each side in [16, 16384], W x H at most "
                  "--max-image-pixels");
  AddImageReadOptions(cmd, image_read);
  cmd->add_option("--max-time-diff", tum_options.max_time_difference,
                  "TUM: largest |dt| between a frame and its ground-truth pose, seconds [0, 3600]")
      ->capture_default_str();
  cmd->add_option("--tum-rgb-list", tum_options.rgb_list, "TUM: image list inside the folder")
      ->capture_default_str();
  cmd->add_option("--tum-groundtruth", tum_options.groundtruth,
                  "TUM: ground-truth file inside the folder")
      ->capture_default_str();
}

std::vector<Frame> SourceArgs::Read() const {
  std::vector<Frame> frames;
  if (!images.empty()) {
    frames = ReadImages(images, first, last);
  } else if (!tum.empty()) {
    frames = SelectFrameRange(ReadTumSequence(tum, tum_options), first, last, "TUM frame");
  } else if (!bag.empty()) {
#ifdef PLACEDB_WITH_ROS
    BagSourceOptions o;
    o.bag = bag;
    o.topic = topic;
    o.groundtruth = bag_groundtruth;
    o.max_time_difference = tum_options.max_time_difference;
    if (!bag_tf.empty()) {
      const size_t comma = bag_tf.find(',');
      if (comma == std::string::npos) PLACEDB_THROW_INVALID("`bag_tf` takes PARENT,CHILD");
      o.tf_parent = bag_tf.substr(0, comma);
      o.tf_child = bag_tf.substr(comma + 1);
    }
    frames = SelectFrameRange(ReadBagFrames(o), first, last, "bag frame");
#else
    PLACEDB_THROW_INVALID(
        "this placedb was built without ROS (-DPLACEDB_WITH_ROS=OFF): `bag` is not available");
#endif
  } else {
    PLACEDB_THROW_INVALID("give `images` DIR, `tum` DIR or `bag` FILE `topic` T");
  }
  PLACEDB_CHECK_OPTIONS(image_read);
  SetImageReadOptions(&frames, image_read);
  if (!frame_size.empty()) {
    const cv::Size size = ParseSize(frame_size, "frame_size");
    if (static_cast<int64_t>(size.width) * size.height > image_read.max_pixels) {
      PLACEDB_THROW_INVALID("`frame_size` ", frame_size, " is ",
                            static_cast<int64_t>(size.width) * size.height,
                            " pixels, more than `max_image_pixels` ", image_read.max_pixels);
    }
    ResizeFramesTo(&frames, size);
  }
  return frames;
}

std::string SourceArgs::Describe() const {
  const std::string range = FrameRangeSuffix(first, last);
  const std::string size = frame_size.empty() ? "" : " at " + frame_size;
  const std::string what = !images.empty() ? "images:" + images
                           : !tum.empty()  ? "tum:" + tum
                                           : "bag:" + bag + ":" + topic;
  return what + range + size;
}

cv::Size ParseSize(const std::string& text, const std::string& name) {
  // Two whole numbers joined by 'x', nothing else around them.
  auto whole = [](const char* begin, const char* end, int* out) {
    const auto [ptr, ec] = std::from_chars(begin, end, *out);
    return begin != end && ec == std::errc() && ptr == end;
  };
  const size_t x = text.find('x');
  int w = 0, h = 0;
  if (x == std::string::npos || !whole(text.data(), text.data() + x, &w) ||
      !whole(text.data() + x + 1, text.data() + text.size(), &h)) {
    PLACEDB_THROW_INVALID("`", name, "` takes WxH, e.g. 160x120 (got '", text, "')");
  }
  if (w < 16 || h < 16 || w > 16384 || h > 16384)
    PLACEDB_THROW_INVALID("`", name, "`: each side must be in [16, 16384] (got ", text, ")");
  return {w, h};
}

void TruthArgs::Add(CLI::App* cmd) {
  cmd->add_option("--truth", csv,
                  "CSV of true matches (query_id,keyframe ids); needed with --images, else "
                  "poses decide");
  cmd->add_option("--max-dist", thresholds.max_distance_m,
                  "poses: a keyframe within this distance (m) ... (0, 1e6]")
      ->capture_default_str();
  cmd->add_option("--max-angle", thresholds.max_angle_deg,
                  "... and this viewing angle (deg) of the query is correct (0, 180]")
      ->capture_default_str();
}

GroundTruth TruthArgs::Get(const SourceArgs& source, const std::string& command) const {
  if (!csv.empty()) return GroundTruth::FromMatchList(ReadMatchTruth(csv));
  if (!source.images.empty()) {
    PLACEDB_THROW_INVALID(command, " with `images` needs `truth` CSV (or use `tum` with poses)");
  }
  return GroundTruth::FromPoses(thresholds);
}

void AddQuerySelectionOptions(CLI::App* cmd, EvalOptions& options) {
  auto* queries = cmd->add_option("--queries", options.num_queries,
                                  "number of random queries (the paper's 50) [1, 1000000]")
                      ->capture_default_str();
  cmd->add_flag("--all", options.all, "use every query with ground truth")->excludes(queries);
  cmd->add_option("--seed", options.seed, "seed of the random query selection")
      ->capture_default_str();
}

void AddImageReadOptions(CLI::App* cmd, ImageReadOptions& options) {
  cmd->add_option("--max-image-pixels", options.max_pixels,
                  "largest image decoded, width x height pixels as its header declares them "
                  "(checked before decoding; also bounds --frame-size) [1, 2^30]")
      ->capture_default_str();
}

void AddThreadsOption(CLI::App* cmd, int& threads, const std::string& what) {
  cmd->add_option("--threads", threads, what + " (0: one per core) [0, 1024]")
      ->capture_default_str();
}

void AddExtractorOptions(CLI::App* cmd, ExtractorOptions& o) {
  OrbOptions& orb = o.orb;
  cmd->add_option("--orb-max-features", orb.max_features,
                  "ORB: most keypoints per image [1, 100000]")
      ->capture_default_str();
  cmd->add_option("--orb-scale-factor", orb.scale_factor, "ORB: pyramid scale factor (1, 4]")
      ->capture_default_str();
  cmd->add_option("--orb-levels", orb.num_levels, "ORB: pyramid levels [1, 32]")
      ->capture_default_str();
  cmd->add_option("--orb-fast-threshold", orb.fast_threshold, "ORB: FAST threshold [1, 255]")
      ->capture_default_str();
  cmd->add_option("--orb-edge-threshold", orb.edge_threshold,
                  "ORB: border without features, px [0, 512]")
      ->capture_default_str();
  cmd->add_option("--orb-patch-size", orb.patch_size, "ORB: BRIEF patch size, px [2, 512]")
      ->capture_default_str();
  SurfOptions& surf = o.surf;
  cmd->add_option("--surf-hessian", surf.hessian_threshold, "SURF: Hessian threshold [0, 1e6]")
      ->capture_default_str();
  cmd->add_option("--surf-octaves", surf.num_octaves, "SURF: octaves [1, 8]")
      ->capture_default_str();
  cmd->add_option("--surf-layers", surf.num_octave_layers, "SURF: layers per octave [1, 8]")
      ->capture_default_str();
  cmd->add_flag("--surf-extended", surf.extended, "SURF: 128-d descriptors");
  cmd->add_flag("--surf-upright", surf.upright, "SURF: U-SURF, no orientation");
  cmd->add_option("--surf-max-features", surf.max_features,
                  "SURF: most keypoints (0: all) [0, 1000000]")
      ->capture_default_str();
  cmd->add_option("--upscale-below", o.upscale_below,
                  "small frames: upscale images whose shorter side is below this for "
                  "extraction (0: never) [0, 4096]")
      ->capture_default_str();
}

void AddCropOptions(CLI::App* cmd, CropOptions& c) {
  cmd->add_option("--crop-percentile", c.percentile,
                  "chroma crop: pixels above this percentile of a channel are concentrated "
                  "[0, 99.9]")
      ->capture_default_str();
  cmd->add_option("--crop-sigma", c.smooth_sigma, "chroma crop: smoothing sigma, px [0, 50]")
      ->capture_default_str();
  cmd->add_option("--crop-padding", c.padding, "chroma crop: padding around a region, px [0, 4096]")
      ->capture_default_str();
  cmd->add_option("--crop-min-fast", c.min_fast_keypoints,
                  "chroma crop: FAST corners a crop needs (the paper's 15) [0, 100000]")
      ->capture_default_str();
  cmd->add_option("--crop-fast-threshold", c.fast_threshold,
                  "chroma crop: FAST threshold of the count [1, 255]")
      ->capture_default_str();
  cmd->add_option("--crop-fast-nonmax", c.fast_nonmax,
                  "chroma crop: FAST non-maximum suppression (true/false)")
      ->capture_default_str();
  cmd->add_option("--crop-min-region", c.min_region_pixels,
                  "chroma crop: smallest region that can become a crop, pixels [1, 1e8]")
      ->capture_default_str();
}

void DatabaseArgs::Add(CLI::App* cmd, const std::string& threads_what) {
  cmd->add_option("--db", dir, "database directory")->required();
  cmd->add_option("--features", features, "expected feature type (must match the database's)")
      ->check(CLI::IsMember({"orb", "surf"}));
  auto* part = cmd->add_option("--partition", partition,
                               "open only partition I of N of the keyframes (I in [0, N), N in "
                               "[1, 4096]), e.g. 0/3");
  cmd->add_option("--partition-scheme", scheme, "contiguous ranges or interleaved indices")
      ->capture_default_str()
      ->check(CLI::IsMember({"contiguous", "interleaved"}));
  cmd->add_option("--keyframes", keyframes, "open only these keyframe ids, e.g. 3,4,17")
      ->excludes(part);
  if (!threads_what.empty()) AddThreadsOption(cmd, open.threads, threads_what);
  cmd->add_option("--cluster-radius", open.clusters.radius_m,
                  "cluster search: radius of a spatial cluster, in the poses' unit (0, 1e6]")
      ->capture_default_str();
  cmd->add_option("--cluster-keyframes", open.clusters.time_keyframes,
                  "cluster search without poses: consecutive keyframes per cluster [1, 1000000]")
      ->capture_default_str();
}

namespace {
// A whole number in [lo, hi] from `text`, or InvalidArgument naming `what` (an
// option name, marked in the message, and the part of it).
int64_t ParseInteger(const std::string& text, const std::string& what, int64_t lo, int64_t hi) {
  size_t used = 0;
  int64_t v = 0;
  try {
    v = std::stoll(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || v < lo || v > hi) {
    PLACEDB_THROW_INVALID(what, ": '", text, "' is not a whole number in [", lo, ", ", hi, "]");
  }
  return v;
}
}  // namespace

PlaceDatabase DatabaseArgs::Open() const {
  OpenOptions o = open;
  if (!features.empty()) o.expected_features = ParseFeatureType(features);
  if (!partition.empty()) {
    const size_t slash = partition.find('/');
    if (slash == std::string::npos) PLACEDB_THROW_INVALID("`partition` takes I/N, e.g. 0/3");
    const int n =
        static_cast<int>(ParseInteger(partition.substr(slash + 1), "`partition` N", 1, 4096));
    const int i =
        static_cast<int>(ParseInteger(partition.substr(0, slash), "`partition` I", 0, n - 1));
    o.subset = KeyframeSubset::Partition(i, n, ParsePartitionScheme(scheme));
  } else if (!keyframes.empty()) {
    std::vector<int32_t> ids;
    size_t begin = 0;
    while (begin <= keyframes.size()) {
      const size_t comma = std::min(keyframes.find(',', begin), keyframes.size());
      ids.push_back(static_cast<int32_t>(ParseInteger(keyframes.substr(begin, comma - begin),
                                                      "`keyframes`", INT32_MIN, INT32_MAX)));
      begin = comma + 1;
    }
    o.subset = KeyframeSubset::Ids(std::move(ids));
  }
  return PlaceDatabase::Open(dir, o);
}

void QueryArgs::Add(CLI::App* cmd, bool for_queries) {
  QueryOptions& q = options;
  cmd->add_option("--top-k", q.top_k, "length of the ranked list [1, 10000]")
      ->capture_default_str();
  cmd->add_option("--search", search,
                  "retrieve stage: exhaustive (every keyframe), bow (bag-of-words candidates; "
                  "needs a database built with --index bow) or cluster (the prior's "
                  "spatial-locality clusters first, then the rest when the answer is weak)")
      ->capture_default_str()
      ->check(CLI::IsMember({"exhaustive", "bow", "cluster"}));
  cmd->add_option("--bow-candidates", q.retrieval.bow_candidates,
                  "bow: keyframes scored best by bag of words [1, 100000]")
      ->capture_default_str();
  cmd->add_option("--guided-candidates", q.retrieval.guided_candidates,
                  "bow: of those, the ones with the most guided matches (same vocabulary node) "
                  "are matched in full; 0 = all [0, 100000]")
      ->capture_default_str();
  cmd->add_option("--cluster-hops", q.retrieval.cluster_hops,
                  "cluster: neighbour clusters searched around the prior's, in hops [0, 64]")
      ->capture_default_str();
  cmd->add_option("--cluster-fallback-score", q.retrieval.cluster_fallback_score,
                  "cluster: a local best score below this searches the rest of the database "
                  "(0: --min-score) [0, 100000]")
      ->capture_default_str();
  if (for_queries) {
    cmd->add_option("--prior-keyframe", q.prior.keyframe_id,
                    "cluster: id of a keyframe near the query (e.g. the last answer); 0: none "
                    "[0, 2^31)")
        ->capture_default_str();
    cmd->add_option("--deadline-ms", q.deadline_ms,
                    "time budget of retrieve + match + verify, ms; candidates are examined best "
                    "first until it runs out (0: none) [0, 1e7]")
        ->capture_default_str();
  }
  cmd->add_option("--ratio", q.match.ratio, "Lowe's ratio test threshold (0, 1]")
      ->capture_default_str();
  cmd->add_option("--max-hamming", q.match.max_hamming,
                  "ORB: largest Hamming distance of a match (0: no limit) [0, 256]")
      ->capture_default_str();
  cmd->add_option("--max-l2", q.match.max_l2,
                  "SURF: largest L2 distance of a match (0: no limit) [0, 2]")
      ->capture_default_str();
  cmd->add_option("--laplacian-sign", q.match.use_laplacian_sign,
                  "SURF: never match opposite Laplacian signs (true/false)")
      ->capture_default_str();
  cmd->add_option("--one-to-one", q.match.one_to_one,
                  "a keyframe descriptor keeps only its closest query match (true/false)")
      ->capture_default_str();
  cmd->add_option("--cross-check", q.match.cross_check,
                  "sparse-keyframe guard: matches must be mutual and pass the ratio test "
                  "among the query's descriptors too (true/false)")
      ->capture_default_str();
  cmd->add_option("--min-matches", q.min_matches,
                  "fewest matches for a keyframe to be ranked [1, 100000]")
      ->capture_default_str();
  cmd->add_flag("--verify,!--no-verify", q.verify.enabled,
                "verify stage: RANSAC (USAC) on the best candidates, inliers are the score")
      ->capture_default_str();
  cmd->add_option("--verify-model", model, "fundamental or homography")
      ->capture_default_str()
      ->check(CLI::IsMember({"fundamental", "homography"}));
  cmd->add_option("--verify-candidates", q.verify.num_candidates,
                  "keyframes verified (the best by matches) [1, 1000]")
      ->capture_default_str();
  cmd->add_option("--verify-error", q.verify.max_error_px,
                  "largest inlier error, px of the query image (0, 100]")
      ->capture_default_str();
  cmd->add_option("--verify-confidence", q.verify.confidence, "RANSAC confidence [0.5, 0.999999]")
      ->capture_default_str();
  cmd->add_option("--verify-iterations", q.verify.max_iterations,
                  "RANSAC iterations at most [1, 100000]")
      ->capture_default_str();
  cmd->add_option("--verify-seed", q.verify.seed, "RANSAC seed [0, 2^31)")->capture_default_str();
  cmd->add_option("--min-score", q.min_score,
                  "decide stage: the best keyframe is the answer when its score (inliers when "
                  "verified, else matches) is at least this; else 'no match' [0, 100000]")
      ->capture_default_str();
}

QueryOptions QueryArgs::Get() const {
  QueryOptions q = options;
  q.retrieval.method = ParseRetrievalMethod(search);
  q.verify.model = ParseGeometricModel(model);
  PLACEDB_CHECK_OPTIONS(q);
  return q;
}

void WriteJson(const std::string& path, const nlohmann::json& j) {
  if (path.empty()) return;
  if (path == "-") {
    std::cout << DumpJson(j, 2) << "\n";
    return;
  }
  WriteFileAtomic(path, DumpJson(j, 2) + "\n");
  spdlog::info("wrote {}", path);
}

std::string FormatPose(const std::optional<Pose>& pose) {
  if (!pose) return "(no pose)";
  const auto& t = pose->translation;
  const auto& q = pose->rotation;
  return fmt::format("t = ({:.4f}, {:.4f}, {:.4f}) m, q = ({:.4f}, {:.4f}, {:.4f}, {:.4f})", t.x(),
                     t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
}

}  // namespace cli
}  // namespace placedb
