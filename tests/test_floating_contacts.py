"""The floating-base solo12 standing on four point contacts: constrained forward dynamics against a KKT solve
built on Pinocchio's ``crba``, ``nonLinearEffects``, frame Jacobians (LOCAL_WORLD_ALIGNED) and classical frame
accelerations, and a stabilised rollout that keeps the feet where they are."""

import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
from helpers import ROBOTS_DIR, URDFS

import jaxskid

FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
STAND = np.array([0, 0.8, -1.6, 0, 0.8, -1.6, 0, -0.8, 1.6, 0, -0.8, 1.6])


def to_pin(v):
    return np.concatenate([v[3:6], v[:3], v[6:]])


NAMES = ["mass_matrix", "inverse_dynamics", "constraint_jacobian", "constraint_drift", "constraint_residual"]


@pytest.fixture(scope="module")
def standing():
    robot = jaxskid.load(URDFS["solo12"], floating_base=True)
    at = dict(zip(robot.joint_names, STAND))  # the feet anchored where they are standing, base at the origin
    robot = robot.with_constraints([jaxskid.PointContact(f, at=at) for f in FEET])
    dyn = jaxskid.lower(robot, NAMES)
    model = pin.buildModelFromUrdf(str(URDFS["solo12"]), pin.JointModelFreeFlyer())
    return robot, dyn, model


def test_seed_quadruped_in_contact():
    """robots/quadruped_contact.yaml: its constraints hold at the standing pose they were anchored at, their
    Jacobian has full row rank there (12 independent rows), and A qd is the rate of the residual along a motion
    integrated on SE(3) x R^12 (central differences)."""
    robot = jaxskid.load(ROBOTS_DIR / "quadruped_contact.yaml")
    dyn = jaxskid.lower(robot, ["constraint_jacobian", "constraint_residual"])
    q0 = np.concatenate([[0, 0, 0, 0, 0, 0, 1.0], np.tile([0.0, 0.8, -1.6], 4)])
    assert np.abs(np.asarray(dyn.constraint_residual(q0))).max() <= 1e-12
    assert np.linalg.matrix_rank(np.asarray(dyn.constraint_jacobian(q0)), tol=1e-9) == 12
    rng = np.random.default_rng(3)
    q = np.asarray(dyn.integrate(q0, rng.normal(0, 0.1, robot.nv)))
    v, h = rng.normal(size=robot.nv), 1e-6
    rate = (np.asarray(dyn.constraint_residual(dyn.integrate(q, v, h)))
            - np.asarray(dyn.constraint_residual(dyn.integrate(q, v, -h)))) / (2 * h)
    assert np.abs(np.asarray(dyn.constraint_jacobian(q)) @ v - rate).max() <= 1e-8


def kkt(model, q, v, tau, feet=FEET):
    """(qdd, lambda) of M qdd + h = tau + A^T lambda, A qdd = -Adot v, all in Pinocchio's velocity order."""
    data = model.createData()
    m = pin.crba(model, data, q)
    m = np.triu(m) + np.triu(m, 1).T
    h = pin.nonLinearEffects(model, data, q, v)
    pin.computeJointJacobians(model, data, q)
    pin.forwardKinematics(model, data, q, v, np.zeros(model.nv))
    pin.updateFramePlacements(model, data)
    rows, drift = [], []
    for name in feet:
        fid = model.getFrameId(name)
        rows.append(pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3])
        drift.append(pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL_WORLD_ALIGNED).linear)
    a, drift = np.vstack(rows), np.concatenate(drift)
    k = np.block([[m, -a.T], [a, np.zeros((len(a), len(a)))]])
    sol = np.linalg.solve(k, np.concatenate([tau - h, -drift]))
    return sol[: model.nv], sol[model.nv:]


def test_constrained_dynamics_matches_a_kkt_solve_on_pinocchio(standing):
    robot, dyn, model = standing
    rng = np.random.default_rng(0)
    for _ in range(3):
        q = np.concatenate([rng.normal(0, 0.1, 3), pin.Quaternion(pin.exp3(rng.normal(0, 0.3, 3))).coeffs(),
                            STAND + rng.normal(0, 0.2, 12)])
        v, tau = rng.normal(0, 1.0, robot.nv), np.concatenate([np.zeros(6), rng.normal(0, 2.0, 12)])
        qdd, lam = dyn.constrained_forward_dynamics(q, v, tau)
        qdd_ref, lam_ref = kkt(model, q, to_pin(v), to_pin(tau))
        assert np.abs(to_pin(np.asarray(qdd)) - qdd_ref).max() <= 1e-9 * max(1, np.abs(qdd_ref).max())
        assert np.abs(np.asarray(lam) - lam_ref).max() <= 1e-9 * max(1, np.abs(lam_ref).max())


@pytest.mark.slow
def test_stabilised_rollout_keeps_the_feet_in_place(standing):
    """Standing on its four feet with the joints driven by PD around the standing pose: over 2 s of RK4 at 1 ms
    the feet stay on their anchors and the base quaternion unit-norm."""
    robot, dyn, _ = standing
    q0 = np.concatenate([[0, 0, 0], [0, 0, 0, 1.0], STAND])  # the configuration the anchors were taken at
    x0 = np.concatenate([q0, np.zeros(robot.nv)])

    def sway(t, x):
        q = x[: robot.nq]
        return jnp.concatenate([jnp.zeros(6), 0.3 * jnp.sin(3 * t) - 2.0 * (q[7:] - STAND)])

    traj = jaxskid.rollout(dyn, x0, sway, 1e-3, 2000, saveat=jaxskid.SaveAt(every=100))
    q, qd = np.asarray(traj.q), np.asarray(traj.qd)
    residual = np.abs(np.asarray(dyn.constraint_residual(q))).max()
    velocity = np.abs(np.einsum("tij,tj->ti", np.asarray(dyn.constraint_jacobian(q)), qd)).max()
    assert residual <= 1e-8 and velocity <= 1e-8, (residual, velocity)
    assert np.abs(np.linalg.norm(q[:, 3:7], axis=1) - 1).max() <= 1e-12
    assert np.abs(q[-1, 7:]).max() > 1e-3  # it moved
