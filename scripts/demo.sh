#!/usr/bin/env bash
# The main job on the sample data shipped in data/: the paper's pipeline on
# the RTAB-Map loop sequence (database = images 1-40, queries = 41-84, ground
# truth from data/rtabmap_loop/ground_truth.csv), verification with and
# without, small cameras, hard places (tiny frames, sequence evidence, the
# whole-image channel: README.md's table), the speed benchmark, and last the paper's
# experiments as one command (placedb experiment: feature x crop x resize x
# verification) with its report, out/demo/experiment/report.html, and the
# database with poses the README's ROS section runs on. Every
# number is measured by this run, with the build in BUILD_DIR.
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
echo "== 7. hard places: tiny frames, sequence evidence and the whole-image channel (database 1-40,"
echo "   queries 41-84 in order, each frame size for both). The defaults are chosen from this table;"
echo "   it is written into README.md (\"Hard places\")."
HARD="$OUT/hard_places"
mkdir -p "$HARD"
SIZES="40x30 64x48 80x60 160x120 512x384"
echo "$SIZES" > "$HARD/sizes.txt"
for size in $SIZES; do
  db="$HARD/db_$size"
  evalq() {
    "$PLACEDB" eval --db "$1" --images "$DATA/images" --first 41 --frame-size "$size" \
      --truth "$TRUTH" --all --quiet --sequence "${@:3}" --json "$2" >/dev/null 2>&1
  }
  "$PLACEDB" build --images "$DATA/images" --last 40 --frame-size "$size" --out "$db" \
    --overwrite --quiet >/dev/null 2>&1
  evalq "$db" "$HARD/$size.json"
  evalq "$db" "$HARD/$size.len5.json" --sequence-length 5
  evalq "$db" "$HARD/$size.local.json" --whole-image-weight 0 --whole-image-candidates 0 \
    --sequence-whole-image-weight 0
  "$PLACEDB" build --images "$DATA/images" --last 40 --frame-size "$size" --out "$db.fast20" \
    --upscaled-fast-threshold 0 --overwrite --quiet >/dev/null 2>&1
  evalq "$db.fast20" "$HARD/$size.fast20.json"
done

echo
echo "== 7b. places that change: the whole-image channels and the sequence over the whole map, alone and"
echo "   together, on the Nordland slice (64x32: 400 summer keyframes, the 400 winter frames as queries)"
echo "   and on the loop (database 1-40, queries 41-84), beside the classic HOG and SeqSLAM on the same"
echo "   frames (eval --baseline both); written into README.md (\"Places that change\")."
CHANGE="$OUT/places_that_change"
mkdir -p "$CHANGE"
NORD=data/nordland64_slice
for name in nordland rtabmap; do
  if [[ $name == nordland ]]; then
    map=(--images "$NORD/summer"); queries=(--images "$NORD/winter" --truth "$NORD/ground_truth.csv")
  else
    map=(--images "$DATA/images" --last 40); queries=(--images "$DATA/images" --first 41 --truth "$TRUTH")
  fi
  for kind in thumbnail hog; do
    "$PLACEDB" build "${map[@]}" --whole-image-kind "$kind" --out "$CHANGE/db_${name}_$kind" \
      --overwrite --quiet >/dev/null 2>&1
  done
  "$PLACEDB" build "${map[@]}" --clahe true --out "$CHANGE/db_${name}_clahe" --overwrite --quiet \
    >/dev/null 2>&1
  change() {
    "$PLACEDB" eval --db "$CHANGE/db_${name}_$1" "${queries[@]}" --all --quiet --sequence "${@:3}" \
      --json "$CHANGE/$name.$2.json" >/dev/null 2>&1
  }
  change hog default --baseline both
  change hog local --whole-image-weight 0 --whole-image-candidates 0 --sequence-whole-image-weight 0
  change hog whole --whole-image-weight 1000 --whole-image-floor 0
  change hog lists --sequence-whole-image-weight 0
  change thumbnail thumb
  change hog velocities --sequence-min-velocity 0.8 --sequence-max-velocity 1.2 --sequence-velocity-steps 5
  change clahe clahe
done
python3 scripts/hard_places.py "$HARD" --change "$CHANGE" --readme README.md

echo
echo "== 8. matching speed: placedb vs the paper's OpenCV BFMatcher loop"
"$PLACEDB" bench --db "$OUT/db_orb_1_40" --images "$DATA/images" --first 41 --last 84 \
  --queries 0 --repeat 3 --json "$OUT/bench.json"
echo
echo "== 9. the same library from Python: import placedb (built in $BUILD_DIR/python)"
PYTHONPATH="$BUILD_DIR/python" /usr/bin/python3 - "$OUT/db_orb_chroma" "$DATA" <<'PY'
import sys
import placedb
db = placedb.PlaceDatabase(sys.argv[1])
image = placedb.read_image(sys.argv[2] + "/images/042.jpg")  # a NumPy BGR array
r = db.query(image, top_k=3)
print(r)
print("ranked:", [(k.keyframe_id, k.num_inliers) for k in r.ranked])
e = placedb.evaluate(db, images=sys.argv[2] + "/images", first=41,
                     truth=sys.argv[2] + "/ground_truth.csv", all=True)
print(f"evaluate: {e['num_correct']} of {e['num_queries']} correct, recall@1 {e['recall_at_1']:.3f}")
PY

echo
echo "== 10. the paper's experiments: feature x crop x resize, verification on and off (all 44 queries)"
echo "   one command builds the 12 databases, evaluates the 24 settings and writes the report"
"$PLACEDB" experiment --images "$DATA/images" --db-first 1 --db-last 40 --first 41 --last 84 \
  --truth "$TRUTH" --all --seed 1 --out "$OUT/experiment" --overwrite --quiet > "$OUT/experiment.log"
python3 - "$OUT/experiment/results.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
print(f"{'feature':<7} {'crop':<7} {'resize':<6} {'verify':<6} {'correct':>7} {'R@1':>6} {'R@5':>6} "
      f"{'prec.':>6} {'PR-AUC':>6} {'ms/query':>8} {'images (B)':>11} {'reduction':>9}")
for s in r["settings"]:
    st, e = s["setting"], s["eval"]
    pr = e["precision_recall"]
    print(f"{st['features']:<7} {st['crop']:<7} {'1/' + str(st['resize']):<6} "
          f"{'on' if st['verify'] else 'off':<6} {e['num_correct']:>4}/{e['num_queries']:<2} "
          f"{e['recall_at_1']:6.3f} {e['recall_at_5']:6.3f} {pr['at_threshold']['precision']:6.3f} "
          f"{pr['average_precision']:6.3f} {e['latency_ms']['mean']:8.2f} "
          f"{e['database_bytes']['images']:11d} {100 * e['reduction_vs_full']:8.1f}%")
p = r["pictures"]
print(f"pictures: {len(p['matches'])} match pictures, {len(p['crops'])} crop illustrations, "
      f"{len(p['failures'])} failed queries of {p['failure_setting']}")
PY
tail -n 3 "$OUT/experiment.log"
# The report as a browser shows it (headless Chromium; the top 2400 px).
/usr/bin/python3 src/placedb/report/check_report.py "$OUT/experiment/report.html" --min-figures 10 \
  --max-height 2400 --screenshot "$OUT/experiment/screenshot.png" | tail -n 2
echo
echo "== 11. a database with poses for the ROS nodes (README, \"On ROS\"): the TUM sequence"
"$PLACEDB" build --tum data/tum_fr3_office_32 --out "$OUT/db_tum_office" --overwrite --quiet
echo
echo "demo outputs in $OUT/"
echo "the report: $OUT/experiment/report.html"
