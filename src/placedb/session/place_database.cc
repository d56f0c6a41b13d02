#include "placedb/session/place_database.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <shared_mutex>
#include <thread>
#include <unordered_map>
#include <unordered_set>

#include "placedb/builder/builder.h"
#include "placedb/feature/extractor.h"
#include "placedb/query/query.h"
#include "placedb/session/storage_view.h"
#include "placedb/feature/whole_image.h"
#include "placedb/feature/whole_image_model.h"
#include "placedb/storage/folder.h"
#include "placedb/storage/whole_image_model_file.h"
#include "placedb/util/check.h"
#include "placedb/util/fair_shared_mutex.h"
#include "placedb/util/file_io.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/mapped_file.h"
#include "placedb/util/options.h"
#include "placedb/util/progress.h"
#include "placedb/util/thread_pool.h"
#include "placedb/util/timer.h"

namespace placedb {
namespace fs = std::filesystem;

struct PlaceDatabase::Impl {
  ~Impl();

  std::string dir;
  // Fixed at open (read without the lock: Save swaps `db`).
  bool whole = true;               // opened on the whole database
  std::string subset_description;  // what it was opened on, when not
  KeyframeSubset subset;
  int descriptor_bytes = 32;
  bool keyframe_table = false;  // opened without features: no queries
  FeatureType feature_type = FeatureType::kOrb;
  Database db;
  BuildOptions build;
  std::unique_ptr<FeatureExtractor> extractor;
  std::unique_ptr<ThreadPool> pool;
  OpenOptions open;
  std::shared_ptr<const Vocabulary> vocabulary;
  std::optional<GrowingBowIndex> bow;
  ClusterSet clusters;
  // One candidate's cost in recent queries under a deadline.
  mutable CandidateCost candidate_cost;
  // Online mapping. Queries and Views hold `state` shared; a writer holds
  // it exclusively only to publish a prepared change. Writers take `writer`
  // first, one at a time; everything below `state` changes only under both.
  mutable FairSharedMutex state;
  std::mutex writer;
  std::vector<uint8_t> removed;  // per keyframe index, 1 = removed
  size_t num_removed = 0;
  size_t pending = 0;
  // Held (under `writer`) from the first change until Save: no other
  // process changes the folder meanwhile, nor sweeps the PNGs of additions
  // not yet saved.
  std::unique_ptr<DirectoryLock> folder_lock;
  // PNGs written by additions not yet saved (removed if never saved).
  std::vector<std::string> unsaved_images;
  // The manifest's "ids" entry (builder/builder.h, IdsEntry) as read at open
  // or the last save; for a manifest without one, next_free 1 (the largest
  // id decides) and removals not recorded.
  int64_t stored_next_free = 1;
  std::optional<uint64_t> stored_removed;
  std::string removed_since;

  // A query's context (under `state`): the restriction `ids` (nullptr:
  // none) as the sorted indices the stages take, into *among (InvalidArgument
  // for an id not in the database), removed keyframes left out by a mask each
  // stage tests (no per-query work for them), the pool, the indexes.
  QueryContext Context(const std::vector<int32_t>* ids, std::vector<uint32_t>* among) const;

  // The files read into the page cache after the open (OpenOptions::prefetch),
  // by `prefetcher` until done or `stop_background`.
  std::thread prefetcher;
  std::atomic<bool> stop_background{false};
  // Queries running now (Run, BowShortlist): the prefetch thread's check of
  // the keyframes' features waits while there are any (it reads and sums
  // the whole file, and a query beside it would share the memory bandwidth
  // and caches of this machine's two cores).
  mutable std::atomic<int> queries_running{0};
  struct QueryRunning {
    explicit QueryRunning(const Impl& m) : m(m) { m.queries_running.fetch_add(1); }
    ~QueryRunning() { m.queries_running.fetch_sub(1); }
    const Impl& m;
  };
  void StartPrefetch();
  // OpenOptions::resident_limit_mb: a query over the limit only asks
  // `releaser` (a thread of its own, started at open) to let go of pages;
  // the thread, while the process's file-backed resident memory is above
  // the limit, lets go of the next slice of the database files (a cursor
  // going round the index file but its postings, then the keyframe file).
  // So no query pays for the release (madvise and its TLB flushes), only for
  // the minor faults of pages it reads again.
  std::thread releaser;
  mutable std::atomic<uint64_t> release_cursor{0};
  void StartReleaser();
  void AskForRelease() const;
  void ReleaseWhileOverLimit() const;
  // What WaitForBackgroundWork waits for, under `background`: the prefetch
  // pass done (or never started), releases asked for and served.
  mutable std::mutex background;
  mutable std::condition_variable background_changed;
  bool prefetch_done = true;
  mutable uint64_t releases_asked = 0;
  uint64_t releases_served = 0;
  void WaitForBackgroundWork() const;
};

void PlaceDatabase::Impl::StartPrefetch() {
  // The index first (every query reads postings all over it), and the
  // checks the first queries would make of its posting lists, on a copy of
  // the index (it shares the file and what is checked, and stays valid when
  // Save replaces the session's index); then the keyframe file.
  std::optional<BowIndex> index;
  if (bow && bow->base().mapped_file()) index.emplace(bow->base());
  std::shared_ptr<const MappedFile> keyframes = db.mapped_file();
  if (!index && !keyframes) return;
  prefetch_done = false;
  prefetcher = std::thread([index = std::move(index), keyframes = std::move(keyframes), this] {
    if (index) {
      index->mapped_file()->Prefetch(stop_background);
      index->CheckInBackground(stop_background);
    }
    if (keyframes) {
      keyframes->Prefetch(stop_background);
      // Then the checks the first queries would make of their candidates'
      // features, reading the file rather than mapping it (the resident
      // memory stays what queries read), 16 keyframes (~0.1 ms) at a time
      // while no query runs, under `state` (a writer waits for no more). A
      // read error leaves the rest to the queries, which report it.
      try {
        std::vector<uint8_t> buffer;
        size_t next = 0;
        // While queries keep running, it looks again after 1, 2, 4 ... up
        // to 64 ms (a busy session does not wake it a thousand times a
        // second), and after 1 ms again once it has found a gap.
        constexpr std::chrono::milliseconds kFirstWait{1}, kLongestWait{64};
        std::chrono::milliseconds wait = kFirstWait;
        for (bool more = true; more && !stop_background.load(std::memory_order_relaxed);) {
          if (queries_running.load() > 0) {
            std::this_thread::sleep_for(wait);
            wait = std::min(2 * wait, kLongestWait);
            continue;
          }
          wait = kFirstWait;
          const std::shared_lock<FairSharedMutex> hold(state);
          more = db.CheckSomeInBackground(&next, 16, &buffer);
        }
      } catch (const std::exception&) {
      }
    }
    const std::lock_guard<std::mutex> lock(background);
    prefetch_done = true;
    background_changed.notify_all();
  });
}

void PlaceDatabase::Impl::StartReleaser() {
  releaser = std::thread([this] {
    std::unique_lock<std::mutex> lock(background);
    for (;;) {
      background_changed.wait(
          lock, [this] { return stop_background.load() || releases_served < releases_asked; });
      if (stop_background) return;
      const uint64_t asked = releases_asked;
      lock.unlock();
      ReleaseWhileOverLimit();
      lock.lock();
      releases_served = asked;
      background_changed.notify_all();
    }
  });
}

void PlaceDatabase::Impl::AskForRelease() const {
  if (open.resident_limit_mb <= 0) return;
  {
    const std::lock_guard<std::mutex> lock(background);
    ++releases_asked;
  }
  background_changed.notify_all();
}

void PlaceDatabase::Impl::WaitForBackgroundWork() const {
  std::unique_lock<std::mutex> lock(background);
  const uint64_t asked = releases_asked;
  background_changed.wait(lock, [&] { return prefetch_done && releases_served >= asked; });
}

void PlaceDatabase::Impl::ReleaseWhileOverLimit() const {
  constexpr uint64_t kSlice = uint64_t{8} << 20;
  // At most this many slices under one hold of `state`: a writer waiting to
  // publish waits for no more.
  constexpr int kSlicesPerHold = 8;
  const uint64_t limit = static_cast<uint64_t>(open.resident_limit_mb) << 20;
  // At most one lap of the files a pass: what else is mapped (libraries,
  // other files) may keep the process above the limit whatever is let go.
  uint64_t released = 0;
  for (;;) {
    if (stop_background || ProcessFileBackedResidentBytes() <= limit) return;
    // The files may change under a writer (Save): they are read under `state`.
    const std::shared_lock<FairSharedMutex> hold(state);
    // What may be let go: the keyframe file, and the index file but for its
    // posting lists (every query reads some of them, all over the section).
    struct Region {
      const MappedFile* file;
      uint64_t offset, bytes;
    };
    std::vector<Region> regions;
    if (const MappedFile* f = db.mapped_file().get()) regions.push_back({f, 0, f->size()});
    if (bow && bow->base().mapped_file()) {
      const MappedFile* f = bow->base().mapped_file().get();
      const auto [at, bytes] = bow->base().PostingsExtent();
      if (at + bytes <= f->size()) {
        regions.push_back({f, 0, at});
        regions.push_back({f, at + bytes, f->size() - at - bytes});
      }
    }
    uint64_t total = 0;
    for (const Region& r : regions) total += r.bytes;
    if (released >= total) return;
    for (int i = 0; i < kSlicesPerHold && released < total; ++i) {
      if (i > 0 && (stop_background || ProcessFileBackedResidentBytes() <= limit)) return;
      // The next slice: from the cursor to at most kSlice on, ending where
      // its region ends, so that slices tile the regions lap after lap.
      const uint64_t cursor = release_cursor.load(std::memory_order_relaxed) % total;
      uint64_t start = 0;
      for (const Region& r : regions) {
        if (cursor < start + r.bytes) {
          const uint64_t length = std::min(kSlice, start + r.bytes - cursor);
          r.file->ReleaseResidentPages(r.offset + (cursor - start), length);
          release_cursor.store(cursor + length, std::memory_order_relaxed);
          released += length;
          break;
        }
        start += r.bytes;
      }
    }
  }
}

QueryContext PlaceDatabase::Impl::Context(const std::vector<int32_t>* ids,
                                          std::vector<uint32_t>* among) const {
  among->clear();
  if (ids != nullptr) {
    among->reserve(ids->size());
    for (const int32_t id : *ids) {
      const int index = db.IndexOfId(id);
      if (index < 0) PLACEDB_THROW_INVALID("no keyframe ", id, " in the database ", dir);
      among->push_back(static_cast<uint32_t>(index));
    }
    std::sort(among->begin(), among->end());
    among->erase(std::unique(among->begin(), among->end()), among->end());
  }
  QueryContext context;
  context.bow = bow ? &*bow : nullptr;
  context.clusters = &clusters;
  context.among = ids != nullptr ? among : nullptr;
  if (num_removed > 0) {
    context.excluded = &removed;
    context.num_excluded = num_removed;
  }
  context.pool = pool.get();
  context.image_dir = dir;
  return context;
}

namespace {
// Removes the stored images `names` ("images/<name>") of the folder `dir`,
// never through a symlinked images/ (storage/folder.h). Best effort.
void RemoveStoredImages(const std::string& dir, const std::vector<std::string>& names) {
  if (names.empty()) return;
  try {
    const std::unique_ptr<DirectoryHandle> images =
        DirectoryHandle::OpenChild(DirectoryHandle(dir), kStoredImageFolder);
    if (!images) return;
    for (const std::string& name : names)
      images->RemoveRegularFile(fs::path(name).filename().string());
  } catch (const Error& e) {
    spdlog::warn("{}: cannot remove stored images: {}", dir, e.what());
  }
}
}  // namespace

PlaceDatabase::Impl::~Impl() {
  {
    const std::lock_guard<std::mutex> lock(background);
    stop_background = true;
  }
  background_changed.notify_all();
  if (prefetcher.joinable()) prefetcher.join();
  if (releaser.joinable()) releaser.join();
  // This session's images of keyframes it did not save (it still holds the
  // folder's lock: `folder_lock` goes after this body).
  RemoveStoredImages(dir, unsaved_images);
}

namespace {

// The bag-of-words index named by the manifest: mapped in place for the
// whole database, rebuilt in memory from its vocabulary for a subset (the
// stored index numbers the whole file's keyframes).
std::optional<BowIndex> OpenBowIndex(const std::string& dir, const Database& db,
                                     const BuildOptions& build, ThreadPool* pool,
                                     std::shared_ptr<const Vocabulary>* vocabulary_out) {
  const nlohmann::json& manifest = db.info();
  if (!manifest.contains("index")) return std::nullopt;
  const JsonReader index(manifest["index"], dir + "/manifest.json: index",
                         JsonOrigin::kDatabaseFile);
  if (index.String("kind") != "bow") index.Fail("kind", "is not bow");
  const std::string vocabulary_name = index.String("vocabulary");
  const std::string bow_name = index.String("bow");
  if (vocabulary_name != kVocabularyFile) index.Fail("vocabulary", "is not a vocabulary file name");
  if (!IsBowIndexFileName(bow_name)) index.Fail("bow", "is not a bag-of-words index file name");
  const DirectoryHandle handle(dir);
  auto map = [&](const std::string& name) {
    std::shared_ptr<const MappedFile> file = handle.MapFile(name);
    if (!file) {
      PLACEDB_THROW_CORRUPT("database ", dir, " is incomplete: ", name,
                            " (named by its manifest) is missing");
    }
    return file;
  };
  const std::string shown_vocabulary = (fs::path(dir) / vocabulary_name).string();
  auto vocabulary = std::make_shared<const Vocabulary>(
      Vocabulary::FromMapped(map(vocabulary_name), shown_vocabulary));
  if (vocabulary->type() != db.feature_type() || vocabulary->row_bytes() != db.descriptor_bytes()) {
    PLACEDB_THROW_CORRUPT(shown_vocabulary, " is for other descriptors than the database's ",
                          "(corrupted database)");
  }
  *vocabulary_out = vocabulary;
  if (!db.subset().all()) {
    return BowIndex::Build(vocabulary, db, build.bow, pool, nullptr);
  }
  return BowIndex::FromMapped(map(bow_name), (fs::path(dir) / bow_name).string(), vocabulary, db);
}

// The HOG whole-image channel's model, named by the manifest; nullptr for
// a database without that channel. Damage is CorruptDatabase.
std::shared_ptr<const WholeImageModel> OpenWholeImageModel(const std::string& dir,
                                                           const Database& db,
                                                           const ExtractorOptions& features) {
  const WholeImageOptions& w = features.whole_image;
  if (!w.enabled || w.kind != WholeImageKind::kHog) return nullptr;
  const nlohmann::json& manifest = db.info();
  const JsonReader m(manifest, dir + "/manifest.json", JsonOrigin::kDatabaseFile);
  if (m.String("whole_image_model") != kWholeImageModelFile)
    m.Fail("whole_image_model", "is not the whole-image model's file name");
  const std::shared_ptr<const MappedFile> file = DirectoryHandle(dir).MapFile(kWholeImageModelFile);
  const std::string shown = (fs::path(dir) / kWholeImageModelFile).string();
  if (!file) {
    PLACEDB_THROW_CORRUPT("database ", dir, " is incomplete: ", kWholeImageModelFile,
                          " (named by its manifest) is missing");
  }
  std::shared_ptr<const WholeImageModel> model = ReadWholeImageModel(file, shown);
  if (model->width() != w.hog_width || model->height() != w.hog_height ||
      model->output_dims() != w.hog_dims) {
    PLACEDB_THROW_CORRUPT(shown, " is for ", model->width(), " x ", model->height(),
                          " thumbnails and ", model->output_dims(),
                          " values, the manifest's settings for ", w.hog_width, " x ",
                          w.hog_height, " and ", w.hog_dims, " (corrupted database)");
  }
  return model;
}

// Removes what killed writers left in the database folder `dir`, whose
// current generation is `db` (the whole database); the rule is
// storage/folder.h's. The caller holds the folder's lock.
void SweepDebris(const std::string& dir, const Database& db) {
  std::string bow_name;
  const nlohmann::json& manifest = db.info();
  if (manifest.contains("index") && manifest["index"].is_object()) {
    const auto it = manifest["index"].find("bow");
    if (it != manifest["index"].end() && it->is_string()) bow_name = it->get<std::string>();
  }
  SweepDatabaseDebris(dir, db, [&](const std::string& name) {
    return IsBowIndexFileName(name) && name != bow_name;
  });
}

// The manifest's "ids" entry into `impl`; absent (an earlier placedb's
// manifest): nothing recorded. A damaged one is CorruptDatabase.
struct IdsRecord {
  int64_t next_free = 1;
  std::optional<uint64_t> removed;
  std::string removed_since;
};
IdsRecord ReadIdsEntry(const nlohmann::json& manifest, const std::string& dir) {
  IdsRecord r;
  if (!manifest.contains("ids")) return r;
  const JsonReader m(manifest, dir + "/manifest.json", JsonOrigin::kDatabaseFile);
  const JsonReader ids = m.Child("ids");
  r.next_free = ids.Integer("next_free", 1, int64_t{1} << 31);
  r.removed = static_cast<uint64_t>(ids.Integer("removed", 0, int64_t{1} << 53));
  r.removed_since = ids.String("removed_since");
  return r;
}

// The id after the largest `db` holds or `stored` records, at most 2^31.
int64_t NextFreeId(const Database& db, int64_t stored) {
  int64_t next = stored;
  for (const Keyframe& k : db.keyframes()) next = std::max(next, int64_t{k.id} + 1);
  return next;
}

// A source path as it is compared (skip_existing): absolute and normal,
// symlinks of existing parts resolved; as given when that fails.
std::string ComparablePath(const std::string& path) {
  std::error_code ec;
  const fs::path absolute = fs::absolute(path, ec);
  if (ec) return fs::path(path).lexically_normal().string();
  const fs::path canonical = fs::weakly_canonical(absolute, ec);
  return ec ? absolute.lexically_normal().string() : canonical.string();
}

// The id a file name is (ids_from_names): "042.jpg" -> 42.
int32_t IdFromFileName(const Frame& frame) {
  if (frame.load) {
    PLACEDB_THROW_INVALID("frame ", frame.id, " (", frame.image_path,
                          ") has no file name to take an id from (`ids_from_names` needs image "
                          "files)");
  }
  const std::string name = fs::path(frame.image_path).filename().string();
  const std::string stem = fs::path(frame.image_path).stem().string();
  size_t digits = 0;
  while (digits < stem.size() && stem[digits] >= '0' && stem[digits] <= '9') ++digits;
  size_t first = 0;
  while (first + 1 < stem.size() && stem[first] == '0') ++first;
  const bool number = !stem.empty() && digits == stem.size() && stem.size() - first <= 10;
  const int64_t id = number ? std::stoll(stem.substr(first)) : 0;
  if (!number || id < 1 || id > INT32_MAX) {
    PLACEDB_THROW_INVALID("cannot take an id from the file name '", name, "' (frame ", frame.id,
                          ", ", frame.image_path,
                          "): `ids_from_names` needs names that are a whole number in [1, 2^31), "
                          "e.g. 042.jpg");
  }
  return static_cast<int32_t>(id);
}

}  // namespace

PlaceDatabase::PlaceDatabase(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
PlaceDatabase::PlaceDatabase(PlaceDatabase&&) noexcept = default;
PlaceDatabase& PlaceDatabase::operator=(PlaceDatabase&&) noexcept = default;
PlaceDatabase::~PlaceDatabase() = default;

PlaceDatabase PlaceDatabase::Open(const std::string& dir, const OpenOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  auto impl = std::make_unique<Impl>();
  impl->dir = dir;
  LoadOptions load;
  load.subset = options.subset;
  load.contents = options.keyframe_table ? LoadContents::kKeyframeTable : LoadContents::kAll;
  load.read_features = options.read_features;
  load.read_features_above_bytes = static_cast<uint64_t>(options.read_features_above_mb) << 20;
  impl->db = Database::Load(dir, load);
  const Database& db = impl->db;
  impl->keyframe_table = options.keyframe_table;
  impl->subset = db.subset();
  impl->descriptor_bytes = db.descriptor_bytes();
  impl->whole = db.subset().all() && !options.keyframe_table;
  if (!impl->whole) {
    impl->subset_description =
        options.keyframe_table ? "its keyframe table" : db.subset().Describe();
  }
  impl->feature_type = db.feature_type();
  if (options.expected_features && *options.expected_features != db.feature_type()) {
    PLACEDB_THROW_INVALID("the database at ", dir, " holds ", FeatureTypeName(db.feature_type()),
                          " features but ", FeatureTypeName(*options.expected_features),
                          " features were asked for; rebuild it or ask for ",
                          FeatureTypeName(db.feature_type()));
  }
  impl->build = BuildOptionsFromManifest(db.info(), dir);
  const ExtractorOptions& features = impl->build.features;
  if (features.type != db.feature_type()) {
    PLACEDB_THROW_CORRUPT(dir, ": the manifest's feature settings say ",
                          FeatureTypeName(features.type), " but the keyframes hold ",
                          FeatureTypeName(db.feature_type()), " (corrupted database)");
  }
  if (DescriptorBytes(features) != db.descriptor_bytes()) {
    PLACEDB_THROW_CORRUPT(dir, ": the manifest's feature settings give ", DescriptorBytes(features),
                          "-byte descriptors but the keyframes hold ", db.descriptor_bytes(),
                          "-byte ones (corrupted database)");
  }
  if (WholeImageDims(features) != db.whole_image_dims()) {
    PLACEDB_THROW_CORRUPT(
        dir, ": the manifest's feature settings ",
        features.whole_image.enabled
            ? "give whole-image rows of " + std::to_string(WholeImageDims(features)) + " values"
            : std::string("have no whole-image channel"),
        " but the keyframes ",
        db.whole_image_dims() > 0
            ? "hold rows of " + std::to_string(db.whole_image_dims()) + " values"
            : std::string("have none"),
        " (corrupted database)");
  }
  impl->extractor = FeatureExtractor::Create(features, OpenWholeImageModel(dir, db, features));
  const int threads = options.threads == 0 ? ThreadPool::HardwareThreads() : options.threads;
  if (threads > 1) impl->pool = std::make_unique<ThreadPool>(threads);
  impl->open = options;
  if (!options.keyframe_table) {
    std::optional<BowIndex> bow =
        OpenBowIndex(dir, db, impl->build, impl->pool.get(), &impl->vocabulary);
    if (bow) impl->bow.emplace(std::move(*bow));
  }
  IdsRecord ids = ReadIdsEntry(db.info(), dir);
  impl->stored_next_free = ids.next_free;
  impl->stored_removed = ids.removed;
  impl->removed_since = std::move(ids.removed_since);
  impl->clusters = ClusterSet::Make(db, options.clusters);
  impl->removed.assign(db.size(), 0);
  // A read writes and deletes nothing (storage/folder.h): debris waits for
  // a writer (BeginChange).
  if (options.prefetch && impl->whole) impl->StartPrefetch();
  if (options.resident_limit_mb > 0) impl->StartReleaser();
  return PlaceDatabase(std::move(impl));
}

void PlaceDatabase::WaitForBackgroundWork() const { impl_->WaitForBackgroundWork(); }
const std::string& PlaceDatabase::directory() const { return impl_->dir; }
const BuildOptions& PlaceDatabase::build_options() const { return impl_->build; }
const ExtractorOptions& PlaceDatabase::extractor_options() const { return impl_->build.features; }
FeatureType PlaceDatabase::feature_type() const { return impl_->feature_type; }
const KeyframeSubset& PlaceDatabase::subset() const { return impl_->subset; }
int PlaceDatabase::descriptor_bytes() const { return impl_->descriptor_bytes; }
int PlaceDatabase::whole_image_dims() const { return WholeImageDims(impl_->build.features); }

std::string PlaceDatabase::manifest_json(int indent) const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  return DumpJson(impl_->db.info(), indent);
}

std::string PlaceDatabase::generation() const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  return impl_->db.keyframes_file();
}

PlaceDatabase::VerifyReport PlaceDatabase::Verify() const {
  if (impl_->keyframe_table) {
    PLACEDB_THROW_INVALID("a session opened as a keyframe table has no features to verify");
  }
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  impl_->db.VerifyAll();
  if (impl_->bow) impl_->bow->base().VerifyAll();
  VerifyReport report;
  report.keyframes = impl_->db.size();
  report.keyframes_bytes = impl_->db.keyframes_bytes();
  report.format_version = impl_->db.file_format_version();
  return report;
}

uint64_t PlaceDatabase::keyframes_bytes() const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  return impl_->db.keyframes_bytes();
}

bool PlaceDatabase::reads_features() const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  return impl_->db.has_features() && impl_->db.reads_features();
}

size_t PlaceDatabase::num_features() const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  if (impl_->num_removed == 0) return impl_->db.num_features();
  size_t n = 0;
  for (size_t i = 0; i < impl_->db.size(); ++i) {
    if (!impl_->removed[i]) n += impl_->db.FeatureCount(i);
  }
  return n;
}

size_t PlaceDatabase::size() const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  return impl_->db.size() - impl_->num_removed;
}

std::optional<Keyframe> PlaceDatabase::FindKeyframe(int32_t id) const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  const int index = impl_->db.IndexOfId(id);
  if (index < 0 || impl_->removed[static_cast<size_t>(index)]) return std::nullopt;
  return impl_->db.keyframe(static_cast<size_t>(index));
}

std::vector<int32_t> PlaceDatabase::keyframe_ids() const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  std::vector<int32_t> ids;
  ids.reserve(impl_->db.size() - impl_->num_removed);
  for (size_t i = 0; i < impl_->db.size(); ++i) {
    if (!impl_->removed[i]) ids.push_back(impl_->db.keyframe(i).id);
  }
  return ids;
}

std::vector<Keyframe> PlaceDatabase::keyframes() const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  std::vector<Keyframe> keyframes;
  keyframes.reserve(impl_->db.size() - impl_->num_removed);
  for (size_t i = 0; i < impl_->db.size(); ++i) {
    if (!impl_->removed[i]) keyframes.push_back(impl_->db.keyframe(i));
  }
  return keyframes;
}

std::vector<float> PlaceDatabase::WholeImageSimilarities(const FeatureSet& query) const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  const Database& db = impl_->db;
  const int dims = db.whole_image_dims();
  if (dims == 0 || query.whole_image.empty() || impl_->keyframe_table) return {};
  const cv::Mat& q = query.whole_image;
  if (q.type() != CV_8SC1 || q.rows != 1 || q.cols != dims || !q.isContinuous()) {
    PLACEDB_THROW_INVALID("a whole-image row of ", q.cols, " values (type ", q.type(),
                          "); the database keeps 1 x ", dims, " CV_8SC1 rows");
  }
  std::vector<float> all(db.size());
  placedb::WholeImageSimilarities(q.ptr<int8_t>(), db.WholeImageData(), db.size(), dims,
                                  all.data());
  if (impl_->num_removed == 0) return all;
  std::vector<float> out;
  out.reserve(db.size() - impl_->num_removed);
  for (size_t i = 0; i < db.size(); ++i) {
    if (!impl_->removed[i]) out.push_back(all[i]);
  }
  return out;
}

FeatureSet PlaceDatabase::KeyframeFeatures(int32_t id) const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  const int index = impl_->db.IndexOfId(id);
  if (index < 0 || impl_->removed[static_cast<size_t>(index)]) {
    PLACEDB_THROW_INVALID("no keyframe ", id, " in the database ", impl_->dir);
  }
  return impl_->db.Features(static_cast<size_t>(index));
}

StorageView::StorageView(const PlaceDatabase& session) {
  PlaceDatabase::Impl& impl = *session.impl_;
  lock_ = std::shared_lock<FairSharedMutex>(impl.state);
  db_ = &impl.db;
  bow_ = impl.bow ? &*impl.bow : nullptr;
  clusters_ = &impl.clusters;
  removed_ = &impl.removed;
  num_removed_ = impl.num_removed;
  pool_ = impl.pool.get();
}

KeyframeIdSummary PlaceDatabase::id_summary() const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  const Impl& m = *impl_;
  KeyframeIdSummary s;
  for (size_t i = 0; i < m.db.size(); ++i) {
    if (m.removed[i]) continue;
    const int32_t id = m.db.keyframe(i).id;
    s.first = s.count == 0 ? id : std::min(s.first, id);
    s.last = s.count == 0 ? id : std::max(s.last, id);
    ++s.count;
  }
  s.next_free = NextFreeId(m.db, m.stored_next_free);
  if (m.stored_removed) {
    s.removed = *m.stored_removed + m.num_removed;
    s.removed_since = m.removed_since;
  }
  return s;
}

std::string PlaceDatabase::info_json(int indent) const {
  const KeyframeIdSummary s = id_summary();
  nlohmann::json info;
  {
    std::shared_lock<FairSharedMutex> lock(impl_->state);
    info = impl_->db.info();
  }
  info["ids"] = {{"count", s.count},
                 {"first", s.first},
                 {"last", s.last},
                 {"next_free", s.next_free},
                 {"removed", s.removed ? nlohmann::json(*s.removed) : nlohmann::json()},
                 {"removed_since", s.removed_since}};
  return DumpJson(info, indent);
}

std::string PlaceDatabase::StoredImagePath(const Keyframe& keyframe) const {
  if (keyframe.image_file.empty()) return "";
  return (fs::path(impl_->dir) / keyframe.image_file).string();
}

FeatureSet PlaceDatabase::Extract(const cv::Mat& image) const {
  if (image.empty()) PLACEDB_THROW_INVALID("the query image is empty");
  if (image.depth() != CV_8U ||
      (image.channels() != 1 && image.channels() != 3 && image.channels() != 4)) {
    PLACEDB_THROW_INVALID("the query image must be 8-bit gray, BGR or BGRA (got ", image.channels(),
                          " channels of depth ", image.depth(), ")");
  }
  return impl_->extractor->Extract(image);
}

QueryResult PlaceDatabase::Run(const FeatureSet& features, const std::vector<int32_t>* among_ids,
                               const QueryOptions& options, double extract_ms) const {
  PLACEDB_CHECK_OPTIONS(options);
  if (impl_->keyframe_table) {
    PLACEDB_THROW_INVALID("the database at ", impl_->dir,
                          " was opened as a keyframe table (`keyframe_table`): it cannot query");
  }
  const Impl::QueryRunning running(*impl_);
  // The deadline's clock starts before the wait for a writer to publish.
  const Timer clock;
  std::shared_lock<FairSharedMutex> lock(impl_->state, std::defer_lock);
  if (options.deadline_ms > 0.0) {
    const auto until = std::chrono::steady_clock::now() +
                       std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                           std::chrono::duration<double, std::milli>(options.deadline_ms));
    if (!lock.try_lock_until(until)) {
      QueryResult late;
      late.num_query_features = static_cast<int>(features.size());
      late.deadline_reached = true;
      late.search = RetrievalMethodName(options.retrieval.method);
      late.times.extract_ms = extract_ms;
      late.times.total_ms = clock.ElapsedMs() + extract_ms;
      return late;
    }
  } else {
    lock.lock();
  }
  std::vector<uint32_t> among;
  QueryContext context = impl_->Context(among_ids, &among);
  context.candidate_cost = &impl_->candidate_cost;
  context.clock = &clock;
  QueryResult r = QueryDatabase(impl_->db, features, options, context);
  impl_->AskForRelease();
  r.times.extract_ms = extract_ms;
  r.times.total_ms += extract_ms;
  return r;
}

Shortlist PlaceDatabase::BowShortlist(const FeatureSet& features,
                                      const std::vector<int32_t>* keyframe_ids,
                                      const QueryOptions& options) const {
  PLACEDB_CHECK_OPTIONS(options);
  const Impl::QueryRunning running(*impl_);
  if (impl_->keyframe_table) {
    PLACEDB_THROW_INVALID("the database at ", impl_->dir,
                          " was opened as a keyframe table (`keyframe_table`): it cannot query");
  }
  if (!impl_->whole) {
    PLACEDB_THROW_INVALID("a shortlist needs a session on the whole database (this one is on ",
                          impl_->subset_description,
                          "): pass the partition's keyframe ids instead");
  }
  const Timer clock;
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  std::vector<uint32_t> among;
  QueryContext context = impl_->Context(keyframe_ids, &among);
  context.clock = &clock;
  Shortlist shortlist = ShortlistDatabase(impl_->db, features, options, context);
  impl_->AskForRelease();
  return shortlist;
}

QueryResult PlaceDatabase::Query(const cv::Mat& image, const QueryOptions& options) const {
  return Query(image, options, nullptr);
}

QueryResult PlaceDatabase::Query(const FeatureSet& features, const QueryOptions& options) const {
  return Run(features, nullptr, options, 0.0);
}

QueryResult PlaceDatabase::Query(const cv::Mat& image, const QueryOptions& options,
                                 std::vector<float>* whole_image_similarities) const {
  PLACEDB_CHECK_OPTIONS(options);
  Timer t;
  const FeatureSet features = Extract(image);
  QueryResult r = Run(features, nullptr, options, t.ElapsedMs());
  if (whole_image_similarities) *whole_image_similarities = WholeImageSimilarities(features);
  return r;
}

QueryResult PlaceDatabase::QueryAmong(const cv::Mat& image, const std::vector<int32_t>& keyframes,
                                      const QueryOptions& options) const {
  PLACEDB_CHECK_OPTIONS(options);
  Timer t;
  const FeatureSet features = Extract(image);
  return Run(features, &keyframes, options, t.ElapsedMs());
}

QueryResult PlaceDatabase::QueryAmong(const FeatureSet& features,
                                      const std::vector<int32_t>& keyframes,
                                      const QueryOptions& options) const {
  return Run(features, &keyframes, options, 0.0);
}

MatchDetail PlaceDatabase::Explain(const FeatureSet& features, int32_t keyframe_id,
                                   const QueryOptions& options) const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  const int index = impl_->db.IndexOfId(keyframe_id);
  if (index < 0 || impl_->removed[static_cast<size_t>(index)]) {
    PLACEDB_THROW_INVALID("no keyframe ", keyframe_id, " in the database ", impl_->dir);
  }
  return MatchKeyframe(impl_->db, features, static_cast<size_t>(index), options);
}

// ---- online mapping -----------------------------------------------------------

namespace {
void RequireWholeDatabase(bool whole, const std::string& subset, const char* what) {
  if (!whole) {
    PLACEDB_THROW_INVALID("cannot ", what, " in a session opened on ", subset,
                          ": open the whole database to change it");
  }
}
}  // namespace

// Takes the folder's lock for this session's changes (once), and checks that
// the folder still holds the generation this session read.
void PlaceDatabase::BeginChange() {
  Impl& m = *impl_;
  if (m.folder_lock) return;
  // Another writer finishing its save holds the lock for a moment: wait up
  // to 1 s before deciding another writer has it.
  std::unique_ptr<DirectoryLock> lock = DirectoryLock::TryLock(m.dir);
  for (int attempt = 0; !lock && attempt < 20; ++attempt) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    lock = DirectoryLock::TryLock(m.dir);
  }
  // Another writer, in this process or another, is not the caller's mistake
  // nor damage: the same call succeeds once it is done (IoError, like any
  // write the system cannot do now).
  if (!lock) {
    PLACEDB_THROW_IO("the database ", m.dir,
                     " is being changed by another process or session; one writer at a "
                     "time (try again when it has saved)");
  }
  const std::string manifest_path = (fs::path(m.dir) / Database::kManifestFile).string();
  bool same = false;
  try {
    std::string text;
    if (DirectoryHandle(m.dir).ReadFile(Database::kManifestFile, &text, kMaxManifestBytes)) {
      const nlohmann::json manifest =
          ParseJson(text, manifest_path, JsonOrigin::kDatabaseFile, kMaxManifestBytes);
      same = manifest.at("files").at("keyframes").get<std::string>() == m.db.keyframes_file();
    }
  } catch (const std::exception&) {
    same = false;
  }
  if (!same) {
    PLACEDB_THROW_IO("the database ", m.dir,
                     " was rewritten on disk since this session opened it; open it again "
                     "to change it");
  }
  m.folder_lock = std::move(lock);
  // The first writer since a crash removes what the crashed one left.
  SweepDebris(m.dir, m.db);
}

void PlaceDatabase::Add(const Frame& frame, const cv::Mat& image, uint64_t source_hash) {
  RequireWholeDatabase(impl_->whole, impl_->subset_description, "add keyframes");
  if (image.empty()) PLACEDB_THROW_INVALID("the image of keyframe ", frame.id, " is empty");
  if (image.depth() != CV_8U ||
      (image.channels() != 1 && image.channels() != 3 && image.channels() != 4)) {
    PLACEDB_THROW_INVALID("the image of keyframe ", frame.id, " must be 8-bit gray, BGR or BGRA");
  }
  if (frame.id < 1) PLACEDB_THROW_INVALID("keyframe id ", frame.id, " must be at least 1");
  // Where its image goes, before anything is done.
  std::unique_ptr<DirectoryHandle> images;
  if (impl_->build.store_images) images = StoredImageFolderForWriting(impl_->dir);
  // The slow part, with no lock held.
  cv::Mat bgr = image;
  if (image.channels() == 1) cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  if (image.channels() == 4) cv::cvtColor(image, bgr, cv::COLOR_BGRA2BGR);
  ProcessedFrame processed = ProcessFrame(frame, bgr, impl_->build, *impl_->extractor);
  processed.keyframe.source_hash = source_hash;
  std::vector<uint8_t> png;
  if (impl_->build.store_images) {
    cv::imencode(".png", processed.stored_image, png,
                 {cv::IMWRITE_PNG_COMPRESSION, impl_->build.png_compression});
  }
  Impl& m = *impl_;
  std::lock_guard<std::mutex> writer(m.writer);
  if (m.db.IndexOfId(frame.id) >= 0) PLACEDB_THROW_INVALID("keyframe id ", frame.id, " is taken");
  KeepTrackedOnline(m.db, m.build, &processed);
  BeginChange();
  std::string written;
  if (images) {
    const std::string name = StoredImageFileName(frame.id);
    images->WriteFileAtomic(fs::path(name).filename().string(),
                            std::string(reinterpret_cast<const char*>(png.data()), png.size()));
    written = name;
    processed.keyframe.image_file = name;
  }
  try {
    AddLocked(std::move(processed.keyframe), processed.features);
  } catch (...) {
    if (images) images->RemoveRegularFile(fs::path(written).filename().string());
    throw;
  }
  if (!written.empty()) m.unsaved_images.push_back(written);
}

void PlaceDatabase::Add(Keyframe keyframe, const FeatureSet& features) {
  RequireWholeDatabase(impl_->whole, impl_->subset_description, "add keyframes");
  std::lock_guard<std::mutex> writer(impl_->writer);
  BeginChange();
  AddLocked(std::move(keyframe), features);
}

void PlaceDatabase::AddLocked(Keyframe keyframe, const FeatureSet& features) {
  Impl& m = *impl_;
  if (m.db.IndexOfId(keyframe.id) >= 0)
    PLACEDB_THROW_INVALID("keyframe id ", keyframe.id, " is taken");
  const std::string reason = CheckKeyframe(keyframe);
  if (!reason.empty()) PLACEDB_THROW_INVALID("keyframe ", keyframe.id, ": ", reason);
  // Everything that takes time happens before the readers are held: the
  // bag of words, and (when the storage is full) a grown copy.
  std::optional<BowVector> words;
  std::vector<uint32_t> nodes;
  if (m.bow) {
    // The rows in the database's order (SURF: grouped by sign), so that the
    // vector and the direct nodes are the ones a rebuilt index computes.
    const GroupedFeatures grouped = GroupByLaplacian(features);
    words = m.bow->Transform(grouped.block, &nodes);
  }
  const size_t rows = features.keypoints.size();
  std::optional<Database> grown;
  if (!m.db.HasRoomFor(1, rows)) {
    grown = m.db;  // reads only, as queries do
    grown->Reserve(2 * m.db.size() + 16, 2 * m.db.num_features() + rows + 4096);
    grown->AddKeyframe(keyframe, features);
  }
  {
    // AddKeyframe checks everything before it changes anything: if it throws
    // here, the session is as it was (nothing below has run).
    std::unique_lock<FairSharedMutex> publish(m.state);
    if (grown) {
      std::swap(m.db, *grown);
    } else {
      m.db.AddKeyframe(keyframe, features);
    }
    if (words) m.bow->Append(std::move(*words), std::move(nodes));
    m.clusters.Add(m.db.keyframe(m.db.size() - 1));
    m.removed.push_back(0);
    ++m.pending;
  }
  // The old storage (after a swap) is freed here, outside the lock.
}

AddReport PlaceDatabase::AddFrames(const std::vector<Frame>& frames, const AddOptions& options,
                                   bool progress) {
  PLACEDB_CHECK_OPTIONS(options);
  RequireWholeDatabase(impl_->whole, impl_->subset_description, "add keyframes");
  if (frames.empty()) PLACEDB_THROW_INVALID("no frames to add");
  // Ids from names first: a name that is not a number is refused before
  // any image is read.
  std::vector<int32_t> name_ids;
  if (options.ids_from_names) {
    for (const Frame& f : frames) name_ids.push_back(IdFromFileName(f));
  }
  // The keyframes by source path (copies: other writers may publish
  // meanwhile; the ids are checked again when each frame is added).
  struct Held {
    int32_t id;  // a keyframe's, or 0 for a frame given earlier
    uint64_t hash;
    size_t pending = 0;  // that earlier frame's place in `todo`
  };
  std::unordered_map<std::string, std::vector<Held>> by_path;
  for (const Keyframe& k : keyframes()) {
    by_path[ComparablePath(k.source)].push_back({k.id, k.source_hash});
  }
  std::vector<std::pair<size_t, size_t>> repeats;  // (frame, its first copy's place in todo)
  AddReport report;
  report.ids.assign(frames.size(), 0);
  std::vector<size_t> todo;
  std::vector<cv::Mat> images;
  std::vector<uint64_t> hashes;
  for (size_t i = 0; i < frames.size(); ++i) {
    const Frame& f = frames[i];
    uint64_t hash = 0;
    cv::Mat image = LoadFrameImage(f, &hash);
    if (image.empty()) ThrowUnreadableFrame(f);
    std::string path = ComparablePath(f.image_path);
    const Held* same = nullptr;
    bool known_path = false;
    if (const auto it = by_path.find(path); it != by_path.end()) {
      known_path = true;
      for (const Held& h : it->second) {
        if (h.hash == hash || h.hash == 0) {
          same = &h;
          if (h.hash == hash) break;  // a content match goes before a path-only one
        }
      }
    }
    if (same && same->id == 0) {
      // Given twice: added once.
      if (!options.skip_existing) {
        PLACEDB_THROW_INVALID("frame ", f.id, " (", f.image_path,
                              ") is the same image as an earlier frame given (same source and "
                              "content); `skip_existing` adds it once");
      }
      ++report.repeated;
      repeats.emplace_back(i, same->pending);
      continue;
    }
    if (same) {
      if (!options.skip_existing) {
        PLACEDB_THROW_INVALID("frame ", f.id, " (", f.image_path, ") is already keyframe ",
                              same->id, " of ", impl_->dir,
                              same->hash != 0
                                  ? " (same source and content)"
                                  : " (same source path; that keyframe has no content hash)",
                              "; `skip_existing` leaves such frames out");
      }
      ++report.skipped;
      if (same->hash == 0) ++report.skipped_by_path;
      report.ids[i] = same->id;
      continue;
    }
    if (known_path) report.changed_sources.push_back(f.image_path);
    by_path[path].push_back({0, hash, todo.size()});
    todo.push_back(i);
    images.push_back(std::move(image));
    hashes.push_back(hash);
  }
  // The ids, all settled before anything changes.
  const int64_t next_free = id_summary().next_free;
  std::unordered_set<int32_t> taken;
  for (size_t j = 0; j < todo.size(); ++j) {
    const size_t i = todo[j];
    const Frame& f = frames[i];
    int64_t id = options.ids_from_names  ? name_ids[i]
                 : options.id_offset > 0 ? int64_t{options.id_offset} + static_cast<int64_t>(i)
                                         : next_free + static_cast<int64_t>(j);
    if (id > INT32_MAX) {
      PLACEDB_THROW_INVALID("frame ", f.id, " (", f.image_path, ") would get id ", id,
                            ", above the largest, 2^31 - 1",
                            options.id_offset > 0 ? " (a smaller `id_offset`)" : "");
    }
    const int32_t id32 = static_cast<int32_t>(id);
    {
      std::shared_lock<FairSharedMutex> lock(impl_->state);
      const int index = impl_->db.IndexOfId(id32);
      if (index >= 0) {
        PLACEDB_THROW_INVALID("frame ", f.id, " (", f.image_path, ") would get id ", id32,
                              ", which is taken by ",
                              impl_->removed[static_cast<size_t>(index)]
                                  ? "a keyframe removed in this session"
                                  : "the keyframe of " + impl_->db.keyframe(index).source,
                              options.ids_from_names  ? " (`ids_from_names`)"
                              : options.id_offset > 0 ? " (choose another `id_offset`)"
                                                      : "");
      }
    }
    if (!taken.insert(id32).second) {
      PLACEDB_THROW_INVALID(
          "frame ", f.id, " (", f.image_path, ") would get id ", id32,
          ", which another frame given gets too",
          options.ids_from_names ? " (`ids_from_names`: two names of one number)" : "");
    }
    report.ids[i] = id32;
  }
  for (const auto& [frame, first_copy] : repeats) report.ids[frame] = report.ids[todo[first_copy]];
  ProgressBar bar("adding", todo.size(), progress);
  for (size_t j = 0; j < todo.size(); ++j) {
    Frame f = frames[todo[j]];
    f.id = report.ids[todo[j]];
    Add(f, images[j], hashes[j]);
    images[j].release();
    ++report.added;
    report.first_id = report.added == 1 ? f.id : std::min(report.first_id, f.id);
    report.last_id = std::max(report.last_id, f.id);
    bar.Advance();
  }
  bar.Finish();
  return report;
}

bool PlaceDatabase::Remove(int32_t id) {
  Impl& m = *impl_;
  RequireWholeDatabase(m.whole, m.subset_description, "remove keyframes");
  std::lock_guard<std::mutex> writer(m.writer);
  const int index = m.db.IndexOfId(id);
  if (index < 0 || m.removed[static_cast<size_t>(index)]) return false;
  BeginChange();
  std::unique_lock<FairSharedMutex> publish(m.state);
  m.removed[static_cast<size_t>(index)] = 1;
  ++m.num_removed;
  ++m.pending;
  return true;
}

size_t PlaceDatabase::num_pending_changes() const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  return impl_->pending;
}

void PlaceDatabase::Save() {
  Impl& m = *impl_;
  RequireWholeDatabase(m.whole, m.subset_description, "save");
  std::lock_guard<std::mutex> writer(m.writer);
  BeginChange();
  std::vector<char> keep(m.db.size());
  std::vector<std::string> dropped_images;
  for (size_t i = 0; i < keep.size(); ++i) {
    keep[i] = !m.removed[i];
    if (!keep[i] && !m.db.keyframe(i).image_file.empty())
      dropped_images.push_back(m.db.keyframe(i).image_file);
  }
  Database compacted = m.db.Compacted(keep);
  if (compacted.empty()) PLACEDB_THROW_INVALID("cannot save a database with no keyframes left");
  // The ids the database ever held stay used; removals are counted from the
  // build (or from this save, for a manifest of an earlier placedb).
  compacted.info()["ids"] =
      IdsEntry(NextFreeId(m.db, m.stored_next_free), m.stored_removed.value_or(0) + m.num_removed,
               m.stored_removed ? m.removed_since : NowIso8601());
  std::string old_bow;
  if (m.bow) {
    const BowIndex index =
        BowIndex::Build(m.vocabulary, compacted, m.build.bow, m.pool.get(), nullptr);
    const std::string name = SaveBowIndexFile(index, m.dir);
    nlohmann::json& entry = compacted.info()["index"];
    old_bow = entry.value("bow", std::string());
    entry["bow"] = name;
    if (old_bow == name) old_bow.clear();
  }
  compacted.Save(m.dir);
  // The new generation is in place: what only the old one used goes.
  if (!old_bow.empty()) DirectoryHandle(m.dir).RemoveRegularFile(old_bow);
  RemoveStoredImages(m.dir, dropped_images);

  // Read back what was written, as a reopened session would.
  OpenOptions options = m.open;
  options.threads = m.pool ? m.pool->size() : 1;
  // Without background threads: its members move into this session under
  // this session's lock, which threads of its own would not hold (they read
  // its `db` under its lock). The new files are checked on first use.
  options.prefetch = false;
  options.resident_limit_mb = 0;
  PlaceDatabase fresh = Open(m.dir, options);
  Impl& f = *fresh.impl_;
  std::unique_lock<FairSharedMutex> publish(m.state);
  std::swap(m.db, f.db);
  std::swap(m.vocabulary, f.vocabulary);
  std::swap(m.bow, f.bow);
  std::swap(m.clusters, f.clusters);
  std::swap(m.removed, f.removed);
  m.stored_next_free = f.stored_next_free;
  m.stored_removed = f.stored_removed;
  m.removed_since = f.removed_since;
  m.num_removed = 0;
  m.pending = 0;
  m.unsaved_images.clear();
  publish.unlock();
  // What killed writers left (none can be writing: we hold the lock).
  SweepDebris(m.dir, m.db);
  m.folder_lock.reset();
}

}  // namespace placedb
