// bvh/version.h — the library's version, MAJOR.MINOR.PATCH. CMakeLists.txt
// reads its project version from these three lines, so the package
// (find_package(bvh 1.1), bvh.pc) and the header cannot disagree.
// <bvh/bvh.h> includes this header.
#ifndef BVH_VERSION_H
#define BVH_VERSION_H

#define BVH_VERSION_MAJOR 1
#define BVH_VERSION_MINOR 1
#define BVH_VERSION_PATCH 0

/// The version as one number, MAJOR * 10000 + MINOR * 100 + PATCH, for #if.
#define BVH_VERSION (BVH_VERSION_MAJOR * 10000 + BVH_VERSION_MINOR * 100 + BVH_VERSION_PATCH)

#endif // BVH_VERSION_H
