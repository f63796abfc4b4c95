#!/usr/bin/env python3
"""tests/browser_check.py — checks a browser's screenshot of a --visualize picture.

    browser_check.py SCREENSHOT.png TREE.txt

TREE.txt is bvh.out's --print_tree output for the same picture. The check
passes (exit 0) when the screenshot shows
  1. the black frame, whole: the dark pixels' bounding rectangle has a dark
     line along each of its four sides (a clipped or missing frame fails), and
  2. the root's three children in red, green and blue: inside the part of
     each child's box (depth-1 lines of TREE.txt, mapped through the frame)
     that no sibling box covers, pixels of the expected pure hue outnumber
     those of the other two hues, and there are enough of them.
Otherwise it prints what is wrong and exits 1.

The PNG reader is written here (zlib and struct only): 8-bit RGB or RGBA,
non-interlaced, every scanline filter, which is what Chromium writes.
"""
import re
import struct
import sys
import zlib


def read_png(path):
    """Returns (width, height, rows) with rows[y] a bytes of R,G,B triples."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG file")
    pos, idat, header = 8, [], None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
    if header is None:
        raise ValueError(f"{path}: no IHDR chunk")
    width, height, depth, color_type, _, _, interlace = header
    if depth != 8 or color_type not in (2, 6) or interlace != 0:
        raise ValueError(f"{path}: unsupported PNG (depth {depth}, colour type {color_type}, interlace {interlace})")
    channels = 3 if color_type == 2 else 4
    raw = zlib.decompress(b"".join(idat))
    stride = width * channels
    rows, prev = [], bytearray(stride)
    for y in range(height):
        start = y * (stride + 1)
        filt = raw[start]
        line = bytearray(raw[start + 1:start + 1 + stride])
        if filt == 1:
            for i in range(channels, stride):
                line[i] = (line[i] + line[i - channels]) & 255
        elif filt == 2:
            for i in range(stride):
                line[i] = (line[i] + prev[i]) & 255
        elif filt == 3:
            for i in range(stride):
                left = line[i - channels] if i >= channels else 0
                line[i] = (line[i] + ((left + prev[i]) >> 1)) & 255
        elif filt == 4:
            for i in range(stride):
                a = line[i - channels] if i >= channels else 0
                b = prev[i]
                c = prev[i - channels] if i >= channels else 0
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pred) & 255
        elif filt != 0:
            raise ValueError(f"{path}: bad filter {filt} on row {y}")
        prev = line
        if channels == 4:
            line = bytearray(b for i, b in enumerate(line) if i % 4 != 3)
        rows.append(bytes(line))
    return width, height, rows


def is_dark(r, g, b):
    return r < 60 and g < 60 and b < 60


# A pixel "shows" a primary when that channel is bright and both others are
# near zero: the shapes of a root child's first leaf (pure #ff0000, #00ff00,
# #0000ff) pass; the blended colours of other leaves (e.g. #a85400) and the
# translucent box fills over white (each layer keeps 75% of the white below,
# so four layers still leave 80 in the other channels) do not.
def hue(r, g, b):
    for name, (c, o1, o2) in (("red", (r, g, b)), ("green", (g, r, b)), ("blue", (b, r, g))):
        if c >= 200 and o1 <= 60 and o2 <= 60:
            return name
    return None


def frame_rectangle(width, height, rows):
    """The dark pixels' bounding rectangle, after checking each side is a line."""
    xs, ys = [], []
    for y in range(height):
        row = rows[y]
        for x in range(width):
            if is_dark(row[3 * x], row[3 * x + 1], row[3 * x + 2]):
                xs.append(x)
                ys.append(y)
    if not xs:
        return None, "no dark pixels at all: the frame is missing"
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    if x1 - x0 < 100 or y1 - y0 < 100:
        return None, f"the dark pixels span only {x1 - x0 + 1} x {y1 - y0 + 1}: no frame"

    def dark_fraction(points):
        points = list(points)
        hits = sum(1 for x, y in points if is_dark(*rows[y][3 * x:3 * x + 3]))
        return hits / len(points)

    # Each side: the darkest of the three outermost lines (the stroke is 3
    # units wide, scaled by the browser) must be dark along 95% of its length.
    sides = {
        "top": [dark_fraction((x, y) for x in range(x0, x1 + 1)) for y in range(y0, min(y0 + 3, y1))],
        "bottom": [dark_fraction((x, y) for x in range(x0, x1 + 1)) for y in range(max(y1 - 2, y0), y1 + 1)],
        "left": [dark_fraction((x, y) for y in range(y0, y1 + 1)) for x in range(x0, min(x0 + 3, x1))],
        "right": [dark_fraction((x, y) for y in range(y0, y1 + 1)) for x in range(max(x1 - 2, x0), x1 + 1)],
    }
    for side, fractions in sides.items():
        if max(fractions) < 0.95:
            return None, f"the frame's {side} side is not a whole line ({max(fractions):.0%} dark): clipped or missing"
    return (x0, y0, x1, y1), None


def root_children(tree_path):
    """Boxes [(xmin, ymin, xmax, ymax)] of the depth-1 nodes, in order."""
    boxes = []
    number = r"\s*(-?[0-9.]+)"
    pattern = re.compile(r"^   (?:inner|leaf) area=\S+ \[<" + number + number + r"> <" + number + number + r">\]")
    with open(tree_path) as f:
        for line in f:
            m = pattern.match(line)
            if m:
                boxes.append(tuple(float(v) for v in m.groups()))
    return boxes


def main():
    if len(sys.argv) != 3:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    width, height, rows = read_png(sys.argv[1])
    frame, why = frame_rectangle(width, height, rows)
    if frame is None:
        print(f"FAIL: {why}")
        return 1
    x0, y0, x1, y1 = frame
    print(f"frame: pixels {x0}..{x1} x {y0}..{y1} of a {width} x {height} screenshot")
    boxes = root_children(sys.argv[2])
    if len(boxes) != 3:
        print(f"FAIL: {sys.argv[2]} lists {len(boxes)} children of the root, not 3")
        return 1
    # The frame's outer edge is at canvas -0.5 and 999.5 (rect at 1..999,
    # stroke 3 wide): map canvas units to pixels through it.
    sx = (x1 - x0 + 1) / 1000.0
    sy = (y1 - y0 + 1) / 1000.0
    failures = 0
    for k, (name, box) in enumerate(zip(("red", "green", "blue"), boxes)):
        others = [b for j, b in enumerate(boxes) if j != k]
        counts = {"red": 0, "green": 0, "blue": 0}
        px0, px1 = int(x0 + (box[0] + 0.5) * sx) + 2, int(x0 + (box[2] + 0.5) * sx) - 2
        py0, py1 = int(y0 + (box[1] + 0.5) * sy) + 2, int(y0 + (box[3] + 0.5) * sy) - 2
        for py in range(max(py0, 0), min(py1, height - 1) + 1):
            cy = (py - y0) / sy - 0.5
            row = rows[py]
            for px in range(max(px0, 0), min(px1, width - 1) + 1):
                cx = (px - x0) / sx - 0.5
                if any(b[0] - 2 <= cx <= b[2] + 2 and b[1] - 2 <= cy <= b[3] + 2 for b in others):
                    continue  # a sibling's box covers it too
                h = hue(row[3 * px], row[3 * px + 1], row[3 * px + 2])
                if h:
                    counts[h] += 1
        area = max(1, (px1 - px0) * (py1 - py0))
        enough = max(50, area // 200)  # at least 0.5% of the box
        ok = counts[name] >= enough and all(counts[name] > c for h, c in counts.items() if h != name)
        print(f"child {k} {box}: expected {name}; pure-hue pixels {counts} (need >= {enough}): "
              f"{'ok' if ok else 'FAIL'}")
        failures += not ok
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
