// Sub-commands of the placedb binary (build, query, eval, info, bench).
#pragma once

#include <CLI/CLI.hpp>

namespace placedb {

// Adds every sub-command and its flags to `app`.
void RegisterCommands(CLI::App& app);

// Runs the parsed sub-command; returns the process exit code. Throws on
// errors (main prints them).
int RunSelectedCommand(CLI::App& app);

}  // namespace placedb
