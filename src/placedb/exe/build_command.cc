// placedb build: make a keyframe database from a sequence of frames.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "placedb/cli/flags.h"
#include "placedb/cli/options.h"
#include "placedb/exe/command.h"
#include "placedb/util/check.h"

namespace placedb {
namespace cli {
namespace {

class BuildCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand("build", "build a keyframe database from a sequence of frames");
    source_.Add(cmd);
    cmd->add_option("--out", out_, "database directory to write")->required();
    AddOptionFlags(cmd, &options_);
    cmd->add_flag("--quiet", quiet_, "no progress bar");
    cmd->add_option("--json", json_, "write a JSON summary to this file ('-': stdout)");
    cmd->footer(
        "Examples:\n"
        "  placedb build --images data/rtabmap_loop/images --last 40 --crop chroma --out office.db\n"
        "  placedb build --tum data/tum_fr3_office_32 --last 16 --out office_tum.db   # with poses\n");
    return cmd;
  }

  int Run() override {
    BuildOptions options = options_;
    options.progress = !quiet_;
    PLACEDB_CHECK_OPTIONS(options);  // before any work or output
    const std::vector<Frame> frames = source_.Read();
    spdlog::info("building {} from {} frames ({} features, crop {}, resize 1/{})", out_,
                 frames.size(), FeatureTypeName(options.features.type), CropModeName(options.crop),
                 options.resize);
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
      fmt::print("index files   {} bytes ({})\n", r.index_bytes, IndexKindName(options.index));
    fmt::print("time          {:.2f} s\n", r.seconds);
    WriteJson(json_, BuildReportJson(r, out_, 2));
    return 0;
  }

 private:
  SourceArgs source_;
  std::string out_;
  BuildOptions options_;
  bool quiet_ = false;
  std::string json_;
};

}  // namespace

std::unique_ptr<Command> MakeBuildCommand() { return std::make_unique<BuildCommand>(); }

}  // namespace cli
}  // namespace placedb
