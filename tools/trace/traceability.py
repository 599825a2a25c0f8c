#!/usr/bin/env python3
"""Requirement -> code -> tests, generated from the sources (issue 6, item 7).

Requirements: the ids in tools/trace/requirements.txt, plus one per transition row, read
from the `id` column of kTransitions. Code: every `@req ID` in a comment of the product's
sources (a transition row is its own code). Tests: `@req ID` in a comment just above a
GoogleTest TEST/TEST_F/TEST_P or a pytest `def test_`, or anywhere in a .scn scenario or an
integration script (the whole file is then the test).

  traceability.py            write docs/traceability.md
  traceability.py --check    fail if docs/traceability.md is stale

Exits 1, naming each problem, when a requirement has no test or no code, when a tag names
an id that does not exist, or when the committed document is stale with --check.
"""
import argparse
import os
import re
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
CATALOGUE = "tools/trace/requirements.txt"
TABLE = "core/include/safestate/core/transitions.hpp"
OUT = "docs/traceability.md"
CODE_DIRS = ["core", "motion", "controller", "hal", "sim", "scenario", "app", "runtime", "bridge", "gateway", "rta",
             "tools/check", "tools/reference"]
CODE_EXT = (".cpp", ".hpp", ".h")
ID = r"[A-Z][A-Z0-9]*(?:-[A-Za-z0-9]+)+"
TAG = re.compile(r"@req((?:[ ,]+" + ID + r")+)")


def rel(p):
    return os.path.relpath(p, ROOT)


def ids_in(line):
    m = TAG.search(line)
    return re.findall(ID, m.group(1)) if m else []


def catalogue():
    reqs, section = [], ""
    with open(os.path.join(ROOT, CATALOGUE)) as f:
        for n, line in enumerate(f, 1):
            line = line.rstrip("\n")
            if line.startswith("## "):
                section = line[3:].strip()
            elif line.strip() and not line.startswith("#"):
                m = re.match(r"^(" + ID + r")\s+(.+)$", line)
                if not m:
                    sys.exit(f"{CATALOGUE}:{n}: expected `ID  text`, found: {line}")
                reqs.append({"id": m.group(1), "section": section, "text": m.group(2).strip(), "code": [], "tests": []})
    return reqs


def table_rows():
    """The rows of kTransitions with their line numbers; their count must match the array's."""
    with open(os.path.join(ROOT, TABLE)) as f:
        lines = f.read().split("\n")
    size = None
    rows = []
    for line in lines:
        m = re.search(r"std::array<Transition, (\d+)>", line)
        if m:
            size = int(m.group(1))
        m = re.match(r'^  \{(k\w+|only\(\w+\)),\s+(\w+),\s+(\w+),\s+(\w+),\s+(\w+),.*"([\w-]+)",\s+"(' + ID + r')"\},?\s*$', line)
        if m:
            frm, trig, guard, to, stop, rule, rid = m.groups()
            rows.append({"id": rid, "section": "§4 Transitions (table rows)",
                         "text": f"{frm} + {trig} [{guard}] -> {to} ({stop}), rule {rule}",
                         "code": [f"{TABLE}#kTransitions[{len(rows)}]"], "tests": []})
    if size is None or len(rows) != size:
        sys.exit(f"{TABLE}: read {len(rows)} rows with an id, the table has {size}: a row lost its id or its layout")
    return rows


def walk(dirs, exts):
    for d in dirs:
        for base, _, files in os.walk(os.path.join(ROOT, d)):
            if "/build" in base or "node_modules" in base:
                continue
            for fn in sorted(files):
                if fn.endswith(exts):
                    yield os.path.join(base, fn)


def code_tags():
    out = []
    for p in walk(CODE_DIRS, CODE_EXT):
        with open(p, errors="replace") as f:
            for n, line in enumerate(f, 1):
                for i in ids_in(line):
                    out.append((i, rel(p)))  # the file, not the line: the document stays stable
    return out


def tags_above(path, comment, test_re, name_of, skip, what, out, problems):
    """Tags in the comment lines directly above a test definition (lines starting with one
    of `skip`, such as decorators, may stand between); a tag followed by anything else is a problem."""
    pending = []
    with open(path) as f:
        for n, line in enumerate(f, 1):
            s = line.strip()
            if s.startswith(comment):
                pending += ids_in(s)
                continue
            if skip and s.startswith(skip):
                continue
            m = re.match(test_re, s)
            if m:
                out += [(i, name_of(m)) for i in pending]
            elif pending:
                problems.append(f"{rel(path)}:{n}: @req tag not followed by {what}")
            pending = []


def tags_anywhere(path, name, out):
    """Tags in any comment line: the whole file is the test."""
    with open(path) as f:
        out += [(i, name) for line in f if line.lstrip().startswith("#") for i in ids_in(line)]


def test_tags(problems):
    out = []
    for p in walk(["tests/unit"], (".cpp",)):
        tags_above(p, "//", r"^TEST(?:_F|_P)?\((\w+),\s*(\w+)\)", lambda m: f"{m.group(1)}.{m.group(2)}", (),
                   "a TEST", out, problems)
    for p in walk(["tests/integration"], (".py",)):
        tags_above(p, "#", r"^(?:async )?def (test_\w+)", lambda m: f"gateway/{m.group(1)}", ("@",),
                   "a test function", out, problems)
    for p in walk(["tests/scenarios"], (".scn",)):
        tags_anywhere(p, "scenario/" + os.path.relpath(p, os.path.join(ROOT, "tests", "scenarios")), out)
    for p in walk(["tests/integration"], (".sh",)):
        tags_anywhere(p, os.path.splitext(os.path.basename(p))[0], out)
    return out


def link(where):
    path, _, anchor = where.partition("#")
    return f"[`{anchor or os.path.basename(path)}`](../{path})"


def render(reqs):
    total = len(reqs)
    tested = sum(1 for r in reqs if r["tests"])
    lines = ["<!-- Generated by tools/trace/traceability.py from the sources; do not edit. -->", "",
             "# Traceability: requirement → code → tests", "",
             "Every requirement of SPEC.md has a stable id. Transition rows carry theirs in the `id` column of",
             "`kTransitions`; the others are listed in `tools/trace/requirements.txt`. Code names what it implements",
             "with `@req ID` in a comment, and so does every test (above a `TEST`, a pytest function, or in a `.scn`",
             "file). `make test` runs `traceability --check`, which fails when a requirement has no test or no code,",
             "when a tag names an unknown id, or when this file is stale.", "",
             f"**{total} requirements, {tested} with tests, "
             f"{sum(len(r['tests']) for r in reqs)} test links, {sum(len(r['code']) for r in reqs)} code links.**", ""]
    section = None
    for r in reqs:
        if r["section"] != section:
            section = r["section"]
            lines += ["", f"## {section}", "", "| id | requirement | code | tests |", "|---|---|---|---|"]
        code = "<br>".join(link(c) for c in r["code"])
        tests = ", ".join(f"`{t}`" for t in r["tests"])
        text = r["text"].replace("|", "\\|")
        lines.append(f"| {r['id']} | {text} | {code} | {tests} |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="fail if docs/traceability.md is stale")
    ap.add_argument("--root", help="the repository to read (default: this one; the self-test uses a copy)")
    a = ap.parse_args()
    if a.root:
        global ROOT
        ROOT = os.path.abspath(a.root)
    problems = []
    rows = table_rows()
    cat = catalogue()
    first4 = next(k for k, r in enumerate(cat) if r["section"].startswith("§4"))
    reqs = cat[:first4] + rows + cat[first4:]  # in the order of SPEC.md
    by_id = {}
    for r in reqs:
        if r["id"] in by_id:
            problems.append(f"requirement id {r['id']} is defined twice")
        by_id[r["id"]] = r
    for i, where in code_tags():
        if i not in by_id:
            problems.append(f"{where}: @req names unknown requirement {i}")
        elif where not in by_id[i]["code"]:
            by_id[i]["code"].append(where)
    for i, test in test_tags(problems):
        if i not in by_id:
            problems.append(f"test {test}: @req names unknown requirement {i}")
        elif test not in by_id[i]["tests"]:
            by_id[i]["tests"].append(test)
    for r in reqs:
        if not r["tests"]:
            problems.append(f"requirement {r['id']} has no test ({r['text'][:70]})")
        if not r["code"]:
            problems.append(f"requirement {r['id']} has no code tagged `@req {r['id']}`")
    text = render(reqs)
    path = os.path.join(ROOT, OUT)
    if a.check:
        old = open(path).read() if os.path.exists(path) else ""
        if old != text:
            problems.append(f"{OUT} is stale: run `make docs` (or tools/trace/traceability.py) and commit it")
    elif not problems:
        with open(path, "w") as f:
            f.write(text)
    for p in problems:
        print(f"traceability: {p}", file=sys.stderr)
    if problems:
        sys.exit(1)
    print(f"traceability: {len(reqs)} requirements, all with code and tests" + ("" if a.check else f"; wrote {OUT}"))


if __name__ == "__main__":
    main()
