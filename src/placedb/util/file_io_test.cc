#include "placedb/util/file_io.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include "placedb/util/checksum.h"
#include "placedb/util/json_reader.h"
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

// Only regular files (or new paths) are replaced. A symlink, a device, a FIFO
// or /dev/fd/N is written as a stream and stays what it was (once, as root,
// `--json /dev/stdout` replaced the system's /dev/stdout symlink with a
// file); a directory is refused with one clear error.
TEST(FileIoTest, SpecialFilesAreStreamedNeverReplaced) {
  testing_util::TempDir tmp;
  // A symlink: the target gets the data, the link stays a link.
  const std::string target = tmp.Path("target.json"), link = tmp.Path("link.json");
  WriteFileAtomic(target, "old old old");
  fs::create_symlink(target, link);
  WriteFileAtomic(link, "new");
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(ReadFileToString(target), "new");
  // A character device, through a link of ours (a failing version of this
  // test must not replace the system's /dev/null).
  const std::string null_link = tmp.Path("null");
  fs::create_symlink("/dev/null", null_link);
  WriteFileAtomic(null_link, "nothing");
  EXPECT_TRUE(fs::is_symlink(null_link));
  EXPECT_TRUE(fs::is_character_file("/dev/null"));
  // /dev/fd/N of a pipe (what /dev/stdout is when output is piped).
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const std::string fd_path = "/dev/fd/" + std::to_string(fds[1]);
  WriteFileAtomic(fd_path, "through the pipe");
  ::close(fds[1]);
  char buf[64] = {};
  EXPECT_EQ(::read(fds[0], buf, sizeof(buf)), 16);
  ::close(fds[0]);
  EXPECT_EQ(std::string(buf), "through the pipe");
  EXPECT_TRUE(fs::is_symlink("/dev/stdout") || !fs::exists("/dev/stdout"));
  // A FIFO: a reader gets the data, the FIFO stays a FIFO.
  const std::string fifo = tmp.Path("fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // The reader opens first (non-blocking), so the writer never waits.
  const int fifo_reader = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);
  ASSERT_GE(fifo_reader, 0);
  WriteFileAtomic(fifo, "fifo data");
  char fifo_buf[64] = {};
  EXPECT_EQ(::read(fifo_reader, fifo_buf, sizeof(fifo_buf)), 9);
  ::close(fifo_reader);
  EXPECT_EQ(std::string(fifo_buf), "fifo data");
  EXPECT_TRUE(fs::is_fifo(fifo));
  // A directory.
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>([&] { WriteFileAtomic(tmp.Path(""), "x"); },
                                                        {"is a directory"}));
  // The binary writer (which fills its header in last) refuses them all.
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>([&] { AtomicFileWriter w(link); },
                                                        {"not a regular file"}));
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>([&] { AtomicFileWriter w(fifo); },
                                                        {"not a regular file"}));
  // Nothing else appeared beside them.
  int entries = 0;
  for (const auto& e : fs::directory_iterator(tmp.Path(""))) {
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
    ++entries;
  }
  EXPECT_EQ(entries, 4);
}

// Two writers of one path at once never share a temporary file: the result
// is one of the two contents, whole.
TEST(FileIoTest, ConcurrentAtomicWritesOfOnePathDoNotMix) {
  testing_util::TempDir tmp;
  const std::string path = tmp.Path("shared.bin");
  const std::string a(1 << 20, 'a'), b(1 << 20, 'b');
  for (int round = 0; round < 5; ++round) {
    std::thread t1([&] { WriteFileAtomic(path, a); });
    std::thread t2([&] { WriteFileAtomic(path, b); });
    t1.join();
    t2.join();
    const std::string got = ReadFileToString(path);
    EXPECT_TRUE(got == a || got == b) << "round " << round;
  }
  EXPECT_NE(TempPathFor(path), TempPathFor(path));
}

// A write that fails (here: the file size limit, as a full disk would) throws
// and leaves no temporary file behind.
TEST(FileIoTest, AFailedWriteLeavesNoTemporaryFile) {
  testing_util::TempDir tmp;
  struct rlimit old_limit;
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  struct rlimit small = old_limit;
  small.rlim_cur = 4096;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  bool threw = false;
  try {
    WriteFileAtomic(tmp.Path("big.bin"), std::string(1 << 20, 'x'));
  } catch (const IoError& e) {
    threw = true;
    EXPECT_NE(std::string(e.what()).find("cannot write"), std::string::npos) << e.what();
  }
  bool writer_threw = false;
  try {
    AtomicFileWriter w(tmp.Path("big2.bin"));
    const std::string chunk(2 << 20, 'y');
    w.Write(chunk.data(), chunk.size());
    w.Commit();
  } catch (const IoError&) {
    writer_threw = true;
  }
  ::setrlimit(RLIMIT_FSIZE, &old_limit);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_TRUE(threw);
  EXPECT_TRUE(writer_threw);
  EXPECT_TRUE(fs::is_empty(tmp.Path("")));
}

// Temporary names: recognised (ours and earlier versions'), with their pid;
// a sweep removes those of gone processes only.
TEST(FileIoTest, TempFileNamesAndSweep) {
  long pid = 0;
  EXPECT_TRUE(IsTempFileName("manifest.json.tmp.123.4", &pid));
  EXPECT_EQ(pid, 123);
  EXPECT_TRUE(IsTempFileName("keyframes.writing.bin.tmp.77", &pid));
  EXPECT_EQ(pid, 77);
  EXPECT_FALSE(IsTempFileName(".tmp.1"));
  EXPECT_FALSE(IsTempFileName("a.tmp."));
  EXPECT_FALSE(IsTempFileName("a.tmp.x1"));
  EXPECT_FALSE(IsTempFileName("a.tmp.1.2.3"));
  EXPECT_FALSE(IsTempFileName("000001.png"));
  const std::string ours = TempPathFor("/x/y.json");
  EXPECT_TRUE(IsTempFileName(fs::path(ours).filename().string(), &pid));
  EXPECT_EQ(pid, ::getpid());
  EXPECT_FALSE(ProcessIsGone(::getpid()));
  EXPECT_TRUE(ProcessIsGone(99999999));

  testing_util::TempDir tmp;
  WriteFileAtomic(tmp.Path("a.json.tmp.99999999.1"), "debris");
  WriteFileAtomic(tmp.Path("a.json.tmp." + std::to_string(::getpid()) + ".5"), "live");
  WriteFileAtomic(tmp.Path("a.json"), "kept");
  EXPECT_EQ(SweepTempFiles(DirectoryHandle(tmp.Path(""))), 1u);
  EXPECT_FALSE(fs::exists(tmp.Path("a.json.tmp.99999999.1")));
  EXPECT_TRUE(fs::exists(tmp.Path("a.json")));
}

// A writer's folder handle never reaches through a symlink: a child that is
// a link is not opened, a link inside is not followed by a removal, and an
// atomic write replaces a link instead of writing through it.
TEST(FileIoTest, DirectoryHandleNeverFollowsSymlinks) {
  testing_util::TempDir tmp;
  fs::create_directories(tmp.Path("outside"));
  fs::create_directories(tmp.Path("db/real"));
  WriteFileAtomic(tmp.Path("outside/mine.png"), "mine");
  fs::create_directory_symlink(tmp.Path("outside"), tmp.Path("db/images"));
  fs::create_symlink(tmp.Path("outside/mine.png"), tmp.Path("db/real/link.png"));
  const DirectoryHandle db(tmp.Path("db"));
  EXPECT_EQ(DirectoryHandle::OpenChild(db, "images"), nullptr);
  EXPECT_EQ(DirectoryHandle::OpenChild(db, "missing"), nullptr);
  const std::unique_ptr<DirectoryHandle> real = DirectoryHandle::OpenChild(db, "real");
  ASSERT_NE(real, nullptr);
  EXPECT_EQ(real->List(), std::vector<std::string>{"link.png"});
  EXPECT_FALSE(real->RemoveRegularFile("link.png"));
  EXPECT_FALSE(db.RemoveRegularFile("images"));
  EXPECT_FALSE(db.RemoveRegularFile("real/link.png"));  // names only, no paths
  real->WriteFileAtomic("link.png", "new");
  EXPECT_EQ(ReadFileToString(tmp.Path("outside/mine.png")), "mine");
  EXPECT_EQ(ReadFileToString(tmp.Path("db/real/link.png")), "new");
  EXPECT_FALSE(fs::is_symlink(tmp.Path("db/real/link.png")));
  EXPECT_TRUE(real->RemoveRegularFile("link.png"));
  EXPECT_TRUE(real->List().empty());
}

// One writer per folder: a second lock on it is refused while the first is
// held, and granted once it is let go.
TEST(FileIoTest, DirectoryLockIsExclusive) {
  testing_util::TempDir tmp;
  std::unique_ptr<DirectoryLock> first = DirectoryLock::TryLock(tmp.Path(""));
  ASSERT_NE(first, nullptr);
  EXPECT_EQ(DirectoryLock::TryLock(tmp.Path("")), nullptr);
  first.reset();
  EXPECT_NE(DirectoryLock::TryLock(tmp.Path("")), nullptr);
  EXPECT_THROW(DirectoryLock::TryLock(tmp.Path("missing")), NotFound);
}

TEST(FileIoTest, MissingFileThrowsNamingIt) {
  try {
    ReadFileToString("/nonexistent/placedb/file.bin");
    FAIL();
  } catch (const NotFound& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/placedb/file.bin"), std::string::npos);
  }
}

// The kinds of errors: a missing input is NotFound, a folder given as a file
// InvalidArgument, a write the system refuses IoError. (Tests run as root, so
// permissions cannot refuse anything: a path through a regular file and
// /proc, which takes no new files, do.)
TEST(FileIoTest, ErrorKindsOfReadsAndWrites) {
  testing_util::TempDir tmp;
  WriteFileAtomic(tmp.Path("file"), "x");
  EXPECT_TRUE(testing_util::ThrowsWith<NotFound>([&] { ReadFileToString(tmp.Path("missing")); },
                                                 {"cannot open", "missing"}));
  EXPECT_THROW(ReadFileToString(tmp.Path("file/inside")), NotFound);
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>([&] { ReadFileToString(tmp.Path("")); },
                                                        "is a directory"));
  EXPECT_TRUE(testing_util::ThrowsWith<IoError>(
      [&] { WriteFileAtomic(tmp.Path("file/out.json"), "{}"); }, "cannot write"));
  EXPECT_THROW(WriteFileAtomic("/proc/placedb_test_output.json", "{}"), IoError);
  EXPECT_THROW(AtomicFileWriter("/proc/placedb_test_output.bin"), IoError);
  EXPECT_THROW(DirectoryHandle(tmp.Path("file")), NotFound);
  // No message names a source file: that is in where().
  try {
    ReadFileToString(tmp.Path("missing"));
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).find(".cc:"), std::string::npos) << e.what();
    EXPECT_NE(e.where().find("util/file_io.cc:"), std::string::npos) << e.where();
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
  EXPECT_THROW(dir.ReadFile("x.txt", &text, 2), CorruptDatabase);
  EXPECT_THROW(DirectoryHandle(tmp.Path("none")), NotFound);
  // A name that is not a regular file (here a folder) where a database file
  // is expected: the database is damaged.
  std::filesystem::create_directories(tmp.Path("b/sub.bin"));  // the handle's folder
  EXPECT_THROW(dir.MapFile("sub.bin"), CorruptDatabase);
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
  } catch (const CorruptDatabase& e) {
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("short.bin"), std::string::npos);
  }
}

// ---- names and text from files (issue 17) -------------------------------------

TEST(PlainFileNameTest, OnlyPlainNamesInsideOneFolder) {
  for (const std::string name : {"000001.png", "a", "a.b.c", "A-Z_0-9.png", "x..y"}) {
    EXPECT_TRUE(IsPlainFileName(name)) << name;
  }
  EXPECT_TRUE(IsPlainFileName(std::string(255, 'a')));
  for (const std::string& name :
       {std::string(""), std::string("."), std::string(".."), std::string(".hidden"),
        std::string("../x"), std::string("a/b"), std::string("/etc/passwd"), std::string("a\\b"),
        std::string("a b"), std::string("a\nb"), std::string("a\x1b"), std::string("a\0b", 3),
        std::string("caf\xe9"), std::string("caf\xc3\xa9"), std::string("a\x7f"),
        std::string(256, 'a'), std::string("a*"), std::string("a:b")}) {
    EXPECT_FALSE(IsPlainFileName(name)) << EscapeForTerminal(name);
  }
}

TEST(TerminalTextTest, ControlBytesAndInvalidUtf8AreEscaped) {
  EXPECT_EQ(EscapeForTerminal("plain/path.png"), "plain/path.png");
  EXPECT_EQ(EscapeForTerminal("caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80"),
            "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80");  // UTF-8 is kept
  EXPECT_EQ(EscapeForTerminal("caf\xe9.jpg"), "caf\\xe9.jpg");
  EXPECT_EQ(EscapeForTerminal("\x1b[2J\n\r\t"), "\\x1b[2J\\x0a\\x0d\\x09");
  EXPECT_EQ(EscapeForTerminal(std::string("a\0b", 3)), "a\\x00b");
  EXPECT_EQ(EscapeForTerminal("\x7f"), "\\x7f");
  EXPECT_EQ(EscapeForTerminal("\xc2\x9b"), "\\xc2\\x9b");                    // C1 CSI
  EXPECT_EQ(EscapeForTerminal("\xc0\xaf"), "\\xc0\\xaf");                    // overlong '/'
  EXPECT_EQ(EscapeForTerminal("\xed\xa0\x80"), "\\xed\\xa0\\x80");           // a surrogate
  EXPECT_EQ(EscapeForTerminal("\xf4\x90\x80\x80"), "\\xf4\\x90\\x80\\x80");  // above U+10FFFF
  EXPECT_EQ(EscapeForTerminal("\xe2\x82"), "\\xe2\\x82");                    // cut short
  EXPECT_TRUE(IsValidUtf8("caf\xc3\xa9"));
  EXPECT_FALSE(IsValidUtf8("caf\xe9"));
  // Any bytes: the result is valid UTF-8 with no control character.
  std::mt19937 rng(17);
  for (int i = 0; i < 2000; ++i) {
    std::string text;
    for (int n = static_cast<int>(rng() % 24); n > 0; --n) text += static_cast<char>(rng());
    const std::string shown = EscapeForTerminal(text);
    EXPECT_TRUE(IsValidUtf8(shown));
    for (const char c : shown) EXPECT_FALSE((c >= 0 && c < 0x20) || c == 0x7f);
  }
}

TEST(JsonOutputTest, AnyBytesDumpAsValidJson) {
  const nlohmann::json j = {{"source", "/data/caf\xe9.jpg"},
                            {"list", {std::string("a\0b\x1b\xff", 5), "ok \xc3\xa9"}}};
  EXPECT_THROW(j.dump(), nlohmann::json::type_error);  // nlohmann's default: error 316
  const std::string text = DumpJson(j, 2);
  EXPECT_TRUE(IsValidUtf8(text));
  const nlohmann::json back = nlohmann::json::parse(text);
  EXPECT_EQ(back["source"], "/data/caf\xef\xbf\xbd.jpg");  // U+FFFD
  EXPECT_EQ(back["list"][0], std::string("a\0b\x1b\xef\xbf\xbd", 7));
  EXPECT_EQ(back["list"][1], "ok \xc3\xa9");
  EXPECT_EQ(DumpJson(nlohmann::json{{"a", 1}}), "{\"a\":1}");
}

}  // namespace
}  // namespace placedb
