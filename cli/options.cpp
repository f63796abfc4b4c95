// cli/options.cpp — bvh.out's command-line parser: the options, their
// values' checks, and the "did you mean" of an unknown one. No tree: the
// fuzz target (tests/fuzz_parser.cpp) links this file alone, through
// bvh_parse_command_line below.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <climits>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <system_error>
#include <vector>

#include "cli.h"

namespace bvh_cli {

bool ends_with(const std::string &s, const std::string &suffix) {
  return s.size() > suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

namespace {

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

} // namespace

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

} // namespace bvh_cli

/// tests/fuzz_parser.cpp's way in (it links this file and no other of
/// bvh.out's): the command line parsed as bvh_main parses it, touching no
/// file. 0 with the parsed limits, or 2 with the one-line message.
int bvh_parse_command_line(int argc, char **argv, int &split_threshold, int &depth_limit, std::string &message) {
  using namespace bvh_cli;
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
