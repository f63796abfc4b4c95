#!/usr/bin/env bash
# tests/course_framework.sh [BVH_H] — a bvh.h as the homework server builds
# it: copied ALONE into a folder with the course's main.cpp, shapes.h/.cpp
# and utils.h/.cpp (here the stand-ins in tests/course_framework/, written
# from ../shared/spec/course-framework.md), compiled with one command, and
# run on the handout's command lines. A bvh.h that needs any other project
# header, or more of the shapes than the course's interface, fails to
# compile here. `make course-check BVH=path/to/bvh.h` runs it.
#
# Checks: a -Werror build (g++), and -Werror compiles (g++ at its default
# -std, clang++ when installed); bulk and incremental
# stdout equal to expected_output/; discard-overlap survivors equal to a
# brute-force scan with the stand-in's own (inexact) intersect, and unequal
# to this project's exact result somewhere (the discard goldens of
# expected_output/ are that result, so the framework's predicate is the one
# called); an instructor-style test of iterators and copies
# (instructor_test.cpp), the extra credit's erase and SAH rule
# (extras_test.cpp), and runs under valgrind.
# Prints `ok`/`FAIL` lines and ends with `N passed, M failed`.
#
# The bvh.h checked: the first argument, else $BVH, else the project's
# bvh.h. Environment: COURSE_DATA (default ../shared/course; skipped with a
# notice when absent), CXX (default g++), EXTRAS (auto: a bvh.h that does
# not compile extras_test.cpp skips it with a notice, as a student's may;
# yes: that is a failure). Needs nothing built.
set -u
BVH=${1:-${BVH:-}}
# (a path given from the caller's folder, before the cd below)
if [ -n "$BVH" ]; then
  [ -f "$BVH" ] || { echo "course_framework.sh: no such file: $BVH" >&2; exit 2; }
  BVH=$(cd "$(dirname "$BVH")" && pwd)/$(basename "$BVH")
fi
cd "$(dirname "$0")/.." || exit 2
BVH=${BVH:-$PWD/bvh.h}
EXTRAS=${EXTRAS:-auto}
COURSE_DATA=${COURSE_DATA:-../shared/course}
CXX=${CXX:-g++}
passed=0
failed=0
ok() { echo "ok $1"; passed=$((passed + 1)); }
bad() { echo "FAIL $1${2:+ — $2}"; failed=$((failed + 1)); }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# The stand-in framework: main.cpp and scene_io.h (its loader and picture
# writer), shapes.h/.cpp, utils.h/.cpp; and the test programs brute.cpp,
# instructor_test.cpp, extras_test.cpp.
cp tests/course_framework/*.h tests/course_framework/*.cpp "$work"/
cp "$BVH" "$work"/bvh.h # the submission, and nothing else of this project
echo "checking $BVH in the course's framework (stand-ins: tests/course_framework/)"

# 1. The server's build: one command over the three .cpp files, plus -Werror.
build() { # name compiler flags... -- sources... (run in $work)
  local out=$1
  shift
  (cd "$work" && "$@" -o "$out") >"$work/$out.log" 2>&1
}
flags=(-std=c++17 -g -Wall -Wextra -pedantic -Werror)
if build bvh.out "$CXX" "${flags[@]}" main.cpp shapes.cpp utils.cpp; then
  ok "course_framework_build_$CXX"
else
  bad "course_framework_build_$CXX" "$(head -c 600 "$work/bvh.out.log")"
  echo "$passed passed, $failed failed"
  exit 1
fi
# Two more compilers' views of the same sources, compiled only (-fsyntax-only
# parses and instantiates everything, and reports the front end's warnings;
# code generation and linking were checked by the build above): as the
# handout's server might build, with no -std (g++'s default) and -g -Wall;
# and clang++.
syntax() { # name compiler flags... (run in $work)
  local name=$1
  shift
  (cd "$work" && "$@" -fsyntax-only main.cpp shapes.cpp utils.cpp) >"$work/$name.log" 2>&1
}
if syntax default_std g++ -g -Wall -Werror; then
  ok course_framework_build_default_std
else
  bad course_framework_build_default_std "$(head -c 600 "$work/default_std.log")"
fi
if command -v clang++ >/dev/null 2>&1; then
  if syntax clang clang++ "${flags[@]}"; then
    ok course_framework_build_clang++
  else
    bad course_framework_build_clang++ "$(head -c 600 "$work/clang.log")"
  fi
else
  echo "skipped course_framework_build_clang++: clang++ not installed (apt-get install clang)"
fi
build brute.out "$CXX" -std=c++17 -O1 brute.cpp shapes.cpp utils.cpp || bad course_framework_brute_build "$(head -c 600 "$work/brute.out.log")"
build instructor_test.out "$CXX" "${flags[@]}" instructor_test.cpp shapes.cpp utils.cpp ||
  bad course_framework_instructor_build "$(head -c 600 "$work/instructor_test.out.log")"
if build extras_test.out "$CXX" "${flags[@]}" extras_test.cpp shapes.cpp utils.cpp; then
  :
elif [ "$EXTRAS" = yes ]; then
  bad course_framework_extras_build "$(head -c 600 "$work/extras_test.out.log")"
else
  echo "skipped course_framework_extras: extras_test.cpp (erase(iterator), set_build_rule(BuildRule::sah)) does not compile with this bvh.h: $(grep -m 1 'error' "$work/extras_test.out.log")"
fi

# A picture's shapes, geometry only (--visualize recolours them by leaf).
shape_lines() { grep -E '^<(circle|polygon) ' "$1" | sed 's/ style=.*//' | sort; }

# 2. The golden command lines the course's main.cpp understands (not
# --pairs, not .shapes), on one data folder.
run_folder() { # label data-folder
  local label=$1 data=$2 differs=0 discards=0
  # Our own scenes and their goldens carry the prefix gen_ (tests/golden.list).
  local prefix=
  [ "$label" = inputs ] && prefix=gen_
  while read -r name args; do
    [[ -z $name || $name == \#* || $args == *--pairs* || $args == *.shapes* ]] && continue
    name=$prefix$name
    local input
    input=$data/$prefix$(echo "$args" | sed -E 's/.*-i ([^ ]+).*/\1/')
    # shellcheck disable=SC2086
    set -- $args
    local argv=() a
    while [ $# -gt 0 ]; do
      a=$1
      shift
      if [ "$a" = -i ]; then argv+=(-i "$input") && shift; else argv+=("$a"); fi
    done
    local case_name=course_framework_${label}_$name out=$work/${label}_$name
    if ! "$work/bvh.out" "${argv[@]}" -o "$out.html" --print_tree >"$out.txt" 2>"$out.err"; then
      bad "$case_name" "stand-in bvh.out failed: $(head -c 300 "$out.err")"
      continue
    fi
    if [[ $args != *--discard_overlap* ]]; then
      # No predicate involved: the tree and its report are the project's.
      if ! cmp -s "$out.txt" "expected_output/$label/$name.txt"; then
        bad "$case_name" "stdout differs from expected_output/$label/$name.txt"
      elif ! "$work/bvh.out" "${argv[@]}" -o "$out.2.html" >"$out.2.txt" 2>&1 ||
        ! cmp -s "$out.2.txt" <(grep -E '^(node count|max depth|inner node area|leaf node area):' "$out.txt"); then
        bad "$case_name" "without --print_tree: not the statistics alone"
      else
        ok "$case_name"
      fi
      continue
    fi
    # Discard-overlap: the survivors of the framework's predicate.
    discards=$((discards + 1))
    "$work/brute.out" "$input" "$out.brute.html"
    if ! cmp -s <(shape_lines "$out.html") <(shape_lines "$out.brute.html"); then
      bad "$case_name" "kept $(shape_lines "$out.html" | wc -l) shapes, the brute-force scan with the stand-in's intersect $(shape_lines "$out.brute.html" | wc -l)"
    else
      ok "$case_name"
    fi
    # The golden is the exact predicate's run: another kept set shows as
    # another tree.
    if ! cmp -s "$out.txt" "expected_output/$label/$name.txt"; then
      differs=$((differs + 1))
    fi
  done <tests/golden.list
  # The stand-in's tolerance must show somewhere, or the discard cases above
  # could not tell its predicate from the project's exact one.
  if [ "$discards" -gt 0 ] && [ "$differs" -gt 0 ]; then
    ok "course_framework_${label}_predicate_is_the_frameworks ($differs of $discards discard runs differ from the exact result)"
  else
    bad "course_framework_${label}_predicate_is_the_frameworks" "no discard run differs from the exact result ($discards runs)"
  fi
}
run_folder inputs inputs
if [ -f "$COURSE_DATA/36.triangles" ]; then
  run_folder course "$COURSE_DATA"
  if ! "$work/bvh.out" -i "$COURSE_DATA/36.triangles" -o "$work/h.html" --depth_limit 2 --visualize --print_tree |
    cmp -s - "$COURSE_DATA/36_triangles_2_stdout.txt"; then
    bad course_framework_handout_sample "differs from $COURSE_DATA/36_triangles_2_stdout.txt"
  else
    ok course_framework_handout_sample
  fi
  scenes=("$COURSE_DATA/200.disks" "$COURSE_DATA/200.triangles" "$COURSE_DATA/200.quads")
else
  echo "skipped course_framework_course_*: no course data at COURSE_DATA=$COURSE_DATA"
  scenes=(inputs/gen_1000.disks inputs/gen_1000.triangles inputs/gen_1000.quads)
fi

# 3. The instructor's kind of test, and the program, under valgrind.
vg=(valgrind -q --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=all --show-leak-kinds=all)
if [ -x "$work/instructor_test.out" ]; then
  if "$work/instructor_test.out" "${scenes[@]}" >"$work/it.log" 2>&1; then
    ok "course_framework_instructor_test ($(tail -n 1 "$work/it.log"))"
  else
    bad course_framework_instructor_test "$(grep -m 3 FAIL "$work/it.log")"
  fi
  if [ -x "$work/extras_test.out" ]; then
    if "$work/extras_test.out" "${scenes[@]}" >"$work/ex.log" 2>&1; then
      ok "course_framework_extras_test ($(tail -n 1 "$work/ex.log"))"
    else
      bad course_framework_extras_test "$(grep -m 3 FAIL "$work/ex.log")"
    fi
  fi
  if command -v valgrind >/dev/null 2>&1; then
    if "${vg[@]}" "$work/instructor_test.out" "${scenes[@]}" >"$work/it_vg.log" 2>&1; then
      ok course_framework_instructor_test_valgrind
    else
      bad course_framework_instructor_test_valgrind "$(head -c 600 "$work/it_vg.log")"
    fi
    if [ -x "$work/extras_test.out" ]; then
      if "${vg[@]}" "$work/extras_test.out" "${scenes[@]}" >"$work/ex_vg.log" 2>&1; then
        ok course_framework_extras_test_valgrind
      else
        bad course_framework_extras_test_valgrind "$(head -c 600 "$work/ex_vg.log")"
      fi
    fi
    if "${vg[@]}" "$work/bvh.out" -i inputs/gen_overlap_1000.triangles -o "$work/v1.html" --depth_limit 8 --incremental \
      --discard_overlap >"$work/vg1.log" 2>&1 &&
      "${vg[@]}" "$work/bvh.out" -i inputs/gen_1000.quads -o "$work/v2.html" --depth_limit 3 --visualize --print_tree \
        >"$work/vg2.log" 2>&1; then
      ok course_framework_bvh_out_valgrind
    else
      bad course_framework_bvh_out_valgrind "$(grep -v '^ *\(inner\|leaf\|node\|max\)' "$work"/vg*.log | head -c 600)"
    fi
  else
    echo "skipped course_framework_*_valgrind: valgrind not installed (apt-get install valgrind)"
  fi
fi

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
