"""Controllers: closed-loop behaviour against closed forms and Lyapunov functions, the mixed regressor
against Pinocchio's Coriolis matrix.

References: the linear error dynamics of computed-torque control (closed-form solution), Pinocchio's
``crba``, ``computeCoriolisMatrix`` and ``computeGeneralizedGravity``, and the Lyapunov functions of PD +
gravity compensation and of Slotine-Li, computed from the true model.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest

import jaxskid
from jaxskid import reference_derivatives
from jaxskid.apps.identification._identification import random_states
from helpers import random_tree_regressor

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def arm():
    robot = jaxskid.load(REPO / "robots/arm_2r.yaml")
    return robot, jaxskid.lower(robot, ["mass_matrix", "inverse_dynamics", "gravity_torques", "regressor"])


def reference(t):
    return jnp.stack([0.8 * jnp.sin(1.1 * t) + 0.5 * jnp.sin(2.9 * t), 1.0 * jnp.cos(1.7 * t) + 0.4 * jnp.sin(3.7 * t)])


def test_reference_derivatives_closed_form():
    q, v, a = reference_derivatives(reference, 0.7)
    t = 0.7
    np.testing.assert_allclose(np.asarray(v), [0.88 * np.cos(1.1 * t) + 1.45 * np.cos(2.9 * t),
                                               -1.7 * np.sin(1.7 * t) + 1.48 * np.cos(3.7 * t)], rtol=1e-13)
    np.testing.assert_allclose(np.asarray(a), [-0.968 * np.sin(1.1 * t) - 4.205 * np.sin(2.9 * t),
                                               -2.89 * np.cos(1.7 * t) - 5.476 * np.sin(3.7 * t)], rtol=1e-13)


def test_mixed_regressor_matches_pinocchio_coriolis_matrix():
    """Y(q, qd, v, a) pi = M a + C(q, qd) v + Q_grav with Pinocchio's C (the Christoffel one)."""
    rng = np.random.default_rng(1)
    _, dyn, params, pi, model, data = random_tree_regressor(rng, 4, prismatic=0.3)
    q, qd, _ = random_states(4, 3, seed=2)
    v, a = rng.normal(size=(2, 3, 4))
    for k in range(3):
        y = np.asarray(jaxskid.mixed_regressor(dyn, q[k], qd[k], v[k], a[k], params))
        ref = (pin.crba(model, data, q[k]) @ a[k] + pin.computeCoriolisMatrix(model, data, q[k], qd[k]) @ v[k]
               + pin.computeGeneralizedGravity(model, data, q[k]))
        np.testing.assert_allclose(y @ pi, ref, atol=1e-10)


def test_computed_torque_error_follows_linear_dynamics(arm):
    """With the exact model, e = q_d - q obeys e'' + kd e' + kp e = 0: compare with its closed form."""
    robot, dyn = arm
    kp, kd = 25.0, 6.0  # underdamped: e = e0 exp(-3t) (cos 4t + 3/4 sin 4t) for e'(0) = 0
    e0 = np.array([0.2, -0.1])
    x0 = jnp.concatenate([reference(0.0) - e0, reference_derivatives(reference, 0.0)[1]])
    traj = jaxskid.rollout(dyn, x0, jaxskid.ComputedTorque(dyn, reference, kp, kd), 1e-3, 2000)
    t = np.asarray(traj.t)
    e = np.asarray(jax.vmap(reference)(traj.t)) - np.asarray(traj.q)
    closed = (np.exp(-3 * t) * (np.cos(4 * t) + 0.75 * np.sin(4 * t)))[:, None] * e0
    np.testing.assert_allclose(e, closed, atol=1e-9)


def test_pd_gravity_regulates_with_decreasing_lyapunov(arm):
    """Set-point regulation: V = 1/2 qd^T M qd + 1/2 kp |q_d - q|^2 never increases; q reaches q_d."""
    robot, dyn = arm
    goal = jnp.array([0.7, -1.2])
    kp, kd = 30.0, 8.0
    traj = jaxskid.rollout(dyn, jnp.array([-0.5, 0.8, 0.0, 0.0]), jaxskid.PDGravity(dyn, goal, kp, kd), 2e-3, 4000)
    q, qd = traj.q, traj.qd
    m = dyn.mass_matrix(q)
    lyap = np.asarray(0.5 * jnp.einsum("ti,tij,tj->t", qd, m, qd) + 0.5 * kp * jnp.sum((goal[None] - q) ** 2, axis=-1))
    assert np.diff(lyap).max() < 1e-9 * lyap[0]
    assert np.abs(np.asarray(q[-1] - goal)).max() < 1e-6


def test_slotine_li_tracking_error_goes_to_zero(arm):
    """From zero parameter estimates: V = 1/2 s^T M s + 1/2 pi~^T gamma^-1 pi~ never increases (computed
    with the true model), the tracking error decays by orders of magnitude and the estimates approach the
    true base parameters."""
    robot, dyn = arm
    base = jaxskid.base_parameters(dyn)
    truth = base.project(jaxskid.standard_params(robot))
    ts = jnp.linspace(0.0, 20.0, 501)
    q, v, a = jax.vmap(lambda t: reference_derivatives(reference, t))(ts)
    y = np.asarray(base.reduce(dyn.regressor(q, v, a)))
    gamma = 20.0 / np.einsum("tip,tip->p", y, y) * len(ts)  # kd / (mean squared column): balanced rates
    ctrl = jaxskid.SlotineLi(dyn, reference, jnp.zeros(base.n_base), lam=10.0, kd=20.0, gamma=gamma, base=base)
    x0 = jnp.concatenate([reference(0.0) + 0.2, jnp.zeros(2)])
    traj = jaxskid.rollout(dyn, x0, ctrl, 2e-3, 15_000)
    err = np.abs(np.asarray(traj.q) - np.asarray(jax.vmap(reference)(traj.t))).max(axis=1)
    windows = err[:-1].reshape(6, -1).max(axis=1)  # 5 s each
    assert windows[-1] < 2e-3 * windows[0]
    assert np.all(np.diff(windows[1:]) < 0.5 * windows[1:-1])  # keeps decreasing after the transient

    def lyapunov(t, x, z):
        _, s = ctrl.regressor(t, x)
        return 0.5 * s @ dyn.mass_matrix(x[:2]) @ s + 0.5 * jnp.sum((z - truth) ** 2 / gamma)

    lyap = np.asarray(jax.vmap(lyapunov)(traj.t, traj.x, traj.z))
    assert np.diff(lyap).max() < 1e-9 * lyap[0]
    est = np.asarray(traj.z)
    assert np.abs(est[-1] - truth).max() < 0.05 * np.abs(est[0] - truth).max()
