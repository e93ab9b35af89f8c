"""The backward pass of an RK4 step under a held torque, or under feedback from a controller, as one native call
(jaxskid.runtime._rk4, jaxskid.lowering._ffi_rk4).

Its cotangents with respect to q, qd, tau, the parameters and the step size are checked against JAX's reverse
mode through the same step written stage by stage (``RK4.step`` over forward dynamics with its forward-mode
rule, which never calls the native kernels) and against central differences; in a batch, in float32, through
its JAX fallback, and inside a rollout's gradient.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import load

import jaxskid
from jaxskid.apps.simulation._integrators import RK4
from jaxskid.runtime._forward import accelerations
from jaxskid.runtime._rk4 import feedback_rk4, held_torque_rk4


@pytest.fixture(scope="module", params=["arm_3dof", "hopping_leg"])
def dyn(request):
    dyn = jaxskid.lower(load(request.param), quantities=["forward_dynamics"])
    assert dyn.native_target("rk4_vjp") is not None, "a C compiler is required (apt-get install gcc)"
    return dyn


def _reference(dyn):
    qdd = accelerations(dyn, False, "forward")

    def step(q, qd, tau, p, h):
        def f(t, y):
            return (y[1], qdd(y[0], y[1], tau, p)), ()

        return RK4().step(f, 0.0, (q, qd), h)[0]

    return step


def _args(dyn, seed=0, batch=()):
    rng = np.random.default_rng(seed)
    n = dyn.n_dof
    q, qd, tau = (jnp.asarray(rng.uniform(-1.5, 1.5, (*batch, n))) for _ in range(3))
    return q, qd, 5.0 * tau, dyn.param_vector(), jnp.asarray(0.01)


def _close(got, ref, rtol):
    for x, r in zip(got, ref):
        np.testing.assert_allclose(x, r, rtol=rtol, atol=rtol * max(1.0, float(jnp.abs(r).max())))


def test_step_and_its_cotangents_match_jax_reverse_mode(dyn):
    fused, ref = held_torque_rk4(dyn, False), _reference(dyn)
    args = _args(dyn)
    y, vjp = jax.vjp(fused, *args)
    y_ref, vjp_ref = jax.vjp(ref, *args)
    _close(y, y_ref, 1e-14)
    rng = np.random.default_rng(1)
    g = tuple(jnp.asarray(rng.normal(size=dyn.n_dof)) for _ in range(2))
    got = jax.jit(vjp)(g)
    _close(got, vjp_ref(g), 1e-10)
    # central differences along a random direction of all five inputs
    d = [jnp.asarray(rng.normal(size=np.shape(x))) * (1.0 if i < 3 else jnp.abs(x)) for i, x in enumerate(args)]
    d[4] = jnp.asarray(1e-3)

    def inner(eps):
        out = fused(*(x + eps * dx for x, dx in zip(args, d)))
        return sum(jnp.vdot(a, b) for a, b in zip(g, out))

    eps = 1e-6
    fd = (inner(eps) - inner(-eps)) / (2 * eps)
    ad = sum(jnp.vdot(a, b) for a, b in zip(got, d))
    assert abs(float(fd - ad)) < 1e-6 * max(1.0, abs(float(ad))), (float(fd), float(ad))


def test_a_batch_float32_and_the_jax_fallback(dyn, monkeypatch):
    fused, ref = held_torque_rk4(dyn, True), _reference(dyn)
    q, qd, tau, p, h = _args(dyn, seed=2, batch=(9,))
    w = jnp.asarray(np.random.default_rng(3).normal(size=(9, dyn.n_dof)))

    def loss(step, q, qd, tau, p, h):
        q1, qd1 = jax.vmap(step, (0, 0, 0, None, None))(q, qd, tau, p, h)
        return jnp.sum(w * q1) + jnp.sum(w * qd1 ** 2)

    grad = jax.grad(loss, argnums=(1, 2, 3, 4, 5))
    want = grad(ref, q, qd, tau, p, h)
    _close(jax.jit(grad, static_argnums=0)(fused, q, qd, tau, p, h), want, 1e-10)
    lo = [x.astype(jnp.float32) for x in (q, qd, tau, p, h)]
    got32 = jax.jit(grad, static_argnums=0)(fused, *lo)
    assert all(x.dtype == jnp.float32 for x in got32)
    _close(got32, want, 2e-3)
    # without the native kernel the same recursion runs in JAX
    monkeypatch.setattr(dyn, "native_target", lambda name="fd_vjp": None)
    _close(jax.jit(grad, static_argnums=0)(held_torque_rk4(dyn, True), q, qd, tau, p, h), want, 1e-10)


def test_a_rollout_gradient_calls_it_once_per_step(dyn):
    """Open-loop torques on a fixed base: the compiled gradient of a rollout holds one call of the step's
    backward kernel (inside the loop over the steps) and none of the per-stage one."""
    n, steps = dyn.n_dof, 6
    rng = np.random.default_rng(4)
    x0 = jnp.asarray(rng.uniform(-1, 1, 2 * n))
    u = jnp.asarray(rng.normal(size=(steps, n)))

    def loss(p):
        return jnp.sum(jaxskid.rollout(dyn, x0, u, 0.01, steps, params=p, integrator=RK4()).x ** 2)

    p = dyn.param_vector()
    text = jax.jit(jax.grad(loss)).lower(p).as_text()
    assert text.count("jaxskid_rk4_vjp") == 1 and "jaxskid_fd_vjp" not in text
    g = jax.jit(jax.grad(loss))(p)
    k = int(jnp.argmax(jnp.abs(g)))
    eps = 1e-6 * max(1.0, abs(float(p[k])))
    e = jnp.zeros_like(p).at[k].set(eps)
    fd = (float(loss(p + e)) - float(loss(p - e))) / (2 * eps)
    assert abs(float(g[k]) - fd) < 1e-6 * max(1.0, abs(fd))


def test_checkpointed_rollout_gradient_keeps_less(dyn):
    """With ``Checkpoint()`` the gradient through open-loop torques (one backward call per step) keeps blocks of
    steps: at 400 and 1600 steps its temporaries grow about as sqrt(steps), the plain gradient's as steps, and
    both give the same gradient."""
    n = dyn.n_dof
    x0 = jnp.asarray(np.r_[np.full(n, 0.3), np.zeros(n)])
    temp = {}
    for steps in (400, 1600):
        u = jnp.asarray(np.random.default_rng(6).normal(size=(steps, n)))
        for checkpoint in (None, jaxskid.Checkpoint()):
            def loss(p):
                x = jaxskid.rollout(dyn, x0, u, 1e-3, steps, params=p, saveat=jaxskid.SaveAt(t1=True),
                                    checkpoint=checkpoint).x
                return jnp.sum(x * x)

            fn = jax.jit(jax.grad(loss), compiler_options=jaxskid.compiler_options()).lower(dyn.param_vector())
            fn = fn.compile()
            temp[steps, checkpoint is None] = (fn.memory_analysis().temp_size_in_bytes, fn(dyn.param_vector()))
        np.testing.assert_allclose(temp[steps, False][1], temp[steps, True][1], rtol=1e-12, atol=0)
    assert temp[1600, True][0] > 3.5 * temp[400, True][0]  # every step kept: linear
    assert temp[1600, False][0] < 2.2 * temp[400, False][0]  # blocks of steps: about sqrt


# ---------------------------------------------------------------- under feedback


def _control(t, x, kp, p_scale):
    """A nonlinear law of time, state, gains and a scale: ``kp (sin(t) - q) - 0.3 qd + p_scale sin(q) qd``."""
    n = x.shape[-1] // 2
    q, qd = x[:n], x[n:]
    return kp * (jnp.sin(t) - q) - 0.3 * qd + p_scale * jnp.sin(q) * qd


def _feedback_reference(dyn):
    qdd = accelerations(dyn, False, "forward")

    def step(q, qd, p, h, t, kp, scale):
        def f(s, y):
            tau = _control(s, jnp.concatenate(y), kp, scale)
            return (y[1], qdd(y[0], y[1], tau, p)), tau

        (q1, qd1), tau = RK4().step(f, t, (q, qd), h)
        return q1, qd1, tau

    return step


def _feedback_args(dyn, seed=0, batch=()):
    rng = np.random.default_rng(seed)
    n = dyn.n_dof
    q, qd = (jnp.asarray(rng.uniform(-1.5, 1.5, (*batch, n))) for _ in range(2))
    return q, qd, dyn.param_vector(), jnp.asarray(0.01), jnp.asarray(0.3), jnp.asarray(rng.uniform(1, 3, n)), \
        jnp.asarray(0.7)


def test_feedback_step_and_its_cotangents_match_jax_reverse_mode(dyn, monkeypatch):
    """Cotangents of q, qd, the parameters, the step, the time and the controller's gains and scale (the first
    stage's torque is an output too), against JAX's reverse mode stage by stage; then the JAX fallback."""
    step, ref = feedback_rk4(dyn, False), _feedback_reference(dyn)
    args = _feedback_args(dyn)

    def fused(q, qd, p, h, t, kp, scale):
        return step(_control, q, qd, p, h, t, (kp, scale))

    y, vjp = jax.vjp(fused, *args)
    y_ref, vjp_ref = jax.vjp(ref, *args)
    _close(y, y_ref, 1e-14)
    rng = np.random.default_rng(1)
    g = tuple(jnp.asarray(rng.normal(size=dyn.n_dof)) for _ in range(3))
    want = vjp_ref(g)
    _close(jax.jit(vjp)(g), want, 1e-10)
    monkeypatch.setattr(dyn, "native_target", lambda name="fd_vjp": None)
    step = feedback_rk4(dyn, False)
    _close(jax.vjp(fused, *args)[1](g), want, 1e-10)


def test_feedback_step_in_a_batch_and_in_float32(dyn):
    step, ref = feedback_rk4(dyn, True), _feedback_reference(dyn)
    q, qd, p, h, t, kp, scale = _feedback_args(dyn, seed=2, batch=(7,))
    w = jnp.asarray(np.random.default_rng(3).normal(size=(7, dyn.n_dof)))

    def loss(which, q, qd, p, h, kp):
        run = (lambda *a: step(_control, *a[:5], (a[5], scale))) if which == "fused" else \
            (lambda *a: ref(*a, scale))
        q1, qd1, tau = jax.vmap(run, (0, 0, None, None, None, None))(q, qd, p, h, t, kp)
        return jnp.sum(w * q1) + jnp.sum(w * qd1**2) + jnp.sum(w * tau)

    grad = jax.jit(jax.grad(loss, argnums=(1, 2, 3, 4, 5)), static_argnums=0)
    want = grad("reference", q, qd, p, h, kp)
    _close(grad("fused", q, qd, p, h, kp), want, 1e-10)
    got32 = grad("fused", *(x.astype(jnp.float32) for x in (q, qd, p, h, kp)))
    assert all(x.dtype == jnp.float32 for x in got32)
    _close(got32, want, 2e-3)


def test_a_closed_loop_rollout_gradient_calls_it_once_per_step(dyn):
    """A policy closing over traced gains: the compiled gradient holds one call of the feedback kernel and
    none of the per-stage one; the gains' gradient agrees with central differences."""
    n, steps = dyn.n_dof, 6
    x0 = jnp.asarray(np.random.default_rng(5).uniform(-1, 1, 2 * n))

    def loss(kp):
        traj = jaxskid.rollout(dyn, x0, lambda t, x: _control(t, x, kp, 0.5), 0.01, steps)
        return jnp.sum(traj.x**2)

    kp = jnp.full(n, 2.0)
    text = jax.jit(jax.grad(loss)).lower(kp).as_text()
    assert text.count("jaxskid_rk4fb_vjp") == 1 and "jaxskid_fd_vjp" not in text
    g, eps = jax.jit(jax.grad(loss))(kp), 1e-6
    for k in range(n):
        e = jnp.zeros(n).at[k].set(eps)
        fd = (float(loss(kp + e)) - float(loss(kp - e))) / (2 * eps)
        assert abs(float(g[k]) - fd) < 1e-6 * max(1.0, abs(fd))
