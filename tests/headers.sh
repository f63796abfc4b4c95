#!/usr/bin/env bash
# tests/headers.sh — the rules of include/bvh/ that docs/design.txt states:
#  - every header is listed in docs/design.txt (a "-- NAME.h" line);
#  - includes go one way: a header includes (with #include "...") only
#    headers listed above it there;
#  - every header compiles alone (-fsyntax-only, -Wall -Wextra -pedantic
#    -Werror) as the one include of a translation unit;
#  - the removed tuning macros are refused with a message naming
#    set_tuning() or DisjointSteps;
#  - the node and slot stores (node_store.h, leaf_pool.h) know nothing of
#    threads: they bring in no <thread>, <mutex>, <atomic> or
#    <condition_variable>, not even through another header, and declare
#    nothing thread_local (the lanes' allocator, lane_alloc.h, is passed
#    in).
# Prints `ok NAME` or `FAIL NAME — why` per case (tests/run.sh's layer
# format). Environment: HEADERS_CXX (default: CXX, else g++, whose
# -fsyntax-only is the quicker here), JOBS.
set -u
cd "$(dirname "$0")/.."
HEADERS_CXX=${HEADERS_CXX:-${CXX:-g++}}
JOBS=${JOBS:-2}
out=${1:-build/test-out/headers}
mkdir -p "$out"

# The order of docs/design.txt.
mapfile -t order < <(sed -n 's/^-- \([A-Za-z0-9_]*\.h\)$/\1/p' docs/design.txt)
declare -A rank
for i in "${!order[@]}"; do rank[${order[$i]}]=$i; done

for path in include/bvh/*.h; do
  h=$(basename "$path")
  if [ -z "${rank[$h]+x}" ]; then
    echo "FAIL header_listed_$h — include/bvh/$h is not in docs/design.txt's map (a '-- $h' line)"
    continue
  fi
  echo "ok header_listed_$h"
  bad=""
  while read -r inc; do
    if [ -z "${rank[$inc]+x}" ]; then
      bad+="$inc (not in the map) "
    elif [ "${rank[$inc]}" -ge "${rank[$h]}" ]; then
      bad+="$inc (listed below $h) "
    fi
  done < <(sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*"\([^"]*\)".*/\1/p' "$path")
  if [ -n "$bad" ]; then
    echo "FAIL header_includes_go_one_way_$h — $h includes $bad"
  else
    echo "ok header_includes_go_one_way_$h"
  fi
done
for h in "${order[@]}"; do
  [ -f "include/bvh/$h" ] || echo "FAIL header_exists_$h — docs/design.txt lists $h, which include/bvh/ does not have"
done

# The tuning and profiling macros of earlier versions changed template
# bodies; they are gone, and defining one must fail with a message that
# names the replacement, not be silently ignored.
for m in BVH_DISK_CODES_MIN_BYTES BVH_DISJOINT_LANES_MIN BVH_DISJOINT_PROFILE; do
  log=$out/removed_$m.log
  if printf '#define %s 1\n#include <bvh/core.h>\n' "$m" | $HEADERS_CXX -std=c++17 -fsyntax-only -Iinclude -x c++ - \
    >"$log" 2>&1; then
    echo "FAIL removed_macro_refused_$m — a program defining $m still compiles"
  elif grep -q 'set_tuning\|DisjointSteps' "$log"; then
    echo "ok removed_macro_refused_$m"
  else
    echo "FAIL removed_macro_refused_$m — the error does not name the replacement: $(grep -m 1 error "$log")"
  fi
done

# The stores that know nothing of threads: the standard headers each one
# brings in, by the compiler's -H list.
for h in node_store.h leaf_pool.h; do
  if ! list=$(echo "#include <bvh/$h>" | $HEADERS_CXX -std=c++17 -Iinclude -x c++ -E -H - 2>&1 >/dev/null); then
    echo "FAIL header_knows_no_threads_$h — $h does not preprocess alone"
    continue
  fi
  threads=$(grep -E '[/ ](thread|mutex|atomic|condition_variable|shared_mutex|future)$' <<<"$list" |
    sed 's#.*/\(.*\)#<\1>#' | sort -u | tr '\n' ' ')
  if grep -q 'thread_local' "include/bvh/$h"; then threads+="thread_local "; fi
  if [ -n "$threads" ]; then
    echo "FAIL header_knows_no_threads_$h — $h brings in $threads"
  else
    echo "ok header_knows_no_threads_$h"
  fi
done

# Each header alone, JOBS at a time.
compile_alone() {
  local h=$1 log=$2/$1.log
  if echo "#include <bvh/$h>" | $HEADERS_CXX -std=c++17 -fsyntax-only -Wall -Wextra -pedantic -Werror -Iinclude \
    -x c++ - >"$log" 2>&1; then
    echo "ok header_compiles_alone_$h"
  else
    echo "FAIL header_compiles_alone_$h — see $log: $(grep -m 1 -E 'error' "$log")"
  fi
}
export -f compile_alone
export HEADERS_CXX
printf '%s\n' include/bvh/*.h | xargs -n 1 basename | xargs -P "$JOBS" -I{} bash -c 'compile_alone "$1" "$2"' _ {} "$out" |
  sort
