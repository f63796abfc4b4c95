// shapes.h — the course's shapes under the course's names: Point, Color,
// BoundingBox, Disk, Triangle, Quad (and Shape, Polygon), unqualified, with
// this project's exact intersect() and distance() for them. This is the
// course's layout: the top-level bvh.h (the course's edition) includes
// "shapes.h", as it does next to the course's own shapes.h on the homework
// server. The library itself is include/bvh/, where every name stays in
// namespace bvh (#include <bvh/shapes.h>).
#ifndef BVH_COURSE_SHAPES_H
#define BVH_COURSE_SHAPES_H

#include "include/bvh/distance.h" // (the shapes, intersect() and distance())

using bvh::BoundingBox;
using bvh::Color;
using bvh::Disk;
using bvh::distance;
using bvh::intersect;
using bvh::Point;
using bvh::Polygon;
using bvh::Quad;
using bvh::ray_hit;
using bvh::Shape;
using bvh::Triangle;

#endif // BVH_COURSE_SHAPES_H
