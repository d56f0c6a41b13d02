// Test-only: extraction options whose whole-image rows need no model of a
// map, for tests that make databases in memory rather than by a build (the
// default HOG channel's rows are projected by the model a build fits).
#pragma once

#include "placedb/feature/options.h"

namespace placedb {
namespace testing {

// The defaults with SeqSLAM's thumbnail as the whole-image descriptor.
inline ExtractorOptions ModelFreeExtractorOptions() {
  ExtractorOptions o;
  o.whole_image.kind = WholeImageKind::kThumbnail;
  return o;
}

}  // namespace testing
}  // namespace placedb
