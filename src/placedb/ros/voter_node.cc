// placedb_voter: gathers the workers' partial results per frame and answers
// each frame once: when every partition has answered, or at the deadline
// with what has arrived (naming the partitions that did not). The merge is
// the library's voting function, so a complete answer equals the single
// process query's. It opens only the database's keyframe table (ids, poses),
// never the descriptors, and publishes the answer and its pose.
#include <geometry_msgs/PoseStamped.h>
#include <placedb_msgs/Answer.h>
#include <placedb_msgs/PartialResult.h>
#include <ros/ros.h>
#include <std_msgs/Header.h>

#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include <nlohmann/json.hpp>

#include "placedb/cli/flags.h"
#include "placedb/cli/options.h"
#include "placedb/ros/messages.h"
#include "placedb/ros/node_common.h"

namespace placedb {
namespace {

class Voter {
 public:
  Voter(PlaceDatabase keyframes, VoteOptions options, std::string scheme, std::string map_frame,
        const std::string& answers_file)
      : keyframes_(std::move(keyframes)),
        collector_(options),
        scheme_(std::move(scheme)),
        map_frame_(std::move(map_frame)),
        database_id_(keyframes_.generation()),
        drops_("placedb_voter") {
    if (!answers_file.empty()) {
      answers_log_.open(answers_file, std::ios::app);
      if (!answers_log_.good()) throw IoError("cannot write " + answers_file);
    }
    answers_ = nh_.advertise<placedb_msgs::Answer>("answers", 100);
    poses_ = nh_.advertise<geometry_msgs::PoseStamped>("pose", 100);
    frames_sub_ =
        nh_.subscribe("frames", 1000, &Voter::OnFrame, this, ros::TransportHints().tcpNoDelay());
    partial_sub_ = nh_.subscribe("partial_results", 1000, &Voter::OnPartial, this,
                                 ros::TransportHints().tcpNoDelay());
    // Deadlines are checked every 2 ms; complete frames are answered as their
    // last partial arrives.
    timer_ = nh_.createSteadyTimer(ros::WallDuration(0.002), &Voter::OnTimer, this);
  }

 private:
  static double NowMs() { return ros::WallTime::now().toSec() * 1000.0; }

  void OnFrame(const std_msgs::HeaderConstPtr& h) {
    headers_.emplace(h->seq, *h);
    collector_.OnFrame(h->seq, NowMs());
  }

  void OnPartial(const placedb_msgs::PartialResultConstPtr& m) {
    if (m->database_id != database_id_) {
      drops_.Drop("database", "a worker serves " + m->database_id.substr(0, 64) + ", the voter " +
                                  database_id_);
      return;
    }
    if (m->scheme != scheme_ ||
        static_cast<int>(m->num_partitions) != collector_.options().num_partitions) {
      drops_.Drop("partition", "a worker splits the database " + std::to_string(m->num_partitions) +
                                   " ways (" + m->scheme.substr(0, 16) + "), the voter expects " +
                                   std::to_string(collector_.options().num_partitions) + " (" +
                                   scheme_ + ")");
      return;
    }
    QueryResult partial;
    try {
      partial = PartialFromMessage(*m);
    } catch (const std::exception& e) {
      drops_.Drop(ros_node::CauseOf(e.what()), e.what());
      return;
    }
    headers_.emplace(m->frame_seq, m->header);
    const VoteStatus status =
        collector_.OnPartial(m->frame_seq, static_cast<int>(m->partition), partial, NowMs());
    if (status != VoteStatus::kAccepted) {
      drops_.Drop(VoteStatusName(status), "partition " + std::to_string(m->partition) + ", frame " +
                                              std::to_string(m->frame_seq));
    }
    Publish();
  }

  void OnTimer(const ros::SteadyTimerEvent&) { Publish(); }

  void Publish() {
    for (const FrameAnswer& a : collector_.Poll(NowMs())) {
      std_msgs::Header header;
      const auto h = headers_.find(a.frame_seq);
      if (h != headers_.end()) header = h->second;
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
        nlohmann::json j = {{"frame_seq", a.frame_seq},      {"stamp", header.stamp.toSec()},
                            {"wall_ms", ros_node::WallMs()}, {"wait_ms", a.waited_ms},
                            {"complete", a.complete()},      {"answered", a.answered},
                            {"missing", a.missing},
                            {"result", nlohmann::json::parse(QueryResultToJson(a.result))}};
        answers_log_ << j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) << "\n"
                     << std::flush;
      }
      // Headers of answered frames are not needed again.
      headers_.erase(headers_.begin(), headers_.upper_bound(a.frame_seq));
    }
  }

  PlaceDatabase keyframes_;
  VoteCollector collector_;
  std::string scheme_, map_frame_, database_id_;
  ros_node::DropLog drops_;
  std::map<uint64_t, std_msgs::Header> headers_;
  std::ofstream answers_log_;
  ros::NodeHandle nh_;
  ros::Publisher answers_, poses_;
  ros::Subscriber frames_sub_, partial_sub_;
  ros::SteadyTimer timer_;
};

}  // namespace
}  // namespace placedb

int main(int argc, char** argv) {
  namespace cli = placedb::cli;
  CLI::App app{"placedb_voter: merges the workers' partial results into one answer per frame"};
  std::string dir, scheme = "contiguous", map_frame = "map", answers_file;
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
  int code = 0;
  if (!placedb::ros_node::Init(
          &argc, argv, [] { return std::string("placedb_voter"); }, app, &code))
    return code;
  return placedb::ros_node::RunNode("placedb_voter", [&] {
    const std::string reason = vote.Check();
    if (!reason.empty()) throw placedb::InvalidArgument("invalid vote options: " + reason);
    placedb::OpenOptions table;
    table.keyframe_table = true;
    placedb::PlaceDatabase keyframes = placedb::PlaceDatabase::Open(dir, table);
    ROS_INFO("placedb_voter: %zu keyframes of %s in %d partitions (%s), deadline %.0f ms",
             keyframes.size(), dir.c_str(), vote.num_partitions, scheme.c_str(), vote.deadline_ms);
    placedb::Voter voter(std::move(keyframes), vote, scheme, map_frame, answers_file);
    ros::spin();
    return 0;
  });
}
