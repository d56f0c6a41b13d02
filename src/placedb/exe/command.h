// The sub-commands of the placedb binary, one file each: they parse flags
// (the flag groups of cli/flags.h), call the library and print.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>

namespace placedb {
namespace cli {

class Command {
 public:
  virtual ~Command() = default;
  // Adds the sub-command and its flags to `app`.
  virtual CLI::App* Register(CLI::App& app) = 0;
  // Runs it after parsing; returns the exit code, throws on errors.
  virtual int Run() = 0;
};

std::unique_ptr<Command> MakeBuildCommand();
std::unique_ptr<Command> MakeQueryCommand();
std::unique_ptr<Command> MakeEvalCommand();
std::unique_ptr<Command> MakeExperimentCommand();
std::unique_ptr<Command> MakeInfoCommand();
std::unique_ptr<Command> MakeBenchCommand();
std::unique_ptr<Command> MakeAddCommand();
std::unique_ptr<Command> MakeRemoveCommand();
std::unique_ptr<Command> MakeOptionsCommand();
std::unique_ptr<Command> MakeVerifyCommand();

}  // namespace cli
}  // namespace placedb
