// bvh/box.h — Box, rounding to float, and the supported range of numbers.
//
// Box (double, closed), round_out (float boxes that contain their double
// box), XY, box_of (a shape's box through its traits), and the check that
// every number a tree stores lies in [2^-200, 2^200] (require_supported,
// which throws std::invalid_argument). Includes config.h and traits.h.
#ifndef BVH_BOX_H
#define BVH_BOX_H

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "config.h"
#include "traits.h"

namespace bvh {
namespace detail {

/// The float next to `f` towards -infinity (towards +infinity when `up`),
/// by stepping its bit pattern: std::nextafter is a library call, and this
/// sits on every insert and query.
inline float float_step(float f, bool up) {
  std::uint32_t bits;
  std::memcpy(&bits, &f, sizeof bits);
  if (f == 0) {
    bits = up ? 0x00000001u : 0x80000001u; // the smallest subnormal
  } else if ((f > 0) == up) {
    ++bits;
  } else {
    --bits;
  }
  std::memcpy(&f, &bits, sizeof f);
  return f;
}
/// The largest float <= d: boxes rounded outwards stay conservative.
inline float float_down(double d) {
  const float f = static_cast<float>(d);
  return static_cast<double>(f) > d ? float_step(f, false) : f;
}
/// The smallest float >= d.
inline float float_up(double d) {
  const float f = static_cast<float>(d);
  return static_cast<double>(f) < d ? float_step(f, true) : f;
}

/// An axis-aligned box in double: the tree's own box arithmetic (union,
/// containment, overlap, area), so that a shape's box need offer only
/// getMin() and getMax(), as the course's BoundingBox does (it has no empty
/// box, no union operator, no containment and no comparison). The default
/// box is empty: it contains nothing, and extending it gives the other box.
struct Box {
  double x0 = std::numeric_limits<double>::infinity(), y0 = std::numeric_limits<double>::infinity();
  double x1 = -std::numeric_limits<double>::infinity(), y1 = -std::numeric_limits<double>::infinity();

  /// The box of `b`.
  static Box of(const bounds &b) { return Box{b.min_x, b.min_y, b.max_x, b.max_y}; }
  /// The box of `b`, any type box_traits understands.
  template <class B> static Box from(const B &b) { return of(box_traits<B>::get(b)); }
  /// The box of one point (anything with x and y).
  template <class P> static Box at(const P &p) { return Box{p.x, p.y, p.x, p.y}; }

  /// True for the box that contains nothing.
  bool empty() const { return x0 > x1 || y0 > y1; }
  /// Width (0 when empty).
  double dx() const { return empty() ? 0 : x1 - x0; }
  /// Height (0 when empty).
  double dy() const { return empty() ? 0 : y1 - y0; }
  /// Area (0 when empty).
  double area() const { return dx() * dy(); }
  /// True when the boxes share a point: touching counts.
  bool overlaps(const Box &o) const { return x0 <= o.x1 && o.x0 <= x1 && y0 <= o.y1 && o.y0 <= y1; }
  /// True when `o` lies inside this box, boundaries included.
  bool contains(const Box &o) const { return x0 <= o.x0 && y0 <= o.y0 && o.x1 <= x1 && o.y1 <= y1; }
  /// This box with every side pushed out by m >= 0 (an empty box stays empty).
  Box grown(double m) const { return empty() ? *this : Box{x0 - m, y0 - m, x1 + m, y1 + m}; }
  /// Grows to include `o` (an empty `o` changes nothing).
  void extend(const Box &o) {
    x0 = std::min(x0, o.x0);
    y0 = std::min(y0, o.y0);
    x1 = std::max(x1, o.x1);
    y1 = std::max(y1, o.y1);
  }
  /// Where the ray (ox, oy) + t (dx, dy), t >= 0, enters the box: 0 when it
  /// starts inside, +inf when it misses (slab test).
  double ray_entry(double ox, double oy, double dx, double dy) const {
    const double inf = std::numeric_limits<double>::infinity();
    double t0 = 0, t1 = inf;
    const double o[2] = {ox, oy}, d[2] = {dx, dy}, lo[2] = {x0, y0}, hi[2] = {x1, y1};
    for (int k = 0; k < 2; ++k) {
      if (d[k] == 0) {
        if (o[k] < lo[k] || o[k] > hi[k]) return inf;
        continue;
      }
      double a = (lo[k] - o[k]) / d[k], b = (hi[k] - o[k]) / d[k];
      if (a > b) std::swap(a, b);
      t0 = std::max(t0, a);
      t1 = std::min(t1, b);
      if (t0 > t1) return inf;
    }
    return t0;
  }
  friend bool operator==(const Box &a, const Box &b) {
    return a.x0 == b.x0 && a.y0 == b.y0 && a.x1 == b.x1 && a.y1 == b.y1;
  }
  friend bool operator!=(const Box &a, const Box &b) { return !(a == b); }
};

/// {float_down(b.x0), float_down(b.y0), float_up(b.x1), float_up(b.y1)}
/// into out: `b` rounded outwards to float.
/// With SSE2 the four at once and without branches: every box a node
/// stores and every query's box is rounded, and the scalar steps' branches
/// go either way at random.
BVH_ALWAYS_INLINE void round_out(const Box &b, float out[4]) {
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  const __m128d lo = _mm_set_pd(b.y0, b.x0), hi = _mm_set_pd(b.y1, b.x1);
  const __m128 f = _mm_movelh_ps(_mm_cvtpd_ps(lo), _mm_cvtpd_ps(hi));
  // Lanes whose conversion went the wrong way (NaN never does).
  const __m128d wrong_lo = _mm_cmpgt_pd(_mm_cvtps_pd(f), lo);
  const __m128d wrong_hi = _mm_cmplt_pd(_mm_cvtps_pd(_mm_movehl_ps(f, f)), hi);
  const __m128i wrong = _mm_castps_si128(
      _mm_shuffle_ps(_mm_castpd_ps(wrong_lo), _mm_castpd_ps(wrong_hi), _MM_SHUFFLE(2, 0, 2, 0)));
  // float_step on the bit patterns: +1 (away from zero) when the float's
  // sign is the direction's, -1 otherwise; from +-0 to the smallest
  // subnormal of the direction's sign.
  const __m128i bits = _mm_castps_si128(f), down = _mm_set_epi32(0, 0, -1, -1);
  const __m128i one = _mm_set1_epi32(1);
  const __m128i stepped = _mm_add_epi32(bits, _mm_or_si128(_mm_xor_si128(_mm_srai_epi32(bits, 31), down), one));
  const __m128i zero = _mm_castps_si128(_mm_cmpeq_ps(f, _mm_setzero_ps()));
  const __m128i smallest = _mm_or_si128(_mm_slli_epi32(down, 31), one);
  const __m128i step = _mm_or_si128(_mm_and_si128(zero, smallest), _mm_andnot_si128(zero, stepped));
  _mm_storeu_ps(out, _mm_castsi128_ps(_mm_or_si128(_mm_and_si128(wrong, step), _mm_andnot_si128(wrong, bits))));
#else
  out[0] = float_down(b.x0);
  out[1] = float_down(b.y0);
  out[2] = float_up(b.x1);
  out[3] = float_up(b.y1);
#endif
}

/// A point in double, from anything with x and y.
struct XY {
  double x, y;
  template <class P> static XY of(const P &p) { return XY{p.x, p.y}; }
};

/// The box of a stored shape, as `traits` (its shape_traits) reads it.
template <class Tr, class T> BVH_ALWAYS_INLINE Box box_of(const Tr &traits, const T &shape) {
  const auto &b = traits.box(shape);
  return Box::from(b);
}

// ---- Supported values (docs/library.txt, SUPPORTED VALUES) ----------------
// intersect.h is exact, and distance.h and the nearest searches' squared
// distances stay finite, for numbers that are 0 or of magnitude in
// [2^-200, 2^200]. The tree stores only such numbers (construct, insert,
// update and insert_disjoint refuse others) and a query outside them finds
// nothing, so that no answer is silently wrong.

/// The least and the greatest supported magnitude besides 0.
constexpr double kLeastSupported = 0x1p-200, kMostSupported = 0x1p200;

/// 1 unless v is 0 or of magnitude in [2^-200, 2^200] (NaN and the
/// infinities give 1), without a branch. (A double's bits without the
/// sign order as its magnitude does, NaNs above the infinities.)
BVH_ALWAYS_INLINE unsigned unsupported_bit(double v) {
  std::uint64_t u;
  std::memcpy(&u, &v, sizeof u);
  u <<= 1; // the sign dropped
  constexpr std::uint64_t least = std::uint64_t(1023 - 200) << 53, most = std::uint64_t(1023 + 200) << 53;
  return unsigned(u - least > most - least) & unsigned(u != 0);
}

/// Whether any of the numbers it is given is unsupported (or a radius
/// negative, or a box's min above its max): every number of a shape is
/// checked, without a branch, and the answer read once. Two at a time with
/// SSE2.
class UnsupportedAny {
public:
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  BVH_ALWAYS_INLINE void pair(double a, double b) { bad_ = _mm_or_pd(bad_, lanes(_mm_set_pd(b, a))); }
  BVH_ALWAYS_INLINE void radius(double r) {
    const __m128d v = _mm_set1_pd(r);
    bad_ = _mm_or_pd(bad_, _mm_or_pd(lanes(v), _mm_cmplt_pd(v, _mm_setzero_pd())));
  }
  BVH_ALWAYS_INLINE void box(const Box &b) {
    const __m128d lo = _mm_set_pd(b.y0, b.x0), hi = _mm_set_pd(b.y1, b.x1);
    bad_ = _mm_or_pd(bad_, _mm_or_pd(_mm_or_pd(lanes(lo), lanes(hi)), _mm_cmpnle_pd(lo, hi)));
  }
  BVH_ALWAYS_INLINE bool any() const { return _mm_movemask_pd(bad_) != 0; }

private:
  /// All ones in each lane of v that is unsupported (NaN included: the
  /// "not less or equal" compare is true for it).
  static BVH_ALWAYS_INLINE __m128d lanes(__m128d v) {
    const __m128d a = _mm_andnot_pd(_mm_set1_pd(-0.0), v);
    const __m128d big = _mm_cmpnle_pd(a, _mm_set1_pd(kMostSupported));
    const __m128d tiny = _mm_and_pd(_mm_cmplt_pd(a, _mm_set1_pd(kLeastSupported)), _mm_cmpneq_pd(a, _mm_setzero_pd()));
    return _mm_or_pd(big, tiny);
  }
  __m128d bad_ = _mm_setzero_pd();
#else
  BVH_ALWAYS_INLINE void pair(double a, double b) { bad_ |= unsupported_bit(a) | unsupported_bit(b); }
  BVH_ALWAYS_INLINE void radius(double r) { bad_ |= unsupported_bit(r) | unsigned(!(r >= 0)); }
  BVH_ALWAYS_INLINE void box(const Box &b) {
    bad_ |= unsupported_bit(b.x0) | unsupported_bit(b.y0) | unsupported_bit(b.x1) | unsupported_bit(b.y1) |
            unsigned(!(b.x0 <= b.x1)) | unsigned(!(b.y0 <= b.y1));
  }
  BVH_ALWAYS_INLINE bool any() const { return bad_ != 0; }

private:
  unsigned bad_ = 0;
#endif
};

/// Every side supported, and min <= max on both axes.
BVH_ALWAYS_INLINE bool supported(const Box &b) {
  UnsupportedAny bad;
  bad.box(b);
  return !bad.any();
}
/// A side of `b` is NaN.
inline bool has_nan(const Box &b) { return std::isnan(b.x0) || std::isnan(b.y0) || std::isnan(b.x1) || std::isnan(b.y1); }

// What a shape type shows of its own numbers: points (numPoints() and
// getPoint(i), as the course's polygons and this project's shapes), a
// centre (getCenter()), a radius (getRadius(), or disk()->getRadius() for
// a mixed Shape holding a disk).
template <class S, class = void> struct ShowsPoints : std::false_type {};
template <class S>
struct ShowsPoints<S, std::void_t<decltype(int(std::declval<const S &>().numPoints()) +
                                           double(std::declval<const S &>().getPoint(0).x))>> : std::true_type {};
template <class S, class = void> struct ShowsCenter : std::false_type {};
template <class S>
struct ShowsCenter<S, std::void_t<decltype(double(std::declval<const S &>().getCenter().x))>> : std::true_type {};
template <class S, class = void> struct ShowsRadius : std::false_type {};
template <class S>
struct ShowsRadius<S, std::void_t<decltype(double(std::declval<const S &>().getRadius()))>> : std::true_type {};
template <class S, class = void> struct HoldsDisk : std::false_type {};
template <class S>
struct HoldsDisk<S, std::void_t<decltype(double(std::declval<const S &>().disk()->getRadius()))>> : std::true_type {};

/// Adds the numbers a shape shows besides its box (above) to `bad`: a
/// type that shows none (an id an adaptor reads) is judged by its box
/// alone.
template <class S> BVH_ALWAYS_INLINE void add_numbers(UnsupportedAny &bad, const S &s) {
  if constexpr (ShowsPoints<S>::value) {
    for (int i = 0, n = int(s.numPoints()); i < n; ++i) {
      const auto &p = s.getPoint(i);
      bad.pair(double(p.x), double(p.y));
    }
  } else if constexpr (ShowsRadius<S>::value && ShowsCenter<S>::value) {
    bad.pair(double(s.getCenter().x), double(s.getCenter().y));
  }
  if constexpr (ShowsRadius<S>::value) {
    bad.radius(double(s.getRadius()));
  } else if constexpr (HoldsDisk<S>::value) {
    if (const auto *d = s.disk()) bad.radius(double(d->getRadius()));
  }
}

/// The tree may store `shape`, and answers a query by it: its box as the
/// traits read it and its own numbers are supported.
template <class Tr, class T> BVH_ALWAYS_INLINE bool supported_shape(const Tr &traits, const T &shape) {
  UnsupportedAny bad;
  bad.box(box_of(traits, shape));
  add_numbers(bad, shape);
  return !bad.any();
}

/// Throws std::invalid_argument for the shape `which` (e.g.
/// "elements[37]") of `call`, naming its box. (Out of line: the message is
/// built only on the error.)
[[noreturn]]
#if defined(__GNUC__)
__attribute__((noinline, cold))
#endif
inline void refuse_unsupported(const char *call, const std::string &which, const Box &b) {
  char box[160];
  std::snprintf(box, sizeof box, "[<%.17g %.17g> <%.17g %.17g>]", b.x0, b.y0, b.x1, b.y1);
  throw std::invalid_argument(std::string("bvh::BVH::") + call + ": " + which + " (box " + box +
                              ") has a coordinate, radius or box side outside the supported range: each must "
                              "be 0 or of magnitude in [2^-200, 2^200], and a radius not negative");
}

/// refuse_unsupported() unless supported_shape(traits, shape).
template <class Tr, class T> void require_supported(const Tr &traits, const T &shape, const char *call) {
  if (!supported_shape(traits, shape)) refuse_unsupported(call, "the shape", box_of(traits, shape));
}

/// refuse_unsupported() for the first of `shapes` that is not supported,
/// named `what`[i].
template <class Tr, class T>
void require_supported(const Tr &traits, const std::vector<T> &shapes, const char *call, const char *what) {
  for (std::size_t i = 0; i < shapes.size(); ++i)
    if (!supported_shape(traits, shapes[i]))
      refuse_unsupported(call, std::string(what) + "[" + std::to_string(i) + "]", box_of(traits, shapes[i]));
}

/// Appends `[<x0 y0> <x1 y1>]` with every number as %5.1f: the course's
/// listing of a box, written here so that neither the stream's flags nor
/// the shape library's printing can change it.
inline void append_box(std::string &out, const Box &b) {
  char buf[1400]; // four %5.1f doubles of any magnitude fit
  std::snprintf(buf, sizeof buf, "[<%5.1f %5.1f> <%5.1f %5.1f>]", b.x0, b.y0, b.x1, b.y1);
  out += buf;
}
} // namespace detail
} // namespace bvh

#endif // BVH_BOX_H
