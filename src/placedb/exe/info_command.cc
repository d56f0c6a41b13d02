// placedb info: describe a database.
#include <fmt/format.h>

#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "placedb/cli/flags.h"
#include "placedb/exe/command.h"
#include "placedb/util/file_io.h"
#include "placedb/util/json_reader.h"

namespace placedb {
namespace cli {
namespace {
namespace fs = std::filesystem;

class InfoCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand("info", "describe a database");
    db_.AddDirectoryOnly(cmd);
    cmd->add_flag("--json", json_,
                  "print the manifest as JSON, its \"ids\" with count, first, last, next_free, "
                  "removed and removed_since");
    cmd->footer(
        "Examples:\n"
        "  placedb info --db office.db\n"
        "  placedb info --db office.db --json");
    return cmd;
  }

  int Run() override {
    // The whole database is opened: its keyframe table and index files are
    // checked (`placedb verify` checks the features too).
    const PlaceDatabase db = db_.Open();
    if (json_) {
      std::cout << db.info_json(2) << "\n";
      return 0;
    }
    const nlohmann::json m = nlohmann::json::parse(db.manifest_json());
    const std::vector<Keyframe> keyframes = db.keyframes();
    const BuildOptions& b = db.build_options();
    fmt::print("database        {}\n", EscapeForTerminal(db_.dir));
    // Descriptive fields the reader does not check: shown only when they are
    // strings (a damaged one must not end the command with a JSON error).
    auto text = [&](const char* key) {
      const auto it = m.find(key);
      return EscapeForTerminal(it != m.end() && it->is_string() ? it->get<std::string>() : "?");
    };
    fmt::print("format version  {}\n", m.value("format_version", 0));
    fmt::print("created         {} by placedb {}\n", text("created"), text("placedb_version"));
    fmt::print("source          {}\n", text("source"));
    fmt::print("features        {} ({} bytes per descriptor)\n", FeatureTypeName(db.feature_type()),
               db.descriptor_bytes());
    if (db.whole_image_dims() > 0) {
      const WholeImageOptions& w = b.features.whole_image;
      if (w.kind == WholeImageKind::kHog) {
        fmt::print("whole image     HOG of {} x {} thumbnails, PCA-whitened ({} values per keyframe)\n",
                   w.hog_width, w.hog_height, db.whole_image_dims());
      } else {
        fmt::print("whole image     {} x {} thumbnails, {}-px tiles ({} values per keyframe)\n",
                   w.width, w.height, w.patch, db.whole_image_dims());
      }
    } else {
      fmt::print("whole image     none\n");
    }
    fmt::print("crop            {}\n", CropModeName(b.crop));
    fmt::print("resize          1/{} of the area\n", b.resize);
    fmt::print("upscale below   {} px (small frames are upscaled for extraction; 0: never)\n",
               b.features.upscale_below);
    size_t cropped = 0, with_pose = 0;
    for (const Keyframe& k : keyframes) {
      cropped += k.crop_channel >= 0;
      with_pose += k.pose.has_value();
    }
    fmt::print("keyframes       {} ({} cropped)\n", db.size(), cropped);
    fmt::print("features        {} ({:.1f} per keyframe)\n", db.num_features(),
               db.empty() ? 0.0 : static_cast<double>(db.num_features()) / db.size());
    fmt::print("stored images   {} bytes\n",
               DirectorySize((fs::path(db_.dir) / "images").string()));
    fmt::print("keyframe file   {} bytes ({})\n", db.keyframes_bytes(), db.generation());
    if (m.contains("bytes") && m["bytes"].is_object()) {
      const nlohmann::json& full = m["bytes"].value("full_frames_png", nlohmann::json());
      if (full.is_number_unsigned())
        fmt::print("whole frames    {} bytes as PNG\n", full.get<uint64_t>());
    }
    fmt::print("poses           {} of {} keyframes\n", with_pose, db.size());
    const KeyframeIdSummary ids = db.id_summary();
    fmt::print("keyframe ids    {}..{}, next free id {}\n", ids.first, ids.last, ids.next_free);
    if (ids.removed) {
      fmt::print("removed         {} keyframes since {}\n", *ids.removed,
                 EscapeForTerminal(ids.removed_since));
    } else {
      fmt::print("removed         not recorded (written by an earlier placedb; counted from its "
                 "next save)\n");
    }
    return 0;
  }

 private:
  DatabaseArgs db_;
  bool json_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeInfoCommand() { return std::make_unique<InfoCommand>(); }

}  // namespace cli
}  // namespace placedb
