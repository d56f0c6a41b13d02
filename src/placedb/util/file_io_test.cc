#include "placedb/util/file_io.h"

#include <gtest/gtest.h>

#include <filesystem>

namespace placedb {
namespace {
namespace fs = std::filesystem;

TEST(FileIoTest, AtomicWriteRoundTripAndReplace) {
  const fs::path dir = fs::temp_directory_path() / ("placedb_fileio_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "a.bin").string();
  WriteFileAtomic(path, "first");
  EXPECT_EQ(ReadFileToString(path), "first");
  WriteFileAtomic(path, std::string("sec\0ond", 7));
  EXPECT_EQ(ReadFileToString(path), std::string("sec\0ond", 7));
  EXPECT_EQ(FileSize(path), 7u);
  // No temporary file is left behind.
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 1);
  EXPECT_EQ(DirectorySize(dir.string()), 7u);
  fs::remove_all(dir);
}

TEST(FileIoTest, MissingFileThrowsNamingIt) {
  try {
    ReadFileToString("/nonexistent/placedb/file.bin");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/placedb/file.bin"), std::string::npos);
  }
}

TEST(FileIoTest, Crc32KnownValue) {
  // The standard CRC-32 check value of "123456789".
  EXPECT_EQ(Crc32("123456789", 9), 0xCBF43926u);
}

TEST(FileIoTest, BinaryRoundTripAndTruncation) {
  BinaryWriter w;
  w.Put<uint32_t>(0xDEADBEEF);
  w.Put<double>(2.5);
  const float values[3] = {1.f, -2.f, 3.5f};
  w.Align(8);
  w.PutArray(values, 3);
  const std::string& buf = w.buffer();

  BinaryReader r(buf.data(), buf.size(), "test");
  EXPECT_EQ(r.Get<uint32_t>(), 0xDEADBEEFu);
  EXPECT_EQ(r.Get<double>(), 2.5);
  r.Align(8);
  float back[3];
  r.GetArray(back, 3);
  EXPECT_EQ(back[2], 3.5f);
  EXPECT_EQ(r.remaining(), 0u);

  BinaryReader short_reader(buf.data(), 6, "short.bin");
  short_reader.Get<uint32_t>();
  try {
    short_reader.Get<double>();
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("short.bin"), std::string::npos);
  }
}

}  // namespace
}  // namespace placedb
