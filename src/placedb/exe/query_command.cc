// placedb query: where was this image taken?
#include <fmt/format.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "placedb/cli/flags.h"
#include "placedb/cli/options.h"
#include "placedb/exe/command.h"
#include "placedb/util/check.h"
#include "placedb/util/file_io.h"
#include "placedb/util/json_reader.h"

namespace placedb {
namespace cli {
namespace fs = std::filesystem;
namespace {

class QueryCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand("query", "find the keyframe that best matches an image");
    db_.Add(cmd);
    cmd->add_option("--image", image_, "query image (a full, uncropped frame)")->required();
    AddOptionFlags(cmd, &image_read_);
    query_.Add(cmd);
    cmd->add_option("--json", json_, "write the result as JSON to this file ('-': stdout)");
    cmd->add_option("--draw", draw_,
                    "write a PNG of the query beside its best keyframe (the best ranked when "
                    "there is no match), the matches joined by lines: verified green, others "
                    "amber");
    cmd->footer(
        "Examples:\n"
        "  placedb query --db office.db --image data/rtabmap_loop/images/042.jpg\n"
        "  placedb query --db office.db --image data/rtabmap_loop/images/042.jpg --json - | python3 -m json.tool\n");
    return cmd;
  }

  int Run() override {
    const QueryOptions options = query_.Get();
    if (!draw_.empty() && fs::path(draw_).extension() != ".png") {
      PLACEDB_THROW_INVALID("`draw` needs a .png file name (got ", draw_, ")");
    }
    const PlaceDatabase db = db_.Open();
    if (db.empty()) {
      fmt::print("the database at {} is empty: no keyframes to match against\n", db_.dir);
      return 2;
    }
    PLACEDB_CHECK_OPTIONS(image_read_);
    const DecodedImage decoded = TryReadImageFile(image_, image_read_);
    if (decoded.too_large) PLACEDB_THROW_INVALID("query ", decoded.error);
    // "cannot read image PATH: why" -> "cannot read query image PATH: why".
    if (decoded.image.empty())
      ThrowImageError(decoded, "cannot read query " + decoded.error.substr(12));
    const cv::Mat& image = decoded.image;
    const QueryResult r = db.Query(image, options);
    if (const RankedKeyframe* best = r.best()) {
      fmt::print("best keyframe {} ({})  {}\n", best->keyframe_id, Describe(*best),
                 EscapeForTerminal(best->source));
      fmt::print("pose          {}\n", FormatPose(best->pose));
    } else if (r.ranked.empty()) {
      fmt::print("no match: no keyframe has {} or more matches ({} query features)\n",
                 options.min_matches, r.num_query_features);
    } else {
      fmt::print("no match (new place?): the best keyframe, {}, scores {:g} < --min-score {:g}\n",
                 r.ranked[0].keyframe_id, r.ranked[0].score, options.min_score);
    }
    if (!r.ranked.empty()) {
      // With the whole-image channel: each keyframe's standardised similarity
      // and the score it makes with the local evidence.
      const bool whole = r.ranked.front().whole_image_z.has_value();
      fmt::print("rank  keyframe  matches  inliers{}\n", whole ? "  whole z    score" : "");
      for (size_t i = 0; i < r.ranked.size(); ++i) {
        const RankedKeyframe& k = r.ranked[i];
        fmt::print("{:>4}  {:>8}  {:>7}  {:>7}", i + 1, k.keyframe_id, k.num_matches,
                   k.verified() ? std::to_string(k.num_inliers) : "-");
        if (whole && k.whole_image_z) fmt::print("  {:>7.2f}  {:>7.1f}", *k.whole_image_z, k.score);
        fmt::print("\n");
      }
    }
    fmt::print(
        "time          {:.2f} ms ({:.2f} extract + {:.2f} match + {:.2f} verify), {} query "
        "features, {} keyframes examined\n",
        r.times.total_ms, r.times.extract_ms, r.times.match_ms, r.times.verify_ms,
        r.num_query_features, r.num_examined);
    fmt::print("search        {}{}, {:.1f}% of {} keyframes examined{}\n", r.search,
               r.cluster >= 0 ? fmt::format(" (cluster {})", r.cluster) : "", 100.0 * r.coverage,
               r.num_keyframes, r.deadline_reached ? ", stopped by the deadline" : "");
    if (!draw_.empty()) Draw(db, image, r, options);
    nlohmann::json j = nlohmann::json::parse(QueryResultToJson(r));
    j["query"] = image_;
    j["database"] = db_.dir;
    WriteJson(json_, DumpJson(j, 2));
    return 0;
  }

 private:
  void Draw(const PlaceDatabase& db, const cv::Mat& image, const QueryResult& r,
            const QueryOptions& options) const {
    if (r.ranked.empty()) {
      fmt::print("draw          nothing to draw: no keyframe was ranked\n");
      return;
    }
    const RankedKeyframe& k = r.ranked.front();
    const std::string caption =
        fmt::format("{} -> keyframe {} ({}{})", fs::path(image_).filename().string(),
                    k.keyframe_id, Describe(k), r.matched ? "" : ", below --min-score");
    const cv::Mat picture =
        DrawQueryMatch(db, image, db.Extract(image), k.keyframe_id, options, caption);
    // Encoded here and written as every output is: a regular file replaced
    // whole, a symlink, device or FIFO streamed, never replaced.
    std::vector<uint8_t> png;
    // PNG encoding of a picture we drew cannot fail but by a bug.
    if (!cv::imencode(".png", picture, png))
      PLACEDB_THROW_INTERNAL("cannot encode the picture ", draw_);
    WriteFileAtomic(draw_, std::string(reinterpret_cast<const char*>(png.data()), png.size()));
    fmt::print("draw          {}\n", draw_);
  }

  static std::string Describe(const RankedKeyframe& k) {
    if (k.verified()) return fmt::format("{} inliers of {} matches", k.num_inliers, k.num_matches);
    return fmt::format("{} matches", k.num_matches);
  }

  DatabaseArgs db_;
  QueryArgs query_;
  ImageReadOptions image_read_;
  std::string image_, json_, draw_;
};

}  // namespace

std::unique_ptr<Command> MakeQueryCommand() { return std::make_unique<QueryCommand>(); }

}  // namespace cli
}  // namespace placedb
