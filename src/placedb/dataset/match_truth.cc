#include "placedb/dataset/match_truth.h"

#include <algorithm>

#include "placedb/dataset/text_lines.h"

namespace placedb {

MatchTruth ReadMatchTruth(const std::string& path) {
  MatchTruth truth;
  std::map<int, int> line_of_query;
  for (const internal::TextLine& line : internal::ReadDataLines(path, "match truth file")) {
    const size_t comma = line.text.find(',');
    if (comma == std::string::npos) {
      internal::ThrowLineError(
          path, line.number,
          "expected 'query_id,id id ...', found no comma in '" + line.text + "'");
    }
    const std::vector<std::string> query_fields =
        internal::SplitFields(line.text.substr(0, comma), " \t");
    if (query_fields.size() != 1) {
      internal::ThrowLineError(path, line.number, "expected one query id before the first comma");
    }
    const int query = internal::ParseInt(query_fields[0], path, line.number, "query id");
    if (query < 1) {
      internal::ThrowLineError(path, line.number,
                               "query id must be >= 1 (1-based), got " + std::to_string(query));
    }
    const auto [previous, inserted] = line_of_query.emplace(query, line.number);
    if (!inserted) {
      internal::ThrowLineError(path, line.number,
                               "duplicate query id " + std::to_string(query) + " (first on line " +
                                   std::to_string(previous->second) + ")");
    }
    std::vector<int> ids;
    for (const std::string& token : internal::SplitFields(line.text.substr(comma + 1), " \t,")) {
      const int id = internal::ParseInt(token, path, line.number, "matching id");
      if (id < 1) {
        internal::ThrowLineError(path, line.number,
                                 "ids must be >= 1 (1-based), got " + std::to_string(id));
      }
      ids.push_back(id);
    }
    std::sort(ids.begin(), ids.end());
    const auto repeated = std::adjacent_find(ids.begin(), ids.end());
    if (repeated != ids.end()) {
      internal::ThrowLineError(
          path, line.number,
          "id " + std::to_string(*repeated) + " listed twice for query " + std::to_string(query));
    }
    truth.emplace(query, std::move(ids));
  }
  return truth;
}

}  // namespace placedb
