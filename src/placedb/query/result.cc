// A query's answer: equality and its JSON.
#include <cmath>
#include <nlohmann/json.hpp>

#include "placedb/query/query.h"
#include "placedb/util/check.h"
#include "placedb/util/json_reader.h"

namespace placedb {

bool RankedKeyframe::operator==(const RankedKeyframe& o) const {
  const bool same_pose = pose.has_value() == o.pose.has_value() &&
                         (!pose || (pose->translation == o.pose->translation &&
                                    pose->rotation.coeffs() == o.pose->rotation.coeffs()));
  return keyframe_id == o.keyframe_id && score == o.score && num_matches == o.num_matches &&
         num_inliers == o.num_inliers && same_pose && timestamp == o.timestamp &&
         source == o.source && stored_image == o.stored_image && whole_image == o.whole_image &&
         whole_image_z == o.whole_image_z;
}

bool SequenceEvidence::operator==(const SequenceEvidence& o) const {
  return keyframe_id == o.keyframe_id && score == o.score && frames == o.frames &&
         velocity == o.velocity && frame_keyframe_id == o.frame_keyframe_id &&
         frame_score == o.frame_score && frame_matched == o.frame_matched;
}

bool ShortlistEntry::operator==(const ShortlistEntry& o) const {
  return index == o.index && keyframe_id == o.keyframe_id && score == o.score && guided == o.guided;
}

double QueryResult::decision_score() const {
  if (decided_by == "sequence" && sequence) return sequence->score;
  return ranked.empty() ? 0.0 : ranked.front().score;
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
  // Absent in results of earlier versions; null without the channel.
  if (j.Has("whole_image") && !j.Member("whole_image").is_null()) {
    const double w = j.Number("whole_image");
    if (w < -1.0 || w > 1.0) j.Fail("whole_image", "is not in [-1, 1]");
    r.whole_image = w;
  }
  if (j.Has("whole_image_z") && !j.Member("whole_image_z").is_null()) {
    if (!r.whole_image) j.Fail("whole_image_z", "is given without whole_image");
    r.whole_image_z = j.Number("whole_image_z");
  }
  return r;
}

}  // namespace

void to_json(nlohmann::json& j, const RankedKeyframe& r) {
  j = {{"keyframe_id", r.keyframe_id},
       {"score", r.score},
       {"num_matches", r.num_matches},
       {"num_inliers", r.num_inliers},
       {"verified", r.verified()},
       {"pose", PoseToJson(r.pose)},
       {"timestamp", r.timestamp},
       {"source", r.source},
       {"stored_image", r.stored_image},
       {"whole_image", r.whole_image ? nlohmann::json(*r.whole_image) : nlohmann::json(nullptr)},
       {"whole_image_z",
        r.whole_image_z ? nlohmann::json(*r.whole_image_z) : nlohmann::json(nullptr)}};
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
  j["coverage"] = r.coverage;
  j["deadline_reached"] = r.deadline_reached;
  j["search"] = r.search;
  j["cluster"] = r.cluster;
  j["decided_by"] = r.decided_by;
  if (r.sequence) {
    const SequenceEvidence& s = *r.sequence;
    j["sequence"] = {{"keyframe_id", s.keyframe_id},
                     {"score", s.score},
                     {"frames", s.frames},
                     {"velocity", s.velocity},
                     {"frame_keyframe_id", s.frame_keyframe_id},
                     {"frame_score", s.frame_score},
                     {"frame_matched", s.frame_matched}};
  } else {
    j["sequence"] = nullptr;
  }
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
  r.coverage = j.Number("coverage");
  if (r.coverage < 0.0 || r.coverage > 1.0) j.Fail("coverage", "is not in [0, 1]");
  r.deadline_reached = j.Boolean("deadline_reached");
  r.search = j.String("search");
  r.cluster = static_cast<int>(j.Integer("cluster", -1, INT32_MAX));
  // Results of workers and of earlier versions carry no sequence part.
  if (j.Has("decided_by")) {
    r.decided_by = j.String("decided_by");
    if (r.decided_by != "frame" && r.decided_by != "sequence")
      j.Fail("decided_by", "is neither \"frame\" nor \"sequence\"");
  }
  if (j.Has("sequence") && !j.Member("sequence").is_null()) {
    const JsonReader s = j.Child("sequence");
    SequenceEvidence e;
    e.keyframe_id = static_cast<int32_t>(s.Integer("keyframe_id", 0, INT32_MAX));
    e.score = s.Number("score");
    e.frames = static_cast<int>(s.Integer("frames", 0, 100));
    e.velocity = s.Number("velocity");
    e.frame_keyframe_id = static_cast<int32_t>(s.Integer("frame_keyframe_id", 0, INT32_MAX));
    e.frame_score = s.Number("frame_score");
    e.frame_matched = s.Boolean("frame_matched");
    r.sequence = e;
  }
  if (r.decided_by == "sequence" && !r.sequence)
    j.Fail("decided_by", "is \"sequence\" but there is no sequence part");
  if (r.decided_by == "sequence" &&
      (r.ranked.empty() || r.ranked.front().keyframe_id != r.sequence->keyframe_id))
    j.Fail("decided_by", "is \"sequence\" but the path's end is not ranked first");
  const JsonReader t = j.Child("times_ms");
  r.times.extract_ms = t.Number("extract");
  r.times.retrieve_ms = t.Number("retrieve");
  r.times.match_ms = t.Number("match");
  r.times.verify_ms = t.Number("verify");
  r.times.total_ms = t.Number("total");
  out = std::move(r);
}

void to_json(nlohmann::json& j, const Shortlist& s) {
  const auto entries = [](const std::vector<ShortlistEntry>& list) {
    nlohmann::json a = nlohmann::json::array();
    for (const ShortlistEntry& e : list) a.push_back({e.index, e.keyframe_id, e.score, e.guided});
    return a;
  };
  j = {{"bow", entries(s.bow)},
       {"whole_image", entries(s.whole_image)},
       {"deadline_reached", s.deadline_reached},
       {"retrieve_ms", s.retrieve_ms}};
}

void from_json(const nlohmann::json& json, Shortlist& out) {
  const JsonReader j(json, "shortlist");
  Shortlist s;
  const auto entries = [&](const char* key, std::vector<ShortlistEntry>* list) {
    const nlohmann::json& a = j.Member(key);
    if (!a.is_array()) j.Fail(key, "is not an array");
    for (size_t i = 0; i < a.size(); ++i) {
      const nlohmann::json& e = a[i];
      const std::string where = std::string(key) + "[" + std::to_string(i) + "]";
      if (!e.is_array() || e.size() != 4 || !e[0].is_number_unsigned() ||
          !e[1].is_number_integer() || !e[2].is_number() || !e[3].is_number_integer()) {
        j.Fail(where.c_str(), "is not [index, keyframe_id, score, guided]");
      }
      ShortlistEntry x;
      const uint64_t index = e[0].get<uint64_t>();
      const int64_t id = e[1].get<int64_t>(), guided = e[3].get<int64_t>();
      x.score = e[2].get<double>();
      if (index > UINT32_MAX || id < INT32_MIN || id > INT32_MAX || guided < -1 ||
          guided > INT32_MAX || !std::isfinite(x.score)) {
        j.Fail(where.c_str(), "has a value out of range");
      }
      x.index = static_cast<uint32_t>(index);
      x.keyframe_id = static_cast<int32_t>(id);
      x.guided = static_cast<int>(guided);
      list->push_back(x);
    }
  };
  entries("bow", &s.bow);
  entries("whole_image", &s.whole_image);
  s.deadline_reached = j.Boolean("deadline_reached");
  s.retrieve_ms = j.Number("retrieve_ms");
  out = std::move(s);
}

std::string QueryResultToJson(const QueryResult& result, int indent) {
  return DumpJson(nlohmann::json(result), indent);
}

std::string RankedKeyframeToJson(const RankedKeyframe& keyframe, int indent) {
  return DumpJson(nlohmann::json(keyframe), indent);
}

std::string ShortlistToJson(const Shortlist& shortlist, int indent) {
  return DumpJson(nlohmann::json(shortlist), indent);
}

namespace {

// A result or shortlist received over the wire: its ranked list is bounded
// by top_k, so a few MiB at most.
constexpr size_t kMaxResultJsonBytes = size_t{64} << 20;

// `json` parsed as a T (`what` names it in the error for text that is not JSON).
template <typename T>
T ParseJsonText(const std::string& json, const char* what) {
  return ParseJson(json, std::string("a ") + what, JsonOrigin::kCaller, kMaxResultJsonBytes)
      .get<T>();
}

}  // namespace

Shortlist ShortlistFromJson(const std::string& json) {
  return ParseJsonText<Shortlist>(json, "shortlist");
}

QueryResult QueryResultFromJson(const std::string& json) {
  return ParseJsonText<QueryResult>(json, "query result");
}

}  // namespace placedb
