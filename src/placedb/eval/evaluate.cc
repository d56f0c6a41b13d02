#include "placedb/eval/evaluate.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <limits>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <set>

#include "placedb/eval/report_json.h"
#include "placedb/query/query.h"
#include "placedb/session/storage_view.h"
#include "placedb/util/check.h"
#include "placedb/util/file_io.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/options.h"
#include "placedb/util/progress.h"
#include "placedb/util/timer.h"

namespace placedb {
namespace fs = std::filesystem;

std::vector<Frame> SampleFrames(std::vector<Frame> frames, int n, uint64_t seed) {
  if (n > 0 && static_cast<size_t>(n) < frames.size()) {
    // Our own Fisher-Yates with mt19937_64: std::shuffle's algorithm is not
    // specified, and the same seed must pick the same frames everywhere.
    std::mt19937_64 rng(seed);
    for (size_t i = frames.size() - 1; i > 0; --i) {
      const size_t j = static_cast<size_t>(rng() % (i + 1));
      std::swap(frames[i], frames[j]);
    }
    frames.resize(n);
  }
  std::sort(frames.begin(), frames.end(),
            [](const Frame& a, const Frame& b) { return a.id < b.id; });
  return frames;
}

std::vector<Frame> SelectQueries(const std::vector<Frame>& frames, const GroundTruth& truth,
                                 const EvalOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  std::vector<Frame> candidates;
  for (const Frame& f : frames) {
    if (truth.HasTruth(f)) candidates.push_back(f);
  }
  return SampleFrames(std::move(candidates), options.all ? 0 : options.num_queries, options.seed);
}

namespace {

// Whether two paths name one file: the same file, or files of the same name
// and the same bytes (a copy of the sequence in another folder).
class SameImageFinder {
 public:
  explicit SameImageFinder(const std::vector<Keyframe>& keyframes) {
    for (const Keyframe& k : keyframes) {
      if (k.source.empty()) continue;
      std::error_code ec;
      const fs::path canonical = fs::weakly_canonical(k.source, ec);
      if (!ec) canonical_.insert(canonical.string());
      by_name_[fs::path(k.source).filename().string()].push_back(k.source);
    }
  }

  bool Contains(const Frame& f) const {
    if (f.load || f.image_path.empty()) return false;  // not a file (a bag's message)
    std::error_code ec;
    const fs::path canonical = fs::weakly_canonical(f.image_path, ec);
    if (!ec && canonical_.count(canonical.string()) > 0) return true;
    const auto it = by_name_.find(fs::path(f.image_path).filename().string());
    if (it == by_name_.end()) return false;
    const uintmax_t size = fs::file_size(f.image_path, ec);
    if (ec) return false;
    for (const std::string& source : it->second) {
      std::error_code ec2;
      if (fs::file_size(source, ec2) != size || ec2) continue;
      try {
        if (ReadFileToString(source) == ReadFileToString(f.image_path)) return true;
      } catch (const Error&) {
        // Unreadable: not known to be the same.
      }
    }
    return false;
  }

 private:
  std::set<std::string> canonical_;
  std::map<std::string, std::vector<std::string>> by_name_;
};

}  // namespace

std::vector<std::string> EvaluationDoubts(const std::vector<Frame>& queries,
                                          const std::vector<Keyframe>& keyframes,
                                          const GroundTruth& truth) {
  std::vector<std::string> doubts;
  const SameImageFinder same(keyframes);
  int num_same = 0;
  const Frame* example = nullptr;
  for (const Frame& q : queries) {
    if (!same.Contains(q)) continue;
    if (num_same++ == 0) example = &q;
  }
  if (num_same > 0) {
    doubts.push_back(fmt::format(
        "{} of {} query frames are database frames (e.g. frame {}, {}): they find themselves; "
        "query other frames (--first/--last) or another sequence",
        num_same, queries.size(), example->id, example->image_path));
  }
  if (!truth.CanJudgeAny(keyframes)) {
    doubts.push_back(
        !truth.IsMatchList()
            ? std::string("the ground truth is poses and no keyframe of the database has a pose: "
                          "no answer can be judged (build from --tum or a bag with poses, or "
                          "give --truth)")
            : std::string("the match list names none of the database's keyframe ids: no answer "
                          "can be judged (is it the truth of this database?)"));
  } else {
    const bool any_answerable = std::any_of(queries.begin(), queries.end(), [&](const Frame& q) {
      return truth.AnyCorrectIn(q, keyframes);
    });
    if (!queries.empty() && !any_answerable) {
      doubts.push_back(fmt::format(
          "none of the {} queries has a true match in the database ({}): recall and precision "
          "are 0/0",
          queries.size(), truth.Describe()));
    }
  }
  return doubts;
}

void ReportEvaluationDoubts(const std::vector<std::string>& doubts, bool strict) {
  if (doubts.empty()) return;
  if (strict) {
    std::string all;
    for (const std::string& d : doubts) all += (all.empty() ? "" : "; ") + d;
    PLACEDB_THROW_INVALID("refused (strict): the evaluation cannot mean anything: ", all);
  }
  for (const std::string& d : doubts) spdlog::warn("meaningless evaluation: {}", d);
}

namespace {

// The whole frames of `keyframes` for the classic baselines: each one's
// stored image when it is the whole frame (not cropped), else its source
// image. InvalidArgument naming the first keyframe that has neither.
std::vector<cv::Mat> KeyframeWholeFrames(const PlaceDatabase& db,
                                         const std::vector<Keyframe>& keyframes,
                                         const ImageReadOptions& read) {
  std::vector<cv::Mat> images;
  images.reserve(keyframes.size());
  for (const Keyframe& k : keyframes) {
    const std::string stored = k.crop_channel < 0 ? db.StoredImagePath(k) : std::string();
    if (!stored.empty()) {
      DecodedImage d = TryReadImageFile(stored, read);
      if (d.error.empty()) {
        images.push_back(std::move(d.image));
        continue;
      }
    }
    DecodedImage d = TryReadImageFile(k.source, read);
    if (!d.error.empty()) {
      PLACEDB_THROW_INVALID("the baselines need every keyframe's whole frame: keyframe ", k.id,
                            " has ", k.crop_channel >= 0 ? "a cropped stored image" :
                            stored.empty() ? "no stored image" : "an unreadable stored image",
                            " and its source cannot be read (", d.error, ")");
    }
    images.push_back(std::move(d.image));
  }
  return images;
}

// recall@1, recall@5 and precision-recall of answers judged per query.
EvalReport::SingleFrame Judged(int num_correct, int num_correct_at_5,
                               const std::vector<ScoredAnswer>& answers, int answerable,
                               double threshold) {
  EvalReport::SingleFrame f;
  f.num_correct = num_correct;
  f.num_correct_at_5 = num_correct_at_5;
  if (answerable > 0) {
    f.recall_at_1 = static_cast<double>(num_correct) / answerable;
    f.recall_at_5 = static_cast<double>(num_correct_at_5) / answerable;
  }
  f.precision_recall = ComputePrecisionRecall(answers, answerable, threshold);
  return f;
}

}  // namespace

EvalReport Evaluate(const PlaceDatabase& db, const std::vector<Frame>& query_frames,
                    const GroundTruth& truth, const EvalOptions& eval_options,
                    const QueryOptions& query_options, bool check_doubts) {
  PLACEDB_CHECK_OPTIONS(eval_options);
  PLACEDB_CHECK_OPTIONS(query_options);
  if (db.empty()) PLACEDB_THROW_INVALID("the database is empty: no keyframes to match against");
  // Ids beyond every frame and keyframe of the data can never be judged: a
  // sign of the wrong ground-truth file.
  int max_id = 0;
  for (const Frame& f : query_frames) max_id = std::max(max_id, f.id);
  for (const int32_t id : db.keyframe_ids()) max_id = std::max(max_id, id);
  const std::vector<int> beyond = truth.IdsAbove(max_id);
  if (!beyond.empty()) {
    spdlog::warn(
        "the ground truth names {} ids beyond the data (the largest query or keyframe id is {}), "
        "e.g. {}: is it the right file?",
        beyond.size(), max_id, beyond.front());
  }
  const std::vector<Frame> queries = SelectQueries(query_frames, truth, eval_options);
  if (queries.empty()) {
    PLACEDB_THROW_INVALID("no query frame has ground truth (", truth.Describe(),
                          "); nothing to evaluate");
  }
  if (!eval_options.all && static_cast<size_t>(eval_options.num_queries) > queries.size()) {
    spdlog::info("only {} queries have ground truth; evaluating all of them", queries.size());
  }
  const std::vector<Keyframe>& keyframes = StorageView(db).database().keyframes();
  EvalReport report;
  report.doubts = EvaluationDoubts(queries, keyframes, truth);
  if (check_doubts) ReportEvaluationDoubts(report.doubts, eval_options.strict);
  report.truth = truth.Describe();
  report.min_score = query_options.min_score;
  report.verified = query_options.verify.enabled;
  ProgressBar progress("evaluating", queries.size(), eval_options.progress);
  std::vector<double> latency, extract, match, verify;
  std::vector<ScoredAnswer> answers, frame_answers;
  QueryOptions options = query_options;
  std::optional<SequenceMatcher> sequence;
  // The rank of the first true match (1-based; 0: none).
  const auto first_correct_id = [&](const Frame& q, const std::vector<int32_t>& ids) {
    for (size_t r = 0; r < ids.size(); ++r) {
      const std::optional<Keyframe> k = db.FindKeyframe(ids[r]);
      if (k && truth.IsCorrect(q, *k)) return static_cast<int>(r) + 1;
    }
    return 0;
  };
  const auto first_correct_rank = [&](const Frame& q, const std::vector<RankedKeyframe>& ranked) {
    std::vector<int32_t> ids;
    for (const RankedKeyframe& r : ranked) ids.push_back(r.keyframe_id);
    return first_correct_id(q, ids);
  };
  EvalReport::SingleFrame single;
  double sequence_ms = 0.0;
  // Over the whole map when the database has a whole-image channel and the
  // sequence weighs it (SequenceMatcher::Feed with similarities).
  const bool whole_map = eval_options.sequence && db.whole_image_dims() > 0 &&
                         eval_options.sequence_options.whole_image_weight > 0;
  if (eval_options.sequence) {
    sequence.emplace(whole_map ? db.keyframes() : keyframes, eval_options.sequence_options);
    report.sequence_min_score = eval_options.sequence_options.min_score;
    if (!eval_options.all && static_cast<size_t>(eval_options.num_queries) < queries.size()) {
      spdlog::warn(
          "sequence evidence over {} sampled queries of {}: the frames are not consecutive "
          "(use --all, or --first/--last, to replay a stretch)",
          eval_options.num_queries, queries.size());
    }
  }
  // The classic baselines on the same queries (their answers judged as the
  // frames' own are).
  std::optional<ClassicBaselines> classic;
  const bool hog = eval_options.baseline == EvalBaseline::kHog ||
                   eval_options.baseline == EvalBaseline::kBoth;
  const bool seqslam = eval_options.baseline == EvalBaseline::kSeqSlam ||
                       eval_options.baseline == EvalBaseline::kBoth;
  struct BaselineTally {
    int correct = 0, correct_at_5 = 0;
    std::vector<ScoredAnswer> answers;
  };
  std::map<std::string, BaselineTally> tallies;
  if (eval_options.baseline != EvalBaseline::kNone) {
    const std::vector<Keyframe> answering = db.keyframes();
    classic.emplace(answering,
                    KeyframeWholeFrames(db, answering,
                                        queries.empty() ? ImageReadOptions() : queries.front().read));
  }
  const auto tally = [&](const char* name, const Frame& q, const BaselineAnswer& a) {
    BaselineTally& t = tallies[name];
    const int rank = first_correct_id(q, a.ranked);
    t.correct += rank == 1;
    t.correct_at_5 += rank >= 1 && rank <= 5;
    ScoredAnswer s;
    s.has_answer = !a.ranked.empty();
    s.score = a.score;
    s.correct = rank == 1;
    t.answers.push_back(s);
  };
  double coverage_sum = 0.0;
  for (const Frame& q : queries) {
    QueryRecord rec;
    rec.query_id = q.id;
    rec.image = q.image_path;
    rec.has_true_match_in_db = truth.AnyCorrectIn(q, keyframes);
    const cv::Mat image = LoadFrameImage(q);
    if (image.empty()) {
      spdlog::warn("skipped unreadable query image {} (frame {})", q.image_path, q.id);
      rec.unreadable = true;
      ++report.num_unreadable;
      report.queries.push_back(rec);
      progress.Advance();
      continue;
    }
    if (hog) tally("hog", q, classic->Hog(image));
    if (seqslam) tally("seqslam", q, classic->SeqSlam(image));
    std::vector<float> similarities;
    rec.result = db.Query(image, options, sequence && whole_map ? &similarities : nullptr);
    if (sequence) {
      const QueryResult frame = rec.result;
      Timer feed_timer;
      rec.result = sequence->Feed(rec.result, similarities);
      sequence_ms += feed_timer.ElapsedMs();
      report.num_decided_by_sequence += rec.result.decided_by == "sequence";
      // The frame's own answer, judged as a single-frame evaluation would.
      const int frame_rank = first_correct_rank(q, frame.ranked);
      rec.frame_correct_at_1 = frame_rank == 1;
      single.num_correct += frame_rank == 1;
      single.num_correct_at_5 += frame_rank >= 1 && frame_rank <= 5;
      ScoredAnswer fa;
      fa.has_answer = !frame.ranked.empty();
      fa.score = frame.ranked.empty() ? 0.0 : frame.ranked[0].score;
      fa.correct = rec.frame_correct_at_1;
      frame_answers.push_back(fa);
    }
    if (eval_options.sequence) {
      // The next query's prior: this one's answer (none after "no match").
      options.prior = QueryPrior();
      if (rec.result.best()) options.prior.keyframe_id = rec.result.best()->keyframe_id;
    }
    if (rec.has_true_match_in_db) {
      for (const Keyframe& k : keyframes) {
        if (truth.IsCorrect(q, k)) {
          rec.true_keyframe_id = k.id;
          break;
        }
      }
    }
    ++report.searches[rec.result.search];
    coverage_sum += rec.result.coverage;
    report.num_deadline_reached += rec.result.deadline_reached;
    const std::vector<RankedKeyframe>& ranked = rec.result.ranked;
    rec.first_correct_rank = first_correct_rank(q, ranked);
    rec.correct_at_1 = rec.first_correct_rank == 1;
    rec.correct_at_5 = rec.first_correct_rank >= 1 && rec.first_correct_rank <= 5;
    ScoredAnswer answer;
    answer.has_answer = !ranked.empty();
    answer.score = rec.result.decision_score();
    answer.correct = rec.correct_at_1;
    answers.push_back(answer);
    ++report.num_queries;
    report.num_correct += rec.correct_at_1;
    report.num_correct_at_5 += rec.correct_at_5;
    report.num_answerable += rec.has_true_match_in_db;
    latency.push_back(rec.result.times.total_ms);
    extract.push_back(rec.result.times.extract_ms);
    match.push_back(rec.result.times.match_ms);
    verify.push_back(rec.result.times.verify_ms);
    report.queries.push_back(std::move(rec));
    progress.Advance();
  }
  progress.Finish();
  // Recall counts the queries that can be answered: a query whose place is
  // not in the database has no correct keyframe to retrieve.
  if (report.num_answerable > 0) {
    report.recall_at_1 = static_cast<double>(report.num_correct) / report.num_answerable;
    report.recall_at_5 = static_cast<double>(report.num_correct_at_5) / report.num_answerable;
  }
  report.precision_recall = ComputePrecisionRecall(
      answers, report.num_answerable,
      sequence ? eval_options.sequence_options.min_score : query_options.min_score);
  if (sequence) {
    report.single_frame = Judged(single.num_correct, single.num_correct_at_5, frame_answers,
                                 report.num_answerable, query_options.min_score);
    if (report.num_queries > 0) report.sequence_ms_mean = sequence_ms / report.num_queries;
  }
  for (const auto& [name, t] : tallies) {
    // Every answer is given: the threshold is below any score.
    report.baselines[name] = Judged(t.correct, t.correct_at_5, t.answers, report.num_answerable,
                                    -std::numeric_limits<double>::infinity());
  }
  report.latency_ms = ComputeLatencyStats(latency);
  report.extract_ms = ComputeLatencyStats(extract);
  report.match_ms = ComputeLatencyStats(match);
  report.verify_ms = ComputeLatencyStats(verify);
  if (report.num_queries > 0) report.mean_coverage = coverage_sum / report.num_queries;
  report.image_bytes = DirectorySize((fs::path(db.directory()) / "images").string());
  report.feature_bytes = db.keyframes_bytes();
  const nlohmann::json info = StorageView(db).database().info();
  if (info.contains("bytes") && info["bytes"].is_object() &&
      info["bytes"].value("full_frames_png", nlohmann::json()).is_number_unsigned()) {
    report.full_png_bytes = info["bytes"]["full_frames_png"].get<uint64_t>();
  }
  if (report.full_png_bytes > 0) {
    report.reduction_vs_full =
        1.0 - static_cast<double>(report.image_bytes) / static_cast<double>(report.full_png_bytes);
  }
  return report;
}

namespace {
nlohmann::json StatsJson(const LatencyStats& s) {
  return {{"mean", s.mean}, {"p50", s.p50}, {"p99", s.p99}, {"max", s.max}};
}
nlohmann::json PointJson(const PrPoint& p) {
  return {{"threshold", p.threshold},
          {"precision", p.precision},
          {"recall", p.recall},
          {"answered", p.answered}};
}
// A side's answers judged on their own: the frames' own beside a
// sequence's, a baseline's.
nlohmann::json FrameJson(const EvalReport::SingleFrame& f) {
  return {{"num_correct", f.num_correct},
          {"num_correct_at_5", f.num_correct_at_5},
          {"recall_at_1", f.recall_at_1},
          {"recall_at_5", f.recall_at_5},
          {"average_precision", f.precision_recall.average_precision},
          {"recall_at_full_precision", f.precision_recall.recall_at_full_precision},
          {"at_threshold", PointJson(f.precision_recall.at_threshold)}};
}
}  // namespace

std::string EvalReportJson(const EvalReport& report, int indent) {
  return DumpJson(EvalReportToJson(report), indent);
}

nlohmann::json EvalReportToJson(const EvalReport& r) {
  nlohmann::json j;
  j["num_queries"] = r.num_queries;
  j["num_correct"] = r.num_correct;
  j["num_correct_at_5"] = r.num_correct_at_5;
  j["num_answerable"] = r.num_answerable;
  j["num_unreadable"] = r.num_unreadable;
  j["recall_at_1"] = r.recall_at_1;
  j["recall_at_5"] = r.recall_at_5;
  j["verified"] = r.verified;
  j["doubts"] = r.doubts;
  nlohmann::json curve = nlohmann::json::array();
  for (const PrPoint& p : r.precision_recall.curve) curve.push_back(PointJson(p));
  j["precision_recall"] = {
      {"average_precision", r.precision_recall.average_precision},
      {"recall_at_full_precision", r.precision_recall.recall_at_full_precision},
      {"min_score", r.min_score},
      {"at_threshold", PointJson(r.precision_recall.at_threshold)},
      {"curve", curve}};
  j["latency_ms"] = StatsJson(r.latency_ms);
  j["stage_ms"] = {{"extract", StatsJson(r.extract_ms)},
                   {"match", StatsJson(r.match_ms)},
                   {"verify", StatsJson(r.verify_ms)}};
  j["searches"] = r.searches;
  j["mean_coverage"] = r.mean_coverage;
  j["num_deadline_reached"] = r.num_deadline_reached;
  j["database_bytes"] = {{"images", r.image_bytes}, {"features", r.feature_bytes}};
  j["full_frames_png_bytes"] = r.full_png_bytes;
  j["reduction_vs_full"] = r.reduction_vs_full;
  j["truth"] = r.truth;
  if (r.single_frame) {
    j["single_frame"] = FrameJson(*r.single_frame);
    j["sequence"] = {{"decided", r.num_decided_by_sequence},
                     {"min_score", r.sequence_min_score},
                     {"feed_ms_mean", r.sequence_ms_mean}};
  } else {
    j["single_frame"] = nullptr;
    j["sequence"] = nullptr;
  }
  j["baselines"] = nlohmann::json::object();
  for (const auto& [name, f] : r.baselines) j["baselines"][name] = FrameJson(f);
  nlohmann::json queries = nlohmann::json::array();
  for (const QueryRecord& q : r.queries) {
    nlohmann::json e;
    e["query_id"] = q.query_id;
    e["image"] = q.image;
    e["unreadable"] = q.unreadable;
    e["correct_at_1"] = q.correct_at_1;
    e["correct_at_5"] = q.correct_at_5;
    e["first_correct_rank"] = q.first_correct_rank;
    e["has_true_match_in_db"] = q.has_true_match_in_db;
    e["true_keyframe_id"] = q.true_keyframe_id;
    if (r.single_frame) e["frame_correct_at_1"] = q.frame_correct_at_1;
    e["result"] = q.unreadable ? nlohmann::json(nullptr) : nlohmann::json(q.result);
    queries.push_back(e);
  }
  j["queries"] = queries;
  return j;
}

std::string FormatEvalReport(const EvalReport& r) {
  const PrecisionRecall& pr = r.precision_recall;
  std::string out;
  out += fmt::format("  queries           {:>10}   (ground truth: {})\n", r.num_queries, r.truth);
  if (r.num_unreadable > 0) out += fmt::format("  unreadable        {:>10}\n", r.num_unreadable);
  out += fmt::format("  answerable        {:>10}   (a true match is in the database)\n",
                     r.num_answerable);
  out += fmt::format("  verification      {:>10}\n", r.verified ? "on" : "off");
  // With nothing answerable, recall is 0/0: not a number to read.
  const auto ratio = [&](double value) {
    return r.num_answerable > 0 ? fmt::format("{:.3f}", value) : std::string("n/a");
  };
  if (r.single_frame) {
    // Sequence evidence: the frames' own answers beside the sequence's.
    const EvalReport::SingleFrame& f = *r.single_frame;
    const PrecisionRecall& fp = f.precision_recall;
    out += fmt::format("                    {:>12} {:>10}\n", "single frame", "sequence");
    out += fmt::format("  correct @1        {:>12} {:>10}\n", f.num_correct, r.num_correct);
    out += fmt::format("  recall@1          {:>12} {:>10}\n", ratio(f.recall_at_1),
                       ratio(r.recall_at_1));
    out += fmt::format("  recall@5          {:>12} {:>10}\n", ratio(f.recall_at_5),
                       ratio(r.recall_at_5));
    out += fmt::format("  PR AUC            {:>12} {:>10}\n", ratio(fp.average_precision),
                       ratio(pr.average_precision));
    out += fmt::format("  recall @ P=1      {:>12} {:>10}\n", ratio(fp.recall_at_full_precision),
                       ratio(pr.recall_at_full_precision));
    out += fmt::format("  answered          {:>12} {:>10}   (score >= {:g} / path mean >= {:g})\n",
                       fp.at_threshold.answered, pr.at_threshold.answered, r.min_score,
                       r.sequence_min_score);
    out += fmt::format("  precision         {:>12} {:>10}   at those thresholds\n",
                       ratio(fp.at_threshold.precision), ratio(pr.at_threshold.precision));
    out += fmt::format("  sequence decided  {:>23}   of {} frames ({:.3f} ms a frame)\n",
                       r.num_decided_by_sequence, r.num_queries, r.sequence_ms_mean);
  } else {
    out += fmt::format("  correct @1        {:>10}\n", r.num_correct);
    out += fmt::format("  recall@1          {:>10}\n", ratio(r.recall_at_1));
    out += fmt::format("  recall@5          {:>10}\n", ratio(r.recall_at_5));
    out += fmt::format("  answered          {:>10}   (best score >= {:g})\n",
                       pr.at_threshold.answered, r.min_score);
    out += fmt::format("  precision         {:>10}   at that threshold (recall {})\n",
                       ratio(pr.at_threshold.precision), ratio(pr.at_threshold.recall));
    out += fmt::format("  PR AUC            {:>10}   (average precision over the threshold)\n",
                       ratio(pr.average_precision));
    out += fmt::format("  recall @ P=1      {:>10}\n", ratio(pr.recall_at_full_precision));
  }
  if (!r.baselines.empty()) {
    // The classic methods on the same queries (every answer given).
    std::string head, r1, r5, auc, full;
    for (const auto& [name, f] : r.baselines) {
      head += fmt::format(" {:>10}", name == "hog" ? "HOG" : "SeqSLAM");
      r1 += fmt::format(" {:>10}", ratio(f.recall_at_1));
      r5 += fmt::format(" {:>10}", ratio(f.recall_at_5));
      auc += fmt::format(" {:>10}", ratio(f.precision_recall.average_precision));
      full += fmt::format(" {:>10}", ratio(f.precision_recall.recall_at_full_precision));
    }
    out += fmt::format("  baselines, same queries{}\n", head);
    out += fmt::format("  recall@1               {}\n", r1);
    out += fmt::format("  recall@5               {}\n", r5);
    out += fmt::format("  PR AUC                 {}\n", auc);
    out += fmt::format("  recall @ P=1           {}\n", full);
  }
  out += fmt::format("  latency ms        {:>10.2f}   mean  (p50 {:.2f}, p99 {:.2f})\n",
                     r.latency_ms.mean, r.latency_ms.p50, r.latency_ms.p99);
  out += fmt::format("  stages ms         {:>10}   extract {:.2f}, match {:.2f}, verify {:.2f}\n",
                     "mean", r.extract_ms.mean, r.match_ms.mean, r.verify_ms.mean);
  std::string searches;
  for (const auto& [name, count] : r.searches)
    searches += fmt::format("{}{} {}", searches.empty() ? "" : ", ", name, count);
  out += fmt::format("  search            {:>10}   mean coverage {:.1f}% of the database\n",
                     searches, 100.0 * r.mean_coverage);
  if (r.num_deadline_reached > 0) {
    out +=
        fmt::format("  deadline reached  {:>10}   queries stopped early\n", r.num_deadline_reached);
  }
  out += fmt::format("  stored images     {:>10} bytes\n", r.image_bytes);
  out += fmt::format("  features          {:>10} bytes\n", r.feature_bytes);
  out += fmt::format("  whole frames PNG  {:>10} bytes\n", r.full_png_bytes);
  out += fmt::format("  image reduction   {:>9.1f}%   vs storing every frame whole\n",
                     100.0 * r.reduction_vs_full);
  for (const std::string& d : r.doubts) out += fmt::format("  WARNING: {}\n", d);
  return out;
}

}  // namespace placedb
