// A user's first hour (issue 19), run as the user runs it: JSON piped into a
// parser, evaluations that cannot mean anything said so, help screens that
// end with examples that work, and errors that name the right flag.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "placedb/exe/cli_testing.h"
#include "placedb/util/testing.h"

namespace {
namespace fs = std::filesystem;
using placedb::testing_util::CommandResult;
using placedb::testing_util::Contains;
using placedb::testing_util::RunShell;

const std::string kBinary = PLACEDB_BINARY;
const std::string kData = PLACEDB_DATA_DIR;
const std::string kImages = kData + "/rtabmap_loop/images";
const std::string kTruth = kData + "/rtabmap_loop/ground_truth.csv";
const std::string kTum = kData + "/tum_fr3_office_32";
// Debian's, with the standard library's json.tool.
const std::string kPython = "/usr/bin/python3";

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Whether `text` is one JSON document and nothing else.
bool IsJustJson(const std::string& text) {
  return !text.empty() && nlohmann::json::accept(text);
}

class CliUserTest : public ::testing::Test {
 protected:
  // One small database of each kind for the whole suite: images 1-20 of the
  // RTAB-Map loop (no poses) and TUM frames 1-16 (with poses).
  static void SetUpTestSuite() {
    dir_ = new placedb::testing_util::TempDir();
    db_ = dir_->Path("loop.db");
    tum_db_ = dir_->Path("tum.db");
    ASSERT_EQ(RunShell(kBinary + " build --images " + kImages + " --last 20 --out " + db_ +
                       " --quiet >/dev/null 2>&1")
                  .code,
              0);
    ASSERT_EQ(RunShell(kBinary + " build --tum " + kTum + " --last 16 --out " + tum_db_ +
                       " --quiet >/dev/null 2>&1")
                  .code,
              0);
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }

  std::string Path(const std::string& name) const { return tmp_.Path(name); }

  static placedb::testing_util::TempDir* dir_;
  static std::string db_, tum_db_;
  placedb::testing_util::TempDir tmp_;
};

placedb::testing_util::TempDir* CliUserTest::dir_ = nullptr;
std::string CliUserTest::db_;
std::string CliUserTest::tum_db_;

// Finding 1: the human text came first on stdout, so `--json - | json.tool`
// failed. Every command with --json, piped.
TEST_F(CliUserTest, JsonToStdoutIsOnlyJsonForEveryCommand) {
  const std::vector<std::string> commands = {
      "build --images " + kImages + " --last 5 --overwrite --out " + Path("piped.db"),
      "query --db " + db_ + " --image " + kImages + "/042.jpg",
      "eval --db " + db_ + " --images " + kImages + " --first 41 --last 50 --truth " + kTruth,
      "bench --db " + db_ + " --images " + kImages + " --first 41 --last 43 --repeat 1",
  };
  for (const std::string& command : commands) {
    SCOPED_TRACE(command);
    // Into a JSON parser, stderr left where it was.
    const CommandResult piped =
        RunShell("set -o pipefail; " + kBinary + " " + command + " --json - 2>/dev/null | " +
                 kPython + " -m json.tool");
    EXPECT_EQ(piped.code, 0) << piped.output;
    // stdout alone is the JSON; the human text went to stderr.
    const CommandResult out = RunShell(kBinary + " " + command + " --json - 2>/dev/null");
    EXPECT_EQ(out.code, 0);
    EXPECT_TRUE(IsJustJson(out.output)) << out.output.substr(0, 400);
    const CommandResult err = RunShell(kBinary + " " + command + " --json - 2>&1 >/dev/null");
    EXPECT_FALSE(err.output.empty()) << "the human text is not on stderr";
  }
  // The flags that print JSON alone.
  for (const std::string& command : {"info --db " + db_ + " --json", std::string("options --json")}) {
    const CommandResult out = RunShell(kBinary + " " + command + " 2>/dev/null");
    EXPECT_EQ(out.code, 0) << command;
    EXPECT_TRUE(IsJustJson(out.output)) << command;
  }
}

// Finding 1 too: `--json >(...)` failed creating /dev/fd/63.tmp.NNN. Every
// special path stdout or a reader can be: /dev/stdout, /dev/fd/1, a process
// substitution, a FIFO.
TEST_F(CliUserTest, JsonToSpecialPathsIsStreamed) {
  const std::string query = kBinary + " query --db " + db_ + " --image " + kImages + "/042.jpg";
  for (const char* path : {"/dev/stdout", "/dev/fd/1"}) {
    const CommandResult out = RunShell(query + " --json " + path + " 2>/dev/null");
    EXPECT_EQ(out.code, 0) << path;
    EXPECT_TRUE(IsJustJson(out.output)) << path << ": " << out.output.substr(0, 300);
  }
  // Process substitution: bash waits for it with `wait $!`.
  const std::string substituted = Path("substituted.json");
  const CommandResult sub = RunShell(query + " --json >(cat > " + substituted +
                                     ") >/dev/null 2>&1; code=$?; wait $! 2>/dev/null; exit $code");
  EXPECT_EQ(sub.code, 0);
  EXPECT_TRUE(IsJustJson(ReadFile(substituted))) << ReadFile(substituted).substr(0, 300);
  // A FIFO with a reader.
  const std::string fifo = Path("answers.fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string read = Path("from_fifo.json");
  const CommandResult through = RunShell("cat " + fifo + " > " + read + " & reader=$!; " + query +
                                         " --json " + fifo +
                                         " >/dev/null 2>&1; code=$?; wait $reader; exit $code");
  EXPECT_EQ(through.code, 0);
  EXPECT_TRUE(IsJustJson(ReadFile(read)));
  EXPECT_TRUE(fs::is_fifo(fifo)) << "the FIFO was replaced";
}

// Finding 5: the database's own frames as queries gave recall@1 1.000 in
// silence.
TEST_F(CliUserTest, QueriesThatAreDatabaseFramesAreWarnedAboutAndRefusedWhenStrict) {
  const std::string eval =
      kBinary + " eval --db " + tum_db_ + " --tum " + kTum + " --last 16 --all --quiet";
  const CommandResult warned = RunShell(eval + " 2>&1 >/dev/null");
  EXPECT_EQ(warned.code, 0);
  EXPECT_TRUE(Contains(warned.output, "meaningless evaluation")) << warned.output;
  EXPECT_TRUE(Contains(warned.output, "query frames are database frames")) << warned.output;
  // The report says it too, and its JSON lists it.
  const CommandResult report = RunShell(eval + " --json " + Path("e.json") + " 2>/dev/null");
  EXPECT_TRUE(Contains(report.output, "WARNING: ")) << report.output;
  const nlohmann::json j = nlohmann::json::parse(ReadFile(Path("e.json")));
  ASSERT_EQ(j["doubts"].size(), 1u);
  // A copy of the same files in another folder is the same frames.
  fs::copy(kTum, Path("copy"), fs::copy_options::recursive);
  const CommandResult copied =
      RunShell(kBinary + " eval --db " + tum_db_ + " --tum " + Path("copy") +
               " --last 16 --all --quiet 2>&1 >/dev/null");
  EXPECT_TRUE(Contains(copied.output, "query frames are database frames")) << copied.output;
  // --strict refuses, in one line, before any query.
  const CommandResult strict = RunShell(eval + " --strict 2>&1");
  EXPECT_EQ(strict.code, 1);
  EXPECT_TRUE(Contains(strict.output, "placedb: error: refused (strict)")) << strict.output;
  EXPECT_FALSE(Contains(strict.output, "recall@1")) << strict.output;
  // Other frames of the sequence: nothing to say.
  const CommandResult honest = RunShell(kBinary + " eval --db " + tum_db_ + " --tum " + kTum +
                                        " --first 17 --all --quiet --strict 2>&1");
  EXPECT_EQ(honest.code, 0) << honest.output;
  EXPECT_FALSE(Contains(honest.output, "meaningless")) << honest.output;
}

// Finding 5: a database without poses against pose truth said "answerable
// 0 ... precision 1.000" and exited 0.
TEST_F(CliUserTest, TruthThatJudgesNoKeyframeIsWarnedAboutAndNoRatioIsPrinted) {
  const std::string no_poses = Path("no_poses.db");
  ASSERT_EQ(RunShell(kBinary + " build --images " + kTum + "/rgb --last 16 --out " + no_poses +
                     " --quiet >/dev/null 2>&1")
                .code,
            0);
  const std::string eval =
      kBinary + " eval --db " + no_poses + " --tum " + kTum + " --first 17 --all --quiet";
  const CommandResult r = RunShell(eval + " 2>&1");
  EXPECT_EQ(r.code, 0);
  EXPECT_TRUE(Contains(r.output, "no keyframe of the database has a pose")) << r.output;
  EXPECT_TRUE(Contains(r.output, "answerable                 0")) << r.output;
  EXPECT_TRUE(Contains(r.output, "recall@1                 n/a")) << r.output;
  EXPECT_TRUE(Contains(r.output, "precision                n/a")) << r.output;
  EXPECT_EQ(RunShell(eval + " --strict >/dev/null 2>&1").code, 1);
  // A match list naming none of the database's keyframes (queries 41-84
  // of the loop, keyframes 1-20, a list of other ids).
  const std::string list = tmp_.Write("other.csv", "# query,true keyframes\n41,70 71\n42,72\n");
  const CommandResult foreign =
      RunShell(kBinary + " eval --db " + db_ + " --images " + kImages +
               " --first 41 --last 42 --truth " + list + " --quiet 2>&1 >/dev/null");
  EXPECT_TRUE(Contains(foreign.output, "names none of the database's keyframe ids"))
      << foreign.output;
}

// Finding 5 and 6: `experiment` with default ranges queried the database's
// frames; `--search bow` built every database, then failed; there was no
// `--index`. The progress lines said "1/12 correct" with 1 answerable.
TEST_F(CliUserTest, ExperimentChecksItsDataUpFrontAndTakesTheIndex) {
  const std::string out = Path("exp");
  const CommandResult same = RunShell(kBinary + " experiment --tum " + kTum +
                                      " --features orb --crop none --resize 1 --verification on "
                                      "--strict --no-report --out " +
                                      out + " 2>&1");
  EXPECT_EQ(same.code, 1);
  EXPECT_TRUE(Contains(same.output, "query frames are database frames")) << same.output;
  EXPECT_FALSE(fs::exists(out + "/databases")) << "built before refusing";

  const CommandResult no_index =
      RunShell(kBinary + " experiment --tum " + kTum +
               " --db-last 16 --first 17 --features orb --search bow --out " + out + " 2>&1");
  EXPECT_EQ(no_index.code, 1);
  EXPECT_TRUE(Contains(no_index.output, "--index bow")) << no_index.output;
  EXPECT_FALSE(fs::exists(out + "/databases")) << "built before refusing";

  const CommandResult bow = RunShell(
      kBinary + " experiment --tum " + kTum +
      " --db-last 16 --first 17 --features orb --crop none --resize 1 --index bow "
      "--vocabulary-depth 2 --search bow --strict --no-report --out " + out + " 2>&1");
  EXPECT_EQ(bow.code, 0) << bow.output;
  // "[1/2] ORB none 1/1 verified: 12 correct of 14 answerable (14 queries), recall@1 0.857"
  EXPECT_TRUE(Contains(bow.output, " answerable (")) << bow.output;
  const nlohmann::json results = nlohmann::json::parse(ReadFile(out + "/results.json"));
  EXPECT_NE(results.dump().find("\"search\":\"bow\""), std::string::npos);
  EXPECT_EQ(results.dump().find("\"search\":\"exhaustive\""), std::string::npos)
      << "a query did not use the bag-of-words index";
}

// Finding 6: no help screen had an example; --verify read as off by
// default. Each command's help ends with its examples.
TEST_F(CliUserTest, HelpEndsWithExamplesAndSaysDefaultsInWords) {
  for (const char* command :
       {"build", "query", "eval", "experiment", "bench", "options", "add", "remove", "info",
        "verify"}) {
    const CommandResult help = RunShell(kBinary + " " + command + " --help 2>&1");
    EXPECT_EQ(help.code, 0) << command;
    const size_t at = help.output.rfind("\nExamples:\n");
    ASSERT_NE(at, std::string::npos) << command << " has no examples";
    EXPECT_TRUE(Contains(help.output.substr(at), std::string("placedb ") + command)) << command;
    EXPECT_FALSE(Contains(help.output, "{false}")) << command;
  }
  const CommandResult query = RunShell(kBinary + " query --help 2>&1");
  EXPECT_TRUE(Contains(query.output, "(default: on; --no-verify turns it off)")) << query.output;
}

// The examples of every help screen, run as printed (in a folder where
// data/ is the sample data), in the order a user would: build first.
TEST_F(CliUserTest, EveryHelpExampleRuns) {
  fs::create_directory_symlink(kData, Path("data"));
  std::string script = "set -e -o pipefail\ncd " + Path("") + "\nplacedb() { " + kBinary +
                       " \"$@\"; }\npython3() { " + kPython + " \"$@\"; }\n";
  int examples = 0;
  // The map changes last: the evaluations above query frames it lacks.
  for (const char* command :
       {"build", "query", "eval", "experiment", "bench", "options", "add", "remove", "info",
        "verify"}) {
    const std::string help = RunShell(kBinary + " " + command + " --help 2>&1").output;
    std::istringstream lines(help.substr(help.rfind("\nExamples:\n") + 11));
    std::string line, joined;
    while (std::getline(lines, line)) {
      if (line.empty()) continue;
      joined += line;
      if (!joined.empty() && joined.back() == '\\') {
        joined.pop_back();
        continue;
      }
      // On its own line: an example may end with a # comment.
      script += "{\n" + joined + "\n} >>" + Path("examples.log") + " 2>&1\n";
      joined.clear();
      ++examples;
    }
  }
  EXPECT_EQ(examples, 19);
  tmp_.Write("examples.sh", script);
  const CommandResult run = RunShell("bash " + Path("examples.sh"));
  EXPECT_EQ(run.code, 0) << script << "\n" << ReadFile(Path("examples.log"));
  EXPECT_FALSE(Contains(ReadFile(Path("examples.log")), "meaningless evaluation"))
      << "an example evaluates nothing";
}

// Finding 6: a TUM folder given to --images said "no images found"; a
// missing folder "not an image folder nor an image list file".
TEST_F(CliUserTest, WrongKindsOfInputNameTheRightFlag) {
  const CommandResult tum_as_images =
      RunShell(kBinary + " build --images " + kTum + " --out " + Path("x.db") + " 2>&1");
  EXPECT_EQ(tum_as_images.code, 1);
  EXPECT_TRUE(Contains(tum_as_images.output, "looks like a TUM RGB-D folder")) << tum_as_images.output;
  EXPECT_TRUE(Contains(tum_as_images.output, "--tum")) << tum_as_images.output;
  const CommandResult images_as_tum =
      RunShell(kBinary + " build --tum " + kImages + " --out " + Path("x.db") + " 2>&1");
  EXPECT_EQ(images_as_tum.code, 1);
  EXPECT_TRUE(Contains(images_as_tum.output, "--images")) << images_as_tum.output;
  for (const char* flag : {"--images", "--tum"}) {
    const CommandResult missing = RunShell(kBinary + " build " + flag + " " + Path("nowhere") +
                                           " --out " + Path("x.db") + " 2>&1");
    EXPECT_EQ(missing.code, 1) << flag;
    EXPECT_TRUE(Contains(missing.output, Path("nowhere") + " does not exist")) << missing.output;
  }
  EXPECT_FALSE(fs::exists(Path("x.db")));
}

}  // namespace
