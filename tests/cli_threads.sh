#!/usr/bin/env bash
# tests/cli_threads.sh DIR [BINARY [COURSE_DATA]] — bvh.out --threads N:
# discard-overlap sampling (insert_disjoint) and the bulk build print the
# same stdout and write the same picture, byte for byte, for N = 1 (the
# plain loop), 2, 3 and 8, on the course's overlap_* scenes, on inputs/ and
# on a generated 300k-disk scene (several insert_disjoint calls, batches of
# every size); on that scene also that sampling on 2 threads peaks at no
# more than 1.25x the memory of 1 thread (peak RSS, with python3). Prints
# `ok NAME`, `FAIL NAME why` or `skip NAME why` per case.
set -u
cd "$(dirname "$0")/.."
dir=${1:-build/test-out/cli_threads}
bin=${2:-./bvh.out}
course=${3:-../shared/course}
rm -rf "$dir"
mkdir -p "$dir"

# With python3, each run of same_for_all_threads below also writes the
# peak RSS of its process, in kB, to $dir/NAME.N.rss.
measure='import resource, subprocess, sys
rc = subprocess.call(sys.argv[2:])
with open(sys.argv[1], "w") as f:
    f.write("%d\n" % resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
sys.exit(rc)'
measured=()
# (tests/run.sh sets PYTHON: python3 found once, past any version manager's
# shim, whose start costs more than some of these runs)
command -v "${PYTHON:-python3}" >/dev/null 2>&1 && measured=("${PYTHON:-python3}" -S -c "$measure")

# same_for_all_threads NAME ARGS...: runs ARGS with each --threads N and
# compares the outputs with N = 1's.
same_for_all_threads() {
  local name=$1 n why= run
  shift
  for n in 1 2 3 8; do
    run=("$bin")
    [ ${#measured[@]} = 0 ] || run=("${measured[@]}" "$dir/$name.$n.rss" "$bin")
    if ! "${run[@]}" "$@" -o "$dir/$name.$n.html" --threads "$n" >"$dir/$name.$n.txt" 2>"$dir/$name.$n.err"; then
      why="--threads $n failed: $(head -c 200 "$dir/$name.$n.err")"
      break
    fi
    if [ "$n" != 1 ]; then
      cmp -s "$dir/$name.1.txt" "$dir/$name.$n.txt" || why="$why stdout of --threads $n differs: diff $dir/$name.1.txt $dir/$name.$n.txt"
      cmp -s "$dir/$name.1.html" "$dir/$name.$n.html" || why="$why picture of --threads $n differs"
    fi
  done
  if [ -z "$why" ] && ! grep -q "^node count:" "$dir/$name.1.txt"; then why="no statistics in $dir/$name.1.txt"; fi
  if [ -z "$why" ]; then echo "ok cli_threads_$name"; else echo "FAIL cli_threads_$name $why"; fi
}

discard=(--depth_limit 8 --incremental --discard_overlap --print_tree --visualize --pairs)
scenes=(inputs/gen_overlap_*.* inputs/gen_1000.disks inputs/gen_1000.shapes)
if [ -f "$course/overlap_1000.disks" ]; then scenes+=("$course"/overlap_*.*); fi
for scene in "${scenes[@]}"; do
  label=$(basename "$scene" | tr . _)
  [ "$(dirname "$scene")" = inputs ] || label=course_$label
  same_for_all_threads "discard_$label" -i "$scene" "${discard[@]}"
done
same_for_all_threads discard_k2_d3_overlap_1000_quads -i inputs/gen_overlap_1000.quads --split_threshold 2 --depth_limit 3 \
  --incremental --discard_overlap --print_tree --build sah
# Bulk: construct()'s threads (a scene above kParallelMin = 65536 shapes).
if "$bin" --generate disks 300000 --seed 5 --overlap --size 0.3:1.2 -o "$dir/big.disks" 2>"$dir/big.err"; then
  same_for_all_threads discard_generated_300k_disks -i "$dir/big.disks" --depth_limit 12 --incremental --discard_overlap --pairs
  # Sampling on 2 threads (insert_disjoint's lanes) holds at most 1.25x
  # the peak memory of 1 thread: the lanes' reserves of room must not stay
  # resident (MappedAllocator in bvh.h).
  one=$(cat "$dir/discard_generated_300k_disks.1.rss" 2>/dev/null)
  two=$(cat "$dir/discard_generated_300k_disks.2.rss" 2>/dev/null)
  if [ ${#measured[@]} = 0 ]; then
    echo "skip cli_threads_memory_generated_300k_disks python3 is missing (it measures the peak RSS)"
  elif [ -z "$one" ] || [ -z "$two" ]; then
    echo "FAIL cli_threads_memory_generated_300k_disks no peak RSS in $dir/discard_generated_300k_disks.{1,2}.rss"
  elif [ $((4 * two)) -le $((5 * one)) ]; then
    echo "ok cli_threads_memory_generated_300k_disks"
  else
    echo "FAIL cli_threads_memory_generated_300k_disks peak RSS ${two} kB on 2 threads > 1.25 x ${one} kB on 1"
  fi
  same_for_all_threads bulk_generated_300k_disks -i "$dir/big.disks" --depth_limit 12 --visualize
else
  echo "FAIL cli_threads_generate $(head -c 200 "$dir/big.err")"
fi
