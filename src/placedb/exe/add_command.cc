// placedb add: add frames to an existing database as keyframes (online
// mapping from the command line), processed as the database was built, then
// saved in place crash-safely. The library numbers and filters the frames
// (PlaceDatabase::AddFrames, AddOptions).
#include <fmt/format.h>

#include "placedb/cli/flags.h"
#include "placedb/cli/options.h"
#include "placedb/exe/command.h"
#include "placedb/util/file_io.h"

namespace placedb {
namespace cli {
namespace {

class AddCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand(
        "add", "add frames to a database as keyframes, with its build settings, and save it");
    db_.AddDirectoryOnly(cmd);
    source_.Add(cmd);
    AddOptionFlags(cmd, &options_);
    cmd->get_option("--id-offset")->excludes(cmd->get_option("--ids-from-names"));
    cmd->add_flag("--quiet", quiet_, "no progress bar");
    cmd->footer(
        "New frames get the ids after the largest the database ever held (placedb info shows "
        "the next free id); poses come with --tum and bags.\n"
        "Examples:\n"
        "  placedb add --db office_tum.db --tum data/tum_fr3_office_32 --first 17 --skip-existing\n"
        "  placedb add --db office.db --images data/rtabmap_loop/images --first 41 "
        "--ids-from-names   # 042.jpg: id 42\n");
    return cmd;
  }

  int Run() override {
    PlaceDatabase db = db_.Open();
    const AddReport r = db.AddFrames(source_.Read(), options_, !quiet_);
    if (db.num_pending_changes() > 0) db.Save();  // nothing added: the files stay as they are
    if (r.added == 0) {
      fmt::print("added         0 keyframes\n");
    } else if (r.added == 1) {
      fmt::print("added         1 keyframe, id {}\n", r.first_id);
    } else {
      fmt::print("added         {} keyframes, ids {}..{}\n", r.added, r.first_id, r.last_id);
    }
    if (options_.skip_existing) {
      fmt::print("skipped       {} already in the database (same source and content{})\n",
                 r.skipped,
                 r.skipped_by_path > 0
                     ? fmt::format("; {} by path alone: keyframes saved without a content hash",
                                   r.skipped_by_path)
                     : "");
      if (r.repeated > 0)
        fmt::print("              {} given twice (added once)\n", r.repeated);
    }
    if (!r.changed_sources.empty()) {
      fmt::print("new content   {} with the path of a keyframe but other content, added as new "
                 "keyframes (the old ones stay): {}{}\n",
                 r.changed_sources.size(), EscapeForTerminal(r.changed_sources.front()),
                 r.changed_sources.size() > 1 ? ", ..." : "");
    }
    const KeyframeIdSummary ids = db.id_summary();
    fmt::print("database      {} now has {} keyframes, ids {}..{}, next free id {}\n",
               EscapeForTerminal(db_.dir), ids.count, ids.first, ids.last, ids.next_free);
    return 0;
  }

 private:
  DatabaseArgs db_;
  SourceArgs source_;
  AddOptions options_;
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeAddCommand() { return std::make_unique<AddCommand>(); }

}  // namespace cli
}  // namespace placedb
