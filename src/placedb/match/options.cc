// The option tables of the match and verify stages (util/option_table.h).
#include "placedb/match/options.h"
#include "placedb/util/check.h"
#include "placedb/util/option_table.h"

namespace placedb {

const OptionTable<MatchOptions>& MatchOptions::Table() {
  static const OptionTable<MatchOptions> table = [] {
    using O = MatchOptions;
    OptionTable<O> t("match options");
    t.Number("ratio", PLACEDB_MEMBER(O, ratio), OptionRange::LeftOpen(0, 1),
             "Lowe's ratio test threshold");
    t.Number("max_hamming", PLACEDB_MEMBER(O, max_hamming), OptionRange::Closed(0, 256),
             "ORB: largest Hamming distance of a match (0: no limit)");
    t.Number("max_l2", PLACEDB_MEMBER(O, max_l2), OptionRange::Closed(0, 2),
             "SURF: largest L2 distance of a match (0: no limit)");
    t.Bool("laplacian_sign", PLACEDB_MEMBER(O, use_laplacian_sign),
           "SURF: never match opposite Laplacian signs");
    t.Bool("one_to_one", PLACEDB_MEMBER(O, one_to_one),
           "a keyframe descriptor keeps only its closest query match");
    t.Bool("cross_check", PLACEDB_MEMBER(O, cross_check),
           "sparse-keyframe guard: matches must be mutual and pass the ratio test among the "
           "query's descriptors too");
    return t;
  }();
  return table;
}

std::string MatchOptions::Check() const { return Table().Check(*this); }

const OptionTable<VerifyOptions>& VerifyOptions::Table() {
  static const OptionTable<VerifyOptions> table = [] {
    using O = VerifyOptions;
    OptionTable<O> t("verification options");
    t.Bool("verify", PLACEDB_MEMBER(O, enabled),
           "verify stage: RANSAC (USAC) on the best candidates, inliers are the score",
           BoolFlag::kNegatable);
    t.Choice("verify_model", PLACEDB_MEMBER(O, model),
             {GeometricModel::kFundamental, GeometricModel::kHomography}, ParseGeometricModel,
             GeometricModelName, "the geometric model RANSAC fits");
    t.Number("verify_candidates", PLACEDB_MEMBER(O, num_candidates), OptionRange::Closed(1, 1000),
             "keyframes verified (the best by matches)");
    t.Number("verify_error", PLACEDB_MEMBER(O, max_error_px), OptionRange::LeftOpen(0, 100),
             "largest inlier error, px of the query image");
    // OpenCV's USAC needs a confidence below 1.
    t.Number("verify_confidence", PLACEDB_MEMBER(O, confidence),
             OptionRange::Closed(0.5, 0.999999), "RANSAC confidence");
    t.Number("verify_iterations", PLACEDB_MEMBER(O, max_iterations),
             OptionRange::Closed(1, 100000), "RANSAC iterations at most");
    t.Number("verify_seed", PLACEDB_MEMBER(O, seed), OptionRange::RightOpen(0, 2147483648.0),
             "RANSAC seed");
    return t;
  }();
  return table;
}

std::string VerifyOptions::Check() const { return Table().Check(*this); }

}  // namespace placedb
