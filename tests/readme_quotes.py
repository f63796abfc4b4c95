#!/usr/bin/env python3
"""Every region of examples/*.cpp marked `// [name]` ... `// [end]` must
appear in README.txt verbatim, dedented, then indented by two spaces: a snippet shown to
users is then always code that make test compiles and runs. Exits 1 and
names the region when one is missing or differs."""
import glob
import re
import sys
import textwrap

readme = open("README.txt", encoding="utf-8").read()
regions = 0
missing = []
for path in sorted(glob.glob("examples/*.cpp")):
    text = open(path, encoding="utf-8").read()
    for m in re.finditer(r"^[ \t]*// \[([a-z0-9-]+)\]\n(.*?)^[ \t]*// \[end\]\n", text, re.S | re.M):
        if m.group(1) == "end":
            continue
        regions += 1
        quoted = "".join("  " + line if line.strip() else line for line in textwrap.dedent(m.group(2)).splitlines(True))
        if quoted not in readme:
            missing.append(f"{path} [{m.group(1)}]")
if regions == 0:
    sys.exit("no quoted regions found in examples/*.cpp")
for name in missing:
    print(f"README.txt does not quote {name} as it stands in the file")
print(f"{regions - len(missing)} of {regions} example regions quoted in README.txt")
sys.exit(1 if missing else 0)
