#include "placedb/feature/types.h"

#include <algorithm>
#include <cctype>

#include "placedb/util/check.h"

namespace placedb {

const char* FeatureTypeName(FeatureType type) {
  switch (type) {
    case FeatureType::kOrb:
      return "orb";
    case FeatureType::kSurf:
      return "surf";
  }
  return "unknown";
}

FeatureType ParseFeatureType(const std::string& name) {
  std::string lower = name;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (lower == "orb") return FeatureType::kOrb;
  if (lower == "surf") return FeatureType::kSurf;
  PLACEDB_THROW_INVALID("unknown feature type '", name, "' (expected orb or surf)");
}

void CheckCompatibleDescriptors(FeatureType a_type, const cv::Mat& a, FeatureType b_type,
                                const cv::Mat& b, const std::string& what) {
  if (a_type != b_type) {
    PLACEDB_THROW_INVALID(what, ": cannot compare ", FeatureTypeName(a_type), " descriptors with ",
                          FeatureTypeName(b_type), " descriptors");
  }
  if (!a.empty() && !b.empty() && (a.cols != b.cols || a.type() != b.type())) {
    PLACEDB_THROW_INVALID(what, ": descriptor layouts differ (", a.cols, " vs ", b.cols,
                          " columns)");
  }
}

}  // namespace placedb
