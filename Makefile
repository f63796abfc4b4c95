# bvh — build, test, demo and benchmark. Header-only library; bvh.out is the
# course's command-line program. Variables may be overridden:
#   make CXX=clang++ CXXFLAGS="-std=c++17 -O3"   make test COURSE_DATA=/path/to/course
CXX ?= g++
CXXFLAGS ?= -std=c++17 -O2 -Wall -Wextra -pedantic
SANITIZE ?= -std=c++17 -O0 -g1 -Wall -Wextra -pedantic -fsanitize=address,undefined -fno-sanitize=null,pointer-overflow \
  -fno-sanitize-recover=all -fno-omit-frame-pointer
COURSE_DATA ?= ../shared/course
BUILD ?= build

# The library (include/bvh/, every name in namespace bvh) and the course's
# edition at the top (bvh.h, with shapes.h, intersect.h and svg.h giving
# the course's unqualified names).
LIB_HEADERS := $(wildcard include/bvh/*.h)
COURSE_HEADERS := bvh.h shapes.h intersect.h svg.h
HEADERS := $(LIB_HEADERS)
# Parallel jobs of make test's build (and of tests/run.sh's layers).
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
UNITS := bvh intersect dynamic moving parse threads names disjoint exceptions lazy_handles editions
# make test builds eight of the suites as one program, build/test_units
# (tests/units.cpp: each suite in a namespace of its own, run as
# build/test_units SUITE), so that the trees they share compile once per
# flavour. The others stay programs of their own: test_exceptions replaces
# operator new, test_names and test_editions have global names of their
# own. insert_disjoint's two suites are also built alone for
# ThreadSanitizer (tests/lanes.cpp, build/test_lanes_tsan). (make
# build/test_bvh still builds one suite alone; make check does.)
UNITY := bvh dynamic moving intersect threads parse disjoint lazy_handles
LANES := disjoint lazy_handles
SOLO := names exceptions editions
TEST_HEADERS := tests/check.h tests/scenes.h tests/lanes_probe.h
UNITY_SOURCES := tests/units.cpp $(UNITY:%=tests/test_%.cpp) $(TEST_HEADERS) $(HEADERS)
LANES_SOURCES := tests/lanes.cpp $(LANES:%=tests/test_%.cpp) tests/test_threads.cpp $(TEST_HEADERS) $(HEADERS)
TESTS := $(BUILD)/test_units $(SOLO:%=$(BUILD)/test_%)
# Every unit test and the CLI under AddressSanitizer + UBSan, compiled by
# SAN_CXX. (-g1: the line tables, for the reports' file:line; full -g takes
# a fifth longer to compile. The ThreadSanitizer builds and the fuzzer too.)
# UBSan's null and pointer-overflow checks are left out: at -O0 they test
# nearly every access and address computation, a fifth of these builds'
# compile, for what ASan already reports (a null dereference faults) or
# what the code never does (addresses that wrap). The fuzzer keeps them.
# make test (tests/run.sh) sets SAN_CXX='clang++ -stdlib=libc++' when
# clang++ and libc++ are installed: these builds are then also the
# portable build with clang++ and libc++ (as on macOS; test_parse there takes
# the reader's fallback for a missing floating-point from_chars), and clang++
# compiles them in about half g++'s time.
SAN_CXX ?= $(CXX)
# (test_names is a test of names at global scope, and test_editions'
# memory is valgrind's: neither has an ASan build in make test, whose
# compile would check no code the others do not.)
SAN_TESTS := $(BUILD)/test_units_san $(BUILD)/test_exceptions_san $(BUILD)/bvh_san.out
# The portable build: the sanitizer build of the unit program above is also
# the one under -std=c++20 (libc++'s C++20 library with clang++, the
# iterator's concept), with -DBVH_NO_SIMD (collision()'s and the nodes'
# scalar fallback instead of SSE2) and -DBVH_NO_HUGE_PAGES (std::allocator
# for a build's items, whose bounds ASan then sees). The default build tests
# SSE2 and the huge-page arrays under C++17, and under ASan the other
# programs (test_exceptions_san, bvh_san.out) do too. g++'s C++20 with
# libstdc++: test_exceptions's default build.
UNITS_SAN_FLAGS ?= -std=c++20 -DBVH_NO_SIMD -DBVH_NO_HUGE_PAGES
# BVH_ASSERT's misuse checks: on (the default build), off (-DNDEBUG), and a
# user's own handler that throws; construct()'s threads under ThreadSanitizer.
ASSERT_TESTS := $(BUILD)/test_asserts $(BUILD)/test_asserts_ndebug $(BUILD)/test_asserts_throwing
TSAN_TESTS := $(BUILD)/test_lanes_tsan
# examples/*.cpp: the library snippets of README.txt and docs/ as programs that check themselves.
EXAMPLES := $(patsubst examples/%.cpp,$(BUILD)/example_%,$(wildcard examples/*.cpp))

.PHONY: bench-edition bench-windows bench-bulk
.PHONY: all check check-build course-check test test-build test-build-longest test-build-gcc test-build-san demo bench clean fuzz bench-dynamic bench-builders bench-moving bench-instructions bench-disjoint bench-widths

# $(BUILD)/NAME.built: the program NAME is linked (tests/run.sh's valgrind
# layer waits for it; see test-build below).
BUILT_MARK = @mkdir -p $(BUILD) && touch $(BUILD)/$(@F).built

# make (all): bvh.out, its translation units compiled JOBS at a time (one
# a core) unless a -j was given (then as that says; make bvh.out: as make
# is told).
all:
	+@case " $(MAKEFLAGS) " in *" -j"*|*jobserver*) $(MAKE) --no-print-directory bvh.out ;; \
	  *) $(MAKE) --no-print-directory -j$(JOBS) bvh.out ;; esac

# bvh.out: main.cpp and cli/ (cli/cli.h names the parts), compiled one file
# at a time into $(BUILD)/cli/ and linked. WIDTHS: the tree widths it has.
# course (the default): the course's width 3 alone, what it runs unless told
# --width (its trees: two translation units of two shape kinds each,
# cli/course_*.cpp, which make -j compiles side by side; --width 2, 4 or 8
# is refused with the way to build them). all: widths 2, 4 and 8 too
# (cli/wider_*.cpp, three times those trees). $(BUILD)/cli-widths holds the
# value bvh.out was linked with, so that changing it relinks.
WIDTHS ?= course
ifeq ($(filter course all,$(WIDTHS)),)
$(error WIDTHS must be course (width 3 alone, the default) or all (2, 3, 4 and 8), not '$(WIDTHS)')
endif
CLI_WIDER_course := cli/course_width_only
CLI_WIDER_all := cli/wider_quads_shapes cli/wider_disks_triangles
CLI_COMMON := cli/course_quads_shapes cli/course_disks_triangles main cli/options cli/progress cli/kinds
CLI_PARTS = $(CLI_WIDER_$(WIDTHS)) $(CLI_COMMON)
CLI_HEADERS := cli/cli.h cli/progress.h
bvh.out: $(CLI_PARTS:%=$(BUILD)/cli/%.o) $(BUILD)/cli-widths
	$(CXX) $(CXXFLAGS) $(CLI_PARTS:%=$(BUILD)/cli/%.o) -o $@
	$(BUILT_MARK)
$(BUILD)/cli/%.o: %.cpp cli/run.h $(CLI_HEADERS) $(HEADERS)
	@mkdir -p $(@D)
	$(CXX) $(CXXFLAGS) -Iinclude -c $< -o $@
# (Rewritten only when WIDTHS changes: make compares its time, not its recipe.)
$(BUILD)/cli-widths: cli-widths-check
	@mkdir -p $(BUILD); if [ "$$(cat $@ 2>/dev/null)" != "$(WIDTHS)" ]; then echo "$(WIDTHS)" > $@; fi
.PHONY: cli-widths-check
cli-widths-check:

# The unit suites at -Og (UNIT_CXXFLAGS): they test behaviour at their full
# rounds in a few seconds either way, and -Og compiles in about three fifths
# of -O1's time, for about a quarter more run time. The -O2 build
# (CXXFLAGS) is bvh.out's, whose output the golden, command-line,
# course-framework and browser layers check.
UNIT_CXXFLAGS ?= -std=c++17 -Og -Wall -Wextra -pedantic
$(BUILD)/test_%: tests/test_%.cpp $(TEST_HEADERS) $(HEADERS) | $(BUILD)
	$(CXX) $(UNIT_CXXFLAGS) -Iinclude -Itests $< -o $@

$(BUILD)/test_%_san: tests/test_%.cpp $(TEST_HEADERS) $(HEADERS) | $(BUILD)
	$(SAN_CXX) $(SANITIZE) -Iinclude -Itests $< -o $@

$(BUILD)/test_exceptions: tests/test_exceptions.cpp $(TEST_HEADERS) $(HEADERS) | $(BUILD)
	$(CXX) $(UNIT_CXXFLAGS) -std=c++20 -Iinclude -Itests $< -o $@

# The two editions against each other: the course's (the top-level bvh.h,
# "bvh.h" through -I.) and the engine (<bvh/bvh.h> through -Iinclude).
EDITIONS_SOURCES := tests/test_editions.cpp tests/check.h $(HEADERS) $(COURSE_HEADERS)
$(BUILD)/test_editions: $(EDITIONS_SOURCES) | $(BUILD)
	$(CXX) $(UNIT_CXXFLAGS) -I. -Iinclude -Itests $< -o $@
	$(BUILT_MARK)
$(BUILD)/test_editions_san: $(EDITIONS_SOURCES) | $(BUILD)
	$(SAN_CXX) $(SANITIZE) -I. -Iinclude -Itests $< -o $@
$(BUILD)/check/test_editions: $(EDITIONS_SOURCES) | $(BUILD)/check
	$(CHECK_CXX) $(CHECK_CXXFLAGS) -I. -Iinclude -Itests $< -o $@

$(BUILD)/test_units: $(UNITY_SOURCES) | $(BUILD)
	$(CXX) $(UNIT_CXXFLAGS) -Iinclude -Itests $< -o $@
	$(BUILT_MARK)

$(BUILD)/test_units_san: $(UNITY_SOURCES) | $(BUILD)
	$(SAN_CXX) $(SANITIZE) $(UNITS_SAN_FLAGS) -Iinclude -Itests $< -o $@

# The sanitized CLI has every width (WIDTHS=all's parts): the
# command-line cases at the course's width 3 and tests/cli_widths.sh's at
# the others run on it (clang++ compiles these at -O0 in about half of
# g++'s time at -O2 for the course's width alone).
CLI_SAN_PARTS := $(CLI_WIDER_all) $(CLI_COMMON)
$(BUILD)/bvh_san.out: $(CLI_SAN_PARTS:%=$(BUILD)/cli_san/%.o)
	$(SAN_CXX) $(SANITIZE) $^ -o $@
$(BUILD)/cli_san/%.o: %.cpp cli/run.h $(CLI_HEADERS) $(HEADERS)
	@mkdir -p $(@D)
	$(SAN_CXX) $(SANITIZE) -Iinclude -c $< -o $@

# test_asserts and the examples at -O0: they run in a second or two (each
# assert case in milliseconds) either way, and -O0 compiles them at least
# as fast as -Og. Compiled by EXAMPLE_CXX: make test (tests/run.sh) sets
# clang++ when it is installed, which compiles them in about 70% of g++'s
# time (g++ compiles the library's code in the unit suites and bvh.out).
EXAMPLE_CXXFLAGS ?= -std=c++17 -O0 -Wall -Wextra -pedantic
EXAMPLE_CXX ?= $(CXX)
$(BUILD)/test_asserts: tests/test_asserts.cpp $(HEADERS) | $(BUILD)
	$(EXAMPLE_CXX) $(EXAMPLE_CXXFLAGS) -Iinclude $< -o $@

$(BUILD)/test_asserts_ndebug: tests/test_asserts.cpp $(HEADERS) | $(BUILD)
	$(EXAMPLE_CXX) $(EXAMPLE_CXXFLAGS) -DNDEBUG -Iinclude $< -o $@

$(BUILD)/test_asserts_throwing: tests/test_asserts.cpp $(HEADERS) | $(BUILD)
	$(EXAMPLE_CXX) $(EXAMPLE_CXXFLAGS) -DBVH_TEST_THROWING_ASSERT -Iinclude $< -o $@

# (TSAN_CXX: tests/run.sh sets clang++ when it is installed, which compiles
# and runs these in about 60% of g++'s time.)
TSAN_CXX ?= $(CXX)
TSAN_FLAGS := -std=c++17 -O0 -g1 -Wall -Wextra -pedantic -fsanitize=thread
$(BUILD)/test_%_tsan: tests/test_%.cpp $(TEST_HEADERS) $(HEADERS) | $(BUILD)
	$(TSAN_CXX) $(TSAN_FLAGS) -Iinclude -Itests $< -o $@
# (insert_disjoint's lanes under TSan from two threads on every tree: the
# lowered Tuning::disjoint_lanes_threads, LANES_PROBE_LANES_THREADS=2, which no other build sets)
$(BUILD)/test_lanes_tsan: $(LANES_SOURCES) | $(BUILD)
	$(TSAN_CXX) $(TSAN_FLAGS) -DLANES_PROBE_LANES_THREADS=2 -Iinclude -Itests $< -o $@

$(BUILD)/example_%: examples/%.cpp $(HEADERS) | $(BUILD)
	$(EXAMPLE_CXX) $(EXAMPLE_CXXFLAGS) -Iinclude $< -o $@

$(BUILD):
	mkdir -p $(BUILD)
$(BUILD)/check:
	mkdir -p $@

# What make test compiles: the sanitizer builds (by SAN_CXX), g++'s builds
# and the fuzzer (clang++ only). tests/run.sh builds them all in one make
# -j$(JOBS) -k, the longest compiles first, so that -j ends on short ones,
# and first the programs of the valgrind layer (the run's longest chain of
# work): each of them, once linked, is marked $(BUILD)/NAME.built
# (BUILT_MARK), and the layer's two streams start beside the rest of the
# build as soon as their programs are there. (A marker target of its own
# would wait for a free job slot, a whole compile.)
LONGEST := bvh.out $(BUILD)/test_units $(BUILD)/test_exceptions
test-build-longest: $(LONGEST)
test-build-san: $(SAN_TESTS)
test-build-gcc: $(TESTS) $(TSAN_TESTS) bvh.out $(ASSERT_TESTS) $(EXAMPLES)
test-build: test-build-longest $(BUILD)/bvh_san.out test-build-san test-build-gcc $(BUILD)/fuzz_parser_O0

# Every test; ends with "N passed, M failed" and fails when M > 0. The
# build runs with -j$(JOBS) and so do the independent layers of tests/run.sh.
# Each layer prints a line when it starts and when it ends, and a line every
# 15 s says what is still building or running. A missing tool (valgrind,
# xmllint, chromium, clang++, cmake) skips its layer with a notice naming
# the package to install. tests/run.sh LAYER... runs some layers only.
test: | $(BUILD)
	+@MAKE="$(MAKE)" JOBS="$(JOBS)" CXX="$(CXX)" COURSE_DATA="$(COURSE_DATA)" BUILD="$(BUILD)" bash tests/run.sh

# make check: the quick layer (under a minute from scratch on 2 cores):
# bvh.out, the unit suites as one program ($(BUILD)/check/test_units, as
# make test's) and test_editions, run at CHECK_SCALE of their random
# rounds, and the golden stdout on the course's scenes and ours. The unit
# programs are compiled by CHECK_CXX with CHECK_CXXFLAGS: tests/run.sh
# --quick sets clang++ at -O0 when it is installed (it compiles them in a
# quarter of g++'s time at -Og, and runs them at a third of the speed:
# hence the smaller scale), else g++ at UNIT_CXXFLAGS. Each suite runs as a
# make target of its own beside the other compiles (its output:
# $(BUILD)/check/test_*.out, which tests/run.sh --quick removes first and
# then reads).
CHECK_CXX ?= $(CXX)
CHECK_CXXFLAGS ?= $(UNIT_CXXFLAGS)
CHECK_SCALE ?= 0.25
CHECK_SUITES := $(UNITY) editions
$(BUILD)/check/test_units: $(UNITY_SOURCES) | $(BUILD)/check
	$(CHECK_CXX) $(CHECK_CXXFLAGS) -Iinclude -Itests $< -o $@
$(UNITY:%=$(BUILD)/check/test_%.out): $(BUILD)/check/test_%.out: $(BUILD)/check/test_units
	@BVH_TEST_SCALE=$(CHECK_SCALE) $< $* >$@.tmp 2>&1; echo "exit status $$?" >>$@.tmp; mv $@.tmp $@
$(BUILD)/check/test_editions.out: $(BUILD)/check/test_editions
	@BVH_TEST_SCALE=$(CHECK_SCALE) $< >$@.tmp 2>&1; echo "exit status $$?" >>$@.tmp; mv $@.tmp $@
# (Longest compiles first.)
check-build: $(BUILD)/check/test_units bvh.out $(CHECK_SUITES:%=$(BUILD)/check/test_%.out)
check: | $(BUILD)
	+@MAKE="$(MAKE)" JOBS="$(JOBS)" CXX="$(CXX)" COURSE_DATA="$(COURSE_DATA)" BUILD="$(BUILD)" bash tests/run.sh --quick

# make course-check [BVH=path/to/bvh.h]: that bvh.h (default: the project's)
# alone in the course's framework, as the homework server builds it (the
# stand-ins in tests/course_framework/): the one-command check of a
# submission (tests/course_framework.sh: the build without warnings, the
# goldens, discard-overlap against a scan with the framework's intersect,
# the instructor-style tests of iterators and copies, the extra credit when
# it compiles, valgrind). Builds all it needs itself.
BVH ?= bvh.h
course-check:
	@COURSE_DATA="$(COURSE_DATA)" CXX="$(CXX)" bash tests/course_framework.sh "$(BVH)"

# libFuzzer on the scene parser, the tree built from what it accepts and the
# command-line parser (tests/fuzz_parser.cpp; needs clang++ and its libFuzzer
# runtime: apt-get install clang libclang-rt-14-dev). New inputs go to
# $(BUILD)/fuzz-work, findings to $(BUILD)/fuzz-crash-*. make fuzz builds it
# at -O1 (at -O0 it runs about a quarter of the inputs a second). make test
# runs it too, for 10 s, built at -O0 (build/fuzz_parser_O0), which compiles
# in a third of -O1's time: a short run replays the corpus either way.
FUZZ_SECONDS ?= 60
FUZZ_CXX ?= clang++
FUZZ_FLAGS := -std=c++17 -g1 -Wall -Wextra -pedantic -fsanitize=fuzzer,address,undefined \
  -fno-sanitize-recover=all -Iinclude
$(BUILD)/fuzz_parser: tests/fuzz_parser.cpp cli/options.cpp $(CLI_HEADERS) $(HEADERS) | $(BUILD)
	$(FUZZ_CXX) -O1 $(FUZZ_FLAGS) $< cli/options.cpp -o $@
$(BUILD)/fuzz_parser_O0: tests/fuzz_parser.cpp cli/options.cpp $(CLI_HEADERS) $(HEADERS) | $(BUILD)
	$(FUZZ_CXX) -O0 $(FUZZ_FLAGS) $< cli/options.cpp -o $@

fuzz: $(BUILD)/fuzz_parser
	mkdir -p $(BUILD)/fuzz-work
	$(BUILD)/fuzz_parser -max_total_time=$(FUZZ_SECONDS) -print_final_stats=1 \
	  -artifact_prefix=$(BUILD)/fuzz-crash- $(BUILD)/fuzz-work tests/fuzz_corpus

# The handout's command lines on the course's scenes in COURSE_DATA (or, when
# they are absent, on our own inputs/gen_*, with a notice): pictures and each
# command's stdout go to demo/. stdout is the commands' stdout alone, byte for
# byte as the handout's; the "$ ./bvh.out ..." lines and notes go to stderr.
# (bvh.out is built by a make of its own whose output goes to stderr, so
# that make's echo of the compile line stays out of the demo's stdout.)
demo:
	@$(MAKE) --no-print-directory bvh.out >&2
	@COURSE_DATA="$(COURSE_DATA)" bash tests/demo.sh

clean:
	rm -rf $(BUILD) bvh.out demo

# ---- make bench (bench/bench.cpp): ours against a brute-force scan, Boost.Geometry's
# R-trees, Box2D's b2DynamicTree and a uniform grid; writes bench/results.txt and
# bench/results.svg. Peers are used when installed (apt-get install libboost-dev
# libbox2d-dev), else skipped with a notice. make bench RUNS=n; make bench QUICK=1 (a
# reduced set in under a minute, results in build/bench-quick/).
# Every method is compiled with the same flags.
BENCH_CXXFLAGS = -std=c++17 -O2 -DNDEBUG -Wall -Wextra -Iinclude
BENCH_ARGS = $(if $(RUNS),--runs $(RUNS)) $(if $(filter-out 0,$(QUICK)),--quick)
.PHONY: bench-peers

bench: bvh.out $(BUILD)/bench $(BUILD)/bench_moving
	$(BUILD)/bench $(BENCH_ARGS)
	$(MAKE) --no-print-directory bench-moving
	$(MAKE) --no-print-directory bench-bulk

# ---- make bench-bulk (bench/bulk.cpp; make bench runs it too): W3 (bulk build + 100k
# probes) and all intersecting pairs on make bench's W1 and W2 disks, ours against
# GEOS's TemplateSTRtree and Flatbush (from PEERS, ../shared/peers: benchmark-only,
# never part of the library, bvh.out or the tests), Boost's packed R-tree and CGAL's
# box_intersection_d (libcgal-dev), each skipped with a notice when absent; every
# method's count must agree. Table to stdout and bench/results_bulk.txt; RUNS=n
# (default 3); QUICK=1 100k disks, into $(BUILD)/results_bulk.txt.
PEERS ?= ../shared/peers
BULK_PEERS = $(if $(wildcard $(PEERS)/geos/include/geos/index/strtree/TemplateSTRtree.h),-I$(PEERS)/geos/include \
  -DUSE_UNSTABLE_GEOS_CPP_API -DBENCH_HAVE_GEOS) $(if $(wildcard $(PEERS)/flatbush/flatbush.h),-I$(PEERS)/flatbush \
  -DFLATBUSH_SPAN -DBENCH_HAVE_FLATBUSH)
$(BUILD)/bench_bulk: bench/bulk.cpp bench/peers.h $(HEADERS) | $(BUILD)
	@id=$$(sha1sum include/bvh/bvh.h | cut -c1-12); head=$$(git rev-parse --short HEAD 2>/dev/null || echo none); \
	info="bvh.h sha1 $$id, HEAD $$head"; \
	echo "$(CXX) $(BENCH_CXXFLAGS) $(BULK_PEERS) bench/bulk.cpp -o $@   ($$info)"; \
	$(CXX) $(BENCH_CXXFLAGS) $(BULK_PEERS) -DBENCH_BUILD_INFO="\"$$info\"" bench/bulk.cpp -o $@
bench-bulk: $(BUILD)/bench_bulk
	$(BUILD)/bench_bulk $(if $(RUNS),--runs $(RUNS)) $(if $(filter-out 0,$(QUICK)),--quick) | tee $(if $(filter-out 0,$(QUICK)),$(BUILD)/results_bulk.txt,bench/results_bulk.txt)

# Which peers this machine has; the file changes (forcing a rebuild) only when that does.
$(BUILD)/bench-peers: bench-peers
	@mkdir -p $(BUILD); p=; \
	if echo 'int main(){}' | $(CXX) -x c++ - -lbox2d -o $(BUILD)/bench-probe >/dev/null 2>&1; then p=box2d; \
	else echo "note: libbox2d not found (apt-get install libbox2d-dev): Box2D will be skipped"; fi; \
	rm -f $(BUILD)/bench-probe; \
	if [ ! -f $@ ] || [ "$$(cat $@)" != "$$p" ]; then echo "$$p" > $@; fi
bench-peers:

# The results name the bvh.h they measured (its sha1, and whether HEAD has it).
$(BUILD)/bench: bench/bench.cpp bench/peers.h $(HEADERS) $(BUILD)/bench-peers | $(BUILD)
	@id=$$(sha1sum include/bvh/bvh.h | cut -c1-12); head=$$(git rev-parse --short HEAD 2>/dev/null || echo none); \
	if [ "$$(git show HEAD:include/bvh/bvh.h 2>/dev/null | sha1sum | cut -c1-12)" = "$$id" ]; then st="as in HEAD $$head"; \
	else st="modified since HEAD $$head"; fi; info="bvh.h sha1 $$id, $$st"; \
	if [ "$$(cat $(BUILD)/bench-peers)" = box2d ]; then lib=-lbox2d; def=-DBENCH_HAVE_BOX2D_LIB; else lib=; def=; fi; \
	echo "$(CXX) $(BENCH_CXXFLAGS) $$def bench/bench.cpp -o $@ $$lib   ($$info)"; \
	$(CXX) $(BENCH_CXXFLAGS) $$def -DBENCH_BUILD_INFO="\"$$info\"" bench/bench.cpp -o $@ $$lib

# ---- make bench-dynamic (bench/dynamic.cpp): all-pairs collision against Boost's
# and Box2D's ways of doing it, and SAH drift under insert/erase churn; the
# table goes to stdout and bench/results_dynamic.txt. QUICK=1 for a small run.
$(BUILD)/bench_dynamic: bench/dynamic.cpp bench/random_disks.h $(HEADERS) $(BUILD)/bench-peers | $(BUILD)
	@if [ "$$(cat $(BUILD)/bench-peers)" = box2d ]; then lib=-lbox2d; def=-DBENCH_HAVE_BOX2D_LIB; else lib=; def=; fi; \
	echo "$(CXX) $(BENCH_CXXFLAGS) $$def bench/dynamic.cpp -o $@ $$lib"; \
	$(CXX) $(BENCH_CXXFLAGS) $$def bench/dynamic.cpp -o $@ $$lib

# ---- make bench-windows (bench/windows.cpp): 1M boxes built in bulk, then
# 100k window queries, the boxes stored in the tree against ids read through
# an adaptor from the program's array, beside Boost's packed rtree (when
# installed); bench/results_windows.txt.
$(BUILD)/bench_windows: bench/windows.cpp bench/peers.h $(HEADERS) | $(BUILD)
	$(CXX) $(BENCH_CXXFLAGS) bench/windows.cpp -o $@
bench-windows: $(BUILD)/bench_windows
	$(BUILD)/bench_windows $(if $(filter-out 0,$(QUICK)),--n 100000 --q 20000) | tee $(if $(filter-out 0,$(QUICK)),$(BUILD)/results_windows.txt,bench/results_windows.txt)

bench-dynamic: $(BUILD)/bench_dynamic
	$(BUILD)/bench_dynamic $(if $(filter-out 0,$(QUICK)),--quick) | tee $(if $(filter-out 0,$(QUICK)),$(BUILD)/results_dynamic.txt,bench/results_dynamic.txt)

# ---- make bench-builders (bench/builders.cpp): course bulk build, SAH bulk build and
# incremental insertion (random and sorted order) compared by SAH cost, height, build
# time and probe time, on the course's scenes (COURSE_DATA) and on 10k-1M random
# disks, at the course's width 3 and then at widths 2, 3, 4 and 8 (node count and fill
# factor too); writes bench/results_builders.txt and the chart bench/builders.svg.
$(BUILD)/bench_builders: bench/builders.cpp $(HEADERS) | $(BUILD)
	$(CXX) $(BENCH_CXXFLAGS) bench/builders.cpp -o $@

bench-builders: $(BUILD)/bench_builders
	$(BUILD)/bench_builders "$(COURSE_DATA)" bench/builders.svg | tee bench/results_builders.txt

# ---- make bench-moving (bench/moving.cpp; make bench runs it too): W4, 100k disks
# moving for 100 frames with an overlap query per disk per frame (ours update() at
# several margins, Box2D MoveProxy, Boost remove + insert), and k-nearest on 1M disks
# (ours nearest(p, k) against Boost's nearest queries). Table to stdout and
# bench/results_moving.txt; RUNS=n (default 3: 13-17 minutes); QUICK=1 a few seconds,
# into $(BUILD)/results_moving.txt.
# Exits 1 when the methods disagree or validate() fails.
$(BUILD)/bench_moving: bench/moving.cpp bench/peers.h $(HEADERS) $(BUILD)/bench-peers | $(BUILD)
	@id=$$(sha1sum include/bvh/bvh.h | cut -c1-12); head=$$(git rev-parse --short HEAD 2>/dev/null || echo none); \
	if [ "$$(git show HEAD:include/bvh/bvh.h 2>/dev/null | sha1sum | cut -c1-12)" = "$$id" ]; then st="as in HEAD $$head"; \
	else st="modified since HEAD $$head"; fi; info="bvh.h sha1 $$id, $$st"; \
	if [ "$$(cat $(BUILD)/bench-peers)" = box2d ]; then lib=-lbox2d; def=-DBENCH_HAVE_BOX2D_LIB; else lib=; def=; fi; \
	echo "$(CXX) $(BENCH_CXXFLAGS) -pedantic $$def bench/moving.cpp -o $@ $$lib   ($$info)"; \
	$(CXX) $(BENCH_CXXFLAGS) -pedantic $$def -DBENCH_BUILD_INFO="\"$$info\"" bench/moving.cpp -o $@ $$lib

bench-moving: $(BUILD)/bench_moving
	@out=$(if $(filter-out 0,$(QUICK)),$(BUILD)/results_moving.txt,bench/results_moving.txt); \
	echo "$(BUILD)/bench_moving $(BENCH_ARGS) | tee $$out"; \
	{ $(BUILD)/bench_moving $(BENCH_ARGS); echo $$? > $(BUILD)/bench_moving.rc; } | tee $$out; \
	exit $$(cat $(BUILD)/bench_moving.rc)

# ---- make bench-edition (bench/edition.cpp): the course's edition (bvh.h) beside the
# engine at width 3 on the course's questions: discard-overlap sampling of 1k-1M random
# disks against a scan, and the build rules' SAH cost on the course's scenes
# (COURSE_DATA). Table to stdout and bench/results_edition.txt; RUNS=n (default 3).
$(BUILD)/bench_edition: bench/edition.cpp bench/random_disks.h $(HEADERS) $(COURSE_HEADERS) | $(BUILD)
	$(CXX) $(BENCH_CXXFLAGS) -pedantic bench/edition.cpp -o $@

bench-edition: $(BUILD)/bench_edition
	COURSE_DATA="$(COURSE_DATA)" $(BUILD)/bench_edition $(if $(RUNS),--runs $(RUNS)) | tee bench/results_edition.txt

# ---- make bench-instructions (bench/instructions.sh): callgrind instruction counts of
# W1, W2, W3 (bench.cpp, ours) and all pairs and erase churn (bench/instructions.cpp),
# one run each: the steady measure for comparing two versions of bvh.h on a shared
# machine. Table to stdout and bench/results_instructions.txt.
$(BUILD)/instructions: bench/instructions.cpp bench/peers.h bench/random_disks.h $(HEADERS) | $(BUILD)
	$(CXX) $(BENCH_CXXFLAGS) -pedantic bench/instructions.cpp -o $@

bench-instructions: bvh.out $(BUILD)/bench $(BUILD)/instructions
	bash bench/instructions.sh $(BUILD) | tee bench/results_instructions.txt

# ---- make bench-disjoint (bench/disjoint_scaling.sh): insert_disjoint's serial fraction
# of the work on W1 and W2 at 1M candidates and W2 at 10M (against Boost's loop and the
# grid there), and the speed-ups Amdahl's law predicts from it for 1-64 cores. Raw output
# and summary to bench/results_disjoint_scaling.txt, chart to docs/disjoint_speedup.svg.
# RUNS=n (1M, default 5), BIG_RUNS=n (10M, default 3). On a shared machine:
# nice -n 10 make bench-disjoint, and nothing else heavy meanwhile.
# ---- make bench-widths: the course's width 3 against widths 4 and 8 (split_threshold
# 4, 8, 16, 32) on W1, W2 and W3 beside Boost and the grid, W2's memory by part with
# the fill factor, and W4 and k-nearest at width 8, split 16 and 32 (bench/moving.cpp
# built with BENCH_WIDTH=8 BENCH_SPLIT=16 or 32). Raw output to
# bench/results_widths.txt; RUNS=n (default 5); about 25 minutes.
define bench_moving_wide
$(BUILD)/$(1): bench/moving.cpp bench/peers.h $(HEADERS) $(BUILD)/bench-peers | $(BUILD)
	@if [ "$$$$(cat $(BUILD)/bench-peers)" = box2d ]; then lib=-lbox2d; def=-DBENCH_HAVE_BOX2D_LIB; else lib=; def=; fi; \
	echo "$(CXX) $(BENCH_CXXFLAGS) -DBENCH_WIDTH=8 -DBENCH_SPLIT=$(2) $$$$def bench/moving.cpp -o $$@ $$$$lib"; \
	$(CXX) $(BENCH_CXXFLAGS) -pedantic $$$$def -DBENCH_WIDTH=8 -DBENCH_SPLIT=$(2) bench/moving.cpp -o $$@ $$$$lib
endef
$(eval $(call bench_moving_wide,bench_moving_w8,16))
$(eval $(call bench_moving_wide,bench_moving_w8k32,32))

WIDTH_METHODS := ours,ours-w4,ours-w8,ours-w8k8,ours-w8k16,ours-w8k32,ours-w8k32-s1,ours-w8k32-all,boost-quad16,boost-rstar16,grid
bench-widths: bvh.out $(BUILD)/bench $(BUILD)/bench_moving $(BUILD)/bench_moving_w8 $(BUILD)/bench_moving_w8k32
	@out=bench/results_widths.txt; { echo "make bench-widths at $$(git rev-parse --short HEAD 2>/dev/null) (bvh.h sha1 $$(sha1sum include/bvh/bvh.h | cut -c1-12)), $$(date -u +%Y-%m-%dT%H:%MZ); uptime: $$(uptime)"; \
	for w in W1 W2 W3; do echo; echo "### $(BUILD)/bench --only $$w --method $(WIDTH_METHODS) --runs $(or $(RUNS),5)"; \
	  $(BUILD)/bench --only $$w --method $(WIDTH_METHODS) --runs $(or $(RUNS),5) 2>/dev/null; done; \
	for b in bench_moving bench_moving_w8 bench_moving_w8k32; do echo; echo "### $(BUILD)/$$b --runs 1"; $(BUILD)/$$b --runs 1; done; } | tee $$out

bench-disjoint: bvh.out $(BUILD)/bench
	$(if $(RUNS),RUNS=$(RUNS)) $(if $(BIG_RUNS),BIG_RUNS=$(BIG_RUNS)) bash bench/disjoint_scaling.sh $(BUILD)
