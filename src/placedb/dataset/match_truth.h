// Ground-truth match lists (which database images show the same place as a
// query), as data/rtabmap_loop/ground_truth.csv.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace placedb {

// Query id -> sorted true keyframe ids (may be empty: a query with no true match).
using MatchTruth = std::map<int, std::vector<int>>;

// Reads "query_id,id id id" lines ('#' comments and blank lines skipped); the
// ids after the first comma are separated by spaces and/or commas; "41," is a
// query with no true match. Ids are positive integers. Malformed lines
// (missing comma, non-numeric or non-positive id, duplicate query id, an id
// repeated within a line) → InvalidArgument naming the file and line.
// Missing file → NotFound; unreadable → IoError.
MatchTruth ReadMatchTruth(const std::string& path);

}  // namespace placedb
