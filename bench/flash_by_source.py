#!/usr/bin/env python3
"""Where an image's code comes from: the bytes of each instruction counted at the source
line it was compiled from (code inlined into a caller counted where it was written, which
a symbol's size cannot say), summed by crate and by file.

    llvm-objdump -d -l --no-show-raw-insn ELF | bench/flash_by_source.py ROOT [FILES]

ROOT: the checkout's directory (taken off its files' paths); FILES: how many of the
largest files to list (default 12). Used by bench/footprint.sh.
"""

import re
import sys
from collections import Counter

INSN = re.compile(r"^\s+([0-9a-f]+):\s")
SYMBOL = re.compile(r"^[0-9a-f]+ <.*>:$")
LINE = re.compile(r"^; (.+):\d+$")
# The standard library's sources, by the compiler's commit.
STD = re.compile(r"^/rustc/[0-9a-f]+/library/")
# A crates.io crate's sources: .../registry/src/INDEX/NAME-VERSION/...
REGISTRY = re.compile(r"^.*/registry/src/[^/]+/([^/]+?)-\d+\.\d+\.\d+[^/]*/(.*)$")


def place(path, root):
    """(crate, file) of a source path, without the machine's directories."""
    m = STD.match(path)
    if m:
        rest = path[m.end():]
        return rest.split("/", 1)[0], rest
    m = REGISTRY.match(path)
    if m:
        return m.group(1), m.group(1) + "/" + m.group(2)
    if path.startswith(root):
        rest = path[len(root):]
        if rest.startswith("node-fw/boards/"):
            board = rest.split("/")[2]
            return "board " + board, rest
        return rest.split("/", 1)[0], rest
    if path == "?":
        return "(no line)", "(no line)"
    return "(elsewhere)", "(elsewhere)"


def main():
    root = sys.argv[1].rstrip("/") + "/"
    files_shown = int(sys.argv[2]) if len(sys.argv) > 2 else 12
    at = []  # (address, source path) of every instruction, in address order
    source = "?"
    for line in sys.stdin:
        line = line.rstrip("\n")
        if SYMBOL.match(line):
            source = "?"
            continue
        m = LINE.match(line)
        if m:
            source = m.group(1)
            continue
        m = INSN.match(line)
        if m:
            at.append((int(m.group(1), 16), source))
    crates, files = Counter(), Counter()
    for (addr, path), (after, _) in zip(at, at[1:]):
        size = after - addr
        # A gap (alignment, data between functions) is no instruction's.
        if not 0 < size <= 4:
            continue
        crate, file = place(path, root)
        crates[crate] += size
        files[file] += size
    total = sum(crates.values())
    print(f"  by crate ({total} bytes of instructions)")
    for crate, size in crates.most_common():
        if size * 100 < total:
            rest = sum(s for c, s in crates.items() if s * 100 < total)
            print(f"  {rest:7d}  {100 * rest / total:4.1f} %  the others (under 1 % each)")
            break
        print(f"  {size:7d}  {100 * size / total:4.1f} %  {crate}")
    print(f"  the {files_shown} largest files")
    for file, size in files.most_common(files_shown):
        print(f"  {size:7d}  {100 * size / total:4.1f} %  {file}")


if __name__ == "__main__":
    main()
