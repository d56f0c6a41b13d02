#!/usr/bin/env bash
# The main job on the sample data shipped in data/: the paper's pipeline on
# the RTAB-Map loop sequence (database = images 1-40, queries = 41-84, ground
# truth from data/rtabmap_loop/ground_truth.csv), verification with and
# without, small cameras, the paper's experiment grid (feature x crop x
# resize) as a table, then the speed benchmark. Every number is measured by
# this run, with the build in BUILD_DIR.
set -euo pipefail
BUILD_DIR=${1:-build}
PLACEDB="$BUILD_DIR/src/placedb/exe/placedb"
DATA=data/rtabmap_loop
TRUTH="$DATA/ground_truth.csv"
OUT=out/demo
mkdir -p "$OUT"

# One row of a table from an eval JSON: label columns, then the numbers.
row() {
  python3 - "$@" <<'PY'
import json, sys
e = json.load(open(sys.argv[1]))
pr = e["precision_recall"]
labels = sys.argv[2:]
print(" ".join(f"{l:<9}" for l in labels) +
      f" {e['recall_at_1']:8.3f} {e['recall_at_5']:8.3f} {pr['at_threshold']['precision']:9.3f}"
      f" {pr['at_threshold']['recall']:8.3f} {pr['average_precision']:7.3f}"
      f" {pr['recall_at_full_precision']:8.3f} {e['latency_ms']['mean']:9.2f}")
PY
}
header() {
  local labels=""
  for l in "$@"; do labels+=$(printf '%-9s ' "$l"); done
  printf '%s%8s %8s %9s %8s %7s %8s %9s\n' "$labels" "R@1" "R@5" "precision" "recall" "PR-AUC" "R@P=1" "ms/query"
}

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
  --truth "$TRUTH" --all --quiet --json "$OUT/eval_orb_chroma.json"

echo
echo "== 5. geometric verification, with and without (ORB, no crop, all 44 queries 41-84)"
echo "   database 1-40: every query revisits a place in it; database 1-20: 18 of the 44"
echo "   queries (63-80) show places it does not hold, and the right answer is 'no match'."
echo "   precision and recall at the default decision threshold (--min-score 12)."
header database verify
for last in 40 20; do
  db="$OUT/db_orb_1_$last"
  "$PLACEDB" build --images "$DATA/images" --last "$last" --out "$db" --overwrite --quiet \
    >/dev/null 2>&1
  for verify in --no-verify --verify; do
    "$PLACEDB" eval --db "$db" --images "$DATA/images" --first 41 --truth "$TRUTH" --all --quiet \
      "$verify" --json "$db$verify.json" >/dev/null 2>&1
    row "$db$verify.json" "1-$last" "${verify#--}"
  done
done

echo
echo "== 6. small cameras: the 512x384 frames resized to 160x120 and 320x240 as they are read"
echo "   (database 1-40, queries 41-84); frames below 240 px are upscaled for extraction"
printf '%-9s %-9s %13s %8s %9s\n' frame upscale "features/kf" "R@1" "ms/query"
for size in 160x120 320x240 512x384; do
  for upscale in 240 0; do
    [[ $size != 160x120 && $upscale == 0 ]] && continue
    db="$OUT/db_small_${size}_$upscale"
    "$PLACEDB" build --images "$DATA/images" --last 40 --frame-size "$size" --upscale-below "$upscale" \
      --out "$db" --overwrite --quiet --json "$db.build.json" >/dev/null 2>&1
    "$PLACEDB" eval --db "$db" --images "$DATA/images" --first 41 --frame-size "$size" \
      --truth "$TRUTH" --all --quiet --json "$db.eval.json" >/dev/null 2>&1
    python3 - "$db.build.json" "$db.eval.json" "$size" "$upscale" <<'PY'
import json, sys
b, e = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
up = "no" if sys.argv[4] == "0" else "to " + sys.argv[4]
print(f"{sys.argv[3]:<9} {up:<9} {b['num_features'] / b['num_keyframes']:13.1f}"
      f" {e['recall_at_1']:8.3f} {e['latency_ms']['mean']:9.2f}")
PY
  done
done

echo
echo "== 7. the paper's experiment grid on this split (all 44 queries, verified)"
printf '%-7s %-7s %-7s %9s %9s %9s %10s %12s %10s\n' feature crop resize recall@1 recall@5 precision \
  "ms/query" "images (B)" reduction
for feature in orb surf; do
  for crop in none chroma; do
    for resize in 1 4 16; do
      db="$OUT/db_${feature}_${crop}_${resize}"
      "$PLACEDB" build --images "$DATA/images" --first 1 --last 40 --features "$feature" \
        --crop "$crop" --resize "$resize" --out "$db" --overwrite --quiet >/dev/null 2>&1
      "$PLACEDB" eval --db "$db" --images "$DATA/images" --first 41 --last 84 \
        --truth "$TRUTH" --all --quiet --json "$db.eval.json" >/dev/null 2>&1
      python3 - "$db.eval.json" "$feature" "$crop" "1/$resize" <<'PY'
import json, sys
e = json.load(open(sys.argv[1]))
print(f"{sys.argv[2]:<7} {sys.argv[3]:<7} {sys.argv[4]:<7} {e['recall_at_1']:9.3f} "
      f"{e['recall_at_5']:9.3f} {e['precision_recall']['at_threshold']['precision']:9.3f} "
      f"{e['latency_ms']['mean']:10.2f} {e['database_bytes']['images']:12d} "
      f"{100*e['reduction_vs_full']:9.1f}%")
PY
    done
  done
done

echo
echo "== 8. matching speed: placedb vs the paper's OpenCV BFMatcher loop"
"$PLACEDB" bench --db "$OUT/db_orb_none_1" --images "$DATA/images" --first 41 --last 84 \
  --queries 0 --repeat 3 --json "$OUT/bench.json"
echo
echo "demo outputs in $OUT/"
