// main.cpp — bvh.out, the course's command line (CSCI-1200 Homework 8):
// reads a scene of disks, triangles or quads (or, in a .shapes file, all
// three mixed), builds a BVH in bulk or one
// shape at a time (optionally discarding shapes that touch one already
// kept: Poisson-disk sampling), prints the course's statistics and writes
// an SVG picture. It also generates random scenes in the same format. The
// scene reader is scene.h, the generator generate.h; this file is the command line.
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
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <climits>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/generate.h>
#include <bvh/shapes.h>
#include <bvh/svg.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

namespace {

[[maybe_unused]] const char *const kUsage = // (unused under BVH_NO_MAIN)
    "usage: bvh.out -i SCENE (-o PICTURE.html | --no_output) [--split_threshold K]\n"
    "               [--depth_limit D] [--incremental [--discard_overlap]] [--visualize]\n"
    "               [--print_tree] [--pairs] [--build course|sah] [--threads N]\n"
    "               [--width 2|3|4|8]\n"
    "       bvh.out --generate disks|triangles|quads|shapes COUNT -o SCENE [--seed S]\n"
    "               [--size MIN:MAX] [--overlap]\n"
    "       bvh.out --help\n";

[[maybe_unused]] const char *const kHelp =
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
    "                           or 8; wider trees are shallower and smaller\n"
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
[[maybe_unused]] void remove_partial_on_signals(const std::string &partial) {
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
[[maybe_unused]] void hold_closed_standard_descriptors() {
  for (int fd = 0; fd <= 2; ++fd)
    if (fcntl(fd, F_GETFD) == -1 && errno == EBADF) {
      const int held = open("/dev/null", O_RDONLY);
      if (held >= 0 && held != fd) {
        dup2(held, fd);
        close(held);
      }
    }
}

/// Flushes stdout; false with `error` set when any write to it since the
/// last call failed. The reason is errno's: the caller clears errno before
/// a part's writes and this clears it after, so that it is the failed
/// write's (without one, the message has no reason).
[[maybe_unused]] bool stdout_written(std::string &error) {
  std::cout.flush();
  const bool failed = std::fflush(stdout) != 0 || std::ferror(stdout) || !std::cout;
  if (failed) {
    error = "error writing standard output";
    if (errno != 0) error += std::string(": ") + std::strerror(errno);
  }
  errno = 0;
  return !failed;
}

// ---------------------------------------------------------------------------
// Progress on a terminal: one line on stderr, rewritten in place, from a
// ticker thread (construct() and write_svg() are single calls), shown once
// the run has lasted kProgressDelay and only when stderr is a terminal, so
// redirected output never holds it. stdout is never touched; pause() clears
// the line before the program prints there or reports an error.

class Progress {
public:
  Progress() : start_(Clock::now()), enabled_(isatty(STDERR_FILENO) == 1) {
    // BVH_PROGRESS_DELAY (seconds) replaces the 1 s delay: tests set 0.
    if (const char *d = std::getenv("BVH_PROGRESS_DELAY")) delay_ = std::chrono::duration<double>(std::atof(d));
    if (enabled_) ticker_ = std::thread([this] { tick(); });
  }
  ~Progress() {
    if (!enabled_) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
      clear();
    }
    wake_.notify_all();
    ticker_.join();
  }
  Progress(const Progress &) = delete;
  Progress &operator=(const Progress &) = delete;

  /// A new stage ("reading x.disks"); `total` > 0 shows "done of total" with `unit`.
  void stage(const std::string &what, std::uint64_t total = 0, const char *unit = "") {
    if (!enabled_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    what_ = what;
    total_ = total;
    unit_ = unit;
    done_.store(0, std::memory_order_relaxed);
    tries_.store(-1, std::memory_order_relaxed);
    paused_ = false;
    show();
  }
  /// How far the stage is (cheap: the ticker reads it).
  void advance(std::uint64_t done) {
    if (enabled_) done_.store(done, std::memory_order_relaxed);
  }
  /// A second count shown after the first, as ", N tries" (--generate).
  void detail(long tries) {
    if (enabled_) tries_.store(tries, std::memory_order_relaxed);
  }
  /// Clears the line until the next stage().
  void pause() {
    if (!enabled_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    paused_ = true;
    clear();
  }

private:
  using Clock = std::chrono::steady_clock;

  void tick() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stopping_) {
      wake_.wait_for(lock, std::chrono::milliseconds(200));
      if (!stopping_) show();
    }
  }
  // Under mutex_.
  void show() {
    const std::chrono::duration<double> elapsed = Clock::now() - start_;
    if (paused_ || what_.empty() || elapsed < delay_) return;
    char buf[160];
    std::string line = "bvh.out: " + what_;
    if (total_ > 0) {
      const std::uint64_t done = std::min(done_.load(std::memory_order_relaxed), total_);
      const bool mb = unit_ == std::string("MB");
      std::snprintf(buf, sizeof buf, mb ? ": %.1f of %.1f %s (%.0f%%)" : ": %.0f of %.0f %s (%.0f%%)",
                    double(done) * (mb ? 1e-6 : 1.0), double(total_) * (mb ? 1e-6 : 1.0), unit_,
                    100.0 * double(done) / double(total_));
      line += buf;
      const long tries = tries_.load(std::memory_order_relaxed);
      if (tries >= 0) {
        std::snprintf(buf, sizeof buf, tries >= 1000000 ? ", %.1fM tries" : ", %.0f tries",
                      tries >= 1000000 ? double(tries) * 1e-6 : double(tries));
        line += buf;
      }
    } else {
      line += "...";
    }
    std::snprintf(buf, sizeof buf, "  %.1f s", elapsed.count());
    line += buf;
    line = "\r\033[K" + line;
    std::fputs(line.c_str(), stderr);
    std::fflush(stderr);
    shown_ = true;
  }
  void clear() {
    if (!shown_) return;
    std::fputs("\r\033[K", stderr);
    std::fflush(stderr);
    shown_ = false;
  }

  const Clock::time_point start_;
  std::chrono::duration<double> delay_{1.0};
  const bool enabled_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::thread ticker_;
  std::string what_;
  std::uint64_t total_ = 0;
  const char *unit_ = "";
  std::atomic<std::uint64_t> done_{0};
  std::atomic<long> tries_{-1};
  bool paused_ = false, shown_ = false, stopping_ = false;
};

// ---------------------------------------------------------------------------
// --generate: the scene text (generate.h), written under a temporary name.

// On a terminal, the progress line shows the shapes placed and the tries
// made ("generating 1000000 disks: 59 of 1000000 shapes (0%), 4.2M tries").
// A non-overlapping request that cannot fit by max_non_overlapping()'s
// packing bound (generate.h) is refused before the first try.
template <class T>
int generate(const std::string &kind, long count, std::uint64_t seed, double lo, double hi, bool overlap,
             const std::string &path) {
  const double most = max_non_overlapping(kind, lo);
  if (!overlap && double(count) > most) {
    char buf[64];
    std::snprintf(buf, sizeof buf, " of %s at least %g", kind == "disks" ? "radius" : "size", lo);
    std::cerr << "bvh.out: " << count << " " << kind << buf
              << " cannot fit in the 1000 x 1000 canvas without touching: a packing bound allows at most "
              << static_cast<long long>(most) << " (random placement fits fewer); choose a smaller --size, a "
              << "smaller COUNT, or --overlap\n";
    return 2;
  }
  Progress progress;
  progress.stage("generating " + std::to_string(count) + " " + kind, std::uint64_t(count), "shapes");
  std::string text;
  const long made = generate_scene<T>(kind, count, seed, lo, hi, overlap, text, [&](long placed, long tries) {
    progress.advance(std::uint64_t(placed));
    progress.detail(tries);
  });
  progress.pause();
  if (made < count) {
    std::cerr << "bvh.out: could place only " << made << " of " << count
              << " non-overlapping shapes; choose a smaller --size or --overlap\n";
    return 1;
  }
  progress.stage("writing " + path);
  const std::string temp = bvh::partial_path(path);
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) {
      progress.pause();
      std::cerr << "bvh.out: " << path << ": cannot write: " << std::strerror(errno) << "\n";
      return 2;
    }
    out << text;
    out.flush();
    if (!out) {
      progress.pause();
      std::cerr << "bvh.out: " << path << ": write failed\n";
      out.close();
      std::remove(temp.c_str());
      return 1;
    }
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    progress.pause();
    std::cerr << "bvh.out: " << path << ": cannot write: " << std::strerror(errno) << "\n";
    std::remove(temp.c_str());
    return 2;
  }
  return 0;
}

// ---------------------------------------------------------------------------
// The course's workflow.

struct Options {
  std::string input, output;
  int split_threshold = 4;
  int depth_limit = 0; // 0: unlimited, and no statistics (the course's default)
  bool incremental = false, discard_overlap = false, visualize = false, print_tree = false, pairs = false;
  bool no_output = false; // --no_output: no picture
  bool sah = false; // --build sah
  unsigned threads = 0; // --threads N (0: all cores)
  int width = 3;        // --width W
  bool generate = false, overlap = false;
  std::string kind;
  long count = 0;
  std::uint64_t seed = 1;
  double size_lo = -1, size_hi = -1;
};

/// The course's workflow on the scene `input`, o.input opened (once: a
/// FIFO's writer is met by one open only).
template <class T, int W> int run(const Options &o, std::FILE *input) {
  std::vector<T> shapes;
  std::string error;
  Progress progress;
  struct stat st {};
  const bool sized = fstat(fileno(input), &st) == 0 && S_ISREG(st.st_mode);
  progress.stage("reading " + o.input, sized ? std::uint64_t(st.st_size) : 0, "MB");
  if (!load_scene(input, o.input, shapes, error, kReadChunk, [&](std::uint64_t read) { progress.advance(read); })) {
    progress.pause();
    std::cerr << "bvh.out: " << error << "\n";
    return 1;
  }
  BVH<T, bvh::shape_traits<T>, W> tree(o.split_threshold, o.depth_limit);
  if (o.sah) tree.set_build_rule(decltype(tree)::BuildRule::sah);
  tree.set_build_threads(o.threads);
  if (!o.incremental) {
    progress.stage("building the tree of " + std::to_string(shapes.size()) + " shapes");
    tree.construct(shapes);
  } else {
    progress.stage(o.discard_overlap ? "sampling" : "inserting", shapes.size(), "shapes");
    std::uint64_t done = 0;
    if (o.discard_overlap) {
      // insert_disjoint: the loop "insert unless it touches a kept one" on
      // every core, with exactly the loop's tree. In parts of kPart
      // candidates (each call is that loop too), for the progress line.
      const std::size_t kPart = std::size_t(1) << 18;
      for (std::size_t at = 0; at < shapes.size(); at += kPart) {
        const std::size_t end = std::min(shapes.size(), at + kPart);
        if (at == 0 && end == shapes.size()) {
          tree.insert_disjoint(shapes, o.threads);
        } else {
          tree.insert_disjoint(std::vector<T>(shapes.begin() + long(at), shapes.begin() + long(end)), o.threads);
        }
        progress.advance(done = end);
      }
    } else {
      for (const T &s : shapes) {
        tree.insert(s);
        progress.advance(++done);
      }
    }
  }
  progress.pause();
  // stdout is checked after each part, so that a failed write stops the run
  // before the next (a --print_tree of millions of lines stops at the failed
  // write: the stream then ignores the rest).
  errno = 0;
  if (o.depth_limit > 0) tree.statistics(o.print_tree);
  if (!stdout_written(error)) {
    std::cerr << "bvh.out: " << error << "\n";
    return 1;
  }
  if (o.pairs) {
    progress.stage("counting overlapping pairs");
    const std::size_t pairs = tree.count_overlapping_pairs();
    progress.pause();
    std::cout << "overlapping pairs: " << pairs << "\n";
    if (!stdout_written(error)) {
      std::cerr << "bvh.out: " << error << "\n";
      return 1;
    }
  }
  if (o.no_output) return 0;
  progress.stage("writing " + o.output);
  if (!write_svg(o.output, tree, o.visualize, &error)) {
    progress.pause();
    std::cerr << "bvh.out: " << error << "\n";
    return 1;
  }
  return 0;
}

/// run() at the tree width of --width. (-DBVH_CLI_COURSE_WIDTH_ONLY: the
/// course's width 3 alone, a quarter of the trees to compile; make test's
/// sanitizer build of bvh.out and the CMake package test build it so, their
/// cases being at width 3. The unit suites test every width, under the
/// sanitizers too.)
template <class T> int run_at(const Options &o, std::FILE *input) {
#ifdef BVH_CLI_COURSE_WIDTH_ONLY
  return run<T, 3>(o, input);
#else
  switch (o.width) {
  case 2: return run<T, 2>(o, input);
  case 4: return run<T, 4>(o, input);
  case 8: return run<T, 8>(o, input);
  default: return run<T, 3>(o, input);
  }
#endif
}

bool ends_with(const std::string &s, const std::string &suffix) {
  return s.size() > suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

long parse_integer(const std::string &flag, const std::string &text, long lo, long hi) {
  long value = 0;
  const char *end = text.data() + text.size();
  const std::from_chars_result r = std::from_chars(text.data(), end, value);
  if (r.ec != std::errc() || r.ptr != end || value < lo || value > hi)
    throw UsageError{flag + " needs an integer from " + std::to_string(lo) + " to " + std::to_string(hi) +
                     ", not '" + text + "'"};
  return value;
}

double parse_real(const std::string &flag, const std::string &text) {
  double value = 0;
#if defined(__cpp_lib_to_chars) && __cpp_lib_to_chars >= 201611L
  const std::from_chars_result r = std::from_chars(text.data(), text.data() + text.size(), value);
  const bool whole = r.ec == std::errc() && r.ptr == text.data() + text.size();
#else
  // No floating-point from_chars (libc++ before 17, as on macOS): strtod,
  // on text that from_chars would also read from its first character, and
  // without strtod's hexadecimal form.
  char *stop = nullptr;
  const bool starts = !text.empty() && (text[0] == '-' || text[0] == '.' || std::isalnum((unsigned char)text[0])) &&
                      text.find_first_of("xX") == std::string::npos;
  if (starts) value = std::strtod(text.c_str(), &stop);
  const bool whole = starts && stop == text.c_str() + text.size();
#endif
  if (!whole || !(value > 0) || value > 500)
    throw UsageError{flag + " needs sizes above 0 and at most 500, not '" + text + "'"};
  return value;
}

/// Every option parse_options knows (-i and -o are --input and --output;
/// --help, which bvh_main handles first, is kHelpOption): option_name and
/// the "did you mean" of an unknown one both read this table, so that no
/// option can be missing from either.
const char *const kOptions[] = {"--input", "--output", "--split_threshold", "--depth_limit", "--incremental",
                                "--discard_overlap", "--visualize", "--print_tree", "--generate", "--seed",
                                "--size", "--overlap", "--pairs", "--build", "--no_output", "--threads",
                                "--width"};
const char *const kHelpOption = "--help";

/// The option's one name (-i is --input, -o is --output), or "" for a word
/// that is not an option.
std::string option_name(const std::string &arg) {
  if (arg == "-i") return "--input";
  if (arg == "-o") return "--output";
  for (const char *name : kOptions)
    if (arg == name) return arg;
  return "";
}

/// Levenshtein distance of a and b, '-' and '_' counting as the same letter.
std::size_t edit_distance(const std::string &a, const std::string &b) {
  auto same = [](char x, char y) { return x == y || ((x == '-' || x == '_') && (y == '-' || y == '_')); };
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (same(a[i - 1], b[j - 1]) ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

/// "unknown argument 'ARG'", with the nearest option when one is close (at
/// most 2 edits, '-' for '_' free: --depth-limit, -depth_limit, --visualise),
/// or the -i a scene name lacks.
std::string unknown_argument(const std::string &arg) {
  std::string message = "unknown argument '" + arg + "'";
  if (arg.size() > 2 && arg.size() < 40 && arg[0] == '-') {
    std::string best;
    std::size_t best_distance = 3;
    auto consider = [&](const char *name) {
      const std::size_t d = edit_distance(arg, name);
      if (d < best_distance) best_distance = d, best = name;
    };
    for (const char *name : kOptions) consider(name);
    consider(kHelpOption);
    if (!best.empty()) message += "; did you mean " + best + "?";
  } else if (arg[0] != '-' && (ends_with(arg, ".disks") || ends_with(arg, ".triangles") ||
                               ends_with(arg, ".quads") || ends_with(arg, ".shapes"))) {
    message += "; did you mean -i " + arg + "?";
  }
  return message;
}

/// The command line (without --help, which bvh_main handles first). Every
/// option may be given once: a repeat is more likely a slip (two -o) than
/// a wish, so it is an error rather than "the last one wins".
Options parse_options(int argc, char **argv) {
  Options o;
  std::vector<std::string> seen;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const std::string name = option_name(arg);
    if (name.empty()) throw UsageError{unknown_argument(arg)};
    if (std::find(seen.begin(), seen.end(), name) != seen.end()) throw UsageError{arg + " given twice"};
    seen.push_back(name);
    // An empty word, or an option where the value should be, means the value was forgotten.
    auto value = [&]() -> std::string {
      if (i + 1 >= argc || argv[i + 1][0] == '\0' || !option_name(argv[i + 1]).empty())
        throw UsageError{arg + " needs a value"};
      return argv[++i];
    };
    if (name == "--input") {
      o.input = value();
    } else if (name == "--output") {
      o.output = value();
    } else if (name == "--split_threshold") {
      o.split_threshold = int(parse_integer(arg, value(), 1, INT_MAX));
    } else if (name == "--depth_limit") {
      o.depth_limit = int(parse_integer(arg, value(), 0, INT_MAX));
    } else if (name == "--incremental") {
      o.incremental = true;
    } else if (name == "--discard_overlap") {
      o.discard_overlap = true;
    } else if (name == "--visualize") {
      o.visualize = true;
    } else if (name == "--print_tree") {
      o.print_tree = true;
    } else if (name == "--pairs") {
      o.pairs = true;
    } else if (name == "--no_output") {
      o.no_output = true;
    } else if (name == "--width") {
      const std::string w = value();
      if (w != "2" && w != "3" && w != "4" && w != "8")
        throw UsageError{"--width needs 2, 3, 4 or 8, not '" + w + "'"};
#ifdef BVH_CLI_COURSE_WIDTH_ONLY
      if (w != "3") throw UsageError{"--width " + w + ": this build has width 3 only (BVH_CLI_COURSE_WIDTH_ONLY)"};
#endif
      o.width = w[0] - '0';
    } else if (name == "--threads") {
      o.threads = unsigned(parse_integer(arg, value(), 1, 1024));
    } else if (name == "--build") {
      const std::string rule = value();
      if (rule != "course" && rule != "sah") throw UsageError{"--build needs course or sah, not '" + rule + "'"};
      o.sah = rule == "sah";
    } else if (name == "--generate") {
      o.generate = true;
      o.kind = value();
      if (o.kind != "disks" && o.kind != "triangles" && o.kind != "quads" && o.kind != "shapes")
        throw UsageError{"--generate needs a kind: disks, triangles, quads or shapes, not '" + o.kind + "'"};
      o.count = parse_integer("--generate COUNT", value(), 0, 100000000);
    } else if (name == "--seed") {
      o.seed = std::uint64_t(parse_integer(arg, value(), 0, 2147483647));
    } else if (name == "--size") {
      const std::string text = value();
      const std::size_t colon = text.find(':');
      if (colon == std::string::npos) throw UsageError{"--size needs MIN:MAX, not '" + text + "'"};
      o.size_lo = parse_real(arg, text.substr(0, colon));
      o.size_hi = parse_real(arg, text.substr(colon + 1));
      if (o.size_lo > o.size_hi) throw UsageError{"--size needs MIN <= MAX, not '" + text + "'"};
    } else {
      o.overlap = true;
    }
  }
  // What is missing, in the order the usage names it: the input first.
  if (!o.generate && o.input.empty()) throw UsageError{"missing -i INPUT"};
  if (o.no_output) {
    if (o.generate) throw UsageError{"--generate needs -o SCENE, not --no_output"};
    if (!o.output.empty()) throw UsageError{"--no_output and -o exclude each other"};
  } else if (o.output.empty()) {
    throw UsageError{"missing -o OUTPUT"};
  }
  if (o.generate) {
    if (!o.input.empty()) throw UsageError{"--generate takes no -i"};
    if (!ends_with(o.output, "." + o.kind))
      throw UsageError{"the generated scene's name must end in ." + o.kind + ": '" + o.output + "'"};
    return o;
  }
  if (o.discard_overlap && !o.incremental) throw UsageError{"--discard_overlap needs --incremental"};
  if (!o.no_output && !ends_with(o.output, ".html") && !ends_with(o.output, ".svg"))
    throw UsageError{"the picture's name must end in .html or .svg: '" + o.output + "'"};
  if (!ends_with(o.input, ".disks") && !ends_with(o.input, ".triangles") && !ends_with(o.input, ".quads") &&
      !ends_with(o.input, ".shapes"))
    throw UsageError{"unknown input kind '" + o.input +
                     "': the name must end in .disks, .triangles, .quads or .shapes"};
  return o;
}

/// The input file, closed when it goes.
using InputFile = std::unique_ptr<std::FILE, int (*)(std::FILE *)>;

/// Checks, before any work, that the input can be opened, that the output
/// can be created, and that they are not one file (through a link): the
/// picture would replace the scene. Sets `error` (exit status 2) if not.
/// The input is opened here, once, and `input` keeps it for the reading.
[[maybe_unused]] bool check_files(const Options &o, InputFile &input, std::string &error) {
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

} // namespace

#ifndef BVH_NO_MAIN
/// The whole program. (-DBVH_NO_MAIN, tests/fuzz_parser.cpp's build, leaves
/// it out, and with it the trees of every shape kind and width it builds:
/// the fuzzer needs only the command-line parser below.)
int bvh_main(int argc, char **argv) {
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "--help" || std::string(argv[i]) == "-h") {
      std::cout << kUsage << "\n" << kHelp;
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
      if (o.kind == "disks") return generate<Disk>(o.kind, o.count, o.seed, lo, hi, o.overlap, o.output);
      if (o.kind == "triangles") return generate<Triangle>(o.kind, o.count, o.seed, lo, hi, o.overlap, o.output);
      if (o.kind == "quads") return generate<Quad>(o.kind, o.count, o.seed, lo, hi, o.overlap, o.output);
      return generate<Shape>(o.kind, o.count, o.seed, lo, hi, o.overlap, o.output);
    }
    if (ends_with(o.input, ".disks")) return run_at<Disk>(o, input.get());
    if (ends_with(o.input, ".triangles")) return run_at<Triangle>(o, input.get());
    if (ends_with(o.input, ".quads")) return run_at<Quad>(o, input.get());
    return run_at<Shape>(o, input.get());
  } catch (const std::bad_alloc &) {
    // A scene too big for this machine's memory.
    std::cerr << "bvh.out: out of memory\n";
    return 1;
  }
}

#endif

/// tests/fuzz_parser.cpp's way in (it links this file, compiled with
/// -DBVH_NO_MAIN): the command line parsed as bvh_main parses it, touching
/// no file. 0 with the parsed limits, or 2 with the one-line message.
int bvh_parse_command_line(int argc, char **argv, int &split_threshold, int &depth_limit, std::string &message) {
  try {
    const Options o = parse_options(argc, argv);
    split_threshold = o.split_threshold;
    depth_limit = o.depth_limit;
    return 0;
  } catch (const UsageError &e) {
    message = e.message;
    return 2;
  }
}

#ifndef BVH_NO_MAIN
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
#endif
