"""From the gateway's messages (protocol.md) to what the ROS 2 adapter publishes: pure functions
on plain data, no rclpy, so that adapters/ros2/tests can check each one on its own.

Everything here reads input from another process and treats it as untrusted: a field that is
missing or of the wrong type reads as unknown, never as a value the robot did not report.
"""

import math
import re
import xml.etree.ElementTree as ET

UNKNOWN = "UNKNOWN"

# diagnostic_msgs/DiagnosticStatus levels (bytes in the message).
OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR", STALE: "STALE"}

T1_LIMIT_MM_S = 250.0  # SPEC §4 rule 3, ISO 10218-1: T1 speed of the TCP and every link origin

STATES = ("BOOT", "ERROR_LOCKOUT", "ESTOP_ACTIVE", "ESTOP_RESET_NEEDED", "IDLE", "ARMING", "OPERATIONAL",
          "STOPPING")


def _str(v, default=""):
    return v if isinstance(v, str) else default


def _num(v):
    """A finite number, or None (JSON null, a string, NaN: unknown)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    return float(v) if math.isfinite(v) else None


def _names(v):
    return [x for x in v if isinstance(x, str)] if isinstance(v, list) else []


# ------------------------------------------------------------------------------ joint names
_ROS_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_/]*$")
DEFAULT_JOINT_NAMES = tuple(f"joint_{i}" for i in range(1, 7))


def _six_names(v):
    """v as six distinct joint names usable in sensor_msgs/JointState, else None."""
    if not isinstance(v, list) or len(v) != 6 or not all(isinstance(n, str) and _ROS_NAME.match(n) for n in v):
        return None
    return list(v) if len(set(v)) == 6 else None


def urdf_joint_names(text):
    """The six moving joints of a URDF's chain from its root link, in chain order, or None.

    The chain is followed from the one link that is no joint's child. Fixed joints are passed
    through, and a branch of fixed joints only (a `tool0` or `base` frame beside the arm, as in
    Universal Robots' descriptions) is no branch of the arm. Two branches that both move, a
    prismatic joint or a count other than six give None (the robot description is then not the
    six-axis arm this adapter reports, and names come from elsewhere)."""
    try:
        root = ET.fromstring(text)
    except (ET.ParseError, TypeError, ValueError):
        return None
    if root.tag != "robot":
        return None
    by_parent = {}
    children = set()
    for j in root.findall("joint"):
        parent, child = j.find("parent"), j.find("child")
        if parent is None or child is None or j.get("type") not in ("revolute", "continuous", "fixed", "prismatic",
                                                                     "floating", "planar"):
            return None
        p, c = parent.get("link"), child.get("link")
        if c in children:
            return None  # a link with two parents: no tree
        by_parent.setdefault(p, []).append(j)
        children.add(c)
    roots = [ln.get("name") for ln in root.findall("link") if ln.get("name") not in children]
    if len(roots) != 1:
        return None

    def moves(link, depth=0):
        """Whether any joint below link is not fixed (depth-bounded: a cycle is no tree)."""
        if depth > 200:
            return True
        return any(j.get("type") != "fixed" or moves(j.find("child").get("link"), depth + 1)
                   for j in by_parent.get(link, []))

    names, link = [], roots[0]
    for _ in range(200):
        joints = [j for j in by_parent.get(link, []) if j.get("type") != "fixed" or moves(j.find("child").get("link"))]
        if not joints:
            break
        if len(joints) != 1:
            return None  # two branches that move: not one arm
        j = joints[0]
        kind = j.get("type")
        if kind in ("revolute", "continuous"):
            names.append(j.get("name"))
        elif kind != "fixed":
            return None
        link = j.find("child").get("link")
    return _six_names(names)


def joint_names(robot=None, status=None):
    """The names of sensor_msgs/JointState, from the best source there is:
    1. the robot description the gateway serves at /api/robot (issue 38): its `joint_names`, its
       `joints[].name`, or the joints of the URDF it carries (`urdf`, or the body itself);
    2. `joint_names` in the status message;
    3. joint_1 .. joint_6 (the names of the ROS-Industrial convention for six-axis arms).
    Any source that does not give six distinct valid names is skipped."""
    candidates = []
    if isinstance(robot, dict):
        candidates.append(robot.get("joint_names"))
        joints = robot.get("joints")
        if isinstance(joints, list) and all(isinstance(j, dict) for j in joints):
            candidates.append([j.get("name") for j in joints])
        if isinstance(robot.get("urdf"), str):
            candidates.append(urdf_joint_names(robot["urdf"]))
    elif isinstance(robot, str):
        candidates.append(urdf_joint_names(robot))
    if isinstance(status, dict):
        candidates.append(status.get("joint_names"))
    for c in candidates:
        names = _six_names(c)
        if names is not None:
            return names
    return list(DEFAULT_JOINT_NAMES)


def joint_positions(status):
    """The six joint positions (rad) of a status, or None when they are not six finite numbers."""
    q = status.get("joints") if isinstance(status, dict) else None
    if not isinstance(q, list) or len(q) != 6:
        return None
    v = [_num(x) for x in q]
    return None if any(x is None for x in v) else v


def joint_velocities(prev, cur, cycle_us):
    """Joint velocities (rad/s) from two statuses' positions and the core's cycle counter
    between them (the status carries no velocities): None when there is no earlier status,
    the cycle counter did not advance, or more than a second of cycles lies between them."""
    if not isinstance(prev, dict) or not isinstance(cur, dict) or not cycle_us or cycle_us <= 0:
        return None
    q0, q1 = joint_positions(prev), joint_positions(cur)
    t0, t1 = _num(prev.get("t")), _num(cur.get("t"))
    if q0 is None or q1 is None or t0 is None or t1 is None or t1 <= t0:
        return None
    dt = (t1 - t0) * cycle_us * 1e-6
    if dt > 1.0:
        return None
    return [(b - a) / dt for a, b in zip(q0, q1)]


# ------------------------------------------------------------------------------ speed scaling
def normal_speed_limit(safety_config):
    """The configuration's normal TCP speed limit (mm/s) from GET /api/safety, or None."""
    if not isinstance(safety_config, dict):
        return None
    for obj in (safety_config.get("config"), safety_config.get("configuration"), safety_config):
        if isinstance(obj, dict):
            v = _num(obj.get("tcp_max_speed_mm_s"))
            if v is not None and v > 0:
                return v
    return None


def speed_scaling(status, normal_mm_s):
    """The fraction (0..1) of the cell's normal TCP speed that the active limits allow now:
    the limit in force (reduced mode and its ramp, SPEC §10), T1's 250 mm/s, and SSM's allowed
    speed (SPEC §11), over the configuration's normal limit. 0 when the robot may not move at
    all (any state but OPERATIONAL), and when the state is unknown."""
    if not isinstance(status, dict) or status.get("state") != "OPERATIONAL":
        return 0.0
    if normal_mm_s is None or normal_mm_s <= 0:
        return 0.0
    safety = status.get("safety") if isinstance(status.get("safety"), dict) else {}
    allowed = normal_mm_s
    for limit in (_num(safety.get("speed_limit")), _num(safety.get("v_allowed")),
                  T1_LIMIT_MM_S if status.get("mode") == "T1" else None):
        if limit is not None:
            allowed = min(allowed, max(limit, 0.0))
    return max(0.0, min(1.0, allowed / normal_mm_s))


# ------------------------------------------------------------------------------ safety state
def safety_state(status, scaling):
    """The fields of safestate_msgs/SafetyState for a status (None: unknown)."""
    if not isinstance(status, dict):
        return unknown_state()
    safety = status.get("safety") if isinstance(status.get("safety"), dict) else {}
    state = _str(status.get("state"))
    return {
        "known": state in STATES,
        "state": state if state in STATES else UNKNOWN,
        "sub": _str(status.get("sub")),
        "mode": _str(status.get("mode")),
        "stop": _str(status.get("stop")),
        "alarms": _names(status.get("alarms")),
        "cause": _str(status.get("cause")),
        "owner": _str(status.get("owner")),
        "contactor": _str(status.get("contactor")),
        "drives": _str(status.get("drives")),
        "brakes": _str(status.get("brakes")),
        "reset_needed": status.get("reset_lamp") == "on",
        "reduced": safety.get("reduced") is True,
        "reduced_by": _names(safety.get("reduced_by")),
        "speed_scaling": float(scaling),
        "speed_limit_mm_s": _num(safety.get("speed_limit")) or 0.0,
        "tcp_speed_mm_s": _num(status.get("tcp_speed")) or 0.0,
        "config_checksum": _str(safety.get("checksum")),
        "config_validated": safety.get("validated") is True,
        "cycle": int(status["t"]) if isinstance(status.get("t"), int) and status["t"] >= 0 else 0,
    }


def unknown_state():
    return {
        "known": False, "state": UNKNOWN, "sub": "", "mode": "", "stop": "", "alarms": [], "cause": "",
        "owner": "", "contactor": "", "drives": "", "brakes": "", "reset_needed": False, "reduced": False,
        "reduced_by": [], "speed_scaling": 0.0, "speed_limit_mm_s": 0.0, "tcp_speed_mm_s": 0.0,
        "config_checksum": "", "config_validated": False, "cycle": 0,
    }


# ------------------------------------------------------------------------------ diagnostics
# One DiagnosticStatus per safety function (name "safestate: <function>"), each with the alarms
# that belong to it (docs/alarms.md). An alarm this table does not know (a newer core) goes to
# "safestate: state", never nowhere.
FUNCTIONS = (
    ("E-stop", ("ESTOP_PRESSED", "ESTOP_DISCREPANCY")),
    ("guard", ("PROTECTIVE_STOP", "GATE_DISCREPANCY")),
    ("enabling device", ("ENABLE_DISCREPANCY", "ENABLING_PANIC", "JOG_LINK_LOST")),
    ("mode", ("MODE_SELECTOR_INVALID", "MODE_CHANGED")),
    ("drives", ("DRIVE_FAULT", "ARMING_TIMEOUT", "STOP_TIME_EXCEEDED", "BRAKE_NOT_ENGAGED", "CONTACTOR_WELDED",
                "ENCODER_DISCREPANCY")),
    ("fieldbus", ("FIELDBUS_LOST", "BOOT_FAILED", "SAFETY_LINK_FAULT")),
    ("safety configuration", ("CONFIG_NOT_VALIDATED", "INTEGRITY_FAULT")),
    ("safe limits", ("JOINT_LIMIT", "ZONE_VIOLATION", "ORIENTATION_LIMIT", "SPEED_LIMIT", "T1_SPEED_EXCEEDED",
                     "REDUCED_SPEED")),
    ("brake test", ("BRAKE_TEST_DUE", "BRAKE_TEST_FAILED")),
    ("collaborative operation", ("SEPARATION_VIOLATED", "PERSON_IN_FIELD", "FIELD_DISCREPANCY", "COLLISION")),
)
CHANNEL_ALARMS = ("CHANNEL_MISMATCH", "CHANNEL_LOST")
PREFIX = "safestate: "
HARDWARE_ID = "safestate"

# An alarm's level from its severity (GET /api/alarms): a lockout or a fault is an ERROR, a
# warning a WARN, information (E-stop pressed, reduced speed, a person in the outer field)
# leaves the level to the function's own rule.
_SEVERITY_LEVEL = {"lockout": ERROR, "fault": ERROR, "warning": WARN, "info": OK}


def _alarm_level(name, info):
    sev = info.get(name, {}).get("severity") if isinstance(info.get(name), dict) else None
    return _SEVERITY_LEVEL.get(sev, WARN)  # unknown severity: not OK, not invented to be an ERROR


def _alarm_values(names, info):
    """Key-values: one per alarm, its name and its words with detail (from /api/alarms)."""
    out = []
    for n in names:
        a = info.get(n) if isinstance(info.get(n), dict) else {}
        words = " ".join(x for x in (_str(a.get("detail")), _str(a.get("text"))) if x)
        sev = _str(a.get("severity"))
        out.append((f"alarm {n}", f"{sev}: {words}" if sev and words else (words or sev or "active")))
    return out


def _fmt(v):
    if v is None:
        return "none"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, (list, tuple)):
        return ", ".join(_fmt(x) for x in v) if v else "none"
    if isinstance(v, dict):
        return ", ".join(f"{k}={_fmt(x)}" for k, x in v.items())
    return str(v)


def _status(name, level, message, values):
    return {"name": PREFIX + name, "level": level, "message": message, "hardware_id": HARDWARE_ID,
            "values": [(k, _fmt(v)) for k, v in values]}


def _function_status(name, alarms, active, info, base_level, base_message, values):
    """The message is the function's active alarm in the gateway's words (the same words as the
    first-out cause when that alarm caused the stop: "E-stop channel A opened"), else the
    function's reading ("released", "mode AUTO"), which is kept as the key-value `reading`."""
    mine = [a for a in alarms if a in active]
    level = max([base_level] + [_alarm_level(a, info) for a in mine])
    message = base_message
    if mine:
        a = info.get(mine[0]) if isinstance(info.get(mine[0]), dict) else {}
        message = _str(a.get("detail")) or _str(a.get("text")) or mine[0]
    return _status(name, level, message,
                   [("reading", base_message)] + values + [("alarms", mine)] + _alarm_values(mine, info))


def diagnostics(status, alarm_info=None):
    """The DiagnosticStatus entries (dicts: name, level, message, hardware_id, values) for a
    status; alarm_info maps alarm names to GET /api/alarms rows (severity, text, detail)."""
    info = alarm_info if isinstance(alarm_info, dict) else {}
    if not isinstance(status, dict) or _str(status.get("state")) not in STATES:
        return stale_diagnostics("no status from the gateway")
    s = status
    safety = s.get("safety") if isinstance(s.get("safety"), dict) else {}
    state, sub, mode = _str(s.get("state")), _str(s.get("sub")), _str(s.get("mode"))
    active = _names(s.get("alarms"))
    cause = _str(s.get("cause"))
    known = {a for _, names in FUNCTIONS for a in names} | set(CHANNEL_ALARMS)
    out = []

    level = {"OPERATIONAL": OK, "IDLE": OK, "ARMING": OK, "BOOT": WARN, "ESTOP_RESET_NEEDED": WARN,
             "STOPPING": ERROR, "ESTOP_ACTIVE": ERROR, "ERROR_LOCKOUT": ERROR}[state]
    if state == "IDLE" and s.get("reset_lamp") == "on":
        level = WARN  # a latched alarm waits for a reset at the cell
    words = state + (f" {sub}" if sub else "")
    others = [a for a in active if a not in known]
    out.append(_function_status("state", others, active, info, level, cause or words, [
        ("state", state), ("sub", sub or None), ("mode", mode), ("stop", s.get("stop")), ("cause", cause or None),
        ("owner", s.get("owner")), ("active alarms", active), ("cycle", s.get("t"))]))

    estop_level, estop_words = OK, "released"
    if state == "ESTOP_ACTIVE":
        estop_level, estop_words = ERROR, "pressed: Cat 0 stop, power removed"
    elif state == "ESTOP_RESET_NEEDED":
        estop_level, estop_words = WARN, "released; a reset at the cell is needed"
    out.append(_function_status("E-stop", FUNCTIONS[0][1], active, info, estop_level, estop_words,
                                [("state", state)]))

    guard_level = ERROR if "PROTECTIVE_STOP" in active else OK
    out.append(_function_status("guard", FUNCTIONS[1][1], active, info, guard_level,
                                "protective stop (guard opened in AUTO)" if guard_level else "no demand",
                                [("mode", mode)]))

    out.append(_function_status("enabling device", FUNCTIONS[2][1], active, info, OK,
                                "used in T1/T2 only" if mode == "AUTO" else f"mode {mode}", [("mode", mode)]))

    mode_level = ERROR if mode in ("NONE", "") else OK
    out.append(_function_status("mode", FUNCTIONS[3][1], active, info, mode_level,
                                f"mode {mode or 'unknown'}", [("mode", mode), ("requested", s.get("mode_requested")),
                                                              ("owner", s.get("owner"))]))

    out.append(_function_status("drives", FUNCTIONS[4][1], active, info, OK,
                                f"contactor {_str(s.get('contactor'))}, drives {_str(s.get('drives'))}, "
                                f"brakes {_str(s.get('brakes'))}",
                                [("contactor", s.get("contactor")), ("drives", s.get("drives")),
                                 ("brakes", s.get("brakes")), ("axis state", s.get("axis_state"))]))

    out.append(_function_status("fieldbus", FUNCTIONS[5][1], active, info, OK, "cyclic data valid",
                                [("simulated", s.get("simulated"))]))

    validated = safety.get("validated") is True
    out.append(_function_status("safety configuration", FUNCTIONS[6][1], active, info, OK if validated else WARN,
                                f"checksum {_str(safety.get('checksum'))}, "
                                + ("validated" if validated else "NOT validated (validate_config on the pendant)"),
                                [("checksum", safety.get("checksum")), ("validated", validated)]))

    reduced = safety.get("reduced") is True
    out.append(_function_status("safe limits", FUNCTIONS[7][1], active, info, OK,
                                ("reduced mode" if reduced else "normal speed")
                                + (f", TCP limit {_fmt(_num(safety.get('speed_limit')))} mm/s"
                                   if _num(safety.get("speed_limit")) is not None else ""),
                                [("speed limit mm/s", _num(safety.get("speed_limit"))), ("reduced", reduced),
                                 ("reduced by", _names(safety.get("reduced_by"))),
                                 ("recovery", safety.get("recovery") is True),
                                 ("tcp speed mm/s", _num(s.get("tcp_speed")))]))

    bt = safety.get("brake_test") if isinstance(safety.get("brake_test"), dict) else {}
    bt_level = WARN if bt.get("due") is True or bt.get("required") is True else OK
    out.append(_function_status("brake test", FUNCTIONS[8][1], active, info, bt_level,
                                f"last {_str(bt.get('last'), 'unknown')}"
                                + (", running" if bt.get("running") is True else "")
                                + (", due" if bt.get("due") is True else ""),
                                [("last", bt.get("last")), ("last time", bt.get("last_time")),
                                 ("due in h", _num(bt.get("due_in_h"))), ("running", bt.get("running") is True)]))

    fields = safety.get("fields") if isinstance(safety.get("fields"), dict) else {}
    out.append(_function_status("collaborative operation", FUNCTIONS[9][1], active, info, OK,
                                f"fields outer {_str(fields.get('outer'), '?')}, inner {_str(fields.get('inner'), '?')}",
                                [("outer field", fields.get("outer")), ("inner field", fields.get("inner")),
                                 ("separation mm", _num(safety.get("separation_mm"))),
                                 ("allowed speed mm/s", _num(safety.get("v_allowed"))),
                                 ("power and force limiting", safety.get("pfl") is True),
                                 ("contact force N", _num(safety.get("contact_force")))]))

    out.extend(channel_diagnostics(s, active, info))
    return out


def channel_diagnostics(status, active, info):
    """One status per channel when the status carries more than one in `channels` (SPEC §14:
    channels A and B in processes of their own, each with its compiler, pid, whether its process
    runs and answered this cycle, its state, cycle, last digest, whether it agrees with the
    other and the first field that differed: GET /api/status); none for a one-channel core. A
    channel that does not agree or whose process has ended is an ERROR, one not in the state the
    status reports a WARN; CHANNEL_MISMATCH goes to both channels, CHANNEL_LOST to the one it
    names (its subject)."""
    chans = status.get("channels")
    if not isinstance(chans, list) or len(chans) < 2:
        return []
    out = []
    for i, c in enumerate(chans):
        if not isinstance(c, dict):
            continue
        name = _str(c.get("name")) or _str(c.get("id")) or ("AB"[i] if i < 2 else str(i + 1))
        level = OK
        bad = c.get("agree") is False or c.get("running") is False
        if bad:
            level = ERROR
        elif isinstance(c.get("state"), str) and c.get("state") != status.get("state"):
            level = WARN
        values = [(k, v) for k, v in c.items() if isinstance(v, (str, int, float, bool)) or v is None]
        msg = ", ".join(f"{k} {_fmt(c[k])}" for k in ("state", "cycle", "digest", "agree") if k in c) or "reported"
        if c.get("running") is False:
            msg = "process ended; " + msg
        if isinstance(c.get("differs_in"), str):
            msg += f", differs in {c['differs_in']}"
        out.append(_function_status(f"channel {name}", _channel_alarms(name, info), active, info, level, msg, values))
    return out


def _channel_alarms(name, info):
    """The alarms that belong to channel `name`: CHANNEL_MISMATCH (the pair) always; CHANNEL_LOST
    only when its subject (GET /api/alarms: "A" or "B", the channel that was lost) is this one,
    or while its subject is not known yet."""
    lost = info.get("CHANNEL_LOST") if isinstance(info.get("CHANNEL_LOST"), dict) else {}
    subject = lost.get("subject")
    if isinstance(subject, str) and subject in ("A", "B") and subject != name:
        return ("CHANNEL_MISMATCH",)
    return CHANNEL_ALARMS


def stale_diagnostics(why):
    """Every function STALE: the gateway or the core is gone, so nothing is known."""
    names = ["state"] + [n for n, _ in FUNCTIONS]
    return [_status(n, STALE, why, [("why", why)]) for n in names]


def diagnostics_summary(entries):
    """(name, level, message) per entry: what changes when a subscriber should hear at once."""
    return tuple((e["name"], e["level"], e["message"]) for e in entries)
