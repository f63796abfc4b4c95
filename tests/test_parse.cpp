// tests/test_parse.cpp — the scene reader (scene.h) against references:
// its fast decimal path against std::from_chars on millions of random
// numbers, mixed (.shapes) lines against the one-kind readers, and the
// chunked file reader against the in-memory one at many chunk sizes.
// Seeds are printed (BVH_SEED changes them; BVH_TEST_SCALE shrinks runs).
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <system_error>
#include <vector>

#include "check.h"
#include <bvh/generate.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
#include "scenes.h"

namespace {

using namespace bvh_scene;

std::string seed_note(const char *what, unsigned seed) {
  return std::string(what) + " BVH_SEED=" + std::to_string(seed) + " BVH_TEST_SCALE=" + std::to_string(scale());
}

/// What the course's `>> float` gives for `text`: from_chars into a float
/// (a leading '+' skipped, as `>>` allows), widened. False if it rejects.
/// Without a floating-point std::from_chars (libc++ before 17), std::strtof
/// on the whole text is the reference (random_decimal makes no hex, inf or
/// nan, the forms where the two differ).
bool reference_number(const std::string &text, double &value) {
  const char *p = text.data(), *end = p + text.size();
  if (end - p >= 2 && p[0] == '+' && p[1] != '-') ++p;
  float f = 0;
#if defined(__cpp_lib_to_chars) && __cpp_lib_to_chars >= 201611L
  const std::from_chars_result r = std::from_chars(p, end, f);
  if (r.ec != std::errc() || r.ptr != end || !std::isfinite(f) || std::fabs(f) > 1e9f) return false;
#else
  if (p == end || *p == '+' || *p == ' ') return false;
  char *stop = nullptr;
  errno = 0;
  f = std::strtof(p, &stop);
  if (stop != end || (errno == ERANGE && f == 0) || !std::isfinite(f) || std::fabs(f) > 1e9f) return false;
#endif
  value = double(f);
  return true;
}

/// LineParser::number on `text` alone; false if it rejects.
bool parsed_number(const std::string &text, double &value) {
  const std::string line = text + '\0'; // the end byte LineParser needs
  LineParser in(line.data(), line.data() + text.size());
  std::string error;
  return in.number(value, "a coordinate", error) && in.at_end();
}

/// A random number in the forms scene files use and around them: signs,
/// up to 12 integer digits, up to 12 decimals, sometimes an exponent.
std::string random_decimal(std::mt19937_64 &rng) {
  std::string s;
  const unsigned sign = unsigned(rng() % 8);
  if (sign == 0) s += '-';
  if (sign == 1) s += '+';
  const int whole = int(rng() % 13), decimals = int(rng() % 13);
  for (int i = 0; i < whole; ++i) s += char('0' + rng() % 10);
  if (rng() % 4 != 0 || whole == 0) {
    s += '.';
    for (int i = 0; i < decimals; ++i) s += char('0' + rng() % 10);
  }
  if (rng() % 10 == 0) s += "e" + std::to_string(int(rng() % 21) - 10);
  return s;
}

/// The shape as a scene line, in the generator's format.
std::string scene_line(const Shape &s) {
  if (const Disk *d = s.disk()) return format_line(d->getCenter(), std::fabs(d->getRadius()), d->getColor());
  Point p[4];
  for (int k = 0; k < s.numPoints(); ++k) p[k] = s.getPoint(k);
  return format_line(p, s.numPoints(), s.getColor());
}

/// Reads `line` with the reader of one kind K; appends its one shape.
template <class K> bool read_as(const char *name, const std::string &line, std::vector<Shape> &out) {
  std::vector<K> one;
  std::string error;
  if (!parse_scene(name, line.data(), line.size(), one, error) || one.size() != 1) return false;
  out.push_back(one[0]);
  return true;
}

bool write_file(const std::string &path, const std::string &text) {
  std::FILE *f = std::fopen(path.c_str(), "wb");
  if (!f) return false;
  const bool ok = std::fwrite(text.data(), 1, text.size(), f) == text.size();
  return std::fclose(f) == 0 && ok;
}

} // namespace

TEST(number_reader_matches_from_chars) {
  const unsigned seed = base_seed();
  note(seed_note("number_reader", seed));
  std::mt19937_64 rng(seed);
  const long n = long(scaled(2000000));
  long accepted = 0, fast_forms = 0, mismatches = 0;
  for (long i = 0; i < n; ++i) {
    // Half the cases in the course's own form: 0-1000 with one decimal.
    const std::string text = i % 2 ? random_decimal(rng)
                                   : std::to_string(rng() % 1000) + "." + std::to_string(rng() % 10);
    double want = 0, got = 0;
    const bool ok_want = reference_number(text, want), ok_got = parsed_number(text, got);
    if (ok_want != ok_got || (ok_want && std::memcmp(&want, &got, sizeof want) != 0)) {
      if (++mismatches <= 5) note(seed_note("number_reader", seed) + " text '" + text + "'");
      CHECK(false);
    }
    accepted += ok_got;
    fast_forms += text.find('e') == std::string::npos;
  }
  std::cout << "  " << n << " numbers, " << accepted << " accepted, " << fast_forms << " without exponent"
            << std::endl;
  CHECK(accepted > n / 2 && accepted < n); // both answers are common
}

TEST(mixed_lines_read_as_their_own_kind) {
  // A .shapes line must give exactly what the one-kind reader gives for it.
  const unsigned seed = base_seed() + 1;
  note(seed_note("mixed_lines", seed));
  Maker make(seed, 0.1);
  std::string text;
  std::vector<Shape> expect;
  const int n = scaled(3000);
  for (int i = 0; i < n; ++i) {
    Shape s;
    make.make(s, 40);
    std::string line = scene_line(s);
    if (i % 7 == 3) line.insert(line.size() - 1, "\r"); // CRLF lines
    if (i % 11 == 5) text += "   \n";                   // blank lines
    text += line;
    // The one-kind reader of the line's own kind is the reference.
    CHECK(s.disk()       ? read_as<Disk>("one.disks", line, expect)
          : s.triangle() ? read_as<Triangle>("one.triangles", line, expect)
                         : read_as<Quad>("one.quads", line, expect));
  }
  std::vector<Shape> got;
  std::string error;
  CHECK(parse_scene("mixed.shapes", text.data(), text.size(), got, error));
  CHECK_EQ(error, std::string());
  CHECK_EQ(got.size(), expect.size());
  CHECK(got == expect);
  int kinds[3] = {};
  for (const Shape &s : got) ++kinds[int(s.kind())];
  for (int k : kinds) CHECK(k > n / 5);
  // The same lines read as a one-kind file fail at the first line of another kind.
  std::vector<Triangle> triangles;
  CHECK(!parse_scene("mixed.triangles", text.data(), text.size(), triangles, error));
  CHECK(error.find("mixed.triangles:") == 0);
}

TEST(mixed_line_errors_name_the_line_and_token) {
  struct Case {
    const char *text, *message;
  };
  const Case cases[] = {
      {"pt= <1 2> color= {1 2 3}\n", "x.shapes:1: expected 'radius=' or 'pt=', found 'color='"},
      {"\npt= <1 2> pt= <3 4> color= {1 2 3}\n", "x.shapes:2: expected 'pt=' (a triangle or quad has 3 or 4 points), found 'color='"},
      {"pt= <1 2> pt= <3 4> pt= <5 6> radius= 2 color= {1 2 3}\n", "x.shapes:1: expected 'pt=' or 'color=', found 'radius='"},
      {"pt= <1 2> pt= <3 4> pt= <5 6> pt= <7 8> pt= <9 9> color= {1 2 3}\n", "x.shapes:1: expected 'color=', found 'pt='"},
      {"pt= <1 2> radius= 3 pt= <3 4> color= {1 2 3}\n", "x.shapes:1: expected 'color=', found 'pt='"},
      {"pt= <1 2> radius= -1 color= {1 2 3}\n", "x.shapes:1: negative radius"},
      {"radius= 3 color= {1 2 3}\n", "x.shapes:1: expected 'pt=', found 'radius='"},
      {"pt= <1 2> pt= <3 4> pt= <5 6> color= {1 2 3} pt= <1 1>\n", "x.shapes:1: unexpected 'pt=' after the shape"},
  };
  for (const Case &c : cases) {
    std::vector<Shape> shapes;
    std::string error;
    const std::string text = c.text;
    CHECK(!parse_scene("x.shapes", text.data(), text.size(), shapes, error));
    if (error != c.message) note(std::string("got: ") + error);
    CHECK_EQ(error, std::string(c.message));
  }
}

TEST(chunked_file_reader_equals_whole_text) {
  // load_scene reads in chunks and carries unfinished lines over; every
  // chunk size must give what parsing the whole text at once gives.
  const unsigned seed = base_seed() + 2;
  note(seed_note("chunked_reader", seed));
  Maker make(seed, 0.1);
  std::string text = "\xef\xbb\xbf"; // a byte-order mark first
  for (int i = 0; i < scaled(400); ++i) {
    Shape s;
    make.make(s, 30);
    text += scene_line(s);
    if (i % 5 == 0) text += "\r\n";
  }
  text += "pt= <1 2> radius= 3 color= {1 2 3}"; // no final line end
  const char *tmp = std::getenv("TMPDIR");
  const std::string path = std::string(tmp && *tmp ? tmp : "/tmp") + "/bvh_test_parse_" + std::to_string(getpid()) +
                           ".shapes";
  CHECK(write_file(path, text));
  std::vector<Shape> whole;
  std::string error;
  CHECK(parse_scene(path, text.data() + 3, text.size() - 3, whole, error));
  for (std::size_t chunk : {std::size_t(1), std::size_t(2), std::size_t(3), std::size_t(7), std::size_t(64),
                            std::size_t(1000), std::size_t(4096), kReadChunk}) {
    std::vector<Shape> got;
    std::string e;
    CHECK(load_scene(path, got, e, chunk));
    if (got != whole) note("chunk size " + std::to_string(chunk));
    CHECK(got == whole);
  }
  // A bad line deep in the file is reported with its own line number.
  text.insert(text.find('\n', text.size() / 2) + 1, "pt= <1 2> radius= oops color= {1 2 3}\n");
  long line = 1;
  for (std::size_t i = 0, stop = text.find("oops"); i < stop; ++i) line += text[i] == '\n';
  CHECK(write_file(path, text));
  for (std::size_t chunk : {std::size_t(1), std::size_t(5), kReadChunk}) {
    std::vector<Shape> got;
    std::string e;
    CHECK(!load_scene(path, got, e, chunk));
    CHECK_EQ(e, path + ":" + std::to_string(line) + ": expected a radius, found 'oops'");
  }
  std::remove(path.c_str());
}

// max_non_overlapping (bvh.out --generate's refusal) is a sound bound: the
// densest regular packings that fit the canvas without touching, placed
// through the generator's own checks (format_line, parse, collision), never
// number more than it allows; and it is not vacuous (a real refusal).
TEST(packing_bound_admits_dense_packings) {
  const double pi = 3.14159265358979323846;
  // Scaled-down runs (valgrind, the sanitizers) try three of the radii: the
  // small ones place tens of thousands of shapes.
  const std::vector<double> radii = scale() >= 1 ? std::vector<double>{3.0, 10.0, 25.0, 50.0, 60.0, 120.0, 250.0, 400.0}
                                                 : std::vector<double>{10.0, 60.0, 400.0};
  for (double r : radii) {
    // Disks of radius r, hexagonal rows 2r + 0.3 apart (apart after rounding).
    CourseBVH<Disk> disks(8, CourseBVH<Disk>::unlimited); // the generator's tree (generate.h)
    const double step = 2 * r + 0.3, row = step * std::sqrt(3.0) / 2;
    long n = 0;
    int k = 0;
    for (double y = r + 0.1; y <= 1000 - r - 0.1; y += row, ++k)
      for (double x = r + 0.1 + (k % 2 ? step / 2 : 0); x <= 1000 - r - 0.1; x += step)
        n += place(format_line(Point(round_to(x, 0.1), round_to(y, 0.1)), r, Color(1, 2, 3)), true, disks);
    CHECK(n == long(disks.size()));
    if (double(n) > max_non_overlapping("disks", r)) note("disks r=" + std::to_string(r) + ": " + std::to_string(n));
    CHECK(double(n) <= max_non_overlapping("disks", r));
    // Quads: axis-aligned squares of circumradius r (side r sqrt 2) on a grid.
    CourseBVH<Quad> quads(8, CourseBVH<Quad>::unlimited);
    const double half = r / std::sqrt(2.0), qstep = 2 * half + 0.3;
    long q = 0;
    for (double y = r; y <= 1000 - r; y += qstep)
      for (double x = r; x <= 1000 - r; x += qstep) {
        Point pts[4];
        for (int i = 0; i < 4; ++i) {
          const double angle = pi / 4 + pi / 2 * i;
          pts[i] = Point(round_to(x + r * std::cos(angle), 0.1), round_to(y + r * std::sin(angle), 0.1));
        }
        q += place(format_line(pts, 4, Color(1, 2, 3)), true, quads);
      }
    CHECK(double(q) <= max_non_overlapping("quads", r));
  }
  // The request: a million disks of radius 50-60 is refused (at most 113).
  CHECK(max_non_overlapping("disks", 50) < 1000000);
  CHECK(max_non_overlapping("disks", 50) >= 81); // a 9 x 9 grid of them fits
  // Tiny sizes: no bound.
  CHECK(max_non_overlapping("triangles", 0.05) > 1e17);
}

int main(int argc, char **argv) {
  std::cout << "seed " << base_seed() << " (set BVH_SEED to change), scale " << scale() << std::endl;
  return run_all_tests(argc, argv);
}
