"""What the bench scripts share: where things are, running a tool, naming the machine."""
import os
import platform
import subprocess
import sys

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


def in_namespace(prefix, script, args):
    """Runs `script --inside ARGS...` in a network namespace of its own (`prefix`-PID) with a veth
    pair ecm/ecs, all links up, and removes the namespace afterwards; its exit code. Needs root."""
    ns = f"{prefix}-{os.getpid()}"
    subprocess.run(["ip", "netns", "add", ns], check=True)
    try:
        subprocess.run(["ip", "-n", ns, "link", "add", "ecm", "type", "veth", "peer", "name", "ecs"], check=True)
        for dev in ("ecm", "ecs", "lo"):
            subprocess.run(["ip", "-n", ns, "link", "set", dev, "up"], check=True)
        return subprocess.run(["ip", "netns", "exec", ns, sys.executable, os.path.abspath(script), "--inside",
                               *args]).returncode
    finally:
        subprocess.run(["ip", "netns", "del", ns], check=False)
