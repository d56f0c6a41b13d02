// The two nearest neighbours found so far in a scan over candidates, for any
// distance type (Hamming counts, squared L2 floats).
#pragma once

#include <limits>

namespace placedb {

template <typename Distance>
struct TwoNearestOf {
  // "No candidate yet": +infinity for floats, the largest value otherwise.
  static constexpr Distance kNone = std::numeric_limits<Distance>::has_infinity
                                        ? std::numeric_limits<Distance>::infinity()
                                        : std::numeric_limits<Distance>::max();
  Distance best = kNone;
  Distance second = kNone;
  int best_index = -1;  // -1 while there is no candidate

  // Takes candidate `index` at distance `d`; ties keep the lower index when
  // candidates arrive in index order.
  void Update(Distance d, int index) {
    if (d < best) {
      second = best;
      best = d;
      best_index = index;
    } else if (d < second) {
      second = d;
    }
  }
};

}  // namespace placedb
