// tests/fuzz_parser.cpp — libFuzzer target for everything a user's bytes reach:
// the scene parser of every kind (mixed .shapes scenes too), the tree built from what it accepts, and the
// command-line parser.
//
//   make fuzz                       # FUZZ_SECONDS=60 by default
//   build/fuzz_parser -runs=100000 tests/fuzz_corpus
//
// Built with clang++ -fsanitize=fuzzer,address,undefined: a crash, a leak,
// undefined behaviour or a failed invariant below (abort) is a finding.
// Input layout: byte 0 picks the path and the tree's parameters (its top two
// bits the kind: disks, triangles, quads, or 3: the command line when the
// byte is odd and a mixed scene when even), the rest
// is a scene file (or, for the command-line path, NUL-separated arguments).
// The scene paths use scene.h; the command-line path calls
// bvh_parse_command_line of cli/options.cpp (bvh.out's parser), linked in.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/intersect.h>
#include <bvh/scene.h>
#include <bvh/shapes.h>
#include <bvh/svg.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

int bvh_parse_command_line(int argc, char **argv, int &split_threshold, int &depth_limit, std::string &message);

namespace {

using bvh_scene::parse_scene;

void require(bool ok, const char *what) {
  if (!ok) {
    std::fprintf(stderr, "fuzz_parser: invariant broken: %s\n", what);
    std::abort();
  }
}

// A parse error must read "NAME:LINE: message" with LINE a 1-based number.
void check_error_format(const std::string &name, const std::string &error) {
  require(error.compare(0, name.size() + 1, name + ":") == 0, "error starts with the file name");
  std::size_t i = name.size() + 1, digits = 0;
  while (i < error.size() && error[i] >= '0' && error[i] <= '9') ++i, ++digits;
  require(digits > 0 && error[name.size() + 1] != '0', "error has a 1-based line number");
  require(error.compare(i, 2, ": ") == 0 && error.size() > i + 2, "error has a message after the line");
  require(error.find('\n') == std::string::npos, "error is one line");
}

bool finite_box(const BoundingBox &b) {
  return std::isfinite(b.getMin().x) && std::isfinite(b.getMin().y) && std::isfinite(b.getMax().x) &&
         std::isfinite(b.getMax().y) && b.getMin().x <= b.getMax().x && b.getMin().y <= b.getMax().y;
}

template <class T> void scene(const std::string &name, std::uint8_t mode, const char *data, std::size_t size) {
  std::vector<T> shapes;
  std::string error;
  if (!parse_scene(name, data, size, shapes, error)) {
    check_error_format(name, error);
    return;
  }
  require(error.empty(), "no error text on success");
  for (const T &s : shapes) {
    require(finite_box(s.getBox()), "accepted shapes have finite boxes");
    require(intersect(s, s), "every shape touches itself");
  }
  const int split_threshold = 1 + (mode & 3);
  const int depth_limit = (mode >> 2) & 3; // 0: unlimited
  CourseBVH<T> tree(split_threshold, depth_limit);
  if (mode & 16) {
    tree.construct(shapes);
    require(tree.size() == shapes.size(), "construct keeps every shape");
  } else {
    const bool discard = (mode & 32) != 0;
    std::vector<T> kept;
    for (const T &s : shapes) {
      const bool hit = tree.collision(s);
      // The tree's answer against the brute-force one (small scenes only).
      if (kept.size() <= 256) {
        bool brute = false;
        for (const T &k : kept) brute = brute || intersect(k, s);
        require(hit == brute, "collision() agrees with brute force");
      }
      if (!discard || !hit) {
        tree.insert(s);
        kept.push_back(s);
      }
    }
    require(tree.size() == kept.size(), "insert keeps what it was given");
  }
  require(tree.validate(), "validate() after build");
  std::ostringstream out;
  tree.statistics(out, true);
  render_start(out);
  tree.render_recolor(out);
  for (const T &s : tree) render_shape(out, s);
  render_end(out);
  CourseBVH<T> copy(tree);
  require(copy.validate() && copy.size() == tree.size(), "copies are whole");
}

void command_line(const char *data, std::size_t size) {
  std::vector<std::string> words{"bvh.out"};
  std::string word;
  for (std::size_t i = 0; i < size; ++i) {
    if (data[i] == '\0') {
      words.push_back(word);
      word.clear();
    } else {
      word += data[i];
    }
  }
  words.push_back(word);
  std::vector<char *> argv;
  for (std::string &w : words) argv.push_back(&w[0]);
  argv.push_back(nullptr);
  int split_threshold = 0, depth_limit = -1;
  std::string message;
  if (bvh_parse_command_line(int(words.size()), argv.data(), split_threshold, depth_limit, message) == 0)
    require(split_threshold >= 1 && depth_limit >= 0, "parsed limits are in range");
  else
    require(!message.empty() && message.find('\n') == std::string::npos, "usage errors are one line");
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *bytes, std::size_t size) {
  if (size == 0) return 0;
  const std::uint8_t mode = bytes[0];
  const char *data = reinterpret_cast<const char *>(bytes + 1);
  --size;
  switch (mode >> 6) {
  case 0: scene<Disk>("fuzz.disks", mode, data, size); break;
  case 1: scene<Triangle>("fuzz.triangles", mode, data, size); break;
  case 2: scene<Quad>("fuzz.quads", mode, data, size); break;
  default:
    // Odd: the command line; even: a mixed scene (split threshold 1 or 3).
    if (mode & 1)
      command_line(data, size);
    else
      scene<Shape>("fuzz.shapes", mode, data, size);
    break;
  }
  return 0;
}
