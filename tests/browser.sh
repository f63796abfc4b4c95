#!/usr/bin/env bash
# tests/browser.sh OUTDIR SCENE — a real browser opens the picture.
# SCENE is the course's 36.triangles, or our inputs/gen_36.triangles.
# Renders the handout's 36_triangles_2 picture (--depth_limit 2 --visualize)
# in headless Chromium at two window sizes and checks each screenshot with
# tests/browser_check.py: the whole black frame is visible and the root's
# three groups show red, green and blue. Three altered pictures (no frame,
# red and blue swapped, and the picture without its fit-to-window style in a
# small window) must fail the same check, so the check itself is tested.
# Prints "ok NAME" or "FAIL NAME reason" per case (read by tests/run.sh);
# prints "skip REASON" and nothing else when Chromium is not installed.
set -u
# (tests/run.sh sets PYTHON: python3 found once, past any version manager's shim)
PYTHON=${PYTHON:-python3}
cd "$(dirname "$0")/.."
out=$1 scene=$2
browser=$(command -v chromium || command -v chromium-browser || true)
if [ -z "$browser" ]; then
  echo "skip Chromium is not installed (apt-get install chromium)"
  exit 0
fi
mkdir -p "$out"
out=$(cd "$out" && pwd)

# The flags keep Chromium off the network and out of any profile: on a
# machine without network access it otherwise stalls on background requests.
shot() { # html window-size png
  local profile
  profile=$(mktemp -d)
  timeout 120 "$browser" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
    --disable-background-networking --disable-component-update --disable-sync --hide-scrollbars \
    --user-data-dir="$profile" --window-size="$2" --screenshot="$3" "file://$1" >"$3.log" 2>&1
  rm -rf "$profile"
  [ -s "$3" ]
}

check() { # name expect(pass|fail) html window-size
  local name=$1 expect=$2 png=$out/$1.png
  if ! shot "$3" "$4" "$png"; then
    echo "FAIL $name Chromium wrote no screenshot: see $png.log"
    return
  fi
  "$PYTHON" -S tests/browser_check.py "$png" "$out/tree.txt" >"$out/$name.check" 2>&1
  local rc=$?
  if [ "$expect" = pass ] && [ $rc -eq 0 ]; then
    echo "ok $name"
  elif [ "$expect" = fail ] && [ $rc -eq 1 ]; then
    echo "ok $name"
  else
    echo "FAIL $name expected the check to $expect, it exited $rc: see $out/$name.check"
  fi
}

if ! ./bvh.out -i "$scene" -o "$out/36_triangles_2.html" --depth_limit 2 --visualize --print_tree \
  >"$out/tree.txt" 2>"$out/bvh.err"; then
  echo "FAIL browser_render bvh.out failed: $(head -c 200 "$out/bvh.err")"
  exit 0
fi
html=$out/36_triangles_2.html
check browser_shows_frame_and_red_green_blue_groups pass "$html" 1000,1000
check browser_fits_picture_in_smaller_window pass "$html" 600,800

grep -v '<rect' "$html" >"$out/no_frame.html"
check browser_check_fails_without_frame fail "$out/no_frame.html" 1000,1000
sed 's/#ff0000/#swap00/g; s/#0000ff/#ff0000/g; s/#swap00/#0000ff/g' "$html" >"$out/swapped.html"
check browser_check_fails_with_red_and_blue_swapped fail "$out/swapped.html" 1000,1000
sed 's/ style="max-width:95vw;max-height:95vh"//' "$html" >"$out/unscaled.html"
check browser_check_fails_on_clipped_frame fail "$out/unscaled.html" 600,600
