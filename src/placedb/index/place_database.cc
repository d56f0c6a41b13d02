#include "placedb/index/place_database.h"

#include <filesystem>
#include <map>
#include <mutex>

#include "placedb/util/check.h"
#include "placedb/util/options.h"
#include "placedb/util/thread_pool.h"
#include "placedb/util/timer.h"

namespace placedb {
namespace fs = std::filesystem;

std::string OpenOptions::Check() const {
  return FirstReason({Nested("subset", subset.Check()), CheckRange("threads", threads, 0, 1024)});
}

struct PlaceDatabase::Impl {
  std::string dir;
  Database db;
  BuildOptions build;
  std::unique_ptr<FeatureExtractor> extractor;
  std::unique_ptr<ThreadPool> pool;
  // Retrievers by method, prepared on first use.
  mutable std::mutex retrievers_mutex;
  mutable std::map<RetrievalMethod, std::unique_ptr<Retriever>> retrievers;

  const Retriever& RetrieverFor(const RetrievalOptions& options) const {
    std::lock_guard<std::mutex> lock(retrievers_mutex);
    std::unique_ptr<Retriever>& r = retrievers[options.method];
    if (!r) r = Retriever::Create(options, db);
    return *r;
  }
};

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
  return PlaceDatabase(std::move(impl));
}

const std::string& PlaceDatabase::directory() const { return impl_->dir; }
const Database& PlaceDatabase::database() const { return impl_->db; }
const nlohmann::json& PlaceDatabase::manifest() const { return impl_->db.info(); }
const BuildOptions& PlaceDatabase::build_options() const { return impl_->build; }
const ExtractorOptions& PlaceDatabase::extractor_options() const { return impl_->build.features; }
FeatureType PlaceDatabase::feature_type() const { return impl_->db.feature_type(); }
size_t PlaceDatabase::size() const { return impl_->db.size(); }
ThreadPool* PlaceDatabase::pool() const { return impl_->pool.get(); }

const Keyframe* PlaceDatabase::FindKeyframe(int32_t id) const {
  const int index = impl_->db.IndexOfId(id);
  return index < 0 ? nullptr : &impl_->db.keyframe(static_cast<size_t>(index));
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
  QueryContext context;
  context.retriever = &impl_->RetrieverFor(options.retrieval);
  context.among = among;
  context.pool = impl_->pool.get();
  context.image_dir = impl_->dir;
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

}  // namespace placedb
