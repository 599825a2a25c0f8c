"""A user's rclpy node, in its own process (the test's or the bench's), as robot software would
run one: it subscribes to what SafeState's ROS 2 adapter publishes and calls its services
(docs/ros2.md). Used by test_ros2.py and bench/ros2_latency.py; runs in the adapter's venv
(.venv-ros2, `make ros2`), which has rclpy, safestate_msgs, websockets and pytest.

Every message is recorded with the monotonic time it arrived; waits scan what arrived.
"""

import os
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ROS2_DIR = ROOT / "adapters" / "ros2"
ROS2_PY = ROOT / ".venv-ros2" / "bin" / "python"


def dds_domain():
    """A DDS domain for this process's cell: from the pid, so that parallel runs on one machine
    do not hear each other (1..100: Linux's ephemeral ports start above domain 101's)."""
    return 1 + os.getpid() % 100


def user_environment():
    """This host only, as the adapter's default (ROS_AUTOMATIC_DISCOVERY_RANGE, Jazzy)."""
    return {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}


class RosUser:
    def __init__(self, domain, namespace="", name="test_user"):
        import rclpy  # noqa: PLC0415 - only in the ROS 2 venv
        from diagnostic_msgs.msg import DiagnosticArray  # noqa: PLC0415
        from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: PLC0415
        from sensor_msgs.msg import JointState  # noqa: PLC0415
        from std_msgs.msg import Float64  # noqa: PLC0415
        from std_srvs.srv import Trigger  # noqa: PLC0415

        from safestate_msgs.msg import Event, SafetyState  # noqa: PLC0415

        os.environ.update(user_environment())
        self.rclpy = rclpy
        self.Trigger = Trigger
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node(name, context=self.context)
        self.base = (namespace.rstrip("/") if namespace else "") + "/safestate"
        self.ns = namespace.rstrip("/") if namespace else ""
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        events_qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.VOLATILE)
        self.lock = threading.Lock()
        self.got = {"state": [], "diag": [], "joints": [], "scaling": [], "events": []}
        subs = (("state", SafetyState, f"{self.base}/safety_state", latched),
                ("scaling", Float64, f"{self.base}/speed_scaling", latched),
                ("events", Event, f"{self.base}/events", events_qos),
                ("diag", DiagnosticArray, f"{self.ns}/diagnostics", 10),
                ("joints", JointState, f"{self.ns}/joint_states", 10))
        for key, typ, topic, qos in subs:
            self.node.create_subscription(typ, topic, self._recorder(key), qos)
        self.clients = {}
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _recorder(self, key):
        def record(msg):
            with self.lock:
                self.got[key].append((time.monotonic(), msg))
        return record

    def _spin(self):
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def close(self):
        self._stop.set()
        self._thread.join(timeout=5)
        self.executor.shutdown(timeout_sec=1)
        self.node.destroy_node()
        self.rclpy.shutdown(context=self.context)

    # ------------------------------------------------------------------ reading
    def mark(self, key):
        with self.lock:
            return len(self.got[key])

    def wait(self, key, pred, timeout, since=0, what=None):
        """(arrival time, message) of the first message of `key` from index `since` that
        satisfies pred, else AssertionError naming what was awaited and what came last."""
        deadline = time.monotonic() + timeout
        i = since
        while True:
            with self.lock:
                items = self.got[key][i:]
            for t, m in items:
                i += 1
                if pred(m):
                    return t, m
            if time.monotonic() > deadline:
                with self.lock:
                    last = self.got[key][-1][1] if self.got[key] else None
                raise AssertionError(f"timeout ({timeout} s) waiting for {what or key}; last {key}: {last}")
            time.sleep(0.01)

    def state(self, pred, timeout=10.0, since=0, what="a safety state"):
        return self.wait("state", pred, timeout, since, what)[1]

    def latest(self, key):
        with self.lock:
            return self.got[key][-1][1] if self.got[key] else None

    def events(self):
        with self.lock:
            return [m for _, m in self.got["events"]]

    # ------------------------------------------------------------------ calling
    def call(self, cmd, timeout=10.0):
        """The std_srvs/Trigger response of ~/cmd."""
        c = self.clients.get(cmd)
        if c is None:
            c = self.clients[cmd] = self.node.create_client(self.Trigger, f"{self.base}/{cmd}")
        assert c.wait_for_service(timeout_sec=timeout), f"{self.base}/{cmd} not offered"
        fut = c.call_async(self.Trigger.Request())
        deadline = time.monotonic() + timeout
        while not fut.done():
            assert time.monotonic() < deadline, f"no answer from {self.base}/{cmd}"
            time.sleep(0.01)
        return fut.result()

    def names_and_types(self):
        return dict(self.node.get_topic_names_and_types())

    def services(self):
        return dict(self.node.get_service_names_and_types())


def diag_status(msg, function):
    """The DiagnosticStatus named `safestate: FUNCTION` in a DiagnosticArray, or None."""
    for s in msg.status:
        if s.name == f"safestate: {function}":
            return s
    return None


def level(status):
    """A DiagnosticStatus' level as an int (0 OK, 1 WARN, 2 ERROR, 3 STALE)."""
    return status.level[0] if isinstance(status.level, (bytes, bytearray)) else int(status.level)
