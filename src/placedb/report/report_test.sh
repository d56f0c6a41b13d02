#!/usr/bin/env bash
# The experiment report as a person sees it: a small `placedb experiment` on
# the paper's own sequence (data/tum_fr3_office_32: database = the first 16
# frames, queries = the 16 after, truth from the poses), its report.html
# opened in headless Chromium by check_report.py (loads, no console error,
# nothing fetched from a network, every figure present with a non-zero size),
# a screenshot saved in OUT; then resuming, and the report script's answer to
# a damaged results.json.
#   report_test.sh PLACEDB DATA_DIR OUT PYTHON
set -euo pipefail
PLACEDB=$1 DATA=$2 OUT=$3 PYTHON=$4
HERE=$(cd "$(dirname "$0")" && pwd)
rm -rf "$OUT/experiment"
mkdir -p "$OUT"
fail() { echo "report_test: FAIL: $*" >&2; exit 1; }

args=(experiment --tum "$DATA/tum_fr3_office_32" --db-first 1 --db-last 16 --first 17
      --features orb --crop none,chroma --resize 1,4 --verification on,off --all
      --pictures 2 --failures 4 --out "$OUT/experiment" --quiet)
"$PLACEDB" "${args[@]}" > "$OUT/experiment.log"
cat "$OUT/experiment.log"
grep -q "8 settings (0 finished earlier)" "$OUT/experiment.log" || fail "first run"
[[ -s "$OUT/experiment/report.html" ]] || fail "no report.html"

# Generous limits (a busy machine starts Chromium slowly): they only end a hang.
"$PYTHON" "$HERE/check_report.py" "$OUT/experiment/report.html" \
  --startup-timeout 120 --timeout 120 --answer-timeout 120 \
  --screenshot "$OUT/report_screenshot.png" --min-figures 11 \
  --expect fig-time --expect fig-correct --expect fig-size --expect fig-recall-at-k \
  --expect fig-pr --expect fig-latency --expect fig-stages --expect fig-failures \
  --expect fig-crop-1
echo "report_test: screenshot $OUT/report_screenshot.png"

# Resumed with the same arguments: nothing is redone.
"$PLACEDB" "${args[@]}" > "$OUT/experiment2.log"
grep -q "8 settings (8 finished earlier)" "$OUT/experiment2.log" || fail "resume"
# Other arguments: refused with one line, exit code 1.
set +e
"$PLACEDB" "${args[@]}" --seed 9 > /dev/null 2> "$OUT/refused.log"
code=$?
set -e
[[ $code == 1 ]] || fail "other arguments: exit code $code"
grep -q "differ in 'eval'" "$OUT/refused.log" || fail "other arguments: $(cat "$OUT/refused.log")"

# A damaged results.json: one clear line, exit code 1, no report.
mkdir -p "$OUT/damaged"
echo '{"settings": [{"setting": 3}]}' > "$OUT/damaged/results.json"
set +e
"$PYTHON" "$HERE/make_report.py" "$OUT/damaged" 2> "$OUT/damaged.log"
code=$?
set -e
[[ $code == 1 && ! -e "$OUT/damaged/report.html" ]] || fail "damaged results: exit code $code"
[[ $(wc -l < "$OUT/damaged.log") == 1 ]] || fail "damaged results: $(cat "$OUT/damaged.log")"
echo "report_test: PASS"
