"""A function bound as one primitive (:mod:`jaxskid.runtime._whole`): the same values, maps and derivatives
as the function itself, and partial evaluation of a loop around it keeps it whole.

The function here is a small closed form with parameter-only subexpressions (the kind JAX hoists out of a
loop when it is not wrapped). Derivatives are checked against central differences.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.extend.core import jaxprs_in_params

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
