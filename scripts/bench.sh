#!/usr/bin/env bash
# Benchmarks of the build in BUILD_DIR (the default Release build for
# `make bench`), each reporting ours next to a baseline measured in the same
# run, and then the README's speed tables rewritten from this run:
#   match_bench   matching kernels vs OpenCV BFMatcher (Google Benchmark)
#   surf_bench    our SURF (dispatched and plain) vs OpenCV SIFT and ORB
#   sequence_bench the sequence step over the whole map vs over ranked lists,
#                 and the HOG rows' comparison, at 10k and 100k keyframes
#   placedb bench whole match stages vs the paper's BFMatcher loop
#   ros_bench     the ROS nodes end to end vs the single-process query
#   scale_bench   1k / 10k / 100k augmented keyframes: latency, memory, size,
#                 open time of exhaustive, BoW and cluster search
set -euo pipefail
BUILD_DIR=${1:-build}
PLACEDB="$BUILD_DIR/src/placedb/exe/placedb"
OUT=out/bench
mkdir -p "$OUT"
"$BUILD_DIR/bench/match_bench" --benchmark_out="$OUT/match_bench.json" --benchmark_out_format=json
"$BUILD_DIR/bench/surf_bench" --benchmark_out="$OUT/surf_bench.json" --benchmark_out_format=json
"$BUILD_DIR/bench/sequence_bench" --benchmark_out="$OUT/sequence_bench.json" \
  --benchmark_out_format=json
"$PLACEDB" build --images data/rtabmap_loop/images --last 40 --out "$OUT/db_orb" --overwrite --quiet
"$PLACEDB" bench --db "$OUT/db_orb" --images data/rtabmap_loop/images --first 41 --queries 0 \
  --repeat 5 --json "$OUT/placedb_bench_orb.json"
"$PLACEDB" build --images data/rtabmap_loop/images --last 40 --features surf --out "$OUT/db_surf" \
  --overwrite --quiet
"$PLACEDB" bench --db "$OUT/db_surf" --images data/rtabmap_loop/images --first 41 --queries 0 \
  --repeat 3 --json "$OUT/placedb_bench_surf.json"
# The ROS system end to end (built with ROS): 1, 2 and 4 workers.
if [[ -x "$BUILD_DIR/bench/ros_bench" ]]; then
  "$BUILD_DIR/bench/ros_bench" --out "$OUT/ros" --json "$OUT/ros_bench.json"
fi
# Scale: databases of 1k, 10k and 100k keyframes (reused from an earlier run
# with the same settings).
"$BUILD_DIR/bench/scale_bench" --out "$OUT/scale" --json "$OUT/scale_bench.json"
python3 scripts/readme_tables.py "$OUT" README.md
