"""A function bound as one primitive (:mod:`jaxskid.runtime._whole`): the same values, maps and derivatives
as the function itself, and partial evaluation of a loop around it keeps it whole.

The function here is a small closed form with parameter-only subexpressions (the kind JAX hoists out of a
loop when it is not wrapped). Derivatives are checked against central differences.
"""

from __future__ import annotations

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
from jax.extend.core import jaxprs_in_params

from helpers import ROBOTS_DIR

from jaxskid.runtime import _whole
from jaxskid.runtime._whole import whole


def _f(q, p):
    return jnp.sin(q) * (p[0] * p[1] + p[2] ** 2) + jnp.cos(q[::-1]) * jnp.exp(p[1] - p[0])


_g = whole(_f, like=0)
_rng = np.random.default_rng(11)
_q = jnp.asarray(_rng.normal(size=4))
_p = jnp.asarray(_rng.uniform(0.5, 1.5, size=3))


def test_values_and_maps_equal_the_function():
    np.testing.assert_array_equal(_g(_q, _p), _f(_q, _p))
    np.testing.assert_array_equal(jax.jit(_g)(_q, _p), jax.jit(_f)(_q, _p))
    qs = jnp.asarray(_rng.normal(size=(5, 4)))
    ps = jnp.asarray(_rng.uniform(0.5, 1.5, size=(5, 3)))
    np.testing.assert_allclose(jax.vmap(_g, (0, None))(qs, _p), jax.vmap(_f, (0, None))(qs, _p), rtol=1e-15)
    np.testing.assert_allclose(jax.vmap(_g)(qs, ps), jax.vmap(_f)(qs, ps), rtol=1e-15)
    nested = jax.vmap(jax.vmap(_g, (None, 0)), (0, None))(qs, ps)
    assert nested.shape == (5, 5, 4)
    np.testing.assert_allclose(nested[2, 3], _f(qs[2], ps[3]), rtol=1e-15)


def test_derivatives_match_central_differences():
    def loss(p):
        return jnp.sum(_g(_q, p) ** 2)

    grad = jax.grad(loss)(_p)
    jac = jax.jacfwd(lambda p: _g(_q, p))(_p)
    h = 1e-6
    for k in range(3):
        e = jnp.zeros(3).at[k].set(h)
        np.testing.assert_allclose(grad[k], (loss(_p + e) - loss(_p - e)) / (2 * h), rtol=1e-7)
        np.testing.assert_allclose(jac[:, k], (_f(_q, _p + e) - _f(_q, _p - e)) / (2 * h), rtol=1e-7, atol=1e-9)
    hess = jax.hessian(loss)(_p)
    fd = jnp.stack([(jax.grad(loss)(_p + jnp.zeros(3).at[k].set(h)) - jax.grad(loss)(_p - jnp.zeros(3).at[k].set(h)))
                    / (2 * h) for k in range(3)])
    np.testing.assert_allclose(hess, fd, rtol=1e-6)


def test_a_loop_keeps_it_whole_under_reverse_mode():
    """Linearising a scan that closes over ``p`` hoists the ``p``-only work of a derivative rule's forward
    pass out of the loop (as for forward dynamics in a rollout, :mod:`jaxskid.runtime._implicit`); with the
    forward pass wrapped, the function stays one equation inside the loop and nothing of it is hoisted."""

    def with_rule(forward):
        @jax.custom_vjp
        def f(q, p):
            return _f(q, p)

        def fwd(q, p):
            return forward(q, p), (q, p)

        def bwd(res, g):
            return jax.vjp(_f, *res)[1](g)

        f.defvjp(fwd, bwd)
        return f

    def rollout(p, body):
        def step(q, _):
            return q + 0.01 * body(q, p), None

        return jnp.sum(jax.lax.scan(step, _q, None, length=3)[0])

    def primitives(jaxpr, out):
        for eqn in jaxpr.eqns:
            out.append(eqn.primitive.name)
            for sub in jaxprs_in_params(eqn.params):
                primitives(sub, out)
        return out

    def forward_pass(body):
        return jax.make_jaxpr(lambda p: jax.vjp(lambda p: rollout(p, body), p)[0])(_p).jaxpr

    wrapped, plain = forward_pass(with_rule(_g)), forward_pass(with_rule(_f))
    assert primitives(wrapped, []).count("jaxskid_whole") == 1
    assert "exp" not in [e.primitive.name for e in wrapped.eqns]  # nothing of _f hoisted out of the loop
    assert "exp" in [e.primitive.name for e in plain.eqns]  # unwrapped, p-only work is hoisted
    np.testing.assert_allclose(jax.grad(rollout)(_p, with_rule(_g)), jax.grad(rollout)(_p, _f), rtol=1e-14)


def test_a_stored_function_is_lowered_from_its_export(tmp_path):
    """With a store, the first program that lowers the function keeps its export; a new primitive of the same
    key (as a new process would make) lowers that export without calling the function, with the same
    values, maps and gradients; another key or argument type makes its own."""
    calls = []

    def counted(q, p):
        calls.append(1)
        return _f(q, p)

    def fresh(key=("f", "1")):  # what a new process builds: a new primitive, nothing traced yet
        return whole(counted, like=0, store=(tmp_path, key))

    first = jax.jit(lambda q, p: 2.0 * fresh()(q, p))(_q, _p)
    assert len(list(tmp_path.glob("*.jaxexport"))) == 1
    _whole._EXPORTED.clear()
    before = len(calls)
    again = jax.jit(lambda q, p: 3.0 * fresh()(q, p))(_q, _p)
    assert len(calls) == before, "the stored export is read, not the function traced"
    np.testing.assert_allclose(again, 1.5 * first, rtol=1e-15)
    np.testing.assert_allclose(first, 2.0 * _f(_q, _p), rtol=1e-15)
    qs = jnp.asarray(_rng.normal(size=(3, 4)))
    mapped = jax.jit(jax.vmap(fresh(), (0, None)))(qs, _p)  # a map has its own export
    np.testing.assert_allclose(mapped, jax.vmap(_f, (0, None))(qs, _p), rtol=1e-15)
    grad = jax.jit(jax.grad(lambda p: jnp.sum(fresh()(_q, p) ** 2)))(_p)
    np.testing.assert_allclose(grad, jax.grad(lambda p: jnp.sum(_f(_q, p) ** 2))(_p), rtol=1e-13)
    jax.jit(fresh(("f", "2")))(_q, _p)  # another key
    jax.jit(fresh())(_q.astype(jnp.float32), _p.astype(jnp.float32))  # another argument type
    assert len(list(tmp_path.glob("*.jaxexport"))) == 4


def test_a_rollout_in_a_new_process_reads_the_stored_forward_dynamics(tmp_path):
    """The rollout's forward dynamics is stored beside the cached module; a second process lowers the
    rollout without tracing the closed form and gets the same states."""
    script = (
        "import sys, jax\n"
        "jax.config.update('jax_enable_x64', True)\n"
        "import jax.numpy as jnp, numpy as np, jaxskid\n"
        "from jaxskid.runtime import _whole\n"
        "dyn = jaxskid.lower(jaxskid.load(sys.argv[1]), ['forward_dynamics'])\n"
        "stored = {p.name for p in (dyn.path.parent / 'exports').glob('*.jaxexport')}\n"
        "x = jaxskid.rollout(dyn, jnp.full(2 * dyn.n_dof, 0.3), jnp.ones((20, dyn.n_dof)), 1e-3, 20).x\n"
        "used = {p.name for p, e in _whole._EXPORTED.items() if e is not None}\n"
        "print(len(used), used <= stored, repr(np.asarray(x).tolist()))\n"
    )
    robot = ROBOTS_DIR / "double_pendulum.yaml"
    env = dict(os.environ, JAXSKID_CACHE_DIR=str(tmp_path))
    runs = [subprocess.run([sys.executable, "-c", script, str(robot)], env=env, capture_output=True, text=True,
                           check=True).stdout for _ in range(2)]
    first, second = (run.split(" ", 2) for run in runs)
    assert first[:2] == ["1", "False"]  # made and stored by the first process
    assert second[:2] == ["1", "True"]  # read back by the second
    assert first[2] == second[2]
