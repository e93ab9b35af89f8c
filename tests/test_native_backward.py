"""The native backward step of forward dynamics (jaxskid.runtime._ffi, jaxskid.lowering._ffi).

On CPU the reverse-mode rule of forward dynamics runs ``lambda = M^-1 g`` and the vector-Jacobian product
of inverse dynamics as one C kernel inside the XLA program. Checked here against the JAX kernels it
replaces and against references independent of both: ``lambda`` against NumPy's dense solve with the
recursive CRBA of jaxskid.testing, and the gradient of a rollout against central differences; float32,
batches with shared and per-state parameters, gradients of gradients, the off switch and a machine
without a C compiler.
"""

from __future__ import annotations

import logging

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import load

import jaxskid
from jaxskid.lowering._ffi_batch import BACKWARD_CHUNK
from jaxskid.runtime._ffi import native_backward
from jaxskid.runtime._ldl import ldl_solve
from jaxskid.testing._recursive import recursive_dynamics


@pytest.fixture(scope="module", params=["arm_3dof", "hopping_leg"])
def case(request):
    robot = load(request.param)
    dyn = jaxskid.lower(robot, quantities=["forward_dynamics"])
    target = dyn.native_target()
    assert target is not None, "a C compiler is required (apt-get install gcc)"
    mass, vjp = dyn.generated("mass_matrix"), dyn.generated("inverse_dynamics_vjp")

    def pure(q, qd, a, g, p):
        lam = ldl_solve(mass(q, p), g)
        return lam, -vjp(q, qd, a, lam, p)

    kernel = native_backward(target, dyn.n_dof, 2 * dyn.n_dof + len(dyn.parameters), pure)
    return robot, dyn, kernel, pure


def _states(n, batch, seed=0):
    rng = np.random.default_rng(seed)
    return [jnp.asarray(rng.uniform(-2, 2, (*batch, n))) for _ in range(4)]


def test_the_kernel_matches_the_jax_kernels_and_a_dense_solve(case):
    robot, dyn, kernel, pure = case
    p = dyn.param_vector()
    q, qd, a, g = _states(dyn.n_dof, (2 * BACKWARD_CHUNK + 5,))  # chunks shared by XLA's threads
    lam, v = jax.jit(jax.vmap(kernel, (0, 0, 0, 0, None)))(q, qd, a, g, p)
    lam_ref, v_ref = jax.vmap(pure, (0, 0, 0, 0, None))(q, qd, a, g, p)
    np.testing.assert_allclose(lam, lam_ref, rtol=1e-11, atol=1e-11 * float(jnp.abs(lam_ref).max()))
    np.testing.assert_allclose(v, v_ref, rtol=1e-11, atol=1e-11 * float(jnp.abs(v_ref).max()))
    rec = recursive_dynamics(robot)
    for i in range(2):  # lambda = M^-1 g with M from the recursive CRBA
        m = np.asarray(rec.mass_matrix(q[i], rec.param_vector(dict(zip(dyn.parameters, np.asarray(p))))))
        np.testing.assert_allclose(lam[i], np.linalg.solve(m, np.asarray(g[i])), rtol=1e-9, atol=1e-12)


def test_per_state_parameters_single_states_and_float32(case):
    _, dyn, kernel, pure = case
    p = dyn.param_vector()
    count = BACKWARD_CHUNK + 3
    ps = p[None, :] * jnp.linspace(0.5, 1.5, count)[:, None]  # one parameter vector per state
    q, qd, a, g = _states(dyn.n_dof, (count,), seed=1)
    got = jax.jit(jax.vmap(kernel))(q, qd, a, g, ps)
    ref = jax.vmap(pure)(q, qd, a, g, ps)
    for x, r in zip(got, ref):
        np.testing.assert_allclose(x, r, rtol=1e-11, atol=1e-11 * float(jnp.abs(r).max()))
    one = jax.jit(kernel)(q[0], qd[0], a[0], g[0], p)  # no batch axis
    np.testing.assert_allclose(one[1], pure(q[0], qd[0], a[0], g[0], p)[1], rtol=1e-11, atol=1e-9)
    lo = [x.astype(jnp.float32) for x in (q[0], qd[0], a[0], g[0], p)]
    lam32, v32 = jax.jit(kernel)(*lo)
    assert lam32.dtype == v32.dtype == jnp.float32
    lam64, v64 = pure(*[x.astype(jnp.float64) for x in lo])
    np.testing.assert_allclose(v32, v64, rtol=1e-4, atol=1e-4 * float(jnp.abs(v64).max()))
    np.testing.assert_allclose(lam32, lam64, rtol=1e-4, atol=1e-4 * float(jnp.abs(lam64).max()))


def _rollout_loss(dyn, steps=8, dt=0.01):
    n = dyn.n_dof
    rng = np.random.default_rng(4)
    x0 = jnp.asarray(np.r_[rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)])
    u = jnp.asarray(rng.normal(size=(steps, n)))

    def loss(p):
        return jnp.sum(jaxskid.rollout(dyn, x0, u, dt, steps, params=p).x ** 2)

    return loss


def test_rollout_gradient_and_its_derivative(case):
    _, dyn, _, _ = case
    loss, p = _rollout_loss(dyn), dyn.param_vector()
    grad = jax.jit(jax.grad(loss))
    g = grad(p)
    f = jax.jit(loss)
    k = int(jnp.argmax(jnp.abs(g)))
    h = 1e-6 * max(1.0, abs(float(p[k])))
    e = jnp.zeros_like(p).at[k].set(h)
    assert abs(float(g[k]) - float(f(p + e) - f(p - e)) / (2 * h)) < 1e-6 * max(1.0, abs(float(g[k])))
    # a gradient of the gradient differentiates the JAX form of the kernel: a Hessian-vector product
    d = jnp.asarray(np.random.default_rng(5).normal(size=p.shape)) * jnp.abs(p)
    hvp = jax.jit(lambda p: jax.jvp(jax.grad(loss), (p,), (d,))[1])(p)
    eps = 1e-6
    fd = (grad(p + eps * d) - grad(p - eps * d)) / (2 * eps)
    np.testing.assert_allclose(hvp, fd, rtol=1e-5, atol=1e-5 * float(jnp.abs(fd).max()))


def test_off_switch_and_no_compiler(monkeypatch, tmp_path, caplog):
    robot = load("arm_3dof")
    monkeypatch.setenv("JAXSKID_NATIVE", "0")
    off = jaxskid.lower(robot, quantities=["forward_dynamics"])
    assert off.native_target() is None
    monkeypatch.delenv("JAXSKID_NATIVE")
    monkeypatch.setenv("CC", "/nonexistent/cc")
    bare = jaxskid.lower(robot, quantities=["forward_dynamics"], cache_dir=tmp_path)
    with caplog.at_level(logging.WARNING, logger="jaxskid"):
        assert bare.native_target() is None
    assert any("native kernels" in r.getMessage() and "no C compiler" in r.getMessage() for r in caplog.records)
    monkeypatch.delenv("CC")
    on = jaxskid.lower(robot, quantities=["forward_dynamics"], cache_dir=tmp_path / "on")
    assert on.native_target() is not None
    p = off.param_vector()
    g_off = jax.jit(jax.grad(_rollout_loss(off)))(p)
    g_bare = jax.jit(jax.grad(_rollout_loss(bare)))(p)
    g_on = jax.jit(jax.grad(_rollout_loss(on)))(p)
    np.testing.assert_allclose(g_on, g_off, rtol=1e-11, atol=1e-11 * float(jnp.abs(g_off).max()))
    # without a compiler the step's backward pass runs the same recursion in JAX (jaxskid.runtime._rk4)
    np.testing.assert_allclose(g_bare, g_off, rtol=1e-11, atol=1e-11 * float(jnp.abs(g_off).max()))
