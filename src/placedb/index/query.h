// Answers a query frame: match its descriptors against keyframes (all of
// them, exhaustively), rank keyframes by good matches, return the top k with
// the best keyframe's pose and the time taken.
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "placedb/feature/extractor.h"
#include "placedb/index/database.h"
#include "placedb/index/ranking.h"
#include "placedb/match/ratio_matcher.h"

namespace placedb {

class ThreadPool;

struct QueryOptions {
  // Length of the ranked list returned. Default 5.
  int top_k = 5;
  // Ratio test and SURF sign rejection.
  MatchOptions match;
  // Keyframes with fewer good matches are not ranked. Default 1.
  int min_matches = 1;

  std::string Check() const;
};

struct QueryResult {
  // Best first; only keyframes with at least min_matches good matches.
  std::vector<ScoredKeyframe> ranked;
  int num_query_features = 0;
  double extract_ms = 0.0;  // feature extraction of the query image
  double match_ms = 0.0;    // matching and ranking
  double total_ms = 0.0;

  bool found() const { return !ranked.empty(); }
};

// Ranks the keyframes with indices [begin, end) of `db` for the query's
// descriptors: the partial top-k of one partition.
std::vector<ScoredKeyframe> RankPartition(const Database& db, const DescriptorBlock& query,
                                          size_t begin, size_t end, const QueryOptions& options);

// Matches already-extracted query features against the whole database. With
// a pool of N threads, the keyframes are split into N partitions whose
// partial lists are merged by MergeRankedLists: the same answer as one
// thread. Throws std::invalid_argument for features of another type than
// the database's.
QueryResult QueryFeatures(const Database& db, const FeatureSet& query, const QueryOptions& options,
                          ThreadPool* pool = nullptr);

// Extracts the query image's features with `extractor` (which must produce
// the database's feature type) and matches them.
QueryResult QueryImage(const Database& db, const FeatureExtractor& extractor, const cv::Mat& image,
                       const QueryOptions& options, ThreadPool* pool = nullptr);

}  // namespace placedb
