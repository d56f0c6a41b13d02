#include "placedb/util/check.h"

#include <gtest/gtest.h>

namespace placedb {
namespace {

struct FakeOptions {
  int value = 1;
  std::string Check() const { return value > 0 ? "" : "value must be > 0"; }
};

TEST(CheckTest, PassingCheckDoesNotThrow) { EXPECT_NO_THROW(PLACEDB_CHECK(1 + 1 == 2)); }

TEST(CheckTest, FailingCheckThrowsWithLocationAndValues) {
  try {
    const int k = 7;
    PLACEDB_CHECK(k < 3, "k=", k);
    FAIL() << "expected a throw";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("check_test.cc"), std::string::npos) << what;
    EXPECT_NE(what.find("k < 3"), std::string::npos) << what;
    EXPECT_NE(what.find("k=7"), std::string::npos) << what;
  }
}

TEST(CheckTest, OptionsCheck) {
  FakeOptions ok;
  EXPECT_NO_THROW(PLACEDB_CHECK_OPTIONS(ok));
  FakeOptions bad;
  bad.value = 0;
  EXPECT_THROW(PLACEDB_CHECK_OPTIONS(bad), std::invalid_argument);
}

TEST(CheckTest, RuntimeThrow) {
  EXPECT_THROW(PLACEDB_THROW_RUNTIME("disk on fire"), std::runtime_error);
}

}  // namespace
}  // namespace placedb
