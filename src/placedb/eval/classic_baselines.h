// The two classic whole-image methods of visual place recognition, which
// `placedb eval --baseline` computes on the same query frames against the
// same keyframes, so that a user sees placedb beside them on their own data:
// - HOG (Dalal and Triggs 2005) of the whole frame: grey, resized by area to
//   64 x a height keeping the map's aspect (a multiple of 8: 48 for 4:3, 32
//   for 2:1), 16 x 16 blocks, 8 px stride, 8 x 8 cells, 9 orientations; the
//   answer is the keyframe of the largest cosine, its score that cosine.
// - SeqSLAM (Milford and Wyeth 2012, OpenSeqSLAM's parameters): the
//   patch-normalised grey thumbnail of the same size (8 x 8 patches,
//   feature/whole_image.h), the mean absolute difference of a query's to
//   every keyframe's, contrast-enhanced along the keyframe order (minus the
//   mean, over the standard deviation of the 10 keyframes on each side), and
//   lines through the last 10 queries at 0.8 to 1.2 keyframes per query
//   (steps of 0.1): the answer is the end of the line with the smallest
//   summed difference, its score minus that sum per query. Causal: a query's
//   answer uses it and the 9 before.
// Neither is placedb's own method (feature/whole_image_model.h and
// query/sequence.h are); they are the yardsticks of the literature.
#pragma once

#include <cstdint>
#include <deque>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "placedb/storage/keyframe.h"

namespace placedb {

enum class EvalBaseline { kNone = 0, kHog = 1, kSeqSlam = 2, kBoth = 3 };
const char* EvalBaselineName(EvalBaseline b);
// "none", "hog", "seqslam" or "both"; InvalidArgument otherwise.
EvalBaseline ParseEvalBaseline(const std::string& name);

// A baseline's answer to a query: its five best keyframes, best first
// (fewer for a smaller map), and the best one's score (larger: surer).
struct BaselineAnswer {
  std::vector<int32_t> ranked;
  double score = 0.0;
};

class ClassicBaselines {
 public:
  static constexpr int kSeqSlamLength = 10;  // queries a line spans
  static constexpr int kSeqSlamWindow = 10;  // keyframes on each side, contrast enhancement

  // `keyframes` and their whole frames `images` (8-bit grey, BGR or BGRA),
  // one each. The thumbnails' height keeps the first image's aspect; every
  // image is resized to it. InvalidArgument for none, or counts that differ.
  ClassicBaselines(const std::vector<Keyframe>& keyframes, const std::vector<cv::Mat>& images);

  // HOG's answer to a query frame.
  BaselineAnswer Hog(const cv::Mat& image) const;
  // SeqSLAM's answer to the next query frame of a sequence (the frames fed
  // so far are the ones before it).
  BaselineAnswer SeqSlam(const cv::Mat& image);

  int thumbnail_height() const { return height_; }

 private:
  cv::Mat HogRow(const cv::Mat& image) const;     // 1 x D CV_32F, L2-normalised
  cv::Mat Thumbnail(const cv::Mat& image) const;  // 1 x (64 x height) CV_8S

  int height_ = 0;
  std::vector<int32_t> ids_;  // by sequence order (timestamp when all have one, else id)
  cv::Mat hog_;               // a row per keyframe, sequence order
  cv::Mat thumbnails_;        // a row per keyframe, sequence order
  std::deque<std::vector<float>> differences_;  // enhanced, newest first
};

}  // namespace placedb
