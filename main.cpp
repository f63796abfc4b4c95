// main.cpp — bvh.out, the course's command line (CSCI-1200 Homework 8):
// reads a scene of disks, triangles or quads (or, in a .shapes file, all
// three mixed), builds a BVH in bulk or one
// shape at a time (optionally discarding shapes that touch one already
// kept: Poisson-disk sampling), prints the course's statistics and writes
// an SVG picture. It also generates random scenes in the same format. The
// scene reader is scene.h, the generator generate.h; this file is the command line,
// and cli/ the rest of the program (cli/cli.h names its parts).
//
//   ./bvh.out -i 36.triangles -o out.html --depth_limit 2 --visualize --print_tree
//   ./bvh.out -i overlap_1000.disks -o out.html --depth_limit 8 --incremental --discard_overlap
//   ./bvh.out --generate disks 1000 --seed 7 --overlap -o overlap_1000.disks
//
// Exit status: 0 on success, 1 when the input file is wrong (FILE:LINE:
// message on stderr) or stdout cannot be written, 2 for a wrong command
// line. No output file is left behind on any error, nor when SIGINT,
// SIGTERM, SIGHUP or SIGQUIT ends the run.
#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <iostream>
#include <memory>
#include <new>
#include <string>
#include <system_error>

#include <bvh/bvh.h>
#include <bvh/generate.h>
#include <bvh/shapes.h>
#include <bvh/svg.h>

#include "cli/cli.h"
#include "cli/progress.h"
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified
using namespace bvh_cli;

namespace {

const char *const kUsage =
    "usage: bvh.out -i SCENE (-o PICTURE.html | --no_output) [--split_threshold K]\n"
    "               [--depth_limit D] [--incremental [--discard_overlap]] [--visualize]\n"
    "               [--print_tree] [--pairs] [--build course|sah] [--threads N]\n"
    "               [--width 2|3|4|8]\n"
    "       bvh.out --generate disks|triangles|quads|shapes COUNT -o SCENE [--seed S]\n"
    "               [--size MIN:MAX] [--overlap]\n"
    "       bvh.out --help\n";

const char *const kHelp =
    "Builds a bounding volume hierarchy (ternary, as the course's, unless --width\n"
    "says otherwise) over the shapes of SCENE (a\n"
    ".disks, .triangles or .quads file, or a .shapes file whose lines may be any of\n"
    "the three) and draws it to PICTURE.html (SVG).\n"
    "\n"
    "  -i, --input SCENE        the shapes, one per line; the suffix gives their kind\n"
    "  -o, --output FILE        the picture (.html or .svg); with --generate, the scene\n"
    "  --no_output              instead of -o: build and print as usual, write no picture\n"
    "                           (a 2M-shape scene's picture is 250 MB no browser opens)\n"
    "  --split_threshold K      split a node holding more than K shapes (K >= 1, default 4)\n"
    "  --depth_limit D          never split below depth D (the root is depth 0); without it,\n"
    "                           or with D = 0, depth is unlimited and no statistics are printed\n"
    "  --incremental            insert the shapes one at a time, in input order\n"
    "  --discard_overlap        with --incremental: skip every shape that touches one\n"
    "                           already kept (Poisson-disk sampling)\n"
    "  --visualize              draw every node's box; colour shapes by their leaf\n"
    "  --print_tree             with the statistics, list every node and its shapes\n"
    "  --build course|sah       how nodes are cut: the course's rule (default), or the\n"
    "                           binned surface area heuristic (also for insert's splits)\n"
    "  --threads N              threads for the bulk build and the sampling (1 to 1024;\n"
    "                           default: all cores); the output is the same for every N\n"
    "  --width W                children per inner node: 2, 3 (the course's, default), 4\n"
    "                           or 8; wider trees are shallower and smaller%s\n"
    "  --pairs                  print 'overlapping pairs: N', the number of pairs of shapes\n"
    "                           in the tree that intersect (after the statistics, if any)\n"
    "  --generate KIND COUNT    write COUNT random shapes of KIND (disks, triangles, quads,\n"
    "                           or shapes: each line a random one of the three)\n"
    "  --seed S                 random seed for --generate (default 1)\n"
    "  --size MIN:MAX           radius range of generated shapes (default from COUNT)\n"
    "  --overlap                generated shapes may overlap (default: none touch)\n"
    "  --help                   this text\n"
    "\n"
    "When stderr is a terminal, a run longer than a second shows its progress there\n"
    "(reading, building or sampling, writing); never when stderr is redirected.\n";

// --help: the usage and kHelp, whose --width line ends with what this build
// has (widths_built_note: the default build has width 3 alone).
void print_help() {
  const std::string note = widths_built_note();
  std::string wrapped, line;
  if (!note.empty()) {
    // The note in parentheses, word-wrapped under the options' descriptions.
    std::istringstream words("(" + note + ")");
    const std::string indent(27, ' ');
    for (std::string word; words >> word;) {
      if (!line.empty() && indent.size() + line.size() + 1 + word.size() > 85) {
        wrapped += "\n" + indent + line;
        line.clear();
      }
      line += (line.empty() ? "" : " ") + word;
    }
    wrapped += "\n" + indent + line;
  }
  const std::string help = kHelp;
  const std::size_t at = help.find("%s");
  std::cout << kUsage << "\n" << help.substr(0, at) << wrapped << help.substr(at + 2);
}

using namespace bvh_scene;

// ---------------------------------------------------------------------------
// The temporary file and the signals that end a run. Every file bvh.out
// writes (the picture, a generated scene, check_files' probe) is written
// under one temporary name, OUTPUT.partial (bvh::partial_path), and renamed
// when complete. A signal that ends the run removes it: the handler
// unlinks the name computed before any file was made (unlink and raise are
// async-signal-safe), then the signal, back at its default action, ends
// the process as it would have (the shell's 128 + N).

std::string g_partial_name;               // the temporary's name (set once, before any file is made)
const char *volatile g_partial = nullptr; // g_partial_name's text while the handler may remove it

extern "C" void remove_partial_and_reraise(int sig) {
  const int saved = errno;
  if (const char *name = g_partial) unlink(name);
  signal(sig, SIG_DFL);
  raise(sig); // delivered once the handler returns (sig is blocked in it)
  errno = saved;
}

/// Installs the handler for the signals that end a run, except those the
/// caller ignores (nohup's SIGHUP, a background job's SIGINT stay ignored).
void remove_partial_on_signals(const std::string &partial) {
  g_partial_name = partial;
  g_partial = g_partial_name.c_str();
  for (int sig : {SIGHUP, SIGINT, SIGQUIT, SIGTERM}) {
    struct sigaction old {};
    if (sigaction(sig, nullptr, &old) != 0 || old.sa_handler == SIG_IGN) continue;
    struct sigaction action {};
    action.sa_handler = remove_partial_and_reraise;
    sigemptyset(&action.sa_mask);
    sigaction(sig, &action, nullptr);
  }
}

// ---------------------------------------------------------------------------
// Standard output. A write that fails (a full disk, a closed stdout) is an
// error: one line on stderr and exit status 1, the picture not written.

/// Before anything is opened: a standard descriptor the caller closed
/// (`>&-`) is opened on /dev/null, read-only, so that no file opened later
/// takes its number (a picture would then receive the statistics), and a
/// write to a closed stdout fails, as it should, with EBADF.
void hold_closed_standard_descriptors() {
  for (int fd = 0; fd <= 2; ++fd)
    if (fcntl(fd, F_GETFD) == -1 && errno == EBADF) {
      const int held = open("/dev/null", O_RDONLY);
      if (held >= 0 && held != fd) {
        dup2(held, fd);
        close(held);
      }
    }
}

} // namespace

/// Flushes stdout; false with `error` set when any write to it since the
/// last call failed. The reason is errno's: the caller clears errno before
/// a part's writes and this clears it after, so that it is the failed
/// write's (without one, the message has no reason).
bool bvh_cli::stdout_written(std::string &error) {
  std::cout.flush();
  const bool failed = std::fflush(stdout) != 0 || std::ferror(stdout) || !std::cout;
  if (failed) {
    error = "error writing standard output";
    if (errno != 0) error += std::string(": ") + std::strerror(errno);
  }
  errno = 0;
  return !failed;
}

namespace {

/// The input file, closed when it goes.
using InputFile = std::unique_ptr<std::FILE, int (*)(std::FILE *)>;

/// Checks, before any work, that the input can be opened, that the output
/// can be created, and that they are not one file (through a link): the
/// picture would replace the scene. Sets `error` (exit status 2) if not.
/// The input is opened here, once, and `input` keeps it for the reading.
bool check_files(const Options &o, InputFile &input, std::string &error) {
  std::error_code ec;
  if (!o.generate) {
    // fopen succeeds on a directory on Linux; only reading it fails.
    if (std::filesystem::is_directory(o.input, ec)) {
      error = o.input + ": cannot open: " + std::strerror(EISDIR);
      return false;
    }
    input.reset(std::fopen(o.input.c_str(), "rb"));
    if (!input) {
      error = o.input + ": cannot open: " + std::strerror(errno);
      return false;
    }
    if (o.no_output) return true;
    if (std::filesystem::equivalent(o.input, o.output, ec)) {
      error = "-i and -o name the same file: '" + o.output + "'";
      return false;
    }
  }
  if (std::filesystem::is_directory(o.output, ec)) {
    error = o.output + ": cannot write: " + std::strerror(EISDIR);
    return false;
  }
  // The output is written under this name, then renamed. Whatever holds the
  // name now (a stale temporary, or a link that would be written through)
  // goes first; removing a link leaves its target alone.
  const std::string temp = bvh::partial_path(o.output);
  std::remove(temp.c_str());
  std::FILE *probe = std::fopen(temp.c_str(), "wbx");
  if (!probe) {
    error = o.output + ": cannot write: " + std::strerror(errno);
    return false;
  }
  std::fclose(probe);
  std::remove(temp.c_str());
  return true;
}

/// The whole program.
int bvh_main(int argc, char **argv) {
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "--help" || std::string(argv[i]) == "-h") {
      print_help();
      return 0;
    }
  Options o;
  std::string error;
  InputFile input(nullptr, &std::fclose);
  try {
    o = parse_options(argc, argv);
    if (!o.no_output) remove_partial_on_signals(bvh::partial_path(o.output));
    if (!check_files(o, input, error)) throw UsageError{error, false};
  } catch (const UsageError &e) {
    std::cerr << "bvh.out: " << e.message << "\n";
    if (e.show_usage) std::cerr << kUsage;
    return 2;
  }
  try {
    if (o.generate) {
      // Default sizes: a fifth of the canvas covered (no overlap), or about
      // twice covered (overlap), by COUNT shapes.
      double hi = o.size_hi, lo = o.size_lo;
      if (hi < 0) default_sizes(o.count, o.overlap, lo, hi);
      return generate_scene_file(o, lo, hi);
    }
    return run_scene(o, input.get());
  } catch (const std::bad_alloc &) {
    // A scene too big for this machine's memory.
    std::cerr << "bvh.out: out of memory\n";
    return 1;
  }
}

} // namespace

int main(int argc, char **argv) {
  hold_closed_standard_descriptors();
  const int status = bvh_main(argc, argv);
  g_partial = nullptr; // (g_partial_name goes after main)
  // What is still unwritten (--help's text) or unreported.
  std::string error;
  if (!stdout_written(error) && status == 0) {
    std::cerr << "bvh.out: " << error << "\n";
    return 1;
  }
  return status;
}
