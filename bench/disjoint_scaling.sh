#!/usr/bin/env bash
# bench/disjoint_scaling.sh — `make bench-disjoint`: how far insert_disjoint
# would scale past this machine's cores. Runs build/bench on W1 and W2 at 1M
# candidates (ours, ours-par, ours-par1) and on W2 at BIG candidates (ours,
# ours-par, boost-quad16, grid), writes each command's raw stdout and stderr
# to bench/results_disjoint_scaling.txt, and appends the summary of
# bench/disjoint_scaling.py: the serial fraction of the work from the
# disjoint-profile lines, Amdahl's predicted speed-ups for 1-64 cores, the
# speed-up measured here and the BIG point against Boost. Draws
# docs/disjoint_speedup.svg from the same file.
#
# Usage: bench/disjoint_scaling.sh [BUILD]     (default build; needs
#        BUILD/bench and ./bvh.out: make bvh.out BUILD/bench)
#   RUNS=5 BIG_RUNS=3 BIG=10000000 bench/disjoint_scaling.sh
#   nice -n 10 make bench-disjoint RUNS=3 BIG_RUNS=1
# On a shared machine run it under nice and alone: the parallel runs
# measure what the other processes leave of the cores.
set -eu
cd "$(dirname "$0")/.."
build=${1:-build}
runs=${RUNS:-5}
big_runs=${BIG_RUNS:-3}
big=${BIG:-10000000}
out=bench/results_disjoint_scaling.txt
svg=docs/disjoint_speedup.svg
for f in "$build/bench" ./bvh.out; do
  [ -x "$f" ] || { echo "disjoint_scaling: $f is missing (make bvh.out $build/bench)" >&2; exit 1; }
done

# The bench's own table cannot give a run's peak RSS with --only (it runs
# in-process), so the command's largest process is measured from outside.
measure='import resource, subprocess, sys, time
t = time.time()
rc = subprocess.call(sys.argv[1:], stderr=subprocess.STDOUT)
print("disjoint_scaling: %.1f s wall, peak RSS %.0f MB (largest process of the command), exit status %d"
      % (time.time() - t, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0, rc))
sys.exit(rc)'

start=$(date +%s)
tmp=$out.tmp
{
  echo "bench/results_disjoint_scaling.txt — written by bench/disjoint_scaling.sh (make bench-disjoint):"
  echo "insert_disjoint's serial fraction and Amdahl's predicted speed-ups. Raw stdout and stderr of each"
  echo "command below, headed by the command and uptime; the summary of bench/disjoint_scaling.py at the end."
  echo "git HEAD $(git rev-parse --short HEAD 2>/dev/null || echo none); $(date -u '+%Y-%m-%d %H:%M UTC'); $(nproc) cores"
  echo
} >"$tmp"

run() {
  echo "disjoint_scaling: $*" >&2
  { echo "### $*"; uptime; } >>"$tmp"
  rc=0
  python3 -c "$measure" "$@" >>"$tmp" 2>&1 || rc=$?
  echo >>"$tmp"
  grep '^disjoint_scaling: ' "$tmp" | tail -n 1 >&2
  [ "$rc" = 0 ] || { echo "disjoint_scaling: failed (exit status $rc); the raw output is in $tmp" >&2; exit 1; }
}

run "$build/bench" --only W1 --method ours,ours-par,ours-par1 --runs "$runs"
run "$build/bench" --only W2 --method ours,ours-par,ours-par1 --runs "$runs"
run "$build/bench" --only W2 --big "$big" --method ours,ours-par,boost-quad16,grid --runs "$big_runs"

{
  echo "### summary"
  uptime
  python3 bench/disjoint_scaling.py summary "$tmp"
  echo
  echo "disjoint_scaling: total $(($(date +%s) - start)) s"
} >"$out.summary"
cat "$out.summary" >>"$tmp"
mv "$tmp" "$out"
python3 bench/disjoint_scaling.py chart "$out" "$svg"
sed '1d' "$out.summary"
rm -f "$out.summary"
echo "disjoint_scaling: wrote $out and $svg"
