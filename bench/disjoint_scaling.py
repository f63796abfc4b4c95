#!/usr/bin/env python3
"""bench/disjoint_scaling.py — reads the raw sections of
bench/results_disjoint_scaling.txt (written by bench/disjoint_scaling.sh) and
either prints the summary table (insert_disjoint's serial fraction, Amdahl's
predicted speed-ups, the measured ones, the 10M point against Boost) or draws
docs/disjoint_speedup.svg from the same figures. Standard library only.

  python3 bench/disjoint_scaling.py summary bench/results_disjoint_scaling.txt
  python3 bench/disjoint_scaling.py chart bench/results_disjoint_scaling.txt docs/disjoint_speedup.svg
"""

import math
import re
import statistics
import sys

CORES = [1, 2, 4, 8, 16, 32, 64]

RUN = re.compile(r"^bench: (\S+) (\S+) run (\d+)/(\d+): ([0-9.]+) s, kept (\d+)")
PROFILE = re.compile(r"^bench: disjoint-profile (.*)$")
PARALLELISM = re.compile(r"^available parallelism .*: ([0-9.]+)x")
MEASURED = re.compile(r"^Measured: (.*)$")
RSS = re.compile(r"^disjoint_scaling: .* peak RSS ([0-9.]+) MB")


def count_label(n):
    if n >= 1000000 and n % 1000000 == 0:
        return "%dM" % (n // 1000000)
    if n >= 1000 and n % 1000 == 0:
        return "%dk" % (n // 1000)
    return str(n)


class Section:
    def __init__(self, command):
        self.command = command
        words = command.split()
        self.workload = words[words.index("--only") + 1] if "--only" in words else "?"
        self.n = int(words[words.index("--big") + 1]) if "--big" in words else 1000000
        self.label = "%s %s" % (self.workload, count_label(self.n))
        self.times = {}     # method -> [seconds per run]
        self.kept = {}      # method -> set of kept counts
        self.profiles = []  # the disjoint-profile fields of each ours-par run
        self.parallelism = None
        self.measured = None
        self.rss_mb = None

    def median(self, method):
        t = self.times.get(method)
        return statistics.median(t) if t else None


def parse(path):
    sections = []
    cur = None
    pending = None  # a profile line belongs to the run line that follows it
    with open(path) as f:
        for line in f:
            line = line.rstrip("\n")
            if line.startswith("### "):
                # Only the bench commands are sections; "### summary" is ours.
                command = line[4:].strip()
                cur = Section(command) if "--only" in command.split() else None
                if cur:
                    sections.append(cur)
                pending = None
                continue
            if cur is None:
                continue
            m = PROFILE.match(line)
            if m:
                pending = {k: float(v) for k, v in (kv.split("=") for kv in m.group(1).split())}
                continue
            m = RUN.match(line)
            if m:
                method = m.group(2)
                cur.times.setdefault(method, []).append(float(m.group(5)))
                cur.kept.setdefault(method, set()).add(int(m.group(6)))
                if pending is not None and method == "ours-par":
                    cur.profiles.append(pending)
                pending = None
                continue
            m = PARALLELISM.match(line)
            if m and cur.parallelism is None:
                cur.parallelism = float(m.group(1))
                continue
            m = MEASURED.match(line)
            if m and cur.measured is None:
                cur.measured = m.group(1)
                continue
            m = RSS.match(line)
            if m:
                cur.rss_mb = float(m.group(1))
    return sections


def fractions(s):
    """(median, min, max) of the per-run serial fraction, from CPU and from wall seconds."""
    cpu = [p["serial_cpu"] / (p["serial_cpu"] + p["parallel_cpu"]) for p in s.profiles
           if p["serial_cpu"] + p["parallel_cpu"] > 0]
    wall = [p["serial_wall"] / (p["serial_wall"] + p["parallel_wall"]) for p in s.profiles
            if p["serial_wall"] + p["parallel_wall"] > 0]
    def stats(v):
        return (statistics.median(v), min(v), max(v)) if v else None
    return stats(cpu), stats(wall)


def amdahl(f, p):
    return 1.0 / (f + (1.0 - f) / p)


def measured_speedup(s):
    loop, par = s.median("ours"), s.median("ours-par")
    return loop / par if loop and par else None


def fmt(x, spec="%.4f", none="-"):
    return none if x is None else spec % x


def summary(sections):
    out = []
    measured = next((s.measured for s in sections if s.measured), "?")
    out.append("Summary (bench/disjoint_scaling.py): medians over each workload's runs. Measured: " + measured)
    out.append("")
    out.append("Times, wall seconds (ours = the loop; ours-par = insert_disjoint on all cores; ours-par1 on one;")
    out.append("peak RSS = the largest process of that bench command):")
    head = "%-8s %4s %8s %9s %9s %9s %9s %9s %7s %8s" % (
        "workload", "runs", "kept", "ours", "ours-par", "ours-par1", "boost-q16", "grid", "avail.", "peak MB")
    out.append(head)
    out.append("-" * len(head))
    for s in sections:
        kept = set().union(*s.kept.values()) if s.kept else set()
        kept_s = str(kept.pop()) if len(kept) == 1 else ("DIFFER" if kept else "-")
        runs = max((len(t) for t in s.times.values()), default=0)
        out.append("%-8s %4d %8s %9s %9s %9s %9s %9s %7s %8s" % (
            s.label, runs, kept_s, fmt(s.median("ours")), fmt(s.median("ours-par")), fmt(s.median("ours-par1")),
            fmt(s.median("boost-quad16")), fmt(s.median("grid")), fmt(s.parallelism, "%.2fx"),
            fmt(s.rss_mb, "%.0f")))
    out.append("")
    out.append("Serial fraction of insert_disjoint's work, per ours-par run, median (min-max):")
    out.append("f = serial_cpu / (serial_cpu + parallel_cpu); the wall figure is the serial steps' share of the")
    out.append("elapsed time with the parallel steps already on this machine's cores, so it is not Amdahl's f.")
    head = "%-8s %22s %22s %10s %10s" % ("workload", "f (CPU seconds)", "f (wall seconds)", "serial s", "parallel s")
    out.append(head)
    out.append("-" * len(head))
    for s in sections:
        cpu, wall = fractions(s)
        if cpu is None:
            continue
        out.append("%-8s %22s %22s %10.4f %10.4f" % (
            s.label, "%.3f (%.3f-%.3f)" % cpu, "%.3f (%.3f-%.3f)" % wall if wall else "-",
            statistics.median(p["serial_cpu"] for p in s.profiles),
            statistics.median(p["parallel_cpu"] for p in s.profiles)))
    out.append("")
    out.append("Amdahl: S(p) = 1 / (f + (1 - f)/p) with f (CPU) above: insert_disjoint on p cores against itself")
    out.append("on one, an upper bound (perfect scaling of the parallel steps, no synchronisation cost). measured =")
    out.append("median ours / median ours-par on this machine (all its cores, against the loop).")
    head = "%-8s" % "workload" + "".join("%8s" % ("p=%d" % p) for p in CORES) + "%10s" % "measured"
    out.append(head)
    out.append("-" * len(head))
    for s in sections:
        cpu, _ = fractions(s)
        if cpu is None:
            continue
        out.append("%-8s" % s.label + "".join("%7.2fx" % amdahl(cpu[0], p) for p in CORES)
                   + "%10s" % fmt(measured_speedup(s), "%.2fx"))
    for s in sections:
        boost = s.median("boost-quad16")
        if not boost:
            continue
        out.append("")
        line = "%s against Boost's quadratic<16> R-tree loop (one core), median time ratios:" % s.label
        out.append(line)
        for method, what in (("ours-par", "all cores"), ("ours", "the loop, one core"), ("grid", "one core")):
            m = s.median(method)
            if m:
                out.append("  %-9s / boost-quad16 = %.3f  (%s: %.2fx faster)" % (method, m / boost, what, boost / m))
    return "\n".join(out) + "\n"


# ---------------------------------------------------------------------------
# The chart: x = cores (log2), y = predicted speed-up (log2, so that the
# ideal line is a diagonal and the workloads that saturate near 2 stay legible).

COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"]
MARKERS = ["circle", "square", "diamond", "triangle"]


def esc(t):
    return t.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def marker(kind, x, y, colour):
    r = 6
    if kind == "circle":
        return '<circle cx="%.1f" cy="%.1f" r="%d" fill="%s" stroke="black" stroke-width="1"/>' % (x, y, r, colour)
    if kind == "square":
        return '<rect x="%.1f" y="%.1f" width="%d" height="%d" fill="%s" stroke="black" stroke-width="1"/>' % (
            x - r, y - r, 2 * r, 2 * r, colour)
    if kind == "diamond":
        pts = [(x, y - r - 1), (x + r + 1, y), (x, y + r + 1), (x - r - 1, y)]
    else:
        pts = [(x, y - r - 1), (x + r + 1, y + r), (x - r - 1, y + r)]
    return '<polygon points="%s" fill="%s" stroke="black" stroke-width="1"/>' % (
        " ".join("%.1f,%.1f" % p for p in pts), colour)


def chart(sections, path):
    series = []
    for s in sections:
        cpu, _ = fractions(s)
        if cpu is not None:
            series.append((s, cpu[0], measured_speedup(s)))
    W, H = 900, 600
    left, right, top, bottom = 80, 250, 70, 70
    pw, ph = W - left - right, H - top - bottom
    lo = min([1.0] + [m for _, _, m in series if m])
    ymin = 2.0 ** math.floor(math.log2(lo)) if lo < 1 else 1.0
    ymax = float(CORES[-1])

    def X(p):
        return left + pw * math.log2(p) / math.log2(CORES[-1])

    def Y(v):
        return top + ph * (1 - (math.log2(v) - math.log2(ymin)) / (math.log2(ymax) - math.log2(ymin)))

    measured = next((s.measured for s in sections if s.measured), "?")
    e = []
    e.append('<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" viewBox="0 0 %d %d" '
             'font-family="sans-serif" font-size="13">' % (W, H, W, H))
    e.append('<rect width="%d" height="%d" fill="white"/>' % (W, H))
    e.append('<text x="%d" y="28" text-anchor="middle" font-size="17" font-weight="bold">'
             'insert_disjoint: Amdahl speed-up predicted from the serial fraction of the work</text>' % (left + pw / 2))
    e.append('<text x="%d" y="48" text-anchor="middle" font-size="11" fill="#444">%s</text>' % (
        left + pw / 2, esc("S(p) = 1 / (f + (1 - f)/p), f = serial CPU s / all CPU s (median of runs); " + measured)))
    # grid and ticks
    y = ymin
    while y <= ymax * 1.0001:
        e.append('<line x1="%d" y1="%.1f" x2="%d" y2="%.1f" stroke="#ddd"/>' % (left, Y(y), left + pw, Y(y)))
        e.append('<text x="%d" y="%.1f" text-anchor="end">%s</text>' % (left - 8, Y(y) + 4, ("%g" % y)))
        y *= 2
    for p in CORES:
        e.append('<line x1="%.1f" y1="%d" x2="%.1f" y2="%d" stroke="#ddd"/>' % (X(p), top, X(p), top + ph))
        e.append('<text x="%.1f" y="%d" text-anchor="middle">%d</text>' % (X(p), top + ph + 20, p))
    e.append('<rect x="%d" y="%d" width="%d" height="%d" fill="none" stroke="black"/>' % (left, top, pw, ph))
    e.append('<text x="%.1f" y="%d" text-anchor="middle" font-size="14">cores p (log scale)</text>' % (
        left + pw / 2, H - 22))
    e.append('<text x="22" y="%.1f" text-anchor="middle" font-size="14" transform="rotate(-90 22 %.1f)">'
             'predicted speed-up S(p) (log scale)</text>' % (top + ph / 2, top + ph / 2))
    # ideal
    e.append('<polyline points="%s" fill="none" stroke="#555" stroke-width="1.5" stroke-dasharray="6,5"/>' % (
        " ".join("%.1f,%.1f" % (X(p), Y(p)) for p in CORES)))
    # workloads
    for i, (s, f, m) in enumerate(series):
        c = COLOURS[i % len(COLOURS)]
        e.append('<polyline points="%s" fill="none" stroke="%s" stroke-width="2.5"/>' % (
            " ".join("%.1f,%.1f" % (X(p), Y(amdahl(f, p))) for p in CORES), c))
        for p in CORES:
            e.append('<circle cx="%.1f" cy="%.1f" r="2.5" fill="%s"/>' % (X(p), Y(amdahl(f, p)), c))
        e.append('<text x="%.1f" y="%.1f" fill="%s" font-size="12">%.1fx</text>' % (
            X(CORES[-1]) + 6, Y(amdahl(f, CORES[-1])) + 4, c, amdahl(f, CORES[-1])))
        if m:
            # Side by side, since the workloads' points at p = 2 often coincide.
            dx = 14 * (i - (len(series) - 1) / 2)
            e.append(marker(MARKERS[i % len(MARKERS)], X(2) + dx, Y(m), c))
    # legend
    lx, ly = left + pw + 45, top + 10
    e.append('<text x="%d" y="%d" font-weight="bold">legend</text>' % (lx, ly))
    ly += 22
    for i, (s, f, m) in enumerate(series):
        c = COLOURS[i % len(COLOURS)]
        e.append('<line x1="%d" y1="%d" x2="%d" y2="%d" stroke="%s" stroke-width="2.5"/>' % (lx, ly, lx + 28, ly, c))
        e.append('<text x="%d" y="%d">%s, f = %.3f</text>' % (lx + 36, ly + 4, esc(s.label), f))
        ly += 22
    e.append('<line x1="%d" y1="%d" x2="%d" y2="%d" stroke="#555" stroke-width="1.5" stroke-dasharray="6,5"/>' % (
        lx, ly, lx + 28, ly))
    e.append('<text x="%d" y="%d">ideal, S(p) = p</text>' % (lx + 36, ly + 4))
    ly += 34
    e.append('<text x="%d" y="%d" font-weight="bold">measured, 2 cores</text>' % (lx, ly))
    ly += 8
    e.append('<text x="%d" y="%d" font-size="11" fill="#444">(loop time / insert_disjoint</text>' % (lx, ly + 12))
    e.append('<text x="%d" y="%d" font-size="11" fill="#444">time, this machine; spin: what</text>' % (lx, ly + 26))
    e.append('<text x="%d" y="%d" font-size="11" fill="#444">a spin loop gained on its cores)</text>' % (
        lx, ly + 40))
    ly += 62
    for i, (s, f, m) in enumerate(series):
        if not m:
            continue
        c = COLOURS[i % len(COLOURS)]
        e.append(marker(MARKERS[i % len(MARKERS)], lx + 14, ly, c))
        spin = " (spin %.2fx)" % s.parallelism if s.parallelism else ""
        e.append('<text x="%d" y="%d">%s: %.2fx%s</text>' % (lx + 36, ly + 4, esc(s.label), m, spin))
        ly += 22
    e.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(e) + "\n")


def main(argv):
    if len(argv) == 3 and argv[1] == "summary":
        sys.stdout.write(summary(parse(argv[2])))
        return 0
    if len(argv) == 4 and argv[1] == "chart":
        chart(parse(argv[2]), argv[3])
        return 0
    sys.stderr.write(__doc__)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
