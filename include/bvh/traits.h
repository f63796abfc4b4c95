// bvh/traits.h — how the tree reads your types: bounds, box_traits, shape_traits.
//
// The public customization points, and the detail that reads them
// (InscribedDisks, kExactDisk). Includes config.h and distance.h (the
// library's shapes and predicates; intersect.h says whether Disk is exact).
#ifndef BVH_TRAITS_H
#define BVH_TRAITS_H

#include <type_traits>

#include "config.h"
#include "distance.h" // the shapes, their exact intersect() and distance()

namespace bvh {
namespace detail {

/// intersect(a, b) as the shape type's own (found by argument-dependent
/// lookup): shape_traits's default. (A function of its own, so that the
/// call does not find shape_traits's member of the same name.)
template <class A, class B> bool intersect_adl(const A &a, const B &b) { return intersect(a, b); }

/// True for a shape type that is the closed disk inscribed in its box and
/// whose intersect() is exact: this project's Disk (intersect.h defines
/// BVH_EXACT_DISKS beside its predicate). The course's own Disk is not: its
/// intersect() has a tolerance, which only it can apply.
template <class T> inline constexpr bool kExactDisk = false;
#if defined(BVH_EXACT_DISKS)
template <> inline constexpr bool kExactDisk<Disk> = true; // (inline: one definition in every translation unit)
#endif


} // namespace detail
// ---- How the tree reads your types: the customization points ------------

/// The four sides of an axis-aligned box, as the tree reads every box.
struct bounds {
  double min_x, min_y, max_x, max_y;
};

/// How the tree reads a box type B. The default reads getMin() and getMax(),
/// points with x and y (this project's BoundingBox and the course's).
/// Specialize it for your own box type, e.g. Box2D's b2AABB:
///   template <> struct bvh::box_traits<b2AABB> {
///     static bvh::bounds get(const b2AABB &b) {
///       return {b.lowerBound.x, b.lowerBound.y, b.upperBound.x, b.upperBound.y}; } };
/// Every box type box_traits understands can be a shape's box and the
/// argument of query() and overlapping().
template <class B> struct box_traits {
  static bounds get(const B &b) {
    const auto &lo = b.getMin();
    const auto &hi = b.getMax();
    return bounds{double(lo.x), double(lo.y), double(hi.x), double(hi.y)};
  }
};
/// bounds itself.
template <> struct box_traits<bounds> {
  static bounds get(const bounds &b) { return b; }
};

/// How the tree reads a stored value of type T: its box, its centre and
/// whether two of them intersect. The default reads the members getBox()
/// and getCenter() and calls the free intersect(a, b) found by
/// argument-dependent lookup, as the course's shapes have them. For a type
/// of your own, specialize shape_traits<YourType> (static members), or pass
/// an adaptor type as BVH's second template argument: the tree keeps a copy
/// of it (given to its constructor), so it may hold state, e.g. pointers to
/// the arrays that stored ids index (examples/ids_into_arrays.cpp).
template <class T> struct shape_traits {
  /// Its box: any type box_traits understands.
  static decltype(auto) box(const T &s) { return s.getBox(); }
  /// Its centre, anything with x and y: the build rules sort by it.
  static decltype(auto) center(const T &s) { return s.getCenter(); }
  /// True when a and b share a point (touching counts).
  static bool intersect(const T &a, const T &b) { return detail::intersect_adl(a, b); }
  /// A promise that each shape is the closed disk inscribed in its box
  /// (up to the rounding of the box's sides to double or float) and that
  /// intersect() is exactly "the closed disks share a point". Collision
  /// searches of trees with leaf summaries (widths 4 to 8) then decide
  /// most shapes from the summary alone, without reading them; the answers
  /// are the same. True for this project's Disk; an adaptor of your own
  /// may declare it too.
  static constexpr bool inscribed_disks = detail::kExactDisk<T>;
};

namespace detail {

/// Tr::inscribed_disks, or false when Tr has no such member.
template <class Tr, class = void> struct InscribedDisks : std::false_type {};
template <class Tr>
struct InscribedDisks<Tr, std::void_t<decltype(Tr::inscribed_disks)>>
    : std::integral_constant<bool, bool(Tr::inscribed_disks)> {};
} // namespace detail
} // namespace bvh

#endif // BVH_TRAITS_H
