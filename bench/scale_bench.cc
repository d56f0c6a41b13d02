// How placedb scales with the database's size (issue #9, item 5): databases
// of 1k, 10k and 100k keyframes made from the sample images by augmentation
// (eval/augment.h), and for each size, in one run:
//  - build time, database bytes (every file of the directory), open time
//    (PlaceDatabase::Open) with a cold page cache (every file of the
//    database dropped from it with posix_fadvise(POSIX_FADV_DONTNEED), which
//    needs no privilege) and warm (the best of 3 more), and the resident
//    memory the open adds, two ways: private (RssAnon: the heap) and
//    file-backed (RssFile: pages of the mapped files read so far);
//  - the same memory after the runs below, and at the largest size after
//    --memory-queries more bag-of-words queries (fresh augmentations, spread
//    over the database), and the time `placedb verify` takes (every byte);
//  - per search mode (exhaustive, bow, cluster) the query latency p50 / p99
//    on one thread, excluding feature extraction (the query's features are
//    extracted once with Extract, then Query(features) is timed; OpenCV on
//    one thread too), the mean stage times, recall@1, and the major page
//    faults of the queries (pages read from the disk; getrusage of the
//    query's thread around each query, outside its timer) with the p99 of
//    the queries that had none;
//  - for bow, the overshoot of a deadline_ms run (p99 of max(0, elapsed -
//    deadline));
//  - the machine's popcount limit: the fastest rate of TwoNearestHamming on
//    an in-cache block (ns per 32-byte distance) times query features x
//    database features, against which the exhaustive latency is printed.
//
// Keyframe k of a database of n is an augmentation of sample image
// (k - 1) % S (S sample images, ids 1..n; eval/augment.h: crop 0.5-0.9 of
// the side, rotation +-10 deg, perspective 5%, blur, brightness, contrast,
// gamma, noise; 320 x 240). Query q is a second, milder augmentation of the
// image of keyframe k_q (spread evenly over 1..n); the correct answer is
// keyframe k_q alone, not its siblings (the other views of the same sample
// image). Those siblings overlap k_q a lot, so the "place" recall@1 (the
// answer is a view of the same sample image) is given too. Cluster
// search gets as prior the keyframe of the same sample image with the
// adjacent augmentation index (k + S, or k - S at the end): where a robot
// that just recognised a nearby view would be. Clusters are made with a
// radius of 0.5 m, so that each sample image's views (at x = s metres, a few
// cm apart) form one cluster, whose neighbours are the adjacent images'.
//
// Frames are built with ORB's FAST threshold 5 (--fast-threshold): with
// the library's 20, these 320 x 240 views (corridors with bare walls, blur)
// hold about 210 features on average; with 5 about 390, nearer the 500
// (--features) that the targets assume.
//
// Exhaustive search at the larger sizes takes seconds per query: above 1000
// keyframes it runs on --exhaustive-queries of the queries (spread evenly),
// and every mode's recall is also given on that subset.
//
// At each of --compare-stored-at keyframes the bench also builds databases
// that keep fewer features per keyframe (--compare-stored: BuildOptions::
// stored_features, those matched in the --track-neighbours nearest
// keyframes first, spread over the image; queries keep all) and runs bow,
// with and without the whole-image channel, on them with the same queries,
// and at the largest size the default options' memory run (the same
// --memory-queries queries as the whole map's): what disk and memory they
// save against the recall they lose.
//
// Databases are written under --out (scale_<n>/, scale_<n>_stored<b>/) and
// reused when their manifest shows the same settings, source description
// and counts.
// Prints a table and writes JSON (--json) for the README's table.
#include <fcntl.h>
#include <fmt/format.h>
#include <malloc.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>
#include <random>
#include <sstream>
#include <thread>

#include "placedb/builder/builder.h"
#include "placedb/distributed/partition_worker.h"
#include "placedb/eval/augment.h"
#include "placedb/eval/metrics.h"
#include "placedb/match/hamming.h"
#include "placedb/query/query.h"
#include "placedb/session/place_database.h"
#include "placedb/util/check.h"
#include "placedb/util/timer.h"

namespace fs = std::filesystem;
using placedb::LatencyStats;

namespace {

constexpr uint64_t kKeyframeSeed = 1;
constexpr uint64_t kQuerySeed = 2;
volatile uint64_t g_sink = 0;  // keeps the timed distances from being optimised away

nlohmann::json StatsJson(const LatencyStats& s) {
  return {{"mean", s.mean}, {"p50", s.p50}, {"p99", s.p99}, {"max", s.max}};
}

// A field of /proc/self/status ("VmRSS"), in MiB.
double StatusMib(const std::string& field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(field + ":", 0) == 0) return std::stod(line.substr(field.size() + 1)) / 1024.0;
  }
  return 0.0;
}

// Resident memory of this process, MiB: private (the heap, RssAnon) and
// file-backed (mapped file pages, RssFile).
struct Resident {
  double anon = 0.0, file = 0.0;
};
Resident ResidentNow() { return {StatusMib("RssAnon"), StatusMib("RssFile")}; }
nlohmann::json ResidentJson(const Resident& r) {
  return {{"private_mib", r.anon}, {"file_mib", r.file}};
}

// Resident MiB of each mapped file under `dir` (/proc/self/smaps; a file
// mapped twice counts twice), by file name.
std::map<std::string, double> MappedResidentMib(const fs::path& dir) {
  std::map<std::string, double> out;
  std::ifstream in("/proc/self/smaps");
  std::string line, current;
  const std::string prefix = fs::absolute(dir).lexically_normal().string() + "/";
  while (std::getline(in, line)) {
    const size_t slash = line.find('/');
    if (!line.empty() && std::isxdigit(static_cast<unsigned char>(line[0])) &&
        line.find('-') != std::string::npos) {
      current = slash != std::string::npos && line.compare(slash, prefix.size(), prefix) == 0
                    ? line.substr(slash + prefix.size())
                    : "";
    } else if (!current.empty() && line.rfind("Rss:", 0) == 0) {
      out[current] += std::stod(line.substr(4)) / 1024.0;
    }
  }
  return out;
}

// Drops every file of `dir` from the page cache (written back first), so
// that the next open reads them from the disk. False when the kernel
// refused for some file.
bool DropFromPageCache(const fs::path& dir) {
  bool ok = true;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file()) continue;
    const int fd = ::open(e.path().c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
      ok = false;
      continue;
    }
    ok = ::fdatasync(fd) == 0 && ok;
    ok = ::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED) == 0 && ok;
    ::close(fd);
  }
  return ok;
}

uint64_t DirectoryBytes(const fs::path& dir) {
  uint64_t bytes = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (e.is_regular_file()) bytes += e.file_size();
  }
  return bytes;
}

// Every sample image under `data`: the files of each folder's images/ and
// rgb/ and the folder itself (jpg, png), sorted. (samples_GT.bmp is a
// ground-truth matrix, not a view.)
std::vector<std::string> SampleImages(const fs::path& data) {
  std::vector<std::string> images;
  const auto add_folder = [&](const fs::path& folder) {
    if (!fs::is_directory(folder)) return;
    for (const auto& e : fs::directory_iterator(folder)) {
      const std::string ext = e.path().extension().string();
      if (e.is_regular_file() && (ext == ".jpg" || ext == ".jpeg" || ext == ".png"))
        images.push_back(e.path().string());
    }
  };
  for (const auto& e : fs::directory_iterator(data)) {
    if (!e.is_directory()) continue;
    add_folder(e.path());
    add_folder(e.path() / "images");
    add_folder(e.path() / "rgb");
  }
  std::sort(images.begin(), images.end());
  return images;
}

// The milder augmentation that makes a query from a keyframe's image.
placedb::AugmentOptions QueryAugmentOptions() {
  placedb::AugmentOptions o;
  o.min_crop = 0.8;
  o.max_crop = 1.0;
  o.max_rotation_deg = 5.0;
  o.max_perspective = 0.03;
  o.max_blur_sigma = 1.0;
  o.max_brightness = 10.0;
  o.max_contrast = 0.1;
  o.max_gamma = 0.1;
  o.max_noise_sigma = 3.0;
  o.seed = kQuerySeed;
  return o;
}

// The fastest rate of the active Hamming kernel on a block that stays in
// cache: ns per 32-byte distance, the best of many passes.
double NsPerDistance() {
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> byte(0, 255);
  double best = 1e9;
  uint64_t sink = 0;
  for (const int rows : {256, 1024, 4096}) {
    std::vector<uint8_t> block(static_cast<size_t>(rows) * 32), queries(64 * 32);
    for (uint8_t& b : block) b = static_cast<uint8_t>(byte(rng));
    for (uint8_t& b : queries) b = static_cast<uint8_t>(byte(rng));
    for (int pass = 0; pass < 200; ++pass) {  // the first ones warm the core up
      placedb::Timer t;
      for (int q = 0; q < 64; ++q) {
        sink += placedb::TwoNearestHamming(&queries[q * 32], block.data(), rows, 32).best;
      }
      best = std::min(best, t.ElapsedSeconds() * 1e9 / (64.0 * rows));
    }
  }
  g_sink = sink;
  return best;
}

struct Query {
  int truth = 0;  // the keyframe the query was made from
  int place = 0;  // its sample image (views of it are the same place)
  int prior = 0;  // a keyframe of the same sample image, the adjacent augmentation
  placedb::FeatureSet features;
};

// Major page faults of the calling thread so far: pages a query had to
// read from the disk (the page cache had not got them, or had dropped them).
long MajorFaults() {
  rusage usage{};
  ::getrusage(RUSAGE_THREAD, &usage);
  return usage.ru_majflt;
}

// Latency with the pages read from disk counted: the major faults of each
// query (taken outside its timer), how many queries had any, and the p99 of
// those that had none.
struct FaultCount {
  long faults = 0;
  int queries_with = 0;
  std::vector<double> ms_without;
  void Add(long query_faults, double ms) {
    faults += query_faults;
    if (query_faults > 0) {
      ++queries_with;
    } else {
      ms_without.push_back(ms);
    }
  }
  nlohmann::json Json() const {
    nlohmann::json j = {{"major_faults", faults}, {"queries_with_major_faults", queries_with}};
    if (!ms_without.empty()) j["p99_ms_without"] = placedb::ComputeLatencyStats(ms_without).p99;
    return j;
  }
  std::string Text() const {
    return fmt::format("{} major faults in {} queries (p99 of the others {:.2f} ms)", faults,
                       queries_with,
                       ms_without.empty() ? 0.0 : placedb::ComputeLatencyStats(ms_without).p99);
  }
};

// One search mode over some of the queries.
struct ModeRun {
  std::string mode;
  double deadline_ms = 0.0;
  int guided_candidates = 0;        // bow and cluster: matched in full after guided ranking; 0: all
  double whole_image_weight = 0.0;  // the whole-image channel's (0: off)
  int whole_image_candidates = 0;
  std::vector<size_t> queries;  // indices into the query list
  std::vector<double> ms;       // per run query
  std::vector<double> overshoot_ms;
  std::map<size_t, bool> correct;        // query index -> ranked[0] is the truth
  std::map<size_t, bool> correct_place;  // ranked[0] is a view of the same sample image
  double coverage = 0.0;                 // sums
  double examined = 0.0;
  placedb::StageTimes stages;
  int matched = 0, deadline_reached = 0;
  std::map<std::string, int> searches;
  FaultCount faults;

  // The share of the queries `among` (those this mode ran) answered right.
  static double Recall(const std::map<size_t, bool>& correct, const std::vector<size_t>& among) {
    int n = 0, right = 0;
    for (const size_t q : among) {
      const auto c = correct.find(q);
      if (c == correct.end()) continue;
      ++n;
      right += c->second;
    }
    return n > 0 ? static_cast<double>(right) / n : 0.0;
  }
};

ModeRun RunMode(const placedb::PlaceDatabase& db, const std::vector<Query>& queries,
                const std::vector<size_t>& which, const std::string& mode, double deadline_ms,
                size_t num_places, int bow_candidates, int guided_candidates,
                double whole_image_weight = 0.0, int whole_image_candidates = 0) {
  placedb::QueryOptions options;
  options.whole_image_weight = whole_image_weight;
  options.whole_image_candidates = whole_image_candidates;
  options.retrieval.bow_candidates = bow_candidates;
  options.retrieval.guided_candidates = guided_candidates;
  options.retrieval.method = placedb::ParseRetrievalMethod(mode);
  options.deadline_ms = deadline_ms;
  ModeRun run;
  run.mode = mode;
  run.deadline_ms = deadline_ms;
  run.guided_candidates = mode == "exhaustive" ? 0 : guided_candidates;
  run.whole_image_weight = whole_image_weight;
  run.whole_image_candidates = whole_image_candidates;
  run.queries = which;
  const auto query = [&](const Query& q) {
    placedb::QueryOptions o = options;
    if (o.retrieval.method == placedb::RetrievalMethod::kCluster) o.prior.keyframe_id = q.prior;
    const long faults_before = MajorFaults();
    placedb::Timer t;
    placedb::QueryResult r = db.Query(q.features, o);
    const double ms = t.ElapsedMs();
    run.faults.Add(MajorFaults() - faults_before, ms);
    return std::make_pair(ms, std::move(r));
  };
  query(queries[which.front()]);  // warm-up, not counted
  run.faults = FaultCount();
  for (const size_t i : which) {
    const auto [ms, r] = query(queries[i]);
    run.ms.push_back(ms);
    if (deadline_ms > 0) run.overshoot_ms.push_back(std::max(0.0, ms - deadline_ms));
    const int best = r.ranked.empty() ? 0 : r.ranked.front().keyframe_id;
    run.correct[i] = best == queries[i].truth;
    run.correct_place[i] =
        best > 0 && (best - 1) % num_places == static_cast<size_t>(queries[i].place);
    run.examined += r.num_examined;
    run.stages.retrieve_ms += r.times.retrieve_ms;
    run.stages.match_ms += r.times.match_ms;
    run.stages.verify_ms += r.times.verify_ms;
    run.coverage += r.coverage;
    run.matched += r.matched;
    run.deadline_reached += r.deadline_reached;
    ++run.searches[r.search];
  }
  return run;
}

std::string ReadLine(FILE* in) {
  std::string line;
  for (int c = std::fgetc(in); c != EOF && c != '\n'; c = std::fgetc(in))
    line.push_back(static_cast<char>(c));
  return line;
}

// What `fn` returns, computed in a forked child process (its JSON through a
// pipe); the child's error ends the run.
nlohmann::json InChildProcess(const std::function<nlohmann::json()>& fn) {
  std::fflush(stdout);
  int up[2];
  if (::pipe(up) != 0) PLACEDB_THROW_INVALID("pipe failed");
  const pid_t pid = ::fork();
  if (pid < 0) PLACEDB_THROW_INVALID("fork failed");
  if (pid == 0) {
    ::close(up[0]);
    try {
      const std::string text = fn().dump() + "\n";
      FILE* out = ::fdopen(up[1], "w");
      std::fputs(text.c_str(), out);
      std::fclose(out);
      std::fflush(stdout);
      std::_Exit(0);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "scale_bench: child process: %s\n", e.what());
      std::_Exit(1);
    }
  }
  ::close(up[1]);
  FILE* in = ::fdopen(up[0], "r");
  const std::string line = ReadLine(in);
  std::fclose(in);
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (line.empty() || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    PLACEDB_THROW_INVALID("a child process failed (see its error above)");
  return nlohmann::json::parse(line);
}

// ---- The map split over partitions: worker processes and a voter --------------
// Each worker is a process of its own (forked, so that it has the queries'
// features; it opens the database itself, after the fork) that answers for
// partition `part` of `num_parts` (contiguous) as a ROS worker node does, with
// the same library class (BowPartitionWorker) and the same two rounds; its
// requests and answers are lines of text over pipes, the answers JSON.
//   "S q"          its shortlist for query q (round 1)
//   "A q i:id,..." its answer over its share of query q's candidates (round 2;
//                  every worker is sent every candidate, as on ROS)
//   "M"            {"open_ms", "private_mib", "file_mib"}: its open time and
//                  the resident memory its session added
struct Worker {
  pid_t pid = -1;
  FILE* to = nullptr;
  FILE* from = nullptr;
};

[[noreturn]] void PartitionWorker(FILE* in, FILE* out, const fs::path& dir,
                                  const placedb::OpenOptions& open_options, int part, int num_parts,
                                  const std::vector<Query>& queries,
                                  const placedb::QueryOptions& options) {
  try {
    const Resident base = ResidentNow();
    placedb::Timer open_timer;
    const placedb::PlaceDatabase db = placedb::PlaceDatabase::Open(dir.string(), open_options);
    const double open_ms = open_timer.ElapsedMs();
    placedb::BowPartitionWorker worker(db, placedb::KeyframeSubset::Partition(part, num_parts),
                                       options);
    for (std::string line = ReadLine(in); !line.empty(); line = ReadLine(in)) {
      std::istringstream request(line);
      char kind = 0;
      request >> kind;
      nlohmann::json answer;
      if (kind == 'M') {
        const Resident now = ResidentNow();
        answer = {{"open_ms", open_ms},
                  {"private_mib", now.anon - base.anon},
                  {"file_mib", now.file - base.file}};
      } else {
        size_t q = 0;
        request >> q;
        if (q >= queries.size()) PLACEDB_THROW_INVALID("no query ", q);
        if (kind == 'S') {
          answer = worker.MakeShortlist(q, queries[q].features);
        } else {
          std::vector<placedb::ShortlistEntry> candidates;
          std::string list;
          request >> list;
          std::istringstream items(list == "-" ? std::string() : list);
          for (std::string item; std::getline(items, item, ',');) {
            const size_t colon = item.find(':');
            if (colon == std::string::npos) PLACEDB_THROW_INVALID("bad candidate ", item);
            candidates.push_back({static_cast<uint32_t>(std::stoul(item.substr(0, colon))),
                                  std::stoi(item.substr(colon + 1)), 0.0, -1});
          }
          answer = worker.Answer(q, candidates);
        }
      }
      std::fputs((answer.dump() + "\n").c_str(), out);
      std::fflush(out);
    }
    std::_Exit(0);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "scale_bench: partition worker %d: %s\n", part, e.what());
    std::_Exit(1);
  }
}

// The bag-of-words search of `options` over `num_parts` worker processes in
// two rounds (query/result.h: shortlists, MergeShortlists, each part's share,
// MergeQueryResults), timed at the voter (this process) per query, each
// answer compared with the whole map's (`db`, the same options).
nlohmann::json RunPartitions(const placedb::PlaceDatabase& db, const fs::path& dir,
                             const placedb::OpenOptions& open_options,
                             const std::vector<Query>& queries, int num_parts,
                             const placedb::QueryOptions& options) {
  std::fflush(stdout);
  // A worker reads its share only: no prefetch of the whole files.
  placedb::OpenOptions worker_options = open_options;
  worker_options.prefetch = false;
  std::vector<Worker> workers;
  for (int p = 0; p < num_parts; ++p) {
    int down[2], up[2];
    if (::pipe(down) != 0 || ::pipe(up) != 0) PLACEDB_THROW_INVALID("pipe failed");
    const pid_t pid = ::fork();
    if (pid < 0) PLACEDB_THROW_INVALID("fork failed");
    if (pid == 0) {
      ::close(down[1]);
      ::close(up[0]);
      for (const Worker& w : workers) {  // the earlier workers' pipes
        std::fclose(w.to);
        std::fclose(w.from);
      }
      PartitionWorker(::fdopen(down[0], "r"), ::fdopen(up[1], "w"), dir, worker_options, p,
                      num_parts, queries, options);
    }
    ::close(down[0]);
    ::close(up[1]);
    workers.push_back({pid, ::fdopen(down[1], "w"), ::fdopen(up[0], "r")});
  }
  const auto ask = [&](Worker& w, const std::string& request) {
    std::fputs((request + "\n").c_str(), w.to);
    std::fflush(w.to);
  };
  const auto answer = [&](Worker& w) {
    const std::string line = ReadLine(w.from);
    if (line.empty()) PLACEDB_THROW_INVALID("a partition worker stopped (see its error above)");
    return nlohmann::json::parse(line);
  };
  std::vector<double> ms;
  int same = 0, correct = 0, whole_correct = 0;
  double examined = 0.0;
  const auto run = [&](size_t q, bool counted) {
    placedb::Timer t;
    std::vector<placedb::Shortlist> lists;
    for (Worker& w : workers) ask(w, fmt::format("S {}", q));
    for (Worker& w : workers) lists.push_back(answer(w).get<placedb::Shortlist>());
    const std::vector<placedb::ShortlistEntry> candidates =
        placedb::MergeShortlists(lists, options);
    std::string list;
    for (const placedb::ShortlistEntry& c : candidates)
      list += fmt::format("{}{}:{}", list.empty() ? "" : ",", c.index, c.keyframe_id);
    // An empty list still gets each worker's (empty) answer, as on ROS.
    for (Worker& w : workers) ask(w, fmt::format("A {} {}", q, list.empty() ? "-" : list));
    std::vector<placedb::QueryResult> parts;
    for (Worker& w : workers) parts.push_back(answer(w).get<placedb::QueryResult>());
    const placedb::QueryResult merged = placedb::MergeQueryResults(parts, options);
    const double elapsed = t.ElapsedMs();
    if (!counted) return;
    ms.push_back(elapsed);
    const placedb::QueryResult whole = db.Query(queries[q].features, options);
    same += merged.ranked == whole.ranked;
    examined += merged.num_examined;
    correct += !merged.ranked.empty() && merged.ranked.front().keyframe_id == queries[q].truth;
    whole_correct += !whole.ranked.empty() && whole.ranked.front().keyframe_id == queries[q].truth;
  };
  run(0, false);  // warm-up, not counted
  for (size_t q = 0; q < queries.size(); ++q) run(q, true);
  nlohmann::json memory = nlohmann::json::array();
  for (Worker& w : workers) {
    ask(w, "M");
    memory.push_back(answer(w));
  }
  for (Worker& w : workers) {
    std::fclose(w.to);  // EOF: the worker exits
    std::fclose(w.from);
    int status = 0;
    ::waitpid(w.pid, &status, 0);
  }
  const LatencyStats s = placedb::ComputeLatencyStats(ms);
  const double nq = static_cast<double>(queries.size());
  return {{"partitions", num_parts},        {"queries", queries.size()},
          {"latency_ms", StatsJson(s)},     {"same_answers", same},
          {"recall_at_1", correct / nq},    {"whole_recall_at_1", whole_correct / nq},
          {"examined_mean", examined / nq}, {"workers", memory}};
}

// `n` of the indices 0..count-1, spread evenly.
std::vector<size_t> Spread(size_t count, size_t n) {
  std::vector<size_t> out;
  n = std::min(n, count);
  for (size_t i = 0; i < n; ++i) out.push_back(i * count / n);
  return out;
}

// The database at `dir` was built with these settings from this source.
bool Reusable(const fs::path& dir, const nlohmann::json& settings, const std::string& source,
              size_t keyframes) {
  std::ifstream in(dir / "manifest.json");
  if (!in) return false;
  try {
    const nlohmann::json m = nlohmann::json::parse(in);
    // Through the options, so that a manifest written before a setting
    // existed (read as its documented absent value) still matches.
    const nlohmann::json stored =
        placedb::BuildSettingsToJson(placedb::BuildOptionsFromManifest(m, dir.string()));
    return stored == settings && m.at("source") == source &&
           m.at("counts").at("keyframes") == keyframes && m.at("counts").at("frames") == keyframes;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"scale_bench: query latency, memory, size and open time against database size"};
  std::vector<size_t> sizes = {1000, 10000, 100000};
  std::vector<std::string> modes = {"exhaustive", "bow", "cluster"};
  int num_queries = 200, exhaustive_queries = 20, threads_build = 0, features = 500;
  int fast_threshold = 5, bow_candidates = placedb::RetrievalOptions().bow_candidates;
  int guided_candidates = placedb::RetrievalOptions().guided_candidates;
  std::vector<int> compare_guided = {0, 10};
  // The whole-image rows run the library's defaults (the baseline rows turn the channel off).
  double deadline_ms = 2.0, cluster_radius = 0.5,
         whole_image_weight = placedb::QueryOptions().whole_image_weight;
  int whole_image_candidates = placedb::QueryOptions().whole_image_candidates,
      memory_queries = 10000, partitions = 4;
  int resident_limit_mb = 768, stored_features = 0;
  int track_neighbours = placedb::BuildOptions().track_neighbours;
  std::vector<int> compare_stored = {210};
  std::vector<size_t> compare_stored_at = {10000, 100000};
  std::string out = "out/bench/scale", json_path, data = PLACEDB_DATA_DIR;
  app.add_option("--sizes", sizes, "database sizes, keyframes")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--queries", num_queries, "queries per size")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--exhaustive-queries", exhaustive_queries,
                 "queries for exhaustive search above 1000 keyframes (it takes seconds each)")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--modes", modes, "search modes: exhaustive, bow, cluster")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--deadline-ms", deadline_ms, "deadline of the bow deadline run")
      ->check(CLI::Range(0.01, 1e6))
      ->capture_default_str();
  app.add_option("--bow-candidates", bow_candidates, "keyframes bow (and cluster) search scores")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--guided-candidates", guided_candidates,
                 "of those, matched in full after guided ranking (0: all)")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  app.add_option("--compare-guided", compare_guided,
                 "bow also runs with these --guided-candidates (0: unguided, all matched)")
      ->delimiter(',')
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  app.add_option("--whole-image-weight", whole_image_weight,
                 "bow and exhaustive also run with the whole-image channel at this weight (0: "
                 "not)")
      ->check(CLI::Range(0.0, 10000.0))
      ->capture_default_str();
  app.add_option("--whole-image-candidates", whole_image_candidates,
                 "that run's bow also matches this many keyframes most similar by whole image")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  app.add_option("--memory-queries", memory_queries,
                 "at the largest size, resident memory after this many more bow queries (0: none)")
      ->check(CLI::Range(0, 1000000))
      ->capture_default_str();
  app.add_option("--partitions", partitions,
                 "at the largest size, bow over this many partition processes in two rounds, "
                 "answers compared with the whole map's (0: not)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  app.add_option("--resident-limit-mb", resident_limit_mb,
                 "the memory runs are made with the default options (also with whole-image scoring "
                 "at --whole-image-weight), with the features mapped "
                 "(OpenOptions::read_features_above_mb 0), and mapped with this "
                 "OpenOptions::resident_limit_mb (0: not)")
      ->check(CLI::Range(0, 1048576))
      ->capture_default_str();
  app.add_option("--cluster-radius", cluster_radius,
                 "cluster radius, metres (views of one "
                 "sample image lie within a few cm, the images 1 m apart)")
      ->capture_default_str();
  app.add_option("--out", out, "databases are written (and reused) under this folder")
      ->capture_default_str();
  app.add_option("--json", json_path, "write the results as JSON");
  app.add_option("--threads-build", threads_build, "build threads; 0 = one per core")
      ->check(CLI::Range(0, 1024))
      ->capture_default_str();
  app.add_option("--features", features, "ORB features per frame")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--stored-features", stored_features,
                 "most features a keyframe keeps, spread over its image (BuildOptions::"
                 "stored_features; 0: all); queries keep every feature")
      ->check(CLI::Range(0, 100000))
      ->capture_default_str();
  app.add_option("--track-neighbours", track_neighbours,
                 "under a feature budget, the features matched in this many nearest keyframes "
                 "first (BuildOptions::track_neighbours; 0: spread alone)")
      ->check(CLI::Range(0, 32))
      ->capture_default_str();
  app.add_option("--compare-stored", compare_stored,
                 "at --compare-stored-at keyframes, databases keeping these --stored-features too "
                 "(bow runs only): disk and memory against recall")
      ->delimiter(',')
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  app.add_option("--compare-stored-at", compare_stored_at,
                 "the sizes of the --compare-stored databases (those of --sizes)")
      ->delimiter(',')
      ->capture_default_str();
  app.add_option("--fast-threshold", fast_threshold,
                 "ORB's FAST threshold (the library's default 20 leaves about 210 features on "
                 "these 320 x 240 views, 5 about 390)")
      ->check(CLI::Range(1, 255))
      ->capture_default_str();
  app.add_option("--data", data, "the sample data folder")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // progress shows in a log file too
  try {
    for (const std::string& m : modes) placedb::ParseRetrievalMethod(m);  // a typo fails early
    fs::create_directories(out);
    const std::vector<std::string> sources = SampleImages(data);
    if (sources.empty()) PLACEDB_THROW_NOT_FOUND("no sample images under ", data);
    const placedb::AugmentOptions keyframe_aug;
    const placedb::AugmentOptions query_aug = QueryAugmentOptions();
    const unsigned cpus = std::max(1u, std::thread::hardware_concurrency());
    const int cv_threads = cv::getNumThreads();

    const double ns = NsPerDistance();
    fmt::print(
        "{} sample images; {} CPUs; Hamming kernel {}: {:.3f} ns per distance at best "
        "(in cache)\n",
        sources.size(), cpus, placedb::HammingKernelName(), ns);
    nlohmann::json results = {
        {"cpus", cpus},
        {"sample_images", sources.size()},
        {"features_per_frame", features},
        {"fast_threshold", fast_threshold},
        {"stored_features", stored_features},
        {"track_neighbours", track_neighbours},
        {"compare_stored", compare_stored},
        {"queries", num_queries},
        {"exhaustive_queries_above_1000", exhaustive_queries},
        {"hamming_kernel", placedb::HammingKernelName()},
        {"ns_per_distance", ns},
        {"deadline_ms", deadline_ms},
        {"bow_candidates", bow_candidates},
        {"guided_candidates", guided_candidates},
        {"cluster_radius_m", cluster_radius},
        {"resident_limit_mb", resident_limit_mb},
        {"read_features_above_mb", placedb::OpenOptions().read_features_above_mb},
        {"keyframe_augment", placedb::AugmentOptionsToJson(keyframe_aug)},
        {"query_augment", placedb::AugmentOptionsToJson(query_aug)},
        {"sizes", nlohmann::json::array()}};
    std::vector<std::string> table;
    // Each size with --stored-features (the main runs), and after the size
    // of --compare-stored-at the same keyframes keeping fewer features (bow runs
    // only).
    struct Config {
      size_t n;
      int stored;
      bool main;
    };
    std::vector<Config> configs;
    for (const size_t n : sizes) {
      configs.push_back({n, stored_features, true});
      if (std::find(compare_stored_at.begin(), compare_stored_at.end(), n) ==
          compare_stored_at.end())
        continue;
      for (const int b : compare_stored)
        if (b != stored_features) configs.push_back({n, b, false});
    }
    const size_t largest = *std::max_element(sizes.begin(), sizes.end());
    const std::vector<std::string> bow_only = {"bow"};
    for (const Config& config : configs) {
      const size_t n = config.n;
      // Build, or reuse the database of an earlier run with the same settings.
      const std::vector<placedb::Frame> frames =
          placedb::AugmentedFrames(sources, n, kKeyframeSeed, keyframe_aug);
      placedb::BuildOptions build;
      build.features.orb.max_features = features;
      build.features.orb.fast_threshold = fast_threshold;
      build.stored_features = config.stored;
      build.track_neighbours = track_neighbours;
      build.store_images = false;
      build.index = placedb::IndexKind::kBow;
      build.threads = threads_build;
      build.overwrite = true;
      const std::string source = fmt::format(
          "scale_bench: {} augmentations (seed {}) of the {} sample images under {}; {}", n,
          kKeyframeSeed, sources.size(), data, placedb::AugmentOptionsToJson(keyframe_aug).dump());
      const std::string dir_name = config.main ? fmt::format("scale_{}", n)
                                               : fmt::format("scale_{}_stored{}", n, config.stored);
      const fs::path dir = fs::path(out) / dir_name;
      const fs::path build_log = fs::path(out) / (dir_name + ".build.json");
      const bool reused = Reusable(dir, placedb::BuildSettingsToJson(build), source, n);
      double build_seconds = 0.0;
      if (reused) {
        std::ifstream in(build_log);
        if (in) build_seconds = nlohmann::json::parse(in).value("seconds", 0.0);
        fmt::print("\n{} keyframes: reusing {} (built in {:.0f} s)\n", n, dir.string(),
                   build_seconds);
      } else {
        fmt::print("\n{} keyframes: building {}\n", n, dir.string());
        cv::setNumThreads(cv_threads);
        const placedb::BuildReport report = placedb::BuildDatabase(frames, build, dir, source);
        build_seconds = report.seconds;
        std::ofstream(build_log) << nlohmann::json{{"seconds", build_seconds}}.dump() << "\n";
        fmt::print("built in {:.1f} s\n", build_seconds);
      }
      malloc_trim(0);  // the build's heap, so that the open's memory shows

      // Open: memory of the kept session; the time of that first open (its
      // files dropped from the page cache: read from disk) and the best of 3
      // more (the files in the page cache; the closing not timed).
      cv::setNumThreads(1);
      placedb::OpenOptions open_options;
      open_options.threads = 1;
      open_options.clusters.radius_m = cluster_radius;
      const bool cold = DropFromPageCache(dir);
      const double rss_before = StatusMib("VmRSS");
      const Resident resident_before = ResidentNow();
      placedb::Timer open_timer;
      const placedb::PlaceDatabase db = placedb::PlaceDatabase::Open(dir.string(), open_options);
      const double first_open_ms = open_timer.ElapsedMs();
      const double rss_after = StatusMib("VmRSS");
      const Resident resident_open = ResidentNow();
      double open_ms = first_open_ms;
      for (int i = 0; i < 3; ++i) {
        placedb::Timer t;
        const placedb::PlaceDatabase again =
            placedb::PlaceDatabase::Open(dir.string(), open_options);
        open_ms = std::min(open_ms, t.ElapsedMs());
      }
      const uint64_t bytes = DirectoryBytes(dir);

      // Queries: a milder augmentation of keyframe k's image; features once.
      const size_t num_sources = sources.size();
      std::vector<Query> queries;
      double query_features = 0;
      for (size_t i = 0; i < static_cast<size_t>(num_queries); ++i) {
        Query q;
        q.truth = static_cast<int>(1 + (2 * i + 1) * n / (2 * num_queries));
        q.place = static_cast<int>((q.truth - 1) % num_sources);
        if (q.truth + num_sources <= n) {
          q.prior = static_cast<int>(q.truth + num_sources);
        } else if (static_cast<size_t>(q.truth) > num_sources) {
          q.prior = static_cast<int>(q.truth - num_sources);
        }
        const cv::Mat keyframe = placedb::LoadFrameImage(frames[q.truth - 1]);
        q.features = db.Extract(placedb::Augment(keyframe, i + 1, query_aug));
        query_features += q.features.size();
        queries.push_back(std::move(q));
      }
      query_features /= queries.size();
      const std::vector<size_t> all = Spread(queries.size(), queries.size());
      const std::vector<size_t> subset =
          n > 1000 ? Spread(queries.size(), exhaustive_queries) : all;

      std::vector<ModeRun> runs;
      const std::vector<std::string>& config_modes =
          config.main ? modes
                      : (std::find(modes.begin(), modes.end(), "bow") != modes.end()
                             ? bow_only
                             : std::vector<std::string>{});
      for (const std::string& m : config_modes) {
        runs.push_back(RunMode(db, queries, m == "exhaustive" ? subset : all, m, 0.0, num_sources,
                               bow_candidates, guided_candidates));
        if (!config.main) {
          // A budget: bow, and bow with the whole-image channel (what the
          // budget loses in fine discrimination, the thumbnail may give back).
          if (m == "bow" && whole_image_weight > 0)
            runs.push_back(RunMode(db, queries, all, m, 0.0, num_sources, bow_candidates,
                                   guided_candidates, whole_image_weight, whole_image_candidates));
          continue;
        }
        if (m == "bow") {
          // The same with other numbers matched in full after guided
          // ranking (0: none, every bow candidate matched in full).
          for (const int g : compare_guided) {
            if (g == guided_candidates) continue;
            runs.push_back(RunMode(db, queries, all, m, 0.0, num_sources, bow_candidates, g));
          }
        }
        if (m == "bow") {
          runs.push_back(RunMode(db, queries, all, m, deadline_ms, num_sources, bow_candidates,
                                 guided_candidates));
        }
        if ((m == "bow" || m == "exhaustive") && whole_image_weight > 0) {
          // The whole-image channel on (query/result.h): fused scores, and
          // bow also matches the keyframes most similar by thumbnail.
          runs.push_back(RunMode(db, queries, m == "exhaustive" ? subset : all, m, 0.0, num_sources,
                                 bow_candidates, guided_candidates, whole_image_weight,
                                 whole_image_candidates));
        }
      }
      const Resident resident_runs = ResidentNow();
      size_t runs_queries = 0;
      for (const ModeRun& r : runs) runs_queries += r.queries.size() + 1;  // + warm-up
      // At the largest size: a session of its own (opened now: the runs
      // above read every page of the first one), bow queries on fresh views
      // spread over the database, and the memory that session added.
      nlohmann::json memory_runs = nlohmann::json::array();
      // A budget's database at that size gets the default options' run
      // alone: the same queries as the whole map's, so their recall compares
      // over --memory-queries queries rather than the table's few.
      if (memory_queries > 0 && n == largest &&
          std::find(modes.begin(), modes.end(), "bow") != modes.end()) {
        // In a process of its own (forked: it starts with none of this
        // process's mapped pages resident), as a robot's would be: the
        // sessions' resident limit is the process's.
        // Every map: the default options (the map's size decides whether the
        // features are read or mapped: OpenOptions::read_features_above_mb),
        // and the same with whole-image scoring. The every-feature map also:
        // the features mapped without a limit, and mapped with the limit.
        struct MemoryConfig {
          int limit;
          bool mapped;
          double whole_image_weight;
        };
        std::vector<MemoryConfig> configs = {{0, false, 0.0}};
        if (whole_image_weight > 0) configs.push_back({0, false, whole_image_weight});
        if (config.main) configs.push_back({0, true, 0.0});
        if (config.main && resident_limit_mb > 0) configs.push_back({resident_limit_mb, true, 0.0});
        for (const MemoryConfig& mc : configs)
          memory_runs.push_back(InChildProcess([&] {
            const int limit = mc.limit;
            placedb::OpenOptions limited = open_options;
            limited.resident_limit_mb = limit;
            if (mc.mapped) limited.read_features_above_mb = 0;
            const Resident before_session = ResidentNow();
            const placedb::PlaceDatabase session =
                placedb::PlaceDatabase::Open(dir.string(), limited);
            placedb::QueryOptions options;
            options.retrieval.method = placedb::RetrievalMethod::kBow;
            options.retrieval.bow_candidates = bow_candidates;
            options.retrieval.guided_candidates = guided_candidates;
            options.whole_image_weight = mc.whole_image_weight;
            options.whole_image_candidates = mc.whole_image_weight > 0 ? whole_image_candidates : 0;
            placedb::AugmentOptions more = query_aug;
            more.seed = kQuerySeed + 1;
            std::vector<double> ms;
            FaultCount faults;
            int correct = 0, correct_place = 0;
            double extract_s = 0.0;
            for (int i = 0; i < memory_queries; ++i) {
              const int truth = static_cast<int>(1 + (2 * static_cast<size_t>(i) + 1) * n /
                                                         (2 * static_cast<size_t>(memory_queries)));
              placedb::Timer te;
              const placedb::FeatureSet f = session.Extract(
                  placedb::Augment(placedb::LoadFrameImage(frames[truth - 1]), i + 1, more));
              extract_s += te.ElapsedSeconds();
              const long faults_before = MajorFaults();
              placedb::Timer t;
              const placedb::QueryResult r = session.Query(f, options);
              ms.push_back(t.ElapsedMs());
              faults.Add(MajorFaults() - faults_before, ms.back());
              const int best = r.ranked.empty() ? 0 : r.ranked.front().keyframe_id;
              correct += best == truth;
              correct_place += best > 0 && (best - 1) % num_sources == (truth - 1) % num_sources;
              if ((i + 1) % 1000 == 0) {
                const Resident now = ResidentNow();
                fmt::print(
                    "  memory run: {} bow queries, resident private {:.0f} MiB, file {:.0f} MiB\n",
                    i + 1, now.anon - before_session.anon, now.file - before_session.file);
              }
            }
            // The releases the last queries asked for done (resident_limit_mb:
            // a thread of the session's lets go of pages behind the queries).
            session.WaitForBackgroundWork();
            const Resident after = ResidentNow();
            nlohmann::json by_file = nlohmann::json::object();
            for (const auto& [name, mib] : MappedResidentMib(dir)) {
              by_file[name] = mib;
              fmt::print("  memory run: {} resident {:.0f} MiB\n", name, mib);
            }
            const LatencyStats s = placedb::ComputeLatencyStats(ms);
            fmt::print(
                "  a new process and session (resident limit {} MiB{}), {} bow queries{}: "
                "resident +{:.0f} MiB private, +{:.0f} "
                "MiB file-backed over the process before its open (the process: {:.0f} + {:.0f} "
                "MiB); p50 {:.2f} ms p99 {:.2f} ms recall@1 {:.3f} place {:.3f}; {}\n",
                limit, session.reads_features() ? ", features read" : ", features mapped",
                memory_queries,
                mc.whole_image_weight > 0
                    ? fmt::format(" + whole image (weight {:g})", mc.whole_image_weight)
                    : std::string(),
                after.anon - before_session.anon, after.file - before_session.file, after.anon,
                after.file, s.p50, s.p99, static_cast<double>(correct) / memory_queries,
                static_cast<double>(correct_place) / memory_queries, faults.Text());
            return nlohmann::json{
                {"queries", memory_queries},
                {"resident_limit_mb", limit},
                {"read_features", session.reads_features()},
                {"default_options", !mc.mapped},
                {"whole_image_weight", mc.whole_image_weight},
                {"whole_image_candidates", options.whole_image_candidates},
                {"resident_increase", ResidentJson({after.anon - before_session.anon,
                                                    after.file - before_session.file})},
                {"latency_ms", StatsJson(s)},
                {"resident_by_file_mib", by_file},
                {"process_resident", ResidentJson(after)},
                {"recall_at_1", static_cast<double>(correct) / memory_queries},
                {"place_recall_at_1", static_cast<double>(correct_place) / memory_queries},
                {"faults", faults.Json()},
                {"extract_seconds", extract_s}};
          }));
      }
      // The map split over partition processes (bow, the default options).
      nlohmann::json partition_run;
      if (partitions > 0 && config.main && n == largest &&
          std::find(modes.begin(), modes.end(), "bow") != modes.end()) {
        placedb::QueryOptions options;
        options.retrieval.method = placedb::RetrievalMethod::kBow;
        options.retrieval.bow_candidates = bow_candidates;
        options.retrieval.guided_candidates = guided_candidates;
        partition_run = RunPartitions(db, dir, open_options, queries, partitions, options);
        const nlohmann::json& p = partition_run;
        fmt::print(
            "  bow over {} partition processes (two rounds): p50 {:.2f} ms p99 {:.2f} ms at the "
            "voter; {} of {} answers equal the whole map's; recall@1 {:.3f} (whole map {:.3f})\n",
            partitions, p["latency_ms"]["p50"].get<double>(), p["latency_ms"]["p99"].get<double>(),
            p["same_answers"].get<int>(), queries.size(), p["recall_at_1"].get<double>(),
            p["whole_recall_at_1"].get<double>());
        for (size_t w = 0; w < p["workers"].size(); ++w) {
          const nlohmann::json& m = p["workers"][w];
          fmt::print(
              "    partition {}: open {:.1f} ms, resident +{:.0f} MiB private, +{:.0f} MiB "
              "file-backed\n",
              w, m["open_ms"].get<double>(), m["private_mib"].get<double>(),
              m["file_mib"].get<double>());
        }
      }
      // Every byte checked (placedb verify).
      placedb::Timer verify_timer;
      db.Verify();
      const double verify_ms = verify_timer.ElapsedMs();

      const double limit_ms = query_features * db.num_features() * ns / 1e6;
      const ModeRun* exhaustive = nullptr;
      for (const ModeRun& r : runs) {
        if (r.mode == "exhaustive" && r.whole_image_weight == 0 && !exhaustive) exhaustive = &r;
      }

      nlohmann::json size = {
          {"keyframes", db.size()},
          {"features", db.num_features()},
          {"features_per_keyframe", static_cast<double>(db.num_features()) / db.size()},
          {"stored_features", config.stored},
          {"query_features_mean", query_features},
          {"build_seconds", build_seconds},
          {"reused", reused},
          {"database_bytes", bytes},
          {"open_ms", open_ms},
          {"first_open_ms", first_open_ms},
          {"rss_mib", rss_after},
          {"rss_increase_mib", rss_after - rss_before},
          {"first_open_cold", cold},
          {"resident_after_open", ResidentJson({resident_open.anon - resident_before.anon,
                                                resident_open.file - resident_before.file})},
          {"resident_after_runs", ResidentJson({resident_runs.anon - resident_before.anon,
                                                resident_runs.file - resident_before.file})},
          {"runs_queries", runs_queries},
          {"reads_features", db.reads_features()},
          {"verify_ms", verify_ms},
          {"popcount_limit_ms", limit_ms},
          {"modes", nlohmann::json::array()}};
      if (!memory_runs.empty()) size["memory_runs"] = memory_runs;
      if (!partition_run.is_null()) size["partition_run"] = partition_run;
      fmt::print(
          "{} keyframes, {} features: build {:.0f} s{}, database {:.1f} MB, open {:.1f} ms ({} "
          "{:.1f} ms), "
          "RSS {:.0f} MiB (+{:.0f} MiB: {:.0f} private, {:.0f} file-backed; after {} queries "
          "{:.0f} + {:.0f}); verify {:.0f} ms; popcount limit {:.2f} ms per query ({:.0f} x {} "
          "features x {:.3f} ns)\n",
          db.size(), db.num_features(), build_seconds, reused ? " (earlier run)" : "", bytes / 1e6,
          open_ms, cold ? "cold" : "first", first_open_ms, rss_after, rss_after - rss_before,
          resident_open.anon - resident_before.anon, resident_open.file - resident_before.file,
          runs_queries, resident_runs.anon - resident_before.anon,
          resident_runs.file - resident_before.file, verify_ms, limit_ms, query_features,
          db.num_features(), ns);
      for (const ModeRun& r : runs) {
        const LatencyStats s = placedb::ComputeLatencyStats(r.ms);
        const size_t nq = r.queries.size();
        const double recall = ModeRun::Recall(r.correct, r.queries);
        const double place = ModeRun::Recall(r.correct_place, r.queries);
        std::string name = r.mode;
        if (r.mode != "exhaustive" && r.guided_candidates != guided_candidates) {
          name += r.guided_candidates == 0 ? std::string(", unguided")
                                           : fmt::format(", guided {}", r.guided_candidates);
        }
        if (r.deadline_ms > 0) name += fmt::format(", deadline {:g} ms", r.deadline_ms);
        if (r.whole_image_weight > 0) name += " + whole image";
        if (!config.main) name += fmt::format(", {} stored", config.stored);
        nlohmann::json m = {
            {"mode", r.mode},
            {"deadline_ms", r.deadline_ms},
            {"guided_candidates", r.guided_candidates},
            {"whole_image_weight", r.whole_image_weight},
            {"whole_image_candidates", r.whole_image_candidates},
            {"queries", nq},
            {"latency_ms", StatsJson(s)},
            {"faults", r.faults.Json()},
            {"recall_at_1", recall},
            {"place_recall_at_1", place},
            {"recall_at_1_on_exhaustive_queries", ModeRun::Recall(r.correct, subset)},
            {"place_recall_at_1_on_exhaustive_queries", ModeRun::Recall(r.correct_place, subset)},
            {"examined_mean", r.examined / nq},
            {"examined_fraction", r.examined / nq / db.size()},
            {"coverage_mean", r.coverage / nq},
            {"stage_ms_mean",
             {{"retrieve", r.stages.retrieve_ms / nq},
              {"match", r.stages.match_ms / nq},
              {"verify", r.stages.verify_ms / nq}}},
            {"matched", r.matched},
            {"deadline_reached", r.deadline_reached},
            {"searches", r.searches}};
        std::string vs;
        if (r.mode == "exhaustive" && r.whole_image_weight == 0) {
          m["vs_popcount_limit"] = limit_ms > 0 ? s.p50 / limit_ms : 0.0;
          vs = fmt::format("p50 = {:.2f}x the popcount limit", s.p50 / limit_ms);
        } else if (exhaustive != nullptr) {
          const double points = 100.0 * (ModeRun::Recall(r.correct, subset) -
                                         ModeRun::Recall(exhaustive->correct, subset));
          const double place_points = 100.0 * (ModeRun::Recall(r.correct_place, subset) -
                                               ModeRun::Recall(exhaustive->correct_place, subset));
          m["recall_points_vs_exhaustive"] = points;
          m["place_recall_points_vs_exhaustive"] = place_points;
          vs = fmt::format("recall {:+.1f} / place {:+.1f} points vs exhaustive on its {} queries",
                           points, place_points, subset.size());
        }
        if (r.deadline_ms > 0) {
          const double over = placedb::Percentile(r.overshoot_ms, 99);
          const double over_max = *std::max_element(r.overshoot_ms.begin(), r.overshoot_ms.end());
          const auto late = std::count_if(r.overshoot_ms.begin(), r.overshoot_ms.end(),
                                          [](double ms) { return ms > 0.0; });
          m["overshoot_p99_ms"] = over;
          m["overshoot_max_ms"] = over_max;
          m["late_queries"] = late;
          vs += fmt::format(
              "; overshoot p99 {:.2f} ms, max {:.2f} ms, {} late (deadline reached {} times)", over,
              over_max, late, r.deadline_reached);
        }
        std::string searches;
        for (const auto& [k, v] : r.searches) searches += fmt::format(" {} {}", k, v);
        fmt::print(
            "  {:<20} {:>4} queries  p50 {:7.2f} ms  p99 {:7.2f} ms  recall@1 {:.3f}  "
            "place {:.3f}  examined {:.1f} keyframes  retrieve / match / verify {:.2f} / "
            "{:.2f} / {:.2f} ms  {}  [{} ]  {}\n",
            name, nq, s.p50, s.p99, recall, place, r.examined / nq, r.stages.retrieve_ms / nq,
            r.stages.match_ms / nq, r.stages.verify_ms / nq, vs, searches, r.faults.Text());
        table.push_back(
            fmt::format("{:>7} {:<20} {:>5} {:>8.2f} {:>8.2f} {:>8.3f} {:>6.3f} {:>9.1f} "
                        "{:>8.1f} {:>8.0f} {:>8.1f} {:>8.0f}",
                        db.size(), name, nq, s.p50, s.p99, recall, place, r.examined / nq, open_ms,
                        rss_after - rss_before, bytes / 1e6, build_seconds));
        size["modes"].push_back(m);
      }
      results["sizes"].push_back(size);
      if (!json_path.empty()) std::ofstream(json_path) << results.dump(2) << "\n";
    }
    fmt::print("\n{:>7} {:<20} {:>5} {:>8} {:>8} {:>8} {:>6} {:>9} {:>8} {:>8} {:>8} {:>8}\n",
               "size", "search", "n", "p50 ms", "p99 ms", "recall@1", "place", "examined",
               "open ms", "+RSS MiB", "DB MB", "build s");
    for (const std::string& row : table) fmt::print("{}\n", row);
    fmt::print(
        "(exhaustive search runs on {} evenly spread queries above 1000 keyframes; "
        "latency excludes feature extraction; one thread)\n",
        exhaustive_queries);
  } catch (const std::exception& e) {
    fmt::print(stderr, "scale_bench: error: {}\n", e.what());
    return 1;
  }
  return 0;
}
