// The option table of the voting node (util/option_table.h).
#include "placedb/distributed/vote_collector.h"
#include "placedb/util/option_table.h"

namespace placedb {

const OptionTable<VoteOptions>& VoteOptions::Table() {
  static const OptionTable<VoteOptions> table = [] {
    using O = VoteOptions;
    OptionTable<O> t("vote options");
    t.Number("partitions", PLACEDB_MEMBER(O, num_partitions), OptionRange::Closed(1, 4096),
             "how many worker partitions", kCommandLine);
    t.Number("deadline_ms", PLACEDB_MEMBER(O, deadline_ms), OptionRange::LeftOpen(0, 600000),
             "answer a frame at the latest this long after it was first seen, ms (with the "
             "partitions that answered)",
             kCommandLine);
    t.Number("max_pending", PLACEDB_MEMBER(O, max_pending), OptionRange::Closed(1, 100000),
             "frames waiting at most", kCommandLine);
    // How answers rank and decide: the workers' query options; the voter
    // runs no query, so neither a query deadline nor a prior applies.
    t.Nest(PLACEDB_MEMBER(O, query), QueryOptions::Table(), kCommandLine,
           {"deadline_ms", "prior_keyframe", "prior_pose"});
    t.Bool("sequence", PLACEDB_MEMBER(O, sequence),
           "answer with sequence evidence: the best path through the keyframe order over each "
           "feed run's last frames (`sequence_*`)",
           BoolFlag::kSwitch, kCommandLine);
    t.Nest(PLACEDB_MEMBER(O, sequence_options), SequenceOptions::Table(), kCommandLine);
    return t;
  }();
  return table;
}

std::string VoteOptions::Check() const { return Table().Check(*this); }

}  // namespace placedb
