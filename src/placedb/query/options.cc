// The option tables of a query: the prior and every stage's options
// (util/option_table.h).
#include <cmath>

#include "placedb/query/result.h"
#include "placedb/util/check.h"
#include "placedb/util/option_table.h"

namespace placedb {

const OptionTable<QueryPrior>& QueryPrior::Table() {
  static const OptionTable<QueryPrior> table = [] {
    using O = QueryPrior;
    OptionTable<O> t("query prior");
    t.Number("prior_keyframe", PLACEDB_MEMBER(O, keyframe_id),
             OptionRange::RightOpen(0, 2147483648.0),
             "cluster: id of a keyframe near the query (e.g. the last answer); 0: none");
    OptionField pose;
    pose.name = "prior_pose";
    pose.member = "pose";
    pose.kind = OptionKind::kNumbers;
    pose.help =
        "cluster: where the robot probably is, in the map frame: x,y,z,qx,qy,qz,qw (the "
        "quaternion is normalised); none by default (`prior_keyframe` wins when both are set)";
    pose.range = "7 finite numbers, a quaternion that is not zero";
    t.Custom(
        &O::pose, pose,
        [](const O& o) -> OptionValue {
          if (!o.pose) return std::vector<double>();
          const Eigen::Vector3d& p = o.pose->translation;
          const Eigen::Quaterniond& q = o.pose->rotation;
          return std::vector<double>{p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w()};
        },
        [](O& o, const OptionValue& v) {
          const std::vector<double> n = option_table_internal::ToNumbers(v, "prior_pose");
          if (n.empty()) {
            o.pose.reset();
            return;
          }
          if (n.size() != 7) {
            PLACEDB_THROW_INVALID("`prior_pose` takes 7 numbers, x,y,z,qx,qy,qz,qw (got ",
                                  n.size(), ")");
          }
          const Eigen::Quaterniond q(n[6], n[3], n[4], n[5]);
          const double norm = q.norm();
          if (!std::isfinite(norm) || !(norm > 1e-12)) {
            PLACEDB_THROW_INVALID("`prior_pose`'s quaternion must be finite and not zero");
          }
          Pose pose;
          pose.translation = Eigen::Vector3d(n[0], n[1], n[2]);
          pose.rotation = q.normalized();
          o.pose = pose;
        },
        [](const O& o) -> std::string {
          if (o.pose && (!o.pose->translation.allFinite() || !o.pose->rotation.coeffs().allFinite()))
            return "`prior_pose` is not finite";
          return "";
        });
    return t;
  }();
  return table;
}

std::string QueryPrior::Check() const { return Table().Check(*this); }

const OptionTable<QueryOptions>& QueryOptions::Table() {
  static const OptionTable<QueryOptions> table = [] {
    using O = QueryOptions;
    OptionTable<O> t("query options");
    constexpr unsigned kQuery = kCallers;  // options of a call, never stored
    t.Number("top_k", PLACEDB_MEMBER(O, top_k), OptionRange::Closed(1, 10000),
             "length of the ranked list", kQuery);
    t.Nest(PLACEDB_MEMBER(O, retrieval), RetrievalOptions::Table(), kQuery);
    t.Number("deadline_ms", PLACEDB_MEMBER(O, deadline_ms), OptionRange::Closed(0, 1e7),
             "time budget of retrieve + match + verify, ms; candidates are examined best first "
             "until it runs out (0: none)",
             kQuery);
    t.Nest(PLACEDB_MEMBER(O, prior), QueryPrior::Table(), kQuery);
    t.Nest(PLACEDB_MEMBER(O, match), MatchOptions::Table(), kQuery);
    t.Number("min_matches", PLACEDB_MEMBER(O, min_matches), OptionRange::Closed(1, 100000),
             "fewest matches for a keyframe to be ranked (or a positive whole-image bonus)",
             kQuery);
    t.Nest(PLACEDB_MEMBER(O, verify), VerifyOptions::Table(), kQuery);
    t.Number("whole_image_weight", PLACEDB_MEMBER(O, whole_image_weight),
             OptionRange::Closed(0, 10000),
             "whole-image channel: a keyframe's score adds this times its whole-image similarity's "
             "deviations from the map's mean above `whole_image_floor` to its inliers (or "
             "matches); 0: the channel does not score",
             kQuery);
    t.Number("whole_image_floor", PLACEDB_MEMBER(O, whole_image_floor), OptionRange::Closed(0, 100),
             "whole-image channel: standardised similarity (deviations above the map's mean) "
             "below which a keyframe gains nothing",
             kQuery);
    t.Number("whole_image_candidates", PLACEDB_MEMBER(O, whole_image_candidates),
             OptionRange::Closed(0, 1000),
             "whole-image channel: bow and cluster search also match the keyframes this many most "
             "similar by whole-image descriptor",
             kQuery);
    t.Number("min_score", PLACEDB_MEMBER(O, min_score), OptionRange::Closed(0, 100000),
             "decide stage: the best keyframe is the answer when its score (inliers when "
             "verified, else matches) is at least this; else 'no match'",
             kQuery);
    return t;
  }();
  return table;
}

std::string QueryOptions::Check() const { return Table().Check(*this); }

}  // namespace placedb
