// The retrieve stage: which keyframes a query examines, in which order.
// Exhaustive search (every keyframe, the paper's method) is the one retriever
// today; a bag-of-words index and spatial clusters plug in behind the same
// interface and factory.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "placedb/feature/types.h"
#include "placedb/index/database.h"

namespace placedb {

enum class RetrievalMethod { kExhaustive };
// "exhaustive".
const char* RetrievalMethodName(RetrievalMethod method);
// Parses a name; throws std::invalid_argument naming the known ones.
RetrievalMethod ParseRetrievalMethod(const std::string& name);

struct RetrievalOptions {
  // How candidates are chosen. Default exhaustive.
  RetrievalMethod method = RetrievalMethod::kExhaustive;

  std::string Check() const;
};

// A keyframe to examine: its index in the database and the retriever's prior
// score (higher first; 0 for exhaustive search).
struct Candidate {
  uint32_t index = 0;
  double prior = 0.0;
};

class Retriever {
 public:
  virtual ~Retriever() = default;
  virtual RetrievalMethod method() const = 0;

  // The keyframes of `db` to examine for `query`, best prior first. With
  // `among` (sorted, unique indices < db.size()), only those may be returned.
  virtual std::vector<Candidate> Retrieve(const Database& db, const FeatureSet& query,
                                          const std::vector<uint32_t>* among) const = 0;

  // The retriever for `options` over `db` (an index may be prepared here).
  static std::unique_ptr<Retriever> Create(const RetrievalOptions& options, const Database& db);
};

}  // namespace placedb
