#!/usr/bin/env python3
"""Lists every decision whose MC/DC coverage is below 100 %, with its source line and
the conditions whose independence pair was not shown, from `llvm-cov show --show-mcdc`
output on stdin. Used to keep docs/verification.md's list of gaps honest."""
import re
import sys

src = {}
out = []
cur = None
region = None
conds = {}
for line in sys.stdin:
    line = line.rstrip("\n")
    if line.startswith("/") and line.endswith(":"):
        cur = line[:-1]
        continue
    m = re.match(r"\s*(\d+)\|\s*[\d.kM]*\|(.*)$", line)
    if m:
        src[(cur, int(m.group(1)))] = m.group(2)
        continue
    m = re.search(r"MC/DC Decision Region \((\d+):(\d+)\) to \((\d+):(\d+)\)", line)
    if m:
        region = (cur, int(m.group(1)))
        conds = {}
        continue
    m = re.search(r"Condition (C\d+) --> \((\d+):(\d+)\)", line)
    if m:
        conds[m.group(1)] = (int(m.group(2)), int(m.group(3)))
        continue
    m = re.search(r"(C\d+)-Pair: not covered", line)
    if m and region:
        out.append((region, m.group(1), conds.get(m.group(1))))
for (f, ln), c, pos in out:
    text = src.get((f, pos[0] if pos else ln), "").strip() if pos else ""
    col = pos[1] if pos else 0
    line_text = src.get((f, pos[0]), "") if pos else ""
    snippet = line_text[col - 1: col + 45].strip() if line_text else ""
    print(f"{(f or 'file').split('/')[-1]}:{ln} {c} at {pos[0] if pos else '?'}:{col}  `{snippet}`")
