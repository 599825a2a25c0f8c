"""`python -m safestate_ros2 --ros-args -p gateway:=127.0.0.1:8080 ...` (docs/ros2.md)."""

import sys

from .node import main

sys.exit(main())
