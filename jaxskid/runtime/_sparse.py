"""Sparse square-root-free Cholesky factorisation on scalars, and the KKT solve of constrained dynamics on it.

The mass matrix of a tree is sparse: ``M[i, j]`` is structurally zero unless one of the two joints supports
the other. Factored from the leaves to the root, ``M = L^T D L``, it has no fill-in at all ("branch-induced
sparsity": Featherstone, "Efficient factorization of the joint-space inertia matrix for branched kinematic
trees", Int. J. Robotics Research 24(6), 2005), and a constraint on a foot touches only the joints on the
foot's path to the root, so ``L^-T A^T`` keeps that path's sparsity too. The generated modules give a
quantity's nonzero entries by name (:meth:`jaxskid.Dynamics.entries`), so the pattern is known when the
program is traced: the factorisation, the substitutions and the Schur complement are written out for exactly
the nonzero entries, every value a scalar of one state. Under ``jax.vmap`` each is one array over the batch
and the whole solve is elementwise, which XLA fuses without materialising any matrix.

The elimination order is the reverse of the velocity coordinates' (children after their parents in jaxskid's
joint order, so leaves go first); for another pattern (mimic couplings, loop closures) the fill-in is
computed symbolically and the factorisation stays exact.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from .._fused import recip
from ._ldl import assemble

Entries = Mapping[int, jax.Array]
"""A matrix's structurally nonzero entries of one state: flat index ``i * columns + j`` -> scalar."""


def minus(s, t):
    """``s - t`` where ``None`` is a structural zero."""
    return -t if s is None else s - t


def plus(s, t):
    """``s + t`` where ``None`` (``s`` only) is a structural zero."""
    return t if s is None else s + t


@dataclass(frozen=True)
class Factor:
    """``P M P^T = L D L^T`` with ``P`` the elimination ``order``: strictly lower ``L`` by position pairs,
    ``1 / D`` by position, and each position's nonzero row and column of ``L``."""

    order: tuple[int, ...]
    lo: dict
    dinv: tuple
    rows: tuple
    cols: tuple


def factor(m: Entries, n: int, order: Sequence[int] | None = None) -> Factor:
    """The sparse factorisation of a symmetric positive definite ``m`` (n, n) from its nonzero entries (both
    triangles). A pivot <= 0 gives nan, as ``jnp.linalg.cholesky`` does."""
    order = tuple(reversed(range(n)) if order is None else order)
    entry = {(a, b): m[order[a] * n + order[b]] for a in range(n) for b in range(n) if order[a] * n + order[b] in m}
    lo, d, dinv = {}, [None] * n, [None] * n
    rows, cols = [[] for _ in range(n)], [[] for _ in range(n)]
    for j in range(n):
        s = entry.get((j, j))
        for k in rows[j]:
            s = minus(s, lo[j, k] * lo[j, k] * d[k])
        s = jnp.zeros(()) if s is None else s
        d[j], dinv[j] = s, jnp.where(s > 0, recip(s), jnp.nan)
        below = {i for i in range(j + 1, n) if (i, j) in entry or (j, i) in entry}
        below |= {i for k in rows[j] for i in cols[k] if i > j}
        for i in sorted(below):
            s = entry.get((i, j), entry.get((j, i)))
            for k in rows[j]:
                if (i, k) in lo:
                    s = minus(s, lo[i, k] * lo[j, k] * d[k])
            lo[i, j] = s * dinv[j]
            rows[i].append(j)
            cols[j].append(i)
    return Factor(order, lo, tuple(dinv), tuple(map(tuple, rows)), tuple(map(tuple, cols)))


def lower(f: Factor, b: Mapping[int, jax.Array]) -> dict[int, jax.Array]:
    """``y`` with ``L y = b``, both by position (missing: zero); ``y`` is nonzero only where ``b`` or one of
    its ancestors in the elimination is."""
    y = {}
    for i in range(len(f.order)):
        s = b.get(i)
        for k in f.rows[i]:
            if k in y:
                s = minus(s, f.lo[i, k] * y[k])
        if s is not None:
            y[i] = s
    return y


def upper(f: Factor, w: Mapping[int, jax.Array]) -> list:
    """``x`` by index (the caller's order) with ``L^T P x = D^-1 w``, ``w`` by position: the second half
    of a solve after :func:`lower`."""
    n = len(f.order)
    x = [None] * n
    for i in reversed(range(n)):
        s = w[i] * f.dinv[i] if i in w else None
        for k in f.cols[i]:
            if x[k] is not None:
                s = minus(s, f.lo[k, i] * x[k])
        x[i] = s
    out = [None] * n
    for i, value in enumerate(x):
        out[f.order[i]] = value
    return out


def by_position(f: Factor, values: Sequence) -> dict[int, jax.Array]:
    """A vector by index (``None``: zero) as a dict by elimination position."""
    return {i: values[k] for i, k in enumerate(f.order) if values[k] is not None}


def solve(f: Factor, b: Sequence) -> list:
    """``x`` with ``M x = b``, both lists of scalars by index (``None``: zero)."""
    return upper(f, lower(f, by_position(f, b)))


def kkt(m: Entries, a: Entries, r1: Sequence, r2: Sequence, eps: float = 0.0) -> tuple[list, list]:
    """``(x, lambda)`` with ``M x - A^T lambda = r1`` and ``A x + eps lambda = r2``, from ``M``'s (n, n) and
    ``A``'s (m, n) nonzero entries and the right-hand sides as lists of scalars (``None``: zero).

    With ``P M P^T = L D L^T``, ``z = L^-1 P r1`` and ``Y = L^-1 P A^T``: ``(Y^T D^-1 Y + eps 1) lambda = r2 -
    Y^T D^-1 z`` (the Schur complement ``A M^-1 A^T``, factored by :func:`factor`), then ``x = P^T
    L^-T D^-1 (z + Y lambda)``. A structurally zero row of ``A`` makes the system singular: every entry is
    nan, unless ``eps > 0``, which gives it ``lambda = 0``.
    """
    n, m_rows = len(r1), len(r2)
    f = factor(m, n)
    z = lower(f, by_position(f, r1))
    y = [lower(f, by_position(f, [a.get(c * n + k) for k in range(n)])) for c in range(m_rows)]
    dy = [{i: v * f.dinv[i] for i, v in col.items()} for col in y]
    s, rhs = {}, []
    for c in range(m_rows):
        for e in range(c + 1):
            total = eps if c == e and eps else None
            for i, v in dy[c].items():
                if i in y[e]:
                    total = plus(total, v * y[e][i])
            if total is not None:
                s[c * m_rows + e] = s[e * m_rows + c] = total
        t = r2[c]
        for i, v in dy[c].items():
            if i in z:
                t = minus(t, v * z[i])
        rhs.append(t)
    if any(c * m_rows + c not in s for c in range(m_rows)):  # a row of A that is zero for every state
        nan = jnp.nan * f.dinv[0]
        return [nan] * n, [nan] * m_rows
    lam = solve(factor(s, m_rows, range(m_rows)), rhs)
    w = dict(z)
    for c, col in enumerate(y):
        if lam[c] is not None:
            for i, v in col.items():
                w[i] = plus(w.get(i), v * lam[c])
    return upper(f, w), lam


def mass_solver(dyn) -> Callable:
    """``x(q, p, b)``, the solution of ``M(q) x = b`` for one state, factored along the mass matrix's
    sparsity from its entries (:meth:`jaxskid.Dynamics.entries`)."""
    entries = dyn.entries("mass_matrix")

    def mass_solve(q, p, b):
        n = b.shape[-1]
        return assemble(solve(factor(entries(q, p), n), [b[i] for i in range(n)]), b.dtype)

    return mass_solve
