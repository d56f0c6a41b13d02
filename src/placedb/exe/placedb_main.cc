// The `placedb` command: one sub-command table. Flags bind straight onto the
// library's options structs, so --help and the code cannot drift apart.
#include <fmt/format.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <opencv2/core/utils/logger.hpp>

#include "placedb/exe/commands.h"

int main(int argc, char** argv) {
  auto logger = spdlog::stderr_color_mt("placedb");
  logger->set_pattern("%^[%l]%$ %v");
  spdlog::set_default_logger(logger);
  // placedb reports unreadable images itself, in one line; OpenCV's own
  // warnings would only repeat them.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);

  CLI::App app{"placedb: visual place recognition against a compact keyframe database"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "placedb 0.1.0");
  placedb::RegisterCommands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    return placedb::RunSelectedCommand(app);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "placedb: error: %s\n", e.what());
    return 1;
  }
}
