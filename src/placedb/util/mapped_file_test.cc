#include "placedb/util/mapped_file.h"

#include <gtest/gtest.h>

#include <cstring>

#include "placedb/util/file_io.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {

TEST(MappedFileTest, MapsContentAndOutlivesAReplace) {
  testing_util::TempDir tmp;
  const std::string path = tmp.Path("f.bin");
  WriteFileAtomic(path, std::string("hello\0world", 11));
  const auto mapped = MappedFile::Open(path);
  ASSERT_EQ(mapped->size(), 11u);
  EXPECT_EQ(std::memcmp(mapped->data(), "hello\0world", 11), 0);
  // Replacing the file (as a rebuild does) leaves the mapping intact.
  WriteFileAtomic(path, "other");
  EXPECT_EQ(std::memcmp(mapped->data(), "hello", 5), 0);
  EXPECT_EQ(MappedFile::Open(path)->size(), 5u);
}

TEST(MappedFileTest, EmptyAndMissingFiles) {
  testing_util::TempDir tmp;
  WriteFileAtomic(tmp.Path("empty"), "");
  EXPECT_EQ(MappedFile::Open(tmp.Path("empty"))->size(), 0u);
  EXPECT_TRUE(testing_util::ThrowsWith<NotFound>([&] { MappedFile::Open(tmp.Path("missing")); },
                                                 "missing"));
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>([&] { MappedFile::Open(tmp.Path("")); },
                                                        "not a regular file"));
}

}  // namespace
}  // namespace placedb
