#!/usr/bin/env bash
# tests/cli_output.sh DIR [BINARY] — large-scene options of bvh.out:
# --no_output (statistics as usual, no file written) and the progress line,
# which appears on stderr only when stderr is a terminal (a pseudo-terminal
# here, tests/stderr_on_tty.py), never in redirected output and never on
# stdout. BVH_PROGRESS_DELAY=0 makes it show from the start (the default
# waits a second). Prints `ok NAME` or `FAIL NAME why` per case.
set -u
# (tests/run.sh sets PYTHON: python3 found once, past any version manager's shim)
PYTHON=${PYTHON:-python3}
cd "$(dirname "$0")/.."
dir=${1:-build/test-out/cli_output}
bin=${2:-./bvh.out}
rm -rf "$dir"
mkdir -p "$dir/empty"
dir=$(cd "$dir" && pwd)
bin=$(cd "$(dirname "$bin")" && pwd)/$(basename "$bin")
src=$(pwd)
case_() { if eval "$2"; then echo "ok $1"; else echo "FAIL $1 ${3:-}"; fi; }

# --no_output: the golden statistics (checked by hand), and no file at all.
golden=expected_output/inputs/gen_discard_overlap_1000_triangles.txt
(cd "$dir/empty" && "$bin" -i "$src/inputs/gen_overlap_1000.triangles" --depth_limit 8 --incremental --discard_overlap \
  --print_tree --no_output >"$dir/no_output.txt" 2>"$dir/no_output.err")
rc=$?
case_ no_output_prints_the_golden_statistics "[ $rc -eq 0 ] && cmp -s '$dir/no_output.txt' '$golden' && [ ! -s '$dir/no_output.err' ]" \
  "exit $rc; diff $dir/no_output.txt $golden"
case_ no_output_writes_no_file "[ -z \"\$(ls -A '$dir/empty')\" ]" "left: $(ls -A "$dir/empty" | head -c 200)"
"$bin" -i inputs/gen_overlap_1000.shapes --depth_limit 6 --pairs --no_output >"$dir/no_output_pairs.txt" 2>&1
"$bin" -i inputs/gen_overlap_1000.shapes --depth_limit 6 --pairs -o "$dir/pairs.html" >"$dir/with_output_pairs.txt" 2>&1
case_ no_output_prints_what_o_prints "cmp -s '$dir/no_output_pairs.txt' '$dir/with_output_pairs.txt' && grep -q '^overlapping pairs: ' '$dir/no_output_pairs.txt'"

# Progress: with stderr on a terminal, every stage shows; stdout stays clean.
"$PYTHON" -S tests/stderr_on_tty.py "$dir/tty_stdout.txt" env BVH_PROGRESS_DELAY=0 "$bin" -i inputs/gen_overlap_1000.disks \
  -o "$dir/tty.html" --depth_limit 8 --incremental --discard_overlap --print_tree >"$dir/tty_stderr.txt" 2>&1
rc=$?
"$PYTHON" -S tests/stderr_on_tty.py "$dir/tty_bulk_stdout.txt" env BVH_PROGRESS_DELAY=0 "$bin" -i inputs/gen_1000.quads \
  -o "$dir/tty_bulk.html" --depth_limit 4 --pairs >"$dir/tty_bulk_stderr.txt" 2>&1
rc2=$?
case_ progress_on_a_terminal_shows_reading_sampling_writing "[ $rc -eq 0 ] && grep -q 'bvh.out: reading inputs/gen_overlap_1000.disks: .* of 0.1 MB' '$dir/tty_stderr.txt' &&
  grep -q 'bvh.out: sampling: ' '$dir/tty_stderr.txt' && grep -q 'bvh.out: writing $dir/tty.html' '$dir/tty_stderr.txt'" \
  "exit $rc; see $dir/tty_stderr.txt"
case_ progress_on_a_terminal_shows_building_and_pairs "[ $rc2 -eq 0 ] && grep -q 'bvh.out: building the tree of 1000 shapes' '$dir/tty_bulk_stderr.txt' &&
  grep -q 'bvh.out: counting overlapping pairs' '$dir/tty_bulk_stderr.txt'" "exit $rc2; see $dir/tty_bulk_stderr.txt"
# The line is cleared at the end: the last thing on the terminal is the erase sequence.
case_ progress_line_is_cleared_at_the_end "[ \"\$(tail -c 4 '$dir/tty_stderr.txt' | od -An -c | tr -d ' ')\" = '\\r033[K' ]" \
  "ends with: $(tail -c 20 "$dir/tty_stderr.txt" | od -An -c | tr -s ' ')"
case_ progress_never_on_stdout "cmp -s '$dir/tty_stdout.txt' expected_output/inputs/gen_discard_overlap_1000_disks.txt" \
  "diff $dir/tty_stdout.txt expected_output/inputs/gen_discard_overlap_1000_disks.txt"
# Redirected stderr: not a byte of progress, even with no delay.
BVH_PROGRESS_DELAY=0 "$bin" -i inputs/gen_overlap_1000.disks -o "$dir/redirected.html" --depth_limit 8 --incremental \
  --discard_overlap --print_tree >"$dir/redirected.txt" 2>"$dir/redirected.err"
case_ progress_never_in_redirected_output "[ ! -s '$dir/redirected.err' ] && cmp -s '$dir/redirected.txt' '$dir/tty_stdout.txt' &&
  ! grep -q 'bvh.out:' '$dir/redirected.txt'" "stderr: $(head -c 200 "$dir/redirected.err")"
# Without BVH_PROGRESS_DELAY a run shorter than a second shows nothing, even on a terminal.
"$PYTHON" -S tests/stderr_on_tty.py "$dir/quick_stdout.txt" "$bin" -i inputs/gen_36.disks -o "$dir/quick.html" --depth_limit 2 \
  >"$dir/quick_stderr.txt" 2>&1
case_ progress_not_shown_for_a_quick_run "[ ! -s '$dir/quick_stderr.txt' ]" "got: $(head -c 200 "$dir/quick_stderr.txt" | od -An -c | head -3)"

# --generate on a terminal: the shapes placed and the tries made, then the
# writing; redirected, nothing; the scene is the same either way.
"$PYTHON" -S tests/stderr_on_tty.py "$dir/gen_tty_stdout.txt" env BVH_PROGRESS_DELAY=0 "$bin" --generate disks 100000 --seed 2 \
  -o "$dir/gen_tty.disks" >"$dir/gen_tty_stderr.txt" 2>&1
rc=$?
BVH_PROGRESS_DELAY=0 "$bin" --generate disks 100000 --seed 2 -o "$dir/gen_redirected.disks" >"$dir/gen_redirected.txt" \
  2>"$dir/gen_redirected.err"
rc2=$?
case_ progress_on_a_terminal_shows_generating_and_writing "[ $rc -eq 0 ] &&
  grep -qE 'bvh.out: generating 100000 disks: [0-9]+ of 100000 shapes \\([0-9]+%\\), [0-9]+ tries' '$dir/gen_tty_stderr.txt' &&
  grep -q 'bvh.out: writing $dir/gen_tty.disks' '$dir/gen_tty_stderr.txt' &&
  [ \"\$(tail -c 4 '$dir/gen_tty_stderr.txt' | od -An -c | tr -d ' ')\" = '\\r033[K' ]" \
  "exit $rc; see $dir/gen_tty_stderr.txt"
case_ generate_progress_never_in_redirected_output "[ $rc2 -eq 0 ] && [ ! -s '$dir/gen_redirected.err' ] &&
  [ ! -s '$dir/gen_redirected.txt' ] && [ ! -s '$dir/gen_tty_stdout.txt' ] &&
  cmp -s '$dir/gen_tty.disks' '$dir/gen_redirected.disks'" "stderr: $(head -c 200 "$dir/gen_redirected.err")"
