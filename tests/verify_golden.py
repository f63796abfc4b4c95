#!/usr/bin/env python3
"""tests/verify_golden.py — an independent model of bvh.out's stdout.

Recomputes every golden file of tests/golden.list from the handout's rules,
written again from scratch in Python (recursive build with a stable sort,
the insertion strategy of docs/library.txt, discard-overlap sampling with exact
rational geometry), and compares it with expected_output/. It is how the
golden files were checked before they were committed, and `make test` runs
it again so the C++ and this model keep agreeing.

usage: verify_golden.py LABEL DATA_FOLDER   (LABEL: course or inputs)
"""
import struct
import sys
from fractions import Fraction

CANVAS = 1000.0 * 1000.0


FLOAT32 = struct.Struct("f")
FLOAT32_BITS = struct.Struct("I")


def to_float32_exact(text):
    """The float nearest to the decimal text (ties to even), as a Python float:
    what the course's `istr >> float` reads."""
    exact = Fraction(text)
    guess = FLOAT32.unpack(FLOAT32.pack(float(exact)))[0]
    bits = FLOAT32_BITS.unpack(FLOAT32.pack(guess))[0]
    best = None
    for b in (bits - 1, bits, bits + 1):
        if not 0 <= b < 2**32:
            continue
        v = FLOAT32.unpack(FLOAT32_BITS.pack(b))[0]
        if v != v or v in (float("inf"), float("-inf")):
            continue
        d = abs(Fraction(v) - exact)
        if best is None or d < best[0] or (d == best[0] and b % 2 == 0):
            best = (d, b, v)
    return best[2]


def to_float32_uncached(text):
    """to_float32_exact's answer, without fractions where they cannot change
    it. float(text) is the double nearest the text; rounding that double to
    float gives the float nearest the text too, unless the double lies
    exactly halfway between two floats (a float's midpoint has 25
    significant bits, so it is a double: a double that is not one lies, with
    the text, on one side of it)."""
    d = float(text)
    guess = FLOAT32.unpack(FLOAT32.pack(d))[0]
    if guess == d:
        return guess
    bits = FLOAT32_BITS.unpack(FLOAT32.pack(guess))[0]
    # The float on d's other side: one step away from zero when d is
    # farther from zero than guess, else one step towards it.
    other_bits = bits + 1 if abs(d) > abs(guess) else bits - 1
    if 0 <= other_bits < 2**32:
        other = FLOAT32.unpack(FLOAT32_BITS.pack(other_bits))[0]
        if other == other and abs(other) != float("inf") and d != (guess + other) / 2:
            return guess
    return to_float32_exact(text)


CACHE = {}


def to_float32(text):
    """The float nearest to the decimal text (ties to even), as a Python float:
    what the course's `istr >> float` reads. (Scenes are read once for each
    golden file that uses them: each text is converted once.)"""
    value = CACHE.get(text)
    if value is None:
        value = CACHE[text] = to_float32_uncached(text)
    return value


def load(path):
    kind = path.rsplit(".", 1)[1]
    shapes = []
    with open(path) as f:
        for line in f:
            text = line.replace("<", " ").replace(">", " ").replace("{", " ").replace("}", " ")
            tok = text.split()
            if not tok:
                continue
            if kind == "shapes":  # a mixed scene: the line's form says its kind
                kind_here = "disks" if "radius=" in tok else ("triangles" if tok.count("pt=") == 3 else "quads")
            else:
                kind_here = kind
            if kind_here == "disks":
                x, y, r = to_float32(tok[1]), to_float32(tok[2]), to_float32(tok[4])
                shapes.append(("disk", [(x, y)], r))
            else:
                n = 3 if kind_here == "triangles" else 4
                pts = [(to_float32(tok[1 + 3 * i]), to_float32(tok[2 + 3 * i])) for i in range(n)]
                shapes.append(("poly", pts, 0.0))
    return shapes


def box_of(s):
    kind, pts, r = s
    if kind == "disk":
        (x, y), = pts
        return (x - r, y - r, x + r, y + r)
    xs = [p[0] for p in pts]
    ys = [p[1] for p in pts]
    return (min(xs), min(ys), max(xs), max(ys))


def center_of(s):
    kind, pts, _ = s
    if kind == "disk":
        return pts[0]
    sx = sy = 0.0
    for x, y in pts:  # same summation order as shapes.h
        sx += x
        sy += y
    return (sx / len(pts), sy / len(pts))


def union(boxes):
    return (min(b[0] for b in boxes), min(b[1] for b in boxes), max(b[2] for b in boxes), max(b[3] for b in boxes))


def area(b):
    return (b[2] - b[0]) * (b[3] - b[1])


def box_text(b):
    return "[<%5.1f %5.1f> <%5.1f %5.1f>]" % b


class Node:
    def __init__(self, depth):
        self.depth = depth
        self.children = []
        self.shapes = None  # list for a leaf
        self.box = None


def build(node, shapes, k, limit):
    """The handout's rule, literally: stable sort, three near-equal groups."""
    node.box = union([box_of(s) for s in shapes])
    if len(shapes) <= k or (limit > 0 and node.depth == limit):
        node.shapes = list(shapes)
        node.children = []
        return
    b = node.box
    axis = 0 if b[2] - b[0] >= b[3] - b[1] else 1
    ordered = sorted(shapes, key=lambda s: center_of(s)[axis])  # Python's sort is stable
    n = len(ordered)
    node.shapes = None
    node.children = []
    start = 0
    for g in range(3):
        size = n // 3 + (1 if g < n % 3 else 0)
        if size == 0:
            continue
        child = Node(node.depth + 1)
        build(child, ordered[start:start + size], k, limit)
        node.children.append(child)
        start += size


def f32(d):
    return struct.unpack("f", struct.pack("f", d))[0]


def f32_step(f, up):
    bits = struct.unpack("I", struct.pack("f", f))[0]
    if f == 0:
        bits = 0x00000001 if up else 0x80000001
    elif (f > 0) == up:
        bits += 1
    else:
        bits -= 1
    return struct.unpack("f", struct.pack("I", bits))[0]


def float_box(b):
    """A box rounded outwards to floats, as the parent keeps it."""
    lo = [f32(v) for v in b[:2]]
    hi = [f32(v) for v in b[2:]]
    lo = [f32_step(f, False) if f > v else f for f, v in zip(lo, b[:2])]
    hi = [f32_step(f, True) if f < v else f for f, v in zip(hi, b[2:])]
    return (lo[0], lo[1], hi[0], hi[1])


def count(node):
    if node.shapes is not None:
        return len(node.shapes)
    return sum(count(c) for c in node.children)


def leaf_order(node):
    if node.shapes is not None:
        return list(node.shapes)
    return [s for c in node.children for s in leaf_order(c)]


LOPSIDED = 0.6


def insert(root, shape, k, limit):
    """docs/library.txt's insertion strategy: descend into the child whose float
    box grows least in area (ties: the smaller, then the first), add to the
    leaf, split an overfull leaf above the limit by the build rule, then
    rebuild the highest node on the path (of at least max(16, 3(k+1))
    shapes) whose child on the path holds more than 0.6 of its shapes."""
    sb = box_of(shape)
    if root is None:
        root = Node(0)
        root.box = sb
        root.shapes = [shape]
        return root
    node = root
    path = []
    while True:
        node.box = union([node.box, sb])
        if node.shapes is not None:
            break
        path.append(node)
        best = None
        for c in node.children:
            x0, y0, x1, y1 = float_box(c.box)
            a = (x1 - x0) * (y1 - y0)
            grown = (max(x1, sb[2]) - min(x0, sb[0])) * (max(y1, sb[3]) - min(y0, sb[1]))
            key = (grown - a, a)
            if best is None or key < best[0]:
                best = (key, c)
        node = best[1]
    node.shapes.append(shape)
    if len(node.shapes) > k and (limit == 0 or node.depth < limit):
        build(node, node.shapes, k, limit)
    below = node
    scapegoat = None
    for a in reversed(path):
        n = count(a)
        if n >= max(16, 3 * (k + 1)) and count(below) > LOPSIDED * n:
            scapegoat = a
        below = a
    if scapegoat is not None:
        build(scapegoat, leaf_order(scapegoat), k, limit)
    return root


# ---- exact geometry for discard-overlap and pairs ---------------------------
# Every coordinate and radius is a float32 value, and every float32 value times
# 2^149 is an integer: scaled so, the predicates below are exact integer
# arithmetic (no rounding anywhere), the same values Fractions would give, only
# faster. Divisions are avoided by cross-multiplying.

SCALE = 2.0 ** 149


def scaled(v):
    return int(v * SCALE)  # exact: a power-of-two scaling of a float32 value (load() reads only those)


def orient(a, b, c):
    v = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    return (v > 0) - (v < 0)


def on_segment(a, b, p):
    return (orient(a, b, p) == 0 and min(a[0], b[0]) <= p[0] <= max(a[0], b[0])
            and min(a[1], b[1]) <= p[1] <= max(a[1], b[1]))


def segments_meet(a, b, c, d):
    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    return on_segment(a, b, c) or on_segment(a, b, d) or on_segment(c, d, a) or on_segment(c, d, b)


def inside_or_on(poly, p):
    n = len(poly)
    for i in range(n):
        if on_segment(poly[i], poly[(i + 1) % n], p):
            return True
    crossings = 0
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        if (a[1] > p[1]) != (b[1] > p[1]):
            # p[0] < a[0] + (p[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1]), times (b[1] - a[1]) != 0
            lhs, rhs = (p[0] - a[0]) * (b[1] - a[1]), (p[1] - a[1]) * (b[0] - a[0])
            if (lhs < rhs) if b[1] > a[1] else (lhs > rhs):
                crossings += 1
    return crossings % 2 == 1


def seg_point_within(a, b, p, r2):
    """Whether the squared distance from p to the segment ab is <= r2."""
    abx, aby = b[0] - a[0], b[1] - a[1]
    apx, apy = p[0] - a[0], p[1] - a[1]
    ll = abx * abx + aby * aby
    dot = apx * abx + apy * aby
    if ll == 0 or dot <= 0:  # nearest point a
        return apx * apx + apy * apy <= r2
    if dot >= ll:  # nearest point b
        bpx, bpy = p[0] - b[0], p[1] - b[1]
        return bpx * bpx + bpy * bpy <= r2
    # |ap|^2 - dot^2 / ll <= r2, times ll > 0
    return (apx * apx + apy * apy) * ll - dot * dot <= r2 * ll


def exact_intersect(s, t):
    fs = (s[0], [(scaled(x), scaled(y)) for x, y in s[1]], scaled(s[2]))
    ft = (t[0], [(scaled(x), scaled(y)) for x, y in t[1]], scaled(t[2]))
    if fs[0] == "disk" and ft[0] == "disk":
        (a,), (b,) = fs[1], ft[1]
        dx, dy = a[0] - b[0], a[1] - b[1]
        return dx * dx + dy * dy <= (fs[2] + ft[2]) ** 2
    if fs[0] == "disk" or ft[0] == "disk":
        disk, poly = (fs, ft) if fs[0] == "disk" else (ft, fs)
        c, r, pts = disk[1][0], disk[2], poly[1]
        if inside_or_on(pts, c):
            return True
        return any(seg_point_within(pts[i], pts[(i + 1) % len(pts)], c, r * r) for i in range(len(pts)))
    p, q = fs[1], ft[1]
    for i in range(len(p)):
        for j in range(len(q)):
            if segments_meet(p[i], p[(i + 1) % len(p)], q[j], q[(j + 1) % len(q)]):
                return True
    return inside_or_on(p, q[0]) or inside_or_on(q, p[0])


def boxes_touch(a, b):
    return a[0] <= b[2] and b[0] <= a[2] and a[1] <= b[3] and b[1] <= a[3]


def discard_overlap(shapes):
    kept = []
    for s in shapes:
        sb = box_of(s)
        if not any(boxes_touch(sb, box_of(k)) and exact_intersect(k, s) for k in kept):
            kept.append(s)
    return kept


def overlapping_pairs(shapes):
    """Pairs that intersect exactly, by a sweep along x over the boxes."""
    boxed = sorted(((box_of(s), s) for s in shapes), key=lambda bs: bs[0][0])
    count = 0
    for i, (bi, si) in enumerate(boxed):
        for bj, sj in boxed[i + 1:]:
            if bj[0] > bi[2]:
                break
            if boxes_touch(bi, bj) and exact_intersect(si, sj):
                count += 1
    return count


def report(root, print_tree=True):
    lines = []
    count = 0
    max_depth = 0
    inner = leaf = 0.0
    stack = [root] if root else []
    while stack:
        n = stack.pop()
        a = area(n.box) / CANVAS
        count += 1
        max_depth = max(max_depth, n.depth)
        text = ("%.3g" if n is root else "%.3f") % a
        if n.shapes is not None:
            leaf += a * len(n.shapes)
            lines.append("   " * n.depth + "leaf area=" + text + " " + box_text(n.box) + " elements:"
                         + "".join(" " + box_text(box_of(s)) for s in n.shapes))
        else:
            inner += a
            lines.append("   " * n.depth + "inner area=" + text + " " + box_text(n.box))
        stack.extend(reversed(n.children))
    lines.append("node count:      %7d" % count)
    lines.append("max depth:       %7d" % max_depth)
    lines.append("inner node area: %7.3f" % inner)
    lines.append("leaf node area:  %7.3f" % leaf)
    return "\n".join(lines) + "\n"


def expected_stdout(data, argv):
    k, limit, incremental, discard, pairs = 4, 0, False, False, False
    scene = None
    i = 0
    while i < len(argv):
        a = argv[i]
        if a == "-i":
            scene = data + "/" + argv[i + 1]
            i += 1
        elif a == "--split_threshold":
            k = int(argv[i + 1])
            i += 1
        elif a == "--depth_limit":
            limit = int(argv[i + 1])
            i += 1
        elif a == "--incremental":
            incremental = True
        elif a == "--discard_overlap":
            discard = True
        elif a == "--pairs":
            pairs = True
        i += 1
    shapes = load(scene)
    if discard:
        shapes = discard_overlap(shapes)
    # --pairs counts the pairs among the shapes in the tree
    tail = "overlapping pairs: %d\n" % overlapping_pairs(shapes) if pairs else ""
    if limit <= 0:
        return tail  # unlimited depth: the course prints no statistics
    root = None
    if incremental:
        for s in shapes:
            root = insert(root, s, k, limit)
    elif shapes:
        root = Node(0)
        build(root, shapes, k, limit)
    return report(root) + tail


def main():
    label, data = sys.argv[1], sys.argv[2]
    bad = 0
    checked = 0
    for line in open("tests/golden.list"):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        name, *argv = line.split()
        if label == "course" and any(a.endswith(".shapes") for a in argv):
            continue  # the course has no mixed scenes
        if label == "inputs":
            # our own scenes and their goldens carry the prefix gen_ (tests/golden.list)
            name = "gen_" + name
            argv = ["gen_" + a if i > 0 and argv[i - 1] == "-i" else a for i, a in enumerate(argv)]
        want = expected_stdout(data, argv)
        with open("expected_output/%s/%s.txt" % (label, name)) as f:
            have = f.read()
        checked += 1
        if want != have:
            bad += 1
            print("MISMATCH %s/%s" % (label, name))
            wl, hl = want.splitlines(), have.splitlines()
            for j, (w, h) in enumerate(zip(wl, hl)):
                if w != h:
                    print("  line %d\n  model: %s\n  file:  %s" % (j + 1, w, h))
                    break
            else:
                print("  lengths differ: model %d lines, file %d lines" % (len(wl), len(hl)))
        else:
            print("agrees %s/%s" % (label, name))
    print("%d golden files checked, %d disagree" % (checked, bad))
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
