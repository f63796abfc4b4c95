// bvh.h — placeholder until the course's edition replaces it: the engine
// under the course's unqualified names.
#ifndef BVH_COURSE_BVH_H
#define BVH_COURSE_BVH_H
#include "shapes.h"
#include "include/bvh/bvh.h"
using bvh::BVH;
#endif
