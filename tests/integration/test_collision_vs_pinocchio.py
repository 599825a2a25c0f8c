"""The core's collision model (SPEC §11 PFL) against an independent model, Pinocchio (issue 38).

The core estimates a contact force from the drives' torques against its own model of the arm:
a recursive Newton-Euler pass in float over the chain and the links' inertials that robot/
reads from the URDF (core::arm_dynamics, prepared by core::prepare_dynamics as the running
program prepares it; `sim_dynamics --core` runs it). For the shipped IRB 120
(examples/robots/abb_irb120.urdf) and example-robot-data's UR3, UR5 and UR10 (installed into
the test venv by tests/integration/requirements-robots.txt, never copied into the
repository), on 10,000 seeded random states each (q within the joint ranges, qd within the
velocity limits, qdd up to 20 rad/s^2):

- the model's joint torques against Pinocchio's rnea (gravity, inertia, Coriolis) for the
  same q, qd, qdd, within TAU_ABS_NM + TAU_REL x the largest torque of that state (float
  against double);
- the force the core reads from drives' torques that carry a known force f on the flange
  (tau = rnea - J^T f, J the linear rows of Pinocchio's tool0 Jacobian, LOCAL_WORLD_ALIGNED;
  |f| 50..200 N) against f: within what the estimator's damping (lambda = 10 mm) takes away
  by design, lambda^2 / (sigma_min^2 + lambda^2) |f| with sigma_min the smallest singular
  value of Pinocchio's J, plus FORCE_ABS_N for float rounding.

Pinocchio reads the URDF itself (its own parser and folding of fixed joints and inertias); it
shares no code with robot/ or the core. docs/collaborative.md "The collision model" states
these tolerances.
"""
import json
import os

import numpy as np
import pinocchio as pin
import pytest

from pin_arms import ROBOTS, descriptions, run

SIM_DYNAMICS = os.environ["SIM_DYNAMICS_BIN"]
STATES = 10_000
QDD_MAX = 20.0
TAU_ABS_NM = 1e-3
TAU_REL = 1e-5
FORCE_ABS_N = 0.05
DAMPING_M = 0.01  # core::kDampingM






@pytest.fixture(scope="module", params=ROBOTS)
def arm(request):
    urdf = descriptions()[request.param]
    table = json.loads(run([SIM_DYNAMICS, "--robot", urdf, "--model"]))
    model = pin.buildModelFromUrdf(urdf)
    names = [model.names[i] for i in range(1, model.njoints)]
    assert names == table["joints"], (names, table["joints"])
    model.gravity = pin.Motion(np.array(table["gravity_m_s2"]), np.zeros(3))
    flange = model.getFrameId(table["flange"], pin.BODY)
    rng = np.random.default_rng(1138 + ROBOTS.index(request.param))
    q = rng.uniform(np.array(table["q_min_rad"]), np.array(table["q_max_rad"]), size=(STATES, 6))
    vmax = np.array([model.velocityLimit[model.joints[model.getJointId(n)].idx_v] for n in names])
    qd = rng.uniform(-vmax, vmax, size=(STATES, 6))
    qdd = rng.uniform(-QDD_MAX, QDD_MAX, size=(STATES, 6))
    direction = rng.normal(size=(STATES, 3))
    f = direction / np.linalg.norm(direction, axis=1)[:, None] * rng.uniform(50.0, 200.0, size=(STATES, 1))
    data = model.createData()
    rnea = np.empty((STATES, 6))
    loaded = np.empty((STATES, 6))
    sigma_min = np.empty(STATES)
    for i in range(STATES):
        rnea[i] = pin.rnea(model, data, q[i], qd[i], qdd[i])
        jac = pin.computeFrameJacobian(model, data, q[i], flange, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3, :]
        loaded[i] = rnea[i] - jac.T @ f[i]
        sigma_min[i] = np.linalg.svd(jac, compute_uv=False)[-1]
    lines = "".join(" ".join(repr(float(x)) for x in np.concatenate(row)) + "\n" for row in zip(q, qd, qdd, loaded))
    out = np.array([[float(x) for x in line.split()]
                    for line in run([SIM_DYNAMICS, "--robot", urdf, "--core"], stdin=lines).splitlines()])
    assert out.shape == (STATES, 9)
    return {"name": request.param, "rnea": rnea, "core_tau": out[:, :6], "core_f": out[:, 6:], "f": f,
            "sigma_min": sigma_min}


def test_model_torques_match_rnea(arm):
    oracle, ours = arm["rnea"], arm["core_tau"]
    bound = TAU_ABS_NM + TAU_REL * np.max(np.abs(oracle), axis=1, keepdims=True)
    excess = np.abs(ours - oracle) - bound
    worst = np.unravel_index(np.argmax(excess), excess.shape)
    assert np.all(excess <= 0.0), (f"{arm['name']}: state {worst[0]} axis {worst[1] + 1}: core {ours[worst]!r} "
                                   f"pinocchio {oracle[worst]!r} (bound {bound[worst[0], 0]:.4g} N m)")
    # Not vacuous: the states load the arm well beyond the tolerance.
    assert np.max(np.abs(oracle[:, 1])) > 1000.0 * TAU_ABS_NM


def test_force_read_from_the_drives_is_the_force_on_the_flange(arm):
    f, est, s = arm["f"], arm["core_f"], arm["sigma_min"]
    mag = np.linalg.norm(f, axis=1)
    damping = DAMPING_M ** 2 / (s ** 2 + DAMPING_M ** 2) * mag
    err = np.linalg.norm(est - f, axis=1)
    excess = err - (damping + FORCE_ABS_N)
    i = int(np.argmax(excess))
    assert np.all(excess <= 0.0), (f"{arm['name']}: state {i}: |f| {mag[i]:.2f} N, estimate off by {err[i]:.3f} N, "
                                   f"sigma_min {s[i]:.4f} m")
    # Most states are well conditioned (the damping takes < 1 %): the check is not all slack.
    assert np.mean(damping < 0.01 * mag) > 0.5
