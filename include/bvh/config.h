// bvh/config.h — the assertions and the platform switches.
//
// BVH_ASSERT (the caller's misuse) and BVH_INVARIANT (our own bugs), the
// inlining hints, and the platform's features: SSE2 (emmintrin.h unless
// BVH_NO_SIMD), huge pages and mapped arrays (Linux). The bottom room: it
// includes nothing of the library's.
#ifndef BVH_CONFIG_H
#define BVH_CONFIG_H

#include <cstdio>
#include <cstdlib>


#if defined(__SSE2__) && !defined(BVH_NO_SIMD)
#include <emmintrin.h>
#endif
// A build's large scratch arrays in transparent huge pages (BuildAllocator),
// and the tree's new blocks faulted in by one call each (populate): Linux
// only (not Android, whose aligned_alloc depends on the API level).
#if defined(__linux__) && !defined(__ANDROID__) && !defined(BVH_NO_HUGE_PAGES)
#define BVH_HUGE_PAGES 1
#include <sys/mman.h>
#else
#define BVH_HUGE_PAGES 0
#endif
// The leaf pool's large bookkeeping arrays mapped on their own
// (MappedAllocator): Linux, whose glibc keeps a freed large array's pages;
// BVH_NO_MAPPED_ARRAYS turns it off.
#if defined(__linux__) && !defined(BVH_NO_MAPPED_ARRAYS)
#define BVH_MAPPED_ARRAYS 1
#include <sys/mman.h>
#else
#define BVH_MAPPED_ARRAYS 0
#endif


// BVH_ASSERT(condition, message): checks of the caller's preconditions
// (iterators past the ends, erasing end() or another tree's iterator). On
// unless NDEBUG is defined; then a failed check prints the message and
// aborts. Define BVH_ASSERT before including bvh.h to handle misuse your own
// way (throw, log), or as ((void)0) to drop the checks.
#ifndef BVH_ASSERT
#ifdef NDEBUG
#define BVH_ASSERT(condition, message) ((void)0)
#else
#define BVH_ASSERT(condition, message)                                                                                \
  ((condition) ? (void)0 : ::bvh::detail::assertion_failed(message, #condition, __FILE__, __LINE__))
#endif
#endif

// BVH_INVARIANT(condition, message): the tree's own invariants, checked
// where one component hands over to another. A failure is a bug in bvh.h,
// never the caller's: it aborts with the message. Off under NDEBUG.
#ifdef NDEBUG
#define BVH_INVARIANT(condition, message) ((void)0)
#else
#define BVH_INVARIANT(condition, message)                                                                             \
  ((condition) ? (void)0 : ::bvh::detail::invariant_failed(message, #condition, __FILE__, __LINE__))
#endif

// The one traversal routine is inlined into each query that uses it, so
// that its visit's state (a query's probe) stays in registers.
// BVH_NOINLINE keeps a small function out of the queries that call it
// once each, where inlining it only crowds their loops' registers.
// Unoptimized builds (-O0: debugging, sanitizers) inline nothing: there
// forced inlining buys no speed and copies each instrumented body into
// every caller, which makes such builds compile far longer.
#if defined(__GNUC__) && defined(__OPTIMIZE__)
#define BVH_ALWAYS_INLINE inline __attribute__((always_inline))
#define BVH_LAMBDA_INLINE __attribute__((always_inline))
#else
#define BVH_ALWAYS_INLINE inline
#define BVH_LAMBDA_INLINE
#endif
#if defined(__GNUC__)
#define BVH_NOINLINE __attribute__((noinline))
#else
#define BVH_NOINLINE
#endif


namespace bvh {
namespace detail {

/// BVH_ASSERT's report: what was misused, where, then abort().
[[noreturn]] inline void assertion_failed(const char *message, const char *condition, const char *file, int line) {
  std::fprintf(stderr, "%s:%d: BVH misuse: %s (%s)\n", file, line, message, condition);
  std::abort();
}

/// BVH_INVARIANT's report, then abort().
[[noreturn]] inline void invariant_failed(const char *message, const char *condition, const char *file, int line) {
  std::fprintf(stderr, "%s:%d: BVH internal error: %s (%s)\n", file, line, message, condition);
  std::abort();
}
} // namespace detail
} // namespace bvh

#endif // BVH_CONFIG_H
