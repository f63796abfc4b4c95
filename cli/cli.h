// cli/cli.h — what bvh.out's translation units share. bvh.out is main.cpp
// (the command line: its files, --generate, the exit statuses) and cli/:
//   options.cpp        the option parser (parse_options; the fuzz target
//                      links it alone, with no tree)
//   progress.h/.cpp    the progress line on a terminal
//   run.h              the work on one shape kind: the course's workflow on a
//                      scene, run<T, W>, and --generate's, generate<T>
//   kinds.cpp          the dispatch on the scene's kind and on --width
//   course_disks_triangles.cpp, course_quads_shapes.cpp
//                      run.h at the course's width 3, two shape kinds each:
//                      two halves of about the same size, which make -j
//                      compiles side by side
//   course_width_only.cpp
//                      the default build's other widths: refused, with the
//                      way to build them (a quarter of the trees to compile)
//   wider_disks_triangles.cpp, wider_quads_shapes.cpp
//                      instead, in a build with every width (make
//                      WIDTHS=all): run.h at widths 2, 4 and 8
#ifndef BVH_CLI_CLI_H
#define BVH_CLI_CLI_H

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

#include <bvh/defaults.h>
#include <bvh/shapes.h>

namespace bvh_cli {

/// A command-line mistake: reported with the usage (a file that cannot be
/// opened or written: without, as one line), exit status 2. The message
/// quotes the user's words, so control bytes in them are shown as \xNN and a
/// huge word is cut: the message stays one readable line.
struct UsageError {
  explicit UsageError(const std::string &text, bool with_usage = true) : show_usage(with_usage) {
    const std::size_t kMaxShown = 1000;
    for (std::size_t i = 0; i < text.size() && message.size() < kMaxShown; ++i) {
      const unsigned char c = static_cast<unsigned char>(text[i]);
      if (c < 0x20 || c == 0x7f) {
        char buf[8];
        std::snprintf(buf, sizeof buf, "\\x%02x", unsigned(c));
        message += buf;
      } else {
        message += char(c);
      }
    }
    if (message.size() >= kMaxShown) message += "...";
  }
  std::string message;
  bool show_usage;
};

struct Options {
  std::string input, output;
  int split_threshold = bvh::course_split_threshold; // the course's tree unless told otherwise
  int depth_limit = 0; // 0: unlimited, and no statistics (the course's default)
  bool incremental = false, discard_overlap = false, visualize = false, print_tree = false, pairs = false;
  bool no_output = false; // --no_output: no picture
  bool sah = false; // --build sah
  unsigned threads = 0; // --threads N (0: all cores)
  int width = bvh::course_width; // --width W
  bool generate = false, overlap = false;
  std::string kind;
  long count = 0;
  std::uint64_t seed = 1;
  double size_lo = -1, size_hi = -1;
};

/// The command line (without --help, which bvh_main handles first); throws
/// UsageError (cli/options.cpp).
Options parse_options(int argc, char **argv);

/// Whether s ends with suffix (and is longer).
bool ends_with(const std::string &s, const std::string &suffix);

/// Flushes stdout; false with `error` set when a write to it failed
/// (main.cpp).
bool stdout_written(std::string &error);

/// The course's workflow on the scene o.input, opened as `input`, at the
/// width o.width, the shape kind by the scene's name; and --generate's scene
/// of o.kind, sizes from lo to hi. Exit statuses as bvh_main's
/// (cli/kinds.cpp).
int run_scene(const Options &o, std::FILE *input);
int generate_scene_file(const Options &o, double lo, double hi);

/// The same for one shape kind T (cli/run.h): at the course's width
/// (cli/course_*.cpp instantiate it), at o.width, another (cli/wider_*.cpp,
/// or cli/course_width_only.cpp's refusal), and --generate's.
template <class T> int run_course_width(const Options &o, std::FILE *input);
template <class T> int run_other_width(const Options &o, std::FILE *input);
template <class T> int generate_kind(const Options &o, double lo, double hi);

/// What --help adds to --width's line: which widths this build has (empty
/// when it has them all).
const char *widths_built_note();

} // namespace bvh_cli

#endif
