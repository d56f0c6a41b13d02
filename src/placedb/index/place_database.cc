#include "placedb/index/place_database.h"

#include <filesystem>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <shared_mutex>

#include "placedb/util/check.h"
#include "placedb/util/fair_shared_mutex.h"
#include "placedb/util/file_io.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/options.h"
#include "placedb/util/thread_pool.h"
#include "placedb/util/timer.h"

namespace placedb {
namespace fs = std::filesystem;

std::string OpenOptions::Check() const {
  return FirstReason({Nested("subset", subset.Check()), CheckRange("threads", threads, 0, 1024),
                      Nested("clusters", clusters.Check())});
}

struct PlaceDatabase::Impl {
  std::string dir;
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
  // Online mapping. Queries hold `state` shared while they run; a writer
  // holds it exclusively only to publish a prepared change. Writers take
  // `writer` first, one at a time.
  mutable FairSharedMutex state;
  std::mutex writer;
  std::vector<char> removed;  // per keyframe index
  size_t num_removed = 0;
  size_t pending = 0;
};

namespace {

// The bag-of-words index named by the manifest: mapped in place for the
// whole database, rebuilt in memory from its vocabulary for a subset (the
// stored index numbers the whole file's keyframes).
std::optional<BowIndex> OpenBowIndex(const std::string& dir, const Database& db,
                                     const BuildOptions& build, ThreadPool* pool,
                                     std::shared_ptr<const Vocabulary>* vocabulary_out) {
  const nlohmann::json& manifest = db.info();
  if (!manifest.contains("index")) return std::nullopt;
  const JsonReader index(manifest["index"], dir + "/manifest.json: index", true);
  if (index.String("kind") != "bow") index.Fail("kind", "is not bow");
  const std::string vocabulary_name = index.String("vocabulary");
  const std::string bow_name = index.String("bow");
  if (vocabulary_name != kVocabularyFile) index.Fail("vocabulary", "is not a vocabulary file name");
  if (!IsBowIndexFileName(bow_name)) index.Fail("bow", "is not a bag-of-words index file name");
  const DirectoryHandle handle(dir);
  auto map = [&](const std::string& name) {
    std::shared_ptr<const MappedFile> file = handle.MapFile(name);
    if (!file) {
      PLACEDB_THROW_RUNTIME("database ", dir, " is incomplete: ", name,
                            " (named by its manifest) is missing");
    }
    return file;
  };
  const std::string shown_vocabulary = (fs::path(dir) / vocabulary_name).string();
  auto vocabulary = std::make_shared<const Vocabulary>(
      Vocabulary::FromMapped(map(vocabulary_name), shown_vocabulary));
  if (vocabulary->type() != db.feature_type() || vocabulary->row_bytes() != db.descriptor_bytes()) {
    PLACEDB_THROW_RUNTIME(shown_vocabulary, " is for other descriptors than the database's ",
                          "(corrupted database)");
  }
  *vocabulary_out = vocabulary;
  if (!db.subset().all()) {
    return BowIndex::Build(vocabulary, db, build.bow, pool, nullptr);
  }
  return BowIndex::FromMapped(map(bow_name), (fs::path(dir) / bow_name).string(), vocabulary, db);
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
  impl->db = Database::Load(dir, options.subset);
  const Database& db = impl->db;
  if (options.expected_features && *options.expected_features != db.feature_type()) {
    PLACEDB_THROW_INVALID("the database at ", dir, " holds ", FeatureTypeName(db.feature_type()),
                          " features but ", FeatureTypeName(*options.expected_features),
                          " features were asked for; rebuild it or ask for ",
                          FeatureTypeName(db.feature_type()));
  }
  impl->build = BuildOptionsFromManifest(db.info(), dir);
  const ExtractorOptions& features = impl->build.features;
  if (features.type != db.feature_type()) {
    PLACEDB_THROW_RUNTIME(dir, ": the manifest's feature settings say ",
                          FeatureTypeName(features.type), " but the keyframes hold ",
                          FeatureTypeName(db.feature_type()), " (corrupted database)");
  }
  if (DescriptorBytes(features) != db.descriptor_bytes()) {
    PLACEDB_THROW_RUNTIME(dir, ": the manifest's feature settings give ", DescriptorBytes(features),
                          "-byte descriptors but the keyframes hold ", db.descriptor_bytes(),
                          "-byte ones (corrupted database)");
  }
  impl->extractor = FeatureExtractor::Create(features);
  const int threads = options.threads == 0 ? ThreadPool::HardwareThreads() : options.threads;
  if (threads > 1) impl->pool = std::make_unique<ThreadPool>(threads);
  impl->open = options;
  std::optional<BowIndex> bow =
      OpenBowIndex(dir, db, impl->build, impl->pool.get(), &impl->vocabulary);
  if (bow) impl->bow.emplace(std::move(*bow));
  impl->clusters = ClusterSet::Make(db, options.clusters);
  impl->removed.assign(db.size(), 0);
  return PlaceDatabase(std::move(impl));
}

const std::string& PlaceDatabase::directory() const { return impl_->dir; }
const Database& PlaceDatabase::database() const { return impl_->db; }
const nlohmann::json& PlaceDatabase::manifest() const { return impl_->db.info(); }
const BuildOptions& PlaceDatabase::build_options() const { return impl_->build; }
const ExtractorOptions& PlaceDatabase::extractor_options() const { return impl_->build.features; }
FeatureType PlaceDatabase::feature_type() const { return impl_->db.feature_type(); }
size_t PlaceDatabase::size() const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  return impl_->db.size() - impl_->num_removed;
}
ThreadPool* PlaceDatabase::pool() const { return impl_->pool.get(); }
const GrowingBowIndex* PlaceDatabase::bow_index() const {
  return impl_->bow ? &*impl_->bow : nullptr;
}
const ClusterSet& PlaceDatabase::clusters() const { return impl_->clusters; }

const Keyframe* PlaceDatabase::FindKeyframe(int32_t id) const {
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  const int index = impl_->db.IndexOfId(id);
  if (index < 0 || impl_->removed[static_cast<size_t>(index)]) return nullptr;
  return &impl_->db.keyframe(static_cast<size_t>(index));
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

QueryResult PlaceDatabase::Run(const FeatureSet& features, const std::vector<uint32_t>* among,
                               const QueryOptions& options, double extract_ms) const {
  PLACEDB_CHECK_OPTIONS(options);
  std::shared_lock<FairSharedMutex> lock(impl_->state);
  QueryContext context;
  context.bow = bow_index();
  context.clusters = &impl_->clusters;
  context.among = among;
  // Removed keyframes (online mapping) are left out.
  std::vector<uint32_t> kept;
  if (impl_->num_removed > 0) {
    const std::vector<char>& removed = impl_->removed;
    if (among != nullptr) {
      for (const uint32_t i : *among) {
        if (i >= removed.size() || !removed[i]) kept.push_back(i);
      }
    } else {
      for (size_t i = 0; i < removed.size(); ++i) {
        if (!removed[i]) kept.push_back(static_cast<uint32_t>(i));
      }
    }
    context.among = &kept;
  }
  context.pool = impl_->pool.get();
  context.image_dir = impl_->dir;
  context.candidate_cost = &impl_->candidate_cost;
  QueryResult r = QueryDatabase(impl_->db, features, options, context);
  r.times.extract_ms = extract_ms;
  r.times.total_ms += extract_ms;
  return r;
}

QueryResult PlaceDatabase::Query(const cv::Mat& image, const QueryOptions& options) const {
  PLACEDB_CHECK_OPTIONS(options);
  Timer t;
  const FeatureSet features = Extract(image);
  return Run(features, nullptr, options, t.ElapsedMs());
}

QueryResult PlaceDatabase::Query(const FeatureSet& features, const QueryOptions& options) const {
  return Run(features, nullptr, options, 0.0);
}

QueryResult PlaceDatabase::QueryAmong(const cv::Mat& image, const std::vector<uint32_t>& keyframes,
                                      const QueryOptions& options) const {
  PLACEDB_CHECK_OPTIONS(options);
  Timer t;
  const FeatureSet features = Extract(image);
  return Run(features, &keyframes, options, t.ElapsedMs());
}

QueryResult PlaceDatabase::QueryAmong(const FeatureSet& features,
                                      const std::vector<uint32_t>& keyframes,
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
void RequireWholeDatabase(const Database& db, const char* what) {
  if (!db.subset().all()) {
    PLACEDB_THROW_INVALID("cannot ", what, " in a session opened on ", db.subset().Describe(),
                          ": open the whole database to change it");
  }
}
}  // namespace

void PlaceDatabase::Add(const Frame& frame, const cv::Mat& image) {
  RequireWholeDatabase(impl_->db, "add keyframes");
  if (image.empty()) PLACEDB_THROW_INVALID("the image of keyframe ", frame.id, " is empty");
  if (image.depth() != CV_8U ||
      (image.channels() != 1 && image.channels() != 3 && image.channels() != 4)) {
    PLACEDB_THROW_INVALID("the image of keyframe ", frame.id, " must be 8-bit gray, BGR or BGRA");
  }
  cv::Mat bgr = image;
  if (image.channels() == 1) cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  if (image.channels() == 4) cv::cvtColor(image, bgr, cv::COLOR_BGRA2BGR);
  ProcessedFrame processed = ProcessFrame(frame, bgr, impl_->build, *impl_->extractor);
  if (impl_->build.store_images) {
    if (impl_->db.IndexOfId(frame.id) >= 0)
      PLACEDB_THROW_INVALID("keyframe id ", frame.id, " is taken");
    char name[32];
    std::snprintf(name, sizeof(name), "images/%06d.png", frame.id);
    std::vector<uint8_t> png;
    cv::imencode(".png", processed.stored_image, png,
                 {cv::IMWRITE_PNG_COMPRESSION, impl_->build.png_compression});
    fs::create_directories(fs::path(impl_->dir) / "images");
    WriteFileAtomic((fs::path(impl_->dir) / name).string(),
                    std::string(reinterpret_cast<const char*>(png.data()), png.size()));
    processed.keyframe.image_file = name;
  }
  Add(std::move(processed.keyframe), processed.features);
}

void PlaceDatabase::Add(Keyframe keyframe, const FeatureSet& features) {
  Impl& m = *impl_;
  RequireWholeDatabase(m.db, "add keyframes");
  std::lock_guard<std::mutex> writer(m.writer);
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

bool PlaceDatabase::Remove(int32_t id) {
  Impl& m = *impl_;
  RequireWholeDatabase(m.db, "remove keyframes");
  std::lock_guard<std::mutex> writer(m.writer);
  const int index = m.db.IndexOfId(id);
  if (index < 0 || m.removed[static_cast<size_t>(index)]) return false;
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
  RequireWholeDatabase(m.db, "save");
  std::lock_guard<std::mutex> writer(m.writer);
  std::vector<char> keep(m.db.size());
  std::vector<std::string> dropped_images;
  for (size_t i = 0; i < keep.size(); ++i) {
    keep[i] = !m.removed[i];
    if (!keep[i] && !m.db.keyframe(i).image_file.empty())
      dropped_images.push_back(m.db.keyframe(i).image_file);
  }
  Database compacted = m.db.Compacted(keep);
  if (compacted.empty()) PLACEDB_THROW_INVALID("cannot save a database with no keyframes left");
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
  std::error_code ignore;
  if (!old_bow.empty()) fs::remove(fs::path(m.dir) / old_bow, ignore);
  for (const std::string& image : dropped_images) fs::remove(fs::path(m.dir) / image, ignore);

  // Read back what was written, as a reopened session would.
  OpenOptions options = m.open;
  options.threads = m.pool ? m.pool->size() : 1;
  PlaceDatabase fresh = Open(m.dir, options);
  Impl& f = *fresh.impl_;
  std::unique_lock<FairSharedMutex> publish(m.state);
  std::swap(m.db, f.db);
  std::swap(m.vocabulary, f.vocabulary);
  std::swap(m.bow, f.bow);
  std::swap(m.clusters, f.clusters);
  std::swap(m.removed, f.removed);
  m.num_removed = 0;
  m.pending = 0;
}

}  // namespace placedb
