#include "placedb/feature/types.h"

#include <gtest/gtest.h>

#include "placedb/util/error.h"

namespace placedb {
namespace {

TEST(FeatureTypesTest, NamesRoundTrip) {
  EXPECT_EQ(ParseFeatureType("orb"), FeatureType::kOrb);
  EXPECT_EQ(ParseFeatureType("SURF"), FeatureType::kSurf);
  EXPECT_STREQ(FeatureTypeName(FeatureType::kSurf), "surf");
  EXPECT_THROW(ParseFeatureType("sift"), InvalidArgument);
}

TEST(FeatureTypesTest, MixingTypesIsAnError) {
  cv::Mat orb(3, 32, CV_8U), surf(3, 64, CV_32F);
  EXPECT_THROW(CheckCompatibleDescriptors(FeatureType::kOrb, orb, FeatureType::kSurf, surf, "t"),
               InvalidArgument);
  EXPECT_NO_THROW(CheckCompatibleDescriptors(FeatureType::kOrb, orb, FeatureType::kOrb, orb, "t"));
  cv::Mat surf128(3, 128, CV_32F);
  EXPECT_THROW(
      CheckCompatibleDescriptors(FeatureType::kSurf, surf, FeatureType::kSurf, surf128, "t"),
      InvalidArgument);
}

}  // namespace
}  // namespace placedb
