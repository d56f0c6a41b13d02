// placedb_worker: holds partition I of N of a database (the session API's
// subset open) and answers every frame it receives over its keyframes: the
// partial result the voter merges. Input: images (raw or compressed) or
// features extracted once by placedb_extractor. Pinned to one CPU with
// --cpu, as in the paper.
//
// Bag-of-words search over more than one partition takes two rounds, so
// that the merged answer is the whole database's (a partition's own best
// candidates are not): the worker opens the whole database (mapped: its
// memory follows what its partition reads) and sends its shortlist of the
// frame (topic shortlists); the voter merges them and sends the frame's
// candidates (topic candidates); the worker answers its share of them on
// partial_results (BowPartitionWorker, distributed/partition_worker.h).
#include <image_transport/image_transport.h>
#include <placedb_msgs/Candidates.h>
#include <placedb_msgs/Features.h>
#include <placedb_msgs/PartialResult.h>
#include <placedb_msgs/Shortlist.h>
#include <ros/ros.h>
#include <sensor_msgs/CompressedImage.h>

#include <algorithm>
#include <map>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>

#include "placedb/cli/flags.h"
#include "placedb/dataset/bag/image_message.h"
#include "placedb/distributed/partition_worker.h"
#include "placedb/ros/messages.h"
#include "placedb/ros/node_common.h"

namespace placedb {
namespace {

class Worker {
 public:
  Worker(PlaceDatabase db, QueryOptions options, KeyframeSubset partition, const std::string& input)
      : db_(std::move(db)),
        options_(std::move(options)),
        partition_(std::move(partition)),
        database_id_(db_.generation()),
        drops_("placedb_worker"),
        it_(nh_) {
    results_ = nh_.advertise<placedb_msgs::PartialResult>("partial_results", 100);
    if (TwoRounds(options_, partition_)) {
      bow_.emplace(db_, partition_, options_, kMaxPending);
      shortlists_ = nh_.advertise<placedb_msgs::Shortlist>("shortlists", 100);
      candidates_sub_ = nh_.subscribe("candidates", 100, &Worker::OnCandidates, this,
                                      ros::TransportHints().tcpNoDelay());
    }
    // Queue of one: a worker that lags always answers the newest frame; the
    // voter answers the frames it skipped without it.
    if (input == "image") {
      image_sub_ =
          it_.subscribe("image", 1, &Worker::OnImage, this,
                        image_transport::TransportHints("raw", ros::TransportHints().tcpNoDelay()));
    } else if (input == "compressed") {
      compressed_sub_ = nh_.subscribe("image/compressed", 1, &Worker::OnCompressed, this,
                                      ros::TransportHints().tcpNoDelay());
    } else {
      features_sub_ = nh_.subscribe("features", 1, &Worker::OnFeatures, this,
                                    ros::TransportHints().tcpNoDelay());
    }
  }

  // Bag of words over more than one partition: two rounds (the session is
  // then opened on the whole database).
  static bool TwoRounds(const QueryOptions& options, const KeyframeSubset& partition) {
    return options.retrieval.method == RetrievalMethod::kBow && partition.num_parts > 1;
  }

 private:
  // Frames kept between the rounds: a frame's candidates come within the
  // voter's deadline (500 ms by default), and 64 frames are over 2 s of a
  // 30 Hz camera; an older frame's candidates are dropped ("no features").
  static constexpr size_t kMaxPending = 64;

  void Answer(const FeatureSet& features, const std_msgs::Header& header, double extract_ms) {
    if (bow_) {
      try {
        const Shortlist s = bow_->MakeShortlist(header.seq, features);
        extract_ms_[header.seq] = extract_ms;
        while (extract_ms_.size() > kMaxPending) extract_ms_.erase(extract_ms_.begin());
        shortlists_.publish(ShortlistToMessage(s, header.seq, header, partition_, database_id_));
      } catch (const std::exception& e) {
        drops_.Drop(ros_node::CauseOf(e.what()), e.what());
      }
      return;
    }
    try {
      QueryResult r = db_.Query(features, options_.ForPartition());
      r.times.extract_ms = extract_ms;
      r.times.total_ms += extract_ms;
      results_.publish(PartialToMessage(r, header.seq, header, partition_, database_id_));
    } catch (const std::exception& e) {
      drops_.Drop(ros_node::CauseOf(e.what()), e.what());
    }
  }

  void OnImage(const sensor_msgs::ImageConstPtr& msg) {
    cv::Mat image;
    try {
      image = ImageMessageToBgr(*msg);
    } catch (const std::exception& e) {
      drops_.Drop(ros_node::CauseOf(e.what()), e.what());
      return;
    }
    Extracted(image, msg->header);
  }

  void OnCompressed(const sensor_msgs::CompressedImageConstPtr& msg) {
    cv::Mat image;
    if (msg->data.size() > (64u << 20)) {
      drops_.Drop("compressed image", "larger than 64 MiB");
      return;
    }
    // Bounded by the header's pixel count before decoding (ImageReadOptions).
    const DecodedImage decoded =
        DecodeImage(msg->data.data(), msg->data.size(), ImageReadOptions(), "compressed image");
    image = decoded.image;
    if (decoded.too_large) {
      drops_.Drop("compressed image", decoded.error);
      return;
    }
    if (image.empty()) {
      drops_.Drop("compressed image",
                  "cannot be decoded (format '" + msg->format.substr(0, 32) + "')");
      return;
    }
    Extracted(image, msg->header);
  }

  void Extracted(const cv::Mat& image, const std_msgs::Header& header) {
    const ros::WallTime start = ros::WallTime::now();
    FeatureSet features;
    try {
      features = db_.Extract(image);
    } catch (const std::exception& e) {
      drops_.Drop(ros_node::CauseOf(e.what()), e.what());
      return;
    }
    Answer(features, header, (ros::WallTime::now() - start).toSec() * 1000.0);
  }

  void OnFeatures(const placedb_msgs::FeaturesConstPtr& msg) {
    FeatureSet features;
    try {
      features = FeaturesFromMessage(*msg);
    } catch (const std::exception& e) {
      drops_.Drop(ros_node::CauseOf(e.what()), e.what());
      return;
    }
    std_msgs::Header header = msg->header;
    header.seq = static_cast<uint32_t>(msg->frame_seq);
    Answer(features, header, 0.0);
  }

  // Round 2: this partition's share of the frame's candidates.
  void OnCandidates(const placedb_msgs::CandidatesConstPtr& m) {
    if (m->database_id != database_id_) {
      drops_.Drop("database", "the voter serves " + m->database_id.substr(0, 64) +
                                  ", this worker " + database_id_);
      return;
    }
    if (m->scheme != PartitionSchemeName(partition_.scheme) ||
        static_cast<int>(m->num_partitions) != partition_.num_parts) {
      drops_.Drop("partition",
                  "the voter splits the database " + std::to_string(m->num_partitions) + " ways (" +
                      m->scheme.substr(0, 16) + "), this worker " + partition_.Describe());
      return;
    }
    try {
      const FrameCandidates c = CandidatesFromMessage(*m);
      // Not merged: this worker's shortlist came after the voter's half of
      // the deadline; the frame is answered without it.
      if (std::find(c.merged.begin(), c.merged.end(), partition_.part) == c.merged.end()) {
        drops_.Drop("late shortlist",
                    "frame " + std::to_string(c.frame_seq) + " was merged without it");
        return;
      }
      QueryResult r = bow_->Answer(c.frame_seq, c.candidates);
      const auto extract = extract_ms_.find(c.frame_seq);
      if (extract != extract_ms_.end()) {
        r.times.extract_ms = extract->second;
        r.times.total_ms += extract->second;
        extract_ms_.erase(extract);
      }
      results_.publish(PartialToMessage(r, c.frame_seq, m->header, partition_, database_id_));
    } catch (const std::exception& e) {
      drops_.Drop(ros_node::CauseOf(e.what()), e.what());
    }
  }

  PlaceDatabase db_;
  QueryOptions options_;
  KeyframeSubset partition_;
  std::string database_id_;
  ros_node::DropLog drops_;
  ros::NodeHandle nh_;
  image_transport::ImageTransport it_;
  ros::Publisher results_, shortlists_;
  image_transport::Subscriber image_sub_;
  ros::Subscriber compressed_sub_, features_sub_, candidates_sub_;
  std::optional<BowPartitionWorker> bow_;  // two rounds
  std::map<uint64_t, double> extract_ms_;  // two rounds: by frame, until its answer
};

}  // namespace
}  // namespace placedb

int main(int argc, char** argv) {
  namespace cli = placedb::cli;
  CLI::App app{"placedb_worker: matches frames against partition I of N of a placedb database",
               "placedb_worker"};
  placedb::ros_node::AddExamples(
      app,
      {"placedb_worker --db out/demo/db_tum_office --partition 0/3 --cpu 0",
       "placedb_worker --db DB --partition 1/2 --partition-scheme interleaved --input features"});
  cli::DatabaseArgs db;
  cli::QueryArgs query;
  std::string input = "image";
  int cpu = -1;
  db.Add(&app);
  query.Add(&app);
  app.add_option("--input", input,
                 "what to subscribe to: image (topic image), compressed "
                 "(image/compressed) or features (features)")
      ->capture_default_str()
      ->check(CLI::IsMember({"image", "compressed", "features"}));
  app.add_option("--cpu", cpu, "pin the process to this CPU (-1: no pinning)")
      ->capture_default_str();
  int code = 0;
  // Named after its partition (parsed by then): placedb_worker_2.
  auto name = [&]() -> std::string {
    const placedb::KeyframeSubset& s = db.open.subset;
    return "placedb_worker_" + (s.kind == placedb::KeyframeSubset::Kind::kPartition
                                    ? std::to_string(s.part)
                                    : std::string("x"));
  };
  if (!placedb::ros_node::Init(&argc, argv, name, app, &code)) return code;
  return placedb::ros_node::RunNode("placedb_worker", [&] {
    if (db.open.subset.kind != placedb::KeyframeSubset::Kind::kPartition) {
      throw placedb::InvalidArgument("`partition` I/N is needed (e.g. 0/3)");
    }
    placedb::ros_node::PinToCpu(cpu);
    if (cpu >= 0) ROS_INFO("placedb_worker: pinned to CPU %d", cpu);
    // A worker is one CPU's worth of work (the paper's node per processor):
    // OpenCV's own threads would only compete with the other workers.
    cv::setNumThreads(1);
    const placedb::KeyframeSubset partition = db.open.subset;
    const placedb::QueryOptions options = query.Get();
    const bool two_rounds = placedb::Worker::TwoRounds(options, partition);
    // Two rounds shortlist the partition within the whole database.
    if (two_rounds) db.open.subset = placedb::KeyframeSubset::All();
    placedb::PlaceDatabase opened = db.Open();
    ROS_INFO("placedb_worker: %s of %s, %zu keyframes, %zu features, input %s%s",
             partition.Describe().c_str(), db.dir.c_str(), opened.size(), opened.num_features(),
             input.c_str(),
             two_rounds ? ", bag of words in two rounds (the whole database opened)" : "");
    placedb::Worker worker(std::move(opened), options, partition, input);
    ros::spin();
    return 0;
  });
}
