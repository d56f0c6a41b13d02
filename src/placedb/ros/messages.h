// placedb's values to and from its ROS messages (placedb_msgs). Every
// message from the wire is validated: a bad one throws InvalidArgument whose
// message starts with its cause, for the nodes to log once per cause.
#pragma once

#include <placedb_msgs/Answer.h>
#include <placedb_msgs/Features.h>
#include <placedb_msgs/PartialResult.h>

#include <string>

#include "placedb/placedb.h"

namespace placedb {

placedb_msgs::Features FeaturesToMessage(const FeatureSet& features, uint64_t frame_seq,
                                         const std_msgs::Header& header);
// Checks: a known feature type, the width of that type, 7 values per
// keypoint, finite values, integral octave and class_id, as many descriptor
// rows as keypoints. (Whether they fit a database is the query's check.)
FeatureSet FeaturesFromMessage(const placedb_msgs::Features& message);

placedb_msgs::PartialResult PartialToMessage(const QueryResult& result, uint64_t frame_seq,
                                             const std_msgs::Header& header,
                                             const KeyframeSubset& partition,
                                             const std::string& database_id);
// Checks: finite numbers, inliers <= matches, the score agreeing with them,
// partition < num_partitions, a known scheme.
QueryResult PartialFromMessage(const placedb_msgs::PartialResult& message);

// The voter's answer: the merged result with the answer's pose from the
// keyframe table `keyframes` (looked up by id).
placedb_msgs::Answer AnswerToMessage(const FrameAnswer& answer, const PlaceDatabase& keyframes,
                                     const std_msgs::Header& header);

}  // namespace placedb
