// Test support: the sample database tests build (header only, for tests).
#pragma once

#include <string>

#include "placedb/builder/builder.h"
#include "placedb/dataset/image_folder.h"

namespace placedb {
namespace testing_util {

#ifdef PLACEDB_DATA_DIR
// Images 1..40 of the shipped RTAB-Map loop sequence as a database in `dir`
// (2 threads, no stored images, quiet), with a bag-of-words index of a small
// vocabulary (depth 3: 40 images) or, with IndexKind::kNone, without one.
inline void BuildSampleDatabase(const std::string& dir, IndexKind index = IndexKind::kBow) {
  BuildOptions options;
  options.threads = 2;
  options.progress = false;
  options.store_images = false;
  options.index = index;
  options.vocabulary.depth = 3;
  BuildDatabase(ListImageFolder(PLACEDB_DATA_DIR "/rtabmap_loop/images", 1, 40), options, dir,
                "rtabmap 1..40");
}
#endif

}  // namespace testing_util
}  // namespace placedb
