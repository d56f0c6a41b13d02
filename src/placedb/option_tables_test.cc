// Every option table of the library, checked against its struct: the table
// describes every member (its layout), every option reads back what it was
// given (typed, as text, and through a manifest), and every range holds at
// both of its ends and refuses just beyond them with the option named.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <algorithm>
#include <limits>
#include <set>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "placedb/builder/builder.h"
#include "placedb/cli/options.h"
#include "placedb/placedb.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/option_json.h"

namespace placedb {
namespace {

// One table, and how to make, copy and check its struct untyped.
struct TableCase {
  const OptionTableBase* table;
  std::function<std::shared_ptr<void>()> make;  // a default-constructed struct
  std::function<std::string(const void*)> check;
};

template <typename T>
TableCase Case() {
  return {&T::Table(), [] { return std::static_pointer_cast<void>(std::make_shared<T>()); },
          [](const void* o) { return static_cast<const T*>(o)->Check(); }};
}

std::vector<TableCase> AllTables() {
  return {Case<OrbOptions>(),         Case<SurfOptions>(),      Case<ExtractorOptions>(),
          Case<CropOptions>(),        Case<MatchOptions>(),     Case<VerifyOptions>(),
          Case<RetrievalOptions>(),   Case<ClusterOptions>(),   Case<VocabularyOptions>(),
          Case<BowIndexOptions>(),    Case<QueryPrior>(),       Case<QueryOptions>(),
          Case<BuildOptions>(),       Case<OpenOptions>(),      Case<ImageReadOptions>(),
          Case<TumOptions>(),         Case<FrameSourceOptions>(), Case<PoseThresholds>(),
          Case<GroundTruthOptions>(), Case<EvalOptions>(),      Case<BenchOptions>(),
          Case<ExperimentOptions>(),  Case<VoteOptions>(),      Case<AddOptions>(),
          Case<WholeImageOptions>()};
}

// Every table of the library is one an entry point takes (the list `placedb
// options --json` reports, and the command-line and Python tests hold their
// surfaces to) or nested in one: an options struct no entry point reaches
// fails here.
TEST(OptionTablesTest, EveryTableIsTakenByAnEntryPointOrNestedInOne) {
  const std::vector<const OptionTableBase*> top = cli::AllOptionTables();
  std::set<std::string> reached;  // members' paths below the top tables
  for (const OptionTableBase* t : top) {
    for (const auto& e : t->entries()) reached.insert(e.field.name);
  }
  for (const TableCase& c : AllTables()) {
    if (std::find(top.begin(), top.end(), c.table) != top.end()) continue;
    int found = 0;
    for (const auto& e : c.table->entries()) found += static_cast<int>(reached.count(e.field.name));
    EXPECT_GT(found, 0) << c.table->what() << " is taken by no entry point";
  }
  for (const OptionTableBase* t : top) {
    bool typed = false;
    for (const TableCase& c : AllTables()) typed |= c.table == t;
    EXPECT_TRUE(typed) << t->what() << " is not in this test's list";
  }
}

TEST(OptionTablesTest, EveryTableDescribesEveryMemberOfItsStruct) {
  for (const TableCase& c : AllTables()) {
    EXPECT_EQ(c.table->CheckLayout(), "") << c.table->what();
  }
}

TEST(OptionTablesTest, DefaultsAreValidAndNamesAreUnique) {
  for (const TableCase& c : AllTables()) {
    SCOPED_TRACE(c.table->what());
    const std::shared_ptr<void> o = c.make();
    EXPECT_EQ(c.check(o.get()), "");
    for (const auto& e : c.table->entries()) {
      const OptionField& f = e.field;
      EXPECT_FALSE(f.help.empty()) << f.name;
      EXPECT_FALSE(f.member.empty()) << f.name;
      EXPECT_EQ(f.name.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789_"),
                std::string::npos)
          << f.name;
      EXPECT_EQ(f.flag.rfind("--", 0), 0u) << f.name;
      EXPECT_NE(f.surfaces, 0u) << f.name << ": an option nobody can set";
    }
  }
}

// Each option takes back what it holds: typed, and as the text a command
// line gives (what `placedb options` shows as its default).
TEST(OptionTablesTest, EveryOptionReadsBackTypedAndAsText) {
  for (const TableCase& c : AllTables()) {
    SCOPED_TRACE(c.table->what());
    for (const auto& e : c.table->entries()) {
      const std::shared_ptr<void> o = c.make();
      const OptionValue before = e.get(o.get());
      e.set(o.get(), before);
      EXPECT_EQ(e.get(o.get()), before) << e.field.name;
      c.table->SetText(o.get(), e.field.name, OptionTableBase::Text(before));
      EXPECT_EQ(OptionTableBase::Text(e.get(o.get())), OptionTableBase::Text(before))
          << e.field.name;
      EXPECT_EQ(c.check(o.get()), "") << e.field.name;
    }
  }
}

// The value an option of `kind` holds for the number `v` (ints as ints).
OptionValue Number(OptionKind kind, double v) {
  if (kind == OptionKind::kDouble) return v;
  if (kind == OptionKind::kUint64) return static_cast<uint64_t>(v);
  return static_cast<int64_t>(v);
}

// A number just inside or outside a bound: the bound itself when closed,
// else the nearest value of the kind beyond it.
double Beside(double bound, bool inside_is_up, bool whole) {
  if (whole) return bound + (inside_is_up ? 1.0 : -1.0);
  return std::nextafter(bound, inside_is_up ? std::numeric_limits<double>::infinity()
                                            : -std::numeric_limits<double>::infinity());
}

// Whether setting option `e` of a fresh struct to `v` is refused, by the
// setter (the member's type cannot hold it) or by Check(), naming it.
::testing::AssertionResult Refused(const TableCase& c, const OptionTableBase::Entry& e,
                                   const OptionValue& v) {
  const std::shared_ptr<void> o = c.make();
  try {
    e.set(o.get(), v);
  } catch (const InvalidArgument& error) {
    if (error.message().find("`" + e.field.name + "`") == std::string::npos)
      return ::testing::AssertionFailure() << "the setter's message lacks the name: "
                                           << error.message();
    return ::testing::AssertionSuccess();
  }
  const std::string reason = c.check(o.get());
  if (reason.find("`" + e.field.name + "`") == std::string::npos)
    return ::testing::AssertionFailure() << "not refused by name: '" << reason << "'";
  return ::testing::AssertionSuccess();
}

TEST(OptionTablesTest, EveryRangeHoldsAtItsEndsAndRefusesBeyondThem) {
  int ranges = 0;
  for (const TableCase& c : AllTables()) {
    SCOPED_TRACE(c.table->what());
    for (const auto& e : c.table->entries()) {
      const OptionField& f = e.field;
      const OptionRange& r = f.bounds;
      if (f.kind != OptionKind::kInt && f.kind != OptionKind::kDouble &&
          f.kind != OptionKind::kUint64)
        continue;
      const bool whole = f.kind != OptionKind::kDouble;
      if (!r.one_of().empty()) {
        for (const int64_t v : r.one_of()) {
          const std::shared_ptr<void> o = c.make();
          e.set(o.get(), OptionValue(v));
          EXPECT_EQ(e.check(o.get()), "") << f.name << " = " << v;
        }
        EXPECT_TRUE(Refused(c, e, OptionValue(r.one_of().back() + 1))) << f.name;
        ++ranges;
        continue;
      }
      if (!r.interval()) continue;
      ++ranges;
      // Inside at both ends (the bound, or next to an open one).
      for (const bool low : {true, false}) {
        const double bound = low ? r.lo() : r.hi();
        const bool open = low ? r.lo_open() : r.hi_open();
        const double inside = open ? Beside(bound, low, whole) : bound;
        const double outside = open ? bound : Beside(bound, !low, whole);
        const std::shared_ptr<void> o = c.make();
        e.set(o.get(), Number(f.kind, inside));
        EXPECT_EQ(e.check(o.get()), "") << f.name << " = " << inside;
        if (f.kind == OptionKind::kUint64 && outside < 0) continue;
        EXPECT_TRUE(Refused(c, e, Number(f.kind, outside))) << f.name << " = " << outside;
      }
      if (f.kind == OptionKind::kDouble) {
        EXPECT_TRUE(Refused(c, e, std::numeric_limits<double>::quiet_NaN())) << f.name;
      }
    }
  }
  EXPECT_GT(ranges, 80);
}

// A value of another kind is refused by the setter, naming the option: a
// caller's types are never converted silently.
TEST(OptionTablesTest, ValuesOfAnotherKindAreRefusedByName) {
  for (const TableCase& c : AllTables()) {
    SCOPED_TRACE(c.table->what());
    for (const auto& e : c.table->entries()) {
      const OptionKind k = e.field.kind;
      const OptionValue wrong = k == OptionKind::kBool ? OptionValue(std::string("yes"))
                                : k == OptionKind::kText || k == OptionKind::kChoice
                                    ? OptionValue(true)
                                    : OptionValue(std::vector<std::string>{"x", "y"});
      if (k == OptionKind::kList) continue;  // a list takes one name as one item
      const std::shared_ptr<void> o = c.make();
      try {
        e.set(o.get(), wrong);
        ADD_FAILURE() << e.field.name << " took a value of another kind";
      } catch (const InvalidArgument& error) {
        EXPECT_NE(error.message().find("`" + e.field.name + "`"), std::string::npos)
            << error.message();
      }
    }
  }
}

// Every setting a manifest keeps is written and read back at both ends of
// its range; a manifest without one of them (but those older manifests
// lack, which the table says) or with a key the table does not know is
// refused, naming the key.
TEST(OptionTablesTest, EveryManifestSettingRoundTripsAndIsRequired) {
  const OptionTableBase& table = BuildOptions::Table();
  for (const auto& e : table.entries()) {
    const OptionField& f = e.field;
    if ((f.surfaces & kManifest) == 0) continue;
    SCOPED_TRACE(f.name);
    std::vector<OptionValue> values;
    if (f.bounds.interval()) {
      const bool whole = f.kind != OptionKind::kDouble;
      values.push_back(
          Number(f.kind, f.bounds.lo_open() ? Beside(f.bounds.lo(), true, whole) : f.bounds.lo()));
      values.push_back(
          Number(f.kind, f.bounds.hi_open() ? Beside(f.bounds.hi(), false, whole) : f.bounds.hi()));
    } else if (f.kind == OptionKind::kUint64) {
      values = {uint64_t{0}, std::numeric_limits<uint64_t>::max()};
    } else if (f.kind == OptionKind::kBool) {
      values = {true, false};
    } else if (!f.choices.empty()) {
      for (const std::string& name : f.choices) values.push_back(name);
    } else if (!f.bounds.one_of().empty()) {
      for (const int64_t v : f.bounds.one_of()) values.push_back(v);
    } else {
      values = {std::string("some/vocabulary.bin")};
    }
    for (const OptionValue& v : values) {
      BuildOptions o;
      // The depth's limit needs a small branching (2^24 words at most).
      if (f.name == "vocabulary_depth") o.vocabulary.branching = 2;
      if (f.name == "vocabulary_branching") o.vocabulary.depth = 2;
      if (f.name == "direct_level") o.vocabulary.depth = 8, o.vocabulary.branching = 2;
      // The tile must fit the thumbnail: small sides with small tiles, large
      // tiles in large thumbnails.
      if (f.name == "whole_image_width" || f.name == "whole_image_height")
        o.features.whole_image.patch = 2;
      if (f.name == "whole_image_patch")
        o.features.whole_image.width = o.features.whole_image.height = 64;
      e.set(&o, v);
      ASSERT_EQ(o.Check(), "") << OptionTableBase::Text(v);
      nlohmann::json manifest;
      manifest["settings"] = BuildSettingsToJson(o);
      const BuildOptions back = BuildOptionsFromManifest(manifest, "db");
      EXPECT_EQ(e.get(&back), v);
    }
    // Without its key.
    nlohmann::json manifest;
    manifest["settings"] = BuildSettingsToJson(BuildOptions());
    nlohmann::json* at = &manifest["settings"];
    std::string member = f.member;
    for (size_t dot; (dot = member.find('.')) != std::string::npos; member = member.substr(dot + 1))
      at = &(*at)[member.substr(0, dot)];
    at->erase(member);
    if (f.absent) {
      const BuildOptions read = BuildOptionsFromManifest(manifest, "db");
      EXPECT_EQ(e.get(&read), *f.absent);
    } else {
      try {
        BuildOptionsFromManifest(manifest, "db");
        ADD_FAILURE() << "a manifest without " << f.member << " was read";
      } catch (const CorruptDatabase& error) {
        EXPECT_NE(std::string(error.what()).find("settings." + f.member + " is missing"),
                  std::string::npos)
            << error.what();
      }
    }
    // With a key next to it that no option has.
    (*at)[member + "_extra"] = 1;
    try {
      BuildOptionsFromManifest(manifest, "db");
      ADD_FAILURE() << "an unknown key beside " << f.member << " was read";
    } catch (const CorruptDatabase& error) {
      EXPECT_NE(std::string(error.what()).find("not a setting this placedb knows"),
                std::string::npos)
          << error.what();
    }
  }
}

// A forgotten member is found: a table that leaves one out fails its
// layout check (the test of the test above).
struct TwoInts {
  int a = 1;
  double b = 2.0;
  int c = 3;
  static const OptionTable<TwoInts>& Table() {
    static const OptionTable<TwoInts> t = [] {
      OptionTable<TwoInts> table("two ints");
      table.Number("a", PLACEDB_MEMBER(TwoInts, a), OptionRange::Any(), "a");
      table.Number("c", PLACEDB_MEMBER(TwoInts, c), OptionRange::Any(), "c");
      return table;
    }();
    return t;
  }
};

TEST(OptionTablesTest, AForgottenMemberFailsTheLayoutCheck) {
  EXPECT_NE(TwoInts::Table().CheckLayout().find("bytes [4, 16)"), std::string::npos)
      << TwoInts::Table().CheckLayout();
}

}  // namespace
}  // namespace placedb
