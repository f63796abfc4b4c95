// cli/course_width_only.cpp — the default bvh.out has the course's width 3
// alone (what it runs unless told --width): a quarter of the trees to
// compile. --width 2, 4 or 8 is then refused with the way to build them,
// here, linked instead of cli/wider_*.cpp.
#include <iostream>

#include "cli.h"

namespace bvh_cli {

namespace {
int refuse_width(const Options &o) {
  std::cerr << "bvh.out: --width " << o.width << ": " << widths_built_note() << "\n";
  return 2;
}
} // namespace

const char *widths_built_note() {
  return "this bvh.out has the course's width 3 alone; make WIDTHS=all (CMake: -DBVH_CLI_ALL_WIDTHS=ON) "
         "builds 2, 4 and 8 too";
}

template <> int run_other_width<bvh::Disk>(const Options &o, std::FILE *) { return refuse_width(o); }
template <> int run_other_width<bvh::Triangle>(const Options &o, std::FILE *) { return refuse_width(o); }
template <> int run_other_width<bvh::Quad>(const Options &o, std::FILE *) { return refuse_width(o); }
template <> int run_other_width<bvh::Shape>(const Options &o, std::FILE *) { return refuse_width(o); }

} // namespace bvh_cli
