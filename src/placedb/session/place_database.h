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
  // After the open, a background thread asks the kernel to read the
  // database's index and keyframe files into its page cache (madvise
  // MADV_WILLNEED), so that the first queries do not wait for the disk; the
  // open itself does not wait, and the process's resident memory does not
  // grow by it (the page cache is the kernel's, given back under memory
  // pressure). Then it checks every posting list of the index, then every
  // keyframe's vector and direct entries (their block checksums and values,
  // what a query checks on first use), which maps them into the process:
  // its file-backed resident memory grows by the index file (317 MiB of
  // postings at 100 000 keyframes, which every query reads all over and
  // the resident limit keeps, and the keyframe blocks, which a query reads
  // for each of its candidates), so that the first queries pay neither the
  // checks nor a page fault per list or candidate. Last, while no query
  // runs, it checks every keyframe's features in the keyframe file, reading
  // them (pread) rather than mapping them: resident memory does not grow by
  // it. A damaged block is left for the query that reads it to report. Only
  // for a session on the whole database. Default true; false leaves
  // everything to the queries (resident memory follows their use alone).
  bool prefetch = true;
  // While, after a query, this process's file-backed resident memory (the
  // pages of mapped files it has touched) is above this many MiB, the
  // session lets go of the next 8 MiB slice of the database's files (a
  // cursor going round them), on a thread of its own that the query only
  // wakes (WaitForBackgroundWork waits for it): madvise MADV_DONTNEED, the
  // pages stay in the page cache and the next read maps them again at the
  // cost of a minor page fault. So the resident memory follows recent use, not everything ever
  // read, at a cost per query (minor faults where pages were let go; README,
  // "Retrieval at scale", measures it). The measure is the process's
  // (/proc/self/statm): other mapped files count too. Range [0, 1048576];
  // 0 (default): no limit, every page read stays mapped until the session
  // closes (clean pages the kernel may still reclaim under pressure).
  int resident_limit_mb = 0;
  // Queries read the features of the keyframes they examine from the
  // keyframe file (pread, into a buffer of the query's) instead of through
  // its mapping (LoadOptions::read_features): the file's pages stay in the
  // kernel's page cache and do not count in this process's resident
  // memory, which then stays near what the open and the index take however
  // many keyframes the queries examine (README, "Retrieval at scale",
  // measures it), at the cost of one read per examined keyframe (about
  // 5 us here; exhaustive search reads every keyframe). Answers are the
  // same, and every byte is still checked before it is used (the bytes read
  // are checked when the keyframe's first use is a read). The whole-image
  // rows stay mapped (every query with the channel scans them: 512 bytes a
  // keyframe with the HOG channel). Only for a version 3 database opened
  // with its features. Default false.
  bool read_features = false;
  // The same, decided by the map's size: queries read the features when the
  // database's keyframe file is larger than this many MiB, so that a map
  // too large to keep mapped (100 000 keyframes of ~400 ORB features: a
  // 1.7 GiB keyframe file; of 210: 0.9 GiB) does not grow the process by it
  // (with the index's pages beside it, a mapped 512 MiB keyframe file keeps
  // the process under 1 GB), while a smaller one (10 000 keyframes: 170 MiB)
  // keeps the mapping's speed (reading costs about 0.16 ms a query at
  // 10 000 keyframes here; at 100 000, where a mapped session's queries pay
  // for their first touches of pages instead, it cost +0.03 to +0.13 ms at
  // p50 in two of three runs: README, "Retrieval at scale").
  // reads_features() says what was chosen.
  // Range [0, 1048576]; 0: size never decides (read_features alone does).
  // Default 512.
  int read_features_above_mb = 512;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<OpenOptions>& Table();
  std::string Check() const;
};

// How PlaceDatabase::AddFrames numbers the frames it adds and which it
// leaves out.
struct AddOptions {
  // The id of the first frame given: the k-th frame given (1-based) gets
  // id_offset + k - 1, skipped frames leaving their ids unused. 0 (default):
  // the frames added get the ids after the largest the database ever held
  // (KeyframeIdSummary::next_free), in order. Range [0, 2^31).
  int id_offset = 0;
  // Each frame's id is the number its file name is (042.jpg: 42, the
  // extension dropped): digits only, at least 1, below 2^31. Any other name
  // (frame_042.jpg, -4.jpg, 1e3.png, a bag frame) is refused before
  // anything is read. Not together with id_offset. Default false.
  bool ids_from_names = false;
  // A frame the database already holds (a keyframe of the same source path
  // and the same source_hash, the file's content; by path alone for a
  // keyframe saved without a hash) is left out instead of being an error.
  // A frame with the path of a keyframe but other content is added (a new
  // keyframe; the old one stays). Default false.
  bool skip_existing = false;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<AddOptions>& Table();
  std::string Check() const;
};

// What AddFrames did.
struct AddReport {
  size_t added = 0;
  // Left out (skip_existing): already in the database, same source path and
  // content; of them, `skipped_by_path` matched a keyframe saved without a
  // source hash by its path alone.
  size_t skipped = 0;
  size_t skipped_by_path = 0;
  // Left out (skip_existing): the same image as an earlier frame given.
  size_t repeated = 0;
  // Added although a keyframe has the same source path: the content differs.
  std::vector<std::string> changed_sources;
  // Per frame given: the id it was added as, or the id of the keyframe that
  // already holds it (skipped).
  std::vector<int32_t> ids;
  // The smallest and largest id added (0 when none was).
  int32_t first_id = 0, last_id = 0;
};

// The keyframe ids of a database (placedb info).
struct KeyframeIdSummary {
  size_t count = 0;   // keyframes answering now
  int32_t first = 0;  // the smallest and largest of their ids (0 when none)
  int32_t last = 0;
  // The id AddFrames gives the next new frame by default: after the largest
  // id the database ever held (also removed keyframes'), so an id is never
  // given to another place. 2^31 when no id is left.
  int64_t next_free = 1;
  // Keyframes removed since `removed_since` (saved, and this session's
  // pending removals); nullopt when not recorded: a database an earlier
  // placedb wrote, not saved since (counting starts with the next save).
  std::optional<uint64_t> removed;
  std::string removed_since;  // ISO 8601 UTC; "" when not recorded
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
  // Values per keyframe of the whole-image channel (feature/whole_image.h;
  // whole_image_width x whole_image_height), 0 when the database has none
  // (built with --no-whole-image, or by an earlier placedb).
  int whole_image_dims() const;

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
  // Whether queries read the keyframes' features from the file now
  // (OpenOptions::read_features, read_features_above_mb) rather than
  // through its mapping: false for a database whose features are held in
  // memory (a version 2 file, a changed database) or a keyframe table.
  bool reads_features() const;
  // The keyframe with this id (a copy), or nullopt (none, or removed).
  std::optional<Keyframe> FindKeyframe(int32_t id) const;
  // The ids of the keyframes answering now, in storage order.
  std::vector<int32_t> keyframe_ids() const;
  // Those keyframes (copies), in storage order.
  std::vector<Keyframe> keyframes() const;
  // The features of keyframe `id` (a copy); InvalidArgument when
  // there is no such keyframe.
  FeatureSet KeyframeFeatures(int32_t id) const;
  // The whole-image similarity of `query` (its FeatureSet::whole_image, as
  // Extract gives it) to every keyframe answering now, in the order of
  // keyframes(): what SequenceMatcher::Feed over the whole map takes. Empty
  // when the database has no whole-image channel or the query no row;
  // InvalidArgument for a row of another size. One pass of the SIMD kernel
  // over every row (feature/whole_image.h).
  std::vector<float> WholeImageSimilarities(const FeatureSet& query) const;
  // The ids: range, next free id, removals.
  KeyframeIdSummary id_summary() const;
  // What `placedb info --json` prints: the manifest, its "ids" entry
  // completed by id_summary() (count, first, last, next_free, removed: null
  // when not recorded, removed_since).
  std::string info_json(int indent = -1) const;
  // Checks every byte of the database now: the keyframe file's features and
  // whole-image rows, and the bag-of-words index's blocks, which version 3
  // keyframe files and version 2 index files otherwise check when they are
  // first used (storage/database.h and retrieval/bow_index.h, "Integrity");
  // and the inverted file against the keyframe vectors. What `placedb
  // verify` runs. CorruptDatabase naming the
  // first damage found; a session opened as a keyframe table has no
  // features to check (InvalidArgument).
  struct VerifyReport {
    size_t keyframes = 0;          // whose features were checked
    uint64_t keyframes_bytes = 0;  // the keyframe file
    uint32_t format_version = 0;   // the keyframe file's
  };
  VerifyReport Verify() const;
  // Waits until the background work asked for so far is done: the prefetch
  // pass (OpenOptions::prefetch) and the releases queries asked for until
  // now (OpenOptions::resident_limit_mb). Answers never depend on it; it is
  // for measuring memory (benchmarks, tests) at a settled point.
  void WaitForBackgroundWork() const;
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
  // Query(image, options), and into `*whole_image_similarities` (when not
  // null) WholeImageSimilarities of the same query features: what
  // SequenceMatcher::Feed(frame, similarities) takes to search the whole map.
  QueryResult Query(const cv::Mat& image, const QueryOptions& options,
                    std::vector<float>* whole_image_similarities) const;
  // Both restricted to the keyframes `keyframe_ids` (a partition, a
  // cluster, the recent keyframes left out of a loop-closure search): only
  // those are examined. An id that is not in the database is
  // InvalidArgument; removed keyframes among them are left out.
  QueryResult QueryAmong(const cv::Mat& image, const std::vector<int32_t>& keyframe_ids,
                         const QueryOptions& options = QueryOptions()) const;
  QueryResult QueryAmong(const FeatureSet& features, const std::vector<int32_t>& keyframe_ids,
                         const QueryOptions& options = QueryOptions()) const;

  // A bag-of-words search split over partitions, exactly (query/result.h,
  // MergeShortlists): every partition's process opens the whole database
  // (mapped: its memory follows what its share reads) and sends
  // BowShortlist(features, its keyframe ids, options); the voter merges
  // them with MergeShortlists(parts, options); every partition then answers
  // QueryAmong(features, the merged candidates of its share, the options
  // with exhaustive retrieval and ForPartition()), and MergeQueryResults
  // gives the whole database's bag-of-words answer. `keyframe_ids`:
  // nullptr, every keyframe. InvalidArgument for other search methods, a
  // database without a bag-of-words index, an unknown id, or a session
  // opened on a subset or as a keyframe table.
  Shortlist BowShortlist(const FeatureSet& features, const std::vector<int32_t>* keyframe_ids,
                         const QueryOptions& options) const;

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
  // `source_hash` is recorded as Keyframe::source_hash (SourceHash of the
  // image's file; 0: none).
  void Add(const Frame& frame, const cv::Mat& image, uint64_t source_hash = 0);
  // Adds frames of a source (an image folder, a TUM folder, a bag) as
  // keyframes, numbered and filtered by `options`: every frame's id is
  // settled, its image read (once, with its source hash) and checked before
  // the first is added, so a bad frame, a taken id or a frame already held
  // (without skip_existing) changes nothing. Poses and timestamps are the
  // frames'. InvalidArgument for those errors and for no frames; NotFound
  // for a missing image. Does not save. `progress`: a progress bar on a
  // terminal.
  AddReport AddFrames(const std::vector<Frame>& frames, const AddOptions& options = AddOptions(),
                      bool progress = false);
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
