#!/usr/bin/env python3
"""code-size.py — the largest files and functions of lensmap's non-test Rust code.

Usage:  tools/scripts/code-size.py [--most N] [--check] [DIR ...]
        (default DIRs: engine baker tools, which holds engine/capi)

How it counts:
- Files: every `.rs` under the DIRs except those under a `tests/` or `benches/` folder, a
  `tests.rs` file, or a `build.rs`. Of each, the lines that are not blank, not comments (`//`,
  `///`, `//!`) and not inside a `#[cfg(test)]` item (a `mod tests { … }` block or a single test
  helper), counted by matching braces.
- Functions: every `fn` item outside `#[cfg(test)]` code, from its `fn` line to its closing brace,
  counting every line in between (blank and comment lines included, as a reader sees it).

`--check` exits 1 when a file has more than 900 counted lines or a function more than 150 (the
limits the codebase keeps), printing each offender.
"""
import os
import re
import sys

FILE_LIMIT = 900
FUNCTION_LIMIT = 150


def strip_strings(line):
    """The line with string and char literals emptied, so braces inside them do not count."""
    line = re.sub(r'r#*"[^"]*"#*', '""', line)
    line = re.sub(r'"(\\.|[^"\\])*"', '""', line)
    line = re.sub(r"'(\\.|[^'\\])'", "''", line)
    return line


def code_part(line):
    """The line without a trailing `//` comment (after literals were emptied)."""
    stripped = strip_strings(line)
    index = stripped.find("//")
    return stripped if index < 0 else stripped[:index]


def analyse(path):
    """(counted lines, [(function name, first line, length)]) of one file."""
    with open(path, encoding="utf-8") as f:
        lines = f.read().split("\n")
    counted = 0
    functions = []
    depth = 0
    test_until = None  # depth at which the current #[cfg(test)] item ends
    pending_test = False
    open_functions = []  # (name, start line, depth before its body)
    in_block_comment = False
    in_raw_string = False
    for number, raw in enumerate(lines, start=1):
        text = raw.strip()
        if in_raw_string:
            if '"#' in raw or (raw.rstrip().endswith('"') and "r\"" not in raw):
                in_raw_string = False
            if test_until is None:
                counted += 1
            continue
        if in_block_comment:
            if "*/" in text:
                in_block_comment = False
            continue
        if text.startswith("/*"):
            in_block_comment = "*/" not in text
            continue
        code = code_part(raw)
        if re.search(r'r#+"', raw) and not re.search(r'"#+', raw.split('r#', 1)[1][1:]):
            in_raw_string = True
        is_test = test_until is not None or pending_test
        if text.startswith("#[cfg(test)]") or text.startswith("#[cfg(all(test"):
            pending_test = True
            is_test = True
        if not is_test and text and not text.startswith("//"):
            counted += 1
        match = re.search(r"\bfn\s+([A-Za-z_][A-Za-z0-9_]*)", code)
        if match and not is_test:
            open_functions.append((match.group(1), number, depth))
        opens, closes = code.count("{"), code.count("}")
        if pending_test and test_until is None and (opens > 0 or code.rstrip().endswith(";")):
            if opens > closes:
                test_until = depth
            pending_test = False
        depth += opens - closes
        if test_until is not None and depth <= test_until:
            test_until = None
        while open_functions and depth <= open_functions[-1][2] and (opens or closes or code.rstrip().endswith(";")):
            name, start, _ = open_functions.pop()
            if number > start or "{" in code:
                functions.append((name, start, number - start + 1))
    return counted, functions


def rust_files(root):
    for folder, dirs, names in os.walk(root):
        dirs[:] = [d for d in dirs if d not in ("tests", "benches", "target", "golden")]
        for name in names:
            if name.endswith(".rs") and name not in ("tests.rs", "build.rs"):
                yield os.path.join(folder, name)


def main(argv):
    most, check, roots = 5, False, []
    args = iter(argv)
    for arg in args:
        if arg == "--most":
            most = int(next(args))
        elif arg == "--check":
            check = True
        else:
            roots.append(arg)
    roots = roots or ["engine", "baker", "tools"]
    files, functions = [], []
    for root in roots:
        for path in sorted(rust_files(root)):
            counted, found = analyse(path)
            files.append((counted, path))
            functions.extend((length, f"{path}:{start}", name) for name, start, length in found)
    files.sort(reverse=True)
    functions.sort(reverse=True)
    print(f"largest files (non-test code lines), of {len(files)}:")
    for counted, path in files[:most]:
        print(f"  {counted:5}  {path}")
    print(f"longest functions (lines, non-test), of {len(functions)}:")
    for length, place, name in functions[:most]:
        print(f"  {length:5}  {place}  {name}")
    if check:
        bad = [f"file {p}: {c} lines > {FILE_LIMIT}" for c, p in files if c > FILE_LIMIT]
        bad += [f"fn {n} at {p}: {l} lines > {FUNCTION_LIMIT}" for l, p, n in functions if l > FUNCTION_LIMIT]
        for line in bad:
            print(f"OVER: {line}")
        return 1 if bad else 0
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
