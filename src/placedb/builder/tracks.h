// Which of a keyframe's features a database keeps under a feature budget
// (BuildOptions::stored_features, track_neighbours): those matched in the
// neighbouring keyframes first, as a SLAM system keeps the map points seen
// from more than one keyframe. A feature that another view of the same
// place also found is one a later visit is likely to find again; a feature
// no other view found (noise, a highlight, a corner of motion blur) spends
// the budget on nothing.
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "placedb/feature/types.h"
#include "placedb/util/pose.h"

namespace placedb {

// For each of n keyframes (poses[i]: keyframe i's, in build order), the
// indices of its `count` neighbours: the nearest by camera position when
// every keyframe has a pose (ties: the lower index), else the nearest in
// build order (i - 1, i + 1, i - 2, ...). Fewer when there are fewer other
// keyframes. Each list is ascending by distance.
std::vector<std::vector<size_t>> TrackNeighbours(const std::vector<std::optional<Pose>>& poses,
                                                 size_t count);

// The `count` neighbours of a keyframe added after the keyframes of
// `poses` (online mapping): the nearest by position when it and every one of
// them have a pose (ties: the lower index), else the last `count`, the
// nearest in order. Ascending by distance.
std::vector<size_t> TrackNeighboursOfNew(const std::vector<std::optional<Pose>>& poses,
                                         const std::optional<Pose>& pose, size_t count);

// For each feature of `features`, in how many of `neighbours` it has a
// match (MatchDescriptors with the default MatchOptions: mutual nearest
// neighbours passing the ratio test and the distance limit).
std::vector<int> TrackCounts(const FeatureSet& features,
                             const std::vector<const FeatureSet*>& neighbours);

}  // namespace placedb
