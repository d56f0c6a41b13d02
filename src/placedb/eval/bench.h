// `placedb bench`: how fast the match stage is against the paper's method,
// measured in one run on the same stored descriptors and the same queries:
//  - placedb's match stage on one thread, and on every core;
//  - the paper's OpenCV BFMatcher knnMatch loop with the same rules;
//  - placedb's whole query (match + verify) on one thread, for reference.
// Each is the best of `repeat` passes over the queries (the machine is
// shared: the minimum is the least disturbed). Both methods must rank the
// keyframes identically; the report counts the queries where they do not.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "placedb/dataset/frame.h"
#include "placedb/session/place_database.h"
#include "placedb/util/option_table.h"

namespace placedb {

struct BenchOptions {
  // Query frames, chosen with `seed`; 0 = all. Range [0, 1000000]. Default 20.
  int num_queries = 20;
  // Seed of the selection. Default 1.
  uint64_t seed = 1;
  // Passes over the queries per method; each method's best pass counts.
  // Range [1, 1000]. Default 3.
  int repeat = 3;
  // Threads for the multi-threaded pass; 0 = one per core. Range [0, 1024].
  // Default 0.
  int threads = 0;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<BenchOptions>& Table();
  std::string Check() const;
};

struct BenchReport {
  size_t num_keyframes = 0;
  size_t num_db_descriptors = 0;
  std::string feature_type;
  std::string kernel;  // the distance kernel used on this CPU
  int num_queries = 0;
  int repeat = 0;
  int threads = 0;                   // of the multi-threaded pass
  double extract_ms = 0.0;           // per query, mean
  double placedb_ms = 0.0;           // match stage, 1 thread, per query
  double placedb_mt_ms = 0.0;        // match stage, `threads` threads
  double bfmatcher_ms = 0.0;         // the paper's loop, 1 thread
  double placedb_verified_ms = 0.0;  // match + verify, 1 thread
  int rankings_that_differ = 0;
  double speedup() const { return placedb_ms > 0 ? bfmatcher_ms / placedb_ms : 0.0; }
  double speedup_mt() const { return placedb_mt_ms > 0 ? bfmatcher_ms / placedb_mt_ms : 0.0; }
};

// Runs the benchmark of `db` with queries from `frames`. Unreadable frames
// are skipped with a warning; none readable is InvalidArgument.
BenchReport RunBench(const PlaceDatabase& db, const std::vector<Frame>& frames,
                     const BenchOptions& options, const QueryOptions& query_options);

// The report as JSON text (`indent` -1: one line).
std::string BenchReportJson(const BenchReport& report, int indent = -1);
std::string FormatBenchReport(const BenchReport& report);

}  // namespace placedb
