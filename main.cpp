// main.cpp — bvh.out, the course's command line (CSCI-1200 Homework 8):
// reads a scene of disks, triangles or quads (or, in a .shapes file, all
// three mixed), builds a BVH in bulk or one
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
#include <algorithm>
#include <cerrno>
#include <cfloat>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <memory>
#include <new>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "bvh.h"
#include "shapes.h"
#include "svg.h"

namespace {

const char *const kUsage =
    "usage: bvh.out -i SCENE -o PICTURE.html [--split_threshold K] [--depth_limit D]\n"
    "               [--incremental [--discard_overlap]] [--visualize] [--print_tree] [--pairs]\n"
    "               [--build course|sah]\n"
    "       bvh.out --generate disks|triangles|quads|shapes COUNT -o SCENE [--seed S]\n"
    "               [--size MIN:MAX] [--overlap]\n"
    "       bvh.out --help\n";

const char *const kHelp =
    "Builds a ternary bounding volume hierarchy over the shapes of SCENE (a\n"
    ".disks, .triangles or .quads file, or a .shapes file whose lines may be any of\n"
    "the three) and draws it to PICTURE.html (SVG).\n"
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
    "  --build course|sah       how nodes are cut: the course's rule (default), or the\n"
    "                           binned surface area heuristic (also for insert's splits)\n"
    "  --pairs                  print 'overlapping pairs: N', the number of pairs of shapes\n"
    "                           in the tree that intersect (after the statistics, if any)\n"
    "  --generate KIND COUNT    write COUNT random shapes of KIND (disks, triangles, quads,\n"
    "                           or shapes: each line a random one of the three)\n"
    "  --seed S                 random seed for --generate (default 1)\n"
    "  --size MIN:MAX           radius range of generated shapes (default from COUNT)\n"
    "  --overlap                generated shapes may overlap (default: none touch)\n"
    "  --help                   this text\n";

/// A command-line mistake: reported with the usage, exit status 2. The
/// message quotes the user's words, so control bytes in them are shown as
/// \xNN and a huge word is cut: the message stays one readable line.
struct UsageError {
  explicit UsageError(const std::string &text) {
    const std::size_t kMaxShown = 1000;
    for (std::size_t i = 0; i < text.size() && message.size() < kMaxShown; ++i) {
      const unsigned char c = static_cast<unsigned char>(text[i]);
      if (c < 0x20 || c == 0x7f) {
        char buf[8];
        std::snprintf(buf, sizeof buf, "\\x%02x", unsigned(c));
        message += buf;
      } else {
        message += char(c);
      }
    }
    if (message.size() >= kMaxShown) message += "...";
  }
  std::string message;
};

// ---------------------------------------------------------------------------
// Reading scenes. The course's loader reads every number into a float and
// widens it to double; the printed boxes depend on that, so we do the same.

const std::size_t kMaxLineLength = 4096;
const float kMaxCoordinate = 1e9f;

// 10^k for k = 0..10. Each is an exact float (5^10 < 2^24), which is what
// makes LineParser::decimal correctly rounded.
constexpr float kPowersOfTen[] = {1e0f, 1e1f, 1e2f, 1e3f, 1e4f, 1e5f, 1e6f, 1e7f, 1e8f, 1e9f, 1e10f};

// decimal() relies on one float division being rounded once, in float.
// intersect.h asserts the same for doubles; this states it for this file.
static_assert(std::numeric_limits<float>::is_iec559 && FLT_EVAL_METHOD == 0,
              "the scene reader needs IEEE floats evaluated without extended precision");

// Marks the error paths, so that the readers' hot paths stay small enough
// to be inlined into one loop per shape kind.
#if defined(__GNUC__)
#define BVH_COLD __attribute__((noinline, cold))
#else
#define BVH_COLD
#endif

/// One line of a scene file (without its line end) and a cursor into it.
/// Each reader skips the blanks (spaces, tabs) before its token. On a
/// mistake it returns false, sets `error` and leaves the cursor on the
/// token at fault, so describe_here() can quote it.
///
/// The byte at `end` must be readable and be the line end ('\r', '\n') or
/// a '\0': no token goes on over it, so the hot loops test characters and
/// not the cursor's distance to the end.
class LineParser {
public:
  LineParser(const char *begin, const char *end) : p_(begin), end_(end) {}

  /// Skips blanks; true when nothing but blanks is left.
  bool at_end() {
    p_ = skip_blanks(p_);
    return p_ == end_;
  }

  /// The keyword `word` (e.g. "pt="). Blanks after it are optional.
  template <std::size_t N> bool keyword(const char (&word)[N], std::string &error) {
    const char *q = p_ = skip_blanks(p_);
    if (!starts_with(q, word, std::make_index_sequence<N - 1>())) return expected(word, error);
    p_ = q + N - 1;
    return true;
  }

  /// True when the next token starts with the keyword `word`; nothing is
  /// read, so the caller can choose between forms (mixed scenes).
  template <std::size_t N> bool next_is(const char (&word)[N]) {
    p_ = skip_blanks(p_);
    return starts_with(p_, word, std::make_index_sequence<N - 1>());
  }

  /// Sets `error` to "expected WHAT, found <the token here>"; false.
  BVH_COLD bool expected_here(const char *what, std::string &error) const {
    error = std::string("expected ") + what + ", found " + describe_here();
    return false;
  }

  /// The punctuation mark `c`, with or without blanks around it.
  bool punct(char c, std::string &error) {
    const char *q = p_ = skip_blanks(p_);
    if (*q == c) {
      p_ = q + 1;
      return true;
    }
    const char word[] = {c, '\0'};
    return expected(word, error);
  }

  /// A finite number of magnitude at most 1e9, read as a float (correctly
  /// rounded, as the course's `>>` does) and widened to double. Accepted
  /// forms: those of std::from_chars (decimal, optional exponent) with an
  /// optional '+' in front; no hexadecimal, inf or nan. `what` names the
  /// number in messages ("a coordinate").
  bool number(double &value, const char *what, std::string &error) {
    p_ = skip_blanks(p_);
    float f = 0;
    if (!decimal(f) && !general_number(f, what, error)) return false;
    value = double(f);
    return true;
  }

  /// A colour channel: an integer 0-255, optionally signed ("+7"; "-0" is
  /// 0), as the course's `>>` into an int accepts.
  bool channel(int &value, std::string &error) {
    const char *q = p_ = skip_blanks(p_);
    const bool negative = *q == '-';
    if (*q == '-' || *q == '+') ++q;
    const char *digits = q;
    int v = 0;
    // Stops as soon as v > 255, so no run of digits can overflow it.
    while (is_digit(*q) && v <= 255) v = v * 10 + (*q++ - '0');
    if (q == digits || (q != end_ && !ends_token(*q)) || v > 255 || (negative && v != 0))
      return fail("expected a colour channel (an integer 0-255), found ", error);
    value = v;
    p_ = q;
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

  /// Text quoting the token at the cursor, for messages: "'x'" (at most 24
  /// bytes, other bytes than printable ASCII as \xNN, so a message stays one
  /// printable line), "byte 0xNN" when the token starts with such a byte,
  /// or "the end of the line".
  std::string describe_here() const {
    if (p_ == end_) return "the end of the line";
    char buf[8];
    if (!printable(*p_)) {
      std::snprintf(buf, sizeof buf, "0x%02x", unsigned(static_cast<unsigned char>(*p_)));
      return std::string("byte ") + buf;
    }
    std::string s = "'";
    for (const char *q = p_; q < end_ && q - p_ < 24 && *q != ' ' && *q != '\t'; ++q) {
      if (q > p_ && is_mark(*q)) break;
      if (printable(*q)) {
        s += *q;
      } else {
        std::snprintf(buf, sizeof buf, "\\x%02x", unsigned(static_cast<unsigned char>(*q)));
        s += buf;
      }
    }
    return s + "'";
  }

private:
  static bool is_digit(char c) { return unsigned(c - '0') < 10; }
  static bool is_mark(char c) { return c == '<' || c == '>' || c == '{' || c == '}'; }
  static bool printable(char c) { return c >= 0x20 && c < 0x7f; }
  static bool ends_token(char c) { return c == ' ' || c == '\t' || is_mark(c); }
  // Compares byte by byte, unrolled, stopping at the first difference: it
  // never reads past the line's end byte, which no keyword contains.
  template <std::size_t N, std::size_t... I>
  static bool starts_with(const char *q, const char (&word)[N], std::index_sequence<I...>) {
    return ((q[I] == word[I]) && ...);
  }
  // Takes and returns the cursor rather than moving p_: a char read may
  // alias p_ itself, so a loop on the member would store it every step.
  const char *skip_blanks(const char *q) const {
    while (*q == ' ' || *q == '\t') ++q;
    return q;
  }

  BVH_COLD bool fail(const char *message, std::string &error) const {
    error = message + describe_here();
    return false;
  }
  BVH_COLD bool expected(const char *word, std::string &error) const {
    error = std::string("expected '") + word + "', found " + describe_here();
    return false;
  }

  // The fast path for the forms scene files use: [+-]digits[.digits] with
  // a mantissa below 2^24 and at most 10 decimals. The mantissa m and 10^k
  // are then exact floats, so the one IEEE division m / 10^k is the
  // correctly rounded value of the decimal: exactly what from_chars gives
  // (tests/test_parse.cpp checks millions). Such a value is below 2^24, so
  // within +-1e9. Anything else returns false without moving the cursor.
  bool decimal(float &f) {
    const char *q = p_;
    const bool negative = *q == '-';
    if (*q == '-' || *q == '+') ++q;
    // m may wrap on a long run of digits; the count below then rejects it.
    std::uint64_t m = 0;
    const char *first = q;
    for (; is_digit(*q); ++q) m = m * 10 + std::uint64_t(*q - '0');
    std::ptrdiff_t digits = q - first, decimals = 0;
    if (*q == '.') {
      first = ++q;
      for (; is_digit(*q); ++q) m = m * 10 + std::uint64_t(*q - '0');
      decimals = q - first;
      digits += decimals;
    }
    if (digits == 0 || digits > 19 || m >= (1u << 24) || decimals > 10 || (q != end_ && !ends_token(*q)))
      return false;
    const float v = float(m) / kPowersOfTen[decimals];
    f = negative ? -v : v;
    p_ = q;
    return true;
  }

  // Every other form, through std::from_chars: exponents, long mantissas,
  // and the mistakes, which it reports.
  BVH_COLD bool general_number(float &f, const char *what, std::string &error) {
    const char *q = p_;
    // from_chars refuses a leading '+', which `>>` accepts ("+-3" stays an error).
    if (end_ - q >= 2 && q[0] == '+' && q[1] != '-') ++q;
    const std::from_chars_result r = std::from_chars(q, end_, f);
    if (r.ec == std::errc::result_out_of_range) return fail((std::string(what) + " out of range: ").c_str(), error);
    if (r.ec != std::errc() || (r.ptr < end_ && !ends_token(*r.ptr)))
      return fail(("expected " + std::string(what) + ", found ").c_str(), error);
    if (!std::isfinite(f)) return fail((std::string(what) + " is not a finite number: ").c_str(), error);
    if (!(std::fabs(f) <= kMaxCoordinate)) return fail((std::string(what) + " beyond +-1e9: ").c_str(), error);
    p_ = r.ptr;
    return true;
  }

  const char *p_;
  const char *end_;
};

/// Reads a disk line's fields after its centre.
bool parse_disk_rest(LineParser &in, const Point &c, Disk &d, std::string &error) {
  double radius = 0;
  Color color;
  if (!in.keyword("radius=", error) || !in.number(radius, "a radius", error) || !in.color(color, error))
    return false;
  if (radius < 0) {
    error = "negative radius";
    return false;
  }
  d = Disk(c, radius + 0.0, color); // + 0.0: "-0" becomes 0, not an r="-0" in the picture
  return true;
}

/// Reads one disk line's fields.
bool parse_shape(LineParser &in, Disk &d, std::string &error) {
  Point c;
  return in.point(c, error) && parse_disk_rest(in, c, d, error);
}

/// Reads one triangle line's fields.
bool parse_shape(LineParser &in, Triangle &t, std::string &error) {
  Point a, b, c;
  Color color;
  if (!in.point(a, error) || !in.point(b, error) || !in.point(c, error) || !in.color(color, error)) return false;
  t = Triangle(a, b, c, color);
  return true;
}

/// Reads one quad line's fields.
bool parse_shape(LineParser &in, Quad &q, std::string &error) {
  Point a, b, c, d;
  Color color;
  if (!in.point(a, error) || !in.point(b, error) || !in.point(c, error) || !in.point(d, error) ||
      !in.color(color, error))
    return false;
  q = Quad(a, b, c, d, color);
  return true;
}

/// Reads one line of a mixed scene (.shapes), whose own form says its kind:
/// a first point followed by `radius=` is a disk; three or four points
/// followed by `color=` are a triangle or a quad.
bool parse_shape(LineParser &in, Shape &s, std::string &error) {
  Point p[4];
  if (!in.point(p[0], error)) return false;
  if (in.next_is("radius=")) {
    Disk d;
    if (!parse_disk_rest(in, p[0], d, error)) return false;
    s = d;
    return true;
  }
  int n = 1;
  for (; n < 4 && in.next_is("pt="); ++n)
    if (!in.point(p[n], error)) return false;
  if (n == 1) return in.expected_here("'radius=' or 'pt='", error);
  if (n == 2) return in.expected_here("'pt=' (a triangle or quad has 3 or 4 points)", error);
  if (n == 3 && !in.next_is("color=")) return in.expected_here("'pt=' or 'color='", error);
  Color color;
  if (!in.color(color, error)) return false;
  if (n == 3)
    s = Triangle(p[0], p[1], p[2], color);
  else
    s = Quad(p[0], p[1], p[2], p[3], color);
  return true;
}

/// Parses one line, [p, stop), into `out` (nothing for a blank line); the
/// byte at `stop` is its line end (see LineParser). False with `what` set.
template <class T> bool parse_line(const char *p, const char *stop, std::vector<T> &out, std::string &what) {
  if (std::size_t(stop - p) > kMaxLineLength) {
    what = "line longer than " + std::to_string(kMaxLineLength) + " characters";
    return false;
  }
  LineParser in(p, stop);
  if (in.at_end()) return true;
  T shape;
  if (!parse_shape(in, shape, what)) return false;
  if (!in.at_end()) {
    what = "unexpected " + in.describe_here() + " after the shape";
    return false;
  }
  out.push_back(shape);
  return true;
}

/// Parses the scene lines in [p, end), the first numbered `line`; the last
/// may lack its '\n'. Appends the shapes to `out`. Returns the number of the
/// line that would follow, or 0 with `error` = "NAME:LINE: what is wrong".
template <class T>
long parse_lines(const std::string &name, const char *p, const char *end, long line, std::vector<T> &out,
                 std::string &error) {
  std::string what;
  for (; p < end; ++line) {
    const char *eol = static_cast<const char *>(std::memchr(p, '\n', std::size_t(end - p)));
    const char *line_end = eol ? eol : end;
    const char *stop = line_end > p && line_end[-1] == '\r' ? line_end - 1 : line_end; // CRLF files
    bool ok;
    if (stop < end) {
      ok = parse_line(p, stop, out, what);
    } else {
      // A last line without its '\n': a copy gets the '\0' end LineParser needs.
      const std::string last(p, std::min<std::size_t>(std::size_t(stop - p), kMaxLineLength + 1));
      ok = parse_line(last.data(), last.data() + last.size(), out, what);
    }
    if (!ok) {
      error = name + ":" + std::to_string(line) + ": " + what;
      return 0;
    }
    p = line_end == end ? end : line_end + 1;
  }
  return line;
}

/// Length of a UTF-8 byte-order mark at `p` (3), or 0. Some editors start
/// files with one; it is skipped.
std::size_t bom_length(const char *p, const char *end) {
  return end - p >= 3 && p[0] == '\xef' && p[1] == '\xbb' && p[2] == '\xbf' ? 3 : 0;
}

/// Parses a whole scene held in memory (`name` is for messages) and appends
/// its shapes to `out`. On error returns false with `error` = "NAME:LINE:
/// what is wrong" (lines counted from 1); `out` may then hold the shapes of
/// the lines before.
template <class T>
bool parse_scene(const std::string &name, const char *data, std::size_t size, std::vector<T> &out,
                 std::string &error) {
  return parse_lines(name, data + bom_length(data, data + size), data + size, 1, out, error) != 0;
}

const std::size_t kReadChunk = std::size_t(1) << 20;

/// Reads the scene file `path` and appends its shapes to `out`; false with
/// `error` ("PATH: cannot open: ...", or parse_scene's message) otherwise.
/// The file is read `chunk` bytes at a time (tests vary it) and each chunk's
/// complete lines parsed at once, so memory stays small and a broken file
/// (even an endless one) fails at its first bad line.
template <class T>
bool load_scene(const std::string &path, std::vector<T> &out, std::string &error, std::size_t chunk = kReadChunk) {
  std::unique_ptr<std::FILE, int (*)(std::FILE *)> file(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!file) {
    error = path + ": cannot open: " + std::strerror(errno);
    return false;
  }
  if (chunk < 1) chunk = 1;
  // An unfinished line waits at the front of the buffer for the rest of it;
  // one longer than this (a line and its '\r') is an error already.
  const std::size_t carry_max = kMaxLineLength + 1;
  std::unique_ptr<char[]> buffer(new char[carry_max + chunk]);
  char *const buf = buffer.get();
  std::size_t have = 0;
  long line = 1;
  bool at_start = true;
  for (;;) {
    const std::size_t got = std::fread(buf + have, 1, chunk, file.get());
    if (got < chunk && std::ferror(file.get())) {
      error = path + ": cannot read: " + std::strerror(errno);
      return false;
    }
    const bool eof = got < chunk;
    have += got;
    const char *p = buf, *const end = buf + have;
    if (at_start) {
      if (have < 3 && !eof) continue; // the byte-order mark may be incomplete
      p += bom_length(p, end);
      at_start = false;
    }
    const char *stop = end;
    if (!eof)
      while (stop > p && stop[-1] != '\n') --stop;
    if (!(line = parse_lines(path, p, stop, line, out, error))) return false;
    if (eof) return true;
    have = std::size_t(end - stop);
    if (have > carry_max) return parse_lines(path, stop, end, line, out, error) != 0;
    std::memmove(buf, stop, have);
  }
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
/// vertices at jittered thirds of a circle, quads are rotated squares; for
/// "shapes", each line is one of the three kinds, equally likely.
std::string random_line(const std::string &kind, Random &rng, double lo, double hi) {
  if (kind == "shapes") {
    static const char *const kinds[] = {"disks", "triangles", "quads"};
    return random_line(kinds[rng.next() % 3], rng, lo, hi);
  }
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
  bool incremental = false, discard_overlap = false, visualize = false, print_tree = false, pairs = false;
  bool sah = false; // --build sah
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
  if (o.sah) tree.set_build_rule(BVH<T>::BuildRule::sah);
  if (!o.incremental) {
    tree.construct(shapes);
  } else {
    for (const T &s : shapes)
      if (!o.discard_overlap || !tree.collision(s)) tree.insert(s);
  }
  if (o.depth_limit > 0) tree.statistics(o.print_tree);
  if (o.pairs) std::cout << "overlapping pairs: " << tree.count_overlapping_pairs() << std::endl;
  if (!write_svg(o.output, tree, o.visualize, &error)) {
    std::cerr << "bvh.out: " << error << "\n";
    return 1;
  }
  return 0;
}

bool ends_with(const std::string &s, const std::string &suffix) {
  return s.size() > suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

long parse_integer(const std::string &flag, const std::string &text, long lo, long hi) {
  long value = 0;
  const char *end = text.data() + text.size();
  const std::from_chars_result r = std::from_chars(text.data(), end, value);
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

/// The option's one name (-i is --input, -o is --output), or "" for a word
/// that is not an option.
std::string option_name(const std::string &arg) {
  static const char *const names[] = {"--input", "--output", "--split_threshold", "--depth_limit",
                                      "--incremental", "--discard_overlap", "--visualize", "--print_tree",
                                      "--generate", "--seed", "--size", "--overlap", "--pairs", "--build"};
  if (arg == "-i") return "--input";
  if (arg == "-o") return "--output";
  for (const char *name : names)
    if (arg == name) return arg;
  return "";
}

/// The command line (without --help, which bvh_main handles first). Every
/// option may be given once: a repeat is more likely a slip (two -o) than
/// a wish, so it is an error rather than "the last one wins".
Options parse_options(int argc, char **argv) {
  Options o;
  std::vector<std::string> seen;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const std::string name = option_name(arg);
    if (name.empty()) throw UsageError{"unknown argument '" + arg + "'"};
    if (std::find(seen.begin(), seen.end(), name) != seen.end()) throw UsageError{arg + " given twice"};
    seen.push_back(name);
    // An empty word, or an option where the value should be, means the value was forgotten.
    auto value = [&]() -> std::string {
      if (i + 1 >= argc || argv[i + 1][0] == '\0' || !option_name(argv[i + 1]).empty())
        throw UsageError{arg + " needs a value"};
      return argv[++i];
    };
    if (name == "--input") {
      o.input = value();
    } else if (name == "--output") {
      o.output = value();
    } else if (name == "--split_threshold") {
      o.split_threshold = int(parse_integer(arg, value(), 1, 1000000));
    } else if (name == "--depth_limit") {
      o.depth_limit = int(parse_integer(arg, value(), 0, 1000000));
    } else if (name == "--incremental") {
      o.incremental = true;
    } else if (name == "--discard_overlap") {
      o.discard_overlap = true;
    } else if (name == "--visualize") {
      o.visualize = true;
    } else if (name == "--print_tree") {
      o.print_tree = true;
    } else if (name == "--pairs") {
      o.pairs = true;
    } else if (name == "--build") {
      const std::string rule = value();
      if (rule != "course" && rule != "sah") throw UsageError{"--build needs course or sah, not '" + rule + "'"};
      o.sah = rule == "sah";
    } else if (name == "--generate") {
      o.generate = true;
      o.kind = value();
      if (o.kind != "disks" && o.kind != "triangles" && o.kind != "quads" && o.kind != "shapes")
        throw UsageError{"--generate needs a kind: disks, triangles, quads or shapes, not '" + o.kind + "'"};
      o.count = parse_integer("--generate COUNT", value(), 0, 100000000);
    } else if (name == "--seed") {
      o.seed = std::uint64_t(parse_integer(arg, value(), 0, 2147483647));
    } else if (name == "--size") {
      const std::string text = value();
      const std::size_t colon = text.find(':');
      if (colon == std::string::npos) throw UsageError{"--size needs MIN:MAX, not '" + text + "'"};
      o.size_lo = parse_real(arg, text.substr(0, colon));
      o.size_hi = parse_real(arg, text.substr(colon + 1));
      if (o.size_lo > o.size_hi) throw UsageError{"--size needs MIN <= MAX, not '" + text + "'"};
    } else {
      o.overlap = true;
    }
  }
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
  if (!ends_with(o.input, ".disks") && !ends_with(o.input, ".triangles") && !ends_with(o.input, ".quads") &&
      !ends_with(o.input, ".shapes"))
    throw UsageError{"unknown input kind '" + o.input +
                     "': the name must end in .disks, .triangles, .quads or .shapes"};
  return o;
}

/// Checks, before any work, that the input can be opened, that the output
/// can be created, and that they are not one file (through a link): the
/// picture would replace the scene. Sets `error` (exit status 2) if not.
bool check_files(const Options &o, std::string &error) {
  std::error_code ec;
  if (!o.generate) {
    // fopen succeeds on a directory on Linux; only reading it fails.
    if (std::filesystem::is_directory(o.input, ec)) {
      error = o.input + ": cannot open: " + std::strerror(EISDIR);
      return false;
    }
    std::FILE *in = std::fopen(o.input.c_str(), "rb");
    if (!in) {
      error = o.input + ": cannot open: " + std::strerror(errno);
      return false;
    }
    std::fclose(in);
    if (std::filesystem::equivalent(o.input, o.output, ec)) {
      error = "-i and -o name the same file: '" + o.output + "'";
      return false;
    }
  }
  if (std::filesystem::is_directory(o.output, ec)) {
    error = o.output + ": cannot write: " + std::strerror(EISDIR);
    return false;
  }
  // The output is written under this name, then renamed. Whatever holds the
  // name now (a stale temporary, or a link that would be written through)
  // goes first; removing a link leaves its target alone.
  const std::string temp = o.output + ".partial";
  std::remove(temp.c_str());
  std::FILE *probe = std::fopen(temp.c_str(), "wbx");
  if (!probe) {
    error = o.output + ": cannot write: " + std::strerror(errno);
    return false;
  }
  std::fclose(probe);
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
  std::string error;
  try {
    o = parse_options(argc, argv);
    if (!check_files(o, error)) throw UsageError{error};
  } catch (const UsageError &e) {
    std::cerr << "bvh.out: " << e.message << "\n" << kUsage;
    return 2;
  }
  try {
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
      if (o.kind == "quads") return generate<Quad>(o.kind, o.count, o.seed, lo, hi, o.overlap, o.output);
      return generate<Shape>(o.kind, o.count, o.seed, lo, hi, o.overlap, o.output);
    }
    if (ends_with(o.input, ".disks")) return run<Disk>(o);
    if (ends_with(o.input, ".triangles")) return run<Triangle>(o);
    if (ends_with(o.input, ".quads")) return run<Quad>(o);
    return run<Shape>(o);
  } catch (const std::bad_alloc &) {
    // A scene too big for this machine's memory.
    std::cerr << "bvh.out: out of memory\n";
    return 1;
  }
}

#ifndef BVH_NO_MAIN
int main(int argc, char **argv) { return bvh_main(argc, argv); }
#endif
