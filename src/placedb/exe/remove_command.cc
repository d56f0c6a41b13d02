// placedb remove: take keyframes out of a database and save it in place
// crash-safely.
#include <fmt/format.h>

#include <algorithm>
#include <climits>
#include <string>
#include <vector>

#include "placedb/cli/flags.h"
#include "placedb/exe/command.h"
#include "placedb/util/check.h"
#include "placedb/util/file_io.h"

namespace placedb {
namespace cli {
namespace {

class RemoveCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand("remove", "remove keyframes from a database and save it");
    db_.AddDirectoryOnly(cmd);
    cmd->add_option("--ids", items_, "keyframe ids to remove, e.g. 3,4,17")
        ->required()
        ->delimiter(',');
    cmd->add_flag("--ignore-missing", ignore_missing_,
                  "ids that are not keyframes are not an error");
    cmd->footer(
        "Removed ids are not given to new frames again (placedb info: next free id, removed "
        "count).\n"
        "Examples:\n"
        "  placedb remove --db office.db --ids 3,4,17\n"
        "  placedb remove --db office.db --ids 17 --ignore-missing");
    return cmd;
  }

  int Run() override {
    // Each item a whole number in [1, 2^31) (CLI11 reads '' as 0): checked
    // before the database is opened.
    std::vector<int32_t> wanted;
    for (const std::string& item : items_) {
      const bool digits =
          !item.empty() && item.size() <= 10 &&
          std::all_of(item.begin(), item.end(), [](char c) { return c >= '0' && c <= '9'; });
      const long long id = digits ? std::stoll(item) : 0;
      if (!digits || id < 1 || id > INT32_MAX) {
        PLACEDB_THROW_INVALID(
            "--ids takes keyframe ids, whole numbers in [1, 2^31) separated by "
            "commas (got '",
            EscapeForTerminal(item), "' in '--ids ", EscapeForTerminal(Join(items_)), "')");
      }
      wanted.push_back(static_cast<int32_t>(id));
    }
    PlaceDatabase db = db_.Open();
    for (const int32_t id : wanted) {
      if (!db.FindKeyframe(id) && !ignore_missing_) {
        PLACEDB_THROW_INVALID("keyframe ", id, " is not in ", db_.dir,
                              " (`ignore_missing` to skip such ids)");
      }
    }
    size_t removed = 0;
    for (const int32_t id : wanted) removed += db.Remove(id);
    if (db.num_pending_changes() > 0) db.Save();
    fmt::print("removed       {} keyframes\n", removed);
    const KeyframeIdSummary ids = db.id_summary();
    fmt::print("database      {} now has {} keyframes, ids {}..{}, next free id {}\n",
               EscapeForTerminal(db_.dir), ids.count, ids.first, ids.last, ids.next_free);
    return 0;
  }

 private:
  DatabaseArgs db_;
  static std::string Join(const std::vector<std::string>& items) {
    std::string out;
    for (const std::string& item : items) out += (out.empty() ? "" : ",") + item;
    return out;
  }
  std::vector<std::string> items_;
  bool ignore_missing_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeRemoveCommand() { return std::make_unique<RemoveCommand>(); }

}  // namespace cli
}  // namespace placedb
