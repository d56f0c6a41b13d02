// The ROS system's speed, end to end on loopback, against the single-process
// query on the same frames in the same run:
//  - a database large enough that matching dominates: the 84 sample images
//    repeated (default 16 copies: 1344 keyframes);
//  - the single-process query (extraction + match + verify) on 1 and 2
//    threads;
//  - feed + N workers (N = 1, 2, 4; contiguous partitions, pinned to CPUs
//    round-robin) + voter, the feed paced by the answers (one frame in
//    flight): latency = the voter's answer time - the feed's publish time,
//    frames per second = 1000 / mean latency;
//  - added latency = end-to-end latency - the slowest worker's own time for
//    the frame (extraction, match, verify), per frame: what transport and
//    voting add;
//  - bag-of-words search (the same frames, a bow index): the single process
//    on one thread, and N workers (N = 2, 4) in two rounds (shortlists, the
//    voter's candidates, the answers), each answer compared with the single
//    process's.
// Prints a table and writes JSON (--json) for the README's table.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <thread>

#include "placedb/builder/builder.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/eval/metrics.h"
#include "placedb/ros/testbed.h"
#include "placedb/session/place_database.h"
#include "placedb/util/error.h"

namespace fs = std::filesystem;
using placedb::LatencyStats;

namespace {

nlohmann::json StatsJson(const LatencyStats& s) {
  return {{"mean", s.mean}, {"p50", s.p50}, {"p99", s.p99}, {"max", s.max}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ros_bench: placedb on ROS, end to end, against the single-process query"};
  std::string images = PLACEDB_DATA_DIR "/rtabmap_loop/images";
  std::string out = "out/bench/ros", json_path, nodes = PLACEDB_ROS_NODES;
  int copies = 16, loops = 1;
  std::vector<int> worker_counts = {1, 2, 4}, bow_worker_counts = {2, 4};
  app.add_option("--images", images, "sample images (the database is made of copies of them)");
  app.add_option("--copies", copies, "copies of the images in the database")->capture_default_str();
  app.add_option("--loops", loops, "passes over the query frames 41-84")->capture_default_str();
  app.add_option("--workers", worker_counts, "worker counts to run")->capture_default_str();
  app.add_option("--bow-workers", bow_worker_counts,
                 "worker counts to run with bag-of-words search (two rounds)")
      ->capture_default_str();
  app.add_option("--out", out, "scratch folder")->capture_default_str();
  app.add_option("--json", json_path, "write the results as JSON");
  CLI11_PARSE(app, argc, argv);
  try {
    fs::create_directories(out);
    // The database: the images repeated, ids 1 .. 84 x copies.
    const std::vector<placedb::Frame> sample = placedb::ListImageFolder(images);
    std::vector<placedb::Frame> frames;
    for (int c = 0; c < copies; ++c) {
      for (placedb::Frame f : sample) {
        f.id = static_cast<int>(frames.size()) + 1;
        frames.push_back(f);
      }
    }
    const std::string db_dir = (fs::path(out) / "db").string();
    placedb::BuildOptions build;
    build.progress = false;
    build.overwrite = true;
    placedb::BuildDatabase(frames, build, db_dir, fmt::format("{} copies of {}", copies, images));
    const std::vector<placedb::Frame> queries = placedb::ListImageFolder(images, 41, 84);

    // The single process, 1 and 2 threads: per-frame total time.
    std::map<int, std::vector<double>> single;  // threads -> ms per frame (in feed order)
    size_t keyframes = 0, features = 0;
    for (const int threads : {1, 2}) {
      placedb::OpenOptions o;
      o.threads = threads;
      const placedb::PlaceDatabase db = placedb::PlaceDatabase::Open(db_dir, o);
      keyframes = db.size();
      features = db.num_features();
      for (int loop = 0; loop < loops; ++loop) {
        for (const placedb::Frame& f : queries) {
          single[threads].push_back(db.Query(placedb::LoadFrameImage(f)).times.total_ms);
        }
      }
    }
    const unsigned cpus = std::max(1u, std::thread::hardware_concurrency());
    nlohmann::json results = {{"keyframes", keyframes},
                              {"features", features},
                              {"frames", queries.size() * loops},
                              {"cpus", cpus},
                              {"single_ms",
                               {{"1", StatsJson(placedb::ComputeLatencyStats(single[1]))},
                                {"2", StatsJson(placedb::ComputeLatencyStats(single[2]))}}},
                              {"ros", nlohmann::json::array()}};
    fmt::print("database: {} keyframes, {} ORB features; {} frames; {} CPUs\n", keyframes, features,
               queries.size() * loops, cpus);
    for (const int t : {1, 2}) {
      const LatencyStats s = placedb::ComputeLatencyStats(single[t]);
      fmt::print("single process, {} thread(s): {:.2f} ms p50, {:.2f} ms p99, {:.1f} frames/s\n", t,
                 s.p50, s.p99, 1000.0 / s.mean);
    }
    // One ROS run: feed + n workers + voter with `search` (query flags of
    // both), paced by the answers; each answer's ranked ids by frame.
    struct RosRun {
      std::map<uint64_t, double> published, answered, work;
      std::map<uint64_t, std::vector<int>> ranked;
      size_t complete = 0;
    };
    const auto run_ros = [&](const std::string& name, const std::string& db, int n,
                             const std::vector<std::string>& search) {
      const std::string dir = (fs::path(out) / name).string();
      fs::remove_all(dir);
      placedb::LoopbackRos ros(dir, nodes);
      std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // the master starts
      std::vector<std::string> voter = {
          "placedb_voter",       "--db",          db,      "--partitions",
          std::to_string(n),     "--deadline-ms", "10000", "--answers-file",
          dir + "/answers.jsonl"};
      voter.insert(voter.end(), search.begin(), search.end());
      ros.Start(voter, "voter.log");
      for (int i = 0; i < n; ++i) {
        std::vector<std::string> worker = {
            "placedb_worker",        "--db", db, "--partition", fmt::format("{}/{}", i, n), "--cpu",
            std::to_string(i % cpus)};
        worker.insert(worker.end(), search.begin(), search.end());
        ros.Start(worker, fmt::format("worker{}.log", i));
      }
      const pid_t feed =
          ros.Start({"placedb_feed", "--images", images, "--first", "41", "--last", "84", "--rate",
                     "0", "--loops", std::to_string(loops), "--wait-for", std::to_string(n),
                     "--answer-timeout-ms", "20000", "--log-file", dir + "/feed.jsonl"},
                    "feed.log");
      if (placedb::LoopbackRos::WaitExit(feed, 600) != 0)
        throw placedb::InvalidArgument("the feed failed:\n" + ros.ReadLog("feed.log"));
      RosRun r;
      for (const auto& j : placedb::LoopbackRos::ReadJsonLines(dir + "/feed.jsonl")) {
        if (j.contains("frame_seq"))
          r.published[j["frame_seq"]] = j["wall_ms"];  // (last: the report)
      }
      for (const auto& j : placedb::LoopbackRos::ReadJsonLines(dir + "/answers.jsonl")) {
        r.answered[j["frame_seq"]] = j["wall_ms"];
        // The slowest partition's own time (extraction + match + verify; in
        // two rounds, + the slowest shortlist).
        r.work[j["frame_seq"]] = j["result"]["times_ms"]["total"];
        r.complete += j["complete"].get<bool>();
        r.ranked[j["frame_seq"]];  // an answer ranking nothing is an answer too
        for (const auto& k : j["result"]["ranked"])
          r.ranked[j["frame_seq"]].push_back(k["keyframe_id"].get<int>());
      }
      return r;
    };
    // Transport and voting: the end-to-end latency minus the workers' own
    // time for the same frame, measured in the same run.
    const auto row = [&](const RosRun& r, int n, double fps_one) {
      std::vector<double> latency, added;
      for (const auto& [seq, t0] : r.published) {
        const auto a = r.answered.find(seq);
        if (a == r.answered.end()) continue;
        latency.push_back(a->second - t0);
        added.push_back(a->second - t0 - r.work.at(seq));
      }
      const LatencyStats l = placedb::ComputeLatencyStats(latency);
      const LatencyStats d = placedb::ComputeLatencyStats(added);
      const double fps = latency.empty() ? 0.0 : 1000.0 / l.mean;
      return nlohmann::json{{"workers", n},
                            {"published", r.published.size()},
                            {"answered", r.answered.size()},
                            {"complete", r.complete},
                            {"latency_ms", StatsJson(l)},
                            {"added_ms", StatsJson(d)},
                            {"fps", fps},
                            {"fps_vs_one_worker", fps_one > 0 ? fps / fps_one : 0.0}};
    };
    const auto print = [](const std::string& what, const nlohmann::json& w) {
      fmt::print(
          "{}, {} worker(s): {} of {} frames answered ({} complete); latency {:.2f} ms p50, {:.2f} "
          "ms p99; {:.1f} frames/s; transport + voting {:.2f} ms p50, {:.2f} ms p99\n",
          what, w["workers"].get<int>(), w["answered"].get<size_t>(), w["published"].get<size_t>(),
          w["complete"].get<size_t>(), w["latency_ms"]["p50"].get<double>(),
          w["latency_ms"]["p99"].get<double>(), w["fps"].get<double>(),
          w["added_ms"]["p50"].get<double>(), w["added_ms"]["p99"].get<double>());
    };
    double fps_one = 0;
    for (const int n : worker_counts) {
      nlohmann::json w = row(run_ros(fmt::format("ros_{}", n), db_dir, n, {}), n, fps_one);
      if (n == 1) {
        fps_one = w["fps"];
        w["fps_vs_one_worker"] = 1.0;
      }
      print("exhaustive", w);
      results["ros"].push_back(w);
    }

    // Bag of words: the same frames against the same keyframes with a bow
    // index; the single process on one thread, then the workers in two
    // rounds, each answer compared with the single process's.
    if (!bow_worker_counts.empty()) {
      const std::string bow_dir = (fs::path(out) / "db_bow").string();
      placedb::BuildOptions bow_build = build;
      bow_build.index = placedb::IndexKind::kBow;
      placedb::BuildDatabase(frames, bow_build, bow_dir,
                             fmt::format("{} copies of {}", copies, images));
      placedb::QueryOptions bow;
      bow.retrieval.method = placedb::RetrievalMethod::kBow;
      std::vector<double> ms;
      std::vector<std::vector<int>> expected;
      {
        placedb::OpenOptions o;
        o.threads = 1;
        const placedb::PlaceDatabase db = placedb::PlaceDatabase::Open(bow_dir, o);
        for (int loop = 0; loop < loops; ++loop) {
          for (const placedb::Frame& f : queries) {
            const placedb::QueryResult r = db.Query(placedb::LoadFrameImage(f), bow);
            ms.push_back(r.times.total_ms);
            std::vector<int> ids;
            for (const placedb::RankedKeyframe& k : r.ranked) ids.push_back(k.keyframe_id);
            expected.push_back(ids);
          }
        }
      }
      const LatencyStats s = placedb::ComputeLatencyStats(ms);
      fmt::print("bag of words, single process, 1 thread: {:.2f} ms p50, {:.2f} ms p99\n", s.p50,
                 s.p99);
      results["bow_single_ms"] = StatsJson(s);
      results["bow"] = nlohmann::json::array();
      for (const int n : bow_worker_counts) {
        const RosRun r = run_ros(fmt::format("ros_bow_{}", n), bow_dir, n, {"--search", "bow"});
        nlohmann::json w = row(r, n, 0.0);
        w.erase("fps_vs_one_worker");
        size_t same = 0;
        for (const auto& [seq, ids] : r.ranked)
          same += seq < expected.size() && ids == expected[seq];
        w["same_as_single_process"] = same;
        print(fmt::format("bag of words ({} equal to the single process)", same), w);
        results["bow"].push_back(w);
      }
    }
    if (!json_path.empty()) std::ofstream(json_path) << results.dump(2) << "\n";
  } catch (const std::exception& e) {
    fmt::print(stderr, "ros_bench: error: {}\n", e.what());
    return 1;
  }
  return 0;
}
