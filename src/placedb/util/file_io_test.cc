#include "placedb/util/file_io.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "placedb/util/checksum.h"
#include "placedb/util/testing.h"

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

// The streaming checksum equals the one-shot checksum, whatever the pieces.
TEST(FileIoTest, ChecksumStreamEqualsOneShot) {
  std::string data(100000, '\0');
  for (size_t i = 0; i < data.size(); ++i) data[i] = static_cast<char>(i * 131 + 7);
  const uint64_t whole = Checksum64(data.data(), data.size());
  Checksum64Stream s;
  for (size_t at = 0, step = 1; at < data.size(); at += step, step = step * 3 % 4099 + 1) {
    s.Update(data.data() + at, std::min(step, data.size() - at));
  }
  EXPECT_EQ(s.Digest(), whole);
  data[500] ^= 1;
  EXPECT_NE(Checksum64(data.data(), data.size()), whole);
  EXPECT_EQ(ChecksumHex(0x0123456789abcdefULL), "0123456789abcdef");
}

// The atomic writer: nothing at the path until Commit; an uncommitted one
// leaves no trace; WriteAt fills in a header.
TEST(FileIoTest, AtomicFileWriter) {
  testing_util::TempDir tmp;
  const std::string path = tmp.Path("f.bin");
  {
    AtomicFileWriter w(path);
    w.Write("xxxxhello", 9);
    w.Align(16);
    EXPECT_EQ(w.position(), 16u);
    w.WriteAt(0, "HEAD", 4);
    EXPECT_FALSE(std::filesystem::exists(path));
    w.Commit();
  }
  EXPECT_EQ(ReadFileToString(path), std::string("HEADhello\0\0\0\0\0\0\0", 16));
  {
    AtomicFileWriter w(tmp.Path("g.bin"));
    w.Write("abc", 3);
  }
  EXPECT_FALSE(std::filesystem::exists(tmp.Path("g.bin")));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(tmp.Path()),
                          std::filesystem::directory_iterator()),
            1);
}

// Files read through one directory handle come from that directory even
// after its path is renamed away.
TEST(FileIoTest, DirectoryHandleReadsFromTheOpenedDirectory) {
  testing_util::TempDir tmp;
  std::filesystem::create_directories(tmp.Path("a"));
  WriteFileAtomic(tmp.Path("a/x.txt"), "first");
  const DirectoryHandle dir(tmp.Path("a"));
  std::filesystem::rename(tmp.Path("a"), tmp.Path("b"));
  std::filesystem::create_directories(tmp.Path("a"));
  WriteFileAtomic(tmp.Path("a/x.txt"), "second");
  std::string text;
  ASSERT_TRUE(dir.ReadFile("x.txt", &text, 100));
  EXPECT_EQ(text, "first");
  EXPECT_FALSE(dir.ReadFile("missing.txt", &text, 100));
  EXPECT_EQ(dir.MapFile("missing.txt"), nullptr);
  ASSERT_NE(dir.MapFile("x.txt"), nullptr);
  EXPECT_THROW(dir.ReadFile("x.txt", &text, 2), std::runtime_error);
  EXPECT_THROW(DirectoryHandle(tmp.Path("none")), std::runtime_error);
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
