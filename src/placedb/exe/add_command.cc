// placedb add: add frames to an existing database as keyframes (online
// mapping from the command line), processed as the database was built, then
// saved in place crash-safely.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "placedb/cli/flags.h"
#include "placedb/exe/command.h"
#include "placedb/util/check.h"
#include "placedb/util/progress.h"

namespace placedb {
namespace cli {
namespace {

class AddCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand(
        "add", "add frames to a database as keyframes, with its build settings, and save it");
    db_.Add(cmd, /*threads=*/false);
    source_.Add(cmd);
    cmd->add_flag("--skip-existing", skip_existing_,
                  "skip frames whose id is already a keyframe (default: an error)");
    cmd->add_flag("--quiet", quiet_, "no progress bar");
    return cmd;
  }

  int Run() override {
    PlaceDatabase db = db_.Open();
    const std::vector<Frame> frames = source_.Read();
    if (frames.empty()) PLACEDB_THROW_INVALID("no frames to add");
    // Every frame is checked before any is added: an error leaves the
    // database as it was.
    std::vector<const Frame*> todo;
    for (const Frame& f : frames) {
      if (!db.FindKeyframe(f.id)) {
        todo.push_back(&f);
      } else if (!skip_existing_) {
        PLACEDB_THROW_INVALID("frame ", f.id, " (", f.image_path, ") is already a keyframe of ",
                              db_.dir, " (`skip_existing` to leave such frames out)");
      }
    }
    std::vector<cv::Mat> images(todo.size());
    for (size_t i = 0; i < todo.size(); ++i) {
      images[i] = LoadFrameImage(*todo[i]);
      if (images[i].empty()) ThrowUnreadableFrame(*todo[i]);
    }
    ProgressBar progress("adding", todo.size(), !quiet_);
    for (size_t i = 0; i < todo.size(); ++i) {
      db.Add(*todo[i], images[i]);
      images[i].release();
      progress.Advance();
    }
    progress.Finish();
    db.Save();
    fmt::print("added         {} keyframes ({} already there)\n", todo.size(),
               frames.size() - todo.size());
    fmt::print("database      {} now has {} keyframes\n", db_.dir, db.size());
    return 0;
  }

 private:
  DatabaseArgs db_;
  SourceArgs source_;
  bool skip_existing_ = false;
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeAddCommand() { return std::make_unique<AddCommand>(); }

}  // namespace cli
}  // namespace placedb
