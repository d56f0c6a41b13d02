// The session API: one open database with the extractor its queries need.
// Every client (the CLI, eval, ROS nodes, Python) opens and queries a
// database through this class.
//
//   placedb::PlaceDatabase db = placedb::PlaceDatabase::Open("office.db");
//   placedb::QueryResult r = db.Query(cv::imread("frame.png"));
//   if (const placedb::RankedKeyframe* best = r.best()) use(best->keyframe_id, best->pose);
//
// Thread-safety contract:
// - Every const method may run on any number of threads at once, and at the
//   same time as the writers Add, Remove and Save on other threads.
// - What a method returns is a value or a copy (FindKeyframe, manifest_json,
//   keyframe_ids, ...): it stays valid whatever writers do afterwards. (The
//   library's own readers, eval and the benchmarks, take a StorageView,
//   session/storage_view.h, which holds the read lock while it lives.)
// - A query sees the keyframes as they were when it started; an addition or
//   removal becomes visible all at once. The deadline of a query
//   (QueryOptions::deadline_ms) starts before it waits for a writer to
//   publish, and the wait counts against it: a query whose deadline passes
//   while it waits returns no answer, deadline_reached set, nothing examined.
// - Writers are serialised within a session. Across processes, one session
//   changes a database at a time: the first Add or Remove takes the
//   database folder's lock (flock) until Save or the session's end; another
//   process's writer is refused with a clear error, and so is a session
//   whose database was rewritten on disk since it opened.
// - Moving or destroying a PlaceDatabase while other threads use it is not
//   allowed (as for any object).
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "placedb/builder/build.h"
#include "placedb/dataset/frame.h"
#include "placedb/feature/options.h"
#include "placedb/query/result.h"
#include "placedb/retrieval/options.h"
#include "placedb/storage/keyframe.h"
#include "placedb/storage/keyframe_subset.h"
#include "placedb/util/option_table.h"

namespace placedb {

class StorageView;

struct OpenOptions {
  // Which keyframes to open: all (default), partition i of N, or an id list.
  KeyframeSubset subset;
  // When set, a database of another feature type is an error naming both.
  std::optional<FeatureType> expected_features;
  // Threads each query uses for matching and verification; 0 = one per core.
  // Range [0, 1024]. Default 1.
  int threads = 1;
  // How keyframes are grouped for cluster search (made when the database
  // opens, from the keyframes' poses or their order).
  ClusterOptions clusters;
  // Open only the keyframe table (ids, poses, crops, sources), not the
  // keypoints and descriptors: a session that cannot query or change, but
  // opens in a fraction of the time (a ROS voter, which only needs the
  // poses of answers; the extractor node, which needs only the settings).
  // Default false.
  bool keyframe_table = false;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<OpenOptions>& Table();
  std::string Check() const;
};

class PlaceDatabase {
 public:
  // Opens the database directory `dir`: loads the keyframes (or the subset),
  // reads every build setting from the manifest and checks it (the feature
  // options must also agree with the stored descriptors), and creates the
  // extractor queries need. Errors: NotFound for no database at `dir`,
  // CorruptDatabase for a damaged one, InvalidArgument for bad options or a
  // feature type other than options.expected_features. Opening the whole database also
  // sweeps the debris of killed writers (temporary files of processes that
  // are gone, keyframe and index files the manifest does not name, PNGs no
  // keyframe names) when no other process is changing it and the folder is
  // writable.
  static PlaceDatabase Open(const std::string& dir, const OpenOptions& options = OpenOptions());

  PlaceDatabase(PlaceDatabase&&) noexcept;
  PlaceDatabase& operator=(PlaceDatabase&&) noexcept;
  ~PlaceDatabase();

  // Fixed for the session's life (Save does not change them).
  const std::string& directory() const;
  const BuildOptions& build_options() const;
  const ExtractorOptions& extractor_options() const;
  FeatureType feature_type() const;
  // What it was opened on: all keyframes, a partition, an id list.
  const KeyframeSubset& subset() const;
  // Bytes per descriptor row (ORB 32; SURF 256 or 512).
  int descriptor_bytes() const;

  // Snapshots: copies taken under the read lock, valid forever.
  // The manifest as JSON text: every build setting, counts, sizes, creation
  // info (`indent` -1: one line).
  std::string manifest_json(int indent = -1) const;
  // The name of the keyframe file the session reads, which names the
  // database's generation: it changes with every save, so two processes
  // that give the same name read the same keyframes (ROS workers and their
  // voter check it).
  std::string generation() const;
  // Bytes of that keyframe file.
  uint64_t keyframes_bytes() const;
  // Descriptor rows of the keyframes answering now.
  size_t num_features() const;
  // Keyframes answering now (removed ones left out).
  size_t size() const;
  bool empty() const { return size() == 0; }
  // The keyframe with this id (a copy), or nullopt (none, or removed).
  std::optional<Keyframe> FindKeyframe(int32_t id) const;
  // The ids of the keyframes answering now, in storage order.
  std::vector<int32_t> keyframe_ids() const;
  // Those keyframes (copies), in storage order.
  std::vector<Keyframe> keyframes() const;
  // The features of keyframe `id` (a copy); InvalidArgument when
  // there is no such keyframe.
  FeatureSet KeyframeFeatures(int32_t id) const;
  // Path of a keyframe's stored PNG ("" when the database keeps none).
  std::string StoredImagePath(const Keyframe& keyframe) const;

  // The query features of an image, as Query(image) computes them: an 8-bit
  // gray, BGR or BGRA frame, full and uncropped. An empty image or another
  // depth is InvalidArgument.
  FeatureSet Extract(const cv::Mat& image) const;

  // Where was this frame taken? retrieve -> match -> verify -> decide.
  QueryResult Query(const cv::Mat& image, const QueryOptions& options = QueryOptions()) const;
  // The same for features computed elsewhere (another node, another process).
  // They are validated against the database (InvalidArgument).
  QueryResult Query(const FeatureSet& features, const QueryOptions& options = QueryOptions()) const;
  // Both restricted to the keyframes `keyframe_ids` (a partition, a
  // cluster, the recent keyframes left out of a loop-closure search): only
  // those are examined. An id that is not in the database is
  // InvalidArgument; removed keyframes among them are left out.
  QueryResult QueryAmong(const cv::Mat& image, const std::vector<int32_t>& keyframe_ids,
                         const QueryOptions& options = QueryOptions()) const;
  QueryResult QueryAmong(const FeatureSet& features, const std::vector<int32_t>& keyframe_ids,
                         const QueryOptions& options = QueryOptions()) const;

  // Why keyframe `keyframe_id` matched `features` (or did not): the match
  // and verify stages on it alone, every match kept (MatchKeyframe). For
  // pictures and diagnostics. InvalidArgument for an unknown id.
  MatchDetail Explain(const FeatureSet& features, int32_t keyframe_id,
                      const QueryOptions& options = QueryOptions()) const;

  // ---- Online mapping: the robot keeps mapping while it localises ----------
  // Adds a keyframe made from `image` (8-bit gray, BGR or BGRA) as the
  // database was built: crop, resize, features, the stored PNG when the
  // database keeps images. `frame` gives its id (>= 1, new), timestamp, pose
  // and source path. The work is done before the keyframe is published:
  // queries wait only while it is appended, and see it whole or not at all.
  // Writers are serialised. InvalidArgument for a taken id, a bad
  // image or a session opened on a subset (open the whole database).
  void Add(const Frame& frame, const cv::Mat& image);
  // The same with features computed elsewhere (in the stored image's frame).
  void Add(Keyframe keyframe, const FeatureSet& features);
  // Takes keyframe `id` out of every later answer; false when there is no
  // such keyframe. Its storage is reclaimed by Save.
  bool Remove(int32_t id);
  // Keyframes added or removed since the database was opened or saved.
  size_t num_pending_changes() const;
  // Writes the keyframes as they are now back to directory(), crash-safely
  // (the previous generation stays until the new manifest is in place),
  // rebuilding the bag-of-words index with the same vocabulary. The session
  // then reads the saved generation: it answers as a reopened database does.
  // Debris of earlier crashes (temporary files, files no manifest names,
  // PNGs no keyframe names) is swept. Refused (InvalidArgument) for a
  // session opened on a subset: that would replace the whole database.
  void Save();

 private:
  friend class StorageView;  // session/storage_view.h: the library's own readers
  struct Impl;
  explicit PlaceDatabase(std::unique_ptr<Impl> impl);
  QueryResult Run(const FeatureSet& features, const std::vector<int32_t>* among,
                  const QueryOptions& options, double extract_ms) const;
  void AddLocked(Keyframe keyframe, const FeatureSet& features);
  void BeginChange();
  std::unique_ptr<Impl> impl_;
};

}  // namespace placedb
