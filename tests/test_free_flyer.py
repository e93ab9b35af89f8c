"""Integration and difference on a floating base's configuration space, against Pinocchio's ``integrate`` and
``difference`` for a ``JointModelFreeFlyer`` root, and their derivatives against finite differences (also at
zero rotation, where the sin/cos quotients switch to their series)."""

import jax
import numpy as np
import pinocchio as pin
import pytest
from helpers import URDFS

from jaxskid.runtime import _free_flyer as ff


@pytest.fixture(scope="module")
def model():
    return pin.buildModelFromUrdf(str(URDFS["solo12"]), pin.JointModelFreeFlyer())


def to_pin(v):
    """jaxskid's velocity (omega, v, qd_j) in Pinocchio's order (v, omega, qd_j)."""
    return np.concatenate([v[3:6], v[:3], v[6:]])


def same_configuration(a, b):
    """Max difference of two configurations, the quaternions compared up to sign."""
    quat = min(np.abs(a[3:7] - b[3:7]).max(), np.abs(a[3:7] + b[3:7]).max())
    return max(np.abs(a[:3] - b[:3]).max(), quat, np.abs(a[7:] - b[7:]).max())


@pytest.mark.parametrize("scale", [0.0, 1e-7, 1e-3, 1.0, 3.0])
def test_integrate_and_difference_match_pinocchio(model, scale):
    rng = np.random.default_rng(int(scale * 1e3) + 1)
    for _ in range(4):
        q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        v = rng.normal(size=model.nv) * scale
        ours = np.asarray(ff.integrate(q, v, 0.7, True))
        ref = pin.integrate(model, q, to_pin(v) * 0.7)
        assert same_configuration(ours, ref) < 1e-13
        assert np.abs(to_pin(np.asarray(ff.difference(q, ref, True))) - pin.difference(model, q, ref)).max() < 1e-12


def test_difference_of_distant_configurations(model):
    """Rotations up to pi apart: log picks the shortest rotation, as Pinocchio's does."""
    for seed in range(20):
        q0 = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        q1 = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
        d = np.asarray(ff.difference(q0, q1, True))
        assert np.abs(to_pin(d) - pin.difference(model, q0, q1)).max() < 1e-10
        assert same_configuration(np.asarray(ff.integrate(q0, d, 1.0, True)), q1) < 1e-12


def test_unnormalized_quaternion_is_its_rotation(model):
    q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
    v = np.random.default_rng(3).normal(size=model.nv)
    scaled = q.copy()
    scaled[3:7] *= 2.5
    assert same_configuration(np.asarray(ff.integrate(scaled, v, 0.1, True)), np.asarray(ff.integrate(q, v, 0.1, True))) < 1e-14
    assert np.abs(np.asarray(ff.normalize(scaled, True)) - q).max() < 1e-15


@pytest.mark.parametrize("scale", [0.0, 1.0])
def test_derivatives_are_finite_and_match_differences(model, scale):
    rng = np.random.default_rng(7)
    q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
    v = rng.normal(size=model.nv) * scale
    jac = np.asarray(jax.jacfwd(lambda x: ff.integrate(q, x, 1.0, True))(v))
    h = 1e-6
    fd = np.stack([(np.asarray(ff.integrate(q, v + h * e, 1.0, True)) - np.asarray(ff.integrate(q, v - h * e, 1.0, True)))
                   / (2 * h) for e in np.eye(model.nv)], axis=1)
    assert np.isfinite(jac).all() and np.abs(jac - fd).max() < 1e-8
    q1 = np.asarray(ff.integrate(q, v, 1.0, True))
    jd = np.asarray(jax.jacrev(lambda x: ff.difference(q, x, True))(q1))
    assert np.isfinite(jd).all()
    # d difference(q, integrate(q1, w)) / dw at w = 0 is the right Jacobian's inverse: check it by the chain rule
    chain = np.asarray(jax.jacfwd(lambda w: ff.difference(q, ff.integrate(q1, w, 1.0, True), True))(np.zeros(model.nv)))
    fd = np.stack([(np.asarray(ff.difference(q, ff.integrate(q1, h * e, 1.0, True), True))
                    - np.asarray(ff.difference(q, ff.integrate(q1, -h * e, 1.0, True), True))) / (2 * h)
                   for e in np.eye(model.nv)], axis=1)
    assert np.abs(chain - fd).max() < 1e-7


def test_configuration_rate_is_the_derivative_of_integrate(model):
    q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
    v = np.random.default_rng(11).normal(size=model.nv)
    h = 1e-6
    fd = (np.asarray(ff.integrate(q, v, h, True)) - np.asarray(ff.integrate(q, v, -h, True))) / (2 * h)
    assert np.abs(np.asarray(ff.configuration_rate(q, v, True)) - fd).max() < 1e-9


def test_fixed_base_is_flat():
    q, v = np.arange(3.0), np.ones(3)
    assert np.allclose(ff.integrate(q, v, 0.5, False), q + 0.5)
    assert np.allclose(ff.difference(q, q + v, False), v)
    assert np.allclose(ff.configuration_rate(q, v, False), v)
