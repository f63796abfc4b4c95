#!/usr/bin/env bash
# tests/cmake_consumer.sh DIR — the CMake package (CMakeLists.txt) as a user
# meets it: configure, build and install bvh into DIR/prefix; build
# tests/consumer against that install with find_package, and again from the
# sources with add_subdirectory; run the consumer and the installed bvh.out.
# The consumer includes <bvh/bvh.h> and <bvh/scene.h> both ways. Also: with
# no build type given, bvh's own build is Release (-O3), a given one stands,
# and a parent project's empty build type is not overridden.
# Prints `ok NAME` or `FAIL NAME why` per case (read by tests/run.sh), or
# `skip REASON` alone when cmake is not installed.
set -u
cd "$(dirname "$0")/.."
dir=${1:-build/test-out/cmake}
if ! command -v cmake >/dev/null 2>&1; then
  echo "skip cmake is not installed (apt-get install cmake)"
  exit 0
fi
rm -rf "$dir"
mkdir -p "$dir"
dir=$(cd "$dir" && pwd)
src=$(pwd)
prefix=$dir/prefix
jobs=${JOBS:-2}

step() { # NAME LOG COMMAND...: one case, passing when COMMAND exits 0
  local name=$1 log=$dir/$2.log
  shift 2
  if "$@" >"$log" 2>&1; then
    echo "ok $name"
  else
    echo "FAIL $name see $log"
    return 1
  fi
}

# 1. bvh itself: configure, build (bvh.out, the course's width 3 alone by
# default), install. (Release's flags are -O0 here, for a quick build: what
# is tested is the build and the install, not the program's speed (the
# golden run below is at width 3); the default -O3 is checked below by a
# configure, and the sources of -DBVH_CLI_ALL_WIDTHS=ON by another.)
if step cmake_configure_build_install_bvh bvh bash -c "
  cmake -S '$src' -B '$dir/bvh-build' -DCMAKE_INSTALL_PREFIX='$prefix' \
    -DCMAKE_CXX_FLAGS_RELEASE='-O0' &&
  cmake --build '$dir/bvh-build' -j $jobs && cmake --install '$dir/bvh-build'"; then
  missing=
  for f in include/bvh/bvh.h include/bvh/shapes.h include/bvh/intersect.h include/bvh/distance.h \
    include/bvh/svg.h include/bvh/scene.h include/bvh/version.h share/pkgconfig/bvh.pc bin/bvh.out \
    share/cmake/bvh/bvhConfig.cmake \
    share/cmake/bvh/bvhConfigVersion.cmake share/cmake/bvh/bvhTargets.cmake; do
    [ -f "$prefix/$f" ] || missing="$missing $f"
  done
  if [ -z "$missing" ]; then echo "ok cmake_install_has_headers_cli_and_config"; else
    echo "FAIL cmake_install_has_headers_cli_and_config missing:$missing"; fi
  # The installed bvh.out prints the hand-checked golden statistics.
  if "$prefix/bin/bvh.out" -i inputs/gen_36.triangles -o "$dir/36.html" --depth_limit 2 --visualize --print_tree \
    >"$dir/36.txt" 2>&1 && cmp -s "$dir/36.txt" expected_output/inputs/gen_36_triangles_2.txt; then
    echo "ok cmake_installed_bvh_out_matches_golden"
  else
    echo "FAIL cmake_installed_bvh_out_matches_golden diff $dir/36.txt expected_output/inputs/gen_36_triangles_2.txt"
  fi

  # No CMAKE_BUILD_TYPE given: Release, and its -O3 on bvh.out's compile line
  # (configure only).
  if cmake -S "$src" -B "$dir/bvh-default" -DCMAKE_EXPORT_COMPILE_COMMANDS=ON >"$dir/bvh-default.log" 2>&1 &&
    grep -q '^CMAKE_BUILD_TYPE:STRING=Release$' "$dir/bvh-default/CMakeCache.txt" &&
    grep -q '"command": .* -O3 .*main.cpp' "$dir/bvh-default/compile_commands.json"; then
    echo "ok cmake_default_build_type_is_release"
  else
    echo "FAIL cmake_default_build_type_is_release $(grep '^CMAKE_BUILD_TYPE' "$dir/bvh-default/CMakeCache.txt"); see $dir/bvh-default/compile_commands.json"
  fi

  # 2. find_package against the install; the package must come from the prefix.
  if step cmake_consumer_find_package consumer-find bash -c "
    cmake -S tests/consumer -B '$dir/consumer-find' -DCMAKE_PREFIX_PATH='$prefix' &&
    cmake --build '$dir/consumer-find' -j $jobs"; then
    if grep -q "^bvh_DIR:PATH=$prefix/share/cmake/bvh\$" "$dir/consumer-find/CMakeCache.txt"; then
      echo "ok cmake_consumer_found_the_installed_package"
    else
      echo "FAIL cmake_consumer_found_the_installed_package bvh_DIR is $(grep '^bvh_DIR' "$dir/consumer-find/CMakeCache.txt")"
    fi
    step cmake_consumer_find_package_runs consumer-find-run "$dir/consumer-find/consumer" inputs/gen_overlap_1000.disks
  fi
fi

# 2b. pkg-config against the install: the consumer built with its flags alone,
# from a second install of the same build at another prefix (cmake --install
# --prefix, with no reconfigure: bvh.pc must follow the files it describes).
if command -v pkg-config >/dev/null 2>&1; then
  cmake --install "$dir/bvh-build" --prefix "$dir/prefix-moved" >"$dir/install-moved.log" 2>&1
  pc_dir=$dir/prefix-moved/share/pkgconfig
  if [ -f "$pc_dir/bvh.pc" ] && flags=$(PKG_CONFIG_PATH=$pc_dir pkg-config --cflags --libs bvh) &&
    [[ $flags == *"$dir/prefix-moved/"* ]] &&
    version=$(PKG_CONFIG_PATH=$pc_dir pkg-config --modversion bvh) &&
    ${CXX:-g++} -std=c++17 -O0 tests/consumer/consumer.cpp -DBVH_PACKAGE_VERSION="\"$version\"" $flags \
      -o "$dir/consumer-pc" >"$dir/consumer-pc.log" 2>&1 &&
    "$dir/consumer-pc" inputs/gen_overlap_1000.disks >>"$dir/consumer-pc.log" 2>&1; then
    echo "ok cmake_installed_pkg_config_builds_the_consumer"
  else
    echo "FAIL cmake_installed_pkg_config_builds_the_consumer flags '${flags:-}' (from $pc_dir); see $dir/consumer-pc.log"
  fi
else
  echo "FAIL cmake_installed_pkg_config_builds_the_consumer pkg-config is not installed (apt-get install pkgconf)"
fi

# 3. add_subdirectory on the sources (no install needed).
if step cmake_consumer_add_subdirectory consumer-sub bash -c "
  cmake -S tests/consumer -B '$dir/consumer-sub' -DBVH_SOURCE_DIR='$src' &&
  cmake --build '$dir/consumer-sub' -j $jobs"; then
  step cmake_consumer_add_subdirectory_runs consumer-sub-run "$dir/consumer-sub/consumer" inputs/gen_overlap_1000.disks
  # bvh under a parent project: the parent's (empty) build type stays its own.
  if grep -q '^CMAKE_BUILD_TYPE:STRING=$' "$dir/consumer-sub/CMakeCache.txt"; then
    echo "ok cmake_subproject_leaves_the_parents_build_type"
  else
    echo "FAIL cmake_subproject_leaves_the_parents_build_type $(grep '^CMAKE_BUILD_TYPE' "$dir/consumer-sub/CMakeCache.txt")"
  fi
fi

# 4. A build type that is given stands (configure only).
# (This configure also asks for bvh.out with every width: see below.)
if cmake -S "$src" -B "$dir/bvh-debug" -DCMAKE_BUILD_TYPE=Debug -DBVH_CLI_ALL_WIDTHS=ON \
  -DCMAKE_EXPORT_COMPILE_COMMANDS=ON >"$dir/bvh-debug.log" 2>&1 &&
  grep -q '^CMAKE_BUILD_TYPE:STRING=Debug$' "$dir/bvh-debug/CMakeCache.txt"; then
  echo "ok cmake_given_build_type_stands"
else
  echo "FAIL cmake_given_build_type_stands see $dir/bvh-debug.log"
fi

# bvh.out's widths: the course's 3 alone by default (the Release configure
# above), every width with -DBVH_CLI_ALL_WIDTHS=ON (the Debug one;
# configures only: make test's sanitized bvh.out compiles the same sources).
cc=$dir/bvh-default/compile_commands.json
wide=$dir/bvh-debug/compile_commands.json
if [ -f "$cc" ] && grep -q 'cli/course_width_only\.cpp' "$cc" && ! grep -q 'cli/wider_' "$cc" &&
  [ -f "$wide" ] && grep -q 'cli/wider_disks_triangles\.cpp' "$wide" && grep -q 'cli/wider_quads_shapes\.cpp' "$wide" &&
  ! grep -q 'cli/course_width_only\.cpp' "$wide"; then
  echo "ok cmake_cli_course_width_by_default_all_widths_on_request"
else
  echo "FAIL cmake_cli_course_width_by_default_all_widths_on_request see $cc and $wide"
fi
