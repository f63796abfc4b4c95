// brute.cpp — discard-overlap sampling without a tree, with the stand-in
// framework's own predicate (intersect(vector, shape)): the reference the
// tree's --incremental --discard_overlap run must equal.
//
//   ./brute.out FILE OUT.html     (the kept shapes, in input order)
#include "utils.h"
#include "shapes.h"

#include "scene_io.h"

#include <fstream>
#include <string>
#include <vector>

template <class T> void keep_separate(const std::vector<T> &input, const std::string &output) {
  std::vector<T> kept;
  for (const T &s : input)
    if (!intersect(kept, s)) kept.push_back(s);
  std::ofstream out(output);
  scene_io::write_start(out);
  for (const T &s : kept) scene_io::write_shape(out, s);
  scene_io::write_end(out);
}

int main(int argc, char *argv[]) {
  if (argc != 3) scene_io::fail(argv[0], "usage: brute.out FILE OUT.html");
  const std::string in = argv[1];
  if (in.find(".disks") != std::string::npos) keep_separate(scene_io::load<Disk>(in), argv[2]);
  else if (in.find(".triangles") != std::string::npos) keep_separate(scene_io::load<Triangle>(in), argv[2]);
  else keep_separate(scene_io::load<Quad>(in), argv[2]);
  return 0;
}
