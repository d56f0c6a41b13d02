#include "placedb/index/retrieval.h"

#include "placedb/util/check.h"

namespace placedb {

const char* RetrievalMethodName(RetrievalMethod method) {
  switch (method) {
    case RetrievalMethod::kExhaustive:
      return "exhaustive";
  }
  return "unknown";
}

RetrievalMethod ParseRetrievalMethod(const std::string& name) {
  if (name == "exhaustive") return RetrievalMethod::kExhaustive;
  PLACEDB_THROW_INVALID("unknown search method '", name, "' (expected exhaustive)");
}

std::string RetrievalOptions::Check() const {
  if (method != RetrievalMethod::kExhaustive) return "method is unknown";
  return "";
}

namespace {

class ExhaustiveRetriever : public Retriever {
 public:
  RetrievalMethod method() const override { return RetrievalMethod::kExhaustive; }

  std::vector<Candidate> Retrieve(const Database& db, const FeatureSet& /*query*/,
                                  const std::vector<uint32_t>* among) const override {
    std::vector<Candidate> out;
    if (among != nullptr) {
      out.reserve(among->size());
      for (const uint32_t i : *among) out.push_back({i, 0.0});
    } else {
      out.reserve(db.size());
      for (size_t i = 0; i < db.size(); ++i) out.push_back({static_cast<uint32_t>(i), 0.0});
    }
    return out;
  }
};

}  // namespace

std::unique_ptr<Retriever> Retriever::Create(const RetrievalOptions& options,
                                             const Database& /*db*/) {
  PLACEDB_CHECK_OPTIONS(options);
  switch (options.method) {
    case RetrievalMethod::kExhaustive:
      return std::make_unique<ExhaustiveRetriever>();
  }
  PLACEDB_THROW_INVALID("unknown retrieval method");
}

}  // namespace placedb
