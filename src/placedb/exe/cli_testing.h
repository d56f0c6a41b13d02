// Helpers for the tests that run the placedb binary as a user would: a
// command line run through bash, its exit code and what it printed.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace placedb {
namespace testing_util {

struct CommandResult {
  int code = -1;
  std::string output;  // what the command line wrote to stdout
};

// Runs `command` with bash (process substitution, pipes, redirections work)
// and returns its exit code and stdout.
inline CommandResult RunShell(const std::string& command) {
  CommandResult run;
  std::string quoted = "'";
  for (char c : command) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  quoted += "'";
  FILE* pipe = popen(("bash -c " + quoted).c_str(), "r");
  if (pipe == nullptr) return run;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof(buf), pipe)) > 0) run.output.append(buf, n);
  const int status = pclose(pipe);
  run.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

// `binary args`: its exit code and stdout and stderr together.
inline CommandResult RunBinary(const std::string& binary, const std::string& args) {
  return RunShell(binary + " " + args + " 2>&1");
}

// `binary args`: its exit code and stderr alone (stdout dropped).
inline CommandResult RunBinaryStderr(const std::string& binary, const std::string& args) {
  return RunShell(binary + " " + args + " 2>&1 >/dev/null");
}

inline bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

}  // namespace testing_util
}  // namespace placedb
