// where_am_i DB IMAGE: which keyframe of a placedb database shows the place
// where IMAGE was taken, and that keyframe's pose.
#include <placedb/placedb.h>

#include <cstdio>
#include <exception>
#include <opencv2/imgcodecs.hpp>

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: where_am_i DB IMAGE\n");
    return 2;
  }
  try {
    const placedb::PlaceDatabase db = placedb::PlaceDatabase::Open(argv[1]);
    placedb::QueryOptions options;  // verified with RANSAC by default
    options.top_k = 3;
    const placedb::QueryResult result = db.Query(cv::imread(argv[2]), options);
    if (const placedb::RankedKeyframe* best = result.best()) {
      std::printf("keyframe %d (%d inliers of %d matches), %s\n", best->keyframe_id,
                  best->num_inliers, best->num_matches, best->source.c_str());
      if (best->pose) {
        const Eigen::Vector3d& t = best->pose->translation;
        std::printf("pose: t = (%.3f, %.3f, %.3f) m\n", t.x(), t.y(), t.z());
      }
    } else {
      std::printf("no match: a new place\n");
    }
    std::printf("%.1f ms, %zu keyframes examined\n", result.times.total_ms, result.num_examined);
    return 0;
  } catch (const placedb::NotFound& e) {
    std::fprintf(stderr, "where_am_i: %s\n", e.what());
    return 2;
  } catch (const placedb::Error& e) {
    std::fprintf(stderr, "where_am_i: %s (%s)\n", e.what(), placedb::ErrorKindName(e.kind()));
    return 1;
  }
}
