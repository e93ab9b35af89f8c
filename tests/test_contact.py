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
    dyn = jaxskid.lower(robot, ["forward_dynamics", *jaxskid.apps.simulation._contact.NEEDED])
    model = pin.buildModelFromUrdf(str(URDFS["solo12"]), pin.JointModelFreeFlyer())
    return robot, dyn, model


def to_pin(v):
    return np.concatenate([v[3:6], v[:3], v[6:]])


def reference_forces(model, q, v, radius=0.0):
    """The contact law of jaxskid.apps.simulation._contact on Pinocchio's kinematics: (forces (4, 3), generalized force in
    Pinocchio's velocity order). With a ``radius``, each foot is a sphere around its frame, touching the ground at
    the material point ``radius`` below its centre, whose velocity and Jacobian are those of that point."""
    data = model.createData()
    pin.forwardKinematics(model, data, q, to_pin(v))
    pin.updateFramePlacements(model, data)
    pin.computeJointJacobians(model, data, q)
    forces, tau = [], np.zeros(model.nv)
    for name in FEET:
        fid = model.getFrameId(name)
        lever = np.array([0.0, 0.0, -radius])  # frame -> contact point, world axes
        p = data.oMf[fid].translation + lever
        frame_jac = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
        jac = frame_jac[:3] - pin.skew(lever) @ frame_jac[3:]  # v_point = v + omega x lever
        vel = jac @ to_pin(v)
        depth = HEIGHT - p[2]
        fn = max(K * depth - C * vel[2], 0.0) if depth > 0 else 0.0
        ft = -MU * fn * vel[:2] / np.sqrt(vel[:2] @ vel[:2] + SLIP**2)
        f = np.array([*ft, fn])
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


def test_sphere_contact_matches_pinocchio_kinematics(solo):
    """Feet as spheres (frames given with a radius): the force acts at the lowest point of each sphere, with that
    point's velocity, as Pinocchio's Jacobian of the point gives them."""
    _, dyn, model = solo
    radius = 0.015
    contact = jaxskid.GroundContact(dyn, dict.fromkeys(FEET, radius), stiffness=K, damping=C, friction=MU,
                                    slip=SLIP, height=HEIGHT)
    assert contact.frames == FEET and np.all(contact.radius == radius)
    rng = np.random.default_rng(2)
    for _ in range(4):
        q = np.concatenate([[0.1, -0.05, 0.235 + rng.uniform(-0.03, 0.01)], pin.Quaternion(pin.exp3(
            rng.normal(0, 0.3, 3))).coeffs(), STAND + rng.normal(0, 0.2, 12)])
        v = rng.normal(0, 0.5, model.nv)
        f_ref, tau_ref = reference_forces(model, q, v, radius)
        points, f, tau = contact.forces(jnp.asarray(q), jnp.asarray(v))
        assert np.abs(np.asarray(f) - f_ref).max() <= 1e-9 * max(1.0, np.abs(f_ref).max())
        assert np.abs(to_pin(np.asarray(tau)) - tau_ref).max() <= 1e-9 * max(1.0, np.abs(tau_ref).max())
        assert (f_ref[:, 2] > 0).any() and (f_ref[:, :2] != 0).any()


def test_contact_frames_are_checked_and_named(solo):
    _, dyn, _ = solo
    contact = jaxskid.GroundContact(dyn, FEET[:2])
    assert "FL_FOOT, FR_FOOT" in repr(contact) and contact.on_base() == ()
    with pytest.raises(jaxskid.RequestError, match=r"frames: .*'FL_FOT' \(did you mean 'FL_FOOT'"):
        jaxskid.GroundContact(dyn, ["FL_FOT"])
    with pytest.raises(jaxskid.RequestError, match=r"frames\['FL_FOOT'\]: expected a radius >= 0 \[m\], got -0.1"):
        jaxskid.GroundContact(dyn, {"FL_FOOT": -0.1})


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
