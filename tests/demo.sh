#!/usr/bin/env bash
# tests/demo.sh — `make demo`: the handout's command lines, run on the
# course's own scenes when COURSE_DATA (default ../shared/course) holds them,
# otherwise on our generated scenes inputs/gen_* (and it says so).
#
# The two streams are kept apart, so that stdout is exactly what the
# handout's commands print, byte for byte, and nothing else:
#   stdout  the concatenated stdout of the commands (what the course grades);
#   stderr  our own lines: a "$ ./bvh.out ..." header before each command,
#           its time, the notices and the final verdict.
# On a terminal both show, interleaved in order. `make demo 2>/dev/null`
# (or `bash tests/demo.sh 2>/dev/null`) leaves the commands' stdout alone.
# Each command's stdout is also saved as demo/NAME.txt, its picture as
# demo/NAME.html. The handout's --print_tree example is saved as
# $DEMO_DIR/36_triangles_2_stdout.txt and compared with the course's published
# 36_triangles_2_stdout.txt: the demo exits 1 if one byte differs.
set -eu
cd "$(dirname "$0")/.."
COURSE_DATA=${COURSE_DATA:-../shared/course}
BIN=${BIN:-./bvh.out}
DEMO_DIR=${DEMO_DIR:-demo} # where the pictures and NAME.txt files go
note() { printf '%s\n' "$*" >&2; }

if [ -f "$COURSE_DATA/36.triangles" ] && [ -f "$COURSE_DATA/overlap_1000.disks" ]; then
  mode=course
  data=$COURSE_DATA
  prefix=
  note "demo: the handout's commands on the course's own scenes in COURSE_DATA=$COURSE_DATA"
  note "demo: stdout is the commands' output only; these notes and the \$ lines are on stderr"
else
  mode=ours
  data=inputs
  prefix=gen_
  note "demo: NOTE: no course data at COURSE_DATA=$COURSE_DATA (make demo COURSE_DATA=/path/to/course)."
  note "demo: NOTE: running the handout's commands on OUR OWN generated scenes inputs/gen_*."
  note "demo: NOTE: these are different shapes from the course's files: the numbers will NOT match the handout's."
fi
mkdir -p "$DEMO_DIR"

# NAME then the handout's arguments (scene relative to the data folder).
commands="
36_triangles                    -i 36.triangles
36_triangles_1                  -i 36.triangles --depth_limit 1 --visualize
36_triangles_2                  -i 36.triangles --depth_limit 2 --visualize
36_disks                        -i 36.disks
36_disks_1                      -i 36.disks --depth_limit 1 --visualize
36_disks_2                      -i 36.disks --depth_limit 2 --visualize
36_disks_incremental_3          -i 36.disks --depth_limit 3 --incremental --visualize
36_triangles_incremental_3      -i 36.triangles --depth_limit 3 --incremental --visualize
36_quads_incremental_3          -i 36.quads --depth_limit 3 --incremental --visualize
overlap_1000_disks              -i overlap_1000.disks
overlap_1000_triangles          -i overlap_1000.triangles
overlap_1000_quads              -i overlap_1000.quads
discard_overlap_1000_disks      -i overlap_1000.disks --depth_limit 8 --incremental --discard_overlap
discard_overlap_1000_triangles  -i overlap_1000.triangles --depth_limit 8 --incremental --discard_overlap
discard_overlap_1000_quads      -i overlap_1000.quads --depth_limit 8 --incremental --discard_overlap
36_triangles_2_stdout           -i 36.triangles --depth_limit 2 --visualize --print_tree
"
# Our mixed scene (the course has none): only when running on our scenes.
[ "$mode" = ours ] && commands+="mixed_36_2 -i 36.shapes --depth_limit 2 --visualize
"

while read -r name args; do
  [ -z "$name" ] && continue
  # shellcheck disable=SC2086
  set -- $args
  html=$DEMO_DIR/$name.html
  [ "$name" = 36_triangles_2_stdout ] && html=$DEMO_DIR/36_triangles_2.html # the handout writes the same picture
  argv=()
  while [ $# -gt 0 ]; do # the handout's order: -i SCENE -o PICTURE, then the options
    if [ "$1" = -i ]; then argv+=(-i "$data/$prefix$2" -o "$html"); shift 2; else argv+=("$1"); shift; fi
  done
  note "\$ $BIN ${argv[*]}"
  start=$(date +%s%N)
  "$BIN" "${argv[@]}" >"$DEMO_DIR/$name.txt"
  end=$(date +%s%N)
  cat "$DEMO_DIR/$name.txt"
  note "  ($(((end - start) / 1000000)) ms)"
done <<<"$commands"

note "demo: pictures in $DEMO_DIR/*.html (open them in a browser); each command's stdout in $DEMO_DIR/NAME.txt"
if [ "$mode" = course ]; then
  if cmp -s $DEMO_DIR/36_triangles_2_stdout.txt "$COURSE_DATA/36_triangles_2_stdout.txt"; then
    note "demo: $DEMO_DIR/36_triangles_2_stdout.txt is byte-identical to the course's $COURSE_DATA/36_triangles_2_stdout.txt"
  else
    note "demo: FAIL: $DEMO_DIR/36_triangles_2_stdout.txt differs from $COURSE_DATA/36_triangles_2_stdout.txt:"
    diff $DEMO_DIR/36_triangles_2_stdout.txt "$COURSE_DATA/36_triangles_2_stdout.txt" >&2 || true
    exit 1
  fi
else
  note "demo: NOTE: that was on our own scenes inputs/gen_*, not the course's; the handout's numbers are for the course's files."
fi
