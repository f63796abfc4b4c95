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


def add_bytes(x, y):
    """Bytewise (x + y) mod 256 of two equal-length byte strings, all bytes at
    once: each byte's low seven bits add without carrying out of the byte,
    and the top bit is the sum's top bit, x's xor y's xor that carry."""
    n = len(x)
    top = int.from_bytes(b"\x80" * n, "big")
    low = top >> 7 | top >> 6 | top >> 5 | top >> 4 | top >> 3 | top >> 2 | top >> 1
    a, b = int.from_bytes(x, "big"), int.from_bytes(y, "big")
    return bytearray((((a & low) + (b & low)) ^ ((a ^ b) & top)).to_bytes(n, "big"))


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
            line = add_bytes(line, prev)
        elif filt == 3:
            for i in range(stride):
                left = line[i - channels] if i >= channels else 0
                line[i] = (line[i] + ((left + prev[i]) >> 1)) & 255
        elif filt == 4:
            # Paeth: the nearest of a (left), b (up), c (up-left) to
            # p = a + b - c, in that order on ties; |p - a| = |b - c|,
            # |p - b| = |a - c|, |p - c| = |a + b - 2c|. (The first pixel's
            # a and c are 0: its predictor is b.)
            for i in range(channels):
                line[i] = (line[i] + prev[i]) & 255
            for i in range(channels, stride):
                a = line[i - channels]
                b = prev[i]
                c = prev[i - channels]
                pa = b - c if b >= c else c - b
                pb = a - c if a >= c else c - a
                pc = a + b - c - c
                if pc < 0:
                    pc = -pc
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else (b if pb <= pc else c))) & 255
        elif filt != 0:
            raise ValueError(f"{path}: bad filter {filt} on row {y}")
        prev = line
        if channels == 4:
            rgb = bytearray(width * 3)
            for k in range(3):
                rgb[k::3] = line[k::4]
            line = rgb
        rows.append(bytes(line))
    return width, height, rows


def table(passes):
    """A translate() table: byte 1 where a channel value passes, else 0."""
    return bytes(1 if passes(v) else 0 for v in range(256))


DARK = table(lambda v: v < 60)
BRIGHT = table(lambda v: v >= 200)
FAINT = table(lambda v: v <= 60)


def mask(row, x0, x1, tables):
    """An int with one byte per pixel x0..x1 of row (the first pixel most
    significant): 1 where its red, green and blue values pass tables[0],
    tables[1] and tables[2], else 0."""
    m = -1
    for channel, t in enumerate(tables):
        m &= int.from_bytes(row[3 * x0 + channel:3 * x1 + 3:3].translate(t), "big")
    return m


# A pixel is dark when all three channels are below 60.
def dark_pixels(row, width):
    """bytes: 1 for each dark pixel of the row, else 0."""
    return mask(row, 0, width - 1, (DARK, DARK, DARK)).to_bytes(width, "big")


# A pixel "shows" a primary when that channel is bright and both others are
# near zero: the shapes of a root child's first leaf (pure #ff0000, #00ff00,
# #0000ff) pass; the blended colours of other leaves (e.g. #a85400) and the
# translucent box fills over white (each layer keeps 75% of the white below,
# so four layers still leave 80 in the other channels) do not.
HUES = (("red", (BRIGHT, FAINT, FAINT)), ("green", (FAINT, BRIGHT, FAINT)), ("blue", (FAINT, FAINT, BRIGHT)))


def frame_rectangle(width, height, rows):
    """The dark pixels' bounding rectangle, after checking each side is a line."""
    dark = [dark_pixels(row, width) for row in rows]
    lit = [y for y in range(height) if 1 in dark[y]]
    if not lit:
        return None, "no dark pixels at all: the frame is missing"
    x0 = min(dark[y].find(1) for y in lit)
    x1 = max(dark[y].rfind(1) for y in lit)
    y0, y1 = lit[0], lit[-1]
    if x1 - x0 < 100 or y1 - y0 < 100:
        return None, f"the dark pixels span only {x1 - x0 + 1} x {y1 - y0 + 1}: no frame"

    def row_fraction(y):
        return dark[y].count(1, x0, x1 + 1) / (x1 - x0 + 1)

    def column_fraction(x):
        return sum(dark[y][x] for y in range(y0, y1 + 1)) / (y1 - y0 + 1)

    # Each side: the darkest of the three outermost lines (the stroke is 3
    # units wide, scaled by the browser) must be dark along 95% of its length.
    sides = {
        "top": [row_fraction(y) for y in range(y0, min(y0 + 3, y1))],
        "bottom": [row_fraction(y) for y in range(max(y1 - 2, y0), y1 + 1)],
        "left": [column_fraction(x) for x in range(x0, min(x0 + 3, x1))],
        "right": [column_fraction(x) for x in range(max(x1 - 2, x0), x1 + 1)],
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
    # (Pixel px is at canvas x (px - x0) / sx - 0.5, which grows with px: the
    # columns a box covers are one range.)
    def columns(lo, hi):
        inside = [px for px in range(width) if lo <= (px - x0) / sx - 0.5 <= hi]
        return (inside[0], inside[-1]) if inside else None

    for k, (name, box) in enumerate(zip(("red", "green", "blue"), boxes)):
        others = [(b, columns(b[0] - 2, b[2] + 2)) for j, b in enumerate(boxes) if j != k]
        counts = {"red": 0, "green": 0, "blue": 0}
        px0, px1 = int(x0 + (box[0] + 0.5) * sx) + 2, int(x0 + (box[2] + 0.5) * sx) - 2
        py0, py1 = int(y0 + (box[1] + 0.5) * sy) + 2, int(y0 + (box[3] + 0.5) * sy) - 2
        for py in range(max(py0, 0), min(py1, height - 1) + 1):
            cy = (py - y0) / sy - 0.5
            row = rows[py]
            # The row's columns in the box, less those a sibling's box covers too.
            covered = sorted(c for b, c in others if c and b[1] - 2 <= cy <= b[3] + 2)
            start = max(px0, 0)
            for lo, hi in covered + [(min(px1, width - 1) + 1, width)]:
                end = min(lo, min(px1, width - 1) + 1)
                if end > start:
                    for h, tables in HUES:
                        counts[h] += bin(mask(row, start, end - 1, tables)).count("1")
                start = max(start, hi + 1)
        area = max(1, (px1 - px0) * (py1 - py0))
        enough = max(50, area // 200)  # at least 0.5% of the box
        ok = counts[name] >= enough and all(counts[name] > c for h, c in counts.items() if h != name)
        print(f"child {k} {box}: expected {name}; pure-hue pixels {counts} (need >= {enough}): "
              f"{'ok' if ok else 'FAIL'}")
        failures += not ok
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
