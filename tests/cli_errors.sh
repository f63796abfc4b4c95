#!/usr/bin/env bash
# tests/cli_errors.sh DIR [BINARY [TAG]] — bvh.out on wrong command lines and
# wrong scenes. Each case expects an exit status, a message on stderr
# matching a pattern, and no output file left behind (neither the picture nor
# its temporary; an existing one stays untouched). Prints `ok NAME` or
# `FAIL NAME why` per case, NAME ending in TAG; run by tests/run.sh once on
# ./bvh.out and once on the ASan/UBSan build (a sanitizer report makes the
# exit status or stderr differ, so the case fails).
set -u
cd "$(dirname "$0")/.."
dir=${1:-build/test-out/cli}
bin=${2:-./bvh.out}
tag=${3:-}
rm -rf "$dir"
mkdir -p "$dir"
good=inputs/gen_36.disks

# expect NAME STATUS PATTERN -- ARGS...   (the output is $dir/out.html)
expect() {
  local name=$1$tag status=$2 pattern=$3
  shift 4
  rm -f "$dir"/out.html "$dir"/*.partial
  timeout 60 "$bin" "$@" >"$dir/stdout" 2>"$dir/stderr"
  local rc=$?
  # stderr's lines: messages ("bvh.out: "), the usage's, others; and any
  # sanitizer report. (Counted in the shell: a case runs no more processes
  # than it needs, each being dear on some hosts.)
  local lines=() line messages=0 others=0 report=no partial=("$dir"/*.partial)
  mapfile -t lines <"$dir/stderr"
  for line in "${lines[@]}"; do
    case $line in
      "bvh.out: "*) messages=$((messages + 1)) ;;
      "usage: "* | "       bvh.out "* | "               "*) ;;
      *) others=$((others + 1)) ;;
    esac
    case $line in *"runtime error"* | *AddressSanitizer* | *LeakSanitizer*) report=yes ;; esac
  done
  if [ "$rc" -ne "$status" ]; then
    echo "FAIL $name exit $rc, expected $status: $(head -c 200 "$dir/stderr")"
  elif ! grep -qE -- "$pattern" "$dir/stderr"; then
    echo "FAIL $name stderr does not match /$pattern/: $(head -c 200 "$dir/stderr")"
  elif [ "$status" -ne 0 ] && { [ "$messages" -ne 1 ] || [ "$others" -ne 0 ]; }; then
    echo "FAIL $name stderr is not one message (plus the usage): $(head -c 300 "$dir/stderr")"
  elif [ "$status" -ne 0 ] && [ "$report" = yes ]; then
    echo "FAIL $name stderr does not match /$pattern/: $(head -c 200 "$dir/stderr")"
  elif [ "$status" -ne 0 ] && { [ -e "$dir/out.html" ] || [ -e "${partial[0]}" ]; }; then
    echo "FAIL $name an output file was left behind"
  else
    echo "ok $name"
  fi
}

o=$dir/out.html
mkdir -p "$dir/dir.disks"
expect cli_unknown_flag 2 "unknown argument '--bogus'" -- -i $good -o "$o" --bogus
expect cli_flag_missing_value 2 "--depth_limit needs a value" -- -i $good -o "$o" --depth_limit
expect cli_non_integer_threshold 2 "--split_threshold needs an integer" -- -i $good -o "$o" --split_threshold abc
expect cli_threshold_zero 2 "--split_threshold needs an integer from 1" -- -i $good -o "$o" --split_threshold 0
expect cli_negative_depth 2 "--depth_limit needs an integer from 0" -- -i $good -o "$o" --depth_limit -1
expect cli_trailing_junk_number 2 "--depth_limit needs an integer" -- -i $good -o "$o" --depth_limit 3x
expect cli_missing_input_flag 2 "missing -i" -- -o "$o"
expect cli_missing_output_flag 2 "missing -o" -- -i $good
# No arguments: the first thing missing, -i, and the usage (checked on stderr's last line).
expect cli_no_arguments_names_the_input_first 2 "missing -i INPUT" --
if "$bin" 2>&1 >/dev/null | grep -q "^usage: bvh.out"; then echo "ok cli_no_arguments_prints_the_usage$tag"; else
  echo "FAIL cli_no_arguments_prints_the_usage$tag no usage on stderr"; fi
expect cli_unknown_suffix 2 "unknown input kind" -- -i tests/golden.list -o "$o"
expect cli_missing_input_file 2 "cannot open" -- -i "$dir/nothing.disks" -o "$o"
expect cli_discard_without_incremental 2 "needs --incremental" -- -i $good -o "$o" --discard_overlap
expect cli_unwritable_output 2 "cannot write" -- -i $good -o "$dir/no/such/dir/out.html"
expect cli_output_not_html 2 "must end in .html or .svg" -- -i $good -o "$dir/out.txt"
expect cli_generate_bad_kind 2 "needs a kind" -- --generate circles 10 -o "$dir/x.circles"
expect cli_usage_shows_on_error 2 "^usage: bvh.out" -- --nonsense
expect cli_input_flag_missing_value 2 "-i needs a value|--input needs a value" -- -o "$o" -i
expect cli_output_flag_missing_value 2 "-o needs a value|--output needs a value" -- -i $good -o
expect cli_negative_threshold 2 "--split_threshold needs an integer from 1" -- -i $good -o "$o" --split_threshold -4
expect cli_width_five 2 "--width needs 2, 3, 4 or 8, not '5'" -- -i $good -o "$o" --width 5
expect cli_width_sixteen 2 "--width needs 2, 3, 4 or 8, not '16'" -- -i $good -o "$o" --width 16
expect cli_width_not_a_number 2 "--width needs 2, 3, 4 or 8, not 'x'" -- -i $good -o "$o" --width x
expect cli_width_missing_value 2 "--width needs a value" -- -i $good -o "$o" --width
# The default build has the course's width 3 alone, and --help says so:
# --width 2, 4 or 8 is then refused with the way to build them, no file
# written. A build with every width (make WIDTHS=all; make test's sanitized
# one) runs them.
if "$bin" --help | grep -q "has the course's width 3 alone"; then
  for w in 2 4 8; do
    expect cli_width_${w}_not_built_says_how_to_build_it 2 \
      "^bvh.out: --width $w: this bvh.out has the course's width 3 alone; make WIDTHS=all \(CMake: -DBVH_CLI_ALL_WIDTHS=ON\) builds 2, 4 and 8 too$" \
      -- -i $good -o "$o" --width $w
  done
else
  for w in 2 4 8; do
    rm -f "$o"
    if "$bin" -i $good -o "$o" --width $w --depth_limit 3 >"$dir/stdout" 2>"$dir/stderr" && [ ! -s "$dir/stderr" ] &&
      grep -q "^node count:" "$dir/stdout" && grep -q "</svg>" "$o"; then
      echo "ok cli_width_${w}_built_and_runs$tag"
    else
      echo "FAIL cli_width_${w}_built_and_runs$tag $(head -c 200 "$dir/stderr")"
    fi
  done
fi
expect cli_fractional_depth 2 "--depth_limit needs an integer" -- -i $good -o "$o" --depth_limit 2.5
expect cli_huge_number 2 "--split_threshold needs an integer" -- -i $good -o "$o" --split_threshold 99999999999999999999
# The limits' extremes: up to INT_MAX, which the library takes (a tree of
# one leaf); one past it, or past any integer, is a usage error.
expect cli_threshold_past_int_max 2 "--split_threshold needs an integer from 1 to 2147483647, not '2147483648'" -- \
  -i $good -o "$o" --split_threshold 2147483648
expect cli_depth_past_int_max 2 "--depth_limit needs an integer from 0 to 2147483647, not '99999999999'" -- \
  -i $good -o "$o" --depth_limit 99999999999
expect cli_threads_past_unsigned 2 "--threads needs an integer from 1 to 1024, not '4294967297'" -- \
  -i $good -o "$o" --threads 4294967297
for mode in "" --incremental "--incremental --discard_overlap"; do
  name=cli_int_max_limits${mode:+_${mode//[- ]/}}
  # shellcheck disable=SC2086 # (mode: words)
  if timeout 60 "$bin" -i $good -o "$o" --split_threshold 2147483647 --depth_limit 2147483647 $mode --print_tree --pairs \
    >"$dir/stdout" 2>"$dir/stderr" && grep -q "^node count:            1$" "$dir/stdout" &&
    grep -q "^overlapping pairs: 0$" "$dir/stdout" && [ ! -s "$dir/stderr" ] && grep -q "</svg>" "$o"; then
    echo "ok $name$tag"
  else
    echo "FAIL $name$tag $(head -c 300 "$dir/stderr")"
  fi
done
if timeout 60 "$bin" -i inputs/gen_overlap_1000.disks --no_output --split_threshold 1 --depth_limit 2147483647 --incremental \
  --pairs >"$dir/stdout" 2>"$dir/stderr" && [ ! -s "$dir/stderr" ] &&
  [ "$("$bin" -i inputs/gen_overlap_1000.disks --no_output --pairs)" = "$(grep '^overlapping pairs' "$dir/stdout")" ]; then
  echo "ok cli_threshold_one_unlimited_depth$tag"
else
  echo "FAIL cli_threshold_one_unlimited_depth$tag $(head -c 300 "$dir/stderr")"
fi
expect cli_empty_number 2 "--depth_limit needs (a value|an integer)" -- -i $good -o "$o" --depth_limit ""
expect cli_output_under_a_file 2 "cannot write" -- -i $good -o "$good/out.html"
expect cli_input_is_a_directory 2 "cannot open|cannot read|is a directory" -- -i "$dir/dir.disks" -o "$o"
expect cli_generate_negative_count 2 "--generate" -- --generate disks -5 -o "$dir/x.disks"
expect cli_generate_missing_count 2 "--generate" -- --generate disks
expect cli_no_output_with_output 2 "--no_output and -o exclude each other" -- -i $good --no_output -o "$o"
expect cli_generate_with_no_output 2 "--generate needs -o SCENE, not --no_output" -- --generate disks 10 --no_output
expect cli_no_output_missing_input_file 2 "cannot open" -- -i "$dir/nothing.disks" --no_output
expect cli_control_bytes_in_argument_stay_one_line 2 "unknown argument 'a\\\\x0ab'" -- "$(printf 'a\nb')" -o "$o"

# A near miss gets the nearest option (edit distance, '-' for '_' free); a
# scene name without -i gets the -i; a word near nothing gets no guess.
expect cli_unknown_flag_suggests_nearest 2 "unknown argument '--depth-limit'; did you mean --depth_limit\?" -- \
  -i $good -o "$o" --depth-limit 2
expect cli_misspelt_flag_suggests_nearest 2 "unknown argument '--visualise'; did you mean --visualize\?" -- \
  -i $good -o "$o" --visualise
expect cli_single_dash_flag_suggests_nearest 2 "did you mean --print_tree\?" -- -i $good -o "$o" -print_tree
expect cli_scene_without_i_suggests_i 2 "unknown argument 'gen_36.disks'; did you mean -i gen_36.disks\?" -- \
  gen_36.disks -o "$o"
expect cli_far_word_gets_no_guess 2 "unknown argument '--bogus'\$" -- -i $good -o "$o" --bogus
expect cli_thread_suggests_threads 2 "unknown argument '--thread'; did you mean --threads\?" -- -i $good -o "$o" --thread 2
expect cli_widht_suggests_width 2 "unknown argument '--widht'; did you mean --width\?" -- -i $good -o "$o" --widht 3
# Every option --help lists, its last letter dropped, gets that option.
options=$("$bin" --help | grep -oE -- '--[a-z_]+' | sort -u)
missed=
for opt in $options; do
  timeout 60 "$bin" "${opt%?}" >/dev/null 2>"$dir/stderr"
  grep -qF "unknown argument '${opt%?}'; did you mean $opt?" "$dir/stderr" || missed="$missed $opt"
done
if [ -n "$options" ] && [ -z "$missed" ]; then echo "ok cli_every_option_near_miss_suggests_it$tag"; else
  echo "FAIL cli_every_option_near_miss_suggests_it$tag no suggestion for:${missed:- (no options in --help)}"; fi
# A file that cannot be opened or written: its one line, without the usage.
one_line() { # NAME: the last case's stderr is exactly one line
  if [ "$(wc -l <"$dir/stderr")" -eq 1 ] && ! grep -q '^usage:' "$dir/stderr"; then echo "ok $1$tag"; else
    echo "FAIL $1$tag stderr is not one line: $(head -c 300 "$dir/stderr")"; fi
}
expect cli_missing_input_file_message 2 "^bvh.out: $dir/nothing.disks: cannot open: No such file or directory\$" -- \
  -i "$dir/nothing.disks" -o "$o"
one_line cli_missing_input_file_prints_one_line
expect cli_unwritable_output_message 2 "cannot write" -- -i $good -o "$dir/no/such/dir/out.html"
one_line cli_unwritable_output_prints_one_line
# --generate refuses at once what a packing bound says cannot fit (the issue's
# example: 1M disks of radius 50-60 took 2.5 minutes to fail), and writes nothing.
rm -f "$dir/x.disks"
start=$(date +%s%N)
timeout 60 "$bin" --generate disks 1000000 --size 50:60 -o "$dir/x.disks" >"$dir/stdout" 2>"$dir/stderr"
rc=$?
ms=$((($(date +%s%N) - start) / 1000000))
if [ $rc -eq 2 ] && [ $ms -lt 2000 ] && [ ! -e "$dir/x.disks" ] && ! ls "$dir"/*.partial >/dev/null 2>&1 &&
  grep -qE "^bvh.out: 1000000 disks of radius at least 50 cannot fit in the 1000 x 1000 canvas without touching: a packing bound allows at most 113 " "$dir/stderr" &&
  [ "$(wc -l <"$dir/stderr")" -eq 1 ]; then
  echo "ok cli_generate_refuses_what_cannot_fit_at_once$tag"
else
  echo "FAIL cli_generate_refuses_what_cannot_fit_at_once$tag exit $rc after $ms ms: $(head -c 300 "$dir/stderr")"
fi
expect cli_generate_refuses_quads_past_the_bound 2 "cannot fit .* at most" -- --generate quads 5000 --size 30:40 -o "$dir/x.quads"
# At the bound it is not refused: it tries, and reports what it placed.
expect cli_generate_at_the_bound_tries 1 "could place only [0-9]+ of 113 non-overlapping shapes" -- \
  --generate disks 113 --size 50:60 -o "$dir/x.disks"
# --overlap has no bound.
rm -f "$dir/x.disks"
if "$bin" --generate disks 1000 --size 50:60 --overlap -o "$dir/x.disks" 2>"$dir/stderr" && [ "$(wc -l <"$dir/x.disks")" -eq 1000 ]; then
  echo "ok cli_generate_overlap_has_no_bound$tag"
else
  echo "FAIL cli_generate_overlap_has_no_bound$tag $(head -c 300 "$dir/stderr")"
fi

# Wrong scenes: FILE:LINE: message, exit 1, no picture.
bad_scene() { # NAME SUFFIX PATTERN CONTENT
  local f=$dir/$1.$2
  printf '%b' "$4" >"$f"
  expect "$1" 1 "$3" -- -i "$f" -o "$o"
}
bad_scene input_not_a_number disks "\.disks:2: expected a coordinate" \
  'pt= <1 2> radius= 3 color= {1 2 3}\npt= <x 2> radius= 3 color= {1 2 3}\n'
bad_scene input_nan disks "\.disks:1: a coordinate is not a finite number" 'pt= <nan 2> radius= 3 color= {1 2 3}\n'
bad_scene input_negative_radius disks "\.disks:1: negative radius" 'pt= <1 2> radius= -3 color= {1 2 3}\n'
bad_scene input_colour_out_of_range triangles "\.triangles:1: expected a colour channel" \
  'pt= <1 2> pt= <3 4> pt= <5 6> color= {1 256 3}\n'
bad_scene input_too_few_points quads "\.quads:1: expected 'pt='" 'pt= <1 2> pt= <3 4> pt= <5 6> color= {1 2 3}\n'
bad_scene input_too_many_points triangles "\.triangles:1: expected 'color='" \
  'pt= <1 2> pt= <3 4> pt= <5 6> pt= <7 8> color= {1 2 3}\n'
bad_scene input_wrong_kind_line triangles "\.triangles:1: expected 'pt='" 'pt= <1 2> radius= 3 color= {1 2 3}\n'
bad_scene input_missing_bracket disks "\.disks:1: expected '>'" 'pt= <1 2 radius= 3 color= {1 2 3}\n'
bad_scene input_trailing_text disks "\.disks:1: unexpected 'extra' after the shape" \
  'pt= <1 2> radius= 3 color= {1 2 3} extra\n'
bad_scene input_binary_garbage disks "\.disks:1: expected 'pt=', found byte 0x" '\x01\x02\xff\n'
bad_scene input_huge_coordinate disks "\.disks:1: a coordinate beyond" 'pt= <1e12 2> radius= 3 color= {1 2 3}\n'
bad_scene input_infinite_value disks "\.disks:1: a coordinate is not a finite number" 'pt= <1 inf> radius= 3 color= {1 2 3}\n'
bad_scene input_infinite_radius disks "\.disks:1: a radius out of range" 'pt= <1 2> radius= 1e39 color= {1 2 3}\n'
# Past float's range at either end (the library would refuse 1e300 and
# 1e-300: outside [2^-200, 2^200]; the reader stops them first, at the line).
bad_scene input_coordinate_1e300 triangles "\.triangles:2: a coordinate out of range: '1e300'" \
  'pt= <1 2> pt= <3 4> pt= <5 6> color= {1 2 3}\npt= <1 2> pt= <1e300 4> pt= <5 6> color= {1 2 3}\n'
bad_scene input_coordinate_1e-300 quads "\.quads:1: a coordinate out of range: '1e-300'" \
  'pt= <1 2> pt= <3 4> pt= <5 6> pt= <1e-300 8> color= {1 2 3}\n'
bad_scene input_mixed_nan_radius shapes "\.shapes:1: a radius is not a finite number: 'NaN'" \
  'pt= <1 2> radius= NaN color= {1 2 3}\n'
bad_scene input_missing_open_bracket disks "\.disks:1: expected '<'" 'pt= 1 2> radius= 3 color= {1 2 3}\n'
bad_scene input_missing_open_brace quads "\.quads:1: expected '\{'" \
  'pt= <1 2> pt= <3 4> pt= <5 6> pt= <7 8> color= 1 2 3}\n'
bad_scene input_missing_close_brace disks "\.disks:1: expected '\}'" 'pt= <1 2> radius= 3 color= {1 2 3\n'
bad_scene input_missing_keyword disks "\.disks:1: expected 'radius='" 'pt= <1 2> 3 color= {1 2 3}\n'
bad_scene input_misspelt_keyword disks "\.disks:1: expected 'color='" 'pt= <1 2> radius= 3 colour= {1 2 3}\n'
bad_scene input_negative_colour disks "\.disks:1: expected a colour channel" 'pt= <1 2> radius= 3 color= {1 -2 3}\n'
bad_scene input_fractional_colour disks "\.disks:1: expected a colour channel" 'pt= <1 2> radius= 3 color= {1 2.5 3}\n'
bad_scene input_too_few_colour_channels disks "\.disks:1: expected a colour channel" 'pt= <1 2> radius= 3 color= {1 2}\n'
bad_scene input_disk_line_in_quads quads "\.quads:1: expected 'pt='" 'pt= <1 2> radius= 3 color= {1 2 3}\n'
bad_scene input_nul_byte triangles "\.triangles:1: " 'pt= <1\x002> pt= <3 4> pt= <5 6> color= {1 2 3}\n'
bad_scene input_invalid_utf8 disks "\.disks:1: " 'pt= <1 2> radius= 3 color= {1 2 3} \xc3\x28\n'
bad_scene input_error_line_number_after_blank_and_crlf_lines disks "\.disks:4: negative radius" \
  'pt= <1 2> radius= 3 color= {1 2 3}\r\n\r\n\npt= <1 2> radius= -1 color= {1 2 3}\r\n'
bad_scene input_truncated_last_line disks "\.disks:2: " 'pt= <1 2> radius= 3 color= {1 2 3}\npt= <1 2> rad'
# Mixed scenes (.shapes): each line's form says its kind; a form that is
# none of the three is an error at its first wrong token.
bad_scene input_mixed_one_point_no_radius shapes "\.shapes:2: expected 'radius=' or 'pt=', found 'color='" \
  'pt= <1 2> radius= 3 color= {1 2 3}\npt= <1 2> color= {1 2 3}\n'
bad_scene input_mixed_two_points shapes "\.shapes:1: expected 'pt=' \(a triangle or quad has 3 or 4 points\)" \
  'pt= <1 2> pt= <3 4> color= {1 2 3}\n'
bad_scene input_mixed_radius_after_three_points shapes "\.shapes:1: expected 'pt=' or 'color=', found 'radius='" \
  'pt= <1 2> pt= <3 4> pt= <5 6> radius= 3 color= {1 2 3}\n'
bad_scene input_mixed_five_points shapes "\.shapes:3: expected 'color=', found 'pt='" \
  'pt= <1 2> pt= <3 4> pt= <5 6> color= {1 2 3}\npt= <1 2> pt= <3 4> pt= <5 6> pt= <7 8> color= {1 2 3}\npt= <1 2> pt= <3 4> pt= <5 6> pt= <7 8> pt= <9 9> color= {1 2 3}\n'
bad_scene input_mixed_negative_radius shapes "\.shapes:1: negative radius" 'pt= <1 2> radius= -3 color= {1 2 3}\n'
bad_scene input_mixed_garbage shapes "\.shapes:1: expected 'pt=', found byte 0x" '\x01\x02\xff\n'
long_line=$(printf 'pt= <1 2> radius= 3 color= {1 2 3}%5000s' '')
bad_scene input_over_long_line disks "\.disks:1: line longer than" "$long_line\n"

expect cli_generate_shapes_wrong_suffix 2 "must end in \.shapes" -- --generate shapes 10 -o "$dir/x.disks"

# --threads N: 1 to 1024 (the default is all cores).
expect cli_threads_zero 2 "--threads needs an integer from 1 to 1024, not '0'" -- -i $good -o "$o" --incremental --discard_overlap --threads 0
expect cli_threads_negative 2 "--threads needs an integer from 1 to 1024, not '-2'" -- -i $good -o "$o" --incremental --discard_overlap --threads -2
expect cli_threads_not_a_number 2 "--threads needs an integer from 1 to 1024, not 'all'" -- -i $good -o "$o" --incremental --discard_overlap --threads all
expect cli_threads_too_large 2 "--threads needs an integer from 1 to 1024, not '1025'" -- -i $good -o "$o" --threads 1025
expect cli_threads_missing_value 2 "--threads needs a value" -- -i $good -o "$o" --incremental --discard_overlap --threads
expect cli_threads_twice 2 "--threads given twice" -- -i $good -o "$o" --threads 2 --threads 2

# An error keeps an existing picture as it was.
echo keep >"$o"
printf 'pt= <x> radius= 1 color= {1 2 3}\n' >"$dir/broken.disks"
"$bin" -i "$dir/broken.disks" -o "$o" >/dev/null 2>&1
if [ "$(cat "$o")" = keep ]; then echo "ok input_error_keeps_existing_output$tag"; else
  echo "FAIL input_error_keeps_existing_output$tag the old file was replaced"; fi

# Standard output that cannot be written: one line, exit 1, no picture. A
# full device (the statistics, the pairs, a long --print_tree, --help) and a
# closed stdout (`>&-`: EBADF).
stdout_fails() { # NAME PATTERN REDIRECTION ARGS...
  local name=$1$tag pattern=$2 how=$3 rc
  shift 3
  rm -f "$o" "$o.partial"
  if [ "$how" = closed ]; then
    timeout 60 "$bin" "$@" 2>"$dir/stderr" >&-
  else
    timeout 60 "$bin" "$@" 2>"$dir/stderr" >"$how"
  fi
  rc=$?
  if [ $rc -eq 1 ] && grep -qE "^bvh.out: error writing standard output: $pattern\$" "$dir/stderr" &&
    [ "$(wc -l <"$dir/stderr")" -eq 1 ] && [ ! -e "$o" ] && [ ! -e "$o.partial" ]; then
    echo "ok $name"
  else
    echo "FAIL $name exit $rc: $(head -c 300 "$dir/stderr")"
  fi
}
if [ -w /dev/full ]; then
  stdout_fails cli_stdout_full_pairs "No space left on device" /dev/full -i $good -o "$o" --pairs
  stdout_fails cli_stdout_full_statistics "No space left on device" /dev/full -i $good -o "$o" --depth_limit 2
  stdout_fails cli_stdout_full_long_tree "No space left on device" /dev/full -i inputs/gen_1000.disks -o "$o" \
    --depth_limit 8 --print_tree --pairs
  stdout_fails cli_stdout_full_help "No space left on device" /dev/full --help
else
  echo "skip cli_stdout_full: no /dev/full"
fi
stdout_fails cli_stdout_closed_pairs "Bad file descriptor" closed -i $good -o "$o" --pairs
stdout_fails cli_stdout_closed_statistics "Bad file descriptor" closed -i $good -o "$o" --depth_limit 3 --print_tree
# (Nothing to print: a closed stdout is no error.)
if timeout 60 "$bin" -i $good -o "$o" 2>"$dir/stderr" >&- && [ ! -s "$dir/stderr" ] && grep -q "</svg>" "$o"; then
  echo "ok cli_stdout_closed_unused$tag"
else
  echo "FAIL cli_stdout_closed_unused$tag $(head -c 300 "$dir/stderr")"
fi

# A FIFO as the scene: read once (opened twice, the first open took the
# writer's lines and the second waited for a writer forever).
rm -f "$dir/fifo.disks"
if mkfifo "$dir/fifo.disks" 2>/dev/null; then
  "$bin" -i $good --no_output --depth_limit 2 --print_tree --pairs >"$dir/expected" 2>&1
  failed=
  for run in 1 2 3 4 5 6; do
    cat $good >"$dir/fifo.disks" &
    writer=$!
    timeout 10 "$bin" -i "$dir/fifo.disks" -o "$o" --depth_limit 2 --print_tree --pairs >"$dir/stdout" 2>&1
    rc=$?
    kill $writer 2>/dev/null
    wait $writer 2>/dev/null
    if [ $rc -ne 0 ] || ! cmp -s "$dir/stdout" "$dir/expected" || ! grep -q "</svg>" "$o"; then
      failed="run $run: exit $rc (124: it hung) $(head -c 200 "$dir/stdout")"
      break
    fi
  done
  if [ -z "$failed" ]; then echo "ok cli_fifo_input_read_once$tag"; else echo "FAIL cli_fifo_input_read_once$tag $failed"; fi
else
  echo "skip cli_fifo_input_read_once: mkfifo failed"
fi

# A signal while the picture is written (a scene of 50000 disks, its
# picture some megabytes): the temporary goes, and the status is the
# signal's. The run is stopped once the temporary has content, the
# signal sent and the run continued, so the signal meets the writing.
# (set -m: a background job of a script otherwise ignores SIGINT, and a
# signal ignored at the start stays ignored.)
awk 'BEGIN { srand(7); for (i = 0; i < 50000; i++)
  printf "pt= <%.1f %.1f> radius= 0.5 color= {1 2 3}\n", 1 + rand() * 998, 1 + rand() * 998 }' >"$dir/big.disks"
# The runs below start with SIGINT at its default action: a shell that
# starts a background job, or a runner started in the background, may
# hand it down ignored, and bvh.out keeps a signal its caller ignores.
# (env --default-signal: coreutils 8.31 and later.)
default_signals=()
env --default-signal=INT true 2>/dev/null && default_signals=(env --default-signal=INT)
signal_removes_partial() { # NAME SIGNAL STATUS
  local name=$1$tag sig=$2 status=$3 try i rc pid seen=no
  for try in 1 2 3; do
    rm -f "$o" "$o.partial"
    set -m
    "${default_signals[@]}" "$bin" -i "$dir/big.disks" -o "$o" --visualize >/dev/null 2>"$dir/stderr" &
    pid=$!
    set +m
    for ((i = 0; i < 6000; i++)); do # (at most a minute)
      if [ -s "$o.partial" ]; then
        kill -STOP $pid
        [ -s "$o.partial" ] && seen=yes
        break
      fi
      kill -0 $pid 2>/dev/null || break
      sleep 0.01
    done
    kill -"$sig" $pid 2>/dev/null
    kill -CONT $pid 2>/dev/null
    wait $pid
    rc=$?
    [ $seen = yes ] && break
  done
  if [ $seen != yes ]; then
    echo "FAIL $name the temporary was never seen: exit $rc $(head -c 200 "$dir/stderr")"
  elif [ $rc -ne "$status" ] || [ -e "$o.partial" ] || [ -e "$o" ]; then
    echo "FAIL $name exit $rc (expected $status); left behind: $(cd "$dir" && echo out.html*) $(head -c 200 "$dir/stderr")"
  else
    echo "ok $name"
  fi
}
signal_removes_partial cli_sigint_removes_partial INT 130
signal_removes_partial cli_sigterm_removes_partial TERM 143
# The same for a generated scene, whose temporary exists only while one
# large write runs: strace holds that write for a second, and the signal
# (to strace's child, the run) meets it.
if strace -o /dev/null true 2>/dev/null; then
  rm -f "$dir/g.disks" "$dir/g.disks.partial"
  set -m
  strace -f -o /dev/null -e trace=write,writev -e inject=write,writev:delay_enter=1000000 \
    "${default_signals[@]}" "$bin" --generate disks 1000 --overlap -o "$dir/g.disks" 2>"$dir/stderr" &
  tracer=$!
  set +m
  # The temporary must still be there 0.3 s after it is seen: check_files'
  # writability probe makes and removes an empty one first, which a slow
  # run (the sanitized build, a loaded host) can leave in view for a poll.
  seen=no
  for ((i = 0; i < 3000; i++)); do
    if [ -e "$dir/g.disks.partial" ]; then
      sleep 0.3
      [ -e "$dir/g.disks.partial" ] && seen=yes && break
    fi
    sleep 0.01
  done
  kill -INT "$(pgrep -P $tracer)" 2>/dev/null
  wait $tracer
  rc=$?
  if [ $seen = yes ] && [ $rc -eq 130 ] && [ ! -e "$dir/g.disks.partial" ] && [ ! -e "$dir/g.disks" ]; then
    echo "ok cli_sigint_removes_generated_partial$tag"
  else
    echo "FAIL cli_sigint_removes_generated_partial$tag temporary seen: $seen, exit $rc; left behind: $(cd "$dir" && echo g.disks*)"
  fi
else
  echo "skip cli_sigint_removes_generated_partial: strace cannot trace here"
fi

# Accepted: a UTF-8 byte-order mark at the start of the scene (some
# editors write one); anywhere else it is a wrong byte.
printf '\xef\xbb\xbfpt= <1 2> radius= 3 color= {1 2 3}\n' >"$dir/bom.disks"
if "$bin" -i "$dir/bom.disks" -o "$o" --depth_limit 1 --print_tree >"$dir/stdout" 2>&1 &&
  grep -q "elements: \[< -2.0  -1.0> <  4.0   5.0>\]$" "$dir/stdout"; then
  echo "ok input_byte_order_mark_accepted$tag"
else
  echo "FAIL input_byte_order_mark_accepted$tag $(head -c 300 "$dir/stdout")"
fi
bad_scene input_byte_order_mark_on_line_two disks "\.disks:2: expected 'pt=', found byte 0xef" \
  'pt= <1 2> radius= 3 color= {1 2 3}\n\xef\xbb\xbfpt= <1 2> radius= 3 color= {1 2 3}\n'

# Accepted: CRLF, blank lines, trailing blanks, an empty scene.
printf 'pt= <1 2> radius= 3 color= {1 2 3}\r\n\r\n  pt=  < 4 5 >  radius=  1  color=  { 0 0 0 }   \n' >"$dir/crlf.disks"
if "$bin" -i "$dir/crlf.disks" -o "$o" --depth_limit 2 --print_tree >"$dir/stdout" 2>&1 &&
  grep -q "^node count:            1$" "$dir/stdout" && grep -q "elements: \[< -2.0  -1.0> <  4.0   5.0>\] \[<  3.0   4.0> <  5.0   6.0>\]" "$dir/stdout"; then
  echo "ok input_crlf_blank_lines_and_spacing_accepted$tag"
else
  echo "FAIL input_crlf_blank_lines_and_spacing_accepted$tag $(head -c 300 "$dir/stdout")"
fi
: >"$dir/empty.quads"
if "$bin" -i "$dir/empty.quads" -o "$o" --depth_limit 3 --print_tree >"$dir/stdout" 2>&1 &&
  [ "$(cat "$dir/stdout")" = "$(printf 'node count:            0\nmax depth:             0\ninner node area:   0.000\nleaf node area:    0.000')" ] &&
  grep -q "</svg>" "$o"; then
  echo "ok input_empty_scene_is_an_empty_tree$tag"
else
  echo "FAIL input_empty_scene_is_an_empty_tree$tag $(head -c 300 "$dir/stdout")"
fi

# A mixed scene: every kind drawn as itself, boxes and pairs across kinds.
printf 'pt= <10 10> radius= 5 color= {1 2 3}\npt= <15 10> pt= <30 10> pt= <15 30> color= {4 5 6}\npt= <31 10> pt= <40 10> pt= <40 20> pt= <31 20> color= {7 8 9}\n' >"$dir/mixed.shapes"
if "$bin" -i "$dir/mixed.shapes" -o "$o" --depth_limit 1 --print_tree --pairs >"$dir/stdout" 2>&1 &&
  grep -q "elements: \[<  5.0   5.0> < 15.0  15.0>\] \[< 15.0  10.0> < 30.0  30.0>\] \[< 31.0  10.0> < 40.0  20.0>\]" "$dir/stdout" &&
  grep -q "^overlapping pairs: 1$" "$dir/stdout" && [ "$(grep -c '<circle ' "$o")" = 1 ] &&
  [ "$(grep -c '<polygon points="[0-9.]*,[0-9.]* [0-9.]*,[0-9.]* [0-9.]*,[0-9.]*" style="fill:#040506"' "$o")" = 1 ] &&
  [ "$(grep -c '<polygon points="[0-9.]*,[0-9.]* [0-9.]*,[0-9.]* [0-9.]*,[0-9.]* [0-9.]*,[0-9.]*" style="fill:#070809"' "$o")" = 1 ]; then
  echo "ok input_mixed_scene_reads_each_kind$tag"
else
  echo "FAIL input_mixed_scene_reads_each_kind$tag $(head -c 300 "$dir/stdout")"
fi
