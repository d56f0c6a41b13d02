#include "placedb/util/mapped_file.h"

#include <gtest/gtest.h>

#include <atomic>
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

// 32 MiB of a pattern, written to `path`.
std::string WritePattern(const std::string& path) {
  std::string content(size_t{32} << 20, '\0');
  for (size_t i = 0; i < content.size(); ++i) content[i] = static_cast<char>(i * 7 + (i >> 12));
  WriteFileAtomic(path, content);
  return content;
}

// Released pages leave the process's resident set and read back the same;
// a prefetch changes nothing a reader sees.
TEST(MappedFileTest, ReleasedPagesLeaveTheResidentSetAndReadBackTheSame) {
  testing_util::TempDir tmp;
  const std::string content = WritePattern(tmp.Path("f.bin"));
  const auto mapped = MappedFile::Open(tmp.Path("f.bin"));
  std::atomic<bool> stop{false};
  mapped->Prefetch(stop);
  const uint64_t before = ProcessFileBackedResidentBytes();
  ASSERT_GT(before, 0u);
  EXPECT_EQ(std::memcmp(mapped->data(), content.data(), content.size()), 0);
  const uint64_t touched = ProcessFileBackedResidentBytes();
  EXPECT_GE(touched, before + (size_t{16} << 20));
  mapped->ReleaseResidentPages();
  EXPECT_LE(ProcessFileBackedResidentBytes() + (size_t{16} << 20), touched);
  EXPECT_EQ(std::memcmp(mapped->data(), content.data(), content.size()), 0);
  stop = true;
  mapped->Prefetch(stop);  // returns at once
  MappedFile::Open(tmp.Path("f.bin"))->ReleaseResidentPages();
}

// ReadAt reads the mapped file's bytes (the ones mapped, also once the path
// is replaced) without mapping them into the process; ranges outside the
// file are refused.
TEST(MappedFileTest, ReadAtReadsTheFileWithoutMappingIt) {
  testing_util::TempDir tmp;
  const std::string path = tmp.Path("f.bin");
  const std::string content = WritePattern(path);
  const auto mapped = MappedFile::Open(path);
  WriteFileAtomic(path, "other");  // the mapped file is read, not the path
  std::string read(content.size(), '\1');
  const uint64_t before = ProcessFileBackedResidentBytes();
  mapped->ReadAt(0, read.size(), read.data());
  const uint64_t after = ProcessFileBackedResidentBytes();
  EXPECT_TRUE(read == content);
  EXPECT_LT(after, before + (size_t{1} << 20)) << "ReadAt mapped the file";
  // Reading through the mapping does map it (the measure can see it).
  EXPECT_EQ(std::memcmp(mapped->data(), content.data(), content.size()), 0);
  EXPECT_GE(ProcessFileBackedResidentBytes(), after + (size_t{16} << 20));
  char part[5];
  mapped->ReadAt(content.size() - 5, 5, part);
  EXPECT_EQ(std::memcmp(part, content.data() + content.size() - 5, 5), 0);
  mapped->ReadAt(content.size(), 0, part);  // nothing, at the end
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>(
      [&] { mapped->ReadAt(content.size() - 4, 5, part); }, "outside"));
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>(
      [&] { mapped->ReadAt(content.size() + 1, 0, part); }, "outside"));
  WriteFileAtomic(tmp.Path("empty"), "");
  const auto empty = MappedFile::Open(tmp.Path("empty"));
  empty->ReadAt(0, 0, part);
  EXPECT_THROW(empty->ReadAt(0, 1, part), InvalidArgument);
}

}  // namespace
}  // namespace placedb
