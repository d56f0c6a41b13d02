// The command-line layer the placedb binary and the ROS nodes share: flag
// groups made from the library's option tables (cli/options.h), so --help,
// the checks and the code cannot drift apart, and output helpers. Commands
// are thin: they parse flags, call the library (placedb/placedb.h), print.
#pragma once

#include <CLI/CLI.hpp>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "placedb/placedb.h"

namespace placedb {
namespace cli {

// The help screens' format, set on the app before its sub-commands are
// added (they inherit it): a negatable flag reads "--verify,--no-verify"
// (CLI11 would print "--verify,--no-verify{false}"), its default said in
// its help.
std::shared_ptr<CLI::Formatter> HelpFormatter();

// Where frames come from: FrameSourceOptions' flags (--images or --tum,
// --first, --last, --frame-size, --max-image-pixels and the TUM options),
// or a ROS bag (--bag FILE --topic T, poses from --bag-groundtruth or
// --bag-tf), read by the bag library in a build with ROS.
struct SourceArgs {
  FrameSourceOptions source;
  std::string bag, topic, bag_groundtruth, bag_tf;

  void Add(CLI::App* cmd);
  std::vector<Frame> Read() const;
  // "images:DIR [41..84]", "tum:DIR [5..]", "bag:FILE:TOPIC".
  std::string Describe() const;
};

// Every query option (retrieve, match, verify, decide) as flags, but those
// named in `skip` (a voter, which only merges, runs no query: no deadline
// of a query, no prior).
struct QueryArgs {
  QueryOptions options;

  void Add(CLI::App* cmd, const std::vector<std::string>& skip = {});
  // The options, checked.
  QueryOptions Get() const;
};

// --db DIR and the open options: the subset (--partition I/N with
// --partition-scheme, or --keyframes ID,ID,...), --features (the type the
// caller expects), --threads (unless `threads` is false) and the clusters.
struct DatabaseArgs {
  std::string dir;
  OpenOptions open;

  void Add(CLI::App* cmd, bool threads = true);
  // --db DIR alone: for commands that open the whole database to change or
  // describe it (add, remove, info), where a subset, clusters or threads
  // would do nothing.
  void AddDirectoryOnly(CLI::App* cmd);
  PlaceDatabase Open() const;
};

// Keeps stdout for JSON alone, so that `--json - | python3 -m json.tool`
// works: when `json_path` is "-" or names the file stdout is (`/dev/stdout`,
// `/dev/fd/1`, the pipe or file stdout was redirected to), everything else
// the command prints to stdout is sent to stderr from now on, and WriteJson
// writes to the original stdout. Returns whether it did. Called once, after
// the flags are parsed and before the command prints anything.
bool ReserveStdoutForJson(const std::string& json_path);
// Writes JSON text to `path` ("-": stdout; "": nothing), as every output is
// written (util/file_io.h: a regular file replaced whole, a special file
// streamed).
void WriteJson(const std::string& path, const std::string& json);
// "t = (x, y, z) m, q = (x, y, z, w)" or "(no pose)".
std::string FormatPose(const std::optional<Pose>& pose);

}  // namespace cli
}  // namespace placedb
