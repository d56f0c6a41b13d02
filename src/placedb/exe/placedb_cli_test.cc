// Runs the placedb binary as a user would: every sub-command, the bad-input
// cases, and the exit codes and one-line errors.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "placedb/builder/builder.h"
#include "placedb/exe/cli_testing.h"
#include "placedb/feature/extractor.h"
#include "placedb/query/query.h"
#include "placedb/storage/database.h"
#include "placedb/storage/keyframe_file.h"
#include "placedb/util/checksum.h"
#include "placedb/util/testing.h"

namespace {
namespace fs = std::filesystem;

const std::string kBinary = PLACEDB_BINARY;
const std::string kImages = PLACEDB_DATA_DIR "/rtabmap_loop/images";
const std::string kTruth = PLACEDB_DATA_DIR "/rtabmap_loop/ground_truth.csv";

using placedb::testing_util::CommandResult;
using placedb::testing_util::Contains;

CommandResult Placedb(const std::string& args) {
  return placedb::testing_util::RunBinary(kBinary, args);
}

// The exit code and what the binary wrote to stdout alone (stderr dropped).
CommandResult PlacedbStdout(const std::string& args) {
  return placedb::testing_util::RunShell(kBinary + " " + args + " 2>/dev/null");
}

// The exit code and what the binary wrote to stderr alone (stdout dropped).
CommandResult PlacedbStderr(const std::string& args) {
  return placedb::testing_util::RunBinaryStderr(kBinary, args);
}

class CliTest : public ::testing::Test {
 protected:
  std::string Path(const std::string& name) const { return tmp_.Path(name); }

  placedb::testing_util::TempDir tmp_;
};

TEST_F(CliTest, HelpListsEverySubcommandAndOption) {
  const CommandResult help = Placedb("--help");
  EXPECT_EQ(help.code, 0);
  for (const char* sub : {"build", "query", "eval", "experiment", "info", "bench", "verify"}) {
    EXPECT_TRUE(Contains(help.output, sub)) << sub;
  }
  const CommandResult build_help = Placedb("build --help");
  EXPECT_EQ(build_help.code, 0);
  for (const char* flag : {"--images",
                           "--tum",
                           "--first",
                           "--last",
                           "--out",
                           "--features",
                           "--crop",
                           "--resize",
                           "--threads",
                           "--quiet",
                           "--strict",
                           "--crop-percentile",
                           "--crop-fast-threshold",
                           "--crop-fast-nonmax",
                           "--crop-min-region",
                           "--orb-max-features",
                           "--orb-patch-size",
                           "--surf-hessian",
                           "--upscale-below",
                           "--frame-size",
                           "--tum-rgb-list",
                           "--tum-groundtruth",
                           "--png-compression",
                           "--extract-in-context",
                           "--no-images"}) {
    EXPECT_TRUE(Contains(build_help.output, flag)) << flag;
  }
  // Every field of the query options has its flag, on query, eval and bench.
  for (const char* sub : {"query", "eval", "bench"}) {
    const CommandResult help = Placedb(std::string(sub) + " --help");
    EXPECT_EQ(help.code, 0);
    for (const char* flag :
         {"--top-k", "--search", "--ratio", "--max-hamming", "--max-l2", "--laplacian-sign",
          "--one-to-one", "--cross-check", "--min-matches", "--no-verify", "--verify-model",
          "--verify-candidates", "--verify-error", "--verify-confidence", "--verify-iterations",
          "--verify-seed", "--min-score", "--threads"}) {
      EXPECT_TRUE(Contains(help.output, flag)) << sub << " " << flag;
    }
  }
  // Defaults come from the options structs.
  EXPECT_TRUE(Contains(build_help.output, "85")) << build_help.output;
  const CommandResult none = Placedb("");
  EXPECT_NE(none.code, 0);
}

// Whether `help` shows `flag` whole (not only as the start of a longer one).
bool HasFlag(const std::string& help, const std::string& flag) {
  for (size_t at = help.find(flag); at != std::string::npos; at = help.find(flag, at + 1)) {
    const size_t end = at + flag.size();
    if (end == help.size() ||
        !(std::isalnum(static_cast<unsigned char>(help[end])) || help[end] == '-'))
      return true;
  }
  return false;
}

// The command line against the library's option tables: every option a
// table shows on the command line is a flag of some command (its --help
// lists it), and `placedb options --json` reports every table, nested ones
// too. An options struct whose table no command binds, or an option every
// command skips, fails here.
TEST_F(CliTest, EveryCommandLineOptionOfEveryTableIsAFlag) {
  const CommandResult r = Placedb("options --json");
  ASSERT_EQ(r.code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output);
  std::map<std::string, std::string> help;  // command -> its --help
  int options = 0;
  ASSERT_GE(j.at("tables").size(), 9u);
  for (const nlohmann::json& table : j.at("tables")) {
    const std::string what = table.at("table");
    EXPECT_FALSE(table.at("options").empty()) << what;
    // The voting node's options are the ROS voter's flags, not placedb's.
    const bool voter = what == "vote options";
    EXPECT_EQ(table.at("commands").empty(), voter) << what;
#ifdef PLACEDB_VOTER
    if (voter && help.count("voter") == 0) {
      FILE* pipe = popen(PLACEDB_VOTER " --help 2>&1", "r");
      ASSERT_NE(pipe, nullptr);
      char buf[4096];
      for (size_t n; (n = fread(buf, 1, sizeof(buf), pipe)) > 0;) help["voter"].append(buf, n);
      EXPECT_EQ(pclose(pipe), 0) << help["voter"];
    }
#endif
    for (const nlohmann::json& o : table.at("options")) {
      if (!o.at("command_line").get<bool>()) continue;
      ++options;
      const std::string flag = o.at("flag");
      if (voter) {
#ifdef PLACEDB_VOTER
        EXPECT_TRUE(HasFlag(help["voter"], flag)) << "placedb_voter --help lacks " << flag;
#endif
        continue;
      }
      EXPECT_FALSE(o.at("shown_by").empty()) << what << ": " << flag << " is no command's flag";
      for (const std::string command : o.at("shown_by")) {
        if (help.count(command) == 0) help[command] = Placedb(command + " --help").output;
        EXPECT_TRUE(HasFlag(help[command], flag)) << command << " --help lacks " << flag;
      }
    }
  }
  EXPECT_GT(options, 80);
  // --markdown and --json exclude each other: one line, exit 1.
  const CommandResult both = PlacedbStderr("options --json --markdown");
  EXPECT_EQ(both.code, 1);
  EXPECT_TRUE(Contains(both.output, "error: --markdown and --json exclude each other"))
      << both.output;
}

TEST_F(CliTest, BuildQueryEvalInfo) {
  const std::string db = Path("db");
  const CommandResult build =
      Placedb("build --images " + kImages + " --first 1 --last 40 --crop chroma --out " + db +
              " --quiet --json " + Path("build.json"));
  ASSERT_EQ(build.code, 0) << build.output;
  EXPECT_TRUE(Contains(build.output, "40 of 40 frames")) << build.output;
  // No progress bar when not a terminal.
  EXPECT_FALSE(Contains(build.output, "\r"));

  const CommandResult info = Placedb("info --db " + db);
  EXPECT_EQ(info.code, 0);
  EXPECT_TRUE(Contains(info.output, "keyframes       40")) << info.output;
  EXPECT_TRUE(Contains(info.output, "chroma"));

  const CommandResult query = Placedb("query --db " + db + " --image " + kImages +
                                      "/042.jpg --top-k 3 --json " + Path("q.json"));
  ASSERT_EQ(query.code, 0) << query.output;
  const auto q = nlohmann::json::parse(std::ifstream(Path("q.json")));
  ASSERT_FALSE(q["best"].is_null());
  // The library's QueryResult JSON: it parses back with the library.
  const placedb::QueryResult parsed = q.get<placedb::QueryResult>();
  EXPECT_TRUE(parsed.matched);
  EXPECT_TRUE(parsed.ranked[0].verified());
  EXPECT_TRUE(Contains(query.output, "inliers")) << query.output;
  const int best = q["best"]["keyframe_id"];
  EXPECT_GE(best, 1);  // 42 revisits images 1-4
  EXPECT_LE(best, 4);
  EXPECT_EQ(q["ranked"].size(), 3u);

  const CommandResult eval =
      Placedb("eval --db " + db + " --images " + kImages + " --first 41 --last 84 --truth " +
              kTruth + " --queries 20 --seed 3 --quiet --json " + Path("e.json"));
  ASSERT_EQ(eval.code, 0) << eval.output;
  const auto e = nlohmann::json::parse(std::ifstream(Path("e.json")));
  EXPECT_EQ(e["num_queries"], 20);
  EXPECT_GE(e["recall_at_1"].get<double>(), 0.8);
  EXPECT_TRUE(e["latency_ms"].contains("p99"));
  EXPECT_GT(e["database_bytes"]["features"].get<long>(), 0);
  EXPECT_GT(e["reduction_vs_full"].get<double>(), 0.3);
  EXPECT_TRUE(Contains(eval.output, "recall@1"));
  EXPECT_TRUE(e["precision_recall"].contains("average_precision"));
  EXPECT_FALSE(e["precision_recall"]["curve"].empty());
  EXPECT_EQ(e["queries"][0]["result"].get<placedb::QueryResult>().num_keyframes, 40u);
  // An open range prints as one.
  const CommandResult open_range =
      Placedb("eval --db " + db + " --images " + kImages + " --first 80 --truth " + kTruth +
              " --all --quiet --no-verify --threads 0");
  ASSERT_EQ(open_range.code, 0) << open_range.output;
  EXPECT_TRUE(Contains(open_range.output, "[80..]")) << open_range.output;
  EXPECT_FALSE(Contains(open_range.output, "-1]")) << open_range.output;
  EXPECT_TRUE(Contains(open_range.output, "verification             off")) << open_range.output;
}

TEST_F(CliTest, UnreadableImageIsSkippedAndCountedOrFatalWithStrict) {
  const fs::path images = Path("images");
  fs::create_directories(images);
  for (const char* name : {"001.jpg", "002.jpg", "003.jpg"}) {
    fs::copy_file(kImages + "/" + name, images / name);
  }
  std::ofstream(images / "004.jpg") << "this is not a jpeg";
  const CommandResult skip =
      Placedb("build --images " + images.string() + " --out " + Path("db") + " --quiet");
  ASSERT_EQ(skip.code, 0) << skip.output;
  EXPECT_TRUE(Contains(skip.output, "3 of 4 frames (1 skipped")) << skip.output;
  EXPECT_TRUE(Contains(skip.output, "004.jpg")) << skip.output;

  const CommandResult strict =
      Placedb("build --images " + images.string() + " --out " + Path("db2") + " --quiet --strict");
  EXPECT_EQ(strict.code, 1);
  EXPECT_TRUE(Contains(strict.output, "placedb: error:")) << strict.output;
  EXPECT_TRUE(Contains(strict.output, "004.jpg")) << strict.output;
  EXPECT_FALSE(fs::exists(Path("db2")));
}

TEST_F(CliTest, ClearErrors) {
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 3 --out " + db + " --quiet").code, 0);
  // Building over an existing database needs --overwrite.
  const CommandResult again =
      Placedb("build --images " + kImages + " --last 3 --out " + db + " --quiet");
  EXPECT_EQ(again.code, 1);
  EXPECT_TRUE(Contains(again.output, "--overwrite")) << again.output;
  // Asking for other features than the database holds names both.
  const CommandResult wrong =
      Placedb("query --db " + db + " --image " + kImages + "/001.jpg --features surf");
  EXPECT_EQ(wrong.code, 1);
  EXPECT_TRUE(Contains(wrong.output, "orb")) << wrong.output;
  EXPECT_TRUE(Contains(wrong.output, "surf")) << wrong.output;
  // Missing database, missing image, bad flag values.
  const CommandResult missing = Placedb("info --db " + Path("nope"));
  EXPECT_EQ(missing.code, 1);
  EXPECT_TRUE(Contains(missing.output, "no database")) << missing.output;
  const CommandResult no_image = Placedb("query --db " + db + " --image " + Path("none.png"));
  EXPECT_EQ(no_image.code, 1);
  EXPECT_TRUE(Contains(no_image.output, "cannot read query image")) << no_image.output;
  const CommandResult bad_resize =
      Placedb("build --images " + kImages + " --out " + Path("x") + " --resize 3");
  EXPECT_NE(bad_resize.code, 0);
  EXPECT_TRUE(Contains(bad_resize.output, "resize")) << bad_resize.output;
  const CommandResult no_truth =
      Placedb("eval --db " + db + " --images " + kImages + " --first 41");
  EXPECT_EQ(no_truth.code, 1);
  EXPECT_TRUE(Contains(no_truth.output, "--truth")) << no_truth.output;
}

// Each kind of error: its exit code (1 input, 74 I/O), exactly one line on
// stderr, "placedb: error: ...", no source file in it (unless --verbose),
// and option names written as flags.
TEST_F(CliTest, ErrorKindsGiveTheirExitCodeAndOneLine) {
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 3 --out " + db + " --quiet").code, 0);
  // A copy of it with one byte of its keyframe file flipped.
  const std::string damaged = Path("damaged");
  fs::create_directories(damaged);
  for (const auto& e : fs::directory_iterator(db)) {
    if (e.is_regular_file()) fs::copy_file(e.path(), damaged / e.path().filename());
  }
  std::string keyframes;
  for (const auto& e : fs::directory_iterator(damaged)) {
    if (e.path().filename().string().rfind("keyframes.", 0) == 0) keyframes = e.path().string();
  }
  ASSERT_FALSE(keyframes.empty());
  {
    std::fstream f(keyframes, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(static_cast<std::streamoff>(fs::file_size(keyframes) / 2));
    const char c = static_cast<char>(f.get());
    f.seekp(static_cast<std::streamoff>(fs::file_size(keyframes) / 2));
    f.put(static_cast<char>(c ^ 0x01));
  }
  const std::string query = "query --db " + db + " --image " + kImages + "/001.jpg";
  struct Case {
    std::string args;
    int code;
    std::vector<std::string> says;
  };
  const std::vector<Case> cases = {
      // A flag value that does not parse.
      {"build --images " + kImages + " --out " + Path("x") + " --threads abc", 1, {"--threads"}},
      // No database there: NotFound.
      {"info --db " + Path("nope"), 1, {"no database at", Path("nope")}},
      // A flipped byte: CorruptDatabase, from verify, or from the query that
      // first uses the damaged keyframe (the open checks the keyframe table).
      {"verify --db " + damaged, 1, {"checksum mismatch", fs::path(keyframes).filename().string()}},
      {"query --db " + damaged + " --image " + kImages + "/001.jpg",
       1,
       {"fail their block checksum", fs::path(keyframes).filename().string()}},
      // Bad option values, named as flags.
      {"build --images " + kImages + " --out " + Path("x") + " --frame-size 10x10",
       1,
       {"--frame-size", "[16, 16384]"}},
      {query + " --partition 5/3", 1, {"--partition"}},
      {query + " --top-k 0", 1, {"[1, 10000]"}},
      // A write the system refuses (/proc takes no new files, even from root):
      // IoError, EX_IOERR.
      {query + " --json /proc/placedb_cli_test.json", 74, {"cannot create", "/proc/"}},
  };
  for (const Case& c : cases) {
    const CommandResult r = PlacedbStderr(c.args);
    EXPECT_EQ(r.code, c.code) << c.args << "\n" << r.output;
    EXPECT_EQ(r.output.rfind("placedb: error: ", 0), 0u) << c.args << "\n" << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << c.args << "\n" << r.output;
    EXPECT_FALSE(Contains(r.output, ".cc:") || Contains(r.output, ".h:")) << r.output;
    for (const std::string& part : c.says) EXPECT_TRUE(Contains(r.output, part)) << r.output;
  }
  // The intact database verifies.
  const CommandResult intact = Placedb("verify --db " + db);
  EXPECT_EQ(intact.code, 0) << intact.output;
  EXPECT_TRUE(Contains(intact.output, "intact: 3 keyframes")) << intact.output;
  // --top-k is named too: as "--top-k" once the options' own checks mark
  // their names (option tables); until then by its keyword.
  const CommandResult top_k = PlacedbStderr(query + " --top-k 0");
  EXPECT_TRUE(Contains(top_k.output, "--top-k") || Contains(top_k.output, "top_k")) << top_k.output;
  EXPECT_FALSE(Contains(top_k.output, "opts.") || Contains(top_k.output, "invalid q:"))
      << top_k.output;
  // --verbose, before or after the sub-command, adds where placedb raised
  // the error, and only that.
  for (const std::string& args :
       {"--verbose info --db " + Path("nope"), "info --verbose --db " + Path("nope")}) {
    const CommandResult r = PlacedbStderr(args);
    EXPECT_EQ(r.code, 1) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_TRUE(Contains(r.output, "no database at")) << r.output;
    EXPECT_TRUE(Contains(r.output, " [storage/database.cc:")) << r.output;
    EXPECT_EQ(r.output.substr(r.output.size() - 2), "]\n") << r.output;
  }
}

// Argument errors, like every other error: one line on stderr, exit code 1.
TEST_F(CliTest, ArgumentErrorsAreOneLineAndExitOne) {
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 3 --out " + db + " --quiet").code, 0);
  const std::string image = " --image " + kImages + "/001.jpg";
  for (const std::string& args :
       {std::string("build --images ") + kImages + " --out " + Path("x") + " --threads abc",
        std::string("build --images ") + kImages + " --out " + Path("x") + " --threads -1",
        std::string("build --images ") + kImages + " --out " + Path("x") + " --threads 5000",
        std::string("build --images ") + kImages + " --out " + Path("x") + " --crop-sigma nan",
        std::string("build --images ") + kImages + " --out " + Path("x") +
            " --orb-edge-threshold 2147483647",
        std::string("build --images ") + kImages + " --out " + Path("x") +
            " --crop-padding 2147483647",
        std::string("build --images ") + kImages + " --out " + Path("x") + " --crop-sigma 1e6",
        std::string("build --images ") + kImages + " --out " + Path("x") +
            " --orb-max-features 2000000000",
        std::string("build --images ") + kImages + " --out " + Path("x") +
            " --orb-levels 2147483647",
        std::string("build --images ") + kImages + " --out " + Path("x") +
            " --orb-patch-size 2147483647",
        std::string("build --images ") + kImages + " --out " + Path("x") + " --threads 2147483648",
        std::string("build --images ") + kImages + " --out " + Path("x") + " --frame-size 160",
        std::string("build --images ") + kImages + " --out " + Path("x") + " --no-such-flag",
        std::string("build --out ") + Path("x"),
        "query --db " + db + image + " --top-k 0",
        "query --db " + db + image + " --ratio 2",
        "query --db " + db + image + " --verify-model affine",
        "query --db " + db + image + " --threads -2",
        "bench --db " + db + " --images " + kImages + " --queries -4",
        "eval --db " + db + " --images " + kImages + " --truth " + kTruth + " --queries 0",
        std::string("frobnicate")}) {
    const CommandResult r = Placedb(args);
    EXPECT_EQ(r.code, 1) << args << "\n" << r.output;
    EXPECT_TRUE(Contains(r.output, "placedb: error:")) << args << "\n" << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << args << "\n" << r.output;
    EXPECT_FALSE(Contains(r.output, "not in range 0.000000")) << r.output;
  }
  EXPECT_FALSE(fs::exists(Path("x")));
  // --threads 0 (one per core) works for every command that takes it.
  EXPECT_EQ(Placedb("query --db " + db + image + " --threads 0").code, 0);
  EXPECT_EQ(
      Placedb("build --images " + kImages + " --last 2 --out " + Path("y") + " --threads 0 --quiet")
          .code,
      0);
  EXPECT_EQ(Placedb("--version").code, 0);
}

// A query may open one partition or a list of keyframes only (a worker's
// share of the database).
// Output paths that are not regular files are written as streams, never
// replaced: /dev/stdout and /dev/fd/1 (a pipe here), a symlink, a FIFO. As
// root, `--json /dev/stdout` once replaced the system's /dev/stdout symlink
// with a regular file.
TEST_F(CliTest, SpecialOutputPathsAreStreamed) {
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 3 --out " + db + " --quiet").code, 0);
  const std::string query = "query --db " + db + " --image " + kImages + "/002.jpg";
  const bool stdout_was_link = fs::is_symlink("/dev/stdout");
  for (const std::string& out : {"/dev/stdout", "/dev/fd/1"}) {
    const CommandResult r = Placedb(query + " --json " + out);
    EXPECT_EQ(r.code, 0) << r.output;
    EXPECT_TRUE(Contains(r.output, "\"ranked\"")) << out << ": " << r.output;
  }
  EXPECT_EQ(fs::is_symlink("/dev/stdout"), stdout_was_link);
  EXPECT_FALSE(fs::is_regular_file(fs::symlink_status("/dev/stdout")));
  // A symlink: its target is written, the link stays.
  const std::string target = Path("target.json"), link = Path("link.json");
  { std::ofstream(target) << "old"; }
  fs::create_symlink(target, link);
  EXPECT_EQ(Placedb(query + " --json " + link).code, 0);
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_NO_THROW(nlohmann::json::parse(std::ifstream(target)));
  // A FIFO, read by another process.
  const std::string fifo = Path("fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  FILE* reader = popen(("cat " + fifo + " > " + Path("from_fifo.json")).c_str(), "w");
  ASSERT_NE(reader, nullptr);
  EXPECT_EQ(Placedb(query + " --json " + fifo).code, 0);
  pclose(reader);
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_NO_THROW(nlohmann::json::parse(std::ifstream(Path("from_fifo.json"))));
  // A directory: one line, exit 1.
  const CommandResult dir = Placedb(query + " --json " + Path(""));
  EXPECT_EQ(dir.code, 1);
  EXPECT_TRUE(Contains(dir.output, "is a directory")) << dir.output;
}

// The full 64-bit vocabulary seed builds, and the database opens: the
// manifest reads back what it wrote (a seed above 2^63 once built a
// database that never opened).
TEST_F(CliTest, VocabularySeedAboveTwoToTheSixtyThreeRoundTrips) {
  const std::string db = Path("db");
  const CommandResult build =
      Placedb("build --images " + kImages + " --last 6 --index bow --vocabulary-depth 2 " +
              "--vocabulary-seed 9223372036854775809 --out " + db + " --quiet");
  ASSERT_EQ(build.code, 0) << build.output;
  const CommandResult info = Placedb("info --db " + db + " --json");
  EXPECT_EQ(info.code, 0) << info.output;
  EXPECT_TRUE(Contains(info.output, "9223372036854775809")) << info.output;
}

TEST_F(CliTest, PartitionsAndKeyframeLists) {
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 9 --out " + db + " --quiet").code, 0);
  const std::string query =
      "query --db " + db + " --image " + kImages + "/042.jpg --top-k 9 --json -";
  const CommandResult part = PlacedbStdout(query + " --partition 1/3");
  ASSERT_EQ(part.code, 0) << part.output;
  const auto p = nlohmann::json::parse(part.output);
  EXPECT_EQ(p["num_keyframes"], 3u);  // indices 3..5: ids 4, 5, 6
  for (const auto& k : p["ranked"]) {
    EXPECT_GE(k["keyframe_id"].get<int>(), 4);
    EXPECT_LE(k["keyframe_id"].get<int>(), 6);
  }
  const CommandResult inter =
      PlacedbStdout(query + " --partition 0/4 --partition-scheme interleaved");
  ASSERT_EQ(inter.code, 0) << inter.output;
  EXPECT_EQ(nlohmann::json::parse(inter.output)["num_keyframes"], 3u);
  const CommandResult ids = PlacedbStdout(query + " --keyframes 2,7");
  ASSERT_EQ(ids.code, 0) << ids.output;
  EXPECT_EQ(nlohmann::json::parse(ids.output)["num_keyframes"], 2u);
  for (const std::string& bad :
       {"--partition 3/3", "--partition 1", "--partition a/2", "--keyframes 2,x", "--keyframes 99",
        "--partition 0/2 --keyframes 1"}) {
    const CommandResult r = Placedb(query + " " + bad);
    EXPECT_EQ(r.code, 1) << bad << "\n" << r.output;
    EXPECT_TRUE(Contains(r.output, "placedb: error:")) << bad << "\n" << r.output;
  }
}

// Ground truth naming ids that no frame of the data can have is probably the
// wrong file: eval says so (and still runs).
TEST_F(CliTest, GroundTruthBeyondTheDataIsWarnedAbout) {
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 10 --out " + db + " --quiet").code, 0);
  std::ofstream(Path("truth.csv")) << "41,1 2 3\n42,5000\n9999,1\n";
  const CommandResult r =
      Placedb("eval --db " + db + " --images " + kImages + " --first 41 --last 42 --truth " +
              Path("truth.csv") + " --all --quiet");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(Contains(r.output, "the ground truth names 2 ids beyond the data")) << r.output;
  const CommandResult fine = Placedb("eval --db " + db + " --images " + kImages +
                                     " --first 41 --truth " + kTruth + " --all --quiet");
  EXPECT_FALSE(Contains(fine.output, "beyond the data")) << fine.output;
}

// A smaller camera, simulated: frames resized as they are read.
TEST_F(CliTest, FrameSizeSimulatesASmallCamera) {
  const std::string db = Path("small");
  const CommandResult build =
      Placedb("build --images " + kImages + " --last 10 --frame-size 160x120 --out " + db +
              " --quiet --json " + Path("b.json"));
  ASSERT_EQ(build.code, 0) << build.output;
  const CommandResult info = Placedb("info --db " + db + " --json");
  ASSERT_EQ(info.code, 0);
  const auto m = nlohmann::json::parse(info.output);
  EXPECT_TRUE(Contains(m["source"].get<std::string>(), "at 160x120")) << m["source"];
  EXPECT_EQ(m["settings"]["features"]["upscale_below"], 240);
}

TEST_F(CliTest, TinyImagesGiveZeroFeaturesWithoutError) {
  const fs::path images = Path("tiny");
  fs::create_directories(images);
  // 8x8 and 1x1 PNGs (written by hand-made bytes is overkill: use the P6 PPM
  // format, which OpenCV reads).
  for (const int side : {1, 8}) {
    std::ofstream ppm(images / ("img" + std::to_string(side) + ".ppm"), std::ios::binary);
    ppm << "P6\n" << side << " " << side << "\n255\n";
    for (int i = 0; i < side * side; ++i) ppm.put(static_cast<char>(i * 37)).put('a').put('z');
  }
  const CommandResult build = Placedb("build --images " + images.string() + " --out " + Path("db") +
                                      " --crop chroma --quiet");
  ASSERT_EQ(build.code, 0) << build.output;
  EXPECT_TRUE(Contains(build.output, "2 of 2 frames")) << build.output;
  EXPECT_TRUE(Contains(build.output, "features      0")) << build.output;
  // Querying it: nothing can match, and it says so.
  const CommandResult query =
      Placedb("query --db " + Path("db") + " --image " + kImages + "/001.jpg");
  EXPECT_EQ(query.code, 0) << query.output;
  EXPECT_TRUE(Contains(query.output, "no match")) << query.output;
}

TEST_F(CliTest, QueryAgainstAnEmptyDatabaseSaysSo) {
  // Builds refuse to produce an empty database; one made through the library
  // is still handled.
  // The thumbnail channel: the HOG channel's rows need a model a build fits.
  placedb::BuildOptions thumbnail;
  thumbnail.features.whole_image.kind = placedb::WholeImageKind::kThumbnail;
  placedb::Database empty(placedb::FeatureType::kOrb, 32,
                          placedb::WholeImageDims(thumbnail.features));
  empty.info()["settings"] = placedb::BuildSettingsToJson(thumbnail);
  fs::create_directories(Path("empty"));
  empty.Save(Path("empty"));
  const CommandResult query =
      Placedb("query --db " + Path("empty") + " --image " + kImages + "/001.jpg");
  EXPECT_EQ(query.code, 2);
  EXPECT_TRUE(Contains(query.output, "empty")) << query.output;
  const CommandResult info = Placedb("info --db " + Path("empty"));
  EXPECT_EQ(info.code, 0);
  EXPECT_TRUE(Contains(info.output, "keyframes       0")) << info.output;
  EXPECT_TRUE(Contains(info.output, "whole image     32 x 24 thumbnails, 8-px tiles (768 values"))
      << info.output;
  // Without the channel (a database of an earlier placedb), info says none.
  placedb::Database plain(placedb::FeatureType::kOrb, 32);
  placedb::BuildOptions no_channel;
  no_channel.features.whole_image.enabled = false;
  plain.info()["settings"] = placedb::BuildSettingsToJson(no_channel);
  fs::create_directories(Path("plain"));
  plain.Save(Path("plain"));
  const CommandResult plain_info = Placedb("info --db " + Path("plain"));
  EXPECT_EQ(plain_info.code, 0) << plain_info.output;
  EXPECT_TRUE(Contains(plain_info.output, "whole image     none")) << plain_info.output;
}

TEST_F(CliTest, BenchComparesWithBfMatcher) {
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 10 --out " + db + " --quiet").code, 0);
  const CommandResult bench =
      Placedb("bench --db " + db + " --images " + kImages +
              " --first 41 --last 50 --queries 5 --repeat 1 --json " + Path("b.json"));
  ASSERT_EQ(bench.code, 0) << bench.output;
  const auto b = nlohmann::json::parse(std::ifstream(Path("b.json")));
  EXPECT_EQ(b["num_queries"], 5);
  EXPECT_EQ(b["rankings_that_differ"], 0);
  EXPECT_GT(b["bfmatcher_ms_per_query"].get<double>(), 0.0);
  EXPECT_GT(b["placedb_ms_per_query"].get<double>(), 0.0);
}

}  // namespace

// Issue 9's commands: build --index bow, query/eval --search
// exhaustive|bow|cluster, --deadline-ms, eval --sequence, add and remove.
TEST_F(CliTest, SearchModesDeadlinesAndOnlineChanges) {
  const std::string db = Path("bow");
  const CommandResult build =
      Placedb("build --images " + kImages + " --last 30 --index bow --vocabulary-depth 3 --out " +
              db + " --quiet");
  ASSERT_EQ(build.code, 0) << build.output;
  EXPECT_TRUE(Contains(build.output, "index files")) << build.output;
  for (const char* search : {"exhaustive", "bow", "cluster"}) {
    const CommandResult eval =
        Placedb("eval --db " + db + " --images " + kImages + " --first 41 --truth " + kTruth +
                " --all --sequence --quiet --cluster-keyframes 5 --search " + search + " --json " +
                Path(std::string(search) + ".json"));
    ASSERT_EQ(eval.code, 0) << eval.output;
    const auto e = nlohmann::json::parse(std::ifstream(Path(std::string(search) + ".json")));
    EXPECT_GE(e["recall_at_1"].get<double>(), 0.85) << search;
    EXPECT_TRUE(Contains(eval.output, "mean coverage")) << eval.output;
    int searches = 0;
    for (const auto& [name, count] : e["searches"].items()) {
      EXPECT_EQ(name.rfind(search, 0), 0u) << name;
      searches += count.get<int>();
    }
    EXPECT_EQ(searches, e["num_queries"].get<int>());
    if (std::string(search) == "bow") EXPECT_LT(e["mean_coverage"].get<double>(), 1.0);
  }
  const CommandResult deadline =
      Placedb("query --db " + db + " --image " + kImages +
              "/042.jpg --deadline-ms 0.000001 --json " + Path("d.json"));
  ASSERT_EQ(deadline.code, 0) << deadline.output;
  EXPECT_TRUE(Contains(deadline.output, "stopped by the deadline")) << deadline.output;
  const auto d = nlohmann::json::parse(std::ifstream(Path("d.json")));
  EXPECT_TRUE(d["deadline_reached"].get<bool>());
  EXPECT_LT(d["coverage"].get<double>(), 1.0);
  EXPECT_EQ(Placedb("query --db " + db + " --image " + kImages + "/042.jpg --deadline-ms -1").code,
            1);

  // A database without an index says how to get one.
  const std::string plain = Path("plain");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 30 --out " + plain + " --quiet").code,
            0);
  const CommandResult no_index =
      Placedb("query --db " + plain + " --image " + kImages + "/042.jpg --search bow");
  EXPECT_EQ(no_index.code, 1);
  EXPECT_TRUE(Contains(no_index.output, "--index set to bow")) << no_index.output;

  // add / remove, saved in place; the database then answers with them.
  const CommandResult add =
      Placedb("add --db " + db + " --images " + kImages + " --first 31 --last 40 --quiet");
  ASSERT_EQ(add.code, 0) << add.output;
  EXPECT_TRUE(Contains(add.output, "now has 40 keyframes")) << add.output;
  const CommandResult again =
      Placedb("add --db " + db + " --images " + kImages + " --first 40 --last 41 --quiet");
  EXPECT_EQ(again.code, 1);
  EXPECT_TRUE(Contains(again.output, "is already keyframe 40 of")) << again.output;
  EXPECT_EQ(Placedb("add --db " + db + " --images " + kImages +
                    " --first 40 --last 41 --skip-existing --quiet")
                .code,
            0);
  const CommandResult self = Placedb("query --db " + db + " --image " + kImages +
                                     "/035.jpg --search bow --json " + Path("s.json"));
  ASSERT_EQ(self.code, 0) << self.output;
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(Path("s.json")))["best"]["keyframe_id"], 35);
  const CommandResult remove = Placedb("remove --db " + db + " --ids 35,36");
  ASSERT_EQ(remove.code, 0) << remove.output;
  EXPECT_TRUE(Contains(remove.output, "now has 39 keyframes")) << remove.output;
  const CommandResult missing = Placedb("remove --db " + db + " --ids 35");
  EXPECT_EQ(missing.code, 1);
  EXPECT_TRUE(Contains(missing.output, "not in")) << missing.output;
  const CommandResult info = Placedb("info --db " + db);
  EXPECT_TRUE(Contains(info.output, "keyframes       39")) << info.output;
}

TEST_F(CliTest, QueryDrawsItsMatchesAndExperimentChecksItsGrid) {
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 12 --out " + db + " --quiet").code, 0);
  const CommandResult drawn =
      Placedb("query --db " + db + " --image " + kImages + "/005.jpg --draw " + Path("m.png"));
  ASSERT_EQ(drawn.code, 0) << drawn.output;
  EXPECT_TRUE(Contains(drawn.output, "draw          " + Path("m.png"))) << drawn.output;
  // A PNG whose header says it is wider than the two images side by side.
  std::ifstream png(Path("m.png"), std::ios::binary);
  unsigned char header[24] = {};
  png.read(reinterpret_cast<char*>(header), sizeof(header));
  ASSERT_EQ(std::string(reinterpret_cast<char*>(header) + 1, 3), "PNG");
  const int width = (header[16] << 24) | (header[17] << 16) | (header[18] << 8) | header[19];
  EXPECT_GT(width, 2 * 360);
  const CommandResult jpg =
      Placedb("query --db " + db + " --image " + kImages + "/005.jpg --draw " + Path("m.jpg"));
  EXPECT_EQ(jpg.code, 1);
  EXPECT_TRUE(Contains(jpg.output, "--draw needs a .png")) << jpg.output;
  EXPECT_FALSE(fs::exists(Path("m.jpg")));

  const std::string exp = "experiment --images " + kImages + " --db-last 12 --first 41 --truth " +
                          kTruth + " --queries 3 --no-report --quiet --out " + Path("exp");
  for (const auto& [flags, phrase] : std::vector<std::pair<std::string, std::string>>{
           {" --resize 1,2", "--resize takes 1, 4 and 16"},
           {" --verification maybe", "--verification takes on and off"},
           {" --features orb,,surf", "empty item"},
           {" --features sift", "sift"},
           {" --crop none,none", "--crop repeats"},
           {" --pictures 99", "--pictures must be in [0, 20] (got 99)"}}) {
    const CommandResult bad = Placedb(exp + flags);
    EXPECT_EQ(bad.code, 1) << flags;
    EXPECT_TRUE(Contains(bad.output, phrase)) << flags << ": " << bad.output;
    EXPECT_EQ(std::count(bad.output.begin(), bad.output.end(), '\n'), 1) << bad.output;
  }
  const CommandResult no_truth = Placedb("experiment --images " + kImages + " --out " + Path("e2"));
  EXPECT_EQ(no_truth.code, 1);
  EXPECT_TRUE(Contains(no_truth.output, "need a --truth CSV")) << no_truth.output;
  const CommandResult ok =
      Placedb(exp + " --features orb --crop chroma --resize 16 --verification on");
  ASSERT_EQ(ok.code, 0) << ok.output;
  EXPECT_TRUE(Contains(ok.output, "1 settings (0 finished earlier), 3 queries each")) << ok.output;
  EXPECT_TRUE(fs::exists(Path("exp/results.json")));
  EXPECT_FALSE(fs::exists(Path("exp/report.html")));
  // Two sequences: the database from one (the paper's training sequence),
  // the queries from another, truth from the poses.
  const CommandResult two =
      Placedb("experiment --tum " PLACEDB_DATA_DIR
              "/tum_fr3_office_32 --first 17 --db-tum " PLACEDB_DATA_DIR
              "/tum_fr3_office_mini --features orb --crop none --resize 16 --verification on --all "
              "--no-report --quiet --out " +
              Path("two"));
  ASSERT_EQ(two.code, 0) << two.output;
  EXPECT_TRUE(Contains(two.output, "16 queries each")) << two.output;
  EXPECT_TRUE(Contains(two.output, "tum_fr3_office_mini (4 frames)")) << two.output;
  const CommandResult both = Placedb("experiment --tum " PLACEDB_DATA_DIR
                                     "/tum_fr3_office_32 --db-tum x --db-images y --out " +
                                     Path("both"));
  EXPECT_EQ(both.code, 1);
  EXPECT_TRUE(Contains(both.output, "excludes")) << both.output;
}

namespace {

// ---- hostile input (issue 17) -------------------------------------------------

// A PNG of width x height 1-bit gray pixels, all black, written without
// zlib: one fixed-Huffman deflate block of runs (length 258, distance 1).
// 30000 x 30000 (900 megapixels, 2.7 GB as BGR) is about 710 KB.
std::string BlackPng(uint32_t width, uint32_t height) {
  auto be32 = [](uint32_t v) {
    return std::string{static_cast<char>(v >> 24), static_cast<char>(v >> 16),
                       static_cast<char>(v >> 8), static_cast<char>(v)};
  };
  auto crc32 = [](const std::string& bytes) {
    uint32_t c = 0xffffffffu;
    for (const char ch : bytes) {
      c ^= static_cast<uint8_t>(ch);
      for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
    }
    return c ^ 0xffffffffu;
  };
  auto chunk = [&](const std::string& type, const std::string& data) {
    return be32(static_cast<uint32_t>(data.size())) + type + data + be32(crc32(type + data));
  };
  // The deflate stream, bits least significant first; Huffman codes most
  // significant bit first.
  std::string z = "\x78\x01";
  uint64_t bit_buffer = 0;
  int bits = 0;
  auto put = [&](uint32_t value, int n) {  // n bits of value, LSB first
    bit_buffer |= static_cast<uint64_t>(value) << bits;
    bits += n;
    while (bits >= 8) {
      z += static_cast<char>(bit_buffer & 0xff);
      bit_buffer >>= 8;
      bits -= 8;
    }
  };
  auto put_code = [&](uint32_t code, int n) {
    for (int i = n - 1; i >= 0; --i) put((code >> i) & 1u, 1);
  };
  const uint64_t total = static_cast<uint64_t>(height) * (1 + (width + 7) / 8);
  put(1, 1);          // BFINAL
  put(1, 2);          // fixed Huffman
  put_code(0x30, 8);  // literal 0
  uint64_t left = total - 1;
  for (; left >= 258; left -= 258) {
    put_code(0xC5, 8);  // length 258 (code 285)
    put_code(0, 5);     // distance 1 (code 0)
  }
  for (; left > 0; --left) put_code(0x30, 8);
  put_code(0, 7);  // end of block
  if (bits > 0) put(0, 8 - bits);
  const uint32_t adler = (static_cast<uint32_t>(total % 65521) << 16) | 1u;
  z += be32(adler);
  const std::string ihdr = be32(width) + be32(height) + std::string("\x01\x00\x00\x00\x00", 5);
  return std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", ihdr) + chunk("IDAT", z) +
         chunk("IEND", "");
}

void WriteFile(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

size_t Lines(const std::string& text) { return std::count(text.begin(), text.end(), '\n'); }

TEST_F(CliTest, DecompressionBombsAreRefusedFromTheirHeader) {
  // The generator makes real PNGs: a small one decodes.
  const std::string small = Path("small.png");
  WriteFile(small, BlackPng(300, 200));
  const cv::Mat decoded = cv::imread(small, cv::IMREAD_GRAYSCALE);
  ASSERT_EQ(decoded.size(), cv::Size(300, 200));
  EXPECT_EQ(cv::countNonZero(decoded), 0);

  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 4 --out " + db + " --quiet").code, 0);
  const std::string bomb = Path("bomb.png");
  WriteFile(bomb, BlackPng(30000, 30000));
  ASSERT_LT(ReadFile(bomb).size(), 1u << 20);
  const CommandResult query = Placedb("query --db " + db + " --image " + bomb);
  EXPECT_EQ(query.code, 1) << query.output;
  EXPECT_TRUE(Contains(query.output, "query image " + bomb +
                                         " is 30000 x 30000 pixels (900.0 megapixels), more than "
                                         "the 40000000 pixels allowed"))
      << query.output;
  EXPECT_EQ(Lines(query.output), 1u) << query.output;
  // The same bomb among the frames of a build or an add.
  const std::string frames = Path("frames");
  fs::create_directories(frames);
  fs::copy_file(kImages + "/001.jpg", frames + "/001.jpg");
  fs::copy_file(bomb, frames + "/002.png");
  const CommandResult build =
      Placedb("build --images " + frames + " --out " + Path("db2") + " --quiet");
  EXPECT_EQ(build.code, 1) << build.output;
  EXPECT_TRUE(Contains(build.output, "30000 x 30000 pixels")) << build.output;
  EXPECT_FALSE(fs::exists(Path("db2/manifest.json")));
  // The bound is an option, with a range; a simulated camera is held to it.
  const CommandResult zero =
      Placedb("query --db " + db + " --image " + small + " --max-image-pixels 0");
  EXPECT_EQ(zero.code, 1);
  EXPECT_TRUE(Contains(zero.output, "--max-image-pixels must be in [1, 2^30] (got 0)"))
      << zero.output;
  const CommandResult lowered =
      Placedb("query --db " + db + " --image " + kImages + "/003.jpg --max-image-pixels 1000");
  EXPECT_EQ(lowered.code, 1);
  EXPECT_TRUE(Contains(lowered.output, "more than the 1000 pixels allowed")) << lowered.output;
  const CommandResult camera = Placedb("build --images " + kImages + " --last 2 --out " +
                                       Path("db3") + " --frame-size 16384x16384 --quiet");
  EXPECT_EQ(camera.code, 1);
  EXPECT_TRUE(Contains(camera.output,
                       "--frame-size 16384x16384 is 268435456 pixels, more than "
                       "--max-image-pixels 40000000"))
      << camera.output;
  EXPECT_EQ(Lines(camera.output), 1u) << camera.output;
}

// A checksum-valid database whose keyframe record names a stored image
// outside the database: no command opens it, and nothing outside is touched.
TEST_F(CliTest, CraftedStoredImageNamesNeverLeaveTheDatabase) {
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 3 --out " + db + " --quiet").code, 0);
  const std::string victim = Path("victim.txt");
  WriteFile(victim, "not yours\n");
  // An absolute name short enough for the record's strings.
  const std::string absolute = "/tmp/placedb_victim_" + std::to_string(::getpid());
  WriteFile(absolute, "not yours\n");
  for (const std::string& name :
       {std::string("../victim.txt"), absolute, std::string("images/../../victim.txt")}) {
    nlohmann::json manifest = nlohmann::json::parse(ReadFile(db + "/manifest.json"));
    const std::string old_name = manifest["files"]["keyframes"];
    std::string bytes = ReadFile(db + "/" + old_name);
    // Keyframe 0's record and its strings (keyframe_file.h's layout).
    auto get64 = [&](size_t at) {
      uint64_t v;
      std::memcpy(&v, &bytes[at], 8);
      return v;
    };
    auto get32 = [&](size_t at) {
      uint32_t v;
      std::memcpy(&v, &bytes[at], 4);
      return v;
    };
    uint64_t records = 0, strings = 0;
    for (uint32_t s = 0; s < 4; ++s) {
      const uint32_t kind = get32(64 + 32 * s);
      if (kind == placedb::keyframe_file::kKeyframes) records = get64(64 + 32 * s + 8);
      if (kind == placedb::keyframe_file::kStrings) strings = get64(64 + 32 * s + 8);
    }
    const uint32_t source_len = get32(records + 132);
    const uint32_t image_len = get32(records + 144);
    const uint64_t at = strings + get64(records + 136);
    ASSERT_GE(source_len + image_len, name.size());
    const uint32_t new_source = source_len + image_len - static_cast<uint32_t>(name.size());
    std::memcpy(&bytes[at + new_source], name.data(), name.size());
    std::memcpy(&bytes[records + 132], &new_source, 4);
    const uint32_t new_image = static_cast<uint32_t>(name.size());
    std::memcpy(&bytes[records + 144], &new_image, 4);
    const uint64_t checksum = placedb::keyframe_file::Reseal(&bytes, true);
    const std::string new_name = placedb::Database::KeyframesFileName(checksum);
    fs::remove(db + "/" + old_name);
    WriteFile(db + "/" + new_name, bytes);
    manifest["files"]["keyframes"] = new_name;
    manifest["files"]["keyframes_bytes"] = bytes.size();
    manifest["files"]["keyframes_checksum"] = placedb::ChecksumHex(checksum);
    WriteFile(db + "/manifest.json", manifest.dump(2));

    for (const std::string& command :
         {"remove --db " + db + " --ids 1", "query --db " + db + " --image " + kImages + "/001.jpg",
          "info --db " + db, "eval --db " + db + " --images " + kImages + " --truth " + kTruth,
          "add --db " + db + " --images " + kImages + " --first 5 --last 5"}) {
      const CommandResult run = Placedb(command);
      EXPECT_EQ(run.code, 1) << command << "\n" << run.output;
      EXPECT_TRUE(Contains(run.output, "stored image name '" + name + "' is not images/"))
          << run.output;
      EXPECT_EQ(Lines(run.output), 1u) << run.output;
      EXPECT_EQ(ReadFile(victim), "not yours\n") << command;
      EXPECT_EQ(ReadFile(absolute), "not yours\n") << command;
    }
  }
  fs::remove(absolute);
}

// The regular files directly inside `dir`, name -> content ("" for others).
std::map<std::string, std::string> FolderContents(const std::string& dir) {
  std::map<std::string, std::string> out;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string name = entry.path().filename().string();
    out[name] = fs::is_regular_file(fs::symlink_status(entry.path())) ? ReadFile(entry.path()) : "";
  }
  return out;
}

// Issue 46, defect 1: a read wrote and deleted files (it swept images/ of
// every PNG no keyframe names, through an images/ symlink out of the
// database). Reads now write and delete nothing; the first writer removes
// only the debris of placedb's own names, and never through a symlink.
TEST_F(CliTest, ReadsDeleteNothingAndWritersNeverSweepThroughASymlink) {
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 5 --out " + db + " --quiet").code, 0);
  const std::string shared = Path("shared");
  fs::copy(db + "/images", shared);
  WriteFile(shared + "/holiday.png", "mine\n");
  WriteFile(shared + "/000099.png", "a placedb name, but not in the database's own folder\n");
  fs::remove_all(db + "/images");
  fs::create_directory_symlink(shared, db + "/images");
  // A killed writer's debris: a temporary file and a build's folder.
  WriteFile(db + "/manifest.json.tmp.99999999.1", "debris\n");
  fs::create_directories(Path("db.building.99999999/images"));
  const std::map<std::string, std::string> before = FolderContents(shared);
  const std::map<std::string, std::string> db_before = FolderContents(db);
  for (const std::string& read :
       {"query --db " + db + " --image " + kImages + "/003.jpg", "info --db " + db,
        "info --db " + db + " --json", "verify --db " + db,
        "eval --db " + db + " --images " + kImages + " --first 41 --last 45 --truth " + kTruth +
            " --quiet"}) {
    const CommandResult run = Placedb(read);
    EXPECT_EQ(run.code, 0) << read << "\n" << run.output;
    EXPECT_EQ(FolderContents(shared), before) << read;
    EXPECT_EQ(FolderContents(db), db_before) << read;
    EXPECT_TRUE(fs::exists(Path("db.building.99999999"))) << read;
  }
  // A writer may not store an image through the link: one line, nothing done.
  const CommandResult add =
      PlacedbStderr("add --db " + db + " --images " + kImages + " --first 6 --last 6 --quiet");
  EXPECT_EQ(add.code, 1) << add.output;
  EXPECT_EQ(Lines(add.output), 1u) << add.output;
  EXPECT_TRUE(Contains(add.output, db + "/images is a symlink")) << add.output;
  EXPECT_EQ(FolderContents(shared), before);
  // A writer that stores nothing removes its own kind of debris, beside and
  // inside the folder, and nothing through the link.
  const CommandResult remove = Placedb("remove --db " + db + " --ids 2");
  EXPECT_EQ(remove.code, 0) << remove.output;
  EXPECT_EQ(FolderContents(shared), before);
  EXPECT_FALSE(fs::exists(db + "/manifest.json.tmp.99999999.1"));
  EXPECT_FALSE(fs::exists(Path("db.building.99999999")));
  EXPECT_TRUE(fs::is_symlink(db + "/images"));
}

// Issue 46, defect 2: an unknown manifest key holding 100 000 nested arrays
// crashed `info` (SIGSEGV) and took `add`/`remove` to 2 GB; 1 000 000 levels
// crashed more. Refused in one line before the manifest is walked, at both
// depths, by every command; the manifest is left as it is.
TEST_F(CliTest, DeeplyNestedManifestsAreRefusedInOneLine) {
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 3 --out " + db + " --quiet").code, 0);
  const std::string text = ReadFile(db + "/manifest.json");
  for (const size_t depth : {size_t{100000}, size_t{1000000}}) {
    const std::string nested =
        "{\"x\":" + std::string(depth, '[') + std::string(depth, ']') + "," + text.substr(1);
    WriteFile(db + "/manifest.json", nested);
    for (const std::string& command :
         {"info --db " + db, "info --db " + db + " --json", "verify --db " + db,
          "query --db " + db + " --image " + kImages + "/001.jpg",
          "add --db " + db + " --images " + kImages + " --first 4 --last 4 --quiet",
          "remove --db " + db + " --ids 1"}) {
      const CommandResult run = PlacedbStderr(command);
      EXPECT_EQ(run.code, 1) << depth << ": " << command << "\n" << run.output;
      EXPECT_EQ(Lines(run.output), 1u) << run.output;
      EXPECT_TRUE(Contains(run.output, depth == 100000 ? "JSON nested deeper than 64 levels"
                                                       : "larger than 1048576 bytes"))
          << run.output;
      EXPECT_EQ(ReadFile(db + "/manifest.json"), nested) << command;
    }
  }
}

// Paths that are not UTF-8, and control characters in them: JSON output is
// valid (U+FFFD for the bytes that are not UTF-8), terminal text is escaped.
TEST_F(CliTest, PathsOfAnyBytesGiveValidJsonAndEscapedText) {
  const std::string folder = Path("caf\xe9");
  fs::create_directories(folder);
  for (int i = 1; i <= 6; ++i) {
    char name[16];
    std::snprintf(name, sizeof(name), "%03d.jpg", i);
    const std::string target = folder + "/" + (i == 3 ? "esc\x1b[31m_" : "img\xe9_") + name;
    fs::copy_file(kImages + "/" + name, target);
  }
  const std::string db = Path("db");
  const CommandResult build =
      Placedb("build --images '" + folder + "' --out " + db + " --quiet --json " + Path("b.json"));
  ASSERT_EQ(build.code, 0) << build.output;
  const std::string query_image = folder + "/esc\x1b[31m_003.jpg";
  const CommandResult query =
      Placedb("query --db " + db + " --image '" + query_image + "' --json " + Path("q.json"));
  ASSERT_EQ(query.code, 0) << query.output;
  EXPECT_TRUE(Contains(query.output, "caf\\xe9/esc\\x1b[31m_003.jpg")) << query.output;
  EXPECT_FALSE(Contains(query.output, "\x1b")) << query.output;
  EXPECT_FALSE(Contains(query.output, "\xe9")) << query.output;
  const nlohmann::json j = nlohmann::json::parse(ReadFile(Path("q.json")));
  EXPECT_EQ(j["query"], Path("caf\xef\xbf\xbd") + "/esc\x1b[31m_003.jpg");
  ASSERT_FALSE(j["ranked"].empty());
  EXPECT_EQ(j["ranked"][0]["source"], j["query"]);
  // To stdout too, and the manifest (whose source names the folder).
  const CommandResult to_stdout =
      PlacedbStdout("query --db " + db + " --image '" + folder + "/img\xe9_001.jpg' --json -");
  ASSERT_EQ(to_stdout.code, 0) << to_stdout.output;
  EXPECT_NO_THROW(nlohmann::json::parse(to_stdout.output));
  const CommandResult info = Placedb("info --db " + db + " --json");
  ASSERT_EQ(info.code, 0) << info.output;
  EXPECT_EQ(nlohmann::json::parse(info.output)["source"], "images:" + Path("caf\xef\xbf\xbd"));
  EXPECT_NO_THROW(nlohmann::json::parse(ReadFile(Path("b.json"))));
}

// Issue #19, item 2. A new folder's frames are numbered 1, 2, ... by their
// place in its listing, which the database holds already: `add` used to
// refuse them ("frame 1 is already a keyframe") or, with --skip-existing,
// drop them all and say "added 0 keyframes (4 already there)". New frames get
// the ids after the largest instead; TUM frames keep their poses;
// --skip-existing knows frames by source path and content and counts truly;
// the same path with other content is added.
TEST_F(CliTest, AddGivesNewFramesFreshIdsAndSkipsBySourceAndContent) {
  const std::string db = Path("add.db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 32 --out " + db + " --quiet").code, 0);
  const std::string folder = Path("new");
  fs::create_directories(folder);
  auto put = [&](int image, const std::string& name) {
    char source[16];
    std::snprintf(source, sizeof(source), "/%03d.jpg", image);
    fs::copy_file(kImages + source, folder + "/" + name, fs::copy_options::overwrite_existing);
  };
  for (int i = 1; i <= 4; ++i) put(32 + i, "00" + std::to_string(i) + ".jpg");
  const CommandResult add = Placedb("add --db " + db + " --images " + folder + " --quiet");
  ASSERT_EQ(add.code, 0) << add.output;
  EXPECT_TRUE(Contains(add.output, "added         4 keyframes, ids 33..36")) << add.output;
  EXPECT_TRUE(Contains(add.output, "now has 36 keyframes, ids 1..36, next free id 37"))
      << add.output;
  // Image 035 is now keyframe 35, the id its new frame got.
  ASSERT_EQ(
      Placedb("query --db " + db + " --image " + kImages + "/035.jpg --json " + Path("q.json"))
          .code,
      0);
  EXPECT_EQ(nlohmann::json::parse(ReadFile(Path("q.json")))["best"]["keyframe_id"], 35);

  // TUM frames: fresh ids, their poses kept (3 of the 4 have one).
  const std::string tum = PLACEDB_DATA_DIR "/tum_fr3_office_mini";
  const CommandResult tum_add = Placedb("add --db " + db + " --tum " + tum + " --quiet");
  ASSERT_EQ(tum_add.code, 0) << tum_add.output;
  EXPECT_TRUE(Contains(tum_add.output, "added         4 keyframes, ids 37..40")) << tum_add.output;
  EXPECT_TRUE(Contains(Placedb("info --db " + db).output, "poses           3 of 40 keyframes"));

  // The folder again with two more frames: true counts.
  put(37, "005.jpg");
  put(38, "006.jpg");
  const CommandResult again = Placedb("add --db " + db + " --images " + folder + " --quiet");
  EXPECT_EQ(again.code, 1);
  EXPECT_TRUE(Contains(again.output, "is already keyframe 33 of")) << again.output;
  const CommandResult skip =
      Placedb("add --db " + db + " --images " + folder + " --skip-existing --quiet");
  ASSERT_EQ(skip.code, 0) << skip.output;
  EXPECT_TRUE(Contains(skip.output, "added         2 keyframes, ids 41..42")) << skip.output;
  EXPECT_TRUE(
      Contains(skip.output, "skipped       4 already in the database (same source and content)"))
      << skip.output;
  // Same path, other content: added, and said.
  put(50, "002.jpg");
  const CommandResult changed =
      Placedb("add --db " + db + " --images " + folder + " --skip-existing --quiet");
  ASSERT_EQ(changed.code, 0) << changed.output;
  EXPECT_TRUE(Contains(changed.output, "added         1 keyframe, id 43")) << changed.output;
  EXPECT_TRUE(Contains(changed.output, "skipped       5 already in the database"))
      << changed.output;
  EXPECT_TRUE(Contains(changed.output,
                       "new content   1 with the path of a keyframe but other "
                       "content, added as new keyframes"))
      << changed.output;
  // Nothing new: nothing is written (a save would replace the manifest by a
  // new file, another inode).
  struct stat before;
  ASSERT_EQ(::stat((db + "/manifest.json").c_str(), &before), 0);
  const CommandResult nothing =
      Placedb("add --db " + db + " --images " + folder + " --skip-existing --quiet");
  ASSERT_EQ(nothing.code, 0) << nothing.output;
  EXPECT_TRUE(Contains(nothing.output, "added         0 keyframes")) << nothing.output;
  EXPECT_TRUE(Contains(nothing.output, "skipped       6 already in the database"))
      << nothing.output;
  struct stat after;
  ASSERT_EQ(::stat((db + "/manifest.json").c_str(), &after), 0);
  EXPECT_EQ(after.st_ino, before.st_ino);
  // Ids from names and from an offset; a name that is not a number is refused.
  const std::string named = Path("named");
  fs::create_directories(named);
  fs::copy_file(kImages + "/060.jpg", named + "/0100.jpg");
  const CommandResult names =
      Placedb("add --db " + db + " --images " + named + " --ids-from-names --quiet");
  ASSERT_EQ(names.code, 0) << names.output;
  EXPECT_TRUE(Contains(names.output, "added         1 keyframe, id 100")) << names.output;
  fs::copy_file(kImages + "/061.jpg", named + "/frame_7.jpg");
  const CommandResult bad_name =
      PlacedbStderr("add --db " + db + " --images " + named + " --ids-from-names --quiet");
  EXPECT_EQ(bad_name.code, 1);
  EXPECT_TRUE(Contains(bad_name.output, "cannot take an id from the file name 'frame_7.jpg'"))
      << bad_name.output;
  EXPECT_EQ(std::count(bad_name.output.begin(), bad_name.output.end(), '\n'), 1) << bad_name.output;
  const CommandResult offset =
      Placedb("add --db " + db + " --images " + named + " --id-offset 500 --skip-existing --quiet");
  ASSERT_EQ(offset.code, 0) << offset.output;
  EXPECT_TRUE(Contains(offset.output, "added         1 keyframe, id 501")) << offset.output;
  EXPECT_TRUE(Contains(offset.output, "next free id 502")) << offset.output;
}

// Issue #19, item 2: info shows the id range, the next free id and the
// removed count, as text and in --json.
TEST_F(CliTest, InfoShowsIdRangeNextFreeIdAndRemovedCount) {
  const std::string db = Path("ids.db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 12 --out " + db + " --quiet").code, 0);
  CommandResult info = Placedb("info --db " + db);
  EXPECT_TRUE(Contains(info.output, "keyframe ids    1..12, next free id 13")) << info.output;
  EXPECT_TRUE(Contains(info.output, "removed         0 keyframes since ")) << info.output;
  const CommandResult remove = Placedb("remove --db " + db + " --ids 12,3");
  ASSERT_EQ(remove.code, 0) << remove.output;
  EXPECT_TRUE(Contains(remove.output, "now has 10 keyframes, ids 1..11, next free id 13"))
      << remove.output;
  info = Placedb("info --db " + db);
  EXPECT_TRUE(Contains(info.output, "keyframe ids    1..11, next free id 13")) << info.output;
  EXPECT_TRUE(Contains(info.output, "removed         2 keyframes since ")) << info.output;
  const CommandResult json = Placedb("info --db " + db + " --json");
  ASSERT_EQ(json.code, 0) << json.output;
  const nlohmann::json ids = nlohmann::json::parse(json.output)["ids"];
  EXPECT_EQ(ids["count"], 10);
  EXPECT_EQ(ids["first"], 1);
  EXPECT_EQ(ids["last"], 11);
  EXPECT_EQ(ids["next_free"], 13);
  EXPECT_EQ(ids["removed"], 2);
  EXPECT_TRUE(ids["removed_since"].is_string());
  // Id 12 is not given again.
  const std::string folder = Path("one");
  fs::create_directories(folder);
  fs::copy_file(kImages + "/070.jpg", folder + "/001.jpg");
  const CommandResult add = Placedb("add --db " + db + " --images " + folder + " --quiet");
  EXPECT_TRUE(Contains(add.output, "added         1 keyframe, id 13")) << add.output;
}

// Issue #19, item 6: the help of add, remove and info lists only the flags
// they use (none of the open options: --partition, --keyframes,
// --cluster-radius, ... do nothing there), shows defaults, and ends with
// examples; `add --partition` is refused before any work.
TEST_F(CliTest, AddRemoveInfoHelpListsOnlyTheirFlagsWithExamples) {
  const CommandResult options = Placedb("options --json");
  ASSERT_EQ(options.code, 0) << options.output;
  std::vector<std::string> open_flags;
  const nlohmann::json tables = nlohmann::json::parse(options.output).at("tables");
  for (const nlohmann::json& table : tables) {
    if (table.at("table").get<std::string>() != "open options") continue;
    for (const nlohmann::json& o : table.at("options")) {
      if (o.at("command_line").get<bool>()) open_flags.push_back(o.at("flag").get<std::string>());
    }
  }
  ASSERT_GE(open_flags.size(), 5u);
  for (const char* flag : {"--partition", "--keyframes", "--cluster-radius", "--threads"}) {
    EXPECT_NE(std::find(open_flags.begin(), open_flags.end(), flag), open_flags.end()) << flag;
  }
  for (const std::string command : {"add", "remove", "info", "verify"}) {
    const CommandResult help = Placedb(command + " --help");
    ASSERT_EQ(help.code, 0) << help.output;
    EXPECT_TRUE(HasFlag(help.output, "--db")) << command;
    for (const std::string& flag : open_flags) {
      EXPECT_FALSE(HasFlag(help.output, flag)) << command << " --help lists " << flag;
    }
    const size_t examples = help.output.find("Examples:\n  placedb " + command + " --db ");
    EXPECT_NE(examples, std::string::npos) << help.output;
  }
  const CommandResult add_help = Placedb("add --help");
  for (const char* shown : {"--id-offset INT=0", "--ids-from-names", "--skip-existing", "--images",
                            "--tum", "--bag", "--first INT=1", "--quiet"}) {
    EXPECT_TRUE(Contains(add_help.output, shown)) << shown << "\n" << add_help.output;
  }
  // --partition is no flag of add: refused while parsing, nothing done.
  const std::string db = Path("db");
  ASSERT_EQ(Placedb("build --images " + kImages + " --last 5 --out " + db + " --quiet").code, 0);
  const std::string manifest = ReadFile(db + "/manifest.json");
  const CommandResult partition =
      PlacedbStderr("add --db " + db + " --images " + kImages + " --partition 0/2 --quiet");
  EXPECT_EQ(partition.code, 1);
  EXPECT_TRUE(Contains(partition.output, "--partition")) << partition.output;
  EXPECT_EQ(std::count(partition.output.begin(), partition.output.end(), '\n'), 1)
      << partition.output;
  EXPECT_EQ(ReadFile(db + "/manifest.json"), manifest);
  EXPECT_EQ(PlacedbStderr("info --db " + db + " --keyframes 1,2").code, 1);
  EXPECT_EQ(PlacedbStderr("remove --db " + db + " --ids 1 --cluster-radius 3").code, 1);
  EXPECT_EQ(ReadFile(db + "/manifest.json"), manifest);
}

}  // namespace
