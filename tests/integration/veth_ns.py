"""A network namespace of its own with a veth pair for the EtherCAT tests: the master on `ecm`,
`safestate ecat-sim` on `ecs`, both and `lo` up; removed again on exit. Needs root."""
import subprocess
import uuid
from contextlib import contextmanager


@contextmanager
def veth_namespace(prefix):
    name = f"{prefix}-{uuid.uuid4().hex[:8]}"
    subprocess.run(["ip", "netns", "add", name], check=True)
    try:
        subprocess.run(["ip", "-n", name, "link", "add", "ecm", "type", "veth", "peer", "name", "ecs"], check=True)
        for dev in ("ecm", "ecs", "lo"):
            subprocess.run(["ip", "-n", name, "link", "set", dev, "up"], check=True)
        yield name
    finally:
        subprocess.run(["ip", "netns", "del", name], check=False)
