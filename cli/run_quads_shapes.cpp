// cli/run_quads_shapes.cpp — bvh.out's trees of quads and mixed scenes' shapes (.shapes), at every
// width, and --generate quads and shapes (cli/run.h).
#include "run.h"

namespace bvh_cli {
template int run_kind<Quad>(const Options &, std::FILE *);
template int generate_kind<Quad>(const Options &, double, double);
template int run_kind<Shape>(const Options &, std::FILE *);
template int generate_kind<Shape>(const Options &, double, double);
} // namespace bvh_cli
