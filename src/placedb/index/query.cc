#include "placedb/index/query.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <unordered_set>

#include "placedb/util/check.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/options.h"
#include "placedb/util/thread_pool.h"
#include "placedb/util/timer.h"

namespace placedb {
namespace fs = std::filesystem;

std::string QueryOptions::Check() const {
  return FirstReason(
      {CheckRange("top_k", top_k, 1, 10000), CheckRange("min_matches", min_matches, 1, 100000),
       Nested("retrieval", retrieval.Check()), Nested("match", match.Check()),
       Nested("verify", verify.Check()), CheckRange("min_score", min_score, 0.0, 100000.0)});
}

QueryOptions QueryOptions::ForPartition() const {
  QueryOptions o = *this;
  if (verify.enabled) o.top_k = std::max(top_k, verify.num_candidates);
  return o;
}

bool RankedKeyframe::operator==(const RankedKeyframe& o) const {
  const bool same_pose = pose.has_value() == o.pose.has_value() &&
                         (!pose || (pose->translation == o.pose->translation &&
                                    pose->rotation.coeffs() == o.pose->rotation.coeffs()));
  return keyframe_id == o.keyframe_id && score == o.score && num_matches == o.num_matches &&
         num_inliers == o.num_inliers && same_pose && timestamp == o.timestamp &&
         source == o.source && stored_image == o.stored_image;
}

// ---- JSON -------------------------------------------------------------------
namespace {

nlohmann::json PoseToJson(const std::optional<Pose>& pose) {
  if (!pose) return nullptr;
  const auto& t = pose->translation;
  const auto& q = pose->rotation;
  return {{"translation", {t.x(), t.y(), t.z()}},
          {"quaternion_xyzw", {q.x(), q.y(), q.z(), q.w()}}};
}

std::optional<Pose> PoseFromJson(const JsonReader& parent, const char* key) {
  if (parent.Member(key).is_null()) return std::nullopt;
  const JsonReader j = parent.Child(key);
  auto vec = [&](const char* name, size_t n) {
    const nlohmann::json& a = j.Member(name);
    if (!a.is_array() || a.size() != n)
      j.Fail(name, "is not an array of " + std::to_string(n) + " numbers");
    std::vector<double> v;
    for (const auto& x : a) {
      if (!x.is_number() || !std::isfinite(x.get<double>()))
        j.Fail(name, "holds a value that is not a finite number");
      v.push_back(x.get<double>());
    }
    return v;
  };
  const std::vector<double> t = vec("translation", 3);
  const std::vector<double> q = vec("quaternion_xyzw", 4);
  Pose pose;
  pose.translation = Eigen::Vector3d(t[0], t[1], t[2]);
  pose.rotation = Eigen::Quaterniond(q[3], q[0], q[1], q[2]);
  if (std::abs(pose.rotation.norm() - 1.0) > 1e-3)
    j.Fail("quaternion_xyzw", "is not a unit quaternion");
  return pose;
}

RankedKeyframe RankedFromJson(const JsonReader& j) {
  RankedKeyframe r;
  r.keyframe_id = static_cast<int32_t>(j.Integer("keyframe_id", INT32_MIN, INT32_MAX));
  r.score = j.Number("score");
  r.num_matches = static_cast<int>(j.Integer("num_matches", 0, INT32_MAX));
  r.num_inliers = static_cast<int>(j.Integer("num_inliers", -1, INT32_MAX));
  r.pose = PoseFromJson(j, "pose");
  r.timestamp = j.Number("timestamp");
  r.source = j.String("source");
  r.stored_image = j.String("stored_image");
  if (r.num_inliers > r.num_matches) j.Fail("num_inliers", "exceeds num_matches");
  return r;
}

}  // namespace

void to_json(nlohmann::json& j, const RankedKeyframe& r) {
  j = {
      {"keyframe_id", r.keyframe_id}, {"score", r.score},         {"num_matches", r.num_matches},
      {"num_inliers", r.num_inliers}, {"verified", r.verified()}, {"pose", PoseToJson(r.pose)},
      {"timestamp", r.timestamp},     {"source", r.source},       {"stored_image", r.stored_image}};
}

void from_json(const nlohmann::json& j, RankedKeyframe& r) {
  r = RankedFromJson(JsonReader(j, "ranked keyframe"));
}

void to_json(nlohmann::json& j, const QueryResult& r) {
  j = nlohmann::json::object();
  j["matched"] = r.matched;
  j["best"] = r.best() ? nlohmann::json(*r.best()) : nlohmann::json(nullptr);
  j["ranked"] = r.ranked;
  j["num_query_features"] = r.num_query_features;
  j["num_keyframes"] = r.num_keyframes;
  j["num_examined"] = r.num_examined;
  j["num_verified"] = r.num_verified;
  j["times_ms"] = {{"extract", r.times.extract_ms},
                   {"retrieve", r.times.retrieve_ms},
                   {"match", r.times.match_ms},
                   {"verify", r.times.verify_ms},
                   {"total", r.times.total_ms}};
}

void from_json(const nlohmann::json& json, QueryResult& out) {
  const JsonReader j(json, "query result");
  QueryResult r;
  r.matched = j.Boolean("matched");
  const nlohmann::json& ranked = j.Member("ranked");
  if (!ranked.is_array()) j.Fail("ranked", "is not an array");
  for (size_t i = 0; i < ranked.size(); ++i) {
    r.ranked.push_back(
        RankedFromJson(JsonReader(ranked[i], j.where() + ".ranked[" + std::to_string(i) + "]")));
  }
  if (r.matched && r.ranked.empty()) j.Fail("matched", "is true but nothing is ranked");
  r.num_query_features = static_cast<int>(j.Integer("num_query_features", 0, INT32_MAX));
  r.num_keyframes = static_cast<size_t>(j.Integer("num_keyframes", 0, INT64_MAX));
  r.num_examined = static_cast<size_t>(j.Integer("num_examined", 0, INT64_MAX));
  r.num_verified = static_cast<size_t>(j.Integer("num_verified", 0, INT64_MAX));
  const JsonReader t = j.Child("times_ms");
  r.times.extract_ms = t.Number("extract");
  r.times.retrieve_ms = t.Number("retrieve");
  r.times.match_ms = t.Number("match");
  r.times.verify_ms = t.Number("verify");
  r.times.total_ms = t.Number("total");
  out = std::move(r);
}

// ---- the pipeline -------------------------------------------------------------
void ValidateQueryFeatures(const FeatureSet& features, const Database& db) {
  if (features.type != db.feature_type()) {
    PLACEDB_THROW_INVALID("the query has ", FeatureTypeName(features.type),
                          " features but the database holds ", FeatureTypeName(db.feature_type()),
                          " features");
  }
  const cv::Mat& d = features.descriptors;
  if (static_cast<size_t>(d.rows) != features.keypoints.size()) {
    PLACEDB_THROW_INVALID("the query has ", features.keypoints.size(), " keypoints but ", d.rows,
                          " descriptor rows");
  }
  if (features.keypoints.empty()) return;
  const int expected_depth = db.feature_type() == FeatureType::kOrb ? CV_8U : CV_32F;
  if (d.depth() != expected_depth || d.channels() != 1) {
    PLACEDB_THROW_INVALID("query descriptors must be single-channel ",
                          expected_depth == CV_8U ? "CV_8U" : "CV_32F", " for ",
                          FeatureTypeName(db.feature_type()), " features");
  }
  const int row_bytes = static_cast<int>(d.cols * d.elemSize());
  if (row_bytes != db.descriptor_bytes()) {
    PLACEDB_THROW_INVALID("query descriptors have ", row_bytes, " bytes per row, the database's ",
                          db.descriptor_bytes());
  }
  if (!d.isContinuous()) PLACEDB_THROW_INVALID("query descriptors must be stored contiguously");
  for (size_t i = 0; i < features.keypoints.size(); ++i) {
    const cv::Point2f& p = features.keypoints[i].pt;
    if (!std::isfinite(p.x) || !std::isfinite(p.y))
      PLACEDB_THROW_INVALID("query keypoint ", i, " has a non-finite position");
  }
}

namespace {

// One examined keyframe: its index and matches (kept only while it may be
// verified).
struct Examined {
  uint32_t index = 0;
  int32_t id = 0;
  int num_matches = 0;
  std::vector<cv::DMatch> matches;
};

// Match-stage order: more matches first, then the lower id.
bool MoreMatches(int32_t id_a, int a, int32_t id_b, int b) { return a != b ? a > b : id_a < id_b; }

// Final order: verified ones by inliers, then matches, then id; unverified by
// matches, then id.
bool RanksFirst(const RankedKeyframe& a, const RankedKeyframe& b) {
  if (a.score != b.score) return a.score > b.score;
  return MoreMatches(a.keyframe_id, a.num_matches, b.keyframe_id, b.num_matches);
}

void KeepBest(std::vector<Examined>* list, size_t keep) {
  auto order = [](const Examined& a, const Examined& b) {
    return MoreMatches(a.id, a.num_matches, b.id, b.num_matches);
  };
  if (list->size() > keep) {
    std::nth_element(list->begin(), list->begin() + static_cast<ptrdiff_t>(keep), list->end(),
                     order);
    list->resize(keep);
  }
  std::sort(list->begin(), list->end(), order);
}

void Decide(QueryResult* r, const QueryOptions& options) {
  r->matched = !r->ranked.empty() && r->ranked.front().score >= options.min_score;
}

// How many of the match stage's best keyframes go on.
size_t KeptAfterMatching(const QueryOptions& options) {
  return static_cast<size_t>(options.verify.enabled ? options.verify.num_candidates
                                                    : options.top_k);
}

}  // namespace

QueryResult QueryDatabase(const Database& db, const FeatureSet& query, const QueryOptions& options,
                          const QueryContext& context) {
  PLACEDB_CHECK_OPTIONS(options);
  ValidateQueryFeatures(query, db);
  PLACEDB_CHECK(db.has_features(), "the database was opened as a keyframe table, without features");
  Timer total;
  QueryResult result;
  result.num_query_features = static_cast<int>(query.size());
  std::vector<uint32_t> among;
  if (context.among != nullptr) {
    among = *context.among;
    std::sort(among.begin(), among.end());
    among.erase(std::unique(among.begin(), among.end()), among.end());
    if (!among.empty() && among.back() >= db.size()) {
      PLACEDB_THROW_INVALID("keyframe index ", among.back(), " is out of range (the database has ",
                            db.size(), " keyframes)");
    }
  }
  result.num_keyframes = context.among ? among.size() : db.size();

  // Retrieve.
  Timer stage;
  std::unique_ptr<Retriever> own_retriever;
  const Retriever* retriever = context.retriever;
  if (retriever == nullptr) {
    own_retriever = Retriever::Create(options.retrieval, db);
    retriever = own_retriever.get();
  }
  const std::vector<Candidate> candidates =
      retriever->Retrieve(db, query, context.among ? &among : nullptr);
  result.times.retrieve_ms = stage.ElapsedMs();
  result.num_examined = candidates.size();

  // Match: contiguous chunks of the candidates, each keeping its best; the
  // merged best do not depend on the chunking.
  stage.Restart();
  // SURF: the query's rows grouped by Laplacian sign, like the database's.
  const GroupedFeatures grouped = GroupByLaplacian(query);
  const DescriptorBlock& block = grouped.block;
  const size_t keep = KeptAfterMatching(options);
  const bool need_matches = options.verify.enabled;
  const size_t n = candidates.size();
  const size_t chunks =
      context.pool == nullptr
          ? 1
          : std::max<size_t>(1, std::min(n, static_cast<size_t>(context.pool->size())));
  std::vector<std::vector<Examined>> partial(chunks);
  auto match_chunk = [&](size_t c) {
    std::vector<Examined>& out = partial[c];
    std::vector<cv::DMatch> matches;
    for (size_t i = n * c / chunks; i < n * (c + 1) / chunks; ++i) {
      const uint32_t index = candidates[i].index;
      matches.clear();
      const int good = MatchDescriptors(block, db.Descriptors(index), options.match,
                                        need_matches ? &matches : nullptr);
      if (good < options.min_matches) continue;
      out.push_back(
          {index, db.keyframe(index).id, good, need_matches ? matches : std::vector<cv::DMatch>()});
      if (out.size() > 2 * keep + 64) KeepBest(&out, keep);  // bounded memory
    }
    KeepBest(&out, keep);
  };
  if (chunks == 1) {
    match_chunk(0);
  } else {
    context.pool->ParallelFor(chunks, match_chunk);
  }
  std::vector<Examined> best;
  for (auto& p : partial) {
    for (auto& e : p) best.push_back(std::move(e));
  }
  KeepBest(&best, keep);
  result.times.match_ms = stage.ElapsedMs();

  // Verify.
  stage.Restart();
  std::vector<RankedKeyframe> ranked(best.size());
  auto fill = [&](size_t i) {
    const Examined& e = best[i];
    const Keyframe& k = db.keyframe(e.index);
    RankedKeyframe& r = ranked[i];
    r.keyframe_id = k.id;
    r.num_matches = e.num_matches;
    r.score = e.num_matches;
    r.pose = k.pose;
    r.timestamp = k.timestamp;
    r.source = k.source;
    if (!k.image_file.empty()) {
      r.stored_image = context.image_dir.empty()
                           ? k.image_file
                           : (fs::path(context.image_dir) / k.image_file).string();
    }
    if (!options.verify.enabled) return;
    const Span<cv::KeyPoint> keypoints = db.Keypoints(e.index);
    std::vector<cv::Point2f> q, t;
    q.reserve(e.matches.size());
    t.reserve(e.matches.size());
    for (const cv::DMatch& m : e.matches) {
      q.push_back(grouped.set.keypoints[m.queryIdx].pt);
      t.push_back(k.ToOriginal(keypoints[m.trainIdx].pt));
    }
    r.num_inliers = VerifyMatches(q, t, options.verify).num_inliers;
    r.score = r.num_inliers;
  };
  if (context.pool == nullptr || ranked.size() <= 1) {
    for (size_t i = 0; i < ranked.size(); ++i) fill(i);
  } else {
    context.pool->ParallelFor(ranked.size(), fill);
  }
  if (options.verify.enabled) result.num_verified = ranked.size();
  result.times.verify_ms = options.verify.enabled ? stage.ElapsedMs() : 0.0;

  // Rank and decide.
  std::sort(ranked.begin(), ranked.end(), RanksFirst);
  if (ranked.size() > static_cast<size_t>(options.top_k)) ranked.resize(options.top_k);
  result.ranked = std::move(ranked);
  Decide(&result, options);
  result.times.total_ms = total.ElapsedMs();
  return result;
}

QueryResult MergeQueryResults(const std::vector<QueryResult>& parts, const QueryOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  QueryResult merged;
  std::vector<RankedKeyframe> all;
  std::unordered_set<int32_t> seen;
  for (const QueryResult& p : parts) {
    merged.num_query_features = std::max(merged.num_query_features, p.num_query_features);
    merged.num_keyframes += p.num_keyframes;
    merged.num_examined += p.num_examined;
    merged.num_verified += p.num_verified;
    merged.times.extract_ms = std::max(merged.times.extract_ms, p.times.extract_ms);
    merged.times.retrieve_ms = std::max(merged.times.retrieve_ms, p.times.retrieve_ms);
    merged.times.match_ms = std::max(merged.times.match_ms, p.times.match_ms);
    merged.times.verify_ms = std::max(merged.times.verify_ms, p.times.verify_ms);
    merged.times.total_ms = std::max(merged.times.total_ms, p.times.total_ms);
    for (const RankedKeyframe& r : p.ranked) {
      if (!seen.insert(r.keyframe_id).second) {
        PLACEDB_THROW_INVALID("keyframe ", r.keyframe_id,
                              " is in two partial results (partitions must be disjoint)");
      }
      if (r.verified() != options.verify.enabled) {
        PLACEDB_THROW_INVALID("keyframe ", r.keyframe_id, " is ",
                              r.verified() ? "verified" : "not verified", " but the merge options ",
                              options.verify.enabled ? "" : "do not ", "verify");
      }
      all.push_back(r);
    }
  }
  // The whole database's match-stage survivors are the best of the parts'
  // (each part kept its own best, which include all of the global best).
  const size_t keep = KeptAfterMatching(options);
  auto more_matches = [](const RankedKeyframe& a, const RankedKeyframe& b) {
    return MoreMatches(a.keyframe_id, a.num_matches, b.keyframe_id, b.num_matches);
  };
  std::sort(all.begin(), all.end(), more_matches);
  if (all.size() > keep) all.resize(keep);
  std::sort(all.begin(), all.end(), RanksFirst);
  if (all.size() > static_cast<size_t>(options.top_k)) all.resize(options.top_k);
  merged.ranked = std::move(all);
  Decide(&merged, options);
  return merged;
}

}  // namespace placedb
