// bvh/simd.h — the query probe and the bit helpers of the node test.
//
// Probe (a query box rounded outwards to float, as the node test reads it),
// two_floats, lowest_bit and prefetch_lines. The SSE2 paths and their
// scalar fallbacks (BVH_NO_SIMD) keep the same data layout. Includes box.h.
#ifndef BVH_SIMD_H
#define BVH_SIMD_H

#include <cstddef>
#include <cstdint>

#include "box.h"

namespace bvh {
namespace detail {

/// Four copies of one float, 16-byte aligned: a probe's bound as the SSE2
/// node test loads it (get()) and the scalar one reads it (f[0]). One
/// layout, whichever test a build compiles (BVH_NO_SIMD).
struct alignas(16) Float4 {
  float f[4];
  static Float4 of(float v) { return Float4{{v, v, v, v}}; }
#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
  __m128 get() const { return _mm_load_ps(f); }
#endif
};

/// A query box rounded outwards to float, and its centre, as child_masks
/// reads them.
struct Probe {
  /// The probe of `box` (once per query: out of line, see BVH_NOINLINE).
  static BVH_NOINLINE Probe around(const Box &box) { return inline_around(box); }
  /// around(), inlined: for a caller that keeps the probe in memory
  /// anyway (collides_each's lanes), where the call costs more than it saves.
  static BVH_ALWAYS_INLINE Probe inline_around(const Box &box) {
    float f[4];
    round_out(box, f);
    return Probe(f[0], f[1], f[2], f[3], 0.5f * (f[0] + f[2]), 0.5f * (f[1] + f[3]));
  }
  // Broadcast to 4 lanes once per query, not once per node.
  Probe(float lx, float ly, float hx, float hy, float mx, float my)
      : lo_x(Float4::of(lx)), lo_y(Float4::of(ly)), hi_x(Float4::of(hx)), hi_y(Float4::of(hy)),
        mid_x(Float4::of(mx)), mid_y(Float4::of(my)) {}
  Float4 lo_x, lo_y, hi_x, hi_y, mid_x, mid_y;
};

#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
/// f[0] and f[1] widened to two doubles: a node's row read two children
/// at a time (choose_child, the nearest searches' bounds).
inline __m128d two_floats(const float *f) {
  return _mm_cvtps_pd(_mm_castsi128_ps(_mm_loadl_epi64(reinterpret_cast<const __m128i *>(f))));
}
#endif

/// The index of the lowest set bit of `bits` (not 0).
inline int lowest_bit(std::uint32_t bits) {
#if defined(__GNUC__)
  return __builtin_ctz(bits);
#else
  int i = 0;
  while (!(bits >> i & 1u)) ++i;
  return i;
#endif
}

/// Asks the cache for the `bytes` bytes at `p`, which a step soon reads:
/// a hint, without effect on what the program computes (none without GCC
/// or clang).
BVH_ALWAYS_INLINE void prefetch_lines(const void *p, std::size_t bytes) {
#if defined(__GNUC__)
  const char *c = static_cast<const char *>(p);
  for (std::size_t o = 0; o < bytes; o += 64) __builtin_prefetch(c + o);
  __builtin_prefetch(c + bytes - 1);
#else
  (void)p;
  (void)bytes;
#endif
}
} // namespace detail
} // namespace bvh

#endif // BVH_SIMD_H
