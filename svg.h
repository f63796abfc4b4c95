// svg.h — the picture of a tree (include/bvh/svg.h) under the course's
// unqualified names: write_svg(path, tree, visualize, &error) and the
// render_* pieces it is made of.
#ifndef BVH_COURSE_SVG_H
#define BVH_COURSE_SVG_H

#include "shapes.h"
#include "include/bvh/svg.h"

using bvh::render_end;
using bvh::render_shape;
using bvh::render_start;
using bvh::write_svg;

#endif // BVH_COURSE_SVG_H
