# bvh — build, test, demo and benchmark. Header-only library; bvh.out is the
# course's command-line program. Variables may be overridden:
#   make CXX=clang++ CXXFLAGS="-std=c++17 -O3"   make test COURSE_DATA=/path/to/course
CXX ?= g++
CXXFLAGS ?= -std=c++17 -O2 -Wall -Wextra -pedantic
SANITIZE ?= -std=c++17 -O1 -g -Wall -Wextra -pedantic -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer
COURSE_DATA ?= ../shared/course
BUILD ?= build

HEADERS := bvh.h shapes.h intersect.h svg.h
TESTS := $(BUILD)/test_bvh $(BUILD)/test_intersect
SAN_TESTS := $(BUILD)/test_bvh_san $(BUILD)/test_intersect_san $(BUILD)/bvh_san.out

.PHONY: all test demo bench clean

all: bvh.out

bvh.out: main.cpp $(HEADERS)
	$(CXX) $(CXXFLAGS) main.cpp -o $@

$(BUILD)/test_%: tests/test_%.cpp tests/check.h $(HEADERS) | $(BUILD)
	$(CXX) $(CXXFLAGS) -I. -Itests $< -o $@

$(BUILD)/test_%_san: tests/test_%.cpp tests/check.h $(HEADERS) | $(BUILD)
	$(CXX) $(SANITIZE) -I. -Itests $< -o $@

$(BUILD)/bvh_san.out: main.cpp $(HEADERS) | $(BUILD)
	$(CXX) $(SANITIZE) main.cpp -o $@

$(BUILD):
	mkdir -p $(BUILD)

# Every test; ends with "N passed, M failed" and fails when M > 0.
test: bvh.out $(TESTS) $(SAN_TESTS)
	CXX="$(CXX)" COURSE_DATA="$(COURSE_DATA)" BUILD="$(BUILD)" bash tests/run.sh

# The handout's command lines on the bundled inputs/: pictures go to demo/.
demo: bvh.out
	bash tests/demo.sh

clean:
	rm -rf $(BUILD) bvh.out demo
