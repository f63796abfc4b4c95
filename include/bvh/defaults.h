// bvh/defaults.h — the two configurations of a tree, stated once.
//
// The library's default, what bvh::BVH<T> is with no other template
// argument: eight children a node and up to 32 shapes a leaf, the fastest
// and smallest configuration measured (docs/performance.txt). The course's
// tree, bvh::CourseBVH<T>: three children, up to four shapes a leaf and
// the course's rule, as the homework fixes it; bvh.out runs it unless told
// otherwise. The benchmarks, the docs, bvh.out and the tests read these
// names. Includes nothing.
#ifndef BVH_DEFAULTS_H
#define BVH_DEFAULTS_H

namespace bvh {

/// Children a node of BVH<T>.
inline constexpr int default_width = 8;
/// Shapes a leaf of BVH<T> holds before it splits.
inline constexpr int default_split_threshold = 32;
/// Children a node of the course's tree, CourseBVH<T>.
inline constexpr int course_width = 3;
/// Shapes a leaf of the course's tree holds before it splits.
inline constexpr int course_split_threshold = 4;

/// The split threshold a tree of width `width` starts with when none is
/// given: the course's at the course's width, the default's at any other.
constexpr int default_split_threshold_at(int width) {
  return width == course_width ? course_split_threshold : default_split_threshold;
}

} // namespace bvh

#endif // BVH_DEFAULTS_H
