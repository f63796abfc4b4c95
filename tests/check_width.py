#!/usr/bin/env python3
"""tests/check_width.py — the tree bvh.out prints and draws at --width W,
checked against the rules every width shares (tests/cli_widths.sh runs it).

usage: check_width.py W SHAPES SPLIT DEPTH STDOUT [PICTURE]

STDOUT is bvh.out's stdout with --depth_limit DEPTH --split_threshold
SPLIT --print_tree, of a scene of SHAPES shapes; PICTURE, when given, its
picture with --visualize. Checked, from the printed numbers alone:
  - every inner node has 2 to W children, and with W > 3 some node more
    than 3 (the width is in use); no node deeper than DEPTH; a leaf holds
    1 to SPLIT shapes (more only at depth DEPTH), SHAPES in all;
  - every box is the union of its children's (a leaf's: of its shapes'):
    the printed sides are rounded, and rounding commutes with min and max,
    so the union holds exactly in print;
  - each node's printed area is its box's share of the 1000 x 1000 canvas,
    and the statistics (node count, max depth, inner node area, leaf node
    area) are those of the printed nodes;
  - the picture draws one translucent box per node, in the same order,
    coloured by the rule of docs/cli.txt (--visualize): the root grey, a
    child of the root primary[c] for its index c among its siblings, a
    deeper child 2/3 its parent's colour and 1/3 primary[c] (in float, as
    bvh.h mixes them); so siblings differ, up to W of them; and each leaf's
    shapes are filled with its colour.
Prints "ok" or the first rule broken, and exits 0 or 1.
"""
import re
import struct
import sys

NUM = r"\s*(-?[0-9.]+)"
BOX = r"\[<" + NUM + NUM + r"> <" + NUM + NUM + r">\]"
NODE = re.compile(r"^( *)(inner|leaf) area=([0-9.]+) " + BOX + r"( elements: (.*))?$")
ELEMENT = re.compile(BOX)
PRIMARY = [(255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 0),
           (0, 255, 255), (255, 0, 255), (255, 128, 0), (128, 0, 255)]


def fail(why):
    print("FAIL " + why)
    sys.exit(1)


def f32(x):
    return struct.unpack("f", struct.pack("f", x))[0]


def blend(parent, own):
    f = f32(2.0 / 3.0)
    g = f32(1.0 - f)
    return tuple(int(f32(f32(p * f) + f32(o * g))) for p, o in zip(parent, own))


def parse_tree(lines):
    nodes = []  # dicts: depth, kind, area, box, elements, children
    stack = []  # (depth, index)
    unit = None
    for n, line in enumerate(lines, 1):
        m = NODE.match(line)
        if not m:
            fail("line %d is not a node: %r" % (n, line[:80]))
        indent = len(m.group(1))
        if indent and unit is None:
            unit = indent
        depth = indent // unit if indent else 0
        if unit and indent % unit:
            fail("line %d: indent %d is not a multiple of %d" % (n, indent, unit))
        box = tuple(float(m.group(i)) for i in range(4, 8))
        elements = [tuple(float(v) for v in e) for e in ELEMENT.findall(m.group(9) or "")]
        node = dict(depth=depth, kind=m.group(2), area=float(m.group(3)), box=box, elements=elements,
                    children=[], line=n)
        while stack and stack[-1][0] >= depth:
            stack.pop()
        if depth > 0:
            if not stack or stack[-1][0] != depth - 1:
                fail("line %d: depth %d under no node of depth %d" % (n, depth, depth - 1))
            parent = nodes[stack[-1][1]]
            if parent["kind"] != "inner":
                fail("line %d: a child of the leaf on line %d" % (n, parent["line"]))
            parent["children"].append(len(nodes))
        elif nodes:
            fail("line %d: a second root" % n)
        stack.append((depth, len(nodes)))
        nodes.append(node)
    return nodes


def union(boxes):
    return (min(b[0] for b in boxes), min(b[1] for b in boxes), max(b[2] for b in boxes), max(b[3] for b in boxes))


def area(b):
    return (b[2] - b[0]) * (b[3] - b[1]) / 1e6


def area_slack(b):
    """How far a box's area may be from its printed sides' (each side
    within 0.05 of its print), as a share of the canvas."""
    return (0.1 * ((b[2] - b[0]) + (b[3] - b[1])) + 0.01) / 1e6


def main():
    if len(sys.argv) not in (6, 7):
        fail("usage: check_width.py W SHAPES SPLIT DEPTH STDOUT [PICTURE]")
    width, shapes, split, depth_limit = (int(a) for a in sys.argv[1:5])
    with open(sys.argv[5]) as f:
        lines = f.read().splitlines()
    stats = {}
    tree = []
    for line in lines:
        m = re.match(r"^(node count|max depth|inner node area|leaf node area|overlapping pairs): *(\S+)$", line)
        if m:
            stats[m.group(1)] = float(m.group(2))
        else:
            tree.append(line)
    for key in ("node count", "max depth", "inner node area", "leaf node area"):
        if key not in stats:
            fail("no '%s:' line" % key)
    nodes = parse_tree(tree)
    if not nodes:
        fail("no tree printed")
    held = 0
    widest = 0
    for node in nodes:
        where = "line %d" % node["line"]
        if node["depth"] > depth_limit:
            fail("%s: depth %d > depth_limit %d" % (where, node["depth"], depth_limit))
        # (the sides are printed to 0.1, the area to 0.001)
        if abs(area(node["box"]) - node["area"]) > 0.0005 + area_slack(node["box"]):
            fail("%s: area %.3f is not its box's %.5f" % (where, node["area"], area(node["box"])))
        if node["kind"] == "inner":
            k = len(node["children"])
            widest = max(widest, k)
            if not 2 <= k <= width:
                fail("%s: an inner node of %d children at width %d" % (where, k, width))
            if node["elements"]:
                fail("%s: an inner node with elements" % where)
            if union([nodes[c]["box"] for c in node["children"]]) != node["box"]:
                fail("%s: box is not the union of its children's" % where)
        else:
            k = len(node["elements"])
            held += k
            if k < 1 or (k > split and node["depth"] < depth_limit):
                fail("%s: a leaf of %d shapes above depth %d (split_threshold %d)" % (where, k, depth_limit, split))
            if union(node["elements"]) != node["box"]:
                fail("%s: box is not the union of its shapes'" % where)
    if held != shapes:
        fail("the leaves hold %d shapes, not %d" % (held, shapes))
    if width > 3 and widest <= 3:
        fail("no node has more than 3 children at width %d" % width)
    if stats["node count"] != len(nodes):
        fail("node count %d, but %d nodes printed" % (stats["node count"], len(nodes)))
    if stats["max depth"] != max(n["depth"] for n in nodes):
        fail("max depth %d, but the deepest node printed is at %d" % (stats["max depth"], max(n["depth"] for n in nodes)))
    inner = sum(area(n["box"]) for n in nodes if n["kind"] == "inner")
    leaf = sum(area(n["box"]) * len(n["elements"]) for n in nodes if n["kind"] == "leaf")
    inner_slack = 0.0005 + sum(area_slack(n["box"]) for n in nodes if n["kind"] == "inner")
    leaf_slack = 0.0005 + sum(area_slack(n["box"]) * len(n["elements"]) for n in nodes if n["kind"] == "leaf")
    if abs(inner - stats["inner node area"]) > inner_slack or abs(leaf - stats["leaf node area"]) > leaf_slack:
        fail("areas %.3f / %.3f, the printed nodes' %.4f / %.4f" % (stats["inner node area"], stats["leaf node area"], inner, leaf))

    if len(sys.argv) == 7:
        with open(sys.argv[6]) as f:
            picture = f.read().splitlines()
        box_colours = []
        shape_colours = {}
        for line in picture:
            m = re.match(r'^<polygon points="[^"]*" style="fill:#([0-9a-f]{6});fill-opacity:0\.25;stroke:#([0-9a-f]{6});stroke-width:1" />$', line)
            if m:
                if m.group(1) != m.group(2):
                    fail("a box filled #%s but stroked #%s" % (m.group(1), m.group(2)))
                box_colours.append(m.group(1))
                continue
            m = re.match(r'^<(circle|polygon) .* style="fill:#([0-9a-f]{6})" />$', line)
            if m:
                shape_colours[m.group(2)] = shape_colours.get(m.group(2), 0) + 1
        if len(box_colours) != len(nodes):
            fail("the picture draws %d boxes for %d nodes" % (len(box_colours), len(nodes)))
        rgb = [None] * len(nodes)
        rgb[0] = (128, 128, 128)
        expected_shapes = {}
        for i, node in enumerate(nodes):
            for c, child in enumerate(node["children"]):
                rgb[child] = PRIMARY[c] if i == 0 else blend(rgb[i], PRIMARY[c])
            colour = "%02x%02x%02x" % rgb[i]
            if box_colours[i] != colour:
                fail("node of line %d drawn #%s, not #%s" % (node["line"], box_colours[i], colour))
            if node["kind"] == "leaf":
                expected_shapes[colour] = expected_shapes.get(colour, 0) + len(node["elements"])
            siblings = [rgb[c] for c in node["children"]]
            if len(set(siblings)) != len(siblings):
                fail("node of line %d: two children of the same colour" % node["line"])
        if shape_colours != expected_shapes:
            fail("the shapes' colours are not their leaves' (%d colours drawn, %d leaves' colours)" %
                 (len(shape_colours), len(expected_shapes)))
    print("ok")


main()
