"""What the bench scripts share: where things are, running a tool, naming the machine."""
import os
import platform
import subprocess

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
BIN = os.path.join(ROOT, "build", "bin")
OUT = os.path.join(ROOT, "build", "bench")


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
