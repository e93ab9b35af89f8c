"""Gradients through rollouts, against independent references.

The rollout's derivatives come from closed-form rules (:mod:`jaxskid.runtime._implicit`): the symbolic
vector-Jacobian product of inverse dynamics in reverse mode, the implicit-function derivative in forward
mode. They are checked against central differences of the rollout itself, and against complex-step
derivatives (Squire & Trapp, SIAM Review 40, 1998: ``f'(x) = Im f(x + i h) / h``, exact to rounding) of a
separate rollout: RK4 written here over the numeric recursive Newton-Euler and CRBA of
:mod:`jaxskid.testing` with a dense complex solve.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import load

import jaxskid
from jaxskid.testing._recursive import recursive_dynamics

STEPS, DT = 12, 0.02


@pytest.fixture(scope="module")
def arm():
    robot = load("arm_3dof")
    dyn = jaxskid.lower(robot, quantities=["forward_dynamics"])
    n = dyn.n_dof
    rng = np.random.default_rng(3)
    x0 = jnp.asarray(np.r_[rng.uniform(-1, 1, n), rng.uniform(-2, 2, n)])
    u = jnp.asarray(rng.normal(size=(STEPS, n)))
    return robot, dyn, x0, u


def _loss(dyn, autodiff="reverse"):
    def loss(p, x0, u):
        x = jaxskid.rollout(dyn, x0, u, DT, STEPS, params=p, autodiff=autodiff).x
        return jnp.sum(jnp.sin(x) * jnp.arange(1, x.shape[-1] + 1)[None, :])

    return loss


def _central(f, x, h=1e-6):
    x = np.asarray(x, float)
    out = np.zeros(x.size)
    for k in range(x.size):
        e = np.zeros(x.size)
        e[k] = h
        out[k] = (f(jnp.asarray(x + e.reshape(x.shape))) - f(jnp.asarray(x - e.reshape(x.shape)))) / (2 * h)
    return out.reshape(x.shape)


def test_reverse_mode_matches_central_differences(arm):
    _, dyn, x0, u = arm
    p = dyn.param_vector()
    loss = jax.jit(_loss(dyn))
    grads = jax.jit(jax.grad(_loss(dyn), argnums=(0, 1, 2)))(p, x0, u)
    refs = (_central(lambda v: loss(v, x0, u), p), _central(lambda v: loss(p, v, u), x0),
            _central(lambda v: loss(p, x0, v), u))
    for g, ref, what in zip(grads, refs, ("params", "x0", "controls")):
        np.testing.assert_allclose(g, ref, rtol=1e-6, atol=1e-7 * np.abs(ref).max(), err_msg=what)


def test_forward_mode_equals_reverse_mode(arm):
    _, dyn, x0, u = arm
    p = dyn.param_vector()
    rev = jax.grad(_loss(dyn), argnums=(0, 1, 2))(p, x0, u)
    fwd = jax.jacfwd(_loss(dyn, "forward"), argnums=(0, 1, 2))(p, x0, u)
    for a, b in zip(rev, fwd):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12 * np.abs(b).max())


def _complex_rollout(rec, p, x0, u):
    """RK4 over the numeric recursive dynamics, in complex arithmetic."""
    n = x0.shape[0] // 2

    def f(x, tau):
        q, qd = x[:n], x[n:]
        bias = rec.inverse_dynamics(q, qd, jnp.zeros_like(q), p)
        return jnp.concatenate([qd, jnp.linalg.solve(rec.mass_matrix(q, p), tau - bias)])

    def step(x, tau):
        k1 = f(x, tau)
        k2 = f(x + DT / 2 * k1, tau)
        k3 = f(x + DT / 2 * k2, tau)
        k4 = f(x + DT * k3, tau)
        x = x + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return x, x

    _, xs = jax.lax.scan(step, x0, u)
    x = jnp.concatenate([x0[None], xs])
    return jnp.sum(jnp.sin(x) * jnp.arange(1, x.shape[-1] + 1)[None, :])


@pytest.mark.slow
def test_gradients_match_complex_step_of_an_independent_rollout(arm):
    robot, dyn, x0, u = arm
    rec = recursive_dynamics(robot)
    p = dyn.param_vector()
    run = jax.jit(lambda p, x0, u: _complex_rollout(rec, p, x0, u))
    loss = _loss(dyn)
    base = [jnp.asarray(a, complex) for a in (p, x0, u)]  # complex throughout: one compiled reference
    np.testing.assert_allclose(loss(p, x0, u), jnp.real(run(*base)), rtol=1e-12)
    grads = jax.grad(loss, argnums=(0, 1, 2))(p, x0, u)
    h = 1e-30
    pick = np.random.default_rng(0)
    for arg, g in enumerate(grads):
        for k in pick.choice(g.size, size=min(g.size, 5), replace=False):  # a sample of the directions
            args = list(base)
            args[arg] = (base[arg].ravel().at[k].add(1j * h)).reshape(g.shape)
            ref = float(jnp.imag(run(*args))) / h
            np.testing.assert_allclose(g.ravel()[k], ref, rtol=1e-9, atol=1e-11 * float(jnp.abs(g).max()))


def test_batched_gradient_is_the_sum_of_single_ones(arm):
    _, dyn, x0, u = arm
    p = dyn.param_vector()
    x0s = jnp.stack([x0, 0.5 * x0, -x0])
    ps = jnp.stack([p, 1.1 * p, 0.9 * p])

    def batched(ps):
        x = jaxskid.rollout(dyn, x0s, u, DT, STEPS, params=ps).x
        return jnp.sum(jnp.sin(x))

    def single(p, x0):
        return jnp.sum(jnp.sin(jaxskid.rollout(dyn, x0, u, DT, STEPS, params=p).x))

    got = jax.grad(batched)(ps)
    for k in range(3):
        np.testing.assert_allclose(got[k], jax.grad(single)(ps[k], x0s[k]), rtol=1e-11, atol=1e-13)


def test_vjp_of_inverse_dynamics_matches_autodiff():
    dyn = jaxskid.lower(load("prr"), quantities=["inverse_dynamics", "inverse_dynamics_vjp"])
    rng = np.random.default_rng(5)
    q, qd, qdd, w = (jnp.asarray(rng.normal(size=dyn.n_dof)) for _ in range(4))
    p = dyn.param_vector()
    _, pullback = jax.vjp(lambda q, qd, p: dyn.inverse_dynamics(q, qd, qdd, p), q, qd, p)
    ref = jnp.concatenate(pullback(w))
    got = dyn.inverse_dynamics_vjp(q, qd, qdd, w, p)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * float(jnp.abs(ref).max()))


def test_bad_autodiff_is_a_clear_error(arm):
    _, dyn, x0, u = arm
    with pytest.raises(jaxskid.RequestError, match="autodiff must be one of"):
        jaxskid.rollout(dyn, x0, u, DT, STEPS, autodiff="backward")
