// cli/run.h — bvh.out's work on one shape kind: the course's workflow on a
// scene (read it, build the tree in bulk, by insertion or by discard-overlap
// sampling, print the statistics and the pairs, write the picture) at each
// tree width, and --generate's scene. Instantiated for two kinds a
// translation unit, at the course's width 3 (cli/course_*.cpp) and at the
// others (cli/wider_*.cpp).
#ifndef BVH_CLI_RUN_H
#define BVH_CLI_RUN_H

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/generate.h>
#include <bvh/shapes.h>
#include <bvh/svg.h>

#include "cli.h"
#include "progress.h"

namespace bvh_cli {

using namespace bvh;
using namespace bvh_scene;

// ---------------------------------------------------------------------------
// --generate: the scene text (scene.h), written under a temporary name.

// On a terminal, the progress line shows the shapes placed and the tries
// made ("generating 1000000 disks: 59 of 1000000 shapes (0%), 4.2M tries").
// A non-overlapping request that cannot fit by max_non_overlapping()'s
// packing bound (scene.h) is refused before the first try.
template <class T>
int generate(const std::string &kind, long count, std::uint64_t seed, double lo, double hi, bool overlap,
             const std::string &path) {
  const double most = max_non_overlapping(kind, lo);
  if (!overlap && double(count) > most) {
    char buf[64];
    std::snprintf(buf, sizeof buf, " of %s at least %g", kind == "disks" ? "radius" : "size", lo);
    std::cerr << "bvh.out: " << count << " " << kind << buf
              << " cannot fit in the 1000 x 1000 canvas without touching: a packing bound allows at most "
              << static_cast<long long>(most) << " (random placement fits fewer); choose a smaller --size, a "
              << "smaller COUNT, or --overlap\n";
    return 2;
  }
  Progress progress;
  progress.stage("generating " + std::to_string(count) + " " + kind, std::uint64_t(count), "shapes");
  std::string text;
  const long made = generate_scene<T>(kind, count, seed, lo, hi, overlap, text, [&](long placed, long tries) {
    progress.advance(std::uint64_t(placed));
    progress.detail(tries);
  });
  progress.pause();
  if (made < count) {
    std::cerr << "bvh.out: could place only " << made << " of " << count
              << " non-overlapping shapes; choose a smaller --size or --overlap\n";
    return 1;
  }
  progress.stage("writing " + path);
  const std::string temp = bvh::partial_path(path);
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) {
      progress.pause();
      std::cerr << "bvh.out: " << path << ": cannot write: " << std::strerror(errno) << "\n";
      return 2;
    }
    out << text;
    out.flush();
    if (!out) {
      progress.pause();
      std::cerr << "bvh.out: " << path << ": write failed\n";
      out.close();
      std::remove(temp.c_str());
      return 1;
    }
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    progress.pause();
    std::cerr << "bvh.out: " << path << ": cannot write: " << std::strerror(errno) << "\n";
    std::remove(temp.c_str());
    return 2;
  }
  return 0;
}

/// The course's workflow on the scene `input`, o.input opened (once: a
/// FIFO's writer is met by one open only).
template <class T, int W> int run(const Options &o, std::FILE *input) {
  std::vector<T> shapes;
  std::string error;
  Progress progress;
  struct stat st {};
  const bool sized = fstat(fileno(input), &st) == 0 && S_ISREG(st.st_mode);
  progress.stage("reading " + o.input, sized ? std::uint64_t(st.st_size) : 0, "MB");
  if (!load_scene(input, o.input, shapes, error, kReadChunk, [&](std::uint64_t read) { progress.advance(read); })) {
    progress.pause();
    std::cerr << "bvh.out: " << error << "\n";
    return 1;
  }
  BVH<T, bvh::shape_traits<T>, W> tree(o.split_threshold, o.depth_limit);
  if (o.sah) tree.set_build_rule(decltype(tree)::BuildRule::sah);
  tree.set_build_threads(o.threads);
  if (!o.incremental) {
    progress.stage("building the tree of " + std::to_string(shapes.size()) + " shapes");
    tree.construct(shapes);
  } else {
    progress.stage(o.discard_overlap ? "sampling" : "inserting", shapes.size(), "shapes");
    std::uint64_t done = 0;
    if (o.discard_overlap) {
      // insert_disjoint: the loop "insert unless it touches a kept one" on
      // every core, with exactly the loop's tree. In parts of kPart
      // candidates (each call is that loop too), for the progress line.
      const std::size_t kPart = std::size_t(1) << 18;
      for (std::size_t at = 0; at < shapes.size(); at += kPart) {
        const std::size_t end = std::min(shapes.size(), at + kPart);
        if (at == 0 && end == shapes.size()) {
          tree.insert_disjoint(shapes, o.threads);
        } else {
          tree.insert_disjoint(std::vector<T>(shapes.begin() + long(at), shapes.begin() + long(end)), o.threads);
        }
        progress.advance(done = end);
      }
    } else {
      for (const T &s : shapes) {
        tree.insert(s);
        progress.advance(++done);
      }
    }
  }
  progress.pause();
  // stdout is checked after each part, so that a failed write stops the run
  // before the next (a --print_tree of millions of lines stops at the failed
  // write: the stream then ignores the rest).
  errno = 0;
  if (o.depth_limit > 0) tree.statistics(o.print_tree);
  if (!stdout_written(error)) {
    std::cerr << "bvh.out: " << error << "\n";
    return 1;
  }
  if (o.pairs) {
    progress.stage("counting overlapping pairs");
    const std::size_t pairs = tree.count_overlapping_pairs();
    progress.pause();
    std::cout << "overlapping pairs: " << pairs << "\n";
    if (!stdout_written(error)) {
      std::cerr << "bvh.out: " << error << "\n";
      return 1;
    }
  }
  if (o.no_output) return 0;
  progress.stage("writing " + o.output);
  if (!write_svg(o.output, tree, o.visualize, &error)) {
    progress.pause();
    std::cerr << "bvh.out: " << error << "\n";
    return 1;
  }
  return 0;
}

template <class T> int run_course_width(const Options &o, std::FILE *input) {
  return run<T, bvh::course_width>(o, input);
}

// (parse_options accepts 2, 3, 4 and 8 alone.)
template <class T> int run_other_width(const Options &o, std::FILE *input) {
  switch (o.width) {
  case 2: return run<T, 2>(o, input);
  case 4: return run<T, 4>(o, input);
  default: return run<T, 8>(o, input);
  }
}

template <class T> int generate_kind(const Options &o, double lo, double hi) {
  return generate<T>(o.kind, o.count, o.seed, lo, hi, o.overlap, o.output);
}

} // namespace bvh_cli

#endif
