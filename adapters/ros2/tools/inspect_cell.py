#!/usr/bin/env python3
"""A look at SafeState's ROS 2 adapter from another shell, as `ros2 topic list|echo` and
`ros2 service call` would give it (PyPI has no ros2cli for Jazzy): a small rclpy node of its own.
Run it with the adapter's venv (docs/ros2.md "Try it"):

  .venv-ros2/bin/python adapters/ros2/tools/inspect_cell.py topics        # topics and services
  .venv-ros2/bin/python adapters/ros2/tools/inspect_cell.py echo [-n 3]   # ~/safety_state
  .venv-ros2/bin/python adapters/ros2/tools/inspect_cell.py diagnostics   # one DiagnosticArray
  .venv-ros2/bin/python adapters/ros2/tools/inspect_cell.py events        # ~/events as they come
  .venv-ros2/bin/python adapters/ros2/tools/inspect_cell.py call start    # ~/start (or servo_on, ...)

--domain N (default ROS_DOMAIN_ID, else 0) and --namespace NS as the adapter was given them.
Discovery on this host only (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) unless the environment says otherwise.
"""

import argparse
import os
import sys
import time

LEVELS = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}
COMMANDS = ("servo_on", "servo_off", "start", "pause", "resume", "stop", "brake_test")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=("topics", "echo", "diagnostics", "events", "call"))
    ap.add_argument("command", nargs="?", choices=COMMANDS, help="for call: the service")
    ap.add_argument("--domain", type=int, default=int(os.environ.get("ROS_DOMAIN_ID") or 0))
    ap.add_argument("--namespace", default="")
    ap.add_argument("-n", "--count", type=int, default=1, help="echo/events: messages to show (0: until Ctrl-C)")
    ap.add_argument("--timeout", type=float, default=10.0)
    a = ap.parse_args()
    if a.what == "call" and a.command is None:
        ap.error(f"call needs a command: {', '.join(COMMANDS)}")
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

    import rclpy  # noqa: PLC0415 - after the environment is set
    from diagnostic_msgs.msg import DiagnosticArray  # noqa: PLC0415
    from rclpy.executors import ExternalShutdownException  # noqa: PLC0415
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: PLC0415
    from std_srvs.srv import Trigger  # noqa: PLC0415

    from safestate_msgs.msg import Event, SafetyState  # noqa: PLC0415

    ns = ("/" + a.namespace.strip("/")) if a.namespace.strip("/") else ""
    base = f"{ns}/safestate"
    rclpy.init(domain_id=a.domain)
    node = rclpy.create_node("safestate_inspect")
    deadline = time.monotonic() + a.timeout
    try:
        if a.what == "topics":
            # Discovery takes a moment: wait until the adapter's publisher (with its QoS) is known.
            while time.monotonic() < deadline and not node.get_publishers_info_by_topic(f"{base}/safety_state"):
                rclpy.spin_once(node, timeout_sec=0.1)
            rclpy.spin_once(node, timeout_sec=0.3)  # and the rest of its endpoints
            for name, types in sorted(node.get_topic_names_and_types()):
                pubs = node.get_publishers_info_by_topic(name)
                qos = ""
                if pubs:
                    q = pubs[0].qos_profile
                    qos = f"  [{q.reliability.name.lower()}, {q.durability.name.lower()}]"
                print(f"topic    {name}  {', '.join(types)}{qos}")
            for name, types in sorted(node.get_service_names_and_types()):
                if name.startswith(base + "/") and not name.rsplit("/", 1)[1].endswith("parameters") \
                        and "parameter" not in name:
                    print(f"service  {name}  {', '.join(types)}")
            return 0
        if a.what == "call":
            c = node.create_client(Trigger, f"{base}/{a.command}")
            if not c.wait_for_service(timeout_sec=a.timeout):
                print(f"{base}/{a.command}: not offered (is `safestate run --ros2` running on domain {a.domain}?)",
                      file=sys.stderr)
                return 1
            fut = c.call_async(Trigger.Request())
            rclpy.spin_until_future_complete(node, fut, timeout_sec=a.timeout)
            if not fut.done():
                print(f"{base}/{a.command}: no answer", file=sys.stderr)
                return 1
            r = fut.result()
            print(f"{base}/{a.command}: success={r.success} message={r.message}")
            return 0 if r.success else 3
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        got = []
        if a.what == "echo":
            node.create_subscription(SafetyState, f"{base}/safety_state", got.append, latched)
        elif a.what == "events":
            node.create_subscription(Event, f"{base}/events", got.append, QoSProfile(
                depth=1000, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE))
            deadline = float("inf")
        else:
            node.create_subscription(DiagnosticArray, f"{ns}/diagnostics", got.append, 10)
        shown = 0
        while a.count == 0 or shown < a.count:
            rclpy.spin_once(node, timeout_sec=0.1)
            while got and (a.count == 0 or shown < a.count):
                show(got.pop(0))
                shown += 1
            if not shown and time.monotonic() > deadline:
                print(f"nothing on {base} within {a.timeout} s (domain {a.domain})", file=sys.stderr)
                return 1
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):  # Ctrl-C, or SIGTERM through rclpy's handler
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def show(m):
    kind = type(m).__name__
    if kind == "SafetyState":
        print(f"known: {m.known}\nstate: {m.state}\nsub: {m.sub}\nmode: {m.mode}\nstop: {m.stop}\n"
              f"alarms: {list(m.alarms)}\ncause: {m.cause}\nowner: {m.owner}\n"
              f"contactor/drives/brakes: {m.contactor}/{m.drives}/{m.brakes}\nreset_needed: {m.reset_needed}\n"
              f"reduced: {m.reduced} {list(m.reduced_by)}\nspeed_scaling: {m.speed_scaling:g}\n"
              f"speed_limit_mm_s: {m.speed_limit_mm_s:g}\ntcp_speed_mm_s: {m.tcp_speed_mm_s:g}\n"
              f"config: {m.config_checksum} validated={m.config_validated}\ncycle: {m.cycle}\n---")
    elif kind == "Event":
        print(f"{m.id} {m.time} {m.kind} {m.data}")
    else:
        for s in m.status:
            lv = s.level[0] if isinstance(s.level, (bytes, bytearray)) else int(s.level)
            print(f"{LEVELS.get(lv, lv):5} {s.name}: {s.message}")
            for kv in s.values:
                print(f"        {kv.key}: {kv.value}")
        print("---")


if __name__ == "__main__":
    sys.exit(main())
