#include "placedb/eval/ground_truth.h"

#include <fmt/format.h>

#include <algorithm>

#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

GroundTruth GroundTruth::FromMatchList(MatchTruth truth) {
  GroundTruth g;
  for (auto& [query, ids] : truth) std::sort(ids.begin(), ids.end());
  g.list_ = std::move(truth);
  return g;
}

GroundTruth GroundTruth::FromPoses(const PoseThresholds& thresholds) {
  PLACEDB_CHECK_OPTIONS(thresholds);
  GroundTruth g;
  g.thresholds_ = thresholds;
  return g;
}

bool GroundTruth::HasTruth(const Frame& query) const {
  if (list_) return list_->count(query.id) > 0;
  return query.pose.has_value();
}

bool GroundTruth::IsCorrect(const Frame& query, const Keyframe& keyframe) const {
  if (list_) {
    const auto it = list_->find(query.id);
    return it != list_->end() &&
           std::binary_search(it->second.begin(), it->second.end(), keyframe.id);
  }
  if (!query.pose || !keyframe.pose) return false;
  return TranslationDistance(*query.pose, *keyframe.pose) <= thresholds_.max_distance_m &&
         RotationAngleDeg(*query.pose, *keyframe.pose) <= thresholds_.max_angle_deg;
}

bool GroundTruth::AnyCorrectIn(const Frame& query, const std::vector<Keyframe>& keyframes) const {
  for (const Keyframe& k : keyframes) {
    if (IsCorrect(query, k)) return true;
  }
  return false;
}

bool GroundTruth::CanJudgeAny(const std::vector<Keyframe>& keyframes) const {
  if (!list_) {
    return std::any_of(keyframes.begin(), keyframes.end(),
                       [](const Keyframe& k) { return k.pose.has_value(); });
  }
  std::vector<int32_t> ids;
  for (const Keyframe& k : keyframes) ids.push_back(k.id);
  std::sort(ids.begin(), ids.end());
  for (const auto& [query, truth_ids] : *list_) {
    for (const int id : truth_ids) {
      if (std::binary_search(ids.begin(), ids.end(), id)) return true;
    }
  }
  return false;
}

std::vector<int> GroundTruth::IdsAbove(int max_id) const {
  std::vector<int> out;
  if (!list_) return out;
  for (const auto& [query, ids] : *list_) {
    if (query > max_id) out.push_back(query);
    for (const int id : ids) {
      if (id > max_id) out.push_back(id);
    }
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::string GroundTruth::Describe() const {
  if (list_) return "match list";
  return fmt::format("poses ({} m, {} deg)", thresholds_.max_distance_m, thresholds_.max_angle_deg);
}

GroundTruth MakeGroundTruth(const GroundTruthOptions& options, const FrameSourceOptions& queries) {
  PLACEDB_CHECK_OPTIONS(options);
  if (!options.truth.empty()) return GroundTruth::FromMatchList(ReadMatchTruth(options.truth));
  if (!queries.images.empty()) {
    PLACEDB_THROW_INVALID("query frames from `images` need a `truth` CSV of true matches (or use "
                          "`tum`, whose frames have poses)");
  }
  return GroundTruth::FromPoses(options.poses);
}

}  // namespace placedb
