"""SafeState's ROS 2 adapter (issue 39, docs/ros2.md): the safety state, joint states, diagnostics
and events for robot software, and the `remote` role's commands as std_srvs/Trigger services."""

__version__ = "0.1.0"
