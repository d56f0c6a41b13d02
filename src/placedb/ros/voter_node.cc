// placedb_voter: gathers the workers' partial results per frame and answers
// each frame once: when every partition has answered, or at the deadline
// with what has arrived (naming the partitions that did not). The merge is
// the library's voting function, so a complete answer equals the single
// process query's. It opens only the database's keyframe table (ids, poses),
// never the descriptors, and publishes the answer and its pose.
// Bag-of-words search over more than one partition takes two rounds
// (VoteCollector): the workers' shortlists (topic shortlists) are merged
// into each frame's candidates (topic candidates), which the workers answer.
#include <geometry_msgs/PoseStamped.h>
#include <placedb_msgs/Answer.h>
#include <placedb_msgs/Candidates.h>
#include <placedb_msgs/PartialResult.h>
#include <placedb_msgs/Shortlist.h>
#include <ros/ros.h>
#include <std_msgs/Header.h>
#include <std_msgs/String.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <utility>

#include "placedb/cli/flags.h"
#include "placedb/cli/options.h"
#include "placedb/ros/messages.h"
#include "placedb/ros/node_common.h"

namespace placedb {
namespace {

class Voter {
 public:
  Voter(PlaceDatabase keyframes, VoteOptions options, std::string scheme, std::string map_frame,
        const std::string& answers_file, double stats_period_s)
      : keyframes_(std::move(keyframes)),
        collector_(options),
        scheme_(std::move(scheme)),
        map_frame_(std::move(map_frame)),
        database_id_(keyframes_.generation()),
        drops_("placedb_voter") {
    if (collector_.options().sequence) collector_.UseSequence(keyframes_.keyframes());
    if (!answers_file.empty()) {
      answers_log_.open(answers_file, std::ios::app);
      if (!answers_log_.good()) throw IoError("cannot write " + answers_file);
    }
    // Latched: a subscriber that comes later (rostopic echo -n 1 /answers)
    // still gets the last answer.
    answers_ = nh_.advertise<placedb_msgs::Answer>("answers", 100, /*latch=*/true);
    poses_ = nh_.advertise<geometry_msgs::PoseStamped>("pose", 100);
    stats_pub_ = nh_.advertise<std_msgs::String>("voter_stats", 1, /*latch=*/true);
    frames_sub_ =
        nh_.subscribe("frames", 1000, &Voter::OnFrame, this, ros::TransportHints().tcpNoDelay());
    partial_sub_ = nh_.subscribe("partial_results", 1000, &Voter::OnPartial, this,
                                 ros::TransportHints().tcpNoDelay());
    if (collector_.two_rounds()) {
      candidates_ = nh_.advertise<placedb_msgs::Candidates>("candidates", 1000);
      shortlist_sub_ = nh_.subscribe("shortlists", 1000, &Voter::OnShortlist, this,
                                     ros::TransportHints().tcpNoDelay());
    }
    // Deadlines are checked every 2 ms; complete frames are answered as their
    // last partial arrives.
    timer_ = nh_.createSteadyTimer(ros::WallDuration(0.002), &Voter::OnTimer, this);
    // The counts, on voter_stats and in the log, when they changed.
    stats_timer_ =
        nh_.createSteadyTimer(ros::WallDuration(stats_period_s), &Voter::OnStatsTimer, this);
    PublishStats();
    last_logged_ = Report();
  }

  // What the voter did: one line (the log at shutdown and every period).
  std::string Report() const {
    const VoteStats& s = collector_.stats();
    return "placedb_voter: " + std::to_string(s.answered) + " frames answered (" +
           std::to_string(s.complete) + " complete, " + std::to_string(s.partial) +
           " partial) in " + std::to_string(s.runs) + " feed runs; dropped: " + drops_.Summary();
  }

 private:
  static double NowMs() { return ros::WallTime::now().toSec() * 1000.0; }

  void OnFrame(const std_msgs::HeaderConstPtr& h) {
    // The feed's run id is its announcements' frame_id.
    const VoteStatus status = collector_.OnFrame(h->seq, NowMs(), h->frame_id);
    if (status != VoteStatus::kAccepted) {
      drops_.Drop(std::string(VoteStatusName(status)) + " announcement",
                  "frame " + std::to_string(h->seq) + " was answered already");
    } else {
      headers_[{collector_.run(), h->seq}] = *h;
    }
    Publish();
  }

  // A worker's message serves this voter's database, split as it expects
  // (else dropped, once per cause in the log).
  bool SameSplit(const std::string& database_id, const std::string& scheme,
                 uint32_t num_partitions) {
    if (database_id != database_id_) {
      drops_.Drop("database",
                  "a worker serves " + database_id.substr(0, 64) + ", the voter " + database_id_);
      return false;
    }
    if (scheme != scheme_ ||
        static_cast<int>(num_partitions) != collector_.options().num_partitions) {
      drops_.Drop("partition", "a worker splits the database " + std::to_string(num_partitions) +
                                   " ways (" + scheme.substr(0, 16) + "), the voter expects " +
                                   std::to_string(collector_.options().num_partitions) + " (" +
                                   scheme_ + ")");
      return false;
    }
    return true;
  }

  void OnShortlist(const placedb_msgs::ShortlistConstPtr& m) {
    if (!SameSplit(m->database_id, m->scheme, m->num_partitions)) return;
    Shortlist shortlist;
    try {
      shortlist = ShortlistFromMessage(*m);
    } catch (const std::exception& e) {
      drops_.Drop(ros_node::CauseOf(e.what()), e.what());
      return;
    }
    const VoteStatus status =
        collector_.OnShortlist(m->frame_seq, static_cast<int>(m->partition), shortlist, NowMs());
    if (status != VoteStatus::kAccepted) {
      drops_.Drop(
          std::string(VoteStatusName(status)) + " shortlist",
          "partition " + std::to_string(m->partition) + ", frame " + std::to_string(m->frame_seq));
    } else {
      headers_.emplace(std::make_pair(collector_.run(), m->frame_seq), m->header);
    }
    Publish();
  }

  void OnPartial(const placedb_msgs::PartialResultConstPtr& m) {
    if (!SameSplit(m->database_id, m->scheme, m->num_partitions)) return;
    QueryResult partial;
    try {
      partial = PartialFromMessage(*m);
    } catch (const std::exception& e) {
      drops_.Drop(ros_node::CauseOf(e.what()), e.what());
      return;
    }
    const VoteStatus status =
        collector_.OnPartial(m->frame_seq, static_cast<int>(m->partition), partial, NowMs());
    if (status != VoteStatus::kAccepted) {
      std::string what =
          "partition " + std::to_string(m->partition) + ", frame " + std::to_string(m->frame_seq);
      // Bag of words takes two rounds: an answer before the frame's
      // candidates comes from a worker that answers in one.
      if (status == VoteStatus::kUnexpected)
        what += " (not asked for: the workers need the voter's search options)";
      drops_.Drop(VoteStatusName(status), what);
    } else {
      headers_.emplace(std::make_pair(collector_.run(), m->frame_seq), m->header);
    }
    Publish();
  }

  void OnTimer(const ros::SteadyTimerEvent&) { Publish(); }

  // Every period: the counts in the log (when they changed since the last
  // line), and on voter_stats (drops do not publish it at once).
  void OnStatsTimer(const ros::SteadyTimerEvent&) {
    const std::string report = Report();
    if (report == last_logged_) return;
    ROS_INFO("%s", report.c_str());
    last_logged_ = report;
    PublishStats();
  }

  // voter_stats (latched std_msgs/String): the counts as JSON.
  void PublishStats() {
    const VoteStats& s = collector_.stats();
    nlohmann::json j = {{"answered", s.answered},    {"complete", s.complete},
                        {"partial", s.partial},      {"runs", s.runs},
                        {"run", collector_.run()},   {"pending", collector_.pending()},
                        {"dropped", drops_.counts()}};
    std_msgs::String msg;
    msg.data = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    stats_pub_.publish(msg);
  }

  void Publish() {
    // Two rounds: the frames whose shortlists are in (or half their
    // deadline gone) get their candidates.
    std::vector<FrameCandidates> merged;
    try {
      merged = collector_.PollCandidates(NowMs());
    } catch (const std::exception& e) {
      drops_.Drop(ros_node::CauseOf(e.what()), e.what());
    }
    for (const FrameCandidates& c : merged) {
      std_msgs::Header header;
      const auto h = headers_.find({collector_.run(), c.frame_seq});
      if (h != headers_.end()) header = h->second;
      header.seq = static_cast<uint32_t>(c.frame_seq);
      candidates_.publish(CandidatesToMessage(c, header, collector_.options().num_partitions,
                                              ParsePartitionScheme(scheme_), database_id_));
    }
    std::vector<FrameAnswer> ready;
    try {
      ready = collector_.Poll(NowMs());
    } catch (const std::exception& e) {
      // Partial results that cannot be merged (a keyframe in two partitions:
      // workers of different splits): the frames are lost, the voter lives.
      drops_.Drop(ros_node::CauseOf(e.what()), e.what());
      return;
    }
    for (FrameAnswer& a : ready) {
      DescribeKeyframes(keyframes_, &a.result);
      std_msgs::Header header;
      const auto h = headers_.find({a.run, a.frame_seq});
      if (h != headers_.end()) {
        header = h->second;
        headers_.erase(h);
      }
      header.seq = static_cast<uint32_t>(a.frame_seq);
      header.frame_id = map_frame_;
      const placedb_msgs::Answer msg = AnswerToMessage(a, keyframes_, header);
      answers_.publish(msg);
      if (msg.has_pose) {
        geometry_msgs::PoseStamped pose;
        pose.header = header;
        pose.pose = msg.pose;
        poses_.publish(pose);
      }
      if (!a.complete()) {
        ROS_DEBUG("placedb_voter: frame %lu answered without %zu partitions",
                  static_cast<unsigned long>(a.frame_seq), a.missing.size());
      }
      if (answers_log_.is_open()) {
        const nlohmann::json result = nlohmann::json::parse(QueryResultToJson(a.result));
        const RankedKeyframe* best = a.result.best();
        const nlohmann::json best_json = best ? result["ranked"][0] : nlohmann::json();
        nlohmann::json j = {{"frame_seq", a.frame_seq},
                            {"run", a.run},
                            // The frame's source timestamp (its header's stamp), seconds.
                            {"timestamp", header.stamp.toSec()},
                            {"keyframe_id", best ? best->keyframe_id : -1},
                            // The answer's pose (null when no match or the database has none)
                            // and its keyframe's source image.
                            {"pose", best ? best_json["pose"] : nlohmann::json()},
                            {"source", best ? best->source : std::string()},
                            {"wall_ms", ros_node::WallMs()},
                            {"wait_ms", a.waited_ms},
                            {"complete", a.complete()},
                            {"answered", a.answered},
                            {"missing", a.missing},
                            {"result", result}};
        answers_log_ << j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) << "\n"
                     << std::flush;
      }
    }
    if (!ready.empty()) PublishStats();
    // Headers of frames that can no longer be answered (a bound, not a rule:
    // every header stored is a pending frame's).
    while (headers_.size() > 2 * static_cast<size_t>(collector_.options().max_pending) + 16)
      headers_.erase(headers_.begin());
  }

  PlaceDatabase keyframes_;
  VoteCollector collector_;
  std::string scheme_, map_frame_, database_id_;
  ros_node::DropLog drops_;
  std::map<std::pair<std::string, uint64_t>, std_msgs::Header> headers_;  // by (run, frame)
  std::ofstream answers_log_;
  std::string last_logged_;
  ros::NodeHandle nh_;
  ros::Publisher answers_, poses_, stats_pub_, candidates_;
  ros::Subscriber frames_sub_, partial_sub_, shortlist_sub_;
  ros::SteadyTimer timer_, stats_timer_;
};

}  // namespace
}  // namespace placedb

int main(int argc, char** argv) {
  namespace cli = placedb::cli;
  CLI::App app{"placedb_voter: merges the workers' partial results into one answer per frame",
               "placedb_voter"};
  placedb::ros_node::AddExamples(
      app, {"placedb_voter --db out/demo/db_tum_office --partitions 3 --answers-file answers.jsonl",
            "placedb_voter --db DB --partitions 4 --partition-scheme interleaved --deadline-ms 200",
            "placedb_voter --db DB --partitions 2 --sequence --sequence-length 10"});
  std::string dir, scheme = "contiguous", map_frame = "map", answers_file;
  double stats_period_s = 10.0;
  placedb::VoteOptions vote;
  app.add_option("--db", dir, "database directory (only its keyframe table is read)")->required();
  // The vote's options and the query options answers rank and decide by.
  cli::AddOptionFlags(&app, &vote);
  app.get_option("--partitions")->required();
  app.add_option("--partition-scheme", scheme, "contiguous or interleaved, as the workers")
      ->capture_default_str()
      ->check(CLI::IsMember({"contiguous", "interleaved"}));
  app.add_option("--map-frame", map_frame, "frame_id of the published poses")
      ->capture_default_str();
  app.add_option("--answers-file", answers_file,
                 "also append every answer to this file as a JSON line");
  app.add_option("--stats-period", stats_period_s,
                 "seconds between reports of the counts (log line, voter_stats), when they "
                 "changed (0.1, 3600]")
      ->capture_default_str();
  int code = 0;
  if (!placedb::ros_node::Init(
          &argc, argv, [] { return std::string("placedb_voter"); }, app, &code))
    return code;
  return placedb::ros_node::RunNode("placedb_voter", [&] {
    if (!(stats_period_s > 0.1 && stats_period_s <= 3600))
      throw placedb::InvalidArgument("`stats_period` must be in (0.1, 3600]");
    const std::string reason = vote.Check();
    if (!reason.empty()) throw placedb::InvalidArgument("invalid vote options: " + reason);
    placedb::OpenOptions table;
    table.keyframe_table = true;
    placedb::PlaceDatabase keyframes = placedb::PlaceDatabase::Open(dir, table);
    ROS_INFO("placedb_voter: %zu keyframes of %s in %d partitions (%s), deadline %.0f ms%s",
             keyframes.size(), dir.c_str(), vote.num_partitions, scheme.c_str(), vote.deadline_ms,
             vote.sequence ? ", sequence evidence" : "");
    placedb::Voter voter(std::move(keyframes), vote, scheme, map_frame, answers_file,
                         stats_period_s);
    ros::spin();
    // Stopped (SIGINT, SIGTERM, rosnode kill): what it did, once more. (On
    // stdout: rosconsole no longer prints once the node has shut down.)
    std::printf("%s (at shutdown)\n", voter.Report().c_str());
    std::fflush(stdout);
    return 0;
  });
}
