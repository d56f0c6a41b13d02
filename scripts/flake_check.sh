#!/usr/bin/env bash
# Runs every test of a build tree 5 times, each round beside two CPU-burning
# processes (a busy machine, as CI is), and reports each round; exits 0 only
# when all 5 rounds passed.
#
#   scripts/flake_check.sh [BUILD_DIR] [CTEST ARGS...]
#
# BUILD_DIR defaults to build (relative to the current folder, else to the
# repository). Extra arguments go to ctest, e.g. `-R ros_` for some tests;
# ctest runs with -j2 unless they set -j/--parallel. Each round's output is
# kept in BUILD_DIR/flake_check/round_N.log.
set -uo pipefail

ROUNDS=5
root=$(cd "$(dirname "$0")/.." && pwd)
build=build
if [[ $# -gt 0 && $1 != -* ]]; then
  build=$1
  shift
fi
if [[ ! -d $build && -d $root/$build ]]; then
  build=$root/$build
fi
if [[ ! -f $build/CTestTestfile.cmake ]]; then
  echo "flake_check: $build is not a configured build tree (no CTestTestfile.cmake);" \
       "build it first (make test, or cmake --build)" >&2
  exit 2
fi
build=$(cd "$build" && pwd)

ctest_args=("$@")
parallel=(-j2)
for a in "$@"; do
  case $a in
    -j* | --parallel | --parallel=*) parallel=() ;;
  esac
done

logs=$build/flake_check
mkdir -p "$logs"

burners=()
stop_burners() {
  local pid
  for pid in "${burners[@]}"; do
    kill "$pid" 2> /dev/null
  done
  for pid in "${burners[@]}"; do
    wait "$pid" 2> /dev/null
  done
  burners=()
}
trap stop_burners EXIT
trap 'stop_burners; exit 130' INT
trap 'stop_burners; exit 143' TERM
for _ in 1 2; do
  sh -c 'while :; do :; done' &
  burners+=($!)
done
echo "flake_check: $ROUNDS rounds of ctest ${parallel[*]} ${ctest_args[*]} in $build," \
     "beside 2 CPU burners (PIDs ${burners[*]})"

passed=0
for round in $(seq 1 $ROUNDS); do
  log=$logs/round_$round.log
  start=$(date +%s)
  (cd "$build" && ctest "${parallel[@]}" --no-tests=error --output-on-failure "${ctest_args[@]}") \
    > "$log" 2>&1
  code=$?
  secs=$(($(date +%s) - start))
  summary=$(grep -E "tests passed, [0-9]+ tests failed" "$log" | tail -n 1)
  if [[ $code == 0 ]]; then
    passed=$((passed + 1))
    echo "round $round/$ROUNDS: PASS in ${secs}s (${summary:-ctest exit 0})"
  else
    echo "round $round/$ROUNDS: FAIL in ${secs}s (${summary:-ctest exit $code}), log $log"
    # ctest's list of the failed tests, indented.
    sed -n '/The following tests FAILED:/,$p' "$log" | sed -n '2,$p' | grep -E '^\s+[0-9]+ - ' |
      sed 's/^\s*/    /'
  fi
done
stop_burners
echo "flake_check: $passed/$ROUNDS rounds passed"
[[ $passed == "$ROUNDS" ]]
