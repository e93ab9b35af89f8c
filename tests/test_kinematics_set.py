"""Skidy's kinematic set (twists, accelerations, system and end-effector Jacobians and their time
derivatives) against Pinocchio, in both LOCAL and LOCAL_WORLD_ALIGNED frames.

Reference: a Pinocchio model rebuilt from the same Robot (``pinref.to_pinocchio``), evaluated by
``forwardKinematics(q, v, a)``, ``getFrameVelocity``, ``getFrameAcceleration``,
``getFrameClassicalAcceleration``, ``getFrameJacobian`` and ``getFrameJacobianTimeVariation`` (after
``computeJointJacobiansTimeVariation``). Pinocchio orders 6-vectors (v, omega), jaxskid (omega, v).

What is compared with what:

* ``body_*`` (LOCAL): twist, the spatial acceleration (= d/dt of the body twist), the Jacobian and its
  time variation;
* ``hybrid_twist`` and ``hybrid_jacobian`` (LOCAL_WORLD_ALIGNED);
* ``hybrid_acceleration``: we define it as d/dt of the hybrid twist, ``(domega/dt, d^2p/dt^2)``. Pinocchio's
  LOCAL_WORLD_ALIGNED *spatial* acceleration is ``(R dv^b/dt, R domega^b/dt)``; ours is that plus
  ``(omega x v, 0)``, and its linear part is Pinocchio's classical acceleration;
* ``hybrid_jacobian_dot``: d/dt of the hybrid Jacobian, Pinocchio's LOCAL_WORLD_ALIGNED time variation
  (checked also through ``J^h qdd + dJ^h/dt qd`` = our hybrid acceleration);
* ``system_jacobian`` and its derivative: the LOCAL Jacobians of the body frames, stacked.
"""

from __future__ import annotations

import jax
import numpy as np
import pinocchio as pin
import pytest

import jaxskid
from helpers import ROBOTS_DIR, load
from pinref import to_pinocchio
from randrobot import random_robot

QUANTITIES = [
    "body_twist", "hybrid_twist", "body_acceleration", "hybrid_acceleration",
    "ee_body_twist", "ee_hybrid_twist", "ee_body_acceleration", "ee_hybrid_acceleration",
    "system_jacobian", "system_jacobian_dot",
    "body_jacobian", "hybrid_jacobian", "body_jacobian_dot", "hybrid_jacobian_dot",
]
N_STATES = 6
TOL = 1e-9
LOCAL, LWA = pin.ReferenceFrame.LOCAL, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def case_robot(name: str) -> jaxskid.Robot:
    if name == "random_tree":  # prismatic joints, screws off the frame origin, end-effector offsets
        return random_robot(np.random.default_rng(21), 6, tree=True)
    return load(name)


def close(ours, ref, what):
    ours, ref = np.asarray(ours), np.asarray(ref)
    err = np.linalg.norm(ours - ref) / max(1.0, np.linalg.norm(ref))
    assert err <= TOL, f"{what}: error {err:.3g}\nours\n{ours}\npinocchio\n{ref}"


def omega_v(m: np.ndarray) -> np.ndarray:
    """Pinocchio's (v, omega) rows -> (omega, v)."""
    return np.concatenate([m[3:], m[:3]])


@pytest.fixture(scope="module", params=[pytest.param("panda7", marks=pytest.mark.slow), "ur5", "solo12", "hopping_leg",
                                        pytest.param("random_tree", marks=pytest.mark.slow)])
def case(request):
    robot = case_robot(request.param)
    params = robot.default_params()
    model, _ = to_pinocchio(robot, params)
    dyn = jaxskid.lower(robot, QUANTITIES)
    rng = np.random.default_rng(5)
    q = rng.uniform(-np.pi, np.pi, size=(N_STATES, robot.n_dof))
    qd, qdd = rng.normal(size=(2, N_STATES, robot.n_dof)) * 2.0
    ours = {}
    with jax.disable_jit():  # eager: these checks are about the derivation, compiling 14 functions is not
        for name in QUANTITIES:
            args, _ = dyn.signature(name)
            ours[name] = np.asarray(getattr(dyn, name)(*(dict(q=q, qd=qd, qdd=qdd)[a] for a in args)))
    return request.param, robot, model, q, qd, qdd, ours


def pinocchio_states(model, q, qd, qdd):
    data = model.createData()
    for k in range(len(q)):
        pin.forwardKinematics(model, data, q[k], qd[k], qdd[k])
        pin.computeJointJacobiansTimeVariation(model, data, q[k], qd[k])
        pin.updateFramePlacements(model, data)
        yield k, data


def pinocchio_frames(case, frames):
    """``(k, data, i, frame, fid)`` for each state k of ``case`` (``data``: Pinocchio's, evaluated there) and each
    frame i of ``frames``, ``fid`` its Pinocchio frame id."""
    _, _, model, q, qd, qdd, _ = case
    for k, data in pinocchio_states(model, q, qd, qdd):
        for i, frame in enumerate(frames):
            yield k, data, i, frame, model.getFrameId(frame)


def test_body_twists_and_accelerations(case):
    name, robot, model, q, qd, qdd, ours = case
    for k, data, i, link, fid in pinocchio_frames(case, robot.link_names):
        v_loc = pin.getFrameVelocity(model, data, fid, LOCAL)
        v_lwa = pin.getFrameVelocity(model, data, fid, LWA)
        a_loc = pin.getFrameAcceleration(model, data, fid, LOCAL)
        a_lwa = pin.getFrameAcceleration(model, data, fid, LWA)
        classical = pin.getFrameClassicalAcceleration(model, data, fid, LWA)
        close(ours["body_twist"][k, i], omega_v(v_loc.vector), f"{name} body_twist {link}")
        close(ours["hybrid_twist"][k, i], omega_v(v_lwa.vector), f"{name} hybrid_twist {link}")
        close(ours["body_acceleration"][k, i], omega_v(a_loc.vector), f"{name} body_acceleration {link}")
        hybrid = omega_v(a_lwa.vector) + np.concatenate([np.zeros(3), np.cross(v_lwa.angular, v_lwa.linear)])
        close(ours["hybrid_acceleration"][k, i], hybrid, f"{name} hybrid_acceleration {link}")
        close(ours["hybrid_acceleration"][k, i, 3:], classical.linear, f"{name} classical acceleration {link}")


def test_end_effector_twists_and_accelerations(case):
    name, robot, model, q, qd, qdd, ours = case
    assert robot.end_effectors, f"{name}: no end-effector to check"
    for k, data, e, frame, fid in pinocchio_frames(case, robot.end_effectors):
        v_lwa = pin.getFrameVelocity(model, data, fid, LWA)
        close(ours["ee_body_twist"][k, e], omega_v(pin.getFrameVelocity(model, data, fid, LOCAL).vector), frame)
        close(ours["ee_hybrid_twist"][k, e], omega_v(v_lwa.vector), frame)
        close(ours["ee_body_acceleration"][k, e],
              omega_v(pin.getFrameAcceleration(model, data, fid, LOCAL).vector), frame)
        hybrid = omega_v(pin.getFrameAcceleration(model, data, fid, LWA).vector)
        hybrid[3:] += np.cross(v_lwa.angular, v_lwa.linear)
        close(ours["ee_hybrid_acceleration"][k, e], hybrid, frame)


def test_end_effector_jacobians_and_time_variations(case):
    name, robot, model, q, qd, qdd, ours = case
    assert robot.end_effectors, f"{name}: no end-effector to check"
    for k, data, e, frame, fid in pinocchio_frames(case, robot.end_effectors):
        for key, rf in (("body", LOCAL), ("hybrid", LWA)):
            close(ours[f"{key}_jacobian"][k, e], omega_v(pin.getFrameJacobian(model, data, fid, rf)),
                  f"{name} {key}_jacobian {frame}")
            close(ours[f"{key}_jacobian_dot"][k, e],
                  omega_v(pin.getFrameJacobianTimeVariation(model, data, fid, rf)),
                  f"{name} {key}_jacobian_dot {frame}")
        # J qdd + dJ/dt qd is the time derivative of the twist, in both representations
        for key in ("body", "hybrid"):
            acc = ours[f"{key}_jacobian"][k, e] @ qdd[k] + ours[f"{key}_jacobian_dot"][k, e] @ qd[k]
            close(acc, ours[f"ee_{key}_acceleration"][k, e], f"{name} {key} J qdd + dJ qd {frame}")


def test_system_jacobian_and_time_variation(case):
    name, robot, model, q, qd, qdd, ours = case
    n = robot.n_dof
    for k, data in pinocchio_states(model, q, qd, qdd):
        j = ours["system_jacobian"][k].reshape(n, 6, n)
        jd = ours["system_jacobian_dot"][k].reshape(n, 6, n)
        for i, link in enumerate(robot.link_names):
            fid = model.getFrameId(link)
            close(j[i], omega_v(pin.getFrameJacobian(model, data, fid, LOCAL)), f"{name} system_jacobian {link}")
            close(jd[i], omega_v(pin.getFrameJacobianTimeVariation(model, data, fid, LOCAL)),
                  f"{name} system_jacobian_dot {link}")
        close(ours["system_jacobian"][k] @ qd[k], ours["body_twist"][k].reshape(-1), f"{name} V = J qd")


def test_shapes_and_names():
    robot = load("hopping_leg")
    eqs = jaxskid.derive(robot, QUANTITIES)
    n, n_ee = robot.n_dof, len(robot.end_effectors)
    expected = {
        "body_twist": (n, 6), "hybrid_twist": (n, 6), "body_acceleration": (n, 6), "hybrid_acceleration": (n, 6),
        "ee_body_twist": (n_ee, 6), "ee_hybrid_twist": (n_ee, 6), "ee_body_acceleration": (n_ee, 6),
        "ee_hybrid_acceleration": (n_ee, 6), "system_jacobian": (6 * n, n), "system_jacobian_dot": (6 * n, n),
        "body_jacobian_dot": (n_ee, 6, n), "hybrid_jacobian_dot": (n_ee, 6, n),
    }
    for name, shape in expected.items():
        assert eqs.quantities[name].shape == shape, name
    assert eqs.quantities["body_acceleration"].args == ("q", "qd", "qdd")
    assert eqs.quantities["system_jacobian"].args == ("q",)
    assert eqs.quantities["hybrid_jacobian_dot"].args == ("q", "qd")


def test_end_effector_quantities_need_an_end_effector():
    robot = jaxskid.load(ROBOTS_DIR / "single_pendulum.yaml")
    if robot.end_effectors:
        robot = jaxskid.Robot.create(robot.name, robot.joints, robot.gravity, (), (), dict(robot.defaults), robot.base)
    with pytest.raises(jaxskid.RequestError, match="need an end-effector"):
        jaxskid.derive(robot, ["ee_body_twist"])
    eqs = jaxskid.derive(robot, "all")
    assert "body_twist" in eqs.quantities and "ee_body_twist" not in eqs.quantities


def test_acceleration_is_the_time_derivative_of_the_twist():
    """d/dt of the lowered twists (jax.jvp along (qd, qdd)) equals the lowered accelerations (jit-compiled)."""
    robot = load("hopping_leg")
    dyn = jaxskid.lower(robot, ["hybrid_twist", "hybrid_acceleration", "ee_hybrid_twist", "ee_hybrid_acceleration"])
    rng = np.random.default_rng(9)
    q, qd, qdd = rng.normal(size=(3, robot.n_dof))
    for twist in ("hybrid_twist", "ee_hybrid_twist"):
        _, tangent = jax.jvp(lambda a, b: getattr(dyn, twist)(a, b), (q, qd), (qd, qdd))
        close(getattr(dyn, twist.replace("twist", "acceleration"))(q, qd, qdd), tangent, twist)
