#include "placedb/dataset/match_truth.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <stdexcept>

#include "placedb/util/testing.h"

namespace placedb {
namespace {

using testing_util::TempDir;
using testing_util::ThrowsWith;

const std::string kData = PLACEDB_DATA_DIR;

TEST(MatchTruthTest, RtabmapLoop) {
  const MatchTruth truth = ReadMatchTruth(kData + "/rtabmap_loop/ground_truth.csv");
  ASSERT_EQ(truth.size(), 44u);
  EXPECT_EQ(truth.begin()->first, 41);
  EXPECT_EQ(truth.rbegin()->first, 84);
  size_t positives = 0;
  for (const auto& [query, ids] : truth) {
    EXPECT_FALSE(ids.empty()) << query;  // every query has a true match
    EXPECT_TRUE(std::is_sorted(ids.begin(), ids.end())) << query;
    for (int id : ids) EXPECT_LT(id, query);  // matches are earlier images
    positives += ids.size();
  }
  EXPECT_EQ(positives, 228u);  // SOURCE.txt: 228 positive pairs
  EXPECT_EQ(truth.at(41), (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(truth.at(60), (std::vector<int>{18, 19, 20, 21, 22}));
  EXPECT_EQ(truth.at(81), (std::vector<int>{1, 2, 39, 40, 41, 42, 43}));
  EXPECT_EQ(truth.at(84), (std::vector<int>{3, 4, 5, 42, 43, 44, 45, 46}));
}

TEST(MatchTruthTest, SeparatorsEmptyListsAndUnsortedIds) {
  TempDir tmp;
  const std::string path = tmp.Write("gt.csv",
                                     "\xEF\xBB\xBF# query,matches\n"
                                     "5,3 1,2\r\n"
                                     "6,\n"
                                     "  7 , 9 ,\t8 \n"
                                     "\n"
                                     "8,10,,11\n");
  const MatchTruth truth = ReadMatchTruth(path);
  ASSERT_EQ(truth.size(), 4u);
  EXPECT_EQ(truth.at(5), (std::vector<int>{1, 2, 3}));
  EXPECT_TRUE(truth.at(6).empty());
  EXPECT_EQ(truth.at(7), (std::vector<int>{8, 9}));
  EXPECT_EQ(truth.at(8), (std::vector<int>{10, 11}));
}

TEST(MatchTruthTest, MalformedLinesNameFileAndLine) {
  TempDir tmp;
  const std::string dup = tmp.Write("dup.csv", "# h\n1,2\n3,4\n1,5\n");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadMatchTruth(dup); },
                                          {dup + ":4:", "duplicate query id 1", "line 2"}));
  const std::string text = tmp.Write("text.csv", "1,2 x3\n");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadMatchTruth(text); }, {text + ":1:", "'x3'"}));
  const std::string header = tmp.Write("header.csv", "query,matches\n1,2\n");
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { ReadMatchTruth(header); }, {header + ":1:", "'query'"}));
  const std::string no_comma = tmp.Write("nocomma.csv", "1,2\n\n3 4 5\n");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadMatchTruth(no_comma); },
                                          {no_comma + ":3:", "no comma"}));
  const std::string semicolon = tmp.Write("semicolon.csv", "1,2;3\n");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadMatchTruth(semicolon); },
                                          {semicolon + ":1:", "'2;3'"}));
  const std::string zero = tmp.Write("zero.csv", "1,0 2\n");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadMatchTruth(zero); }, {zero + ":1:", ">= 1"}));
  const std::string repeated = tmp.Write("repeated.csv", "1,2\n2,3 4 3\n");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadMatchTruth(repeated); },
                                          {repeated + ":2:", "id 3 listed twice"}));
  const std::string two_queries = tmp.Write("two.csv", "1 2,3\n");
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { ReadMatchTruth(two_queries); }, {two_queries + ":1:"}));
  EXPECT_TRUE(ThrowsWith<NotFound>([&] { ReadMatchTruth(tmp.Path("none.csv")); }, {"none.csv"}));
}

// A binary file given as ground truth: one clear line, never its raw bytes.
TEST(MatchTruthTest, BinaryFilesGiveAPrintableError) {
  testing_util::TempDir tmp;
  const std::string png = tmp.Write("truth.png", std::string("\x89PNG\r\n\x1a\n\0\0\0\rIHDR", 16));
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { ReadMatchTruth(png); }, {"not a text file", "NUL bytes"}));
  const std::string junk = tmp.Write("junk.csv", "1,2\n\x1b[31m\xff\xfe,3\n");
  try {
    ReadMatchTruth(junk);
    ADD_FAILURE() << "no error";
  } catch (const InvalidArgument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(junk + ":2:"), std::string::npos) << message;
    EXPECT_NE(message.find("\\x1b"), std::string::npos) << message;
    for (const char c : message) {
      EXPECT_TRUE(c >= 0x20 && c < 0x7f)
          << "raw byte " << static_cast<int>(static_cast<unsigned char>(c));
    }
  }
}

}  // namespace
}  // namespace placedb
