// placedb_worker: holds partition I of N of a database (the session API's
// subset open) and answers every frame it receives over its keyframes: the
// partial result the voter merges. Input: images (raw or compressed) or
// features extracted once by placedb_extractor. Pinned to one CPU with
// --cpu, as in the paper.
#include <image_transport/image_transport.h>
#include <placedb_msgs/Features.h>
#include <placedb_msgs/PartialResult.h>
#include <ros/ros.h>
#include <sensor_msgs/CompressedImage.h>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>

#include "placedb/cli/flags.h"
#include "placedb/dataset/bag/image_message.h"
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

 private:
  void Answer(const FeatureSet& features, const std_msgs::Header& header, double extract_ms) {
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

  PlaceDatabase db_;
  QueryOptions options_;
  KeyframeSubset partition_;
  std::string database_id_;
  ros_node::DropLog drops_;
  ros::NodeHandle nh_;
  image_transport::ImageTransport it_;
  ros::Publisher results_;
  image_transport::Subscriber image_sub_;
  ros::Subscriber compressed_sub_, features_sub_;
};

}  // namespace
}  // namespace placedb

int main(int argc, char** argv) {
  namespace cli = placedb::cli;
  CLI::App app{"placedb_worker: matches frames against partition I of N of a placedb database",
               "placedb_worker"};
  placedb::ros_node::AddExamples(
      app, {"placedb_worker --db out/demo/db_tum_office --partition 0/3 --cpu 0",
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
    return "placedb_worker_" +
           (s.kind == placedb::KeyframeSubset::Kind::kPartition ? std::to_string(s.part)
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
    placedb::PlaceDatabase opened = db.Open();
    const placedb::KeyframeSubset partition = opened.subset();
    ROS_INFO("placedb_worker: %s of %s, %zu keyframes, %zu features, input %s",
             partition.Describe().c_str(), db.dir.c_str(), opened.size(),
             opened.num_features(), input.c_str());
    placedb::Worker worker(std::move(opened), query.Get(), partition, input);
    ros::spin();
    return 0;
  });
}
