"""The composite-rigid-body algorithm: M(q) on the tape (Featherstone, "Rigid Body Dynamics Algorithms",
2008, Alg. 6.2, body-fixed).

The composite inertia of each subtree is kept in the 10-parameter form ``(m, h, I)`` (mass, first moment
``h = m c`` and rotational inertia about the frame origin), which moves to the parent with fewer
operations than the 6x6 product ``T^T Ic T``; ``M_ij = X_j^T (T^T ... Ic_i X_i)`` for j on the path from
i to the root, and only the lower triangle is computed. The drives' armature adds to the diagonal
(:mod:`._drives`). A floating base (body ``-1``, ``X = I_6``) gets the base block ``M_bb = Ic_b``, the
composite inertia of the whole tree in the base frame, and the columns ``M_bi = T^T ... Ic_i X_i`` carried
up to the base frame (Featherstone 2008, sec. 9.2).
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ..model import _lie as lie
from ..model import _spatial as sa
from ._derivation import Derivation, memoized
from ._drives import armature
from ._kinematics import Vec, inertia, relative, screw, to_parent


@memoized
def composite_inertia_parts(d: Derivation, i: int) -> tuple:
    """Composite inertia of the subtree at body i as ``(m, h, I)`` in body i's frame."""
    t = d.tape
    mass, h, inert = sa.inertia_parts(inertia(d, i))
    for c in d.robot.children(i):
        child = composite_inertia_parts(d, c)
        mass, h, inert = sa.add_inertia_parts((mass, h, inert), *relative(d, c), child, t.vec)
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
    return sa.apply_inertia_parts(composite_inertia_parts(d, i), x)


def mass_matrix(d: Derivation) -> sp.Matrix:
    """M(q) + diag(Ia), symmetric, nv x nv (``Ia``: the drives' armature, 0 without drives)."""
    m = sp.zeros(d.nv)
    for i, ia in enumerate(armature(d)):
        x = screw(d, i)
        f = d.tape.vec(apply_composite(d, i, x))
        a = d.position(i)
        m[a, a] = d.tape(sa.dot(x, f) + ia)
        j = i
        while j >= 0 and d.is_body(d.robot.joints[j].parent):
            f = to_parent(d, j, f)
            j = d.robot.joints[j].parent
            if j >= 0:
                m[a, d.position(j)] = m[d.position(j), a] = d.tape(sa.dot(screw(d, j), f))
            else:
                f = d.tape.vec(f)
                for c in range(6):
                    m[a, c] = m[c, a] = f[c]
    if d.floating:
        m[:6, :6] = composite_inertia(d, -1)
    return m
