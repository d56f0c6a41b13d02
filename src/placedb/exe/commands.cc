#include "placedb/exe/commands.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>

#include "placedb/dataset/image_folder.h"
#include "placedb/dataset/match_truth.h"
#include "placedb/dataset/tum.h"
#include "placedb/eval/baseline.h"
#include "placedb/eval/evaluate.h"
#include "placedb/index/builder.h"
#include "placedb/index/query.h"
#include "placedb/match/hamming.h"
#include "placedb/match/l2_distance.h"
#include "placedb/util/check.h"
#include "placedb/util/file_io.h"
#include "placedb/util/thread_pool.h"
#include "placedb/util/timer.h"

namespace placedb {
namespace fs = std::filesystem;
namespace {

// Where frames come from: an image folder / list, or a TUM RGB-D folder.
struct SourceArgs {
  std::string images;
  std::string tum;
  int first = 1;
  int last = 0;
  TumOptions tum_options;

  void Add(CLI::App* cmd, const std::string& what) {
    auto* images_opt = cmd->add_option("--images", images,
                                       what +
                                           ": a folder of images (sorted by name) or a text "
                                           "file listing image paths");
    auto* tum_opt = cmd->add_option("--tum", tum,
                                    what +
                                        ": a TUM RGB-D folder (rgb.txt, "
                                        "groundtruth.txt)");
    images_opt->excludes(tum_opt);
    cmd->add_option("--first", first, "first image id to use (1-based position in the listing)")
        ->capture_default_str()
        ->check(CLI::PositiveNumber);
    cmd->add_option("--last", last, "last image id to use (0: to the end)")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--max-time-diff", tum_options.max_time_difference,
                    "TUM: largest |dt| between a frame and its ground-truth pose, seconds")
        ->capture_default_str();
  }

  std::vector<Frame> Read() const {
    if (!images.empty()) return ReadImages(images, first, last);
    if (!tum.empty()) {
      std::vector<Frame> frames = ReadTumSequence(tum, tum_options);
      const size_t begin = static_cast<size_t>(first - 1);
      const size_t end =
          last == 0 ? frames.size() : std::min(frames.size(), static_cast<size_t>(last));
      PLACEDB_CHECK(begin < frames.size() && begin < end, "--first/--last select no TUM frame");
      return std::vector<Frame>(frames.begin() + begin, frames.begin() + end);
    }
    PLACEDB_THROW_INVALID("give --images DIR or --tum DIR");
  }

  std::string Describe() const {
    const std::string range =
        (first != 1 || last != 0) ? fmt::format(" [{}..{}]", first, last == 0 ? -1 : last) : "";
    return (images.empty() ? "tum:" + tum : "images:" + images) + range;
  }
};

void AddOrbOptions(CLI::App* cmd, OrbOptions& orb) {
  cmd->add_option("--orb-max-features", orb.max_features, "ORB: most keypoints per image")
      ->capture_default_str();
  cmd->add_option("--orb-scale-factor", orb.scale_factor, "ORB: pyramid scale factor")
      ->capture_default_str();
  cmd->add_option("--orb-levels", orb.num_levels, "ORB: pyramid levels")->capture_default_str();
  cmd->add_option("--orb-fast-threshold", orb.fast_threshold, "ORB: FAST threshold")
      ->capture_default_str();
  cmd->add_option("--orb-edge-threshold", orb.edge_threshold, "ORB: border without features, px")
      ->capture_default_str();
}

void AddSurfOptions(CLI::App* cmd, SurfOptions& surf) {
  cmd->add_option("--surf-hessian", surf.hessian_threshold, "SURF: Hessian threshold")
      ->capture_default_str();
  cmd->add_option("--surf-octaves", surf.num_octaves, "SURF: octaves")->capture_default_str();
  cmd->add_option("--surf-layers", surf.num_octave_layers, "SURF: layers per octave")
      ->capture_default_str();
  cmd->add_flag("--surf-extended", surf.extended, "SURF: 128-d descriptors");
  cmd->add_flag("--surf-upright", surf.upright, "SURF: U-SURF, no orientation");
  cmd->add_option("--surf-max-features", surf.max_features, "SURF: most keypoints (0: all)")
      ->capture_default_str();
}

void AddQueryOptions(CLI::App* cmd, QueryOptions& q) {
  cmd->add_option("--top-k", q.top_k, "length of the ranked list")->capture_default_str();
  cmd->add_option("--ratio", q.match.ratio, "Lowe's ratio test threshold")->capture_default_str();
  cmd->add_option("--max-hamming", q.match.max_hamming,
                  "ORB: largest Hamming distance of a match (0: no limit)")
      ->capture_default_str();
  cmd->add_option("--max-l2", q.match.max_l2, "SURF: largest L2 distance of a match (0: no limit)")
      ->capture_default_str();
  cmd->add_option("--min-matches", q.min_matches, "fewest good matches for a keyframe to rank")
      ->capture_default_str();
}

void WriteJson(const std::string& path, const nlohmann::json& j) {
  if (path.empty()) return;
  if (path == "-") {
    std::cout << j.dump(2) << "\n";
    return;
  }
  WriteFileAtomic(path, j.dump(2) + "\n");
  spdlog::info("wrote {}", path);
}

std::string FormatPose(const std::optional<Pose>& pose) {
  if (!pose) return "(no pose)";
  const auto& t = pose->translation;
  const auto& q = pose->rotation;
  return fmt::format("t = ({:.4f}, {:.4f}, {:.4f}) m, q = ({:.4f}, {:.4f}, {:.4f}, {:.4f})", t.x(),
                     t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
}

nlohmann::json PoseJson(const std::optional<Pose>& pose) {
  if (!pose) return nullptr;
  return {{"translation", {pose->translation.x(), pose->translation.y(), pose->translation.z()}},
          {"quaternion_xyzw",
           {pose->rotation.x(), pose->rotation.y(), pose->rotation.z(), pose->rotation.w()}}};
}

// Opens a database and the extractor its queries need. `requested` (from
// --features, may be empty) must agree with what the database was built with.
struct OpenedDatabase {
  Database db;
  ExtractorOptions extractor_options;
  std::unique_ptr<FeatureExtractor> extractor;
};

OpenedDatabase OpenDatabase(const std::string& dir, const std::string& requested) {
  OpenedDatabase o;
  o.db = Database::Load(dir);
  o.extractor_options = ExtractorOptionsFromManifest(o.db.info());
  if (!requested.empty() && ParseFeatureType(requested) != o.db.feature_type()) {
    PLACEDB_THROW_INVALID("the database at ", dir, " was built with ",
                          FeatureTypeName(o.db.feature_type()), " features but --features ",
                          requested, " was asked for; rebuild it or drop --features");
  }
  o.extractor = FeatureExtractor::Create(o.extractor_options);
  return o;
}

// ---- build ----------------------------------------------------------------
struct BuildArgs {
  SourceArgs source;
  std::string out;
  std::string features = "orb";
  std::string crop = "none";
  BuildOptions options;
  bool quiet = false;
  bool no_images = false;
  std::string json;
} g_build;

void RegisterBuild(CLI::App& app) {
  auto* cmd = app.add_subcommand("build", "build a keyframe database from a sequence of frames");
  g_build.source.Add(cmd, "training frames");
  cmd->add_option("--out", g_build.out, "database directory to write")->required();
  cmd->add_option("--features", g_build.features, "feature type")
      ->capture_default_str()
      ->check(CLI::IsMember({"orb", "surf"}));
  cmd->add_option("--crop", g_build.crop, "none, or chroma: the paper's feature-rich crop")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "chroma"}));
  cmd->add_option("--resize", g_build.options.resize, "stored image area divisor: 1, 4 or 16")
      ->capture_default_str()
      ->check(CLI::IsMember({1, 4, 16}));
  cmd->add_option("--threads", g_build.options.threads, "worker threads (0: one per core)")
      ->capture_default_str();
  cmd->add_flag("--quiet", g_build.quiet, "no progress bar");
  cmd->add_flag("--strict", g_build.options.strict, "fail on an unreadable image (default: skip)");
  cmd->add_flag("--overwrite", g_build.options.overwrite, "replace an existing database");
  cmd->add_flag("--no-images", g_build.no_images, "do not keep the stored images (PNG)");
  cmd->add_option("--extract-in-context", g_build.options.extract_in_context,
                  "crop: extract features on the whole frame and keep those inside the crop "
                  "(false: on the stored crop alone)")
      ->capture_default_str();
  cmd->add_option("--png-compression", g_build.options.png_compression, "PNG level 0-9")
      ->capture_default_str();
  CropOptions& c = g_build.options.crop_options;
  cmd->add_option("--crop-percentile", c.percentile,
                  "chroma crop: pixels above this percentile of a channel are concentrated")
      ->capture_default_str();
  cmd->add_option("--crop-sigma", c.smooth_sigma, "chroma crop: smoothing sigma, px")
      ->capture_default_str();
  cmd->add_option("--crop-padding", c.padding, "chroma crop: padding around a region, px")
      ->capture_default_str();
  cmd->add_option("--crop-min-fast", c.min_fast_keypoints,
                  "chroma crop: FAST corners a crop needs (the paper's 15)")
      ->capture_default_str();
  AddOrbOptions(cmd, g_build.options.features.orb);
  AddSurfOptions(cmd, g_build.options.features.surf);
  cmd->add_option("--json", g_build.json, "write a JSON summary to this file ('-': stdout)");
}

int RunBuild() {
  BuildOptions options = g_build.options;
  options.features.type = ParseFeatureType(g_build.features);
  options.crop = ParseCropMode(g_build.crop);
  options.progress = !g_build.quiet;
  options.store_images = !g_build.no_images;
  const std::vector<Frame> frames = g_build.source.Read();
  spdlog::info("building {} from {} frames ({} features, crop {}, resize 1/{})", g_build.out,
               frames.size(), g_build.features, g_build.crop, options.resize);
  const BuildReport r = BuildDatabase(frames, options, g_build.out, g_build.source.Describe());
  fmt::print("database      {}\n", g_build.out);
  fmt::print("keyframes     {} of {} frames ({} skipped as unreadable)\n", r.num_keyframes,
             r.num_frames, r.num_skipped);
  fmt::print("cropped       {} keyframes kept as a feature-rich crop\n", r.num_cropped);
  fmt::print("features      {} ({:.1f} per keyframe)\n", r.num_features,
             r.num_keyframes ? static_cast<double>(r.num_features) / r.num_keyframes : 0.0);
  fmt::print("images        {} bytes (whole frames as PNG: {} bytes, reduction {:.1f}%)\n",
             r.image_bytes, r.full_png_bytes,
             r.full_png_bytes
                 ? 100.0 * (1.0 - static_cast<double>(r.image_bytes) / r.full_png_bytes)
                 : 0.0);
  fmt::print("feature file  {} bytes\n", r.feature_bytes);
  fmt::print("time          {:.2f} s\n", r.seconds);
  nlohmann::json j = {{"database", g_build.out},
                      {"num_frames", r.num_frames},
                      {"num_keyframes", r.num_keyframes},
                      {"num_skipped", r.num_skipped},
                      {"skipped", r.skipped},
                      {"num_cropped", r.num_cropped},
                      {"num_features", r.num_features},
                      {"image_bytes", r.image_bytes},
                      {"feature_bytes", r.feature_bytes},
                      {"full_png_bytes", r.full_png_bytes},
                      {"seconds", r.seconds}};
  WriteJson(g_build.json, j);
  return 0;
}

// ---- query ----------------------------------------------------------------
struct QueryArgs {
  std::string db;
  std::string image;
  std::string features;
  QueryOptions options;
  int threads = 1;
  std::string json;
} g_query;

void RegisterQuery(CLI::App& app) {
  auto* cmd = app.add_subcommand("query", "find the keyframe that best matches an image");
  cmd->add_option("--db", g_query.db, "database directory")->required();
  cmd->add_option("--image", g_query.image, "query image (a full, uncropped frame)")->required();
  cmd->add_option("--features", g_query.features,
                  "expected feature type (must match the database's)")
      ->check(CLI::IsMember({"orb", "surf"}));
  AddQueryOptions(cmd, g_query.options);
  cmd->add_option("--threads", g_query.threads, "threads matching (database partitions)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--json", g_query.json, "write the result as JSON to this file ('-': stdout)");
}

int RunQuery() {
  OpenedDatabase o = OpenDatabase(g_query.db, g_query.features);
  if (o.db.empty()) {
    fmt::print("the database at {} is empty: no keyframes to match against\n", g_query.db);
    return 2;
  }
  const cv::Mat image = cv::imread(g_query.image, cv::IMREAD_COLOR);
  if (image.empty()) PLACEDB_THROW_INVALID("cannot read query image ", g_query.image);
  std::unique_ptr<ThreadPool> pool;
  if (g_query.threads > 1) pool = std::make_unique<ThreadPool>(g_query.threads);
  const QueryResult r = QueryImage(o.db, *o.extractor, image, g_query.options, pool.get());
  nlohmann::json j;
  j["query"] = g_query.image;
  j["num_query_features"] = r.num_query_features;
  j["extract_ms"] = r.extract_ms;
  j["match_ms"] = r.match_ms;
  j["total_ms"] = r.total_ms;
  j["ranked"] = nlohmann::json::array();
  if (!r.found()) {
    fmt::print("no match: no keyframe has {} or more good matches ({} query features)\n",
               g_query.options.min_matches, r.num_query_features);
    j["best"] = nullptr;
  } else {
    const Keyframe& best = o.db.keyframe(o.db.IndexOfId(r.ranked[0].keyframe_id));
    fmt::print("best keyframe {} ({} good matches)  {}\n", best.id, r.ranked[0].score, best.source);
    fmt::print("pose          {}\n", FormatPose(best.pose));
    fmt::print("rank  keyframe  matches\n");
    for (size_t i = 0; i < r.ranked.size(); ++i) {
      fmt::print("{:>4}  {:>8}  {:>7}\n", i + 1, r.ranked[i].keyframe_id, r.ranked[i].score);
      j["ranked"].push_back(
          {{"keyframe_id", r.ranked[i].keyframe_id}, {"score", r.ranked[i].score}});
    }
    j["best"] = {{"keyframe_id", best.id},
                 {"score", r.ranked[0].score},
                 {"source", best.source},
                 {"timestamp", best.timestamp},
                 {"pose", PoseJson(best.pose)}};
  }
  fmt::print("time          {:.2f} ms ({:.2f} extract + {:.2f} match), {} query features\n",
             r.total_ms, r.extract_ms, r.match_ms, r.num_query_features);
  WriteJson(g_query.json, j);
  return 0;
}

// ---- eval -----------------------------------------------------------------
struct EvalArgs {
  std::string db;
  SourceArgs source;
  std::string truth_csv;
  PoseThresholds thresholds;
  EvalOptions options;
  QueryOptions query;
  std::string features;
  bool quiet = false;
  std::string json;
} g_eval;

void RegisterEval(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "eval", "evaluate a database on query frames with ground truth (recall, latency, size)");
  cmd->add_option("--db", g_eval.db, "database directory")->required();
  g_eval.source.Add(cmd, "query frames");
  cmd->add_option("--truth", g_eval.truth_csv,
                  "CSV of true matches (query_id,keyframe ids); with --images");
  cmd->add_option("--max-dist", g_eval.thresholds.max_distance_m,
                  "poses: a keyframe within this distance (m) ...")
      ->capture_default_str();
  cmd->add_option("--max-angle", g_eval.thresholds.max_angle_deg,
                  "... and this viewing angle (deg) of the query is correct")
      ->capture_default_str();
  auto* queries = cmd->add_option("--queries", g_eval.options.num_queries,
                                  "number of random queries (the paper's 50)")
                      ->capture_default_str();
  auto* all = cmd->add_flag("--all", g_eval.options.all, "use every query with ground truth");
  all->excludes(queries);
  cmd->add_option("--seed", g_eval.options.seed, "seed of the random query selection")
      ->capture_default_str();
  cmd->add_option("--threads", g_eval.options.threads, "threads matching each query")
      ->capture_default_str();
  cmd->add_option("--features", g_eval.features, "expected feature type")
      ->check(CLI::IsMember({"orb", "surf"}));
  AddQueryOptions(cmd, g_eval.query);
  cmd->add_flag("--quiet", g_eval.quiet, "no progress bar");
  cmd->add_option("--json", g_eval.json, "write the report as JSON to this file ('-': stdout)");
}

int RunEval() {
  OpenedDatabase o = OpenDatabase(g_eval.db, g_eval.features);
  const std::vector<Frame> frames = g_eval.source.Read();
  GroundTruth truth = GroundTruth::FromPoses(g_eval.thresholds);
  if (!g_eval.truth_csv.empty()) {
    truth = GroundTruth::FromMatchList(ReadMatchTruth(g_eval.truth_csv));
  } else if (g_eval.source.tum.empty()) {
    PLACEDB_THROW_INVALID("eval with --images needs --truth CSV (or use --tum with poses)");
  }
  EvalOptions options = g_eval.options;
  options.progress = !g_eval.quiet;
  const EvalReport r =
      Evaluate(o.db, g_eval.db, *o.extractor, frames, truth, options, g_eval.query);
  fmt::print("eval of {} ({} keyframes, {} features) on {}\n", g_eval.db, o.db.size(),
             FeatureTypeName(o.db.feature_type()), g_eval.source.Describe());
  fmt::print("{}", FormatEvalReport(r));
  nlohmann::json j = EvalReportToJson(r);
  j["database"] = g_eval.db;
  j["queries_from"] = g_eval.source.Describe();
  j["seed"] = options.seed;
  j["settings"] = o.db.info().value("settings", nlohmann::json::object());
  WriteJson(g_eval.json, j);
  return 0;
}

// ---- info -----------------------------------------------------------------
struct InfoArgs {
  std::string db;
  bool json = false;
} g_info;

void RegisterInfo(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "describe a database");
  cmd->add_option("--db", g_info.db, "database directory")->required();
  cmd->add_flag("--json", g_info.json, "print the manifest as JSON");
}

int RunInfo() {
  const Database db = Database::Load(g_info.db);
  const nlohmann::json& m = db.info();
  if (g_info.json) {
    std::cout << m.dump(2) << "\n";
    return 0;
  }
  const nlohmann::json settings = m.value("settings", nlohmann::json::object());
  fmt::print("database        {}\n", g_info.db);
  fmt::print("format version  {}\n", m.value("format_version", 0));
  fmt::print("created         {} by placedb {}\n", m.value("created", "?"),
             m.value("placedb_version", "?"));
  fmt::print("source          {}\n", m.value("source", "?"));
  fmt::print("features        {} ({} bytes per descriptor)\n", FeatureTypeName(db.feature_type()),
             db.descriptor_bytes());
  fmt::print("crop            {}\n", settings.value("crop", "?"));
  fmt::print("resize          1/{} of the area\n", settings.value("resize", 1));
  fmt::print("keyframes       {} ({} cropped, {} frames skipped)\n", db.size(),
             m.contains("counts") ? m["counts"].value("cropped", 0) : 0,
             m.contains("counts") ? m["counts"].value("skipped_images", 0) : 0);
  fmt::print("features        {} ({:.1f} per keyframe)\n", db.num_features(),
             db.empty() ? 0.0 : static_cast<double>(db.num_features()) / db.size());
  fmt::print("stored images   {} bytes\n",
             DirectorySize((fs::path(g_info.db) / "images").string()));
  fmt::print("feature file    {} bytes\n",
             FileSize((fs::path(g_info.db) / Database::kKeyframesFile).string()));
  if (m.contains("bytes")) {
    fmt::print("whole frames    {} bytes as PNG\n",
               m["bytes"].value("full_frames_png", uint64_t{0}));
  }
  size_t with_pose = 0;
  for (const Keyframe& k : db.keyframes()) with_pose += k.pose.has_value();
  fmt::print("poses           {} of {} keyframes\n", with_pose, db.size());
  return 0;
}

// ---- bench ----------------------------------------------------------------
struct BenchArgs {
  std::string db;
  SourceArgs source;
  int queries = 20;
  uint64_t seed = 1;
  int repeat = 3;
  QueryOptions query;
  std::string json;
} g_bench;

void RegisterBench(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "bench", "time matching per query: placedb vs the paper's OpenCV BFMatcher loop");
  cmd->add_option("--db", g_bench.db, "database directory")->required();
  g_bench.source.Add(cmd, "query frames");
  cmd->add_option("--queries", g_bench.queries, "number of query frames (0: all)")
      ->capture_default_str();
  cmd->add_option("--seed", g_bench.seed, "seed of the query selection")->capture_default_str();
  cmd->add_option("--repeat", g_bench.repeat, "times each query is matched per method")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  AddQueryOptions(cmd, g_bench.query);
  cmd->add_option("--json", g_bench.json, "write the timings as JSON to this file ('-': stdout)");
}

int RunBench() {
  OpenedDatabase o = OpenDatabase(g_bench.db, "");
  if (o.db.empty()) PLACEDB_THROW_INVALID("the database is empty: nothing to benchmark");
  const std::vector<Frame> frames =
      SampleFrames(g_bench.source.Read(), g_bench.queries, g_bench.seed);
  std::vector<FeatureSet> features;
  double extract_ms = 0;
  for (const Frame& f : frames) {
    const cv::Mat image = cv::imread(f.image_path, cv::IMREAD_COLOR);
    if (image.empty()) {
      spdlog::warn("skipped unreadable query image {}", f.image_path);
      continue;
    }
    Timer t;
    features.push_back(o.extractor->Extract(image));
    extract_ms += t.ElapsedMs();
  }
  PLACEDB_CHECK(!features.empty(), "no readable query image");
  const int n = static_cast<int>(features.size());
  cv::setNumThreads(1);  // the baseline on one core, as ours
  int disagreements = 0;
  double ours_ms = 1e300, base_ms = 1e300, ours_mt_ms = 1e300;
  const int threads = ThreadPool::HardwareThreads();
  ThreadPool pool(threads);
  for (int rep = 0; rep < g_bench.repeat; ++rep) {
    Timer t;
    std::vector<std::vector<ScoredKeyframe>> ours(n), base(n);
    for (int i = 0; i < n; ++i) ours[i] = QueryFeatures(o.db, features[i], g_bench.query).ranked;
    ours_ms = std::min(ours_ms, t.ElapsedMs() / n);
    t.Restart();
    for (int i = 0; i < n; ++i) QueryFeatures(o.db, features[i], g_bench.query, &pool);
    ours_mt_ms = std::min(ours_mt_ms, t.ElapsedMs() / n);
    t.Restart();
    for (int i = 0; i < n; ++i) base[i] = BfMatcherQuery(o.db, features[i], g_bench.query);
    base_ms = std::min(base_ms, t.ElapsedMs() / n);
    if (rep == 0) {
      // BFMatcher knows no Laplacian sign: compare SURF rankings without it.
      QueryOptions same = g_bench.query;
      same.match.use_laplacian_sign = false;
      for (int i = 0; i < n; ++i) {
        const auto& comparable = o.db.feature_type() == FeatureType::kSurf
                                     ? QueryFeatures(o.db, features[i], same).ranked
                                     : ours[i];
        disagreements += comparable != base[i];
      }
    }
  }
  const double descriptors_per_query = static_cast<double>(o.db.num_features());
  fmt::print("bench of {} ({} keyframes, {} {} descriptors), {} queries x {} repeats\n", g_bench.db,
             o.db.size(), o.db.num_features(), FeatureTypeName(o.db.feature_type()), n,
             g_bench.repeat);
  const char* kernel =
      o.db.feature_type() == FeatureType::kOrb ? HammingKernelName() : L2SquaredKernelName();
  fmt::print("distance kernel           {}\n", kernel);
  fmt::print("query extraction          {:8.3f} ms/query\n", extract_ms / n);
  fmt::print("placedb, 1 thread         {:8.3f} ms/query\n", ours_ms);
  fmt::print("placedb, {} threads        {:8.3f} ms/query\n", threads, ours_mt_ms);
  fmt::print("BFMatcher loop (paper)    {:8.3f} ms/query\n", base_ms);
  fmt::print("speed-up vs BFMatcher     {:8.2f}x (1 thread), {:.2f}x ({} threads)\n",
             base_ms / ours_ms, base_ms / ours_mt_ms, threads);
  fmt::print("rankings that differ      {} of {}\n", disagreements, n);
  nlohmann::json j = {{"database", g_bench.db},
                      {"num_keyframes", o.db.size()},
                      {"num_db_descriptors", descriptors_per_query},
                      {"num_queries", n},
                      {"repeat", g_bench.repeat},
                      {"distance_kernel", kernel},
                      {"extract_ms_per_query", extract_ms / n},
                      {"placedb_ms_per_query", ours_ms},
                      {"placedb_threads", threads},
                      {"placedb_mt_ms_per_query", ours_mt_ms},
                      {"bfmatcher_ms_per_query", base_ms},
                      {"speedup_vs_bfmatcher", base_ms / ours_ms},
                      {"speedup_mt_vs_bfmatcher", base_ms / ours_mt_ms},
                      {"rankings_that_differ", disagreements}};
  WriteJson(g_bench.json, j);
  return disagreements == 0 ? 0 : 3;
}

const std::map<std::string, std::function<int()>>& Runners() {
  static const std::map<std::string, std::function<int()>> runners = {{"build", RunBuild},
                                                                      {"query", RunQuery},
                                                                      {"eval", RunEval},
                                                                      {"info", RunInfo},
                                                                      {"bench", RunBench}};
  return runners;
}

}  // namespace

void RegisterCommands(CLI::App& app) {
  RegisterBuild(app);
  RegisterQuery(app);
  RegisterEval(app);
  RegisterInfo(app);
  RegisterBench(app);
}

int RunSelectedCommand(CLI::App& app) {
  for (CLI::App* sub : app.get_subcommands()) {
    const auto it = Runners().find(sub->get_name());
    if (it != Runners().end()) return it->second();
  }
  PLACEDB_THROW_INVALID("no sub-command given");
}

}  // namespace placedb
