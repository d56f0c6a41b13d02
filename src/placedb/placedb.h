// placedb: where is the robot? The public face of the library, and the only
// header a program needs:
//
//   #include <placedb/placedb.h>
//
//   const placedb::PlaceDatabase db = placedb::PlaceDatabase::Open("office.db");
//   const placedb::QueryResult r = db.Query(cv::imread("frame.png"));
//   if (const placedb::RankedKeyframe* best = r.best()) use(best->keyframe_id, best->pose);
//
// What it gives:
//   PlaceDatabase        the session: open a database (all of it, a partition,
//                        an id list), query an image or features, explain a
//                        match, add and remove keyframes while querying, save
//   QueryOptions, QueryResult, MergeQueryResults, Shortlist, MergeShortlists
//                        a query's options (retrieve, match, verify, decide),
//                        its answer and the voting merge of partial answers
//   BuildDatabase        a database from frames (BuildOptions, BuildReport)
//   ReadFrames           frames from an image folder or list or a TUM folder
//   Evaluate, RunExperiment, RunBench
//                        the paper's experiments against ground truth, and
//                        the speed against the paper's OpenCV matcher
//   VoteCollector        the bookkeeping of a voting node (distributed search;
//                        bag of words in two rounds)
//   BowPartitionWorker   a partition's side of those two rounds
//   OptionTable          every options struct's description (names, defaults,
//                        ranges, help): X::Table(), for clients that bind
//                        options (command lines, scripting languages)
//   Error and its kinds  what every function throws (util/error.h)
//
// Types of other libraries that are part of the contract: OpenCV's core
// types (cv::Mat images, cv::KeyPoint, cv::Rect, cv::Size, cv::Point2f,
// cv::DMatch) and Eigen's (a Pose is an Eigen::Vector3d and an
// Eigen::Quaterniond). Nothing else: no JSON library's types (JSON is text),
// no internal class (the database container, indexes, thread pools).
#pragma once

#include "placedb/builder/build.h"
#include "placedb/dataset/frame.h"
#include "placedb/dataset/frame_source.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/dataset/match_truth.h"
#include "placedb/dataset/tum.h"
#include "placedb/distributed/partition_worker.h"
#include "placedb/distributed/vote_collector.h"
#include "placedb/eval/bench.h"
#include "placedb/eval/evaluate.h"
#include "placedb/eval/experiment.h"
#include "placedb/eval/ground_truth.h"
#include "placedb/eval/metrics.h"
#include "placedb/eval/pictures.h"
#include "placedb/feature/options.h"
#include "placedb/feature/types.h"
#include "placedb/image/crop_options.h"
#include "placedb/image/feature_rich_crop.h"
#include "placedb/match/options.h"
#include "placedb/query/result.h"
#include "placedb/query/sequence.h"
#include "placedb/retrieval/options.h"
#include "placedb/session/place_database.h"
#include "placedb/storage/keyframe.h"
#include "placedb/storage/keyframe_subset.h"
#include "placedb/util/error.h"
#include "placedb/util/option_table.h"
#include "placedb/util/pose.h"
#include "placedb/util/version.h"
