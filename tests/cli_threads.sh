#!/usr/bin/env bash
# tests/cli_threads.sh DIR [BINARY [COURSE_DATA]] — bvh.out --threads N:
# discard-overlap sampling (insert_disjoint) and the bulk build print the
# same stdout and write the same picture, byte for byte, for N = 1 (the
# plain loop), 2, 3 and 8, on the course's overlap_* scenes, on inputs/ and
# on a generated 300k-disk scene (several insert_disjoint calls, batches of
# every size). Prints `ok NAME` or `FAIL NAME why` per case.
set -u
cd "$(dirname "$0")/.."
dir=${1:-build/test-out/cli_threads}
bin=${2:-./bvh.out}
course=${3:-../shared/course}
rm -rf "$dir"
mkdir -p "$dir"

# same_for_all_threads NAME ARGS...: runs ARGS with each --threads N and
# compares the outputs with N = 1's.
same_for_all_threads() {
  local name=$1 n why=
  shift
  for n in 1 2 3 8; do
    if ! "$bin" "$@" -o "$dir/$name.$n.html" --threads "$n" >"$dir/$name.$n.txt" 2>"$dir/$name.$n.err"; then
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
  same_for_all_threads bulk_generated_300k_disks -i "$dir/big.disks" --depth_limit 12 --visualize
else
  echo "FAIL cli_threads_generate $(head -c 200 "$dir/big.err")"
fi
