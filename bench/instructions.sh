#!/usr/bin/env bash
# bench/instructions.sh — `make bench-instructions`: instruction counts
# (valgrind --tool=callgrind, the instrumented region only) of one run of
# each operation: W1, W2, W3 of bench/bench.cpp (ours) and pairs, churn of
# bench/instructions.cpp, at width 3 (the course's tree) and at width 8
# (W1@8: bench's method ours-w8; pairs8, churn8). Counts repeat exactly for the same binaries and
# inputs, whatever else the machine runs, so two versions of bvh.h compare
# here where wall-clock times on a shared machine cannot.
# Usage: bench/instructions.sh BUILD [WORKLOAD...]   (default: all ten)
set -eu
cd "$(dirname "$0")/.."
build=$1
shift
workloads=${*:-W1 W2 W3 pairs churn W1@8 W2@8 W3@8 pairs8 churn8}
command -v valgrind >/dev/null 2>&1 || { echo "skipped: valgrind is not installed (apt-get install valgrind)"; exit 0; }
printf '%-8s %16s  %s\n' workload instructions result
for w in $workloads; do
  out=$build/callgrind.$w
  case $w in
    W*@8) valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file="$out" "$build/bench" --only "${w%@8}" --method ours-w8 >"$out.log" 2>&1 ;;
    W*) valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file="$out" "$build/bench" --only "$w" --method ours >"$out.log" 2>&1 ;;
    *) valgrind --tool=callgrind --instr-atstart=no --callgrind-out-file="$out" "$build/instructions" "$w" >"$out.log" 2>&1 ;;
  esac
  count=$(sed -n 's/.*Collected : *//p' "$out.log")
  result=$(grep -E '^(pairs|churn):|^bench: .* run 1/1' "$out.log" | tail -n 1 | sed 's/^bench: //')
  printf '%-8s %16s  %s\n' "$w" "$count" "$result"
done
