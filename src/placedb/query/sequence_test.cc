// SequenceMatcher on synthetic frame answers: what each frame ranks is set
// here, so the path the matcher must find is known.
#include "placedb/query/sequence.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "placedb/util/error.h"

namespace placedb {
namespace {

std::vector<Keyframe> Keyframes(int n, bool timed = true) {
  std::vector<Keyframe> k(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    k[static_cast<size_t>(i)].id = i + 1;
    k[static_cast<size_t>(i)].timestamp = timed ? 100.0 + i : -1.0;
  }
  return k;
}

// A frame's answer: `entries` (id, score) ranked as given; matched when the
// first scores at least `min_score`.
QueryResult Frame(const std::vector<std::pair<int32_t, double>>& entries, double min_score = 12.0) {
  QueryResult r;
  for (const auto& [id, score] : entries) {
    RankedKeyframe k;
    k.keyframe_id = id;
    k.score = score;
    r.ranked.push_back(k);
  }
  r.matched = !r.ranked.empty() && r.ranked.front().score >= min_score;
  return r;
}

TEST(SequenceMatcherTest, AConsistentPathBeatsStrongerScatteredAnswers) {
  // The camera passes keyframes 10, 11, 12, ... one per frame. Each frame
  // ranks its true keyframe second (score 8) behind a random wrong one (9).
  SequenceOptions options;
  options.min_score = 6.0;
  options.min_length = options.length;  // SeqSLAM's fixed length
  SequenceMatcher matcher(Keyframes(200), options);
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> any(1, 200);
  int sequence_right = 0, frame_right = 0;
  for (int t = 0; t < 30; ++t) {
    const int32_t truth = 10 + t;
    int32_t wrong = any(rng);
    while (std::abs(wrong - truth) < 3) wrong = any(rng);
    const QueryResult r = matcher.Feed(Frame({{wrong, 9.0}, {truth, 8.0}}));
    ASSERT_TRUE(r.sequence.has_value());
    EXPECT_EQ(r.sequence->frame_keyframe_id, wrong);
    frame_right += r.sequence->frame_keyframe_id == truth;
    if (t == 0) {
      EXPECT_EQ(r.decided_by, "frame");  // one frame is no sequence
      continue;
    }
    EXPECT_EQ(r.decided_by, "sequence");
    if (t >= 2) {
      EXPECT_EQ(r.ranked.front().keyframe_id, truth) << "frame " << t;
      EXPECT_TRUE(r.matched);
      EXPECT_DOUBLE_EQ(r.sequence->velocity, 1.0);
      EXPECT_EQ(r.decision_score(), r.sequence->score);
    }
    sequence_right += r.ranked.front().keyframe_id == truth;
  }
  EXPECT_EQ(frame_right, 0);
  EXPECT_GE(sequence_right, 28);
  EXPECT_EQ(matcher.frames_held(), static_cast<size_t>(SequenceOptions().length));
}

TEST(SequenceMatcherTest, FindsTheEndAFrameDidNotRankAndKeepsTheListLength) {
  SequenceMatcher matcher(Keyframes(50), SequenceOptions());
  for (int t = 0; t < 6; ++t) matcher.Feed(Frame({{20 + t, 10.0}, {3, 1.0}}));
  // The newest frame ranks neither 26 nor anything near it.
  const QueryResult r = matcher.Feed(Frame({{40, 2.0}, {41, 1.0}}));
  EXPECT_EQ(r.decided_by, "sequence");
  ASSERT_EQ(r.ranked.size(), 2u);
  EXPECT_EQ(r.ranked.front().keyframe_id, 26);
  EXPECT_EQ(r.ranked.front().score, 0.0);
  EXPECT_EQ(r.ranked.front().timestamp, 125.0);
  EXPECT_EQ(r.ranked[1].keyframe_id, 40);
  EXPECT_NEAR(r.sequence->score, 60.0 / 7.0, 1e-12);
}

TEST(SequenceMatcherTest, AConfidentFrameThePathDoesNotFollowAnswersAndResetForgets) {
  SequenceOptions options;
  options.min_score = 5.5;
  options.min_length = options.length;
  SequenceMatcher matcher(Keyframes(100), options);
  for (int t = 0; t < 5; ++t) matcher.Feed(Frame({{10 + t, 6.0}}));
  // A jump to keyframe 80, confident (30 >= 12). The best paths, 10..14 ->
  // 15 and 80 standing still, both have mean 30 / 6 = 5 < 5.5: the frame
  // answers.
  const QueryResult jump = matcher.Feed(Frame({{80, 30.0}}));
  EXPECT_EQ(jump.decided_by, "frame");
  EXPECT_TRUE(jump.matched);
  EXPECT_EQ(jump.ranked.front().keyframe_id, 80);
  EXPECT_DOUBLE_EQ(jump.sequence->score, 5.0);
  EXPECT_EQ(jump.decision_score(), 30.0);
  // With the default min_length of 2, the jump's frame and the one before
  // (which did not see 80) already make a path: mean 15.
  SequenceMatcher quick(Keyframes(100), SequenceOptions());
  for (int t = 0; t < 5; ++t) quick.Feed(Frame({{10 + t, 6.0}}));
  const QueryResult followed = quick.Feed(Frame({{80, 30.0}}));
  EXPECT_EQ(followed.decided_by, "sequence");
  EXPECT_EQ(followed.ranked.front().keyframe_id, 80);
  EXPECT_DOUBLE_EQ(followed.sequence->score, 15.0);
  EXPECT_EQ(followed.sequence->frames, 2);
  matcher.Reset();
  EXPECT_EQ(matcher.frames_held(), 0u);
  const QueryResult after = matcher.Feed(Frame({{80, 30.0}}));
  EXPECT_EQ(after.decided_by, "frame");
  EXPECT_EQ(after.sequence->frames, 1);
  EXPECT_EQ(after.sequence->keyframe_id, 80);
}

TEST(SequenceMatcherTest, SlowAndBackwardCamerasFollowTheirVelocity) {
  SequenceOptions slow;
  slow.min_velocity = 0.0;
  slow.max_velocity = 1.0;
  slow.velocity_steps = 5;
  SequenceMatcher half(Keyframes(100), slow);
  QueryResult r;
  for (int t = 0; t < 12; ++t) r = half.Feed(Frame({{30 + (t + 1) / 2, 7.0}, {90 - t, 7.5}}));
  // The true path moves half a keyframe per frame; the distractor runs
  // backwards, which this range does not allow.
  EXPECT_EQ(r.ranked.front().keyframe_id, 30 + 12 / 2);
  EXPECT_DOUBLE_EQ(r.sequence->velocity, 0.5);

  SequenceOptions back;
  back.min_length = back.length;
  back.min_velocity = -2.0;
  back.max_velocity = 2.0;
  SequenceMatcher both(Keyframes(100), back);
  for (int t = 0; t < 12; ++t) r = both.Feed(Frame({{30 + t / 3, 7.0}, {90 - t, 7.5}}));
  EXPECT_EQ(r.ranked.front().keyframe_id, 90 - 11);
  EXPECT_DOUBLE_EQ(r.sequence->velocity, -1.0);
}

TEST(SequenceMatcherTest, OrderIsByTimestampElseIdAndUnknownIdsAreIgnored) {
  std::vector<Keyframe> k = Keyframes(30);
  // Ids out of time order: id 30 was taken first.
  k[29].timestamp = 1.0;
  SequenceOptions full;
  full.min_length = full.length;
  SequenceMatcher timed(k, full);
  QueryResult r;
  for (int t = 0; t < 4; ++t) r = timed.Feed(Frame({{t == 0 ? 30 : t, 8.0}, {999, 50.0}}));
  EXPECT_EQ(r.ranked.front().keyframe_id, 3);
  EXPECT_NEAR(r.sequence->score, 8.0, 1e-12);  // 30, 1, 2, 3 are one path
  EXPECT_EQ(r.sequence->frame_keyframe_id, 3);

  k[5].timestamp = -1.0;  // not every keyframe has a time: id order
  SequenceMatcher untimed(k, full);
  for (int t = 0; t < 4; ++t) r = untimed.Feed(Frame({{t == 0 ? 30 : t, 8.0}}));
  EXPECT_NEAR(r.sequence->score, 6.0, 1e-12);  // 30 is not before 1 any more

  std::vector<Keyframe> twice = Keyframes(3);
  twice[2].id = 1;
  EXPECT_THROW(SequenceMatcher(twice, SequenceOptions()), InvalidArgument);
}

TEST(SequenceMatcherTest, OptionsAreChecked) {
  SequenceOptions o;
  o.min_velocity = 2.0;
  o.max_velocity = 1.0;
  EXPECT_NE(o.Check().find("sequence_min_velocity"), std::string::npos);
  EXPECT_THROW(SequenceMatcher(Keyframes(3), o), InvalidArgument);
  o = SequenceOptions();
  o.length = 0;
  EXPECT_NE(o.Check(), "");
  o = SequenceOptions();
  EXPECT_EQ(o.Check(), "");
}

TEST(SequenceMatcherTest, TheSequencePartTravelsAsJson) {
  SequenceMatcher matcher(Keyframes(40), SequenceOptions());
  QueryResult r;
  for (int t = 0; t < 5; ++t) r = matcher.Feed(Frame({{5 + t, 20.0}}));
  ASSERT_EQ(r.decided_by, "sequence");
  const QueryResult back = QueryResultFromJson(QueryResultToJson(r));
  EXPECT_EQ(back.decided_by, "sequence");
  ASSERT_TRUE(back.sequence.has_value());
  EXPECT_EQ(*back.sequence, *r.sequence);
  // A worker's result has neither field and reads as a frame's.
  const QueryResult plain = QueryResultFromJson(QueryResultToJson(Frame({{3, 20.0}})));
  EXPECT_EQ(plain.decided_by, "frame");
  EXPECT_FALSE(plain.sequence.has_value());
  std::string no_part = QueryResultToJson(r);
  no_part.replace(no_part.find("\"decided_by\":\"sequence\""), 23, "\"decided_by\":\"guess\"");
  EXPECT_THROW(QueryResultFromJson(no_part), InvalidArgument);
}

// The whole map: the frames' whole-image similarities (table order) and
// local answers, oldest first.
struct DenseFrame {
  std::vector<float> similarity;
  std::vector<std::pair<int32_t, double>> local;
};

// What Feed with similarities must answer after `frames` (oldest first), by
// brute force from its contract: evidence = weight x the similarity
// standardised over the window (population deviation; NaN and flat windows
// give 0) + the local score; every end and velocity; a path's rank is the
// best sum over its newest m frames over sqrt(m), m >= min_length; the
// score its mean over those m. Only the frames given (the earlier ones) and
// only the newest `length` of them.
std::pair<int32_t, double> BruteForce(const std::vector<Keyframe>& table,
                                      const std::vector<DenseFrame>& frames,
                                      const SequenceOptions& o) {
  const int n = static_cast<int>(table.size());
  // Sequence order: the ids are 1..n with times in id order here.
  std::vector<int> pos(static_cast<size_t>(n));
  for (int t = 0; t < n; ++t) pos[static_cast<size_t>(t)] = table[static_cast<size_t>(t)].id - 1;
  const size_t h = std::min(frames.size(), static_cast<size_t>(o.length));
  // Every frame's evidence from the first (the hub means run over all of
  // them), newest first.
  std::vector<std::vector<double>> all;
  std::vector<double> hub(static_cast<size_t>(n), 0.0);
  for (const DenseFrame& f : frames) {
    std::vector<double> v(static_cast<size_t>(n), std::nan("")), z(static_cast<size_t>(n), 0.0);
    for (int t = 0; t < n; ++t) {
      v[static_cast<size_t>(pos[static_cast<size_t>(t)])] = f.similarity[static_cast<size_t>(t)];
    }
    for (int p = 0; p < n; ++p) {
      if (!std::isfinite(v[static_cast<size_t>(p)])) continue;
      const int lo = o.contrast_window > 0 ? std::max(0, p - o.contrast_window) : 0;
      const int hi = o.contrast_window > 0 ? std::min(n - 1, p + o.contrast_window) : n - 1;
      double s = 0, ss = 0, c = 0;
      for (int q = lo; q <= hi; ++q) {
        if (!std::isfinite(v[static_cast<size_t>(q)])) continue;
        s += v[static_cast<size_t>(q)];
        ss += v[static_cast<size_t>(q)] * v[static_cast<size_t>(q)];
        c += 1;
      }
      if (c < 2) continue;
      const double mean = s / c, var = ss / c - mean * mean;
      if (var > 1e-12) {
        z[static_cast<size_t>(p)] =
            o.whole_image_weight * (v[static_cast<size_t>(p)] - mean) / std::sqrt(var);
      }
    }
    if (o.hub_frames > 0) {
      for (size_t p = 0; p < z.size(); ++p) {
        const double before = z[p];
        z[p] -= hub[p];
        hub[p] += (before - hub[p]) / o.hub_frames;
      }
    }
    for (const auto& [id, score] : f.local) z[static_cast<size_t>(id - 1)] += score;
    all.insert(all.begin(), z);
  }
  const std::vector<std::vector<double>> e(all.begin(), all.begin() + static_cast<long>(h));
  double best_rank = -1e300, best_score = 0;
  int32_t best_id = -1;
  for (int j = 0; j < n; ++j) {
    for (int vi = 0; vi < o.velocity_steps; ++vi) {
      const double v = o.velocity_steps == 1 ? o.min_velocity
                                             : o.min_velocity + (o.max_velocity - o.min_velocity) *
                                                                    vi / (o.velocity_steps - 1);
      double prefix = 0;
      for (size_t k = 0; k < h; ++k) {
        const long p = j - std::lround(v * static_cast<double>(k));
        if (p >= 0 && p < n) prefix += e[k][static_cast<size_t>(p)];
        const double m = static_cast<double>(k + 1);
        if (k + 1 >= std::min(h, static_cast<size_t>(o.min_length)) &&
            prefix / std::sqrt(m) > best_rank + 1e-9) {
          best_rank = prefix / std::sqrt(m);
          best_score = prefix / m;
          best_id = j + 1;
        }
      }
    }
  }
  return {best_id, best_score};
}

// Over the whole map the matcher finds the path of the camera through
// keyframes that no frame ranks and whose similarity is never the frame's
// best: every frame's best is a random wrong keyframe, the true one is only
// somewhat above the noise. Its answers are what a brute force over the
// frames fed so far gives (causal: a frame's answer uses only it and the
// frames before, and only the newest `length`), in whatever order the
// keyframe table lists the keyframes, with and without a contrast window.
TEST(SequenceMatcherTest, OverTheWholeMapEveryPathIsScoredCausally) {
  std::vector<Keyframe> table = Keyframes(300);
  std::mt19937 rng(11);
  std::shuffle(table.begin(), table.end(), rng);  // the table's order is not the map's
  std::vector<int> row_of(301);
  for (size_t t = 0; t < table.size(); ++t) row_of[static_cast<size_t>(table[t].id)] = static_cast<int>(t);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  std::uniform_int_distribution<int> any(1, 300);
  std::vector<DenseFrame> frames;
  for (int t = 0; t < 40; ++t) {
    DenseFrame f;
    f.similarity.resize(300);
    for (float& v : f.similarity) v = 0.3f + noise(rng);
    const int truth = 100 + t;
    f.similarity[static_cast<size_t>(row_of[static_cast<size_t>(truth)])] += 0.15f;
    int wrong = any(rng);
    while (std::abs(wrong - truth) < 3) wrong = any(rng);
    f.similarity[static_cast<size_t>(row_of[static_cast<size_t>(wrong)])] += 0.3f;
    if (t % 3 == 0) f.local = {{wrong, 4.0}};  // local answers mislead too
    if (t == 7) f.similarity[5] = std::nanf("");  // a keyframe left out
    frames.push_back(f);
  }
  for (const auto& [window, hub] : {std::pair{0, 0}, {25, 0}, {0, 50}, {25, 7}}) {
    SequenceOptions o;
    o.whole_image_weight = 10.0;
    o.match_weight = 0.0;  // the brute force counts the scores alone
    o.contrast_window = window;
    o.hub_frames = hub;
    SequenceMatcher matcher(table, o);
    int right = 0;
    for (size_t t = 0; t < frames.size(); ++t) {
      QueryResult frame;
      for (const auto& [id, score] : frames[t].local) {
        RankedKeyframe k;
        k.keyframe_id = id;
        k.score = score;
        k.num_matches = static_cast<int>(score);  // unverified: the score is the matches
        frame.ranked.push_back(k);
      }
      const QueryResult r = matcher.Feed(frame, frames[t].similarity);
      ASSERT_TRUE(r.sequence.has_value());
      const std::vector<DenseFrame> so_far(frames.begin(), frames.begin() + static_cast<long>(t) + 1);
      const auto [id, score] = BruteForce(table, so_far, o);
      EXPECT_EQ(r.sequence->keyframe_id, id) << "frame " << t << ", window " << window << ", hub " << hub;
      EXPECT_NEAR(r.sequence->score, score, 1e-4) << "frame " << t;
      if (t >= 5) {
        EXPECT_EQ(r.decided_by, "sequence");
        right += r.ranked.front().keyframe_id == 100 + static_cast<int>(t);
      }
    }
    EXPECT_EQ(matcher.frames_held(), static_cast<size_t>(SequenceOptions().length));
    EXPECT_GE(right, 33) << "window " << window << ", hub " << hub;  // of 35
  }
  SequenceOptions o;
  o.whole_image_weight = 10.0;
  SequenceMatcher matcher(table, o);
  EXPECT_THROW(matcher.Feed(QueryResult(), std::vector<float>(299, 0.0f)), InvalidArgument);
  // Every similarity equal: no evidence, no path reaches the score.
  QueryResult r;
  for (int t = 0; t < 4; ++t) r = matcher.Feed(QueryResult(), std::vector<float>(300, 0.5f));
  EXPECT_EQ(r.sequence->score, 0.0);
  EXPECT_FALSE(r.matched);
  // Weight 0, or no similarities: each frame's ranked list alone, as
  // Feed(frame).
  SequenceOptions off;
  off.whole_image_weight = 0.0;
  SequenceMatcher local(table, off), plain(table, off);
  for (size_t t = 0; t < 12; ++t) {
    QueryResult frame;
    RankedKeyframe k;
    k.keyframe_id = 50 + static_cast<int32_t>(t);
    k.score = 9.0;
    frame.ranked.push_back(k);
    const QueryResult a = local.Feed(frame, frames[t].similarity);
    const QueryResult b = plain.Feed(frame);
    EXPECT_EQ(a.sequence, b.sequence);
    EXPECT_EQ(a.ranked.front().keyframe_id, b.ranked.front().keyframe_id);
  }
}

// A keyframe like every frame (a hub: its similarity is high whatever the
// camera sees) holds the standing-still path without hub_frames; with it,
// its evidence fades within about hub_frames frames and the camera's true
// path answers.
TEST(SequenceMatcherTest, AKeyframeLikeEveryFrameFadesWithHubFrames) {
  const std::vector<Keyframe> table = Keyframes(200);
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  std::vector<std::vector<float>> frames;
  for (int t = 0; t < 80; ++t) {
    std::vector<float> s(200);
    for (float& v : s) v = 0.3f + noise(rng);
    s[static_cast<size_t>(10 + t)] += 0.15f;  // the camera passes 11, 12, ... (ids)
    s[150] += 0.3f;                           // id 151, like every frame
    frames.push_back(s);
  }
  auto answers = [&](int hub_frames) {
    SequenceOptions o;
    o.whole_image_weight = 10.0;
    o.hub_frames = hub_frames;
    SequenceMatcher matcher(table, o);
    int truth = 0, hub = 0;
    for (int t = 0; t < 80; ++t) {
      const QueryResult r = matcher.Feed(QueryResult(), frames[static_cast<size_t>(t)]);
      if (t < 60) continue;
      truth += r.sequence->keyframe_id == 11 + t;
      hub += r.sequence->keyframe_id == 151;
    }
    return std::pair{truth, hub};
  };
  EXPECT_EQ(answers(0).second, 20);
  EXPECT_EQ(answers(20).first, 20);
}

}  // namespace
}  // namespace placedb
