#!/usr/bin/env bash
# tests/demo.sh — `make demo`: the handout's command lines on the bundled
# inputs/, pictures into demo/, each command and its statistics on stdout.
set -eu
cd "$(dirname "$0")/.."
mkdir -p demo
while read -r name args; do
  [[ -z $name || $name == \#* ]] && continue
  # shellcheck disable=SC2086
  set -- $args
  argv=()
  while [ $# -gt 0 ]; do
    if [ "$1" = -i ]; then argv+=(-i "inputs/$2"); shift 2; else argv+=("$1"); shift; fi
  done
  echo "\$ ./bvh.out ${argv[*]} -o demo/$name.html"
  start=$(date +%s%N)
  ./bvh.out "${argv[@]}" -o "demo/$name.html"
  end=$(date +%s%N)
  echo "  ($(((end - start) / 1000000)) ms)"
done < <(sed -n -e '/^36_triangles /,/^discard_overlap_1000_quads /p' -e '/^mixed_36_2 /p' tests/golden.list)
echo "Pictures: demo/*.html (open them in a browser)."
