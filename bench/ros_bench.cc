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
//    voting add.
// Prints a table and writes JSON (--json) for the README's table.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <thread>

#include "placedb/dataset/image_folder.h"
#include "placedb/eval/metrics.h"
#include "placedb/builder/builder.h"
#include "placedb/session/place_database.h"
#include "placedb/ros/testbed.h"

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
  std::vector<int> worker_counts = {1, 2, 4};
  app.add_option("--images", images, "sample images (the database is made of copies of them)");
  app.add_option("--copies", copies, "copies of the images in the database")->capture_default_str();
  app.add_option("--loops", loops, "passes over the query frames 41-84")->capture_default_str();
  app.add_option("--workers", worker_counts, "worker counts to run")->capture_default_str();
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
    double fps_one = 0;
    for (const int n : worker_counts) {
      const std::string dir = (fs::path(out) / fmt::format("ros_{}", n)).string();
      fs::remove_all(dir);
      placedb::LoopbackRos ros(dir, nodes);
      std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // the master starts
      ros.Start({"placedb_voter", "--db", db_dir, "--partitions", std::to_string(n),
                 "--deadline-ms", "10000", "--answers-file", dir + "/answers.jsonl"},
                "voter.log");
      for (int i = 0; i < n; ++i) {
        ros.Start({"placedb_worker", "--db", db_dir, "--partition", fmt::format("{}/{}", i, n),
                   "--cpu", std::to_string(i % cpus)},
                  fmt::format("worker{}.log", i));
      }
      const pid_t feed =
          ros.Start({"placedb_feed", "--images", images, "--first", "41", "--last", "84", "--rate",
                     "0", "--loops", std::to_string(loops), "--wait-for", std::to_string(n),
                     "--answer-timeout-ms", "20000", "--log-file", dir + "/feed.jsonl"},
                    "feed.log");
      if (placedb::LoopbackRos::WaitExit(feed, 600) != 0) {
        fmt::print(stderr, "ros_bench: the feed failed:\n{}\n", ros.ReadLog("feed.log"));
        return 1;
      }
      std::map<uint64_t, double> published, answered, work;
      for (const auto& j : placedb::LoopbackRos::ReadJsonLines(dir + "/feed.jsonl")) {
        if (j.contains("frame_seq")) published[j["frame_seq"]] = j["wall_ms"];  // (last: the report)
      }
      size_t complete = 0;
      for (const auto& j : placedb::LoopbackRos::ReadJsonLines(dir + "/answers.jsonl")) {
        answered[j["frame_seq"]] = j["wall_ms"];
        // The slowest partition's own time (extraction + match + verify).
        work[j["frame_seq"]] = j["result"]["times_ms"]["total"];
        complete += j["complete"].get<bool>();
      }
      // Transport and voting: the end-to-end latency minus the workers' own
      // time for the same frame, measured in the same run.
      std::vector<double> latency, added;
      for (const auto& [seq, t0] : published) {
        const auto a = answered.find(seq);
        if (a == answered.end()) continue;
        latency.push_back(a->second - t0);
        added.push_back(a->second - t0 - work[seq]);
      }
      const LatencyStats l = placedb::ComputeLatencyStats(latency);
      const LatencyStats d = placedb::ComputeLatencyStats(added);
      const double fps = latency.empty() ? 0.0 : 1000.0 / l.mean;
      if (n == 1) fps_one = fps;
      fmt::print(
          "{} worker(s): {} of {} frames answered ({} complete); latency {:.2f} ms p50, {:.2f} ms "
          "p99; "
          "{:.1f} frames/s ({:.2f}x one worker); transport + voting {:.2f} ms p50, {:.2f} ms p99\n",
          n, answered.size(), published.size(), complete, l.p50, l.p99, fps,
          fps_one > 0 ? fps / fps_one : 0.0, d.p50, d.p99);
      results["ros"].push_back({{"workers", n},
                                {"published", published.size()},
                                {"answered", answered.size()},
                                {"complete", complete},
                                {"latency_ms", StatsJson(l)},
                                {"added_ms", StatsJson(d)},
                                {"fps", fps},
                                {"fps_vs_one_worker", fps_one > 0 ? fps / fps_one : 0.0}});
    }
    if (!json_path.empty()) std::ofstream(json_path) << results.dump(2) << "\n";
  } catch (const std::exception& e) {
    fmt::print(stderr, "ros_bench: error: {}\n", e.what());
    return 1;
  }
  return 0;
}
