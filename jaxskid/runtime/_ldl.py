"""The unrolled square-root-free Cholesky solve ``M x = b`` that forward dynamics and its derivative use.

``M = L D L^T`` (Golub & Van Loan, "Matrix Computations", 4th ed., Alg. 4.1.2), written entry by entry so
that XLA fuses it with the computation of ``M`` and ``b`` into one kernel.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax
import jax.numpy as jnp

from .._fused import recip


def assemble(values: Sequence, dtype) -> jax.Array:
    """A vector from scalars (``None``: zero) by a chain of ``where`` selects (the output form XLA fuses
    into one loop, see :mod:`jaxskid.codegen._jax`); ``jnp.stack`` would split the computation into slow
    kernels."""
    out = jnp.zeros((len(values),), dtype)
    index = jnp.arange(len(values))
    for k, v in enumerate(values):
        if v is not None:
            out = jnp.where(index == k, v, out)
    return out


_reciprocal = recip
"""``1 / d`` by Newton's iteration from a bit-level first guess, the same as in generated modules
(:mod:`jaxskid._fused`): XLA on CPU will not fuse a division whose result has several users, so
each pivot reciprocal of the factorisation would cut the fused kernel in pieces that recompute their
shared inputs (slower per state, and slower still with a division per entry)."""


def ldl_solve(m: jax.Array, b: jax.Array) -> jax.Array:
    """Solve ``m x = b`` for one symmetric positive definite ``m`` (n, n) by ``m = L D L^T``, unrolled.

    Square-root free Cholesky (Golub & Van Loan, Alg. 4.1.2), written entry by entry so that XLA fuses it
    with the computation of ``m`` and ``b``; vmap it for a batch. A matrix that is not positive definite
    (a pivot <= 0, e.g. from non-physical inertial parameters) gives nan, as ``jnp.linalg.cholesky`` does.
    """
    return ldl_substitute(ldl_factor(m), b)


def ldl_factor(m: jax.Array) -> tuple[list, list]:
    """The factors of ``m = L D L^T`` (n, n) as scalars: ``(L, 1 / D)``, ``L[i][j]`` for ``j < i``; solve with
    them by :func:`ldl_substitute`, once per right-hand side (:func:`ldl_solve`)."""
    n = m.shape[-1]
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
    return lo, dinv


def ldl_substitute(factor: tuple[list, list], b: jax.Array) -> jax.Array:
    """``x`` with ``L D L^T x = b``, from the factors of :func:`ldl_factor`: forward then back substitution."""
    lo, dinv = factor
    n = b.shape[-1]
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
    return assemble(x, b.dtype)


@jax.custom_jvp
def materialize(x: jax.Array) -> jax.Array:
    """``x``, computed once. XLA on CPU fuses a producer made of cheap operations into every consumer
    fusion, so chaining accelerations (the stages of RK4) recomputed each stage inside the next one's
    kernels, an evaluation in a chain of four costing several times one alone. A dot is never fused on
    CPU and ``optimization_barrier`` is dropped by the compiler, so
    ``x @ I`` (n^2 multiply-adds) materialises ``x``. Its derivative is the identity, not a second dot
    (nor a third, its transpose, in reverse mode)."""
    return x @ jnp.eye(x.shape[-1], dtype=x.dtype)


@materialize.defjvp
def _materialize_jvp(primals, tangents):
    return materialize(primals[0]), tangents[0]
