// A keyframe's feature budget: the subset of a frame's features a database
// stores when it keeps fewer than extraction found (BuildOptions::
// stored_features), spread over the image rather than piled where the
// strongest corners are.
#pragma once

#include <cstddef>
#include <opencv2/core/types.hpp>
#include <vector>

#include "placedb/feature/types.h"

namespace placedb {

// The grid KeepSpread ranks features in: kSpreadColumns x kSpreadRows
// cells of equal size over the image.
constexpr int kSpreadColumns = 8;
constexpr int kSpreadRows = 6;

// Keeps at most `max_features` of `features` (0: all), spread over an image
// of `image_size`: every grid cell's strongest feature (by response) comes
// before any cell's second, and so on; within one round the stronger first,
// then the earlier. The kept features stay in their order, keypoints and
// descriptor rows together. Positions outside the image count in its
// nearest cell. Deterministic: the same features give the same subset.
// With `priority` (one value per feature, or empty: all equal), a feature
// of a higher priority comes before every feature of a lower one, and the
// rounds above run within each priority (builder/tracks.h: the features
// matched in more neighbouring keyframes first).
void KeepSpread(FeatureSet* features, size_t max_features, cv::Size image_size,
                const std::vector<int>& priority = {});

}  // namespace placedb
