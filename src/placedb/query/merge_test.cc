// The match stage, the ranking and the voting merge checked against
// independent oracles: nothing here calls MatchDescriptors or re-runs the
// merge's own algorithm to compute what is expected.
//
//  - Match stage: OpenCV's cv::BFMatcher gives every descriptor's two nearest
//    neighbours (both directions); the rules of ratio_matcher.h are applied
//    to those lists here.
//  - Ranking: every keyframe's oracle count, fully sorted.
//  - Merge: the whole list's answer by its definition, each candidate's place
//    decided by counting how many others beat it (no sort, no truncation).
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <numeric>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "placedb/feature/extractor.h"
#include "placedb/feature/testing.h"
#include "placedb/query/query.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
using testing_util::RtabmapImage;

constexpr int kFirstKeyframe = 1, kLastKeyframe = 40;  // the database
constexpr int kFirstQuery = 41, kLastQuery = 84;       // the revisits
// The queries the BFMatcher oracle runs on: every other one (42, 44, ... 84,
// image 46, which has no features, among them): the brute force over all 44
// takes twice as long, and in mutation runs of the matcher it caught no
// mutation that these 22 missed.
constexpr int kOracleQueryStep = 2;
constexpr int kNumOracleQueries = 22;

// Both directions' two nearest neighbours of one (query, keyframe) pair, as
// cv::BFMatcher::knnMatch reports them (nearest first; fewer than two when
// the other side has fewer rows).
struct PairKnn {
  std::vector<std::vector<cv::DMatch>> forward;   // per query row, in the keyframe
  std::vector<std::vector<cv::DMatch>> backward;  // per keyframe row, in the query
};

// ORB features of images 1..84 extracted once, a database of 1..40 built
// from them (the pattern of query_test.cc's QueryTest), and the BFMatcher
// neighbour lists of every (oracle query, keyframe) pair, which do not depend
// on the match options and so serve every option set below.
class QueryOracleTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto extractor = FeatureExtractor::Create(testing::ModelFreeExtractorOptions());
    features_ = new std::map<int, FeatureSet>();
    db_ = new Database(FeatureType::kOrb, 32);
    for (int i = kFirstKeyframe; i <= kLastQuery; ++i) {
      const cv::Mat image = cv::imread(RtabmapImage(i));
      ASSERT_FALSE(image.empty()) << RtabmapImage(i);
      (*features_)[i] = extractor->Extract(image);
      if (i <= kLastKeyframe) {
        Keyframe k;
        k.id = i;
        k.original_size = image.size();
        k.crop = cv::Rect(0, 0, image.cols, image.rows);
        k.stored_size = image.size();
        k.source = RtabmapImage(i);
        db_->AddKeyframe(k, (*features_)[i]);
      }
    }
    knn_ = new std::map<std::pair<int, int>, PairKnn>();
    cv::BFMatcher bf(cv::NORM_HAMMING);
    for (int q = kFirstQuery + 1; q <= kLastQuery; q += kOracleQueryStep) {
      for (int k = kFirstKeyframe; k <= kLastKeyframe; ++k) {
        PairKnn& knn = (*knn_)[{q, k}];
        const cv::Mat& a = Features(q).descriptors;
        const cv::Mat& b = Features(k).descriptors;
        // knnMatch of an empty side is no neighbours at all (image 46 has
        // no ORB features).
        if (a.empty() || b.empty()) continue;
        bf.knnMatch(a, b, knn.forward, 2);
        bf.knnMatch(b, a, knn.backward, 2);
      }
    }
  }
  static void TearDownTestSuite() {
    delete knn_;
    delete db_;
    delete features_;
  }
  static const FeatureSet& Features(int i) { return features_->at(i); }
  static const PairKnn& Knn(int query, int keyframe) { return knn_->at({query, keyframe}); }

  static std::map<int, FeatureSet>* features_;
  static Database* db_;
  static std::map<std::pair<int, int>, PairKnn>* knn_;
};
std::map<int, FeatureSet>* QueryOracleTest::features_ = nullptr;
Database* QueryOracleTest::db_ = nullptr;
std::map<std::pair<int, int>, PairKnn>* QueryOracleTest::knn_ = nullptr;

// Rule 1 of ratio_matcher.h on one row's neighbour list: the nearest is within
// the absolute limit (max_hamming, "at most", 0 = none) and passes Lowe's test
// "nearest < ratio x second-nearest", strictly. Equal nearest distances
// (d0 == d1) therefore never pass, whatever the ratio in (0, 1]: which of two
// tied rows BFMatcher lists first cannot change the outcome. With a single
// candidate there is no second neighbour to fail against (ratio_matcher.cc:
// it always passes).
bool PassesRatioAndLimit(const std::vector<cv::DMatch>& nearest, const MatchOptions& o) {
  if (nearest.empty()) return false;
  const double d0 = nearest[0].distance;
  if (o.max_hamming > 0 && d0 > o.max_hamming) return false;
  if (nearest.size() == 1) return true;
  return d0 < o.ratio * static_cast<double>(nearest[1].distance);
}

// The matches ratio_matcher.h documents, from BFMatcher's neighbour lists, in
// query order. Written per query row and per keyframe row rather than as the
// matcher's sort / unique / remove pipeline:
//  - the cross-check first: q's nearest t must have q as its own nearest
//    (passing the test among the query's rows). At most one q per t can be
//    that nearest, so with the cross-check the one-to-one rule has nothing
//    left to remove; the order of the two rules does not matter.
//  - one-to-one: per t, the closest q (equal distance: the lower q) of those
//    that chose t.
std::vector<cv::DMatch> OracleMatches(const PairKnn& knn, const MatchOptions& o) {
  std::vector<cv::DMatch> chosen;
  for (size_t q = 0; q < knn.forward.size(); ++q) {
    if (!PassesRatioAndLimit(knn.forward[q], o)) continue;
    const cv::DMatch& m = knn.forward[q][0];
    if (o.cross_check) {
      const std::vector<cv::DMatch>& back = knn.backward.at(m.trainIdx);
      if (!PassesRatioAndLimit(back, o) || back[0].trainIdx != static_cast<int>(q)) continue;
    }
    chosen.push_back(m);
  }
  if (!o.one_to_one) return chosen;
  // The winner for each keyframe row: query rows arrive in ascending order,
  // so only a strictly closer one replaces the current winner.
  std::map<int, cv::DMatch> winner;
  for (const cv::DMatch& m : chosen) {
    const auto it = winner.find(m.trainIdx);
    if (it == winner.end() || m.distance < it->second.distance) winner[m.trainIdx] = m;
  }
  std::vector<cv::DMatch> kept;
  for (const auto& [t, m] : winner) kept.push_back(m);
  std::sort(kept.begin(), kept.end(),
            [](const cv::DMatch& a, const cv::DMatch& b) { return a.queryIdx < b.queryIdx; });
  return kept;
}

// Option sets that each exercise a different rule of the match stage.
struct NamedOptions {
  std::string name;
  MatchOptions match;
};
std::vector<NamedOptions> MatchOptionSets() {
  std::vector<NamedOptions> sets;
  sets.push_back({"defaults", MatchOptions()});
  MatchOptions one_to_one_only;  // ties of the one-to-one rule decide, not the cross-check
  one_to_one_only.cross_check = false;
  sets.push_back({"one-to-one without cross-check", one_to_one_only});
  MatchOptions plain;  // Lowe's test alone, no distance limit
  plain.cross_check = false;
  plain.one_to_one = false;
  plain.max_hamming = 0;
  sets.push_back({"plain ratio test", plain});
  MatchOptions tight;  // a limit and ratio that sit on many distances exactly
  tight.ratio = 0.75;
  tight.max_hamming = 40;
  sets.push_back({"ratio 0.75, max_hamming 40", tight});
  MatchOptions ratio_one;  // only a strictly nearer nearest passes
  ratio_one.ratio = 1.0;
  ratio_one.cross_check = false;
  ratio_one.max_hamming = 80;
  sets.push_back({"ratio 1, no cross-check", ratio_one});
  return sets;
}

std::string Describe(const cv::DMatch& m) {
  return "(" + std::to_string(m.queryIdx) + " -> " + std::to_string(m.trainIdx) + ", " +
         std::to_string(static_cast<int>(m.distance)) + ")";
}

// MatchKeyframe's matches (what the verify stage receives) are exactly the
// oracle's, pair by pair, for every query and keyframe and every option set:
// the ratio test's strict inequality, the limit's "at most", the one-to-one
// winner (and its tie-break on the lower query index) and the cross-check.
TEST_F(QueryOracleTest, MatchStageEqualsBfMatcherWithTheDocumentedRules) {
  size_t pairs = 0, matches = 0;
  for (const NamedOptions& set : MatchOptionSets()) {
    QueryOptions options;
    options.match = set.match;
    options.verify.enabled = false;
    for (int q = kFirstQuery + 1; q <= kLastQuery; q += kOracleQueryStep) {
      for (size_t i = 0; i < db_->size(); ++i) {
        const int id = db_->keyframe(i).id;
        const std::vector<cv::DMatch> expected = OracleMatches(Knn(q, id), set.match);
        const std::vector<cv::DMatch> got = MatchKeyframe(*db_, Features(q), i, options).matches;
        ASSERT_EQ(got.size(), expected.size()) << set.name << ": query " << q << " keyframe " << id;
        for (size_t j = 0; j < got.size(); ++j) {
          ASSERT_TRUE(got[j].queryIdx == expected[j].queryIdx &&
                      got[j].trainIdx == expected[j].trainIdx &&
                      got[j].distance == expected[j].distance)
              << set.name << ": query " << q << " keyframe " << id << " match " << j << ": got "
              << Describe(got[j]) << ", expected " << Describe(expected[j]);
        }
        ++pairs;
        matches += got.size();
      }
    }
  }
  EXPECT_EQ(pairs, MatchOptionSets().size() * kNumOracleQueries * 40);
  EXPECT_GT(matches, 0u);
}

// Unverified, QueryDatabase's ranked list is every keyframe with at least
// min_matches oracle matches, fully sorted by (matches desc, id asc); a
// shorter top k is that list's prefix.
TEST_F(QueryOracleTest, UnverifiedRankingEqualsFullSortOfOracleCounts) {
  size_t ties = 0;  // neighbours in the expected list with equal counts
  for (const NamedOptions& set : MatchOptionSets()) {
    for (const int min_matches : {1, 8}) {
      QueryOptions options;
      options.match = set.match;
      options.verify.enabled = false;
      options.min_matches = min_matches;
      for (int q = kFirstQuery + 1; q <= kLastQuery; q += kOracleQueryStep) {
        struct Counted {
          int32_t id;
          int count;
        };
        std::vector<Counted> expected;
        for (int id = kFirstKeyframe; id <= kLastKeyframe; ++id) {
          const int count = static_cast<int>(OracleMatches(Knn(q, id), set.match).size());
          if (count >= min_matches) expected.push_back({id, count});
        }
        std::sort(expected.begin(), expected.end(), [](const Counted& a, const Counted& b) {
          return a.count != b.count ? a.count > b.count : a.id < b.id;
        });
        for (size_t i = 1; i < expected.size(); ++i)
          ties += expected[i].count == expected[i - 1].count;
        for (const int top_k : {40, 3}) {
          options.top_k = top_k;
          const QueryResult r = QueryDatabase(*db_, Features(q), options);
          const size_t n = std::min<size_t>(top_k, expected.size());
          const std::string where = set.name + ", min_matches " + std::to_string(min_matches) +
                                    ", top " + std::to_string(top_k) + ": query " +
                                    std::to_string(q);
          ASSERT_EQ(r.ranked.size(), n) << where;
          for (size_t i = 0; i < n; ++i) {
            const RankedKeyframe& k = r.ranked[i];
            ASSERT_TRUE(k.keyframe_id == expected[i].id && k.num_matches == expected[i].count)
                << where << " #" << i << ": got {" << k.keyframe_id << ": " << k.num_matches
                << "}, expected {" << expected[i].id << ": " << expected[i].count << "}";
            EXPECT_FALSE(k.verified()) << where;
            EXPECT_EQ(k.score, k.num_matches) << where;
          }
          EXPECT_EQ(r.num_examined, 40u) << where;
        }
      }
    }
  }
  EXPECT_GT(ties, 0u);  // the tie-break on the id was exercised
}

// ---- the merge ------------------------------------------------------------------

// A ranked list for failure messages: {id: matches, inliers, score} each.
std::string Describe(const std::vector<RankedKeyframe>& list) {
  std::string s = "[";
  for (const RankedKeyframe& k : list) {
    s += " {" + std::to_string(k.keyframe_id) + ": " + std::to_string(k.num_matches) + " m, " +
         std::to_string(k.num_inliers) + " i, score " + std::to_string(k.score) + "}";
  }
  return s + " ]";
}

// The documented orders as "a beats b": the match stage's (more matches, then
// the lower id) and the final one (higher score, then the match stage's).
bool BeatsByMatches(const RankedKeyframe& a, const RankedKeyframe& b) {
  if (a.num_matches != b.num_matches) return a.num_matches > b.num_matches;
  return a.keyframe_id < b.keyframe_id;
}
bool BeatsByScore(const RankedKeyframe& a, const RankedKeyframe& b) {
  if (a.score != b.score) return a.score > b.score;
  return BeatsByMatches(a, b);
}

// The answer a list of examined keyframes defines (query.h): the keep best by
// matches survive the match stage (keep = num_candidates when verifying, else
// top_k), they are ranked by score, the first top_k are the ranked list, and
// the query matched when the best score reaches min_score. Each candidate's
// place is the number of candidates that beat it; the places of the
// survivors must be a permutation (the orders are strict), which is checked.
QueryResult DefinedAnswer(const std::vector<RankedKeyframe>& all, const QueryOptions& o) {
  const size_t keep = static_cast<size_t>(o.verify.enabled ? o.verify.num_candidates : o.top_k);
  std::vector<RankedKeyframe> survivors;
  for (const RankedKeyframe& a : all) {
    const auto beaten_by = std::count_if(
        all.begin(), all.end(), [&](const RankedKeyframe& b) { return BeatsByMatches(b, a); });
    if (static_cast<size_t>(beaten_by) < keep) survivors.push_back(a);
  }
  std::vector<std::optional<RankedKeyframe>> places(
      std::min(survivors.size(), static_cast<size_t>(o.top_k)));
  for (const RankedKeyframe& a : survivors) {
    const size_t place = static_cast<size_t>(
        std::count_if(survivors.begin(), survivors.end(),
                      [&](const RankedKeyframe& b) { return BeatsByScore(b, a); }));
    if (place >= places.size()) continue;
    EXPECT_FALSE(places[place].has_value()) << "two candidates at place " << place;
    places[place] = a;
  }
  QueryResult r;
  for (const auto& p : places) {
    EXPECT_TRUE(p.has_value());
    if (p) r.ranked.push_back(*p);
  }
  r.matched = !r.ranked.empty() && r.ranked[0].score >= o.min_score;
  return r;
}

// Random synthetic partial results: each part reports what the definition
// gives for its own keyframes under ForPartition(); the merge must give what
// the definition gives for all of them. Matches and inliers are drawn from
// small ranges (many ties, min_score often equal to the best score), ids are
// shuffled, parts may be empty, num_candidates may be below top_k.
TEST(MergeOracleTest, RandomPartialResultsMergeIntoTheDefinedWholeAnswer) {
  int verified_runs = 0, matched_runs = 0, empty_parts = 0;
  for (uint32_t seed = 1; seed <= 2000; ++seed) {
    std::mt19937 rng(seed);
    auto uniform = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
    const int n = uniform(0, 50);
    const int parts = uniform(1, 7);
    QueryOptions options;
    options.verify.enabled = seed % 3 != 0;
    options.top_k = uniform(1, 8);
    options.verify.num_candidates = uniform(1, 12);
    options.min_score = uniform(0, 8);
    const int most_matches = seed % 2 ? 5 : 40;
    // Distinct ids in random order, so that id order and list order differ.
    std::vector<int32_t> ids(static_cast<size_t>(3 * n + 5));
    std::iota(ids.begin(), ids.end(), 1);
    std::shuffle(ids.begin(), ids.end(), rng);
    std::vector<RankedKeyframe> all;
    std::vector<std::vector<RankedKeyframe>> by_part(static_cast<size_t>(parts));
    for (int i = 0; i < n; ++i) {
      RankedKeyframe k;
      k.keyframe_id = ids[static_cast<size_t>(i)];
      k.num_matches = uniform(1, most_matches);
      k.num_inliers = options.verify.enabled ? uniform(0, k.num_matches) : -1;
      k.score = options.verify.enabled ? k.num_inliers : k.num_matches;
      k.source = "frame " + std::to_string(k.keyframe_id);
      all.push_back(k);
      by_part[static_cast<size_t>(uniform(0, parts - 1))].push_back(k);
    }
    std::vector<QueryResult> partial;
    for (const std::vector<RankedKeyframe>& p : by_part) {
      partial.push_back(DefinedAnswer(p, options.ForPartition()));
      partial.back().num_keyframes = p.size();
      partial.back().num_examined = p.size();
      empty_parts += p.empty();
    }
    const QueryResult expected = DefinedAnswer(all, options);
    const QueryResult merged = MergeQueryResults(partial, options);
    // (RankedKeyframe has no printer: the lists are described by hand.)
    ASSERT_TRUE(merged.ranked == expected.ranked)
        << "merged " << Describe(merged.ranked) << ", expected " << Describe(expected.ranked)
        << ", seed " << seed << " (n " << n << ", parts " << parts << ", verify "
        << options.verify.enabled << ", top_k " << options.top_k << ", num_candidates "
        << options.verify.num_candidates << ")";
    ASSERT_EQ(merged.matched, expected.matched) << "seed " << seed;
    ASSERT_EQ(merged.num_keyframes, static_cast<size_t>(n)) << "seed " << seed;
    ASSERT_EQ(merged.num_examined, static_cast<size_t>(n)) << "seed " << seed;
    verified_runs += options.verify.enabled;
    matched_runs += expected.matched;
  }
  // Every kind of case was drawn.
  EXPECT_GT(verified_runs, 0);
  EXPECT_LT(verified_runs, 2000);
  EXPECT_GT(matched_runs, 0);
  EXPECT_LT(matched_runs, 2000);
  EXPECT_GT(empty_parts, 0);
}

// The real pipeline: QueryDatabase on the whole loop database equals the
// merge of QueryDatabase on random disjoint restrictions (2 to 7 parts of
// random sizes and interleaving; every fifth run leaves one part empty, a
// worker without keyframes) run with ForPartition(), verified and unverified,
// for random queries, top k, num_candidates and min_score.
TEST_F(QueryOracleTest, RandomPartitionsOfTheLoopMergeIntoTheWholeAnswer) {
  int compared = 0, verified_runs = 0, matched_runs = 0;
  for (uint32_t seed = 1; seed <= 96; ++seed) {
    std::mt19937 rng(seed);
    auto uniform = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
    const int q = uniform(kFirstQuery, kLastQuery);
    const int parts = 2 + static_cast<int>(seed % 6);  // 2..7, each count 16 times
    QueryOptions options;
    options.verify.enabled = seed % 2 == 0;
    options.top_k = uniform(1, 6);
    options.verify.num_candidates = uniform(1, 10);
    options.min_score = std::vector<double>{0, 12, 40, 80}[static_cast<size_t>(uniform(0, 3))];
    const int filled = seed % 5 == 0 ? parts - 1 : parts;  // the last part may stay empty
    std::vector<std::vector<uint32_t>> among(static_cast<size_t>(parts));
    for (uint32_t i = 0; i < db_->size(); ++i)
      among[static_cast<size_t>(uniform(0, filled - 1))].push_back(i);
    std::vector<QueryResult> partial;
    for (const std::vector<uint32_t>& a : among) {
      QueryContext context;
      context.among = &a;
      partial.push_back(QueryDatabase(*db_, Features(q), options.ForPartition(), context));
    }
    const QueryResult whole = QueryDatabase(*db_, Features(q), options);
    const QueryResult merged = MergeQueryResults(partial, options);
    const std::string where = "seed " + std::to_string(seed) + ": query " + std::to_string(q) +
                              ", " + std::to_string(parts) + " parts, verify " +
                              std::to_string(options.verify.enabled) + ", top_k " +
                              std::to_string(options.top_k) + ", num_candidates " +
                              std::to_string(options.verify.num_candidates);
    EXPECT_TRUE(merged.ranked == whole.ranked)
        << where << ": merged " << Describe(merged.ranked) << ", whole " << Describe(whole.ranked);
    EXPECT_EQ(merged.matched, whole.matched) << where;
    EXPECT_EQ(merged.num_keyframes, 40u) << where;
    EXPECT_EQ(merged.num_examined, 40u) << where;
    ++compared;
    verified_runs += options.verify.enabled;
    matched_runs += whole.matched;
  }
  EXPECT_EQ(compared, 96);
  EXPECT_EQ(verified_runs, 48);
  EXPECT_GT(matched_runs, 0);
  EXPECT_LT(matched_runs, 96);
}

}  // namespace
}  // namespace placedb
