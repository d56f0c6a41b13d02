#!/usr/bin/env bash
# The main job on the sample data shipped in data/: the paper's pipeline on
# the RTAB-Map loop sequence (database = images 1-40, queries = 41-84, ground
# truth from data/rtabmap_loop/ground_truth.csv), then the paper's experiment
# grid (feature x crop x resize) as a table, then the speed benchmark.
set -euo pipefail
BUILD_DIR=${1:-build}
PLACEDB="$BUILD_DIR/src/placedb/exe/placedb"
DATA=data/rtabmap_loop
OUT=out/demo
mkdir -p "$OUT"

echo "== 1. build a database of images 1-40 with the paper's feature-rich crop"
"$PLACEDB" build --images "$DATA/images" --first 1 --last 40 --crop chroma \
  --out "$OUT/db_orb_chroma" --overwrite --quiet

echo
echo "== 2. what is in it"
"$PLACEDB" info --db "$OUT/db_orb_chroma"

echo
echo "== 3. where was image 042.jpg taken?"
"$PLACEDB" query --db "$OUT/db_orb_chroma" --image "$DATA/images/042.jpg" --top-k 3

echo
echo "== 4. evaluate all 44 queries (41-84) against the ground truth"
"$PLACEDB" eval --db "$OUT/db_orb_chroma" --images "$DATA/images" --first 41 --last 84 \
  --truth "$DATA/ground_truth.csv" --all --quiet --json "$OUT/eval_orb_chroma.json"

echo
echo "== 5. the paper's experiment grid on this split (all 44 queries)"
printf '%-5s %-7s %-7s %9s %9s %10s %12s %10s\n' feature crop resize recall@1 recall@5 "ms/query" "images (B)" reduction
for feature in orb surf; do
  for crop in none chroma; do
    for resize in 1 4 16; do
      db="$OUT/db_${feature}_${crop}_${resize}"
      "$PLACEDB" build --images "$DATA/images" --first 1 --last 40 --features "$feature" \
        --crop "$crop" --resize "$resize" --out "$db" --overwrite --quiet >/dev/null 2>&1
      "$PLACEDB" eval --db "$db" --images "$DATA/images" --first 41 --last 84 \
        --truth "$DATA/ground_truth.csv" --all --quiet --json "$db.eval.json" >/dev/null 2>&1
      python3 - "$db.eval.json" "$feature" "$crop" "1/$resize" <<'PY'
import json, sys
e = json.load(open(sys.argv[1]))
print(f"{sys.argv[2]:<7} {sys.argv[3]:<7} {sys.argv[4]:<7} {e['recall_at_1']:9.3f} "
      f"{e['recall_at_5']:9.3f} {e['latency_ms']['mean']:10.2f} "
      f"{e['database_bytes']['images']:12d} {100*e['reduction_vs_full']:9.1f}%")
PY
    done
  done
done

echo
echo "== 6. matching speed: placedb vs the paper's OpenCV BFMatcher loop"
"$PLACEDB" bench --db "$OUT/db_orb_none_1" --images "$DATA/images" --first 41 --last 84 \
  --queries 0 --repeat 3 --json "$OUT/bench.json"
echo
echo "demo outputs in $OUT/"
