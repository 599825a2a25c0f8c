"""Any arm from its URDF (issue 38) against an independent model, Pinocchio.

For the shipped IRB 120 (examples/robots/abb_irb120.urdf) and three real arms' URDFs from
PyPI's example-robot-data (UR3, UR5, UR10; installed into the venv at test time by
tests/integration/requirements-robots.txt, never copied into the repository), on 10,000
seeded random configurations each (q within the joint ranges, qd within the velocity limits):

- `safestate robot fk` (the core's own kinematics, float) against Pinocchio's frame
  placements: every link origin, the flange and a TCP offset in the flange frame, within
  0.01 mm;
- the point speeds the T1 monitor computes (core::point_speed of every joint origin, the
  flange and the TCP) against Pinocchio's frame velocities, within 1e-5 of the speed
  (0.01 mm/s at 1 m/s) plus 1e-3 mm/s;
- the gravity torques of the simulated arm (`sim_dynamics`, KDL) against Pinocchio's
  computeGeneralizedGravity, within 0.1 % of the largest torque of that configuration.

Pinocchio reads the URDF itself (urdfdom from PyPI, its own folding of fixed joints and
inertias); it shares no code with robot/, the core, the motion layer or KDL.
"""
import json
import os

import numpy as np
import pinocchio as pin
import pytest

from pin_arms import ROBOTS, descriptions, run

SAFESTATE = os.environ["SAFESTATE_BIN"]
SIM_DYNAMICS = os.environ["SIM_DYNAMICS_BIN"]
CONFIGS = 10_000
TCP_MM = np.array([30.0, -20.0, 100.0])
POS_TOL_MM = 0.01
SPEED_REL = 1e-5
SPEED_ABS_MM_S = 1e-3
GRAVITY_REL = 1e-3










@pytest.fixture(scope="module", params=ROBOTS)
def arm(request):
    urdf = descriptions()[request.param]
    table = json.loads(run([SIM_DYNAMICS, "--robot", urdf, "--model"]))
    model = pin.buildModelFromUrdf(urdf)
    names = [model.names[i] for i in range(1, model.njoints)]
    assert names == table["joints"], (names, table["joints"])  # the same six joints, in order
    flange = model.getFrameId(table["flange"], pin.BODY)
    tcp = model.addFrame(pin.Frame("safestate_tcp", model.frames[flange].parentJoint,
                                   model.frames[flange].placement * pin.SE3(np.eye(3), TCP_MM / 1000.0),
                                   pin.FrameType.OP_FRAME))
    model.gravity = pin.Motion(np.array(table["gravity_m_s2"]), np.zeros(3))
    rng = np.random.default_rng(38 + ROBOTS.index(request.param))
    lo = np.array(table["q_min_rad"])
    hi = np.array(table["q_max_rad"])
    q = rng.uniform(lo, hi, size=(CONFIGS, 6))
    vmax = np.array([model.velocityLimit[model.joints[model.getJointId(n)].idx_v] for n in names])
    qd = rng.uniform(-vmax, vmax, size=(CONFIGS, 6))
    lines = "".join(" ".join(repr(float(x)) for x in np.concatenate([np.degrees(a), np.degrees(b)])) + "\n"
                    for a, b in zip(q, qd))
    fk = [json.loads(line) for line in run([SAFESTATE, "robot", "fk", "--robot", urdf, "--q", "-", "--tcp",
                                            ",".join(str(x) for x in TCP_MM)], stdin=lines).splitlines()]
    assert len(fk) == CONFIGS
    return {"name": request.param, "urdf": urdf, "table": table, "model": model, "tcp": tcp, "q": q, "qd": qd,
            "fk": fk}


def test_link_origins_flange_and_tcp_within_0_01_mm(arm):
    model, fk = arm["model"], arm["fk"]
    data = model.createData()
    link_frames = {name: model.getFrameId(name, pin.BODY) for name in fk[0]["links"]}
    assert len(link_frames) >= 8  # base, six moving links, the flange at least
    worst = (0.0, None)
    for i in range(CONFIGS):
        pin.framesForwardKinematics(model, data, arm["q"][i])
        for name, fid in link_frames.items():
            err = np.max(np.abs(np.array(fk[i]["links"][name]) - data.oMf[fid].translation * 1000.0))
            worst = max(worst, (err, f"config {i} link {name}"), key=lambda w: w[0])
        err = np.max(np.abs(np.array(fk[i]["tcp_mm"]) - data.oMf[arm["tcp"]].translation * 1000.0))
        worst = max(worst, (err, f"config {i} TCP"), key=lambda w: w[0])
    print(f"{arm['name']}: worst position difference {worst[0]:.2e} mm ({worst[1]})")
    assert worst[0] <= POS_TOL_MM, worst


def test_point_speeds_match_frame_velocities(arm):
    model, fk, table = arm["model"], arm["fk"], arm["table"]
    data = model.createData()
    joints = table["joints"]
    # Point k (k = 0..5): joint k+1's origin = its child link's origin; 6: the flange.
    frames = [model.getFrameId(j, pin.JOINT) for j in joints]
    frames.append(model.getFrameId(table["flange"], pin.BODY))
    worst = (0.0, None)
    largest = 0.0
    for i in range(CONFIGS):
        pin.forwardKinematics(model, data, arm["q"][i], arm["qd"][i])
        pin.updateFramePlacements(model, data)
        speeds = fk[i]["speed_mm_s"]
        for k, fid in enumerate(frames):
            v = np.linalg.norm(pin.getFrameVelocity(model, data, fid, pin.LOCAL_WORLD_ALIGNED).linear) * 1000.0
            largest = max(largest, v)
            excess = abs(speeds["origins"][k] - v) - (SPEED_REL * v + SPEED_ABS_MM_S)
            worst = max(worst, (excess, f"config {i} point {k}: ours {speeds['origins'][k]} pinocchio {v}"),
                        key=lambda w: w[0])
        v = np.linalg.norm(pin.getFrameVelocity(model, data, arm["tcp"], pin.LOCAL_WORLD_ALIGNED).linear) * 1000.0
        excess = abs(speeds["tcp"] - v) - (SPEED_REL * v + SPEED_ABS_MM_S)
        worst = max(worst, (excess, f"config {i} TCP: ours {speeds['tcp']} pinocchio {v}"), key=lambda w: w[0])
    assert largest > 1000.0  # not vacuous: metres per second
    assert worst[0] <= 0.0, worst


def test_gravity_torques_of_the_simulated_arm_within_0_1_percent(arm):
    model = arm["model"]
    data = model.createData()
    q = arm["q"]
    zeros = np.zeros(6)
    lines = "".join(" ".join(repr(float(x)) for x in np.concatenate([q[i], zeros, zeros, np.zeros(3)])) + "\n"
                    for i in range(CONFIGS))
    ours = np.array([[float(x) for x in line.split()]
                     for line in run([SIM_DYNAMICS, "--robot", arm["urdf"]], stdin=lines).splitlines()])
    oracle = np.array([pin.computeGeneralizedGravity(model, data, q[i]) for i in range(CONFIGS)])
    scale = np.max(np.abs(oracle), axis=1, keepdims=True)
    excess = np.abs(ours - oracle) - GRAVITY_REL * scale
    i, k = np.unravel_index(np.argmax(excess), excess.shape)
    assert np.max(np.abs(oracle)) > 5.0  # not vacuous
    assert excess[i, k] <= 0.0, f"config {i} axis {k + 1}: sim {ours[i, k]} pinocchio {oracle[i, k]}"
