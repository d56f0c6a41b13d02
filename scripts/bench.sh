#!/usr/bin/env bash
# Benchmarks, each reporting ours next to a baseline measured in the same run:
#   match_bench   matching kernels vs OpenCV BFMatcher (Google Benchmark)
#   surf_bench    our SURF vs OpenCV SIFT and ORB (Google Benchmark)
#   placedb bench whole queries vs the paper's BFMatcher loop
set -euo pipefail
BUILD_DIR=${1:-build}
PLACEDB="$BUILD_DIR/src/placedb/exe/placedb"
OUT=out/bench
mkdir -p "$OUT"
"$BUILD_DIR/bench/match_bench" --benchmark_out="$OUT/match_bench.json" --benchmark_out_format=json
"$BUILD_DIR/bench/surf_bench" --benchmark_out="$OUT/surf_bench.json" --benchmark_out_format=json
# Ratios from this one run (the machine is shared: only ratios are comparable).
python3 - "$OUT/surf_bench.json" <<'PY'
import json, sys
runs = {b["name"]: b["real_time"] for b in json.load(open(sys.argv[1]))["benchmarks"]}
for i, name in ((0, "640x480 TUM frame"), (1, "graf1 800x640")):
    surf, sift, orb = runs[f"BM_Surf/{i}"], runs[f"BM_Sift/{i}"], runs[f"BM_Orb/{i}"]
    print(f"{name:20s} SURF {surf:7.1f} ms  SIFT {sift:7.1f} ms  ORB {orb:6.1f} ms  "
          f"SURF/SIFT {surf / sift:.2f}  SURF/ORB {surf / orb:.2f}")
PY
"$PLACEDB" build --images data/rtabmap_loop/images --last 40 --out "$OUT/db_orb" --overwrite --quiet
"$PLACEDB" bench --db "$OUT/db_orb" --images data/rtabmap_loop/images --first 41 --queries 0 \
  --repeat 5 --json "$OUT/placedb_bench_orb.json"
"$PLACEDB" build --images data/rtabmap_loop/images --last 40 --features surf --out "$OUT/db_surf" \
  --overwrite --quiet
"$PLACEDB" bench --db "$OUT/db_surf" --images data/rtabmap_loop/images --first 41 --queries 0 \
  --repeat 3 --json "$OUT/placedb_bench_surf.json"
