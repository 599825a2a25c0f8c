#!/usr/bin/env bash
# Installs the ROS 2 adapter's venv: ROS 2 Jazzy's rclpy and message packages from PyPI
# (requirements.txt, every version pinned; no ROS installation), then generates, builds and
# installs the adapter's interface package safestate_msgs into the same venv with the
# registry's rosidl generators. Usage: install.sh VENV BUILD_DIR  (`make ros2` runs it).
#
# The venv's layout is the one the wheels use: C libraries in VENV/lib (put on the library path
# by ros-wheels-bootstrapper when Python starts), Python packages in site-packages, the ament
# index and CMake configurations in VENV/share. safestate_msgs goes to the same places.
set -euo pipefail

venv=${1:?usage: install.sh VENV BUILD_DIR}
build=${2:?usage: install.sh VENV BUILD_DIR}
here=$(cd "$(dirname "$0")" && pwd)

if [[ ! -x "$venv/bin/python" ]]; then
  python3 -m venv "$venv"
fi
venv=$(cd "$venv" && pwd)
py="$venv/bin/python"
"$py" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' || {
  echo "ros2: the PyPI wheels of ROS 2 Jazzy are built for CPython 3.11 (Debian 12's python3); $("$py" --version) found" >&2
  exit 1
}
# The wheels are large (about 250 MB installed); pip keeps them in its cache between installs.
"$py" -m pip install -q --disable-pip-version-check -r "$here/requirements.txt"

# safestate_msgs: rosidl_generate_interfaces through ament_cmake, all from the venv, in a fresh
# build tree (a cache left by another venv or checkout would point elsewhere).
rm -rf "$build"
export PATH="$venv/bin:$PATH"
export AMENT_PREFIX_PATH="$venv"
cmake -S "$here/safestate_msgs" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$venv" -DCMAKE_INSTALL_PREFIX="$venv" -DPython3_EXECUTABLE="$py" \
  -DBUILD_TESTING=OFF > "$build.configure.log" 2>&1 || {
  echo "ros2: configuring safestate_msgs failed; see $build.configure.log" >&2
  tail -20 "$build.configure.log" >&2
  exit 1
}
cmake --build "$build"
cmake --install "$build" > /dev/null

# The adapter itself runs from this checkout: a .pth file puts adapters/ros2 on the venv's path,
# so that `.venv-ros2/bin/python -m safestate_ros2` works from anywhere.
site=$("$py" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
echo "$here" > "$site/safestate_ros2.pth"

# The check that it all fits together: the adapter's imports, in a fresh interpreter.
"$py" -c 'import rclpy, websockets, safestate_ros2.node; from safestate_msgs.msg import SafetyState, Event; from sensor_msgs.msg import JointState; from diagnostic_msgs.msg import DiagnosticArray; from std_srvs.srv import Trigger'
echo "ros2: $venv ready (rclpy $("$py" -c 'from importlib.metadata import version; print(version("ros-jazzy-rclpy"))'), safestate_msgs)"
