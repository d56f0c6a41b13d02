#include "placedb/util/check.h"

#include <gtest/gtest.h>

#include <string>

namespace placedb {
namespace {

struct FakeOptions {
  int value = 1;
  std::string Check() const { return value > 0 ? "" : "`value` must be > 0"; }
};

TEST(CheckTest, PassingCheckDoesNotThrow) { EXPECT_NO_THROW(PLACEDB_CHECK(1 + 1 == 2)); }

// A failed check is a bug in placedb: InternalError, whose message names the
// condition and the values, and whose what() also names the source line and
// asks for a report. The message itself has no path.
TEST(CheckTest, FailingCheckIsAnInternalErrorWithLocationInWhere) {
  try {
    const int k = 7;
    PLACEDB_CHECK(k < 3, "k=", k);
    FAIL() << "expected a throw";
  } catch (const InternalError& e) {
    EXPECT_EQ(e.kind(), ErrorKind::kInternal);
    const std::string message = e.message();
    EXPECT_NE(message.find("k < 3"), std::string::npos) << message;
    EXPECT_NE(message.find("k=7"), std::string::npos) << message;
    EXPECT_EQ(message.find("check_test.cc"), std::string::npos) << message;
    EXPECT_EQ(e.where().rfind("util/check_test.cc:", 0), 0u) << e.where();
    const std::string what = e.what();
    EXPECT_NE(what.find("bug in placedb"), std::string::npos) << what;
    EXPECT_NE(what.find("[util/check_test.cc:"), std::string::npos) << what;
  }
}

// Every other kind keeps the source line out of what() (a user reads it) and
// in where() (for --verbose and debug logs).
TEST(CheckTest, ThrowMacrosGiveTheirKindAndKeepTheLocationOutOfTheMessage) {
  auto expect_kind = [](auto&& fn, ErrorKind kind) {
    try {
      fn();
      ADD_FAILURE() << "nothing thrown";
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), kind) << e.what();
      EXPECT_EQ(std::string(e.what()), "disk on fire 3");
      EXPECT_EQ(e.message(), "disk on fire 3");
      EXPECT_EQ(e.where().rfind("util/check_test.cc:", 0), 0u) << e.where();
    }
  };
  expect_kind([] { PLACEDB_THROW_INVALID("disk on fire ", 3); }, ErrorKind::kInvalidArgument);
  expect_kind([] { PLACEDB_THROW_NOT_FOUND("disk on fire ", 3); }, ErrorKind::kNotFound);
  expect_kind([] { PLACEDB_THROW_CORRUPT("disk on fire ", 3); }, ErrorKind::kCorruptDatabase);
  expect_kind([] { PLACEDB_THROW_IO("disk on fire ", 3); }, ErrorKind::kIo);
  EXPECT_THROW(PLACEDB_THROW_INVALID("x"), InvalidArgument);
  EXPECT_THROW(PLACEDB_THROW_NOT_FOUND("x"), NotFound);
  EXPECT_THROW(PLACEDB_THROW_CORRUPT("x"), CorruptDatabase);
  EXPECT_THROW(PLACEDB_THROW_IO("x"), IoError);
  try {
    PLACEDB_THROW_INTERNAL("broken ", 1);
    ADD_FAILURE() << "nothing thrown";
  } catch (const InternalError& e) {
    EXPECT_EQ(e.message(), "broken 1");
    EXPECT_NE(std::string(e.what()).find("[util/check_test.cc:"), std::string::npos) << e.what();
  }
  // All of them are placedb::Error and std::exception.
  EXPECT_THROW(PLACEDB_THROW_IO("x"), Error);
  EXPECT_THROW(PLACEDB_THROW_IO("x"), std::exception);
}

TEST(CheckTest, OptionsCheckIsInvalidArgumentWithoutTheVariableName) {
  FakeOptions ok;
  EXPECT_NO_THROW(PLACEDB_CHECK_OPTIONS(ok));
  FakeOptions bad;
  bad.value = 0;
  try {
    PLACEDB_CHECK_OPTIONS(bad);
    FAIL() << "expected a throw";
  } catch (const InvalidArgument& e) {
    EXPECT_EQ(e.message(), "invalid options: `value` must be > 0");
    EXPECT_EQ(std::string(e.what()), "invalid options: value must be > 0");
    EXPECT_EQ(FormatOptionNames(e.message(), OptionNames::kFlags),
              "invalid options: --value must be > 0");
  }
}

TEST(CheckTest, FormatOptionNames) {
  EXPECT_EQ(FormatOptionNames("`top_k` must be in [1, 10000]", OptionNames::kFlags),
            "--top-k must be in [1, 10000]");
  EXPECT_EQ(FormatOptionNames("`top_k` must be in [1, 10000]", OptionNames::kKeywords),
            "top_k must be in [1, 10000]");
  // Only lower-case names are option names; other backquoted text is kept.
  EXPECT_EQ(FormatOptionNames("run `placedb build` or `Top`", OptionNames::kFlags),
            "run `placedb build` or `Top`");
  EXPECT_EQ(FormatOptionNames("a lone ` quote", OptionNames::kFlags), "a lone ` quote");
}

}  // namespace
}  // namespace placedb
