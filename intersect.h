// intersect.h — the exact intersection predicates (include/bvh/intersect.h)
// under the course's unqualified names: intersect(a, b) for every pair of
// Disk, Triangle, Quad and Shape. Comes with "shapes.h".
#ifndef BVH_COURSE_INTERSECT_H
#define BVH_COURSE_INTERSECT_H

#include "shapes.h"

#endif // BVH_COURSE_INTERSECT_H
