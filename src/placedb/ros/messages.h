// placedb's values to and from its ROS messages (placedb_msgs). Every
// message from the wire is validated: a bad one throws InvalidArgument whose
// message starts with its cause, for the nodes to log once per cause.
#pragma once

#include <placedb_msgs/Answer.h>
#include <placedb_msgs/Candidates.h>
#include <placedb_msgs/Features.h>
#include <placedb_msgs/PartialResult.h>
#include <placedb_msgs/Shortlist.h>

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

// Two rounds of bag-of-words search (distributed/vote_collector.h): a
// worker's shortlist, and the voter's candidates for every worker.
placedb_msgs::Shortlist ShortlistToMessage(const Shortlist& shortlist, uint64_t frame_seq,
                                           const std_msgs::Header& header,
                                           const KeyframeSubset& partition,
                                           const std::string& database_id);
// Checks: partition < num_partitions, a known scheme, at most 100000
// entries a list, finite scores, guided >= -1, a finite time >= 0.
Shortlist ShortlistFromMessage(const placedb_msgs::Shortlist& message);
placedb_msgs::Candidates CandidatesToMessage(const FrameCandidates& candidates,
                                             const std_msgs::Header& header, int num_partitions,
                                             PartitionScheme scheme,
                                             const std::string& database_id);
// Checks: num_partitions in [1, 4096], a known scheme, partitions ascending
// and below num_partitions, at most 100000 candidates, each as a shortlist's.
// (Whether they are the database's keyframes is BowPartitionWorker's check.)
FrameCandidates CandidatesFromMessage(const placedb_msgs::Candidates& message);

// The voter's answer: the merged result with the answer's pose from the
// keyframe table `keyframes` (looked up by id).
placedb_msgs::Answer AnswerToMessage(const FrameAnswer& answer, const PlaceDatabase& keyframes,
                                     const std_msgs::Header& header);

}  // namespace placedb
