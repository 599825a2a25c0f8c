"""The arms the Pinocchio comparisons load (test_robot_vs_pinocchio, test_collision_vs_pinocchio):
the shipped IRB 120 (IRB120_URDF) and example-robot-data's UR3, UR5 and UR10, installed into the
test venv by tests/integration/requirements-robots.txt, never copied into the repository."""
import os
import pathlib
import subprocess
import sysconfig

ROBOTS = ["irb120", "ur3", "ur5", "ur10"]


def example_robot_data():
    share = pathlib.Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
    assert share.is_dir(), ("example-robot-data is not installed in the test venv "
                            "(pip install -r tests/integration/requirements-robots.txt; `make test` does)")
    return share / "ur_description" / "urdf"


def descriptions():
    ur = example_robot_data()
    return {"irb120": os.environ["IRB120_URDF"], "ur3": str(ur / "ur3_robot.urdf"), "ur5": str(ur / "ur5_robot.urdf"),
            "ur10": str(ur / "ur10_robot.urdf")}


def run(args, stdin=None):
    r = subprocess.run(args, input=stdin, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return r.stdout
