#!/usr/bin/env python3
"""tests/readme_quotes.py DOC... -- EXAMPLE.cpp... — every snippet that the
documentation quotes from an example is still the example's code.

In an example, the lines between `// [readme:NAME]` and `// [end]` are a
snippet; one of the documents (README.txt, docs/*.txt) must contain the same
lines, in order, one after another (leading and trailing blanks of each line
and blank lines aside). The documents are the arguments before `--`, the
examples those after it; without `--` the first argument is the only
document (`tests/readme_quotes.py README.txt examples/*.cpp`). Prints
`ok readme_quotes_FILE_NAME` or `FAIL readme_quotes_FILE_NAME why` per
snippet (read by tests/run.sh); an example without snippets, and a document
that cannot be read, is a FAIL too.
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
    args = sys.argv[1:]
    if "--" in args:
        split = args.index("--")
        doc_paths, example_paths = args[:split], args[split + 1:]
    else:
        doc_paths, example_paths = args[:1], args[1:]
    if not doc_paths or not example_paths:
        sys.exit("usage: readme_quotes.py DOC... -- EXAMPLE.cpp...  (or README EXAMPLE.cpp...)")
    docs = []  # (path, its lines); a snippet must lie within one document
    for path in doc_paths:
        try:
            docs.append((path, lines_of(open(path, encoding="utf-8").read())))
        except OSError as e:
            print("FAIL readme_quotes_document_%s cannot read %s: %s"
                  % (re.sub(r"\W", "_", path), path, e.strerror))
    names = ", ".join(path for path, _ in docs) or "no document"
    for path in example_paths:
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
            elif any(contains(lines, body) for _, lines in docs):
                print("ok %s" % case)
            else:
                print("FAIL %s none of %s quotes %s's snippet %s as it is: first line %r"
                      % (case, names, path, name, body[0]))


main()
