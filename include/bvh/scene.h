// scene.h — the scene files of bvh.out (CSCI-1200 Homework 8): the reader of
// .disks, .triangles, .quads and mixed .shapes files, which reads numbers as
// the course's loader does, and Random, a generator whose numbers are the
// same on every compiler. Header-only, C++17, in namespace bvh_scene; uses
// shapes.h only (the scene generator behind `bvh.out --generate`, which
// places shapes with a tree, is generate.h).
//
//   std::vector<Disk> disks;
//   std::string error;
//   if (!bvh_scene::load_scene("1000.disks", disks, error))
//     std::cerr << error << "\n"; // e.g. "1000.disks:3: negative radius"
//
// Errors name the file and the 1-based line; the reader stops at the first.
#ifndef BVH_SCENE_H
#define BVH_SCENE_H

#include <algorithm>
#include <cerrno>
#include <cfloat>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "shapes.h"

namespace bvh_scene {

using namespace bvh; // (the shapes)

// Reading scenes. The course's loader reads every number into a float and
// widens it to double; the printed boxes depend on that, so we do the same.

inline constexpr std::size_t kMaxLineLength = 4096;
inline constexpr float kMaxCoordinate = 1e9f;

// 10^k for k = 0..10. Each is an exact float (5^10 < 2^24), which is what
// makes LineParser::decimal correctly rounded.
inline constexpr float kPowersOfTen[] = {1e0f, 1e1f, 1e2f, 1e3f, 1e4f, 1e5f, 1e6f, 1e7f, 1e8f, 1e9f, 1e10f};

// decimal() relies on one float division being rounded once, in float.
// intersect.h asserts the same for doubles; this states it for this header.
static_assert(std::numeric_limits<float>::is_iec559 && FLT_EVAL_METHOD == 0,
              "the scene reader needs IEEE floats evaluated without extended precision");

// Marks the error paths, so that the readers' hot paths stay small enough
// to be inlined into one loop per shape kind.
#if defined(__GNUC__)
#define BVH_SCENE_COLD __attribute__((noinline, cold))
#else
#define BVH_SCENE_COLD
#endif

/// std::from_chars into a float (chars_format::general) where the standard
/// library has it; otherwise (libc++ before 17, as on macOS) the same forms
/// are scanned here and converted by std::strtof, which is also correctly
/// rounded (bvh.out never changes the "C" locale; a program that does must
/// keep '.' as its decimal point). Same results, same errors: an overflow,
/// or an underflow to 0, is result_out_of_range; subnormals are accepted.
inline std::from_chars_result float_from_chars(const char *first, const char *last, float &value) {
#if defined(__cpp_lib_to_chars) && __cpp_lib_to_chars >= 201611L
  return std::from_chars(first, last, value);
#else
  const auto digit = [](char c) { return unsigned(c - '0') < 10; };
  const char *p = first;
  if (p < last && *p == '-') ++p;
  // The rest of `word` (lower case) at p, in any case: its end, or nullptr.
  const auto word = [&](const char *w) -> const char * {
    const char *q = p;
    for (; *w; ++w, ++q)
      if (q == last || (*q | 0x20) != *w) return nullptr;
    return q;
  };
  if (const char *q = word("inf")) {
    p = q;
    if (const char *r = word("inity")) p = r;
  } else if (const char *n = word("nan")) {
    p = n;
    if (p < last && *p == '(') {
      const char *r = p + 1;
      while (r < last && (digit(*r) || ((*r | 0x20) >= 'a' && (*r | 0x20) <= 'z') || *r == '_')) ++r;
      if (r < last && *r == ')') p = r + 1;
    }
  } else {
    const char *start = p;
    while (p < last && digit(*p)) ++p;
    bool any = p > start;
    if (p < last && *p == '.') {
      const char *fraction = ++p;
      while (p < last && digit(*p)) ++p;
      any = any || p > fraction;
    }
    if (!any) return {first, std::errc::invalid_argument};
    if (p < last && (*p == 'e' || *p == 'E')) {
      const char *e = p + 1;
      if (e < last && (*e == '+' || *e == '-')) ++e;
      const char *exponent = e;
      while (e < last && digit(*e)) ++e;
      if (e > exponent) p = e;
    }
  }
  const std::string text(first, p);
  char *stop = nullptr;
  errno = 0;
  const float f = std::strtof(text.c_str(), &stop);
  if (text.empty() || stop != text.c_str() + text.size()) return {first, std::errc::invalid_argument};
  if (errno == ERANGE && (std::isinf(f) || f == 0)) return {p, std::errc::result_out_of_range};
  value = f;
  return {p, std::errc()};
#endif
}

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
  BVH_SCENE_COLD bool expected_here(const char *what, std::string &error) const {
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

  BVH_SCENE_COLD bool fail(const char *message, std::string &error) const {
    error = message + describe_here();
    return false;
  }
  BVH_SCENE_COLD bool expected(const char *word, std::string &error) const {
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
  BVH_SCENE_COLD bool general_number(float &f, const char *what, std::string &error) {
    const char *q = p_;
    // from_chars refuses a leading '+', which `>>` accepts ("+-3" stays an error).
    if (end_ - q >= 2 && q[0] == '+' && q[1] != '-') ++q;
    const std::from_chars_result r = float_from_chars(q, end_, f);
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
inline bool parse_disk_rest(LineParser &in, const Point &c, Disk &d, std::string &error) {
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
inline bool parse_shape(LineParser &in, Disk &d, std::string &error) {
  Point c;
  return in.point(c, error) && parse_disk_rest(in, c, d, error);
}

/// Reads one triangle line's fields.
inline bool parse_shape(LineParser &in, Triangle &t, std::string &error) {
  Point a, b, c;
  Color color;
  if (!in.point(a, error) || !in.point(b, error) || !in.point(c, error) || !in.color(color, error)) return false;
  t = Triangle(a, b, c, color);
  return true;
}

/// Reads one quad line's fields.
inline bool parse_shape(LineParser &in, Quad &q, std::string &error) {
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
inline bool parse_shape(LineParser &in, Shape &s, std::string &error) {
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
inline std::size_t bom_length(const char *p, const char *end) {
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

inline constexpr std::size_t kReadChunk = std::size_t(1) << 20;

/// load_scene's default progress report: none.
struct NoProgress {
  void operator()(std::uint64_t /*bytes_read*/) const {}
};

/// Reads the scene from `file`, already open for reading, to its end and
/// appends its shapes to `out`; false with `error` ("PATH: cannot read:
/// ...", or parse_scene's message, `path` naming the file) otherwise. The
/// file is read `chunk` bytes at a time (tests vary it) and each chunk's
/// complete lines parsed at once, so memory stays small and a broken file
/// (even an endless one) fails at its first bad line. `progress(bytes)` is
/// called after each chunk with the bytes read so far (bvh.out's progress
/// line). The caller closes `file`. (bvh.out opens its input once and reads
/// it from here: a FIFO or a device cannot be opened twice for one stream.)
template <class T, class Progress = NoProgress>
bool load_scene(std::FILE *file, const std::string &path, std::vector<T> &out, std::string &error,
                std::size_t chunk = kReadChunk, Progress progress = Progress());

/// Opens the scene file `path` and reads it as above; false with `error`
/// ("PATH: cannot open: ...", or the reading's message) otherwise.
template <class T, class Progress = NoProgress>
bool load_scene(const std::string &path, std::vector<T> &out, std::string &error, std::size_t chunk = kReadChunk,
                Progress progress = Progress()) {
  std::unique_ptr<std::FILE, int (*)(std::FILE *)> file(std::fopen(path.c_str(), "rb"), &std::fclose);
  if (!file) {
    error = path + ": cannot open: " + std::strerror(errno);
    return false;
  }
  return load_scene(file.get(), path, out, error, chunk, progress);
}

template <class T, class Progress>
bool load_scene(std::FILE *file, const std::string &path, std::vector<T> &out, std::string &error,
                std::size_t chunk, Progress progress) {
  if (chunk < 1) chunk = 1;
  // An unfinished line waits at the front of the buffer for the rest of it;
  // one longer than this (a line and its '\r') is an error already.
  const std::size_t carry_max = kMaxLineLength + 1;
  std::unique_ptr<char[]> buffer(new char[carry_max + chunk]);
  char *const buf = buffer.get();
  std::size_t have = 0;
  long line = 1;
  bool at_start = true;
  std::uint64_t total = 0;
  for (;;) {
    const std::size_t got = std::fread(buf + have, 1, chunk, file);
    if (got < chunk && std::ferror(file)) {
      error = path + ": cannot read: " + std::strerror(errno);
      return false;
    }
    const bool eof = got < chunk;
    have += got;
    total += got;
    progress(total);
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

} // namespace bvh_scene

#undef BVH_SCENE_COLD

#endif // BVH_SCENE_H
