// main.cpp — bvh.out, the course's command line (CSCI-1200 Homework 8):
// reads a scene of disks, triangles or quads, builds a BVH in bulk or one
// shape at a time (optionally discarding shapes that touch one already
// kept: Poisson-disk sampling), prints the course's statistics and writes
// an SVG picture. It also generates random scenes in the same format.
//
//   ./bvh.out -i 36.triangles -o out.html --depth_limit 2 --visualize --print_tree
//   ./bvh.out -i overlap_1000.disks -o out.html --depth_limit 8 --incremental --discard_overlap
//   ./bvh.out --generate disks 1000 --seed 7 --overlap -o overlap_1000.disks
//
// Exit status: 0 on success, 1 when the input file is wrong (FILE:LINE:
// message on stderr), 2 for a wrong command line. No output file is left
// behind on any error.
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include "bvh.h"
#include "shapes.h"
#include "svg.h"

namespace {

const char *const kUsage =
    "usage: bvh.out -i SCENE -o PICTURE.html [--split_threshold K] [--depth_limit D]\n"
    "               [--incremental [--discard_overlap]] [--visualize] [--print_tree]\n"
    "       bvh.out --generate disks|triangles|quads COUNT -o SCENE [--seed S]\n"
    "               [--size MIN:MAX] [--overlap]\n"
    "       bvh.out --help\n";

const char *const kHelp =
    "Builds a ternary bounding volume hierarchy over the shapes of SCENE (a\n"
    ".disks, .triangles or .quads file) and draws it to PICTURE.html (SVG).\n"
    "\n"
    "  -i, --input SCENE        the shapes, one per line; the suffix gives their kind\n"
    "  -o, --output FILE        the picture (.html or .svg); with --generate, the scene\n"
    "  --split_threshold K      split a node holding more than K shapes (K >= 1, default 4)\n"
    "  --depth_limit D          never split below depth D (the root is depth 0); without it,\n"
    "                           or with D = 0, depth is unlimited and no statistics are printed\n"
    "  --incremental            insert the shapes one at a time, in input order\n"
    "  --discard_overlap        with --incremental: skip every shape that touches one\n"
    "                           already kept (Poisson-disk sampling)\n"
    "  --visualize              draw every node's box; colour shapes by their leaf\n"
    "  --print_tree             with the statistics, list every node and its shapes\n"
    "  --generate KIND COUNT    write COUNT random shapes of KIND (disks, triangles, quads)\n"
    "  --seed S                 random seed for --generate (default 1)\n"
    "  --size MIN:MAX           radius range of generated shapes (default from COUNT)\n"
    "  --overlap                generated shapes may overlap (default: none touch)\n"
    "  --help                   this text\n";

/// A command-line mistake: reported with the usage, exit status 2.
struct UsageError {
  std::string message;
};

// ---------------------------------------------------------------------------
// Reading scenes. The course's loader reads every number into a float and
// widens it to double; the printed boxes depend on that, so we do the same.

/// One line of a scene file, with a cursor and the error it may raise.
class LineParser {
public:
  LineParser(const char *begin, const char *end) : p_(begin), end_(end) {}

  /// Skips blanks; true when nothing but blanks is left.
  bool at_end() {
    skip_blanks();
    return p_ == end_;
  }

  /// The keyword `word` (e.g. "pt="), as its own token.
  bool keyword(const char *word, std::string &error) {
    skip_blanks();
    const std::size_t n = std::strlen(word);
    if (std::size_t(end_ - p_) >= n && std::memcmp(p_, word, n) == 0) {
      p_ += n;
      return true;
    }
    error = std::string("expected '") + word + "', found " + describe_here();
    return false;
  }

  /// The punctuation mark `c`, with or without blanks around it.
  bool punct(char c, std::string &error) {
    skip_blanks();
    if (p_ < end_ && *p_ == c) {
      ++p_;
      return true;
    }
    error = std::string("expected '") + c + "', found " + describe_here();
    return false;
  }

  /// A finite number read as a float and widened to double, as the course
  /// does; magnitudes above 1e9 are refused.
  bool number(double &value, const char *what, std::string &error) {
    skip_blanks();
    const char *start = p_;
    if (p_ < end_ && *p_ == '+') ++p_; // from_chars refuses '+', the course's >> accepts it
    float f = 0;
    const std::from_chars_result r = std::from_chars(p_, end_, f);
    if (r.ec == std::errc::result_out_of_range) {
      p_ = start;
      error = std::string(what) + " out of range: " + describe_here();
      return false;
    }
    if (r.ec != std::errc() || (r.ptr < end_ && !ends_token(*r.ptr))) {
      p_ = start;
      error = std::string("expected ") + what + ", found " + describe_here();
      return false;
    }
    if (!std::isfinite(f)) {
      p_ = start;
      error = std::string(what) + " is not a finite number: " + describe_here();
      return false;
    }
    if (std::fabs(f) > 1e9f) {
      p_ = start;
      error = std::string(what) + " beyond +-1e9: " + describe_here();
      return false;
    }
    p_ = r.ptr;
    value = double(f);
    return true;
  }

  /// A colour channel: an integer 0-255.
  bool channel(int &value, std::string &error) {
    skip_blanks();
    const char *start = p_;
    if (p_ < end_ && *p_ == '+') ++p_;
    const std::from_chars_result r = std::from_chars(p_, end_, value);
    if (r.ec != std::errc() || (r.ptr < end_ && !ends_token(*r.ptr)) || value < 0 || value > 255) {
      p_ = start;
      error = "expected a colour channel (an integer 0-255), found " + describe_here();
      return false;
    }
    p_ = r.ptr;
    return true;
  }

  /// `pt= <x y>`
  bool point(Point &p, std::string &error) {
    return keyword("pt=", error) && punct('<', error) && number(p.x, "a coordinate", error) &&
           number(p.y, "a coordinate", error) && punct('>', error);
  }

  /// `color= {r g b}`
  bool color(Color &c, std::string &error) {
    return keyword("color=", error) && punct('{', error) && channel(c.r, error) && channel(c.g, error) &&
           channel(c.b, error) && punct('}', error);
  }

  /// Text describing what stands at the cursor, for error messages.
  std::string describe_here() const {
    if (p_ == end_) return "the end of the line";
    const unsigned char c = static_cast<unsigned char>(*p_);
    if (c < 0x20 || c >= 0x7f) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "byte 0x%02x", c);
      return buf;
    }
    const char *q = p_;
    while (q < end_ && q - p_ < 24 && *q != ' ' && *q != '\t') ++q;
    return "'" + std::string(p_, q) + "'";
  }

private:
  static bool ends_token(char c) { return c == ' ' || c == '\t' || c == '>' || c == '}' || c == '<' || c == '{'; }
  void skip_blanks() {
    while (p_ < end_ && (*p_ == ' ' || *p_ == '\t')) ++p_;
  }
  const char *p_;
  const char *end_;
};

bool parse_shape(LineParser &in, Disk &d, std::string &error) {
  Point c;
  double radius = 0;
  Color color;
  if (!in.point(c, error) || !in.keyword("radius=", error) || !in.number(radius, "a radius", error) ||
      !in.color(color, error))
    return false;
  if (radius < 0) {
    error = "negative radius";
    return false;
  }
  d = Disk(c, radius, color);
  return true;
}

bool parse_shape(LineParser &in, Triangle &t, std::string &error) {
  Point a, b, c;
  Color color;
  if (!in.point(a, error) || !in.point(b, error) || !in.point(c, error) || !in.color(color, error)) return false;
  t = Triangle(a, b, c, color);
  return true;
}

bool parse_shape(LineParser &in, Quad &q, std::string &error) {
  Point a, b, c, d;
  Color color;
  if (!in.point(a, error) || !in.point(b, error) || !in.point(c, error) || !in.point(d, error) ||
      !in.color(color, error))
    return false;
  q = Quad(a, b, c, d, color);
  return true;
}

const std::size_t kMaxLineLength = 4096;

/// Parses a whole scene held in memory. On error returns false with
/// `error` = "NAME:LINE: what is wrong" (lines counted from 1).
template <class T>
bool parse_scene(const std::string &name, const char *data, std::size_t size, std::vector<T> &out,
                 std::string &error) {
  const char *p = data, *end = data + size;
  for (long line = 1; p < end; ++line) {
    const char *eol = static_cast<const char *>(std::memchr(p, '\n', std::size_t(end - p)));
    if (!eol) eol = end;
    const char *stop = eol;
    if (stop > p && stop[-1] == '\r') --stop; // CRLF files
    std::string what;
    if (std::size_t(stop - p) > kMaxLineLength) {
      what = "line longer than " + std::to_string(kMaxLineLength) + " characters";
    } else {
      LineParser in(p, stop);
      if (!in.at_end()) {
        T shape;
        if (parse_shape(in, shape, what)) {
          if (in.at_end())
            out.push_back(shape);
          else
            what = "unexpected " + in.describe_here() + " after the shape";
        }
      }
    }
    if (!what.empty()) {
      error = name + ":" + std::to_string(line) + ": " + what;
      return false;
    }
    p = eol + 1;
  }
  return true;
}

template <class T> bool load_scene(const std::string &path, std::vector<T> &out, std::string &error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = path + ": cannot open: " + std::strerror(errno);
    return false;
  }
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad()) {
    error = path + ": read failed";
    return false;
  }
  const std::string text = buffer.str();
  return parse_scene(path, text.data(), text.size(), out, error);
}

// ---------------------------------------------------------------------------
// Generating scenes.

/// splitmix64: a tiny generator whose stream is the same on every compiler
/// (std::uniform_real_distribution is not), so a seed names one scene.
class Random {
public:
  explicit Random(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  /// Uniform in [lo, hi).
  double uniform(double lo, double hi) { return lo + (hi - lo) * double(next() >> 11) * 0x1.0p-53; }
  int channel() { return int(next() % 256); }

private:
  std::uint64_t state_;
};

double round_to(double v, double unit) { return std::round(v / unit) * unit; }

/// Formats one shape as a scene line, with the precision of the course's
/// files (one decimal for coordinates, three for radii).
std::string format_line(const Point &c, double radius, const Color &color) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "pt= <%5.1f %5.1f> radius= %7.3f color= {%3d %3d %3d}\n", c.x, c.y, radius,
                color.r, color.g, color.b);
  return buf;
}
std::string format_line(const Point *pts, int n, const Color &color) {
  std::string s;
  char buf[64];
  for (int i = 0; i < n; ++i) {
    std::snprintf(buf, sizeof buf, "pt= <%5.1f %5.1f> ", pts[i].x, pts[i].y);
    s += buf;
  }
  std::snprintf(buf, sizeof buf, "color= {%3d %3d %3d}\n", color.r, color.g, color.b);
  return s + buf;
}

/// Makes one random shape's line: centre anywhere its whole shape fits in
/// the 1000 x 1000 canvas, size uniform in [lo, hi]. Triangles have their
/// vertices at jittered thirds of a circle, quads are rotated squares.
std::string random_line(const std::string &kind, Random &rng, double lo, double hi) {
  const double size = rng.uniform(lo, hi);
  const Point c(rng.uniform(size, 1000 - size), rng.uniform(size, 1000 - size));
  const Color color(rng.channel(), rng.channel(), rng.channel());
  if (kind == "disks") return format_line(Point(round_to(c.x, 0.1), round_to(c.y, 0.1)), round_to(size, 0.001), color);
  const double pi = 3.14159265358979323846;
  const double turn = rng.uniform(0, 2 * pi);
  Point pts[4];
  const int n = kind == "triangles" ? 3 : 4;
  for (int i = 0; i < n; ++i) {
    const double angle = turn + 2 * pi * i / n + (n == 3 ? rng.uniform(-0.5, 0.5) : 0.0);
    pts[i] = Point(round_to(c.x + size * std::cos(angle), 0.1), round_to(c.y + size * std::sin(angle), 0.1));
  }
  return format_line(pts, n, color);
}

/// Adds `line` to the scene unless `no_overlap` and it touches a shape
/// already placed. The check uses the values the loader will read back.
template <class T> bool place(const std::string &line, bool no_overlap, BVH<T> &placed) {
  if (!no_overlap) return true;
  LineParser in(line.data(), line.data() + line.size() - 1);
  T shape;
  std::string error;
  if (!parse_shape(in, shape, error) || placed.collision(shape)) return false;
  placed.insert(shape);
  return true;
}

template <class T>
int generate(const std::string &kind, long count, std::uint64_t seed, double lo, double hi, bool overlap,
             const std::string &path) {
  Random rng(seed);
  BVH<T> placed(8, BVH<T>::unlimited);
  std::string text;
  long made = 0;
  // Non-overlapping scenes fill up; give up rather than loop forever.
  const long max_tries = overlap ? count : 1000 + 200 * count;
  for (long tries = 0; made < count && tries < max_tries; ++tries) {
    const std::string line = random_line(kind, rng, lo, hi);
    if (!place(line, !overlap, placed)) continue;
    text += line;
    ++made;
  }
  if (made < count) {
    std::cerr << "bvh.out: could place only " << made << " of " << count
              << " non-overlapping shapes; choose a smaller --size or --overlap\n";
    return 1;
  }
  const std::string temp = path + ".partial";
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) {
      std::cerr << "bvh.out: " << path << ": cannot write: " << std::strerror(errno) << "\n";
      return 2;
    }
    out << text;
    out.flush();
    if (!out) {
      std::cerr << "bvh.out: " << path << ": write failed\n";
      out.close();
      std::remove(temp.c_str());
      return 1;
    }
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    std::cerr << "bvh.out: " << path << ": cannot write: " << std::strerror(errno) << "\n";
    std::remove(temp.c_str());
    return 2;
  }
  return 0;
}

// ---------------------------------------------------------------------------
// The course's workflow.

struct Options {
  std::string input, output;
  int split_threshold = 4;
  int depth_limit = 0; // 0: unlimited, and no statistics (the course's default)
  bool incremental = false, discard_overlap = false, visualize = false, print_tree = false;
  bool generate = false, overlap = false;
  std::string kind;
  long count = 0;
  std::uint64_t seed = 1;
  double size_lo = -1, size_hi = -1;
};

template <class T> int run(const Options &o) {
  std::vector<T> shapes;
  std::string error;
  if (!load_scene(o.input, shapes, error)) {
    std::cerr << "bvh.out: " << error << "\n";
    return 1;
  }
  BVH<T> tree(o.split_threshold, o.depth_limit);
  if (!o.incremental) {
    tree.construct(shapes);
  } else {
    for (const T &s : shapes)
      if (!o.discard_overlap || !tree.collision(s)) tree.insert(s);
  }
  if (o.depth_limit > 0) tree.statistics(o.print_tree);
  if (!write_svg(o.output, tree, o.visualize, &error)) {
    std::cerr << "bvh.out: " << error << "\n";
    return 1;
  }
  return 0;
}

bool ends_with(const std::string &s, const std::string &suffix) {
  return s.size() > suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

long parse_integer(const std::string &flag, const char *text, long lo, long hi) {
  long value = 0;
  const char *end = text + std::strlen(text);
  const std::from_chars_result r = std::from_chars(text, end, value);
  if (r.ec != std::errc() || r.ptr != end || value < lo || value > hi)
    throw UsageError{flag + " needs an integer from " + std::to_string(lo) + " to " + std::to_string(hi) +
                     ", not '" + text + "'"};
  return value;
}

double parse_real(const std::string &flag, const std::string &text) {
  double value = 0;
  const std::from_chars_result r = std::from_chars(text.data(), text.data() + text.size(), value);
  if (r.ec != std::errc() || r.ptr != text.data() + text.size() || !(value > 0) || value > 500)
    throw UsageError{flag + " needs sizes above 0 and at most 500, not '" + text + "'"};
  return value;
}

Options parse_options(int argc, char **argv) {
  Options o;
  bool depth_given = false;
  auto value = [&](int &i) -> const char * {
    if (i + 1 >= argc) throw UsageError{std::string(argv[i]) + " needs a value"};
    return argv[++i];
  };
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "-i" || arg == "--input") {
      o.input = value(i);
    } else if (arg == "-o" || arg == "--output") {
      o.output = value(i);
    } else if (arg == "--split_threshold") {
      o.split_threshold = int(parse_integer(arg, value(i), 1, 1000000));
    } else if (arg == "--depth_limit") {
      o.depth_limit = int(parse_integer(arg, value(i), 0, 1000000));
      depth_given = true;
    } else if (arg == "--incremental") {
      o.incremental = true;
    } else if (arg == "--discard_overlap") {
      o.discard_overlap = true;
    } else if (arg == "--visualize") {
      o.visualize = true;
    } else if (arg == "--print_tree") {
      o.print_tree = true;
    } else if (arg == "--generate") {
      o.generate = true;
      o.kind = value(i);
      if (o.kind != "disks" && o.kind != "triangles" && o.kind != "quads")
        throw UsageError{"--generate needs a kind: disks, triangles or quads, not '" + o.kind + "'"};
      o.count = parse_integer("--generate COUNT", value(i), 0, 100000000);
    } else if (arg == "--seed") {
      o.seed = std::uint64_t(parse_integer(arg, value(i), 0, 2147483647));
    } else if (arg == "--size") {
      const std::string text = value(i);
      const std::size_t colon = text.find(':');
      if (colon == std::string::npos) throw UsageError{"--size needs MIN:MAX, not '" + text + "'"};
      o.size_lo = parse_real(arg, text.substr(0, colon));
      o.size_hi = parse_real(arg, text.substr(colon + 1));
      if (o.size_lo > o.size_hi) throw UsageError{"--size needs MIN <= MAX, not '" + text + "'"};
    } else if (arg == "--overlap") {
      o.overlap = true;
    } else {
      throw UsageError{"unknown argument '" + arg + "'"};
    }
  }
  (void)depth_given;
  if (o.output.empty()) throw UsageError{"missing -o OUTPUT"};
  if (o.generate) {
    if (!o.input.empty()) throw UsageError{"--generate takes no -i"};
    if (!ends_with(o.output, "." + o.kind))
      throw UsageError{"the generated scene's name must end in ." + o.kind + ": '" + o.output + "'"};
    return o;
  }
  if (o.input.empty()) throw UsageError{"missing -i INPUT"};
  if (o.discard_overlap && !o.incremental) throw UsageError{"--discard_overlap needs --incremental"};
  if (!ends_with(o.output, ".html") && !ends_with(o.output, ".svg"))
    throw UsageError{"the picture's name must end in .html or .svg: '" + o.output + "'"};
  if (!ends_with(o.input, ".disks") && !ends_with(o.input, ".triangles") && !ends_with(o.input, ".quads"))
    throw UsageError{"unknown input kind '" + o.input + "': the name must end in .disks, .triangles or .quads"};
  return o;
}

/// Fails early, before any work, when the output cannot be created.
bool output_writable(const std::string &path) {
  const std::string temp = path + ".partial";
  std::ofstream probe(temp, std::ios::binary | std::ios::trunc);
  if (!probe) {
    std::cerr << "bvh.out: " << path << ": cannot write: " << std::strerror(errno) << "\n" << kUsage;
    return false;
  }
  probe.close();
  std::remove(temp.c_str());
  return true;
}

} // namespace

/// The whole program, callable from tests and fuzz targets.
int bvh_main(int argc, char **argv) {
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "--help" || std::string(argv[i]) == "-h") {
      std::cout << kUsage << "\n" << kHelp;
      return 0;
    }
  Options o;
  try {
    o = parse_options(argc, argv);
  } catch (const UsageError &e) {
    std::cerr << "bvh.out: " << e.message << "\n" << kUsage;
    return 2;
  }
  if (!o.generate && !std::ifstream(o.input, std::ios::binary)) {
    std::cerr << "bvh.out: " << o.input << ": cannot open: " << std::strerror(errno) << "\n" << kUsage;
    return 2;
  }
  if (!output_writable(o.output)) return 2;
  if (o.generate) {
    // Default sizes: a fifth of the canvas covered (no overlap), or about
    // twice covered (overlap), by COUNT shapes.
    double hi = o.size_hi, lo = o.size_lo;
    if (hi < 0) {
      const double n = double(o.count > 0 ? o.count : 1);
      hi = std::min(200.0, (o.overlap ? 1400.0 : 420.0) / std::sqrt(n));
      lo = hi / 2;
    }
    if (o.kind == "disks") return generate<Disk>(o.kind, o.count, o.seed, lo, hi, o.overlap, o.output);
    if (o.kind == "triangles") return generate<Triangle>(o.kind, o.count, o.seed, lo, hi, o.overlap, o.output);
    return generate<Quad>(o.kind, o.count, o.seed, lo, hi, o.overlap, o.output);
  }
  if (ends_with(o.input, ".disks")) return run<Disk>(o);
  if (ends_with(o.input, ".triangles")) return run<Triangle>(o);
  return run<Quad>(o);
}

#ifndef BVH_NO_MAIN
int main(int argc, char **argv) { return bvh_main(argc, argv); }
#endif
