"""Every robot in robots/ against a Pinocchio model built from the same description, and the 2R arm
against its textbook closed form."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import sympy as sp

import jaxskid
from jaxskid.testing import closed_form
from pinref import to_pinocchio, velocity_to_pin
from helpers import load_example

ROBOTS = sorted((Path(__file__).parents[1] / "robots").glob("*.yaml"))
QUANTITIES = ["mass_matrix", "coriolis_torques", "gravity_torques", "inverse_dynamics", "forward_kinematics"]


def test_there_are_seed_robots():
    names = {p.stem for p in ROBOTS}
    assert {"single_pendulum", "double_pendulum", "arm_2r", "prr", "hopping_leg", "arm_3dof", "quadruped_12dof",
            "four_bar", "quadruped_contact"} <= names


@pytest.mark.parametrize("path", ROBOTS, ids=lambda p: p.stem)
def test_seed_robot_matches_pinocchio(path):
    robot = jaxskid.load(path)
    params = robot.default_params()
    assert set(params) == set(robot.parameters), "every seed robot gives every parameter a default"
    model, frames = to_pinocchio(robot, params)
    data = model.createData()
    dyn = jaxskid.lower(robot, QUANTITIES)
    rng = np.random.default_rng(11)
    q, qd, qdd = _states(robot, rng)
    m, cqd, g, tau = (np.asarray(x) for x in (dyn.mass_matrix(q), dyn.coriolis_torques(q, qd), dyn.gravity_torques(q),
                                              dyn.inverse_dynamics(q, qd, qdd)))
    fb = robot.floating_base
    m = velocity_to_pin(velocity_to_pin(m, fb, -1), fb, -2)
    cqd, g, tau, qd, qdd = (velocity_to_pin(x, fb) for x in (cqd, g, tau, qd, qdd))
    poses = dyn.forward_kinematics(q)
    for k in range(200):
        mp = pin.crba(model, data, q[k])
        mp = np.triu(mp) + np.triu(mp, 1).T
        gp = pin.computeGeneralizedGravity(model, data, q[k]).copy()
        for ours, ref in ((m[k], mp), (g[k], gp), (cqd[k], pin.nonLinearEffects(model, data, q[k], qd[k]) - gp),
                          (tau[k], pin.rnea(model, data, q[k], qd[k], qdd[k]))):
            assert np.linalg.norm(ours - ref) <= 1e-9 * max(1e-12, np.linalg.norm(ref))
        pin.framesForwardKinematics(model, data, q[k])
        for f in frames:
            assert np.abs(np.asarray(poses[f][k]) - data.oMf[model.getFrameId(f)].homogeneous).max() <= 1e-9


def _states(robot, rng, count: int = 200):
    """Random (q, qd, qdd): joint positions in [-2, 2]; a floating base's position in [-2, 2] and a random unit
    quaternion; velocities and accelerations of nv."""
    q = rng.uniform(-2, 2, size=(count, robot.nq))
    if robot.floating_base:
        quat = rng.normal(size=(count, 4))
        q[:, 3:7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    qd, qdd = rng.uniform(-2, 2, size=(2, count, robot.nv))
    return q, qd, qdd


def test_arm_2r_textbook_closed_form():
    robot = jaxskid.load(Path(__file__).parents[1] / "robots" / "arm_2r.yaml")
    assert set(robot.parameters) == {"m1", "m2", "l1", "l2", "g"}
    eqs = jaxskid.derive(robot, ["mass_matrix", "gravity_torques"])
    m1, m2, l1, l2, g = (jaxskid.symbol(x) for x in ("m1", "m2", "l1", "l2", "g"))
    q1, q2 = eqs.arguments["q"].symbols
    c2 = sp.cos(q2)
    textbook_m = [
        m1 * l1**2 + m2 * (l1**2 + 2 * l1 * l2 * c2 + l2**2), m2 * (l1 * l2 * c2 + l2**2),
        m2 * (l1 * l2 * c2 + l2**2), m2 * l2**2,
    ]
    textbook_g = [(m1 + m2) * g * l1 * sp.cos(q1) + m2 * g * l2 * sp.cos(q1 + q2), m2 * g * l2 * sp.cos(q1 + q2)]
    for ours, ref in zip(closed_form(eqs, "mass_matrix"), textbook_m):
        assert sp.simplify(sp.expand_trig(ours - ref)) == 0
    for ours, ref in zip(closed_form(eqs, "gravity_torques"), textbook_g):
        assert sp.simplify(sp.expand_trig(ours - ref)) == 0


def test_python_description_equals_yaml():
    built = load_example("python_robot").arm_2r()
    loaded = jaxskid.load(Path(__file__).parents[1] / "robots" / "arm_2r.yaml")
    assert built.joint_types == loaded.joint_types and built.parents == loaded.parents
    a = jaxskid.lower(built, ["inverse_dynamics", "forward_kinematics"])
    b = jaxskid.lower(loaded, ["inverse_dynamics", "forward_kinematics"])
    params = {"m1": 1.3, "m2": 0.7, "l1": 0.9, "l2": 0.6, "g": 9.81}
    rng = np.random.default_rng(0)
    q, qd, qdd = rng.normal(size=(3, 10, 2))
    np.testing.assert_allclose(a.inverse_dynamics(q, qd, qdd, params), b.inverse_dynamics(q, qd, qdd, params), rtol=1e-13)
    np.testing.assert_allclose(a.forward_kinematics(q, params)["tip"], b.forward_kinematics(q, params)["tip"], atol=1e-14)
