"""Forward dynamics: the joint accelerations from the lowered quantities.

Forward dynamics solves the equations of motion for the accelerations,

    M(q) qdd = tau - C(q, qd) qd - Q_grav(q) - Q_ext(q, W),

in closed form when the quantity ``forward_dynamics`` was lowered (:mod:`jaxskid.symbolic._forward`),
otherwise with the bias ``C qd + Q_grav`` from one recursive Newton-Euler pass (``inverse_dynamics`` at
``qdd = 0``, measured faster than ``coriolis_torques + gravity_torques``) and an unrolled square-root-free
Cholesky factorisation ``M = L D L^T`` (Golub & Van Loan, "Matrix Computations", 4th ed., Alg. 4.1.2).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial

import jax
import jax.numpy as jnp

from .._errors import RequestError
from .._kernels import recip
from ._batching import batch_shape, float_arrays, vmapped
from ._jit import jit
from ._parameters import param_array


def _assemble(values: Sequence, dtype) -> jax.Array:
    """A vector from scalars by a chain of ``where`` selects (the output form XLA fuses into one loop,
    see :mod:`jaxskid.codegen._jax`); ``jnp.stack`` would split the computation into slow kernels."""
    out = jnp.zeros((len(values),), dtype)
    index = jnp.arange(len(values))
    for k, v in enumerate(values):
        out = jnp.where(index == k, v, out)
    return out


_reciprocal = recip
"""``1 / d`` by Newton's iteration from a bit-level first guess, the same as in generated modules
(:mod:`jaxskid._kernels`): XLA on CPU will not fuse a division whose result has several users, so
each pivot reciprocal of the factorisation would cut the fused kernel in pieces that recompute their
shared inputs (measured: 1.2 us instead of 0.9 us per Panda state, and 5 us with a division per entry)."""


def _materialize(x: jax.Array) -> jax.Array:
    """``x``, computed once. XLA on CPU fuses a producer made of cheap operations into every consumer
    fusion, so chaining accelerations (the stages of RK4) recomputed each stage inside the next one's
    kernels: 0.46 us per evaluation alone, 1.4 us per evaluation in a chain of four (3-DOF arm, batch
    1024). A dot is never fused on CPU and ``optimization_barrier`` is dropped by the compiler, so
    ``x @ I`` (n^2 multiply-adds) materialises ``x``."""
    return x @ jnp.eye(x.shape[-1], dtype=x.dtype)


def ldl_solve(m: jax.Array, b: jax.Array) -> jax.Array:
    """Solve ``m x = b`` for one symmetric positive definite ``m`` (n, n) by ``m = L D L^T``, unrolled.

    Square-root free Cholesky (Golub & Van Loan, Alg. 4.1.2), written entry by entry so that XLA fuses it
    with the computation of ``m`` and ``b``; vmap it for a batch. A matrix that is not positive definite
    (a pivot <= 0, e.g. from non-physical inertial parameters) gives nan, as ``jnp.linalg.cholesky`` does.
    """
    n = b.shape[-1]
    lo = [[None] * n for _ in range(n)]
    d, dinv = [None] * n, [None] * n
    for j in range(n):
        s = m[j, j]
        for k in range(j):
            s = s - lo[j][k] * lo[j][k] * d[k]
        d[j], dinv[j] = s, jnp.where(s > 0, _reciprocal(s), jnp.nan)  # as jnp.linalg.cholesky: nan if not SPD
        for i in range(j + 1, n):
            s = m[i, j]
            for k in range(j):
                s = s - lo[i][k] * lo[j][k] * d[k]
            lo[i][j] = s * dinv[j]
    y = [None] * n
    for i in range(n):  # L y = b
        s = b[i]
        for k in range(i):
            s = s - lo[i][k] * y[k]
        y[i] = s
    x = [None] * n
    for i in reversed(range(n)):  # D L^T x = y
        s = y[i] * dinv[i]
        for k in range(i + 1, n):
            s = s - lo[k][i] * x[k]
        x[i] = s
    return _assemble(x, b.dtype)


def _with_implicit_derivative(solve: Callable, mass: Callable, inverse: Callable) -> Callable:
    """``solve`` with the derivative of the equations of motion it solves, ``ID(q, qd, qdd, p) = tau``:

        d qdd = M(q)^-1 (d tau - dID/dq dq - dID/dqd dqd - Y(q, qd, qdd) dp),

    one forward-mode pass of inverse dynamics at the computed ``qdd`` and one solve with M (the implicit
    function theorem; Carpentier & Mansard, "Analytical derivatives of rigid body dynamics algorithms",
    RSS 2018, sec. IV). Reverse mode transposes it: one reverse pass of inverse dynamics.
    """

    @jax.custom_jvp
    def fd(q, qd, tau, p):
        return solve(q, qd, tau, p)

    @jax.checkpoint
    def tangent(q, qd, a, p, dq, dqd, dtau, dp):
        _, did = jax.jvp(lambda q, qd, p: inverse(q, qd, a, p), (q, qd, p), (dq, dqd, dp))
        return ldl_solve(mass(q, p), dtau - did)

    @fd.defjvp
    def rule(primals, tangents):
        q, qd, tau, p = primals
        a = fd(q, qd, tau, p)
        return a, tangent(q, qd, a, p, *tangents)

    return fd


def require_solver(dyn, what: str) -> None:
    """Raise :class:`RequestError` unless ``dyn`` has the quantities :func:`accelerations` needs."""
    have = set(dyn.quantities)
    if "forward_dynamics" in have:
        return
    if "mass_matrix" not in have or not ({"inverse_dynamics"} <= have or {"coriolis_torques", "gravity_torques"} <= have):
        raise RequestError(
            f"{what} needs the quantity forward_dynamics, or mass_matrix and inverse_dynamics (or "
            f"coriolis_torques and gravity_torques); lowered: {', '.join(dyn.quantities)}. Ask for them with "
            "jaxskid.lower(robot, quantities=[..., 'forward_dynamics'])"
        )


def _bias(dyn, raw: Callable) -> Callable:
    """``b(q, qd, p) = C(q, qd) qd + Q_grav(q)`` from the lowered quantities."""
    if "inverse_dynamics" in dyn.quantities:
        rnea = raw("inverse_dynamics")
        return lambda q, qd, p: rnea(q, qd, jnp.zeros_like(qd), p)
    cor, grav = raw("coriolis_torques"), raw("gravity_torques")
    return lambda q, qd, p: cor(q, qd, p) + grav(q, p)


def accelerations(dyn, batched: bool = True) -> Callable:
    """The single-state function ``qdd(q, qd, tau, p, wrench=None)`` with ``p`` a parameter vector.

    With the quantity ``forward_dynamics`` lowered, this is the closed form (:mod:`jaxskid.symbolic._forward`);
    otherwise M and the bias are evaluated and solved by :func:`ldl_solve`. ``batched``: whether the
    function will be mapped with ``jax.vmap`` (see :meth:`jaxskid.Dynamics.raw`).
    """
    require_solver(dyn, "forward_dynamics")

    def raw(name: str) -> Callable:
        return dyn.raw(name, batched)

    if "forward_dynamics" in dyn.quantities:
        solve = raw("forward_dynamics")
    else:
        mass, bias = raw("mass_matrix"), _bias(dyn, raw)

        def solve(q, qd, tau, p):
            return ldl_solve(mass(q, p), tau - bias(q, qd, p))

    if {"mass_matrix", "inverse_dynamics"} <= set(dyn.quantities):
        solve = _with_implicit_derivative(solve, dyn.raw("mass_matrix", False), dyn.raw("inverse_dynamics", False))

    def qdd(q, qd, tau, p, wrench=None):
        if wrench is not None:
            tau = tau - raw("external_torques")(q, wrench, p)
        return _materialize(solve(q, qd, tau, p))

    return qdd


@partial(jit, static_argnames=("dyn",))
def _forward_dynamics(dyn, q, qd, tau, params, wrench):
    (q, qd, tau), dtype = float_arrays((q, qd, tau))
    p = param_array(dyn.layout, params, dtype)
    extras = [("params", p.shape, (len(dyn.parameters),))]
    if wrench is not None:
        wrench = jnp.asarray(wrench, dtype)
        extras.append(("wrench", wrench.shape, (len(dyn.end_effectors), 6)))
    n = (dyn.n_dof,)
    batch = batch_shape("forward_dynamics", [("q", q.shape, n), ("qd", qd.shape, n), ("tau", tau.shape, n)], extras)
    f = accelerations(dyn, batched=bool(batch))
    if not batch:
        return f(q, qd, tau, p, wrench)
    return vmapped(f, batch, [(q, 1), (qd, 1), (tau, 1), (p, 1), (wrench, 2)])


def forward_dynamics(dyn, q, qd, tau, params=None, wrench=None) -> jax.Array:
    """Joint accelerations ``qdd = M(q)^-1 (tau - C(q, qd) qd - Q_grav(q) - Q_ext(q, W))``.

    Args:
        dyn: a :class:`~jaxskid.Dynamics` lowered with ``forward_dynamics`` (the closed form, fastest), or
            with ``mass_matrix`` and ``inverse_dynamics`` (or ``coriolis_torques`` and ``gravity_torques``);
            with ``external_torques`` too if ``wrench`` is given.
        q, qd, tau: shape ``(n,)``, or ``(..., n)`` for a batch (the same for the three).
        params: ``None`` (defaults), a dict name -> value (missing names take their defaults), or a vector
            ``(n_params,)``; a batch of vectors ``(..., n_params)`` or a dict of batched values broadcasts
            against the batch of the states.
        wrench: end-effector wrenches ``(n_ee, 6)`` (moment, force), exerted by the robot on its
            environment, as in ``inverse_dynamics``; ``(..., n_ee, 6)`` for a batch.

    Returns:
        qdd ``(..., n)``. One jitted call; a dict of plain numbers is packed on the host before it.
    """
    require_solver(dyn, "forward_dynamics")
    if wrench is not None and "external_torques" not in dyn.quantities:
        raise RequestError("forward_dynamics with a wrench needs the quantity external_torques; lower it too")
    return _forward_dynamics(dyn, q, qd, tau, dyn._packed(params), wrench)


def mass_matrix_condition(dyn, q, params=None) -> jax.Array:
    """The 2-norm condition number ``lambda_max / lambda_min`` of ``M(q)``, shape ``q.shape[:-1]``.

    A large value warns that :func:`forward_dynamics` loses about ``log10(cond)`` digits; ``inf`` means M
    is not positive definite in floating point.
    """
    m = dyn.mass_matrix(q, params)
    ev = jnp.linalg.eigvalsh(m)
    return jnp.where(ev[..., 0] > 0, ev[..., -1] / ev[..., 0], jnp.inf)
