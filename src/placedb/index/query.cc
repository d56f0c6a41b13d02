#include "placedb/index/query.h"

#include <algorithm>

#include "placedb/util/check.h"
#include "placedb/util/thread_pool.h"
#include "placedb/util/timer.h"

namespace placedb {

std::string QueryOptions::Check() const {
  if (top_k < 1) return "top_k must be >= 1";
  if (min_matches < 1) return "min_matches must be >= 1";
  return match.Check();
}

std::vector<ScoredKeyframe> RankPartition(const Database& db, const DescriptorBlock& query,
                                          size_t begin, size_t end, const QueryOptions& options) {
  std::vector<ScoredKeyframe> scored;
  scored.reserve(end - begin);
  for (size_t i = begin; i < end; ++i) {
    const int good = CountRatioMatches(query, db.Descriptors(i), options.match);
    if (good >= options.min_matches)
      scored.push_back({db.keyframe(i).id, static_cast<double>(good)});
  }
  return TopK(std::move(scored), options.top_k);
}

QueryResult QueryFeatures(const Database& db, const FeatureSet& query, const QueryOptions& options,
                          ThreadPool* pool) {
  PLACEDB_CHECK_OPTIONS(options);
  if (query.type != db.feature_type()) {
    PLACEDB_THROW_INVALID("the query has ", FeatureTypeName(query.type),
                          " features but the database holds ", FeatureTypeName(db.feature_type()),
                          " features");
  }
  Timer timer;
  QueryResult result;
  result.num_query_features = static_cast<int>(query.size());
  std::vector<int8_t> laplacian;
  const DescriptorBlock block = MakeDescriptorBlock(query, &laplacian);
  if (block.rows > 0 && block.row_bytes != db.descriptor_bytes()) {
    PLACEDB_THROW_INVALID("query descriptors have ", block.row_bytes,
                          " bytes per row, the database's ", db.descriptor_bytes());
  }
  const size_t n = db.size();
  const size_t parts = pool == nullptr ? 1 : std::min(n, static_cast<size_t>(pool->size()));
  if (parts <= 1) {
    result.ranked = RankPartition(db, block, 0, n, options);
  } else {
    std::vector<std::vector<ScoredKeyframe>> partial(parts);
    pool->ParallelFor(parts, [&](size_t p) {
      partial[p] = RankPartition(db, block, n * p / parts, n * (p + 1) / parts, options);
    });
    result.ranked = MergeRankedLists(partial, options.top_k);
  }
  result.match_ms = timer.ElapsedMs();
  result.total_ms = result.match_ms;
  return result;
}

QueryResult QueryImage(const Database& db, const FeatureExtractor& extractor, const cv::Mat& image,
                       const QueryOptions& options, ThreadPool* pool) {
  PLACEDB_CHECK(!image.empty(), "the query image is empty");
  Timer timer;
  const FeatureSet features = extractor.Extract(image);
  const double extract_ms = timer.ElapsedMs();
  QueryResult result = QueryFeatures(db, features, options, pool);
  result.extract_ms = extract_ms;
  result.total_ms = timer.ElapsedMs();
  return result;
}

}  // namespace placedb
