"""Closed-form forward dynamics on the tape: ``qdd = M^-1 (tau - C qd - Q_grav)`` without a matrix solve.

The mass matrix from the composite-rigid-body algorithm and the bias from one Newton-Euler pass are
factored *symbolically* as ``M = L^T D L`` with the branch-induced sparsity of the tree (Featherstone,
"Efficient factorization of the joint-space inertia matrix for branched kinematic trees", IJRR 24(6),
2005, Alg. LTDL), then solved by substitution: about ``n d^2 / 2`` extra operations for depth ``d``.
Lowered like any quantity, the whole of forward dynamics becomes one fused kernel. A floating base's six
coordinates enter the tree as a chain above the root joints (Featherstone 2005, sec. 7: a multi-DOF joint is
a chain of single-DOF ones in the factorisation), so its 6x6 block is factored densely.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ._crba import mass_matrix
from ._derivation import Derivation
from ._rnea import bias_forces


def forward_dynamics(d: Derivation, tau: Sequence[sp.Symbol]) -> list:
    """``qdd`` (nv expressions on the tape) for joint forces ``tau``, by the sparse ``L^T D L`` of M."""
    return solve(d.tape, mass_matrix(d), tau, bias_forces(d), tree(d))


def tree(d: Derivation) -> list[int]:
    """The parent of each velocity coordinate (``-1``: none): the bodies' tree, below a chain of the floating
    base's six coordinates, if any."""
    base = list(range(-1, d.offset - 1))
    return base + [d.position(p) if p >= 0 else d.offset - 1 for p in d.robot.parents]


def solve(t, m, tau: Sequence, bias: Sequence, lam: Sequence[int]) -> list:
    """``M^-1 (tau - bias)`` on the tape ``t``, for a symmetric positive definite ``M`` (n x n) whose entry
    ``(i, j)``, ``j < i``, is zero unless ``j`` is an ancestor of ``i`` in the tree of parents ``lam`` (``-1``:
    the root). ``lam = [-1, 0, 1, ...]`` (a chain) factors a dense matrix; entries that are zero give no work."""
    n = len(tau)
    h = [[m[i, j] for j in range(n)] for i in range(n)]
    recip = [None] * n
    for k in reversed(range(n)):  # Featherstone 2005, Alg. LTDL: h becomes L (below the diagonal) and D
        recip[k] = t(1 / h[k][k])
        i = lam[k]
        while i != -1:
            a = t(h[k][i] * recip[k])
            j = i
            while j != -1:
                h[i][j] = t(h[i][j] - a * h[k][j])
                j = lam[j]
            h[k][i] = a
            i = lam[i]
    x = [t(tau[i] - bias[i]) for i in range(n)]
    for i in reversed(range(n)):  # L^T y = b
        j = lam[i]
        while j != -1:
            x[j] = t(x[j] - h[i][j] * x[i])
            j = lam[j]
    x = [t(x[i] * recip[i]) for i in range(n)]  # D z = y
    for i in range(n):  # L qdd = z
        j = lam[i]
        while j != -1:
            x[i] = t(x[i] - h[i][j] * x[j])
            j = lam[j]
    return x
