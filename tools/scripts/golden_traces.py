#!/usr/bin/env python3
"""Every scenario of the repository replays to the trace it gave before a refactoring.

`safestate replay --trace` of each tests/scenarios/**/*.scn and examples/*.scn, compared
byte for byte with tests/golden/traces.jsonl.gz (one JSON object per scenario: its path and
its trace lines). A change of behaviour shows as the first differing line of the first
scenario that moved. The golden file was written by the build of the commit named in it;
`--update` writes it again (only when a change of behaviour is intended: say why in the
commit).

`--ignore-speed` compares everything but the measured `tcp_speed` (a state line whose only
change was the speed's tenth drops out): a change of arm model that moves a speed by float
rounding must still leave every state, output, alarm, reply and their cycles as they were.

usage: golden_traces.py --bin build/bin/safestate [--update] [--ignore-speed] [--jobs N]
"""
import argparse
import concurrent.futures
import gzip
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
GOLDEN = os.path.join(ROOT, "tests", "golden", "traces.jsonl.gz")


def scenarios():
    out = []
    for base in ("tests/scenarios", "examples"):
        for d, _, files in os.walk(os.path.join(ROOT, base)):
            if os.path.relpath(d, ROOT).startswith(os.path.join("tests", "scenarios", "ur5")):
                continue  # replayed on another arm (--robot), by their own tests
            out += [os.path.relpath(os.path.join(d, f), ROOT) for f in files if f.endswith(".scn")]
    return sorted(out)


def trace(binary, rel):
    p = subprocess.run([binary, "replay", "--trace", rel], cwd=ROOT, capture_output=True, timeout=600)
    return p.stdout.decode("utf-8", "replace").splitlines()


def without_speed(lines):
    """The trace with tcp_speed removed and the lines that then repeat the previous state dropped."""
    out, last = [], None
    for line in lines:
        try:
            j = json.loads(line)
        except ValueError:
            out.append(line)
            continue
        if "state" in j:
            j.pop("tcp_speed", None)
            key = json.dumps({k: v for k, v in j.items() if k != "t"}, sort_keys=True)
            if key == last:
                continue
            last = key
        out.append(json.dumps(j, sort_keys=True))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", required=True)
    ap.add_argument("--update", action="store_true")
    ap.add_argument("--commit", default="", help="with --update: the commit whose build wrote it")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--ignore-speed", action="store_true", help="compare all but tcp_speed (see above)")
    a = ap.parse_args()
    binary = os.path.abspath(a.bin)
    files = scenarios()
    with concurrent.futures.ThreadPoolExecutor(a.jobs) as ex:
        traces = dict(zip(files, ex.map(lambda f: trace(binary, f), files)))
    if a.update:
        with gzip.open(GOLDEN, "wt", encoding="utf-8", compresslevel=9) as g:
            g.write(json.dumps({"written_by": a.commit, "scenarios": len(files)}) + "\n")
            for f in files:
                g.write(json.dumps({"file": f, "trace": traces[f]}) + "\n")
        print(f"golden_traces: wrote {len(files)} traces to {os.path.relpath(GOLDEN, ROOT)}")
        return 0
    with gzip.open(GOLDEN, "rt", encoding="utf-8") as g:
        head = json.loads(g.readline())
        golden = {o["file"]: o["trace"] for o in map(json.loads, g)}
    bad = 0
    for f in files:
        if f not in golden:
            continue  # a scenario added after the golden file: its own test judges it
        want, got = golden[f], traces[f]
        if a.ignore_speed:
            want, got = without_speed(want), without_speed(got)
        if want != got:
            bad += 1
            n = next((i for i, (x, y) in enumerate(zip(want, got)) if x != y), min(len(want), len(got)))
            print(f"{f}: trace differs at line {n + 1} ({len(want)} lines before, {len(got)} now)")
            print(f"  before: {want[n] if n < len(want) else '(end)'}")
            print(f"  now:    {got[n] if n < len(got) else '(end)'}")
    missing = sorted(set(golden) - set(files))
    for f in missing:
        print(f"{f}: in the golden file but no longer in the repository")
    compared = sum(1 for f in files if f in golden)
    if bad or missing:
        print(f"golden_traces: {bad} of {compared} traces differ from those of {head.get('written_by') or 'the golden build'}")
        return 1
    if compared == 0:
        print("golden_traces: nothing compared")
        return 1
    print(f"golden_traces: {compared} traces unchanged since {head.get('written_by') or 'the golden build'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
