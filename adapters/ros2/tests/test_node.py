"""The node's own bookkeeping with rclpy but without a gateway: what it publishes when the
gateway's callbacks come in a given order (they are called directly here, in this thread).
Run: .venv-ros2/bin/python -m pytest adapters/ros2/tests  (CTest ros2_units)."""

import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from safestate_ros2 import config  # noqa: E402

rclpy = pytest.importorskip("rclpy", reason="runs in the ROS 2 venv (.venv-ros2, `make ros2`)")
from safestate_ros2.node import SafeStateNode  # noqa: E402

UR_NAMES = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
            "wrist_3_joint"]
STATUS = {"t": 1000, "state": "IDLE", "sub": None, "mode": "AUTO", "stop": None, "alarms": [], "reset_lamp": "off",
          "joints": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6], "core_heartbeat_age_ms": 1.0,
          "safety": {"checksum": "3F9A01C2", "validated": True, "reduced": False, "speed_limit": 2000.0}}


@pytest.fixture
def ros_context():
    # A domain of this process's own and DDS on this host, as the adapter's default.
    os.environ.update(config.dds_environment(os.environ, True))
    made = []

    def init(*args):
        rclpy.init(args=["node", "--ros-args", *args], domain_id=1 + os.getpid() % 100)
        made.append(True)

    yield init
    if made:
        rclpy.try_shutdown()


class Recorder:
    def __init__(self):
        self.msgs = []

    def publish(self, m):
        self.msgs.append(m)


def test_joint_states_wait_for_the_robot_description_then_carry_its_names(ros_context):
    """A subscriber (robot_state_publisher) must see one set of names: no joint_states with the
    fallback names in the moment between the welcome and GET /api/robot's answer."""
    ros_context()
    node = SafeStateNode(0, "", True)
    try:
        node.pub_joints = Recorder()
        node._on_status(dict(STATUS))
        node._on_status(dict(STATUS, t=1020))
        assert node.pub_joints.msgs == [], "joint_states before the robot description was asked"
        node._on_robot({"joints": [{"name": n} for n in UR_NAMES]})
        node._on_status(dict(STATUS, t=1040))
        assert [list(m.name) for m in node.pub_joints.msgs] == [UR_NAMES]
        # A reconnect whose GET /api/robot fails keeps the names it had.
        node._on_robot(None)
        node._on_status(dict(STATUS, t=1060))
        assert list(node.pub_joints.msgs[-1].name) == UR_NAMES
    finally:
        node.destroy_node()


def test_a_gateway_without_a_robot_description_gives_the_fallback_names(ros_context):
    ros_context()
    node = SafeStateNode(0, "", True)
    try:
        node.pub_joints = Recorder()
        node._on_robot(None)
        node._on_status(dict(STATUS))
        assert [list(m.name) for m in node.pub_joints.msgs] == [[f"joint_{i}" for i in range(1, 7)]]
    finally:
        node.destroy_node()


@pytest.mark.parametrize("args, words", [
    (["-p", "gatway:=127.0.0.1:9"], "unknown parameter gatway (known: cycle_us, domain_id, events_after, gateway,"),
    (["-p", "gateway:=127.0.0.1:9", "-p", "cycle:=5"], "unknown parameter cycle"),
])
def test_a_parameter_the_node_does_not_have_is_refused(ros_context, args, words):
    ros_context(*args)
    with pytest.raises(config.ConfigError, match=words.replace("(", r"\(")):
        SafeStateNode(0, "", True, cmdline=set(config.ros_params(["--ros-args", *args])))


def test_early_parameters_only_from_the_command_line(ros_context, tmp_path):
    """domain_id from a params file would be shown by `ros2 param get` but not be in force."""
    f = tmp_path / "p.yaml"
    f.write_text("safestate:\n  ros__parameters:\n    domain_id: 9\n")
    ros_context("--params-file", str(f))
    with pytest.raises(config.ConfigError, match="domain_id: give it on the command line"):
        SafeStateNode(0, "", True, cmdline=set())
