// placedb build: make a keyframe database from a sequence of frames.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "placedb/cli/flags.h"
#include "placedb/exe/command.h"
#include "placedb/build/builder.h"
#include "placedb/util/check.h"

namespace placedb {
namespace cli {
namespace {

class BuildCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand("build", "build a keyframe database from a sequence of frames");
    source_.Add(cmd, "training frames");
    cmd->add_option("--out", out_, "database directory to write")->required();
    cmd->add_option("--features", features_, "feature type: orb or surf")
        ->capture_default_str()
        ->check(CLI::IsMember({"orb", "surf"}));
    cmd->add_option("--crop", crop_, "none, or chroma: the paper's feature-rich crop")
        ->capture_default_str()
        ->check(CLI::IsMember({"none", "chroma"}));
    cmd->add_option("--resize", options_.resize, "stored image area divisor: 1, 4 or 16")
        ->capture_default_str();
    AddThreadsOption(cmd, options_.threads, "worker threads");
    cmd->add_flag("--quiet", quiet_, "no progress bar");
    cmd->add_flag("--strict", options_.strict, "fail on an unreadable image (default: skip)");
    cmd->add_flag("--overwrite", options_.overwrite, "replace an existing database");
    cmd->add_flag("--no-images", no_images_, "do not keep the stored images (PNG)");
    cmd->add_option("--extract-in-context", options_.extract_in_context,
                    "crop: extract features on the whole frame and keep those inside the crop "
                    "(false: on the stored crop alone)")
        ->capture_default_str();
    cmd->add_option("--png-compression", options_.png_compression, "PNG level [0, 9]")
        ->capture_default_str();
    cmd->add_option("--index", index_,
                    "retrieval index: none, or bow (a vocabulary and an inverted file, for "
                    "--search bow)")
        ->capture_default_str()
        ->check(CLI::IsMember({"none", "bow"}));
    cmd->add_option("--vocabulary", options_.vocabulary_file,
                    "bow: use this vocabulary file (e.g. another database's vocabulary.bin) "
                    "instead of training one");
    VocabularyOptions& v = options_.vocabulary;
    cmd->add_option("--vocabulary-branching", v.branching, "bow: children per node [2, 64]")
        ->capture_default_str();
    cmd->add_option("--vocabulary-depth", v.depth,
                    "bow: levels of the vocabulary tree [1, 8] (branching^depth <= 2^24)")
        ->capture_default_str();
    cmd->add_option("--vocabulary-iterations", v.iterations,
                    "bow: clustering iterations per node [1, 100]")
        ->capture_default_str();
    cmd->add_option("--vocabulary-sample", v.max_training_descriptors,
                    "bow: descriptors sampled for training [1000, 100000000]")
        ->capture_default_str();
    cmd->add_option("--vocabulary-seed", v.seed, "bow: training seed")->capture_default_str();
    cmd->add_option("--direct-level", options_.bow.direct_level,
                    "bow: vocabulary level of the direct index [0, depth]")
        ->capture_default_str();
    AddCropOptions(cmd, options_.crop_options);
    AddExtractorOptions(cmd, options_.features);
    cmd->add_option("--json", json_, "write a JSON summary to this file ('-': stdout)");
    return cmd;
  }

  int Run() override {
    BuildOptions options = options_;
    options.features.type = ParseFeatureType(features_);
    options.crop = ParseCropMode(crop_);
    options.index = ParseIndexKind(index_);
    options.progress = !quiet_;
    options.store_images = !no_images_;
    PLACEDB_CHECK_OPTIONS(options);  // before any work or output
    const std::vector<Frame> frames = source_.Read();
    spdlog::info("building {} from {} frames ({} features, crop {}, resize 1/{})", out_,
                 frames.size(), features_, crop_, options.resize);
    const BuildReport r = BuildDatabase(frames, options, out_, source_.Describe());
    fmt::print("database      {}\n", out_);
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
    if (options.index != IndexKind::kNone)
      fmt::print("index files   {} bytes ({})\n", r.index_bytes, index_);
    fmt::print("time          {:.2f} s\n", r.seconds);
    WriteJson(json_, BuildReportToJson(r, out_));
    return 0;
  }

 private:
  SourceArgs source_;
  std::string out_;
  std::string features_ = "orb";
  std::string crop_ = "none";
  std::string index_ = "none";
  BuildOptions options_;
  bool quiet_ = false;
  bool no_images_ = false;
  std::string json_;
};

}  // namespace

std::unique_ptr<Command> MakeBuildCommand() { return std::make_unique<BuildCommand>(); }

}  // namespace cli
}  // namespace placedb
