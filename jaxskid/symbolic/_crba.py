"""The composite-rigid-body algorithm: M(q) on the tape (Featherstone, "Rigid Body Dynamics Algorithms",
2008, Alg. 6.2, body-fixed).

The composite inertia of each subtree is kept in the 10-parameter form ``(m, h, I)`` (mass, first moment
``h = m c`` and rotational inertia about the frame origin), which moves to the parent with fewer
operations than the 6x6 product ``T^T Ic T``; ``M_ij = X_j^T (T^T ... Ic_i X_i)`` for j on the path from
i to the root, and only the lower triangle is computed.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ..model import _lie as lie
from ..model import _spatial as sa
from ._derivation import Derivation, memoized
from ._kinematics import Vec, inertia, relative, screw, to_parent


def _add_child(d: Derivation, c: int, mass, h: Vec, inert: list[Vec]) -> tuple:
    """Add child c's composite ``(m_c, h_c, I_c)``, at its relative pose ``(R, p)``, to the parent's
    ``(m, h, I)``: ``h += R h_c + m_c p`` and ``I += R I_c R^T + m_c(|p|^2 1 - p p^T) - (h_R p^T + p h_R^T
    - 2 (p.h_R) 1)`` with ``h_R = R h_c``."""
    t = d.tape
    mc, hc, ic = composite_inertia_parts(d, c)
    r, p = relative(d, c)
    hr = t.vec(sa.matvec(r, hc))
    ri = [t.vec(row) for row in sa.matmul(r, ic)]  # R I
    rirt = [[t(sa.dot(ri[a], r[b])) if a <= b else None for b in range(3)] for a in range(3)]
    pp = t(sa.dot(p, p))
    ph = t(sa.dot(p, hr))
    new = [[None] * 3 for _ in range(3)]
    for a in range(3):
        for b in range(a, 3):
            e = inert[a][b] + rirt[a][b] - mc * p[a] * p[b] - hr[a] * p[b] - p[a] * hr[b]
            if a == b:
                e = e + mc * pp + 2 * ph
            new[a][b] = new[b][a] = e
    return mass + mc, sa.add(h, hr, sa.scale(p, mc)), new


@memoized
def composite_inertia_parts(d: Derivation, i: int) -> tuple:
    """Composite inertia of the subtree at body i as ``(m, h, I)`` in body i's frame."""
    t = d.tape
    m6 = inertia(d, i)
    mass = m6[5][5]
    h = [m6[2][4], m6[0][5], m6[1][3]]
    inert = [[m6[r][c] for c in range(3)] for r in range(3)]
    for c in d.robot.children(i):
        mass, h, inert = _add_child(d, c, mass, h, inert)
    mass, h = t(mass), t.vec(h)
    sym = [[None] * 3 for _ in range(3)]
    for a in range(3):
        for b in range(a, 3):
            sym[a][b] = sym[b][a] = t(inert[a][b])
    return mass, h, sym


def composite_inertia(d: Derivation, i: int) -> sp.Matrix:
    """The composite inertia of :func:`composite_inertia_parts` as a 6x6 matrix."""
    m, h, inert = composite_inertia_parts(d, i)
    hx = lie.skew(h)
    top = sp.Matrix(inert).row_join(hx)
    bottom = (-hx).row_join(m * sp.eye(3))
    return top.col_join(bottom)


def apply_composite(d: Derivation, i: int, x: Sequence) -> Vec:
    """``Ic_i X = (I w + h x v, m v + w x h)`` for a twist ``X = (w, v)``."""
    m, h, inert = composite_inertia_parts(d, i)
    w, v = x[:3], x[3:]
    return [*sa.add(sa.matvec(inert, w), sa.cross(h, v)), *sa.add(sa.scale(v, m), sa.cross(w, h))]


def mass_matrix(d: Derivation) -> sp.Matrix:
    """M(q), symmetric, n x n."""
    m = sp.zeros(d.n)
    for i in range(d.n):
        x = screw(d, i)
        f = d.tape.vec(apply_composite(d, i, x))
        m[i, i] = d.tape(sa.dot(x, f))
        j = i
        while d.robot.joints[j].parent >= 0:
            f = to_parent(d, j, f)
            j = d.robot.joints[j].parent
            m[i, j] = m[j, i] = d.tape(sa.dot(screw(d, j), f))
    return m
