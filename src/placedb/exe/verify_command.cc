// placedb verify: check every byte of a database now.
#include <fmt/format.h>

#include "placedb/cli/flags.h"
#include "placedb/exe/command.h"
#include "placedb/util/file_io.h"
#include "placedb/util/timer.h"

namespace placedb {
namespace cli {
namespace {

class VerifyCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand(
        "verify",
        "check every byte of a database now (opening checks the keyframe table and the index "
        "files; a keyframe's features are otherwise checked when a query first uses them)");
    db_.AddDirectoryOnly(cmd);
    cmd->footer(
        "Exit code 0 when the database is intact, 1 (with the first damage found) when not.\n"
        "\n"
        "Examples:\n"
        "  placedb verify --db office.db");
    return cmd;
  }

  int Run() override {
    const Timer timer;
    const PlaceDatabase db = db_.Open();
    const PlaceDatabase::VerifyReport report = db.Verify();
    fmt::print(
        "{}: intact: {} keyframes, keyframe file {} bytes (format version {}), checked in "
        "{:.0f} ms\n",
        EscapeForTerminal(db_.dir), report.keyframes, report.keyframes_bytes, report.format_version,
        timer.ElapsedMs());
    return 0;
  }

 private:
  DatabaseArgs db_;
};

}  // namespace

std::unique_ptr<Command> MakeVerifyCommand() { return std::make_unique<VerifyCommand>(); }

}  // namespace cli
}  // namespace placedb
