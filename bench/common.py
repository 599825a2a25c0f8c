"""What the bench scripts share: where things are, running a tool, naming the machine."""
import argparse
import os
import platform
import subprocess
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
BIN = os.path.join(ROOT, "build", "bin")
OUT = os.path.join(ROOT, "build", "bench")

# The namespace with its veth pair, set up as the EtherCAT tests set it up (one helper for both).
sys.path.insert(0, os.path.join(ROOT, "tests", "integration"))
from veth_ns import veth_namespace  # noqa: E402


def run(cmd, **kw):
    """Runs `cmd` in the repository, echoing it; its stdout (fails on a non-zero exit)."""
    print("bench: " + " ".join(cmd), flush=True)
    return subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True, cwd=ROOT, **kw).stdout


def cpu_model():
    for line in open("/proc/cpuinfo"):
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return "?"


def machine():
    """The CPU, its core count and the kernel, as the documents state them."""
    return f"{cpu_model()}, {os.cpu_count()} cores, Linux {platform.release()}"


def in_namespace(prefix, script, args):
    """Runs `script --inside ARGS...` in a network namespace of its own (`prefix`-ID) with a veth
    pair ecm/ecs, all links up, and removes the namespace afterwards; its exit code. Needs root."""
    with veth_namespace(prefix) as ns:
        return subprocess.run(["ip", "netns", "exec", ns, sys.executable, os.path.abspath(script), "--inside",
                               *args]).returncode


def namespace_bench(doc, prog, prefix, script, count, default, top, inside):
    """The command line of an EtherCAT bench: --bin, --COUNT (1..top), --json; run as root it
    re-runs itself (--inside) in a namespace of its own (in_namespace), where `inside(args)`
    measures. Its exit code."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("--bin", default=os.environ.get("SAFESTATE_BIN", "build/bin/safestate"))
    ap.add_argument(f"--{count}", type=int, default=default)
    ap.add_argument("--json", help="write the figures to this file")
    ap.add_argument("--inside", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    a.bin = os.path.abspath(a.bin)
    n = getattr(a, count)
    if not 1 <= n <= top:
        ap.error(f"--{count} must be 1..{top}")
    if a.inside:
        return inside(a)
    if os.geteuid() != 0:
        raise SystemExit(f"{prog}: needs root (network namespace, raw sockets)")
    args = ["--bin", a.bin, f"--{count}", str(n)] + (["--json", os.path.abspath(a.json)] if a.json else [])
    return in_namespace(prefix, script, args)


def write_section(doc, title, sec):
    """Replaces (or adds, as put_section) the section `title` of the document at `doc` by `sec`."""
    text = open(doc).read() if os.path.exists(doc) else ""
    with open(doc, "w") as f:
        f.write(put_section(text, title, sec))


def put_section(text, title, sec):
    """`text` (a Markdown document) with its section `title` replaced by `sec`, or `sec` added
    before "## Footprint" (at the end when there is none). One rule for every bench that
    writes its own section of docs/performance.md."""
    start = text.find(title + "\n")
    if start >= 0:
        end = text.find("\n## ", start + len(title))
        return text[:start] + sec + (text[end + 1:] if end >= 0 else "")
    if "## Footprint\n" in text:
        return text.replace("## Footprint\n", sec + "## Footprint\n", 1)
    return text + "\n" + sec
