#!/usr/bin/env python3
"""tests/readme_quotes.py README EXAMPLE.cpp... — every snippet that README
quotes from an example is still the example's code.

In an example, the lines between `// [readme:NAME]` and `// [end]` are a
snippet; README must contain the same lines, in order, one after another
(leading and trailing blanks of each line and blank lines aside). Prints
`ok readme_quotes_FILE_NAME` or `FAIL readme_quotes_FILE_NAME why` per
snippet (read by tests/run.sh); an example without snippets is a FAIL too.
"""
import os
import re
import sys


def lines_of(text):
    return [line.strip() for line in text.splitlines() if line.strip()]


def snippets(path):
    found, name, body = [], None, []
    for number, line in enumerate(open(path, encoding="utf-8"), 1):
        m = re.match(r"\s*// \[readme:(\w+)\]\s*$", line)
        if m:
            if name is not None:
                raise ValueError("%s:%d: snippet %s not ended" % (path, number, name))
            name, body = m.group(1), []
        elif re.match(r"\s*// \[end\]\s*$", line):
            if name is None:
                raise ValueError("%s:%d: [end] without [readme:NAME]" % (path, number))
            found.append((name, lines_of("".join(body))))
            name = None
        elif name is not None:
            body.append(line)
    if name is not None:
        raise ValueError("%s: snippet %s not ended" % (path, name))
    return found


def contains(haystack, needle):
    return any(haystack[i:i + len(needle)] == needle for i in range(len(haystack) - len(needle) + 1))


def main():
    readme = lines_of(open(sys.argv[1], encoding="utf-8").read())
    for path in sys.argv[2:]:
        base = os.path.splitext(os.path.basename(path))[0]
        try:
            found = snippets(path)
        except ValueError as e:
            print("FAIL readme_quotes_%s %s" % (base, e))
            continue
        if not found:
            print("FAIL readme_quotes_%s no // [readme:NAME] snippet in %s" % (base, path))
        for name, body in found:
            case = "readme_quotes_%s_%s" % (base, name)
            if not body:
                print("FAIL %s empty snippet" % case)
            elif contains(readme, body):
                print("ok %s" % case)
            else:
                print("FAIL %s README does not quote %s's snippet %s: first line %r" % (case, path, name, body[0]))


main()
