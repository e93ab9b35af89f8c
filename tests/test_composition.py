"""Rollouts under every composition of JAX's transformations, with policies that close over traced values.

A user's loss builds its policy inside the loss, capturing what is being differentiated (the gains being
learnt, the parameters being identified), and reads other values from the enclosing module. Each case
differentiates such a loss with respect to a scalar ``theta`` that scales one captured or passed value (the
PD gains, the initial state, the inertial parameters, the step; the policy reads the state through an index
array made inside the loss, an integer tracer under ``jax.jit``) under ``jax.grad``, ``jax.jit``, ``jaxskid.jit``,
``jax.vmap``, ``jax.jacfwd`` and ``jax.hessian`` and their compositions, with the rollout's default
``autodiff``; the first derivatives are checked against central differences of the loss, the second against
the central second difference.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxskid
from helpers import ROBOTS_DIR

STEPS = 100
X0 = jnp.asarray([0.4, -0.3, 0.0, 0.0])  # module-level: closed over, not passed
KP, KD = jnp.asarray([30.0, 20.0]), jnp.asarray([4.0, 3.0])
THETA = 0.05
KINDS = ("gains", "x0", "params", "dt")


@pytest.fixture(scope="module")
def dyn():
    return jaxskid.lower(jaxskid.load(ROBOTS_DIR / "arm_2r.yaml"), ["forward_dynamics", "gravity_torques"])


def _loss(dyn, kind):
    n, p0 = dyn.n_dof, dyn.param_vector()

    def loss(theta):
        kp = KP * (1 + theta) if kind == "gains" else KP
        x0 = X0 * (1 + theta) if kind == "x0" else X0
        p = p0 * (1 + 0.1 * theta) if kind == "params" else None
        dt = 2e-3 * (1 + theta) if kind == "dt" else 2e-3

        joints = jnp.arange(n)  # an index array made inside the loss: an integer tracer under jax.jit

        def policy(t, x):  # PD towards zero with gravity compensation from the same parameters
            q = x[joints]
            return -kp * q - KD * x[n + joints] + dyn.gravity_torques(q, p)

        traj = jaxskid.rollout(dyn, x0, policy, dt, STEPS, params=p)
        return jnp.sum(traj.q[-1] ** 2) + jnp.mean(traj.qd**2)

    return loss


def _vmapped(fn):
    return lambda theta: jax.vmap(fn)(jnp.stack([theta, theta + 0.01]))[0]


TRANSFORMS = {  # name: (transform, the derivative's order)
    "grad": (jax.grad, 1),
    "jit(grad)": (lambda f: jax.jit(jax.grad(f)), 1),
    "jaxskid.jit(grad)": (lambda f: jaxskid.jit(jax.grad(f)), 1),
    "vmap(grad)": (lambda f: _vmapped(jax.grad(f)), 1),
    "jit(vmap(grad))": (lambda f: jax.jit(_vmapped(jax.grad(f))), 1),
    "jacfwd": (jax.jacfwd, 1),
    "jaxskid.jit(jacfwd)": (lambda f: jaxskid.jit(jax.jacfwd(f)), 1),
    "vmap(jacfwd)": (lambda f: _vmapped(jax.jacfwd(f)), 1),
    "hessian": (jax.hessian, 2),
    "jit(hessian)": (lambda f: jax.jit(jax.hessian(f)), 2),
    "jacfwd(grad)": (lambda f: jax.jacfwd(jax.grad(f)), 2),
}


@pytest.fixture(scope="module")
def differences(dyn):
    """Central first and second differences of each kind's loss at THETA, evaluated at the top level."""
    out = {}
    for kind in KINDS:
        loss = _loss(dyn, kind)
        h1, h2 = 1e-5, 1e-3
        first = (loss(THETA + h1) - loss(THETA - h1)) / (2 * h1)
        second = (loss(THETA + h2) - 2 * loss(THETA) + loss(THETA - h2)) / h2**2
        out[kind] = (float(first), float(second))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("transform", list(TRANSFORMS))
def test_derivative_under_each_composition(dyn, differences, kind, transform):
    """First derivatives against the central difference (1e-6), second ones against the central second
    difference (1e-5, its own truncation error)."""
    fn, order = TRANSFORMS[transform]
    got = float(fn(_loss(dyn, kind))(jnp.asarray(THETA)))
    want, tol = differences[kind][order - 1], (1e-6, 1e-5)[order - 1]
    assert abs(got - want) <= tol * max(1.0, abs(want)), (got, want)


def test_policy_closing_over_traced_gains_inside_a_callers_jit(dyn):
    """The gains traced by the caller's ``jax.jit`` (no differentiation): the rollout runs nested, and its
    result equals the one with the gains as constants."""
    n = dyn.n_dof

    def final(kp):
        traj = jaxskid.rollout(dyn, X0, lambda t, x: -kp * x[:n] - KD * x[n:], 2e-3, STEPS)
        return traj.x[-1]

    np.testing.assert_allclose(np.asarray(jax.jit(final)(KP)), np.asarray(final(KP)), rtol=1e-12, atol=1e-14)


def test_auto_autodiff_picks_forward_mode_only_under_jvp(dyn):
    """``autodiff="reverse"`` refuses forward mode (a ``custom_vjp``); the default serves both."""
    n = dyn.n_dof

    def loss(theta, autodiff):
        traj = jaxskid.rollout(dyn, X0, lambda t, x: -KP * (1 + theta) * x[:n] - KD * x[n:], 2e-3, 20,
                               autodiff=autodiff)
        return jnp.sum(traj.q[-1] ** 2)

    with pytest.raises(TypeError, match="custom_vjp"):
        jax.jacfwd(lambda th: loss(th, "reverse"))(THETA)
    np.testing.assert_allclose(float(jax.jacfwd(lambda th: loss(th, "auto"))(THETA)),
                               float(jax.grad(lambda th: loss(th, "reverse"))(THETA)), rtol=1e-12)
