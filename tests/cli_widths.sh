#!/usr/bin/env bash
# tests/cli_widths.sh DIR [BINARY] — bvh.out --width W for W = 2, 3, 4, 8
# on every scene kind, bulk (the course's rule and SAH), incremental and
# discard-overlap: tests/check_width.py checks each printed tree and its
# --visualize picture against the rules every width shares (2 to W
# children, and more than 3 somewhere at W > 3; tight boxes; the leaves'
# sizes; the statistics; the colouring, up to W distinct siblings). What
# does not depend on the width must not change with it: the pairs count
# (--pairs) and the shapes --discard_overlap keeps (the loop's result) are
# width 3's, which the golden layer checks. The checker itself must reject
# a tree of the wrong width and a picture with one colour changed.
# Prints `ok NAME` or `FAIL NAME why` per case.
set -u
# (tests/run.sh sets PYTHON: python3 found once, past any version manager's shim)
PYTHON=${PYTHON:-python3}
cd "$(dirname "$0")/.."
dir=${1:-build/test-out/cli_widths}
bin=${2:-./bvh.out}
rm -rf "$dir"
mkdir -p "$dir"

# The picture's shapes, geometry only (--visualize recolours them).
shape_lines() { grep -E '^<(circle|polygon) ' "$1" | grep -v 'fill-opacity' | sed 's/ style=.*//' | sort; }

# check NAME W SHAPES SPLIT DEPTH ARGS...: bvh.out ARGS at width W, then check_width.py.
check() {
  local name=$1 w=$2 shapes=$3 split=$4 depth=$5
  shift 5
  local out=$dir/$name
  if ! "$bin" "$@" --width "$w" --split_threshold "$split" --depth_limit "$depth" --print_tree --visualize \
    -o "$out.html" >"$out.txt" 2>"$out.err"; then
    echo "FAIL cli_width_$name bvh.out failed: $(head -c 200 "$out.err")"
    return 1
  fi
  local why
  if why=$("$PYTHON" -S tests/check_width.py "$w" "$shapes" "$split" "$depth" "$out.txt" "$out.html"); then
    echo "ok cli_width_$name"
  else
    echo "FAIL cli_width_$name $why (see $out.txt)"
    return 1
  fi
}

for kind in disks triangles quads shapes; do
  scene=inputs/gen_1000.$kind
  overlap=inputs/gen_overlap_1000.$kind
  "$bin" -i "$overlap" --no_output --pairs >"$dir/pairs_$kind.3" 2>&1
  "$bin" -i "$overlap" -o "$dir/discard_$kind.3.html" --incremental --discard_overlap >/dev/null 2>&1
  shape_lines "$dir/discard_$kind.3.html" >"$dir/discard_$kind.3.shapes"
  kept=$(wc -l <"$dir/discard_$kind.3.shapes")
  for w in 2 3 4 8; do
    check "${w}_bulk_$kind" "$w" 1000 4 8 -i "$scene"
    check "${w}_incremental_$kind" "$w" 1000 4 10 -i "$scene" --incremental
    check "${w}_discard_$kind" "$w" "$kept" 4 8 -i "$overlap" --incremental --discard_overlap &&
      if shape_lines "$dir/${w}_discard_$kind.html" | cmp -s - "$dir/discard_$kind.3.shapes"; then
        echo "ok cli_width_${w}_discard_keeps_width_3s_shapes_$kind"
      else
        echo "FAIL cli_width_${w}_discard_keeps_width_3s_shapes_$kind the kept shapes differ from width 3's"
      fi
    for how in "" --incremental; do
      "$bin" -i "$overlap" --no_output --pairs --width "$w" $how >"$dir/pairs_$kind.$w$how" 2>&1
      if grep -q '^overlapping pairs: [0-9]' "$dir/pairs_$kind.3" && cmp -s "$dir/pairs_$kind.3" "$dir/pairs_$kind.$w$how"; then
        echo "ok cli_width_${w}_pairs${how/--/_}_$kind"
      else
        echo "FAIL cli_width_${w}_pairs${how/--/_}_$kind $(cat "$dir/pairs_$kind.$w$how"), width 3 bulk: $(cat "$dir/pairs_$kind.3")"
      fi
    done
  done
done
for w in 2 4 8; do
  check "${w}_sah_triangles" "$w" 1000 4 8 -i inputs/gen_1000.triangles --build sah
  check "${w}_shallow_limit_disks" "$w" 1000 4 2 -i inputs/gen_1000.disks
done

# The checker can fail: width 8's tree is not width 4's, and one box
# recoloured is seen.
if "$PYTHON" -S tests/check_width.py 4 1000 4 8 "$dir/8_bulk_disks.txt" >/dev/null; then
  echo "FAIL cli_width_checker_rejects_a_wider_tree check_width.py accepted width 8's tree as width 4's"
else
  echo "ok cli_width_checker_rejects_a_wider_tree"
fi
sed '0,/fill:#ff0000;fill-opacity:0.25;stroke:#ff0000/s//fill:#00ff00;fill-opacity:0.25;stroke:#00ff00/' \
  "$dir/8_bulk_disks.html" >"$dir/recoloured.html"
if "$PYTHON" -S tests/check_width.py 8 1000 4 8 "$dir/8_bulk_disks.txt" "$dir/recoloured.html" >/dev/null; then
  echo "FAIL cli_width_checker_rejects_a_recoloured_box check_width.py accepted a box drawn in its sibling's colour"
else
  echo "ok cli_width_checker_rejects_a_recoloured_box"
fi
