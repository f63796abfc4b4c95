// main.cpp — stand-in for the course's main.cpp: it uses BVH<T> exactly as
// ../shared/spec/course-framework.md says the course's does, and nothing
// more (construct or insert with collision, statistics when a depth limit
// is given, render_recolor, iteration through a const reference). Its
// files: this one, scene_io.h (the scene reader and picture writer that
// the course's main.cpp has inside), shapes.h/.cpp and utils.h/.cpp, with
// a bvh.h beside them: g++ -g -Wall main.cpp shapes.cpp utils.cpp
//
//   ./bvh.out -i FILE -o OUT.html [--split_threshold K] [--depth_limit D]
//             [--incremental [--discard_overlap]] [--visualize] [--print_tree]
#include "utils.h"
#include "shapes.h"
#include "bvh.h"

#include "scene_io.h"

#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

struct Options {
  std::string input, output;
  int split_threshold = 4, depth_limit = 0;
  bool incremental = false, discard_overlap = false, visualize = false, print_tree = false;
};

template <class T> void run(const std::vector<T> &elements, const Options &o) {
  BVH<T> bvh(o.split_threshold, o.depth_limit);
  if (!o.incremental) {
    bvh.construct(elements);
  } else {
    for (std::size_t i = 0; i < elements.size(); ++i) {
      if (o.discard_overlap && bvh.collision(elements[i])) continue;
      bvh.insert(elements[i]);
    }
  }
  if (o.depth_limit > 0) bvh.statistics(o.print_tree);
  std::ofstream ostr(o.output);
  if (!ostr) scene_io::fail(o.output, "cannot write");
  scene_io::write_start(ostr);
  if (o.visualize) bvh.render_recolor(ostr);
  for (typename BVH<T>::iterator itr = bvh.begin(); itr != bvh.end(); itr++) {
    const T &shape = *itr;
    scene_io::write_shape(ostr, shape);
  }
  scene_io::write_end(ostr);
}

static bool ends_with(const std::string &s, const std::string &tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

int main(int argc, char *argv[]) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) scene_io::fail(a, "needs a value");
      return argv[++i];
    };
    if (a == "-i") o.input = value();
    else if (a == "-o") o.output = value();
    else if (a == "--split_threshold") o.split_threshold = std::atoi(value().c_str());
    else if (a == "--depth_limit") o.depth_limit = std::atoi(value().c_str());
    else if (a == "--incremental") o.incremental = true;
    else if (a == "--discard_overlap") o.discard_overlap = true;
    else if (a == "--visualize") o.visualize = true;
    else if (a == "--print_tree") o.print_tree = true;
    else scene_io::fail(a, "unknown option");
  }
  if (o.input.empty() || o.output.empty()) scene_io::fail(argv[0], "needs -i FILE and -o FILE");
  if (ends_with(o.input, ".disks")) run(scene_io::load<Disk>(o.input), o);
  else if (ends_with(o.input, ".triangles")) run(scene_io::load<Triangle>(o.input), o);
  else if (ends_with(o.input, ".quads")) run(scene_io::load<Quad>(o.input), o);
  else scene_io::fail(o.input, "unknown shape type");
  return 0;
}
