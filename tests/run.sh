#!/usr/bin/env bash
# tests/run.sh — every test of the project, run by `make test`. First it
# builds every test binary (make -k -j$JOBS: each translation unit once per
# flavour), then it runs the LAYERS below, independent groups of tests,
# JOBS at a time, and prints each layer's results in the order the layers
# are listed: `ok NAME`, `FAIL NAME — why` (with a log path) or `skipped
# NAME: why` per case. It ends with `N passed, M failed` and exits 1 on any
# failure.
#
# Adding a layer: write a function (or a script) that prints those lines on
# stdout, one per case, and list it at the bottom:
#     layer my_layer bash tests/my_layer.sh
# Inside a function, ok / bad / skip / run_case / run_suite print the lines.
# A layer writes its files under $OUT/<its name> and $LOGS only; its stderr
# goes to $LOGS/layer_NAME.err.
#
# Environment: CXX (the compiler of the default build), COURSE_DATA (the
# course's files; golden cases on them are skipped with a notice when the
# folder is missing), BUILD (where `make` puts the binaries), JOBS (parallel
# jobs; default: the number of cores), FUZZ_SECONDS (default 10; make fuzz: 60),
# UPDATE_GOLDEN=1 (write missing golden files instead of failing: each new
# file must then be checked by hand before it is committed).
set -u
cd "$(dirname "$0")/.."
CXX=${CXX:-g++}
COURSE_DATA=${COURSE_DATA:-../shared/course}
BUILD=${BUILD:-build}
JOBS=${JOBS:-$(nproc 2>/dev/null || echo 2)}
MAKE=${MAKE:-make}
export CXX COURSE_DATA BUILD JOBS
# Arguments: none (every layer: make test), --quick (make check: bvh.out and
# the unit tests at -Og, then the unit and golden layers), or layer names
# (the full build, then only those layers: tests/run.sh valgrind golden).
ALL_LAYERS="fuzz valgrind sanitizers headers cmake course_framework golden python_model unit cli_errors cli_output cli_threads cli_widths demo examples asserts tsan browser"
QUICK=no
ONLY=()
for a in "$@"; do
  case $a in
    --quick) QUICK=yes ;;
    *)
      if [[ " $ALL_LAYERS " != *" $a "* ]]; then
        echo "tests/run.sh: unknown layer '$a'; the layers: $ALL_LAYERS (or --quick)" >&2
        exit 2
      fi
      ONLY+=("$a")
      ;;
  esac
done
LOGS=$BUILD/test-logs
OUT=$BUILD/test-out
RESULTS=$BUILD/test-results
rm -rf "$LOGS" "$OUT" "$RESULTS"
mkdir -p "$LOGS" "$OUT" "$RESULTS"

ok() { echo "ok $1"; }
bad() { echo "FAIL $1${2:+ — $2}"; }
skip() { echo "skipped $1: $2"; }
have() { command -v "$1" >/dev/null 2>&1; }
# LOG=the log file of case NAME. (Here and in the waiting loops below, no
# command substitution or external command: each process costs
# milliseconds on a host where forks are dear, and a run has thousands.)
logname() { LOG=$LOGS/${1//[^A-Za-z0-9_.-]/_}.log; }
# The Python scripts' interpreter, found once: python3 on the PATH may be a
# version manager's shim (pyenv's runs about a dozen processes, 0.3 s, at
# every start). -S: they need the standard library only.
PYTHON=python3
if have python3; then PYTHON=$(python3 -c 'import sys; print(sys.executable or "python3")' 2>/dev/null) || PYTHON=python3; fi
export PYTHON

# A test binary built on tests/check.h: its own cases count one by one
# (`ok-suite NAME: P passed, F failed` counts P; each failed case prints its
# own FAIL line).
run_suite() {
  local name=$1
  shift
  local LOG
  logname "$name"
  "$@" >"$LOG" 2>&1
  suite_result "$name" "$LOG" $? "$1"
}
# The lines of a suite's log LOG (exit status RC, binary BIN).
suite_result() {
  local name=$1 log=$2 rc=$3
  set -- "$4"
  local last
  last=$(tail -n 1 "$log")
  if [[ $last =~ ^([0-9]+)\ passed,\ ([0-9]+)\ failed$ ]]; then
    local p=${BASH_REMATCH[1]} f=${BASH_REMATCH[2]} shown
    grep -E '^FAIL ' "$log" | sed "s/^FAIL /FAIL $name: /"
    grep -E '^skipped ' "$log"
    shown=$(grep -cE '^FAIL ' "$log")
    [ "$f" -gt "$shown" ] && bad "$name" "$((f - shown)) more failed cases, see $log"
    echo "ok-suite $name: $p passed, $f failed"
    if [ "$rc" -ne 0 ] && [ "$f" -eq 0 ]; then bad "$name" "exit status $rc, see $log"; fi
  elif [ ! -x "$1" ] && [ ! -x "$(command -v "$1" 2>/dev/null)" ]; then
    bad "$name" "not built: see $LOGS/build.log"
  else
    bad "$name" "did not finish (exit $rc), see $log"
  fi
}

# One command as one case: passes when it exits 0.
run_case() {
  local name=$1
  shift
  local LOG
  logname "$name"
  if "$@" >"$LOG" 2>&1; then ok "$name"; else bad "$name" "see $LOG"; fi
}

# A script's own `ok NAME`, `FAIL NAME why` and `skip REASON` lines, as results.
relay() { # NAME LOG
  local group=$1 log=$2 status name rest
  while read -r status name rest; do
    case $status in
      ok) ok "$name" ;;
      FAIL) bad "$name" "$rest" ;;
      skip) skip "$group" "$name $rest" ;;
    esac
  done <"$log"
  grep -qE '^(ok|FAIL|skip) ' "$log" || bad "$group" "printed nothing: see $log"
}

# ---------------------------------------------------------------------------
# Layer machinery: `layer NAME COMMAND...` starts COMMAND in the background
# (at most JOBS at once) and prints "-- NAME started"; when a layer ends, its
# results follow at once under "== NAME done (N s)". While nothing else is
# printed, a line every $HEARTBEAT seconds names the layers still running, so
# that a run is never silent for long.
HEARTBEAT=${HEARTBEAT:-15}
LAYERS=()
STARTED=()
SHOWN=()
LAST_LINE=$SECONDS
print_done_layers() {
  local i
  for ((i = 0; i < ${#LAYERS[@]}; i++)); do
    [ -n "${SHOWN[$i]:-}" ] && continue
    [ -f "$RESULTS/$i.done" ] || continue
    SHOWN[$i]=1
    local name=${LAYERS[$i]} rc secs
    read -r rc secs <"$RESULTS/$i.done"
    echo "== $name done ($secs s)"
    cat "$RESULTS/$i.txt"
    if ! grep -qE '^(ok|ok-suite|FAIL|skipped) ' "$RESULTS/$i.txt"; then
      bad "layer_$name" "printed no result (exit $rc): see $LOGS/layer_$name.err" | tee -a "$RESULTS/$i.txt"
    elif [ "$rc" -ne 0 ] && ! grep -q '^FAIL ' "$RESULTS/$i.txt"; then
      bad "layer_$name" "exit status $rc without a FAIL line: see $LOGS/layer_$name.err" | tee -a "$RESULTS/$i.txt"
    fi
    LAST_LINE=$SECONDS
  done
}
running_layers() {
  local i list=
  for ((i = 0; i < ${#LAYERS[@]}; i++)); do
    [ -f "$RESULTS/$i.done" ] || list+="${list:+, }${LAYERS[$i]} $((SECONDS - STARTED[i])) s"
  done
  echo "$list"
}
# RUNNING=the number of layers still running.
count_running() {
  local i
  RUNNING=0
  for ((i = 0; i < ${#LAYERS[@]}; i++)); do [ -f "$RESULTS/$i.done" ] || RUNNING=$((RUNNING + 1)); done
}
# A fifth of a second of waiting, by a read that times out on a FIFO no one
# writes (the shell's own timer: no sleep process five times a second).
mkfifo "$RESULTS/pause.fifo" && exec {pause_fd}<>"$RESULTS/pause.fifo"
pause() {
  if [ -n "${pause_fd:-}" ]; then read -r -t 0.2 -u "$pause_fd" _; else sleep 0.2; fi
}
# Waits a fifth of a second (a layer starts that soon after a slot frees),
# then prints what has ended, and the heartbeat when due.
tick() {
  pause
  print_done_layers
  if [ $((SECONDS - LAST_LINE)) -ge "$HEARTBEAT" ]; then
    echo "   ... still running: $(running_layers)"
    LAST_LINE=$SECONDS
  fi
}
layer() {
  local name=$1
  shift
  if [ "${#ONLY[@]}" -gt 0 ] && [[ " ${ONLY[*]} " != *" $name "* ]]; then return; fi
  while count_running && [ "$RUNNING" -ge "$JOBS" ]; do tick; done
  local i=${#LAYERS[@]}
  LAYERS+=("$name")
  STARTED[$i]=$SECONDS
  (
    start=$SECONDS
    "$@" >"$RESULTS/$i.txt" 2>"$LOGS/layer_$name.err" </dev/null
    echo "$? $((SECONDS - start))" >"$RESULTS/$i.done"
  ) &
  echo "-- $name started"
  LAST_LINE=$SECONDS
}
finish_layers() {
  while count_running && [ "$RUNNING" -gt 0 ]; do tick; done
  wait
  print_done_layers
}

# ---------------------------------------------------------------------------
# The layers.

# Unit and model tests (tests/test_*.cpp, tests/check.h), default build.
unit_tests() {
  run_suite test_bvh "$BUILD/test_units" bvh
  run_suite test_threads "$BUILD/test_units" threads
  run_suite test_intersect "$BUILD/test_units" intersect
  run_suite test_dynamic "$BUILD/test_units" dynamic
  run_suite test_moving "$BUILD/test_units" moving
  run_suite test_lazy_handles "$BUILD/test_units" lazy_handles
  run_suite test_parse "$BUILD/test_units" parse
  run_suite test_names "$BUILD/test_names"
  run_suite test_disjoint "$BUILD/test_units" disjoint
  # Fault injection: every mutating operation at its k-th copy and allocation (issue 21).
  run_suite test_exceptions "$BUILD/test_exceptions"
  # The engine and the course's edition (the top-level bvh.h) against each other.
  run_suite test_editions "$BUILD/test_editions"
  # (collision()'s scalar fallback, BVH_NO_SIMD: the sanitizer layer's build.)
}

# make check's unit tests: the same suites, built into $BUILD/check (by
# clang++ -O0 when it is installed: the Makefile's CHECK_CXX) and already
# run by the build, each at CHECK_SCALE of its random rounds, as soon as its
# program was built: here their output ($BUILD/check/test_*.out) is read.
unit_tests_quick() {
  local t out LOG rc bin
  for t in bvh threads intersect dynamic moving lazy_handles parse disjoint editions; do
    out=$BUILD/check/test_$t.out
    bin=$BUILD/check/test_units
    [ "$t" = editions ] && bin=$BUILD/check/test_editions
    logname "test_$t"
    if [ ! -f "$out" ]; then
      : >"$LOG"
      suite_result "test_$t" "$LOG" 1 "$bin"
      continue
    fi
    rc=$(tail -n 1 "$out" | sed -n 's/^exit status //p')
    sed '$d' "$out" >"$LOG"
    suite_result "test_$t" "$LOG" "${rc:-1}" "$bin"
  done
}

# The unit tests and the CLI under AddressSanitizer + UBSan, built by
# clang++ with libc++ when both are installed (the suites' names then end in
# _libcxx), else by g++. The unit program (build/test_units_san) is also the
# portable build: -std=c++20, -DBVH_NO_SIMD and -DBVH_NO_HUGE_PAGES (the
# Makefile's UNITS_SAN_FLAGS; its suites' names say _cxx20_no_simd). The
# wide trees' models in test_dynamic run at 0.3 of their rounds here: the
# scalar fallback's passes over four children at a time end differently at
# widths 2, 4, 5, 7 and 8.
sanitizers() {
  local s=_sanitized
  [ "$HAVE_LIBCXX" = yes ] && s=_sanitized_libcxx
  local u=${s}_cxx20_no_simd
  BVH_TEST_SCALE=0.05 run_suite test_bvh$u "$BUILD/test_units_san" bvh
  BVH_TEST_SCALE=0.3 run_suite test_threads$u "$BUILD/test_units_san" threads
  BVH_TEST_SCALE=0.1 run_suite test_intersect$u "$BUILD/test_units_san" intersect
  BVH_TEST_SCALE=0.15 run_suite test_dynamic$u "$BUILD/test_units_san" dynamic
  BVH_TEST_SCALE=0.1 run_suite test_moving$u "$BUILD/test_units_san" moving
  BVH_TEST_SCALE=0.05 run_suite test_lazy_handles$u "$BUILD/test_units_san" lazy_handles
  BVH_TEST_SCALE=0.1 run_suite test_parse$u "$BUILD/test_units_san" parse
  BVH_TEST_SCALE=0.05 run_suite test_disjoint$u "$BUILD/test_units_san" disjoint
  BVH_TEST_SCALE=0.2 run_suite test_exceptions$s "$BUILD/test_exceptions_san"
  # The sanitized CLI on a discard run must print what the plain one prints.
  run_case sanitized_cli_discard_overlap bash -c "
    '$BUILD/bvh_san.out' -i inputs/gen_overlap_1000.triangles -o '$OUT/san.html' --depth_limit 8 --incremental \
      --discard_overlap --print_tree > '$OUT/san.txt' &&
    cmp '$OUT/san.txt' expected_output/inputs/gen_discard_overlap_1000_triangles.txt"
}

# tests/NAME.sh DIR ./bvh.out, a script that needs python3, as results
# named PREFIX*.
python_script() { # NAME PREFIX
  if have python3; then
    bash "tests/$1.sh" "$OUT/$1" ./bvh.out >"$LOGS/$1.log" 2>&1
    relay "$2*" "$LOGS/$1.log"
  else
    bad python3_available "python3 is missing: apt-get install python3"
  fi
}

# --no_output and the progress line of bvh.out (tests/cli_output.sh).
cli_output() { python_script cli_output cli_output_; }

# BVH_ASSERT (tests/test_asserts.cpp): in a debug build each misuse of the
# API aborts with a "BVH misuse" message; correct use near the edges fires
# nothing; -DNDEBUG compiles the checks away (and a stale handle then has
# its defined outcome: nothing changes); a user's own BVH_ASSERT (here one
# that throws) replaces the default for every check.
asserts() {
  local c cases
  if ! cases=$("$BUILD/test_asserts" list); then
    bad bvh_assert "not built: see $LOGS/build.log"
    return
  fi
  for c in $cases; do
    run_case "bvh_assert_$c" bash -c "! '$BUILD/test_asserts' $c >'$OUT/assert_$c.out' 2>&1 &&
      grep -qE 'bvh\.h:[0-9]+: BVH misuse: .+ \(.+\)$' '$OUT/assert_$c.out'"
  done
  run_case bvh_assert_quiet_on_valid_use "$BUILD/test_asserts" valid
  run_case bvh_assert_off_under_ndebug "$BUILD/test_asserts_ndebug" valid
  run_case bvh_assert_off_stale_handles_do_nothing "$BUILD/test_asserts_ndebug" stale
  run_case bvh_assert_user_handler "$BUILD/test_asserts_throwing" handler
}

# construct()'s build threads and insert_disjoint's workers (and const
# queries from several threads) under ThreadSanitizer: a data race fails it.
tsan() {
  BVH_TEST_SCALE=0.25 run_suite test_threads_under_thread_sanitizer "$BUILD/test_lanes_tsan" threads
  BVH_TEST_SCALE=0.03 run_suite test_disjoint_under_thread_sanitizer "$BUILD/test_lanes_tsan" disjoint
  BVH_TEST_SCALE=0.05 run_suite test_lazy_handles_under_thread_sanitizer "$BUILD/test_lanes_tsan" lazy_handles
}

# bvh.h alone in the course's framework (stand-ins written from the spec),
# as the homework server builds it: tests/course_framework.sh.
course_framework() {
  EXTRAS=yes run_suite course_framework bash tests/course_framework.sh
}

# examples/*.cpp (the library snippets of README.txt and docs/ as programs):
# each checks its own answers against a scan and ends with "ok"; README.txt
# or a docs/*.txt must still quote each snippet (tests/readme_quotes.py).
examples() {
  local src name
  for src in examples/*.cpp; do
    name=${src##*/}
    name=${name%.cpp}
    run_case "example_$name" bash -c "'$BUILD/example_$name' > '$OUT/example_$name.txt' &&
      cat '$OUT/example_$name.txt' && [ \"\$(tail -n 1 '$OUT/example_$name.txt')\" = ok ]"
  done
  if have python3; then
    "$PYTHON" -S tests/readme_quotes.py README.txt docs/*.txt -- examples/*.cpp
  else
    bad python3_available "python3 is missing: apt-get install python3"
  fi
}

# Golden stdout: tests/golden.list on the course's data and on inputs/.
golden_folder() { # label data-folder
  local label=$1 data=$2
  local expected=expected_output/$label
  # Our own scenes and their goldens carry the prefix gen_ (tests/golden.list).
  local prefix=
  [ "$label" = inputs ] && prefix=gen_
  while read -r name args; do
    [[ -z $name || $name == \#* ]] && continue
    name=$prefix$name
    # The course has no mixed scenes: .shapes cases run on inputs/ only.
    [[ $label == course && $args == *.shapes* ]] && continue
    # shellcheck disable=SC2086
    set -- $args
    local argv=() a
    while [ $# -gt 0 ]; do
      a=$1
      shift
      if [ "$a" = -i ]; then
        argv+=(-i "$data/$prefix$1")
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


golden() {
  local OUT=$OUT/golden # golden_folder's pictures, which the XML check reads
  mkdir -p "$OUT"
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
  # Every picture is well-formed XML.
  if have xmllint; then
    for html in "$OUT"/*.html; do
      [ -e "$html" ] || continue
      run_case "xml_well_formed_$(basename "$html" .html)" xmllint --noout "$html"
    done
  else
    skip "xml_well_formed_*" "xmllint not installed (apt-get install libxml2-utils)"
  fi
}

# The golden files agree with an independent model of the handout's rules
# (tests/verify_golden.py: Python, stable sorts, exact rational geometry).
python_model() {
  if ! have python3; then
    bad python3_available "python3 is missing: apt-get install python3"
  elif [ -f "$COURSE_DATA/36.triangles" ]; then
    run_case golden_course_agrees_with_python_model "$PYTHON" -S tests/verify_golden.py course "$COURSE_DATA"
  else
    skip golden_course_agrees_with_python_model "no course data at COURSE_DATA=$COURSE_DATA"
  fi
  have python3 && run_case golden_inputs_agrees_with_python_model "$PYTHON" -S tests/verify_golden.py inputs inputs
}

# A real browser: headless Chromium renders 36_triangles_2 (tests/browser.sh).
browser() {
  local scene=inputs/gen_36.triangles
  [ -f "$COURSE_DATA/36.triangles" ] && scene=$COURSE_DATA/36.triangles
  bash tests/browser.sh "$OUT/browser" "$scene" >"$LOGS/browser.log" 2>&1
  relay "browser_*" "$LOGS/browser.log"
}

# make demo (tests/demo.sh): on the course's scenes its stdout is the
# commands' stdout alone, and the handout's --print_tree example in it is
# byte for byte the course's published 36_triangles_2_stdout.txt; without
# course data it runs on inputs/gen_* and says so on stderr.
demo_layer() {
  local d=$OUT/demo
  mkdir -p "$d"
  if [ -f "$COURSE_DATA/36_triangles_2_stdout.txt" ]; then
    local n
    n=$(wc -c <"$COURSE_DATA/36_triangles_2_stdout.txt")
    run_case demo_course_stdout_ends_with_the_handouts_bytes bash -c "
      DEMO_DIR='$d/course' COURSE_DATA='$COURSE_DATA' bash tests/demo.sh >'$d/course.out' 2>'$d/course.err' &&
      tail -c $n '$d/course.out' | cmp - '$COURSE_DATA/36_triangles_2_stdout.txt' &&
      grep -q 'byte-identical' '$d/course.err'"
    run_case demo_course_stdout_is_only_the_commands_output bash -c "
      ! grep -qE '^(\\$|demo:| +\\()' '$d/course.out' && [ \"\$(grep -c '^node count:' '$d/course.out')\" = 11 ]"
  else
    skip demo_course "no course data at COURSE_DATA=$COURSE_DATA"
  fi
  run_case demo_without_course_data_says_it_runs_on_our_scenes bash -c "
    DEMO_DIR='$d/ours' COURSE_DATA='$d/no-such-folder' bash tests/demo.sh >'$d/ours.out' 2>'$d/ours.err' &&
    grep -q 'OUR OWN generated scenes inputs/gen_' '$d/ours.err' && grep -q 'will NOT match' '$d/ours.err' &&
    cmp -s '$d/ours/36_triangles_2_stdout.txt' expected_output/inputs/gen_36_triangles_2.txt"
}

# Command-line and input errors: message, exit status, no output file; every
# case twice, on bvh.out and on the ASan/UBSan build of it.
cli_errors() {
  {
    bash tests/cli_errors.sh "$OUT/cli" ./bvh.out
    bash tests/cli_errors.sh "$OUT/cli_san" "$BUILD/bvh_san.out" _sanitized
  } >"$LOGS/cli_errors.log" 2>&1
  relay "cli_*" "$LOGS/cli_errors.log"
}

# bvh.out --width W: each tree and picture checked against the rules every
# width shares, and what the width must not change (tests/cli_widths.sh).
# (On the sanitized bvh.out: the default bvh.out has the course's width 3
# alone, and the sanitized one every width. Its leak check is off here,
# a third of these runs' time: the cli_errors layer's sanitized runs and
# valgrind's check bvh.out's leaks.)
cli_widths() {
  if have python3; then
    ASAN_OPTIONS=detect_leaks=0 bash tests/cli_widths.sh "$OUT/cli_widths" "$BUILD/bvh_san.out" \
      >"$LOGS/cli_widths.log" 2>&1
    relay "cli_width_*" "$LOGS/cli_widths.log"
  else
    bad python3_available "python3 is missing: apt-get install python3"
  fi
}

# bvh.out --threads N: the same stdout and picture for every N (tests/cli_threads.sh).
cli_threads() {
  bash tests/cli_threads.sh "$OUT/cli_threads" ./bvh.out "$COURSE_DATA" >"$LOGS/cli_threads.log" 2>&1
  relay "cli_threads_*" "$LOGS/cli_threads.log"
}

# valgrind memcheck: the default build (SSE2, the huge-page arrays, g++'s
# libstdc++) for uninitialised reads, which ASan does not see, and leaks:
# the suites that build, insert, erase and move trees, insert_disjoint's
# lanes on handles (test_lazy_handles), the two editions against each
# other, and bvh.out's runs. (The predicates, the reader, construct()'s
# threads, test_disjoint's lanes and the fault injection of test_exceptions
# are ASan's and ThreadSanitizer's: their memory is checked there.) Two
# streams side by side, each starting as soon as its programs are built
# (the build marks each: $BUILD/NAME.built): three suites of
# build/test_units, then bvh.out's runs; and test_lazy_handles, then
# build/test_editions. The layer is the run's longest chain of work: in one
# stream, it would end after everything else.
VG=(valgrind -q --error-exitcode=99 --leak-check=full --errors-for-leak-kinds=all --show-leak-kinds=all)
# Waits until the build has made each program NAME ($BUILD/NAME.built) or has ended.
wait_built() {
  local name
  for name in "$@"; do
    while [ ! -f "$BUILD/$name.built" ] && [ ! -f "$RESULTS/build-ended" ]; do pause; done
  done
}
valgrind_units() {
  wait_built test_units
  BVH_TEST_SCALE=0.03 run_suite valgrind_test_bvh "${VG[@]}" "$BUILD/test_units" bvh
  BVH_TEST_SCALE=0.05 run_suite valgrind_test_dynamic "${VG[@]}" "$BUILD/test_units" dynamic
  BVH_TEST_SCALE=0.08 run_suite valgrind_test_moving "${VG[@]}" "$BUILD/test_units" moving
  wait_built bvh.out
  run_case valgrind_bulk_build "${VG[@]}" ./bvh.out -i inputs/gen_1000.triangles -o "$OUT/vg_bulk.html" \
    --depth_limit 4 --visualize --print_tree
  run_case valgrind_incremental "${VG[@]}" ./bvh.out -i inputs/gen_1000.quads -o "$OUT/vg_incremental.html" \
    --depth_limit 5 --incremental --visualize
  run_case valgrind_discard_overlap "${VG[@]}" ./bvh.out -i inputs/gen_overlap_1000.disks -o "$OUT/vg_discard.html" \
    --depth_limit 8 --incremental --discard_overlap
  run_case valgrind_generate "${VG[@]}" ./bvh.out --generate triangles 300 --seed 3 -o "$OUT/vg.triangles"
  run_case valgrind_mixed_scene "${VG[@]}" ./bvh.out -i inputs/gen_overlap_1000.shapes -o "$OUT/vg_mixed.html" \
    --depth_limit 6 --incremental --discard_overlap --visualize --print_tree --pairs
}
valgrind_lanes() {
  wait_built test_units
  BVH_TEST_SCALE=0.05 run_suite valgrind_test_lazy_handles "${VG[@]}" "$BUILD/test_units" lazy_handles
  wait_built test_editions
  # (nouserintercepts: the test's own operator new, which fails the copies'
  # allocations one by one, stays in place)
  BVH_TEST_SCALE=0.05 run_suite valgrind_test_editions "${VG[@]}" --soname-synonyms=somalloc=nouserintercepts \
    "$BUILD/test_editions"
}
valgrind_layer() {
  if ! have valgrind; then
    skip "valgrind layer" "valgrind not installed (apt-get install valgrind)"
    return
  fi
  valgrind_units >"$OUT/valgrind_units.txt" &
  valgrind_lanes >"$OUT/valgrind_lanes.txt"
  wait
  cat "$OUT/valgrind_units.txt" "$OUT/valgrind_lanes.txt"
}

# include/bvh/'s rules (docs/design.txt): every header listed, includes
# going one way, every header compiling alone (tests/headers.sh).
headers_layer() {
  JOBS=1 bash tests/headers.sh "$OUT/headers"
}

# The CMake package: install + find_package, and add_subdirectory (tests/cmake_consumer.sh).
cmake_package() {
  bash tests/cmake_consumer.sh "$OUT/cmake" >"$LOGS/cmake_consumer.log" 2>&1
  relay "cmake_*" "$LOGS/cmake_consumer.log"
}

# libFuzzer for FUZZ_SECONDS on the parser, the tree and the command line
# (make fuzz runs the same target, built at -O1; this build is -O0's, which
# compiles in a third of the time); skipped with a notice without clang's
# libFuzzer.
fuzz() {
  if [ "$HAVE_FUZZER" != yes ]; then
    skip fuzz_parser "clang++ with libFuzzer is not installed (apt-get install clang libclang-rt-14-dev)"
    return
  fi
  if [ ! -x "$BUILD/fuzz_parser_O0" ]; then
    bad fuzz_parser_build "see $LOGS/build.log"
    return
  fi
  mkdir -p "$BUILD/fuzz-work"
  local LOG
  logname fuzz_parser
  if "$BUILD/fuzz_parser_O0" -max_total_time="${FUZZ_SECONDS:-10}" -print_final_stats=1 \
    -artifact_prefix="$BUILD/fuzz-crash-" "$BUILD/fuzz-work" tests/fuzz_corpus >"$LOG" 2>&1; then
    ok "fuzz_parser_${FUZZ_SECONDS:-10}s_$(grep -o 'number_of_executed_units: [0-9]*' "$LOG" | grep -o '[0-9]*$')_runs"
  else
    bad fuzz_parser "a finding: see $LOG and $BUILD/fuzz-crash-*"
  fi
}

# ---------------------------------------------------------------------------
# 1. The build: every binary the layers run, in one make -k -j$JOBS; g++'s
# and clang++'s builds must be free of warnings (-Wall -Wextra -pedantic).
# (--quick: only bvh.out and make check's unit tests.) While it runs, a line
# every $HEARTBEAT seconds says how many of its compiles have finished.
HAVE_LIBCXX=no
HAVE_FUZZER=no
if [ "$QUICK" = no ] && have clang++; then
  echo '#include <vector>
int main() { return int(std::vector<int>(1).size()) - 1; }' |
    clang++ -std=c++17 -stdlib=libc++ -fsanitize=address,undefined -x c++ - -o "$BUILD/libcxx-probe" \
      >/dev/null 2>&1 && "$BUILD/libcxx-probe" && HAVE_LIBCXX=yes
  echo 'extern "C" int LLVMFuzzerTestOneInput(const char *, unsigned long) { return 0; }' |
    clang++ -x c++ -fsanitize=fuzzer - -o "$BUILD/fuzz-probe" >/dev/null 2>&1 && HAVE_FUZZER=yes
  rm -f "$BUILD/libcxx-probe" "$BUILD/fuzz-probe"
fi
if [ "$QUICK" = no ] && ! have clang++; then
  skip "clang++ builds" "clang++ not installed (apt-get install clang): the libc++ build, the fuzzer and clang++'s course-framework build are skipped; g++ builds the sanitizer tests" |
    tee "$RESULTS/build_notices.txt"
fi
# One make, the longest compiles first, so that -j ends on short ones;
# first the programs the valgrind layer runs, each marked when linked
# ($BUILD/NAME.built; marked here already when up to date): the layer's two
# streams, the run's longest chain of work, start beside the rest of the
# build as soon as their programs are there.
targets=()
if [ "$QUICK" = yes ]; then
  rm -f "$BUILD"/check/test_*.out # make runs each unit test again
  # (The folder made first: a target waiting for it would let make -j start
  # shorter compiles before the longest.)
  mkdir -p "$BUILD/check"
  targets+=(check-build)
  # The unit programs: clang++ at -O0 when installed (see the Makefile's
  # CHECK_CXX), else the Makefile's default (CXX at -Og).
  if have clang++; then
    export CHECK_CXX=clang++ CHECK_CXXFLAGS="-std=c++17 -O0 -Wall -Wextra -pedantic"
  fi
else
  for prog in "$BUILD/test_units" "$BUILD/test_editions" bvh.out; do
    rm -f "$BUILD/${prog##*/}.built"
    if $MAKE --no-print-directory -q "$prog" 2>/dev/null; then : >"$BUILD/${prog##*/}.built"; fi
  done
  targets+=("$BUILD/test_units" "$BUILD/test_exceptions" bvh.out "$BUILD/test_editions" "$BUILD/bvh_san.out")
  [ "$HAVE_FUZZER" = yes ] && targets+=("$BUILD/fuzz_parser_O0")
  targets+=(test-build-san test-build-gcc)
fi
# A compile is a recipe line that starts with a compiler (make -n lists those to do).
compile_re="^($(printf '%s' "$CXX" | sed 's/[+.]/\\&/g')|g\+\+|clang\+\+) "
# The sanitizer builds: clang++ with libc++ when they work (also the libc++
# build then), else g++.
if [ "$HAVE_LIBCXX" = yes ]; then SAN_CXX="clang++ -stdlib=libc++"; else SAN_CXX=$CXX; fi
export SAN_CXX
# The ThreadSanitizer builds: clang++ when it has ThreadSanitizer (it
# compiles and runs them in about 60% of g++'s time), else g++.
TSAN_CXX=$CXX
if [ "$QUICK" = no ] && have clang++; then
  echo 'int main() { return 0; }' | clang++ -fsanitize=thread -x c++ - -o "$BUILD/tsan-probe" >/dev/null 2>&1 &&
    "$BUILD/tsan-probe" && TSAN_CXX=clang++
  rm -f "$BUILD/tsan-probe"
fi
export TSAN_CXX
# The examples and test_asserts (-O0): clang++ when installed, else g++.
EXAMPLE_CXX=$CXX
[ "$QUICK" = no ] && have clang++ && EXAMPLE_CXX=clang++
export EXAMPLE_CXX
todo=$($MAKE --no-print-directory -n -k "${targets[@]}" 2>/dev/null | grep -cE "$compile_re")
echo "building: $MAKE -k -j$JOBS ${targets[*]}: $todo compiles to do (log: $LOGS/build.log)"
build_start=$SECONDS
# (The build's results go to $RESULTS/build.txt too; not through a pipe, so
# that a layer started during the build is this shell's.)
build_result() { "$@" | tee -a "$RESULTS/build.txt"; }
VALGRIND_EARLY=no
rm -f "$RESULTS/build-ended"
(
  $MAKE --no-print-directory -k -j"$JOBS" --output-sync=target "${targets[@]}"
  rc=$?
  : >"$RESULTS/build-ended"
  exit $rc
) >"$LOGS/build.log" 2>&1 &
make_pid=$!
last=$SECONDS
while kill -0 "$make_pid" 2>/dev/null; do
  pause
  if [ "$VALGRIND_EARLY" = no ] && [ "$QUICK" = no ] && [ -f "$BUILD/test_units.built" ]; then
    VALGRIND_EARLY=yes
    echo "   (the first unit suites are built: valgrind starts beside the rest of the build, $((SECONDS - build_start)) s)"
    layer valgrind valgrind_layer
  fi
  if [ $((SECONDS - last)) -ge "$HEARTBEAT" ]; then
    echo "   ... building: $(grep -cE "$compile_re" "$LOGS/build.log") of $todo compiles done ($((SECONDS - build_start)) s)"
    last=$SECONDS
  fi
done
: >"$RESULTS/build-ended"
if wait "$make_pid"; then
  build_result ok "build_$((SECONDS - build_start))s"
else
  build_result bad build "make failed: see $LOGS/build.log"
fi
if grep -qE 'warning:' "$LOGS/build.log"; then
  build_result bad compiles_without_warnings "$(grep -m 3 -E 'warning:' "$LOGS/build.log" | tr '\n' ' ')"
else
  build_result ok compiles_without_warnings
fi

# 2. The layers, longest first (they run JOBS at a time; valgrind may have
# started during the build).
if [ "$QUICK" = yes ]; then
  layer unit unit_tests_quick
  layer golden golden
else
  [ "$VALGRIND_EARLY" = yes ] || layer valgrind valgrind_layer
  layer sanitizers sanitizers
  layer unit unit_tests
  layer course_framework course_framework
  layer cmake cmake_package
  layer headers headers_layer
  layer tsan tsan
  layer fuzz fuzz
  layer browser browser
  layer cli_errors cli_errors
  layer python_model python_model
  layer cli_threads cli_threads
  layer cli_widths cli_widths
  layer golden golden
  layer cli_output cli_output
  layer demo demo_layer
  layer examples examples
  layer asserts asserts
fi
finish_layers

# ---------------------------------------------------------------------------
results=("$RESULTS/build.txt")
[ -f "$RESULTS/build_notices.txt" ] && results+=("$RESULTS/build_notices.txt")
for ((i = 0; i < ${#LAYERS[@]}; i++)); do results+=("$RESULTS/$i.txt"); done
passed=$(cat "${results[@]}" | awk '/^ok /{n++} /^ok-suite /{sub(/:/,"",$2); n+=$3} END{print n+0}')
failed=$(cat "${results[@]}" | grep -c '^FAIL ')
skipped=$(cat "${results[@]}" | grep -c '^skipped ')
echo
[ "$skipped" -gt 0 ] && echo "($skipped skipped: see the notices above)"
echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
