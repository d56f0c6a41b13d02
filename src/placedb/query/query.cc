#include "placedb/query/query.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <mutex>
#include <unordered_set>

#include "placedb/feature/whole_image.h"
#include "placedb/query/order.h"
#include "placedb/retrieval/clusters.h"
#include "placedb/util/check.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/options.h"
#include "placedb/util/thread_pool.h"
#include "placedb/util/timer.h"

namespace placedb {
namespace fs = std::filesystem;
using namespace query_order;  // NOLINT: the rules the stages apply

void CandidateCost::Report(double worst_ms) {
  double old = ms_.load();
  while (!ms_.compare_exchange_weak(old, std::max(worst_ms, 0.98 * old))) {
  }
}

QueryOptions QueryOptions::ForPartition() const {
  QueryOptions o = *this;
  if (verify.enabled) o.top_k = std::max(top_k, verify.num_candidates);
  return o;
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
  // The whole-image descriptor, when the query has one and the database the
  // channel: the size the database stores, values in [-127, 127].
  const cv::Mat& w = features.whole_image;
  if (!w.empty() && db.whole_image_dims() > 0) {
    if (w.type() != CV_8SC1 || w.rows != 1 || w.cols != db.whole_image_dims() ||
        !w.isContinuous()) {
      PLACEDB_THROW_INVALID("the query's whole-image descriptor is not a continuous 1 x ",
                            db.whole_image_dims(), " int8 row (the database's)");
    }
    const int8_t* v = w.ptr<int8_t>();
    if (std::find(v, v + w.cols, static_cast<int8_t>(-128)) != v + w.cols)
      PLACEDB_THROW_INVALID("the query's whole-image descriptor holds -128");
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
  // The query image's size is not known here: positions are bounded by the
  // largest image side.
  const std::string bad =
      CheckKeypoints(features.keypoints.data(), features.keypoints.size(), cv::Size());
  if (!bad.empty()) PLACEDB_THROW_INVALID("the query ", bad);
  if (db.feature_type() == FeatureType::kSurf &&
      !AllFinite(d.ptr<float>(0), features.keypoints.size() * static_cast<size_t>(d.cols))) {
    PLACEDB_THROW_INVALID("the query has a SURF descriptor value that is not finite");
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
  std::optional<double> whole_image;    // similarity, with the channel
  std::optional<double> whole_image_z;  // standardised, with the channel
  double key = 0.0;                     // matches + the whole-image bonus (order.h)
};

// The whole-image similarity to the query of every keyframe (by index) and
// their mean and standard deviation over the database's keyframes (not the
// restriction's, and for a subset over its file's: every partition
// standardises alike; the removed ones left out). Empty without the
// channel.
struct WholeImageScores {
  std::vector<float> similarity;
  double mean = 0.0;
  double inverse_deviation = 0.0;  // 0 when the similarities do not vary
  std::optional<double> Of(uint32_t index) const {
    if (similarity.empty()) return std::nullopt;
    return static_cast<double>(similarity[index]);
  }
  std::optional<double> StandardOf(uint32_t index) const {
    if (similarity.empty()) return std::nullopt;
    return (static_cast<double>(similarity[index]) - mean) * inverse_deviation;
  }
};

Examined MakeExamined(const Database& db, uint32_t index, int good, std::vector<cv::DMatch> matches,
                      const WholeImageScores& whole, const QueryOptions& options) {
  Examined e{index,           db.keyframe(index).id,  good, std::move(matches),
             whole.Of(index), whole.StandardOf(index), 0.0};
  e.key = good + WholeImageBonus(e.whole_image_z, options);
  return e;
}

// Whether an examined keyframe is ranked: enough matches, or whole-image
// evidence (a tiny or featureless frame still has its thumbnail).
bool Ranked(int good, const WholeImageScores& whole, uint32_t index, const QueryOptions& options) {
  return good >= options.min_matches || WholeImageBonus(whole.StandardOf(index), options) > 0.0;
}

void KeepBest(std::vector<Examined>* list, size_t keep) {
  auto order = [](const Examined& a, const Examined& b) {
    return MoreEvidence(a.id, a.key, b.id, b.key);
  };
  if (list->size() > keep) {
    std::nth_element(list->begin(), list->begin() + static_cast<ptrdiff_t>(keep), list->end(),
                     order);
    list->resize(keep);
  }
  std::sort(list->begin(), list->end(), order);
}

// The verify stage on one keyframe: the matched points (the query's in its
// image, the keyframe's mapped back to its original image) through USAC.
VerifyResult VerifyKeyframe(const Database& db, size_t index, const FeatureSet& query,
                            const std::vector<cv::DMatch>& matches, const VerifyOptions& options) {
  const Keyframe& k = db.keyframe(index);
  const std::vector<cv::KeyPoint> keypoints = db.Keypoints(index);
  std::vector<cv::Point2f> q, t;
  q.reserve(matches.size());
  t.reserve(matches.size());
  for (const cv::DMatch& m : matches) {
    q.push_back(query.keypoints[m.queryIdx].pt);
    t.push_back(k.ToOriginal(keypoints[m.trainIdx].pt));
  }
  return VerifyMatches(q, t, options);
}

// The ranked entry of an examined keyframe (its score the matches until
// verified).
RankedKeyframe Describe(const Database& db, const Examined& e, const std::string& image_dir) {
  const Keyframe& k = db.keyframe(e.index);
  RankedKeyframe r;
  r.keyframe_id = k.id;
  r.num_matches = e.num_matches;
  r.whole_image = e.whole_image;
  r.whole_image_z = e.whole_image_z;
  r.score = e.key;
  r.pose = k.pose;
  r.timestamp = k.timestamp;
  r.source = k.source;
  if (!k.image_file.empty()) {
    r.stored_image =
        image_dir.empty() ? k.image_file : (fs::path(image_dir) / k.image_file).string();
  }
  return r;
}

// The largest of the durations added so far (thread-safe): what the next
// candidate is expected to cost at most.
class WorstCost {
 public:
  void Add(double ms) {
    double seen = worst_.load();
    while (ms > seen && !worst_.compare_exchange_weak(seen, ms)) {
    }
  }
  double Get() const { return worst_.load(); }

 private:
  std::atomic<double> worst_{0.0};
};

// What the match and verify stages give RunStages.
struct Examination {
  std::vector<RankedKeyframe> ranked;  // unsorted, every one verified when verification is on
  size_t examined = 0;
  size_t verified = 0;
  bool stopped = false;  // the deadline cut the stages short
  double match_ms = 0.0, verify_ms = 0.0;
  double costliest_ms = 0.0;  // one candidate's match + verify at most (timed runs)
};

// No deadline: every candidate matched (contiguous chunks over the pool,
// each keeping its best; the merged best do not depend on the chunking),
// then the best num_candidates by matches verified, skipping those that
// cannot reach the top k.
Examination ExamineAll(const Database& db, const GroupedFeatures& grouped,
                       const std::vector<Candidate>& candidates, const QueryOptions& options,
                       const QueryContext& context, const WholeImageScores& whole) {
  Examination out;
  Timer stage;
  const size_t keep = KeptAfterMatching(options);
  const bool need_matches = options.verify.enabled;
  const size_t n = candidates.size();
  const size_t chunks = UsefulThreads(context.pool, n);
  std::vector<std::vector<Examined>> partial(chunks);
  auto match_chunk = [&](size_t c) {
    std::vector<Examined>& kept = partial[c];
    std::vector<cv::DMatch> matches;
    std::vector<uint8_t> rows;  // a candidate's rows, when the database reads them
    for (size_t i = n * c / chunks; i < n * (c + 1) / chunks; ++i) {
      const uint32_t index = candidates[i].index;
      matches.clear();
      const int good = MatchDescriptors(grouped.block, db.Descriptors(index, &rows), options.match,
                                        need_matches ? &matches : nullptr);
      if (!Ranked(good, whole, index, options)) continue;
      kept.push_back(MakeExamined(
          db, index, good, need_matches ? matches : std::vector<cv::DMatch>(), whole, options));
      if (kept.size() > 2 * keep + 64) KeepBest(&kept, keep);  // bounded memory
    }
    KeepBest(&kept, keep);
  };
  ForEach(context.pool, chunks, match_chunk);
  out.examined = n;
  std::vector<Examined> best;
  for (auto& p : partial) {
    for (auto& e : p) best.push_back(std::move(e));
  }
  KeepBest(&best, keep);
  out.match_ms = stage.ElapsedMs();

  stage.Restart();
  std::vector<RankedKeyframe> ranked(best.size());
  std::vector<char> done(best.size(), 0);
  auto fill = [&](size_t i) {
    ranked[i] = Describe(db, best[i], context.image_dir);
    done[i] = 1;
    if (!options.verify.enabled) return;
    ranked[i].num_inliers =
        VerifyKeyframe(db, best[i].index, grouped.set, best[i].matches, options.verify).num_inliers;
    ranked[i].score = VerifiedScore(ranked[i], options);
  };
  const auto fill_range = [&](size_t first, size_t last) {
    if (first < last) ForEach(context.pool, last - first, [&](size_t i) { fill(first + i); });
  };
  // Only what can reach the top k is verified: once k candidates are
  // verified, one whose key (matches + whole-image bonus) is below the k-th
  // best score so far cannot rank among them (inliers are a subset of its
  // matches, the bonus the same), nor can any after it (smaller keys still).
  // In two rounds, so that which ones are verified does not depend on the
  // threads: the best k by key, then those of the rest that could still
  // rank.
  const size_t top_k = static_cast<size_t>(options.top_k);
  if (!options.verify.enabled || ranked.size() <= top_k) {
    fill_range(0, ranked.size());
  } else {
    fill_range(0, top_k);
    double kth = ranked[0].score;
    for (size_t i = 1; i < top_k; ++i) kth = std::min(kth, ranked[i].score);
    size_t last = top_k;
    while (last < ranked.size() && best[last].key >= kth) ++last;
    fill_range(top_k, last);
  }
  for (size_t i = 0; i < ranked.size(); ++i) {
    if (done[i]) out.ranked.push_back(std::move(ranked[i]));
  }
  if (options.verify.enabled) out.verified = out.ranked.size();
  out.verify_ms = options.verify.enabled ? stage.ElapsedMs() : 0.0;
  return out;
}

// Under a deadline: candidates in prior order (threads take the next from a
// counter), each matched and, while it is among the best num_candidates by
// matches so far, verified at once; a later candidate with more matches
// displaces it (its verification is dropped). A candidate is started only
// when the costliest of this query's candidates so far would still end
// before the deadline, so a query is late only by what one candidate costs
// beyond that; the first candidate is always examined and verified.
Examination ExamineTimed(const Database& db, const GroupedFeatures& grouped,
                         const std::vector<Candidate>& candidates, const QueryOptions& options,
                         const QueryContext& context, const Deadline& deadline,
                         const WholeImageScores& whole) {
  Examination out;
  const size_t keep = KeptAfterMatching(options);
  const bool verify = options.verify.enabled;
  const size_t n = candidates.size();
  struct Kept {
    Examined e;
    RankedKeyframe r;
  };
  std::vector<Kept> best;  // at most keep, guarded by `mutex`
  std::mutex mutex;
  std::atomic<size_t> next{0}, examined{0};
  std::atomic<bool> stopped{false};
  WorstCost cost;
  double match_ms = 0.0, verify_ms = 0.0;        // guarded by `mutex`
  const auto in_best = [&](const Examined& e) {  // under `mutex`
    if (best.size() < keep) return true;
    const Examined& worst = best.back().e;
    return MoreEvidence(e.id, e.key, worst.id, worst.key);
  };
  const auto insert = [&](Kept k) {  // under `mutex`
    const auto at = std::find_if(best.begin(), best.end(), [&](const Kept& b) {
      return MoreEvidence(k.e.id, k.e.key, b.e.id, b.e.key);
    });
    best.insert(at, std::move(k));
    if (best.size() > keep) best.pop_back();
  };
  auto worker = [&](size_t) {
    std::vector<cv::DMatch> matches;
    std::vector<uint8_t> rows;  // a candidate's rows, when the database reads them
    for (;;) {
      const size_t i = next.fetch_add(1);
      if (i >= n) break;
      if (i > 0 && (stopped || !deadline.Fits(cost.Get()))) {
        stopped = true;
        break;
      }
      Timer t;
      const uint32_t index = candidates[i].index;
      matches.clear();
      const int good = MatchDescriptors(grouped.block, db.Descriptors(index, &rows), options.match,
                                        verify ? &matches : nullptr);
      examined.fetch_add(1, std::memory_order_relaxed);
      const double matched_ms = t.ElapsedMs();
      double verified_ms = 0.0;
      if (Ranked(good, whole, index, options)) {
        Examined e = MakeExamined(db, index, good, verify ? matches : std::vector<cv::DMatch>(),
                                  whole, options);
        bool candidate;
        {
          std::lock_guard<std::mutex> lock(mutex);
          candidate = in_best(e);
        }
        if (candidate) {
          Kept k{std::move(e), RankedKeyframe()};
          k.r = Describe(db, k.e, context.image_dir);
          if (verify) {
            Timer v;
            k.r.num_inliers =
                VerifyKeyframe(db, index, grouped.set, k.e.matches, options.verify).num_inliers;
            k.r.score = VerifiedScore(k.r, options);
            k.e.matches.clear();  // not needed any more
            verified_ms = v.ElapsedMs();
          }
          std::lock_guard<std::mutex> lock(mutex);
          if (in_best(k.e)) insert(std::move(k));
        }
      }
      {
        std::lock_guard<std::mutex> lock(mutex);
        match_ms += matched_ms;
        verify_ms += verified_ms;
      }
      cost.Add(matched_ms + verified_ms);
    }
  };
  ForEach(context.pool, UsefulThreads(context.pool, n), worker);
  for (Kept& k : best) out.ranked.push_back(std::move(k.r));
  out.examined = examined.load();
  if (verify) out.verified = out.ranked.size();
  out.stopped = stopped.load();
  out.match_ms = match_ms;
  out.verify_ms = verify ? verify_ms : 0.0;
  out.costliest_ms = cost.Get();
  return out;
}

// The whole-image channel: every keyframe's similarity to the query and
// their statistics, when the database has the channel, the query a
// descriptor of its size (a query from an image; features from elsewhere
// carry none) and the options use it (a weight to score or candidates to
// add). `excluded`: the removed keyframes (nullptr: none), left out of the
// statistics.
WholeImageScores ScoreWholeImages(const Database& db, const FeatureSet& query,
                                  const QueryOptions& options, const uint8_t* excluded) {
  WholeImageScores s;
  const int dims = db.whole_image_dims();
  if (dims <= 0 || query.whole_image.empty() || db.size() == 0) return s;
  if (options.whole_image_weight <= 0.0 && options.whole_image_candidates <= 0) return s;
  const int8_t* q = query.whole_image.ptr<int8_t>();
  s.similarity.resize(db.size());
  WholeImageSimilarities(q, db.WholeImageData(), db.size(), dims, s.similarity.data());
  // A subset standardises over its file's rows, as the whole database does.
  size_t count = 0;
  const int8_t* rows = db.StandardisingRows(&count);
  std::vector<float> file_similarity;
  if (rows != db.WholeImageData()) {
    file_similarity.resize(count);
    WholeImageSimilarities(q, rows, count, dims, file_similarity.data());
    excluded = nullptr;  // the mask is the subset's
  }
  const std::vector<float>& reference = rows != db.WholeImageData() ? file_similarity : s.similarity;
  double sum = 0.0, sum_sq = 0.0;
  size_t n = 0;
  for (size_t i = 0; i < reference.size(); ++i) {
    if (excluded != nullptr && excluded[i] != 0) continue;
    const double v = reference[i];
    sum += v;
    sum_sq += v * v;
    ++n;
  }
  if (n >= 2) {
    s.mean = sum / static_cast<double>(n);
    const double variance = std::max(0.0, sum_sq / static_cast<double>(n) - s.mean * s.mean);
    // Similarities are in [-1, 1]: a deviation below 1e-6 is rounding.
    if (variance > 1e-12) s.inverse_deviation = 1.0 / std::sqrt(variance);
  }
  return s;
}

// The `m` keyframes of the restriction most similar to the query (then the
// lower index), most similar first.
std::vector<uint32_t> MostSimilarWholeImages(const WholeImageScores& whole, size_t m,
                                             const std::vector<uint32_t>* among,
                                             const uint8_t* excluded) {
  if (m == 0) return {};
  // The best m in one pass: a min-heap on (similarity, then the higher index
  // first out), no copy of the restriction.
  const auto worse = [&](uint32_t a, uint32_t b) {  // a ranks after b
    const float sa = whole.similarity[a], sb = whole.similarity[b];
    return sa != sb ? sa < sb : a > b;
  };
  const auto heap_order = [&](uint32_t a, uint32_t b) { return worse(b, a); };
  std::vector<uint32_t> best;
  best.reserve(m + 1);
  const auto consider = [&](uint32_t i) {
    if (excluded != nullptr && excluded[i] != 0) return;
    if (best.size() < m) {
      best.push_back(i);
      std::push_heap(best.begin(), best.end(), heap_order);
    } else if (worse(best.front(), i)) {
      std::pop_heap(best.begin(), best.end(), heap_order);
      best.back() = i;
      std::push_heap(best.begin(), best.end(), heap_order);
    }
  };
  if (among != nullptr) {
    for (const uint32_t i : *among) consider(i);
  } else {
    for (uint32_t i = 0; i < whole.similarity.size(); ++i) consider(i);
  }
  std::sort(best.begin(), best.end(), [&](uint32_t a, uint32_t b) { return worse(b, a); });
  return best;
}

// Appends the whole_image_candidates keyframes of the restriction most similar
// to the query (then the lower index) that retrieval did not find.
void AddWholeImageCandidates(const WholeImageScores& whole, const QueryOptions& options,
                             const std::vector<uint32_t>* among, const uint8_t* excluded,
                             std::vector<Candidate>* candidates) {
  const std::vector<uint32_t> best = MostSimilarWholeImages(
      whole, static_cast<size_t>(options.whole_image_candidates), among, excluded);
  std::unordered_set<uint32_t> have;
  for (const Candidate& c : *candidates) have.insert(c.index);
  for (const uint32_t i : best) {
    if (have.insert(i).second) candidates->push_back({i, whole.similarity[i]});
  }
}

// retrieve -> match -> verify -> decide over `among` (sorted, unique, in
// range; nullptr = the whole database) with `retriever`. `clock` started with
// the query: the deadline is measured from it.
QueryResult RunStages(const Database& db, const FeatureSet& query, const QueryOptions& options,
                      const QueryContext& context, const std::vector<uint32_t>* among,
                      const Retriever& retriever, const Timer& clock) {
  QueryResult result;
  result.num_query_features = static_cast<int>(query.size());
  const uint8_t* excluded = context.excluded != nullptr ? context.excluded->data() : nullptr;
  if (among == nullptr) {
    result.num_keyframes = db.size() - (excluded != nullptr ? context.num_excluded : 0);
  } else {
    result.num_keyframes = among->size();
    if (excluded != nullptr) {
      for (const uint32_t i : *among) result.num_keyframes -= excluded[i];
    }
  }
  result.search = RetrievalMethodName(retriever.method());
  const Deadline deadline(clock, options.deadline_ms);

  // Retrieve. Under a deadline the retriever may stop early (bag-of-words
  // scoring of a large database takes milliseconds): the match stage then
  // takes the candidates found so far, the first always. It stops early
  // enough to leave one candidate's cost (the session's estimate) free.
  Timer stage;
  bool retrieve_stopped = false;
  const double reserve =
      deadline.enabled() && context.candidate_cost != nullptr ? context.candidate_cost->Get() : 0.0;
  const Deadline retrieve_deadline =
      deadline.enabled() ? Deadline(clock, std::max(options.deadline_ms - reserve, 1e-9))
                         : Deadline();
  std::vector<Candidate> candidates =
      retriever.Retrieve(db, query, among, excluded, retrieve_deadline, &retrieve_stopped);
  const bool exhaustive = retriever.method() == RetrievalMethod::kExhaustive;
  const WholeImageScores whole = ScoreWholeImages(db, query, options, excluded);
  if (!whole.similarity.empty() && !exhaustive && options.whole_image_candidates > 0)
    AddWholeImageCandidates(whole, options, among, excluded, &candidates);
  result.times.retrieve_ms = stage.ElapsedMs();

  // Match and verify. SURF: the query's rows grouped by Laplacian sign,
  // like the database's.
  const GroupedFeatures grouped = GroupByLaplacian(query);
  Examination e = deadline.enabled()
                      ? ExamineTimed(db, grouped, candidates, options, context, deadline, whole)
                      : ExamineAll(db, grouped, candidates, options, context, whole);
  if (deadline.enabled() && context.candidate_cost != nullptr && e.examined > 0)
    context.candidate_cost->Report(e.costliest_ms);
  result.num_examined = e.examined;
  result.num_verified = e.verified;
  result.times.match_ms = e.match_ms;
  result.times.verify_ms = e.verify_ms;
  result.deadline_reached = e.stopped || retrieve_stopped;

  // Rank and decide.
  std::vector<RankedKeyframe>& ranked = e.ranked;
  std::sort(ranked.begin(), ranked.end(), RanksFirst);
  if (ranked.size() > static_cast<size_t>(options.top_k)) ranked.resize(options.top_k);
  result.ranked = std::move(ranked);
  Decide(&result, options);
  result.coverage = CoverageOf(result);
  return result;
}

// The keyframes of `among` (nullptr: all of [0, n)) that are not in `local`
// (both sorted).
std::vector<uint32_t> Complement(size_t n, const std::vector<uint32_t>* among,
                                 const std::vector<uint32_t>& local) {
  std::vector<uint32_t> all;
  if (among != nullptr) {
    all = *among;
  } else {
    all.resize(n);
    for (size_t i = 0; i < n; ++i) all[i] = static_cast<uint32_t>(i);
  }
  std::vector<uint32_t> out;
  std::set_difference(all.begin(), all.end(), local.begin(), local.end(), std::back_inserter(out));
  return out;
}

// Cluster search: the prior's clusters first, the rest only when the local
// answer is weak; the two stages' results merge into the answer the union
// gives (MergeQueryResults).
QueryResult RunClusterSearch(const Database& db, const FeatureSet& query,
                             const QueryOptions& options, const QueryContext& context,
                             const std::vector<uint32_t>* among, const Retriever& retriever,
                             const Timer& clock) {
  if (context.clusters == nullptr) {
    PLACEDB_THROW_INVALID(
        "cluster search needs the database's clusters (open it with "
        "PlaceDatabase::Open)");
  }
  const ClusterSet& clusters = *context.clusters;
  if (clusters.size() != 0 && db.size() == 0) {
    PLACEDB_THROW_INVALID("the clusters belong to another database");
  }
  int c = -1;
  if (options.prior.keyframe_id != 0) {
    const int index = db.IndexOfId(options.prior.keyframe_id);
    if (index >= 0) c = clusters.ClusterOf(static_cast<uint32_t>(index));
  } else if (options.prior.pose) {
    c = clusters.Nearest(options.prior.pose->translation);
  }
  if (c < 0) {
    QueryResult r = RunStages(db, query, options, context, among, retriever, clock);
    r.search = "cluster+global";
    return r;
  }
  const QueryOptions part = options.ForPartition();
  std::vector<uint32_t> local = clusters.KeyframesAround(c, options.retrieval.cluster_hops);
  if (among != nullptr) {
    std::vector<uint32_t> both;
    std::set_intersection(local.begin(), local.end(), among->begin(), among->end(),
                          std::back_inserter(both));
    local = std::move(both);
  }
  std::vector<QueryResult> parts;
  parts.push_back(RunStages(db, query, part, context, &local, retriever, clock));
  const double weak = options.retrieval.cluster_fallback_score > 0.0
                          ? options.retrieval.cluster_fallback_score
                          : options.min_score;
  const QueryResult& first = parts.front();
  const bool strong = !first.ranked.empty() && first.ranked.front().score >= weak;
  bool fallback = false;
  if (!strong && !first.deadline_reached) {
    const std::vector<uint32_t> rest = Complement(db.size(), among, local);
    if (!rest.empty()) {
      parts.push_back(RunStages(db, query, part, context, &rest, retriever, clock));
      fallback = true;
    }
  }
  QueryResult r = MergeQueryResults(parts, options);
  // The stages ran one after the other.
  StageTimes sum;
  for (const QueryResult& p : parts) {
    sum.retrieve_ms += p.times.retrieve_ms;
    sum.match_ms += p.times.match_ms;
    sum.verify_ms += p.times.verify_ms;
  }
  r.times = sum;
  r.search = fallback ? "cluster+fallback" : "cluster";
  r.cluster = c;
  return r;
}

}  // namespace

namespace {

// context.among sorted and unique (empty when it is nullptr), after checking
// it and the mask of removed keyframes against `db` (InvalidArgument).
std::vector<uint32_t> CheckedRestriction(const Database& db, const QueryContext& context) {
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
  if (context.excluded != nullptr && context.excluded->size() != db.size()) {
    PLACEDB_THROW_INVALID("the mask of removed keyframes has ", context.excluded->size(),
                          " entries for ", db.size(), " keyframes");
  }
  return among;
}

// What every entry point checks first.
void CheckQueryInput(const Database& db, const FeatureSet& query, const QueryOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  ValidateQueryFeatures(query, db);
  if (!db.has_features()) {
    PLACEDB_THROW_INVALID("the database was opened as a keyframe table, without features");
  }
}

}  // namespace

QueryResult QueryDatabase(const Database& db, const FeatureSet& query, const QueryOptions& options,
                          const QueryContext& context) {
  CheckQueryInput(db, query, options);
  const Timer own_clock;
  const Timer& clock = context.clock != nullptr ? *context.clock : own_clock;
  const std::vector<uint32_t> among = CheckedRestriction(db, context);
  std::unique_ptr<Retriever> own_retriever;
  const Retriever* retriever = context.retriever;
  if (retriever == nullptr) {
    own_retriever = Retriever::Create(options.retrieval, db, context.bow, options.match);
    retriever = own_retriever.get();
  }
  const std::vector<uint32_t>* restriction = context.among ? &among : nullptr;
  QueryResult result =
      options.retrieval.method == RetrievalMethod::kCluster
          ? RunClusterSearch(db, query, options, context, restriction, *retriever, clock)
          : RunStages(db, query, options, context, restriction, *retriever, clock);
  result.times.total_ms = clock.ElapsedMs();
  return result;
}

Shortlist ShortlistDatabase(const Database& db, const FeatureSet& query,
                            const QueryOptions& options, const QueryContext& context) {
  CheckQueryInput(db, query, options);
  if (options.retrieval.method != RetrievalMethod::kBow) {
    PLACEDB_THROW_INVALID("a shortlist is the first round of a bow search, not of ",
                          RetrievalMethodName(options.retrieval.method), " search");
  }
  if (context.bow == nullptr) {
    PLACEDB_THROW_INVALID(
        "bow search needs a bag-of-words index: rebuild the database with `index` set to bow");
  }
  const Timer own_clock;
  const Timer& clock = context.clock != nullptr ? *context.clock : own_clock;
  const std::vector<uint32_t> among = CheckedRestriction(db, context);
  const std::vector<uint32_t>* restriction = context.among ? &among : nullptr;
  const uint8_t* excluded = context.excluded != nullptr ? context.excluded->data() : nullptr;
  const Deadline deadline(clock, options.deadline_ms);
  Shortlist out;
  const std::vector<BowCandidate> scored =
      ScoreBowCandidates(*context.bow, db, query, options.retrieval, options.match, restriction,
                         excluded, deadline, &out.deadline_reached, /*count_always=*/true);
  for (const BowCandidate& c : scored)
    out.bow.push_back({c.index, db.keyframe(c.index).id, c.score, c.guided});
  // The thumbnails are scanned only to name whole-image candidates.
  const WholeImageScores whole = options.whole_image_candidates > 0
                                     ? ScoreWholeImages(db, query, options, excluded)
                                     : WholeImageScores();
  if (!whole.similarity.empty()) {
    for (const uint32_t i : MostSimilarWholeImages(
             whole, static_cast<size_t>(options.whole_image_candidates), restriction, excluded))
      out.whole_image.push_back({i, db.keyframe(i).id, whole.similarity[i], -1});
  }
  out.retrieve_ms = clock.ElapsedMs();
  return out;
}

MatchDetail MatchKeyframe(const Database& db, const FeatureSet& query, size_t index,
                          const QueryOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  ValidateQueryFeatures(query, db);
  if (index >= db.size()) {
    PLACEDB_THROW_INVALID("keyframe index ", index, " is out of range (", db.size(), " keyframes)");
  }
  const GroupedFeatures grouped = GroupByLaplacian(query);
  MatchDetail d;
  d.keyframe_id = db.keyframe(index).id;
  std::vector<uint8_t> rows;
  MatchDescriptors(grouped.block, db.Descriptors(index, &rows), options.match, &d.matches);
  d.query_keypoints = grouped.set.keypoints;
  const Keyframe& k = db.keyframe(index);
  const std::vector<cv::KeyPoint> keypoints = db.Keypoints(index);
  d.keyframe_stored_points.reserve(keypoints.size());
  d.keyframe_points.reserve(keypoints.size());
  for (const cv::KeyPoint& kp : keypoints) {
    d.keyframe_stored_points.push_back(kp.pt);
    d.keyframe_points.push_back(k.ToOriginal(kp.pt));
  }
  if (options.verify.enabled && static_cast<int>(d.matches.size()) >= options.min_matches) {
    VerifyResult v = VerifyKeyframe(db, index, grouped.set, d.matches, options.verify);
    d.verified = true;
    d.num_inliers = v.num_inliers;
    d.inliers = v.estimated ? std::move(v.inlier_mask) : std::vector<uint8_t>(d.matches.size(), 0);
  }
  return d;
}

}  // namespace placedb
