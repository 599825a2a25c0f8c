"""The simulated arm's rigid-body dynamics against an independent oracle, Pinocchio.

The simulator (`sim_dynamics`, KDL's recursive Newton-Euler on the chain robot/ makes from the
URDF: fixed joints folded, each moving link's inertial with its fixed links) and Pinocchio,
which reads the same URDF itself (examples/robots/abb_irb120.urdf, the shipped default), must
agree:

- inverse dynamics (rnea) on 200 random states, seeded: q within the joint ranges, qd up to
  3 rad/s, qdd up to 20 rad/s^2; within 1e-6 N m + 1e-6 relative;
- the external force's part: with a random force on tool0 (base frame), the simulator's
  torques must be rnea - J^T f, J the linear rows of Pinocchio's frame Jacobian of tool0
  (LOCAL_WORLD_ALIGNED), i.e. the force of the environment on the TCP loads the drives as
  tau = ID - J^T f.

Other arms (UR3, UR5, UR10) are compared in test_robot_vs_pinocchio.py. What this does not
check: that the description matches the real robot (docs/robot.md "Dynamics").
"""
import json
import os
import subprocess

import numpy as np
import pinocchio as pin
import pytest

BIN = os.environ["SIM_DYNAMICS_BIN"]
URDF = os.environ["IRB120_URDF"]
SEED = 20
STATES = 200
ABS_TOL = 1e-6
REL_TOL = 1e-6


def sim_dynamics(*args, stdin=None):
    r = subprocess.run([BIN, "--robot", URDF, *args], input=stdin, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return r.stdout


@pytest.fixture(scope="module")
def table():
    return json.loads(sim_dynamics("--model"))


@pytest.fixture(scope="module")
def model(table):
    m = pin.buildModelFromUrdf(URDF)
    assert [m.names[i] for i in range(1, m.njoints)] == table["joints"]
    m.gravity = pin.Motion(np.array(table["gravity_m_s2"]), np.zeros(3))
    return m


def random_states(table, n, seed):
    rng = np.random.default_rng(seed)
    lo = np.array(table["q_min_rad"])
    hi = np.array(table["q_max_rad"])
    q = rng.uniform(lo, hi, size=(n, 6))
    qd = rng.uniform(-3.0, 3.0, size=(n, 6))
    qdd = rng.uniform(-20.0, 20.0, size=(n, 6))
    f = rng.uniform(-200.0, 200.0, size=(n, 3))
    return q, qd, qdd, f


def tool_torques(q, qd, qdd, f):
    lines = "".join(" ".join(repr(float(x)) for x in np.concatenate(row)) + "\n" for row in zip(q, qd, qdd, f))
    out = sim_dynamics(stdin=lines).splitlines()
    assert len(out) == len(q)
    return np.array([[float(x) for x in line.split()] for line in out])


def assert_close(ours, oracle, what):
    diff = np.abs(ours - oracle)
    bound = ABS_TOL + REL_TOL * np.abs(oracle)
    worst = np.unravel_index(np.argmax(diff - bound), diff.shape)
    assert np.all(diff <= bound), (f"{what}: state {worst[0]} axis {worst[1] + 1}: "
                                   f"sim {ours[worst]!r} pinocchio {oracle[worst]!r}")


def test_the_model_is_the_irb120(table, model):
    assert table["name"] == "abb_irb120_3_58" and table["flange"] == "tool0" and model.nq == 6
    assert table["gravity_m_s2"][2] == pytest.approx(-9.81, rel=1e-6)
    total = sum(model.inertias[i].mass for i in range(1, model.njoints))
    assert total == pytest.approx(11.931, abs=1e-4)  # 3.067 + 3.909 + 2.944 + 1.328 + 0.546 + 0.137
    # tool0 at home: 302 + 72 mm forward, 290 + 270 + 70 mm up; its z along the base's x.
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.zeros(6))
    tool0 = data.oMf[model.getFrameId("tool0")]
    assert np.allclose(tool0.translation, [0.374, 0.0, 0.63], atol=1e-6)
    assert np.allclose(tool0.rotation[:, 2], [1.0, 0.0, 0.0])


def test_inverse_dynamics_matches_pinocchio_on_random_states(table, model):
    q, qd, qdd, f = random_states(table, STATES, SEED)
    ours = tool_torques(q, qd, qdd, np.zeros_like(f))
    data = model.createData()
    oracle = np.array([pin.rnea(model, data, q[i], qd[i], qdd[i]) for i in range(STATES)])
    assert_close(ours, oracle, "rnea")
    # Not vacuous: the states load the axes well beyond the tolerance.
    assert np.max(np.abs(oracle[:, 1])) > 10.0


def test_gravity_alone_matches_pinocchio(table, model):
    q, _, _, _ = random_states(table, STATES, SEED + 1)
    zero = np.zeros_like(q)
    ours = tool_torques(q, zero, zero, np.zeros((STATES, 3)))
    data = model.createData()
    oracle = np.array([pin.computeGeneralizedGravity(model, data, q[i]) for i in range(STATES)])
    assert_close(ours, oracle, "gravity")


def test_external_force_on_tool0_is_minus_jacobian_transpose(table, model):
    q, qd, qdd, f = random_states(table, STATES, SEED + 2)
    ours = tool_torques(q, qd, qdd, f)
    data = model.createData()
    fid = model.getFrameId("tool0")
    oracle = np.empty_like(ours)
    for i in range(STATES):
        tau = pin.rnea(model, data, q[i], qd[i], qdd[i])
        jac = pin.computeFrameJacobian(model, data, q[i], fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        oracle[i] = tau - jac[:3, :].T @ f[i]
    assert_close(ours, oracle, "rnea - J^T f")
    # The force's part alone is large against the tolerance (up to 200 N at 0.6 m).
    without = tool_torques(q, qd, qdd, np.zeros_like(f))
    assert np.max(np.abs(ours - without)) > 50.0
