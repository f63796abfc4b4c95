// bench/peers.h — what bench.cpp and moving.cpp share: the peers, each
// compiled in only when it is installed (Boost.Geometry's headers; Box2D's
// library, which the Makefile detects and announces with
// -DBENCH_HAVE_BOX2D_LIB), the callgrind markers of the timed region, and
// the build note the Makefile passes. -DBENCH_NO_BOOST / -DBENCH_NO_BOX2D
// leave a peer out even when it is installed (to try the skip notices).
#ifndef BVH_BENCH_PEERS_H
#define BVH_BENCH_PEERS_H

#if !defined(BENCH_NO_BOOST) && __has_include(<boost/geometry/index/rtree.hpp>)
#define BENCH_HAVE_BOOST 1
#define BOOST_ALLOW_DEPRECATED_HEADERS // Boost 1.74's own includes, not ours
#include <boost/geometry.hpp>
#include <boost/geometry/index/rtree.hpp>
#include <boost/iterator/function_output_iterator.hpp>
#include <bvh/shapes.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
#include <cstdint>
#include <utility>
// The peers' value type: a box and the shape's index.
namespace bg = boost::geometry;
namespace bgi = boost::geometry::index;
using BPoint = bg::model::point<double, 2, bg::cs::cartesian>;
using BBox = bg::model::box<BPoint>;
using BValue = std::pair<BBox, std::uint32_t>;
inline BBox to_boost(const BoundingBox &b) {
  return BBox(BPoint(b.getMin().x, b.getMin().y), BPoint(b.getMax().x, b.getMax().y));
}
#else
#define BENCH_HAVE_BOOST 0
#endif

#if defined(BENCH_HAVE_BOX2D_LIB) && !defined(BENCH_NO_BOX2D) && __has_include(<box2d/b2_dynamic_tree.h>)
#define BENCH_HAVE_BOX2D 1
#include <box2d/b2_dynamic_tree.h>
#else
#define BENCH_HAVE_BOX2D 0
#endif

#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#define BENCH_CG_START() CALLGRIND_START_INSTRUMENTATION
#define BENCH_CG_STOP() CALLGRIND_STOP_INSTRUMENTATION
#else
#define BENCH_CG_START() ((void)0)
#define BENCH_CG_STOP() ((void)0)
#endif

#ifndef BENCH_BUILD_INFO
#define BENCH_BUILD_INFO "bvh.h of unknown version (built without the Makefile)"
#endif

#endif // BVH_BENCH_PEERS_H
