// The `placedb` command: one sub-command table. Flags bind straight onto the
// library's options structs, so --help and the code cannot drift apart. Any
// error, of the arguments or of the work, is one line on stderr and an exit
// code of its kind (cli/errors.h: 1 input, 74 I/O, 70 a bug).
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <memory>
#include <opencv2/core/utils/logger.hpp>
#include <vector>

#include "placedb/cli/errors.h"
#include "placedb/cli/flags.h"
#include "placedb/exe/command.h"
#include "placedb/util/file_io.h"
#include "placedb/util/version.h"

int main(int argc, char** argv) {
  auto logger = spdlog::stderr_color_mt("placedb");
  logger->set_pattern("%^[%l]%$ %v");
  spdlog::set_default_logger(logger);
  // placedb reports unreadable images itself, in one line; OpenCV's own
  // warnings would only repeat them.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);

  namespace cli = placedb::cli;
  CLI::App app{"placedb: visual place recognition against a compact keyframe database"};
  app.formatter(cli::HelpFormatter());
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("placedb ") + placedb::kPlacedbVersion);
  bool verbose = false;
  app.add_flag("--verbose", verbose,
               "debug logging; an error line also names where in placedb it was raised");
  // Global flags (--verbose) are taken after the sub-command too: the
  // sub-commands, registered below, inherit this.
  app.fallthrough();
  std::vector<std::unique_ptr<cli::Command>> commands;
  commands.push_back(cli::MakeBuildCommand());
  commands.push_back(cli::MakeQueryCommand());
  commands.push_back(cli::MakeEvalCommand());
  commands.push_back(cli::MakeExperimentCommand());
  commands.push_back(cli::MakeInfoCommand());
  commands.push_back(cli::MakeBenchCommand());
  commands.push_back(cli::MakeAddCommand());
  commands.push_back(cli::MakeRemoveCommand());
  commands.push_back(cli::MakeOptionsCommand());
  commands.push_back(cli::MakeVerifyCommand());
  std::vector<std::pair<CLI::App*, cli::Command*>> table;
  for (auto& c : commands) table.emplace_back(c->Register(app), c.get());
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "placedb: error: %s (see placedb --help)\n",
                 placedb::EscapeForTerminal(e.what()).c_str());
    return cli::kExitInput;
  } catch (...) {
    // A flag's value the option table refused (InvalidArgument naming it).
    return cli::ReportCurrentException("placedb", verbose);
  }
  if (verbose) spdlog::set_level(spdlog::level::debug);
  try {
    for (const auto& [sub, command] : table) {
      if (!sub->parsed()) continue;
      // `--json -` (or a path that is stdout): stdout carries the JSON alone.
      const CLI::Option* json = sub->get_option_no_throw("--json");
      if (json != nullptr && json->count() == 1 && json->get_expected_min() > 0)
        cli::ReserveStdoutForJson(json->results().front());
      return command->Run();
    }
    std::fprintf(stderr, "placedb: error: no sub-command given (see placedb --help)\n");
    return cli::kExitInput;
  } catch (...) {
    // Messages name paths and values from files: escaped, one line.
    return cli::ReportCurrentException("placedb", verbose);
  }
}
