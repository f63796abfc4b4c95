// cli/wider_quads_shapes.cpp — bvh.out's trees of quads and of mixed scenes'
// shapes at widths 2, 4 and 8 (cli/run.h), in a build with every width
// (make WIDTHS=all).
#include "run.h"

namespace bvh_cli {
template int run_other_width<Quad>(const Options &, std::FILE *);
template int run_other_width<Shape>(const Options &, std::FILE *);
} // namespace bvh_cli
