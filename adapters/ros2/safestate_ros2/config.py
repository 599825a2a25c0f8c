"""The adapter's settings: ROS parameters, validated before anything starts (exit 2 naming what
is wrong, like the OPC UA adapter's EXIT_CONFIG, so that `safestate run` does not restart it).

domain_id and namespace are ROS parameters as the issue asks, but they must be known before
rclpy creates its context and the node, so they are read from the command line's --ros-args
(`-p domain_id:=7 -p namespace:=/cell1`) here; the node declares them read-only afterwards so
that `ros2 param get` shows them. The other parameters are read by the node (node.py).

Secrets never come from the command line (other local users can read /proc/PID/cmdline): the
gateway's remote token comes from the file named by the parameter remote_token_file or from the
environment variable SAFESTATE_REMOTE_TOKEN.
"""

import os
import re

EXIT_CONFIG = 2
HERE = os.path.dirname(os.path.abspath(__file__))
LOOPBACK_PROFILE = os.path.join(HERE, "fastdds-loopback.xml")
EARLY_PARAMETERS = ("domain_id", "namespace", "localhost_only")  # read before rclpy starts
MAX_DOMAIN_ID = 232  # the largest domain id Fast DDS maps to valid UDP ports (ROS 2 "domain ID" docs)


class ConfigError(Exception):
    pass


def ros_params(argv):
    """NAME -> VALUE text of every `-p NAME:=VALUE` / `--param NAME:=VALUE` in the --ros-args
    sections of argv (a node-name prefix `safestate:NAME` counts too)."""
    out = {}
    in_ros = False
    i = 0
    while i < len(argv):
        a = argv[i]
        if a == "--ros-args":
            in_ros = True
        elif a == "--":
            in_ros = False
        elif in_ros and a in ("-p", "--param") and i + 1 < len(argv):
            i += 1
            name, sep, value = argv[i].partition(":=")
            if sep:
                out[name.split(":", 1)[-1] if ":" in name else name] = value
        i += 1
    return out


def _int(name, text, lo, hi):
    if not re.fullmatch(r"[0-9]+", text or ""):
        raise ConfigError(f"{name}: not a whole number: {text!r}")
    v = int(text)
    if not lo <= v <= hi:
        raise ConfigError(f"{name}: {v} out of range {lo}..{hi}")
    return v


def _bool(name, text):
    t = (text or "").strip().lower()
    if t in ("true", "1", "yes", "on"):
        return True
    if t in ("false", "0", "no", "off"):
        return False
    raise ConfigError(f"{name}: expected true or false, got {text!r}")


def early_settings(argv, environ):
    """(domain_id, namespace, localhost_only) from the command line, validated; the domain id
    defaults to ROS_DOMAIN_ID as every ROS 2 node's does, else 0."""
    p = ros_params(argv)
    if "domain_id" in p:
        domain = _int("domain_id", p["domain_id"], 0, MAX_DOMAIN_ID)
    elif environ.get("ROS_DOMAIN_ID", "") != "":
        domain = _int("ROS_DOMAIN_ID", environ["ROS_DOMAIN_ID"], 0, MAX_DOMAIN_ID)
    else:
        domain = 0
    ns = p.get("namespace", "")
    if ns not in ("", "/"):
        if not ns.startswith("/"):
            ns = "/" + ns
        if not re.fullmatch(r"(/[A-Za-z_][A-Za-z0-9_]*)+", ns) or "__" in ns:
            raise ConfigError(f"namespace: not a valid ROS namespace: {p['namespace']!r} "
                              "(tokens of letters, digits and _, each starting with a letter or _)")
    else:
        ns = ""
    localhost = _bool("localhost_only", p["localhost_only"]) if "localhost_only" in p else True
    return domain, ns, localhost


DISCOVERY_VARIABLES = ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS", "ROS_LOCALHOST_ONLY")


def dds_environment(environ, localhost_only):
    """The environment rclpy must start with. Localhost only (the default): Fast DDS with a
    participant profile whose only transports are UDP on 127.0.0.1 (an interface allowlist) and
    shared memory, because DDS here has no authentication: anyone who reaches the domain may call
    ~/start. The discovery variables are removed on purpose: with ROS_AUTOMATIC_DISCOVERY_RANGE=
    LOCALHOST (or ROS_LOCALHOST_ONLY) rmw_fastrtps adds transports of its own that bind 0.0.0.0
    and the host's addresses, beside the profile's; with the profile alone every socket the
    participant receives on is bound to 127.0.0.1 (or to the discovery multicast group, joined on
    the loopback interface only). Nodes of this host find it whatever their own discovery range.
    localhost_only:=false leaves the DDS environment to the user."""
    env = dict(environ)
    if localhost_only:
        for k in DISCOVERY_VARIABLES:
            env.pop(k, None)
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = LOOPBACK_PROFILE
    return env


def gateway_address(text):
    m = re.fullmatch(r"([A-Za-z0-9.\-]+|\[[0-9A-Fa-f:]+\]):([0-9]+)", text or "")
    if m is None:
        raise ConfigError(f"gateway: expected HOST:PORT, got {text!r}")
    return m.group(1), _int("gateway port", m.group(2), 1, 65535)


def read_token(path, environ):
    if path:
        try:
            with open(path, encoding="utf-8") as f:
                return f.read().rstrip("\r\n")
        except OSError as e:
            raise ConfigError(f"remote_token_file: {e.strerror}: {path}") from e
    return environ.get("SAFESTATE_REMOTE_TOKEN", "")
