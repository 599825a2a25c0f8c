"""The ROS 2 node `safestate` (docs/ros2.md): what SafeState's gateway says, in ROS 2 terms.

Threads: rclpy's executor runs the services and a 10 Hz timer; the gateway client runs in an
asyncio loop of its own thread and calls back into this node, which publishes from there (rclpy's
publishers may be used from any thread). One lock orders what both threads publish.
"""

import asyncio
import json
import os
import signal
import sys
import threading
import time

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.exceptions import NameValidationException, ParameterException
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from safestate_msgs.msg import Event, SafetyState

from . import __version__, config, mapping
from .gateway import REPLY_TIMEOUT_S, Gateway

# The remote role's commands (SPEC §4, protocol.md "Roles"): AUTO only. No reset (a deliberate
# act at the cell, ISO 13849-1 manual reset) and no jog (it needs the pendant's enabling device).
COMMANDS = ("servo_on", "servo_off", "start", "pause", "resume", "stop", "brake_test")
CORE_STALE_MS = 300.0  # the core's cycle counter unchanged this long (as the gateway sees it): gone
STATUS_SILENCE_S = 0.6  # no status this long (50 Hz expected): unknown, checked every 0.1 s (<= 0.7 s)
REPUBLISH_S = 1.0  # state topics and diagnostics at least this often (diagnostics: the ROS convention)

# QoS a ROS 2 user expects (docs/ros2.md "Topics"): state topics latched, the stream reliable.
STATE_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL)
EVENTS_QOS = QoSProfile(depth=1000, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
STREAM_QOS = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)


def _read_only(description):
    return ParameterDescriptor(description=description, read_only=True)


class SafeStateNode(Node):
    def __init__(self, domain_id, namespace, localhost_only, cmdline=()):
        """cmdline: the names of the parameters given with -p on the command line."""
        super().__init__("safestate", namespace=namespace or None)
        self.declare_parameter("domain_id", domain_id, _read_only("the DDS domain (set at start: -p domain_id:=N)"))
        self.declare_parameter("namespace", namespace, _read_only("the node's namespace (set at start)"))
        self.declare_parameter("localhost_only", localhost_only,
                               _read_only("DDS on this host only (loopback; docs/ros2.md Security)"))
        gw = self.declare_parameter("gateway", "127.0.0.1:8080", _read_only("the SafeState gateway, HOST:PORT"))
        token_file = self.declare_parameter("remote_token_file", "",
                                            _read_only("file holding the gateway's remote token "
                                                       "(else env SAFESTATE_REMOTE_TOKEN)"))
        cycle_us = self.declare_parameter("cycle_us", 1000, _read_only("the core's scan cycle in us (velocities)"))
        after = self.declare_parameter("events_after", -1,
                                       _read_only("publish events after this id; -1: from the start of the adapter"))
        # A parameter this node does not have (a typo: `gatway:=...`) would be ignored by ROS and
        # the node would run on the default: refused instead, naming it and the known ones.
        unknown = sorted(set(self._parameter_overrides) - set(self._parameters))
        if unknown:
            raise config.ConfigError(f"unknown parameter{'s' if len(unknown) > 1 else ''} {', '.join(unknown)} "
                                     f"(known: {', '.join(sorted(set(self._parameters) - {'use_sim_time'}))})")
        # domain_id, namespace and localhost_only take effect before the node exists (config.py):
        # from a params file they would show here and not be in force.
        for name in config.EARLY_PARAMETERS:
            if name in self._parameter_overrides and name not in cmdline:
                raise config.ConfigError(f"{name}: give it on the command line (--ros-args -p {name}:=...), "
                                         "not in a params file: it is needed before the node is created")
        host, port = config.gateway_address(gw.value)
        if not isinstance(cycle_us.value, int) or not 50 <= cycle_us.value <= 100000:
            raise config.ConfigError(f"cycle_us: {cycle_us.value!r} out of range 50..100000")
        if not isinstance(after.value, int) or after.value < -1:
            raise config.ConfigError(f"events_after: {after.value!r} must be -1 or an event id")
        self.cycle_us = cycle_us.value
        token = config.read_token(token_file.value, os.environ)

        self.gw = Gateway(host, port, token, f"safestate-ros2 {__version__}", self.get_logger(),
                          events_after=None if after.value < 0 else after.value)
        self.gw.on_status = self._on_status
        self.gw.on_events = self._on_events
        self.gw.on_down = self._on_down
        self.gw.on_robot = self._on_robot
        self.gw.on_safety = self._on_safety
        self.gw.on_alarms = self._on_alarms

        self.pub_joints = self.create_publisher(JointState, "joint_states", STREAM_QOS)
        self.pub_diag = self.create_publisher(DiagnosticArray, "diagnostics", STREAM_QOS)
        self.pub_state = self.create_publisher(SafetyState, "~/safety_state", STATE_QOS)
        self.pub_scaling = self.create_publisher(Float64, "~/speed_scaling", STATE_QOS)
        self.pub_events = self.create_publisher(Event, "~/events", EVENTS_QOS)
        group = ReentrantCallbackGroup()
        for cmd in COMMANDS:
            self.create_service(Trigger, f"~/{cmd}", self._service(cmd), callback_group=group)

        self._lock = threading.RLock()
        self._status = None  # the latest status while known, else None
        self._prev = None
        self._why = "not connected to the gateway yet"
        self._received = 0.0
        self._robot = None
        self._described = False  # /api/robot asked (joint_states wait for it: one set of names)
        self._names = list(mapping.DEFAULT_JOINT_NAMES)
        self._status_names = None
        self._normal = None
        self._alarm_info = {}
        self._last_state = None
        self._last_scaling = None
        self._last_diag = None
        self._published_at = 0.0
        self.loop = None
        self.create_timer(0.1, self._tick)
        self._publish_all(force=True)

    # ------------------------------------------------------------------ the gateway's thread
    def start_gateway(self):
        ready = threading.Event()

        def run():
            self.loop = asyncio.new_event_loop()
            asyncio.set_event_loop(self.loop)
            ready.set()
            self.loop.run_until_complete(self.gw.run())

        self._thread = threading.Thread(target=run, name="gateway", daemon=True)
        self._thread.start()
        ready.wait()

    def stop_gateway(self):
        if self.loop is not None:
            fut = asyncio.run_coroutine_threadsafe(self.gw.stop(), self.loop)
            try:
                fut.result(timeout=2)
            except Exception:  # noqa: BLE001 - best effort on the way out
                pass
            self._thread.join(timeout=3)

    def _on_status(self, s):
        with self._lock:
            age = mapping._num(s.get("core_heartbeat_age_ms"))
            if age is not None and age > CORE_STALE_MS:
                self._set_unknown(f"the core has not cycled for {age:.0f} ms (gateway up)")
                return
            self._prev, self._status = self._status, s
            self._received = time.monotonic()
            self._why = ""
            if s.get("joint_names") != self._status_names:
                self._status_names = s.get("joint_names")
                self._names = mapping.joint_names(self._robot, s)
            if self._described:
                self._publish_joints(s)
            self._publish_all()

    def _on_down(self, why):
        with self._lock:
            self._set_unknown(f"gateway: {why}")

    def _on_events(self, events):
        with self._lock:
            for e in events:
                m = Event()
                m.id = e["id"]
                m.cycle = max(0, e["t"])
                m.time = e["time"]
                m.kind = e["kind"]
                m.data = json.dumps(e.get("data"), separators=(",", ":"))
                self.pub_events.publish(m)

    def _on_robot(self, robot):
        """The robot description (GET /api/robot), or None when the gateway serves none."""
        with self._lock:
            if robot is not None or not self._described:
                self._robot = robot
                self._names = mapping.joint_names(robot, self._status)
            self._described = True

    def _on_safety(self, cfg):
        with self._lock:
            self._normal = mapping.normal_speed_limit(cfg)

    def _on_alarms(self, rows):
        with self._lock:
            self._alarm_info = {r["name"]: r for r in rows if isinstance(r, dict) and isinstance(r.get("name"), str)}
            self._publish_all()

    # ------------------------------------------------------------------ publishing
    def _set_unknown(self, why):
        self._status, self._prev = None, None
        self._why = why
        self._publish_all()

    def _normal_limit(self, s):
        if self._normal is not None:
            return self._normal
        # Without GET /api/safety: the limit in force while reduced mode is off is the normal one.
        safety = s.get("safety") if isinstance(s.get("safety"), dict) else {}
        if safety.get("reduced") is False:
            v = mapping._num(safety.get("speed_limit"))
            if v is not None and v > 0:
                self._normal = v
        return self._normal

    def _publish_joints(self, s):
        q = mapping.joint_positions(s)
        if q is None:
            return
        m = JointState()
        m.header.stamp = self.get_clock().now().to_msg()
        m.name = list(self._names)
        m.position = q
        v = mapping.joint_velocities(self._prev, s, self.cycle_us)
        if v is not None:
            m.velocity = v
        self.pub_joints.publish(m)

    def _publish_all(self, force=False):
        """Publishes what changed (and everything once a second): the state topics at once on a
        change, so that an E-stop reaches a subscriber with the status that shows it."""
        with self._lock:
            now = time.monotonic()
            due = force or now - self._published_at >= REPUBLISH_S
            s = self._status
            scaling = mapping.speed_scaling(s, self._normal_limit(s)) if s is not None else 0.0
            state = mapping.safety_state(s, scaling)
            diag = mapping.diagnostics(s, self._alarm_info) if s is not None else mapping.stale_diagnostics(self._why)
            state_key = {k: v for k, v in state.items() if k not in ("cycle", "tcp_speed_mm_s")}
            if due or state_key != self._last_state:
                self._last_state = state_key
                self.pub_state.publish(self._state_msg(state))
            if due or scaling != self._last_scaling:
                self._last_scaling = scaling
                self.pub_scaling.publish(Float64(data=scaling))
            summary = mapping.diagnostics_summary(diag)
            if due or summary != self._last_diag:
                self._last_diag = summary
                self.pub_diag.publish(self._diag_msg(diag))
            if due:
                self._published_at = now

    def _state_msg(self, st):
        m = SafetyState()
        m.header.stamp = self.get_clock().now().to_msg()
        for k, v in st.items():
            setattr(m, k, v)
        return m

    def _diag_msg(self, entries):
        m = DiagnosticArray()
        m.header.stamp = self.get_clock().now().to_msg()
        for e in entries:
            d = DiagnosticStatus()
            d.level = bytes([e["level"]])
            d.name = e["name"]
            d.message = e["message"]
            d.hardware_id = e["hardware_id"]
            d.values = [KeyValue(key=k, value=v) for k, v in e["values"]]
            m.status.append(d)
        return m

    def _tick(self):
        with self._lock:
            # A status older than the silence limit is unknown (the gateway hangs, or its thread here).
            if self._status is not None and time.monotonic() - self._received > STATUS_SILENCE_S:
                self._set_unknown(f"no status from the gateway for {STATUS_SILENCE_S:g} s")
            self._publish_all()

    # ------------------------------------------------------------------ services
    def _service(self, cmd):
        def call(request, response):
            del request
            if self.loop is None:
                result = "GATEWAY_UNAVAILABLE"
            else:
                fut = asyncio.run_coroutine_threadsafe(self.gw.command(cmd), self.loop)
                try:
                    result = fut.result(timeout=REPLY_TIMEOUT_S + 2.0)
                except Exception:  # noqa: BLE001 - a lost loop is an unavailable gateway
                    result = "GATEWAY_UNAVAILABLE"
            response.success = result == "OK"
            response.message = result
            self.get_logger().info(f"~/{cmd}: {result}")
            return response
        return call

    def shutdown_state(self):
        """The last word before the node goes: the state is unknown from now on."""
        with self._lock:
            self._set_unknown("the adapter stopped")


def main(argv=None):
    argv = list(sys.argv if argv is None else argv)
    try:
        domain, ns, localhost = config.early_settings(argv, os.environ)
    except config.ConfigError as e:
        print(f"safestate-ros2: {e}", file=sys.stderr)
        return config.EXIT_CONFIG
    env = config.dds_environment(os.environ, localhost)
    for k in set(os.environ) - set(env):
        del os.environ[k]
    os.environ.update(env)
    rclpy.init(args=argv, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    try:
        node = SafeStateNode(domain, ns, localhost, cmdline=set(config.ros_params(argv)))
    except (config.ConfigError, ParameterException, NameValidationException) as e:
        # A parameter of the wrong type (cycle_us:=fast), or a remapped name that is no ROS name.
        print(f"safestate-ros2: {e}", file=sys.stderr)
        rclpy.shutdown()
        return config.EXIT_CONFIG
    node.get_logger().info(
        f"domain {domain}, namespace '{ns or '/'}', DDS {'on this host only' if localhost else 'on the network'}; "
        f"gateway {node.gw.url}")
    if not localhost:
        node.get_logger().warning("localhost_only is false: DDS has no authentication here, anyone on the "
                                  "network who reaches this domain may call ~/start (docs/ros2.md Security)")
    node.start_gateway()
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    try:
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    finally:
        node.shutdown_state()
        node.stop_gateway()
        time.sleep(0.1)  # the last state on its way to current subscribers
        executor.shutdown(timeout_sec=1)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0

