"""Compliant ground contact (jaxskid.GroundContact) on the floating-base solo12: the contact law against the
same law evaluated on Pinocchio's frame placements, velocities and Jacobians, and its gradient against central
differences. Dropped robots that come to rest carrying their weight: tests/test_examples.py::test_quadruped_drop."""

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
from helpers import URDFS

import jaxskid

FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
STAND = np.array([0, 0.8, -1.6, 0, 0.8, -1.6, 0, -0.8, 1.6, 0, -0.8, 1.6])
K, C, MU, SLIP, HEIGHT = 5e3, 50.0, 0.8, 5e-2, 0.02


@pytest.fixture(scope="module")
def solo():
    robot = jaxskid.load(URDFS["solo12"], floating_base=True)
    dyn = jaxskid.lower(robot, ["forward_dynamics", *jaxskid.apps._contact.NEEDED])
    model = pin.buildModelFromUrdf(str(URDFS["solo12"]), pin.JointModelFreeFlyer())
    return robot, dyn, model


def to_pin(v):
    return np.concatenate([v[3:6], v[:3], v[6:]])


def reference_forces(model, q, v):
    """The contact law of jaxskid.apps._contact on Pinocchio's kinematics: (forces (4, 3), generalized force in
    Pinocchio's velocity order)."""
    data = model.createData()
    pin.forwardKinematics(model, data, q, to_pin(v))
    pin.updateFramePlacements(model, data)
    pin.computeJointJacobians(model, data, q)
    forces, tau = [], np.zeros(model.nv)
    for name in FEET:
        fid = model.getFrameId(name)
        p = data.oMf[fid].translation
        vel = pin.getFrameVelocity(model, data, fid, pin.LOCAL_WORLD_ALIGNED).linear
        depth = HEIGHT - p[2]
        fn = max(K * depth - C * vel[2], 0.0) if depth > 0 else 0.0
        ft = -MU * fn * vel[:2] / np.sqrt(vel[:2] @ vel[:2] + SLIP**2)
        f = np.array([*ft, fn])
        jac = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
        forces.append(f)
        tau += jac.T @ f
    return np.array(forces), tau


def test_contact_law_matches_pinocchio_kinematics(solo):
    _, dyn, model = solo
    contact = jaxskid.GroundContact(dyn, FEET, stiffness=K, damping=C, friction=MU, slip=SLIP, height=HEIGHT)
    rng = np.random.default_rng(0)
    for _ in range(4):
        q = np.concatenate([[0.1, -0.05, 0.22 + rng.uniform(-0.03, 0.01)], pin.Quaternion(pin.exp3(
            rng.normal(0, 0.1, 3))).coeffs(), STAND + rng.normal(0, 0.1, 12)])
        v = rng.normal(0, 0.5, model.nv)
        f_ref, tau_ref = reference_forces(model, q, v)
        _, f, tau = contact.forces(jnp.asarray(q), jnp.asarray(v))
        assert np.abs(np.asarray(f) - f_ref).max() <= 1e-9 * max(1.0, np.abs(f_ref).max())
        assert np.abs(to_pin(np.asarray(tau)) - tau_ref).max() <= 1e-9 * max(1.0, np.abs(tau_ref).max())
        assert (f_ref[:, 2] > 0).any()  # some feet are in contact at these heights


def test_contact_gradient_matches_finite_differences(solo):
    """d tau_c / d stiffness through the contact law, by forward differences of the whole law."""
    _, dyn, model = solo
    q = np.concatenate([[0.0, 0.0, 0.205], [0, 0, 0, 1.0], STAND])
    v = np.random.default_rng(1).normal(0, 0.3, model.nv)

    def tau(k):
        law = jaxskid.GroundContact(dyn, FEET, stiffness=k, damping=C, friction=MU, slip=SLIP, height=HEIGHT)
        return law.forces(jnp.asarray(q), jnp.asarray(v))[2]

    grad = np.asarray(jax.jacfwd(tau)(K))
    h = 1e-3
    fd = (np.asarray(tau(K + h)) - np.asarray(tau(K - h))) / (2 * h)
    assert np.abs(grad - fd).max() <= 1e-6 * np.abs(fd).max() and np.abs(fd).max() > 0
