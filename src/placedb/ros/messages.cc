#include "placedb/ros/messages.h"

#include <cmath>
#include <cstring>
#include <limits>

namespace placedb {
namespace {

// A message from the wire that is not what it should be: the sender's input.
// The message starts with the cause, what a node's DropLog counts drops by.
[[noreturn]] void Bad(const std::string& cause, const std::string& what) {
  throw InvalidArgument(cause + ": " + what);
}

placedb_msgs::RankedKeyframe RankedToMessage(const RankedKeyframe& k) {
  placedb_msgs::RankedKeyframe m;
  m.keyframe_id = k.keyframe_id;
  m.score = k.score;
  m.num_matches = k.num_matches;
  m.num_inliers = k.num_inliers;
  const double absent = std::numeric_limits<double>::quiet_NaN();
  m.whole_image = k.whole_image.value_or(absent);
  m.whole_image_z = k.whole_image_z.value_or(absent);
  return m;
}

// The split a message names: partition < num_partitions <= 4096 and a known
// scheme.
void CheckSplit(uint32_t partition, uint32_t num_partitions, const std::string& scheme) {
  if (num_partitions < 1 || num_partitions > 4096 || partition >= num_partitions)
    Bad("partition", std::to_string(partition) + " of " + std::to_string(num_partitions));
  if (scheme != "contiguous" && scheme != "interleaved")
    Bad("scheme", "'" + scheme.substr(0, 16) + "'");
}

std::vector<placedb_msgs::ShortlistEntry> EntriesToMessage(const std::vector<ShortlistEntry>& in) {
  std::vector<placedb_msgs::ShortlistEntry> out(in.size());
  for (size_t i = 0; i < in.size(); ++i) {
    out[i].index = in[i].index;
    out[i].keyframe_id = in[i].keyframe_id;
    out[i].score = in[i].score;
    out[i].guided = in[i].guided;
  }
  return out;
}

std::vector<ShortlistEntry> EntriesFromMessage(const std::vector<placedb_msgs::ShortlistEntry>& in,
                                               const char* what) {
  if (in.size() > 100000) Bad(what, "more than 100000 keyframes");
  std::vector<ShortlistEntry> out(in.size());
  for (size_t i = 0; i < in.size(); ++i) {
    if (!std::isfinite(in[i].score) || in[i].guided < -1)
      Bad(what, "impossible values for keyframe " + std::to_string(in[i].keyframe_id));
    out[i] = {in[i].index, in[i].keyframe_id, in[i].score, in[i].guided};
  }
  return out;
}

// What a worker's message starts with: the frame, the database it serves
// and its partition (0 of 1 for the whole database).
template <typename Message>
void SetWorkerFields(Message* m, const std_msgs::Header& header, uint64_t frame_seq,
                     const KeyframeSubset& partition, const std::string& database_id) {
  const bool part = partition.kind == KeyframeSubset::Kind::kPartition;
  m->header = header;
  m->frame_seq = frame_seq;
  m->database_id = database_id;
  m->partition = static_cast<uint32_t>(part ? partition.part : 0);
  m->num_partitions = static_cast<uint32_t>(part ? partition.num_parts : 1);
  m->scheme = PartitionSchemeName(partition.scheme);
}

}  // namespace

placedb_msgs::Features FeaturesToMessage(const FeatureSet& f, uint64_t frame_seq,
                                         const std_msgs::Header& header) {
  placedb_msgs::Features m;
  m.header = header;
  m.frame_seq = frame_seq;
  m.feature_type = FeatureTypeName(f.type);
  m.descriptor_bytes =
      static_cast<uint32_t>(f.type == FeatureType::kOrb ? 32 : f.descriptors.cols * 4);
  if (f.empty() && f.type == FeatureType::kSurf)
    m.descriptor_bytes = static_cast<uint32_t>(f.descriptors.cols * 4);
  m.keypoints.reserve(f.keypoints.size() * 7);
  for (const cv::KeyPoint& k : f.keypoints) {
    m.keypoints.insert(m.keypoints.end(),
                       {k.pt.x, k.pt.y, k.size, k.angle, k.response, static_cast<float>(k.octave),
                        static_cast<float>(k.class_id)});
  }
  if (!f.empty()) {
    if (!f.descriptors.isContinuous()) {
      throw InvalidArgument("the descriptors must be one contiguous matrix");
    }
    const auto* data = f.descriptors.ptr<uint8_t>();
    m.descriptors.assign(data, data + f.descriptors.total() * f.descriptors.elemSize());
  }
  if (!f.whole_image.empty()) {
    if (f.whole_image.type() != CV_8SC1 || f.whole_image.rows != 1 || !f.whole_image.isContinuous())
      throw InvalidArgument("the whole-image row must be one contiguous 1 x N int8 row");
    const auto* w = f.whole_image.ptr<int8_t>();
    m.whole_image.assign(w, w + f.whole_image.cols);
  }
  return m;
}

FeatureSet FeaturesFromMessage(const placedb_msgs::Features& m) {
  FeatureSet f;
  try {
    f.type = ParseFeatureType(m.feature_type);
  } catch (const InvalidArgument&) {
    Bad("feature type", "'" + m.feature_type.substr(0, 16) + "' is not orb or surf");
  }
  const bool orb = f.type == FeatureType::kOrb;
  if (orb ? m.descriptor_bytes != 32 : (m.descriptor_bytes != 256 && m.descriptor_bytes != 512))
    Bad("descriptor width",
        std::to_string(m.descriptor_bytes) + " bytes do not fit " + m.feature_type);
  if (m.keypoints.size() % 7 != 0) Bad("keypoints", "not 7 values per keypoint");
  const size_t rows = m.keypoints.size() / 7;
  if (rows > 1000000) Bad("keypoints", "more than 1000000");
  if (m.descriptors.size() != rows * m.descriptor_bytes)
    Bad("descriptors",
        std::to_string(m.descriptors.size()) + " bytes for " + std::to_string(rows) + " keypoints");
  f.keypoints.resize(rows);
  for (size_t i = 0; i < rows; ++i) {
    const float* v = &m.keypoints[7 * i];
    for (int j = 0; j < 7; ++j) {
      if (!std::isfinite(v[j])) Bad("keypoints", "a value is not finite");
    }
    if (v[5] != std::round(v[5]) || std::abs(v[5]) > 1e6 || v[6] != std::round(v[6]) ||
        std::abs(v[6]) > 1e9) {
      Bad("keypoints", "octave and class_id must be whole numbers");
    }
    f.keypoints[i] =
        cv::KeyPoint(v[0], v[1], v[2], v[3], v[4], static_cast<int>(v[5]), static_cast<int>(v[6]));
  }
  if (orb) {
    f.descriptors = cv::Mat(static_cast<int>(rows), 32, CV_8U);
  } else {
    f.descriptors =
        cv::Mat(static_cast<int>(rows), static_cast<int>(m.descriptor_bytes / 4), CV_32F);
  }
  if (rows > 0) std::memcpy(f.descriptors.data, m.descriptors.data(), m.descriptors.size());
  if (!orb) {
    for (size_t i = 0; i < f.descriptors.total(); ++i) {
      if (!std::isfinite(reinterpret_cast<const float*>(f.descriptors.data)[i]))
        Bad("descriptors", "a value is not finite");
    }
  }
  // Its size against the database's and its values are the query's checks
  // (ValidateQueryFeatures); here only what a matrix can hold.
  if (m.whole_image.size() > 65536) Bad("whole image", "more than 65536 values");
  if (!m.whole_image.empty()) {
    f.whole_image = cv::Mat(1, static_cast<int>(m.whole_image.size()), CV_8SC1);
    std::memcpy(f.whole_image.data, m.whole_image.data(), m.whole_image.size());
  }
  return f;
}

placedb_msgs::PartialResult PartialToMessage(const QueryResult& r, uint64_t frame_seq,
                                             const std_msgs::Header& header,
                                             const KeyframeSubset& partition,
                                             const std::string& database_id) {
  placedb_msgs::PartialResult m;
  SetWorkerFields(&m, header, frame_seq, partition, database_id);
  for (const RankedKeyframe& k : r.ranked) m.ranked.push_back(RankedToMessage(k));
  m.num_query_features = r.num_query_features;
  m.num_keyframes = r.num_keyframes;
  m.num_examined = r.num_examined;
  m.num_verified = r.num_verified;
  m.extract_ms = r.times.extract_ms;
  m.retrieve_ms = r.times.retrieve_ms;
  m.match_ms = r.times.match_ms;
  m.verify_ms = r.times.verify_ms;
  m.total_ms = r.times.total_ms;
  return m;
}

QueryResult PartialFromMessage(const placedb_msgs::PartialResult& m) {
  CheckSplit(m.partition, m.num_partitions, m.scheme);
  if (m.ranked.size() > 10000) Bad("ranked", "more than 10000 keyframes");
  QueryResult r;
  for (const auto& k : m.ranked) {
    if (!std::isfinite(k.score) || k.num_matches < 0 || k.num_inliers < -1 ||
        k.num_inliers > k.num_matches)
      Bad("ranked keyframe", "impossible counts for keyframe " + std::to_string(k.keyframe_id));
    const bool whole = !std::isnan(k.whole_image);
    if (whole != !std::isnan(k.whole_image_z) || (whole && (k.whole_image < -1.0 ||
                                                            k.whole_image > 1.0 ||
                                                            !std::isfinite(k.whole_image_z))))
      Bad("ranked keyframe", "bad whole-image values for keyframe " + std::to_string(k.keyframe_id));
    // The counts, plus the whole-image bonus (which the voter checks against
    // its options: VoteCollector::OnPartial).
    const double counted = k.num_inliers >= 0 ? k.num_inliers : k.num_matches;
    if (whole ? !(k.score >= counted) : k.score != counted)
      Bad("ranked keyframe", "score disagrees with the counts");
    RankedKeyframe out;
    out.keyframe_id = k.keyframe_id;
    out.score = k.score;
    out.num_matches = k.num_matches;
    out.num_inliers = k.num_inliers;
    if (whole) {
      out.whole_image = k.whole_image;
      out.whole_image_z = k.whole_image_z;
    }
    r.ranked.push_back(out);
  }
  for (const double t : {m.extract_ms, m.retrieve_ms, m.match_ms, m.verify_ms, m.total_ms}) {
    if (!std::isfinite(t) || t < 0) Bad("times", "not finite and >= 0");
  }
  if (m.num_query_features < 0) Bad("counts", "negative query features");
  r.num_query_features = m.num_query_features;
  r.num_keyframes = m.num_keyframes;
  r.num_examined = m.num_examined;
  r.num_verified = m.num_verified;
  r.times.extract_ms = m.extract_ms;
  r.times.retrieve_ms = m.retrieve_ms;
  r.times.match_ms = m.match_ms;
  r.times.verify_ms = m.verify_ms;
  r.times.total_ms = m.total_ms;
  return r;
}

placedb_msgs::Shortlist ShortlistToMessage(const Shortlist& s, uint64_t frame_seq,
                                           const std_msgs::Header& header,
                                           const KeyframeSubset& partition,
                                           const std::string& database_id) {
  placedb_msgs::Shortlist m;
  SetWorkerFields(&m, header, frame_seq, partition, database_id);
  m.bow = EntriesToMessage(s.bow);
  m.whole_image = EntriesToMessage(s.whole_image);
  m.deadline_reached = s.deadline_reached;
  m.retrieve_ms = s.retrieve_ms;
  return m;
}

Shortlist ShortlistFromMessage(const placedb_msgs::Shortlist& m) {
  CheckSplit(m.partition, m.num_partitions, m.scheme);
  if (!std::isfinite(m.retrieve_ms) || m.retrieve_ms < 0) Bad("times", "not finite and >= 0");
  Shortlist s;
  s.bow = EntriesFromMessage(m.bow, "shortlist");
  s.whole_image = EntriesFromMessage(m.whole_image, "shortlist");
  s.deadline_reached = m.deadline_reached;
  s.retrieve_ms = m.retrieve_ms;
  return s;
}

placedb_msgs::Candidates CandidatesToMessage(const FrameCandidates& c,
                                             const std_msgs::Header& header, int num_partitions,
                                             PartitionScheme scheme,
                                             const std::string& database_id) {
  placedb_msgs::Candidates m;
  m.header = header;
  m.frame_seq = c.frame_seq;
  m.database_id = database_id;
  m.num_partitions = static_cast<uint32_t>(num_partitions);
  m.scheme = PartitionSchemeName(scheme);
  for (const int p : c.merged) m.partitions.push_back(static_cast<uint32_t>(p));
  m.candidates = EntriesToMessage(c.candidates);
  return m;
}

FrameCandidates CandidatesFromMessage(const placedb_msgs::Candidates& m) {
  CheckSplit(0, m.num_partitions, m.scheme);
  FrameCandidates c;
  c.frame_seq = m.frame_seq;
  for (size_t i = 0; i < m.partitions.size(); ++i) {
    if (m.partitions[i] >= m.num_partitions || (i > 0 && m.partitions[i - 1] >= m.partitions[i]))
      Bad("partition",
          "the merged partitions must be ascending and below " + std::to_string(m.num_partitions));
    c.merged.push_back(static_cast<int>(m.partitions[i]));
  }
  c.candidates = EntriesFromMessage(m.candidates, "candidates");
  return c;
}

placedb_msgs::Answer AnswerToMessage(const FrameAnswer& a, const PlaceDatabase& keyframes,
                                     const std_msgs::Header& header) {
  placedb_msgs::Answer m;
  m.header = header;
  m.frame_seq = a.frame_seq;
  m.run_id = a.run;
  m.matched = a.result.matched;
  m.keyframe_id = -1;
  if (const RankedKeyframe* best = a.result.best()) {
    m.keyframe_id = best->keyframe_id;
    m.score = best->score;
    m.num_matches = best->num_matches;
    m.num_inliers = best->num_inliers;
    const std::optional<Keyframe> k = keyframes.FindKeyframe(best->keyframe_id);
    if (k && k->pose) {
      const Pose& p = *k->pose;
      m.has_pose = true;
      m.pose.position.x = p.translation.x();
      m.pose.position.y = p.translation.y();
      m.pose.position.z = p.translation.z();
      m.pose.orientation.x = p.rotation.x();
      m.pose.orientation.y = p.rotation.y();
      m.pose.orientation.z = p.rotation.z();
      m.pose.orientation.w = p.rotation.w();
    }
  }
  if (!m.has_pose) m.pose.orientation.w = 1.0;
  for (const RankedKeyframe& k : a.result.ranked) m.ranked.push_back(RankedToMessage(k));
  for (const int p : a.answered) m.partitions_answered.push_back(static_cast<uint32_t>(p));
  for (const int p : a.missing) m.partitions_missing.push_back(static_cast<uint32_t>(p));
  m.complete = a.complete();
  m.wait_ms = a.waited_ms;
  return m;
}

}  // namespace placedb
