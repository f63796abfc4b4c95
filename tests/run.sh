#!/usr/bin/env bash
# tests/run.sh — every test of the project, run by `make test` (which builds
# the binaries first). Prints `ok NAME` or `FAIL NAME` per case, a log path
# for each failure, and ends with `N passed, M failed`; exits 1 on failure.
#
# Environment: CXX (compiler for the warning checks), COURSE_DATA (the
# course's files; golden cases on them are skipped with a notice when the
# folder is missing), BUILD (where `make` put the test binaries),
# UPDATE_GOLDEN=1 (write missing golden files instead of failing: each new
# file must then be checked by hand before it is committed).
set -u
cd "$(dirname "$0")/.."
CXX=${CXX:-g++}
COURSE_DATA=${COURSE_DATA:-../shared/course}
BUILD=${BUILD:-build}
LOGS=$BUILD/test-logs
OUT=$BUILD/test-out
rm -rf "$LOGS" "$OUT"
mkdir -p "$LOGS" "$OUT"
passed=0
failed=0
skipped=0

ok() { echo "ok $1"; passed=$((passed + 1)); }
bad() {
  echo "FAIL $1${2:+ — $2}"
  failed=$((failed + 1))
}
skip() {
  echo "skipped $1: $2"
  skipped=$((skipped + 1))
}
logname() { echo "$LOGS/$(echo "$1" | tr -c 'A-Za-z0-9_.\n-' '_').log"; }

# A test binary built on tests/check.h: its own cases count one by one.
run_suite() {
  local name=$1
  shift
  local log
  log=$(logname "$name")
  "$@" >"$log" 2>&1
  local rc=$?
  local last
  last=$(tail -n 1 "$log")
  if [[ $last =~ ^([0-9]+)\ passed,\ ([0-9]+)\ failed$ ]]; then
    local p=${BASH_REMATCH[1]} f=${BASH_REMATCH[2]}
    grep -E '^FAIL ' "$log" | sed "s/^FAIL /FAIL $name: /"
    passed=$((passed + p))
    failed=$((failed + f))
    echo "ok-suite $name: $p passed, $f failed"
    if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then bad "$name" "exit status $rc, see $log"; fi
  else
    bad "$name" "did not finish (exit $rc), see $log"
  fi
}

# One command as one case: passes when it exits 0.
run_case() {
  local name=$1
  shift
  local log
  log=$(logname "$name")
  if "$@" >"$log" 2>&1; then ok "$name"; else bad "$name" "see $log"; fi
}

# ---------------------------------------------------------------------------
# 1. Warning-free under g++ and clang++ with -Wall -Wextra -pedantic.
for compiler in g++ clang++; do
  if command -v "$compiler" >/dev/null 2>&1; then
    run_case "warnings_$compiler" bash -c "
      $compiler -std=c++17 -Wall -Wextra -pedantic -Werror -fsyntax-only main.cpp &&
      $compiler -std=c++17 -Wall -Wextra -pedantic -Werror -fsyntax-only -I. -Itests tests/test_bvh.cpp &&
      $compiler -std=c++17 -Wall -Wextra -pedantic -Werror -fsyntax-only -I. -Itests tests/test_intersect.cpp &&
      $compiler -std=c++17 -Wall -Wextra -pedantic -Werror -fsyntax-only -I. -Itests tests/test_dynamic.cpp &&
      $compiler -std=c++17 -Wall -Wextra -pedantic -Werror -fsyntax-only -I. -Itests tests/test_parse.cpp &&
      $compiler -std=c++17 -Wall -Wextra -pedantic -Werror -fsyntax-only -I. tests/fuzz_parser.cpp &&
      $compiler -std=c++17 -Wall -Wextra -pedantic -Werror -fsyntax-only -I. scene.h"
  else
    skip "warnings_$compiler" "$compiler is not installed"
  fi
done
# The iterator satisfies std::bidirectional_iterator (static_assert under C++20).
run_case iterator_is_a_cxx20_bidirectional_iterator \
  "$CXX" -std=c++20 -Wall -Wextra -pedantic -Werror -fsyntax-only -I. -Itests tests/test_bvh.cpp

# ---------------------------------------------------------------------------
# 2. Unit and model tests (plain, then under AddressSanitizer + UBSan).
run_suite test_bvh "$BUILD/test_bvh"
run_suite test_intersect "$BUILD/test_intersect"
run_suite test_dynamic "$BUILD/test_dynamic"
run_suite test_parse "$BUILD/test_parse"
# collision() without SSE2 (BVH_NO_SIMD): the scalar fallback against the same brute force.
BVH_TEST_SCALE=0.3 run_suite test_bvh_scalar "$BUILD/test_bvh_scalar"
BVH_TEST_SCALE=0.3 run_suite test_bvh_sanitized "$BUILD/test_bvh_san"
BVH_TEST_SCALE=0.3 run_suite test_intersect_sanitized "$BUILD/test_intersect_san"
BVH_TEST_SCALE=0.5 run_suite test_dynamic_sanitized "$BUILD/test_dynamic_san"
BVH_TEST_SCALE=0.1 run_suite test_parse_sanitized "$BUILD/test_parse_san"

# ---------------------------------------------------------------------------
# 3. Golden stdout: tests/golden.list on the course's data and on inputs/.
golden_folder() { # label data-folder
  local label=$1 data=$2
  local expected=expected_output/$label
  while read -r name args; do
    [[ -z $name || $name == \#* ]] && continue
    # The course has no mixed scenes: .shapes cases run on inputs/ only.
    [[ $label == course && $args == *.shapes* ]] && continue
    # shellcheck disable=SC2086
    set -- $args
    local argv=() a
    while [ $# -gt 0 ]; do
      a=$1
      shift
      if [ "$a" = -i ]; then
        argv+=(-i "$data/$1")
        shift
      else
        argv+=("$a")
      fi
    done
    local html=$OUT/${label}_$name.html
    local got=$OUT/${label}_$name.txt
    local case_name=golden_${label}_$name
    if ! ./bvh.out "${argv[@]}" -o "$html" --print_tree >"$got" 2>"$got.err"; then
      bad "$case_name" "bvh.out failed: $(head -c 300 "$got.err")"
      continue
    fi
    if [ ! -f "$expected/$name.txt" ]; then
      if [ "${UPDATE_GOLDEN:-0}" = 1 ]; then
        mkdir -p "$expected"
        cp "$got" "$expected/$name.txt"
        echo "wrote $expected/$name.txt: check it by hand before committing"
      fi
      bad "$case_name" "no golden file $expected/$name.txt"
      continue
    fi
    if ! cmp -s "$got" "$expected/$name.txt"; then
      bad "$case_name" "stdout differs: diff $got $expected/$name.txt"
      continue
    fi
    # Without --print_tree: the same minus the tree's lines (the statistics
    # and the --pairs line; nothing of the tree without a depth limit).
    local plain=$OUT/${label}_$name.plain
    ./bvh.out "${argv[@]}" -o "$OUT/${label}_${name}_plain.html" >"$plain" 2>&1
    local want
    want=$(grep -vE '^ *(inner|leaf) area=' "$expected/$name.txt")
    if [ "$(cat "$plain")" != "$want" ]; then
      bad "$case_name" "output without --print_tree is not the statistics alone: $plain"
      continue
    fi
    if ! cmp -s "$html" "$OUT/${label}_${name}_plain.html"; then
      bad "$case_name" "--print_tree changed the picture"
      continue
    fi
    ok "$case_name"
  done <tests/golden.list
}

if [ -f "$COURSE_DATA/36.triangles" ]; then
  golden_folder course "$COURSE_DATA"
  # The course's own published expected output, byte for byte.
  if ./bvh.out -i "$COURSE_DATA/36.triangles" -o "$OUT/handout.html" --depth_limit 2 --visualize --print_tree \
    >"$OUT/handout.txt" 2>&1 && cmp -s "$OUT/handout.txt" "$COURSE_DATA/36_triangles_2_stdout.txt"; then
    ok course_published_36_triangles_2_is_byte_exact
  else
    bad course_published_36_triangles_2_is_byte_exact "diff $OUT/handout.txt $COURSE_DATA/36_triangles_2_stdout.txt"
  fi
else
  skip "golden_course_*" "no course data at COURSE_DATA=$COURSE_DATA (set COURSE_DATA to run them)"
fi
golden_folder inputs inputs

# The golden files agree with an independent model of the handout's rules
# (tests/verify_golden.py: Python, stable sorts, exact rational geometry).
if command -v python3 >/dev/null 2>&1; then
  [ -f "$COURSE_DATA/36.triangles" ] && run_case golden_course_agrees_with_python_model \
    python3 tests/verify_golden.py course "$COURSE_DATA"
  run_case golden_inputs_agrees_with_python_model python3 tests/verify_golden.py inputs inputs
else
  bad python3_available "python3 is missing: apt-get install python3"
fi

# ---------------------------------------------------------------------------
# 4. Every picture is well-formed XML.
if command -v xmllint >/dev/null 2>&1; then
  for html in "$OUT"/*.html; do
    [ -e "$html" ] || continue
    run_case "xml_well_formed_$(basename "$html" .html)" xmllint --noout "$html"
  done
else
  bad xmllint_available "xmllint is missing: apt-get install libxml2-utils"
fi

# A real browser: headless Chromium renders 36_triangles_2 (tests/browser.sh).
if [ -f "$COURSE_DATA/36.triangles" ]; then browser_data=$COURSE_DATA; else browser_data=inputs; fi
bash tests/browser.sh "$OUT/browser" "$browser_data" >"$LOGS/browser.log" 2>&1
while read -r status name rest; do
  case $status in
    ok) ok "$name" ;;
    FAIL) bad "$name" "$rest" ;;
    skip) skip "browser_*" "$name $rest" ;;
  esac
done <"$LOGS/browser.log"
grep -qE '^(ok|FAIL|skip) ' "$LOGS/browser.log" || bad browser_test "tests/browser.sh printed nothing: see $LOGS/browser.log"

# ---------------------------------------------------------------------------
# 5. Command-line and input errors: message, exit status, no output file.
# Every case twice: on bvh.out and on the ASan/UBSan build of it.
{
  bash tests/cli_errors.sh "$OUT/cli" ./bvh.out
  bash tests/cli_errors.sh "$OUT/cli_san" "$BUILD/bvh_san.out" _sanitized
} >"$LOGS/cli_errors.log" 2>&1
while read -r status name rest; do
  case $status in
    ok) ok "$name" ;;
    FAIL) bad "$name" "$rest" ;;
  esac
done <"$LOGS/cli_errors.log"

# ---------------------------------------------------------------------------
# 6. valgrind memcheck: unit tests and a bulk, an incremental and a discard run.
if command -v valgrind >/dev/null 2>&1; then
  VG=(valgrind -q --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=all --show-leak-kinds=all)
  BVH_TEST_SCALE=0.05 run_suite valgrind_test_bvh "${VG[@]}" "$BUILD/test_bvh"
  BVH_TEST_SCALE=0.01 run_suite valgrind_test_intersect "${VG[@]}" "$BUILD/test_intersect"
  BVH_TEST_SCALE=0.2 run_suite valgrind_test_dynamic "${VG[@]}" "$BUILD/test_dynamic"
  BVH_TEST_SCALE=0.02 run_suite valgrind_test_parse "${VG[@]}" "$BUILD/test_parse"
  run_case valgrind_bulk_build "${VG[@]}" ./bvh.out -i inputs/1000.triangles -o "$OUT/vg_bulk.html" \
    --depth_limit 4 --visualize --print_tree
  run_case valgrind_incremental "${VG[@]}" ./bvh.out -i inputs/1000.quads -o "$OUT/vg_incremental.html" \
    --depth_limit 5 --incremental --visualize
  run_case valgrind_discard_overlap "${VG[@]}" ./bvh.out -i inputs/overlap_1000.disks -o "$OUT/vg_discard.html" \
    --depth_limit 8 --incremental --discard_overlap
  run_case valgrind_generate "${VG[@]}" ./bvh.out --generate triangles 300 --seed 3 -o "$OUT/vg.triangles"
  run_case valgrind_mixed_scene "${VG[@]}" ./bvh.out -i inputs/overlap_1000.shapes -o "$OUT/vg_mixed.html" \
    --depth_limit 6 --incremental --discard_overlap --visualize --print_tree --pairs
else
  bad valgrind_available "valgrind is missing: apt-get install valgrind"
fi
# The sanitized CLI on a discard run must print what the plain one prints.
run_case sanitized_cli_discard_overlap bash -c "
  '$BUILD/bvh_san.out' -i inputs/overlap_1000.triangles -o '$OUT/san.html' --depth_limit 8 --incremental \
    --discard_overlap --print_tree > '$OUT/san.txt' &&
  cmp '$OUT/san.txt' expected_output/inputs/discard_overlap_1000_triangles.txt"

# ---------------------------------------------------------------------------
# 7. libFuzzer for FUZZ_SECONDS on the parser, the tree and the command line
# (make fuzz runs the same); skipped with a notice without clang's libFuzzer.
if command -v clang++ >/dev/null 2>&1 &&
  echo 'extern "C" int LLVMFuzzerTestOneInput(const char *, unsigned long) { return 0; }' |
  clang++ -x c++ -fsanitize=fuzzer - -o "$BUILD/fuzz-probe" >/dev/null 2>&1; then
  rm -f "$BUILD/fuzz-probe"
  if make -s "$BUILD/fuzz_parser" BUILD="$BUILD" >"$LOGS/fuzz_build.log" 2>&1; then
    mkdir -p "$BUILD/fuzz-work"
    log=$(logname fuzz_parser)
    if "$BUILD/fuzz_parser" -max_total_time="${FUZZ_SECONDS:-60}" -print_final_stats=1 \
      -artifact_prefix="$BUILD/fuzz-crash-" "$BUILD/fuzz-work" tests/fuzz_corpus >"$log" 2>&1; then
      ok "fuzz_parser_${FUZZ_SECONDS:-60}s_$(grep -o 'number_of_executed_units: [0-9]*' "$log" | grep -o '[0-9]*$')_runs"
    else
      bad fuzz_parser "a finding: see $log and $BUILD/fuzz-crash-*"
    fi
  else
    bad fuzz_parser_build "see $LOGS/fuzz_build.log"
  fi
else
  skip fuzz_parser "clang++ with libFuzzer is not installed (apt-get install clang libclang-rt-14-dev)"
fi

echo
[ "$skipped" -gt 0 ] && echo "($skipped skipped: see the notices above)"
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
