// A consistent view of a session's storage, for code of the library that
// needs the Database itself (evaluation, benchmarks, baselines, tests that
// run the query stages by hand). Not part of the public face.
//
// It holds the session's read lock while it lives: a writer waits for every
// view in flight before it publishes, so a thread that holds a view must not
// call Add, Remove or Save (it would wait for itself), and views are meant
// to be short. Holding one, a thread may call every const method of the
// session (its nested reads never wait for a writer). A view is destroyed on
// the thread that made it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <mutex>
#include <shared_mutex>
#include <vector>

#include "placedb/retrieval/clusters.h"
#include "placedb/retrieval/growing_bow_index.h"
#include "placedb/session/place_database.h"
#include "placedb/storage/database.h"
#include "placedb/util/fair_shared_mutex.h"

namespace placedb {

class ThreadPool;

class StorageView {
 public:
  explicit StorageView(const PlaceDatabase& session);

  // The keyframes, removed ones included (removed(i) tells them).
  const Database& database() const { return *db_; }
  // The bag-of-words index (nullptr when the database was built without
  // one).
  const GrowingBowIndex* bow_index() const { return bow_; }
  // The spatial-locality clusters of the opened keyframes.
  const ClusterSet& clusters() const { return *clusters_; }
  // Whether keyframe index `index` was removed (online, not yet saved).
  bool removed(size_t index) const { return (*removed_)[index] != 0; }
  // The excluded mask QueryContext takes (nullptr when none is removed).
  const std::vector<uint8_t>* excluded() const {
    return num_removed_ > 0 ? removed_ : nullptr;
  }
  // The pool the session's queries run on (nullptr for one thread).
  ThreadPool* pool() const { return pool_; }

 private:
  std::shared_lock<FairSharedMutex> lock_;
  const Database* db_ = nullptr;
  const GrowingBowIndex* bow_ = nullptr;
  const ClusterSet* clusters_ = nullptr;
  const std::vector<uint8_t>* removed_ = nullptr;
  size_t num_removed_ = 0;
  ThreadPool* pool_ = nullptr;
};

}  // namespace placedb
