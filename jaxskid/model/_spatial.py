"""Spatial algebra on plain sequences, written once for the symbolic and the numeric recursions.

A 3-vector or 6-vector is a sequence of scalars, a matrix a sequence of rows. A scalar is anything with
``+``, ``-`` and ``*``: a SymPy expression (the symbolic stage, which names results on its tape through
the ``name`` hooks below) or a JAX scalar (the numeric recursive evaluation in :mod:`jaxskid.testing`).
Nothing here imports JAX, and nothing tests a scalar's value, so the same code traces in JAX. A sum with a
SymPy term is built as one n-ary ``Add`` (the same expression as ``a + b + c``, without flattening the growing
sum again at each ``+``: that is quadratic in the number of terms); other sums fold left from their first term.

Conventions, as in :mod:`jaxskid.model._lie` (Müller 2018, "Screw and Lie group theory in multibody
kinematics"; Featherstone, "Rigid Body Dynamics Algorithms", 2008, ch. 2):

* a twist (motion vector) is ``V = (omega, v)``, a wrench (force vector) ``F = (n, f)`` (moment, force);
* a pose ``C = (R, p)`` maps the coordinates of its own frame to its reference frame;
* ``Ad(C) = [[R, 0], [p~ R, R]]`` moves twists from the frame of ``C`` to the reference frame, and
  ``Ad(C^-1)^T`` moves wrenches the same way (Pinocchio's ``SE3::act`` on motions and forces);
* ``ad(V) = [[w~, 0], [v~, w~]]`` (the Lie bracket ``[V, X]``) and ``V x* F = -ad(V)^T F``;
* a 6x6 mass-inertia in a body frame is ``[[I_o, m c~], [-m c~, m 1]]`` (``I_o`` about the frame origin).
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Sequence
from functools import reduce

Vec = list
"""A list of scalars."""

Rows = list
"""A matrix as a list of rows."""

Name = Callable[[Sequence], Vec]
"""A hook applied to an intermediate vector before it is used again (identity by default)."""


def unnamed(v: Sequence) -> Vec:
    """The default :data:`Name` hook: the vector as it is."""
    return list(v)


def _sum(terms) -> object:
    terms = list(terms)
    if any(getattr(t, "__sympy__", False) for t in terms):
        from sympy import Add

        return Add(*terms)
    return reduce(operator.add, terms)


# ---------------------------------------------------------------------------------------------- 3-vectors
def cross(a: Sequence, b: Sequence) -> Vec:
    """``a x b``."""
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def dot(a: Sequence, b: Sequence):
    """``a . b`` (any equal lengths)."""
    return _sum(x * y for x, y in zip(a, b))


def add(*vs: Sequence) -> Vec:
    """The entrywise sum of one or more vectors of equal length."""
    return [_sum(items) for items in zip(*vs)]


def scale(v: Sequence, s) -> Vec:
    """``v s``."""
    return [x * s for x in v]


def skew(v: Sequence) -> Rows:
    """The 3x3 cross-product matrix ``v~`` (``v~ b = v x b``), as rows."""
    x, y, z = v
    return [[0, -z, y], [z, 0, -x], [-y, x, 0]]


def matvec(m: Sequence[Sequence], v: Sequence) -> Vec:
    """``m v`` for a matrix given as rows."""
    return [dot(row, v) for row in m]


def matTvec(m: Sequence[Sequence], v: Sequence) -> Vec:
    """``m^T v`` for a matrix given as rows."""
    return [_sum(m[r][c] * v[r] for r in range(len(v))) for c in range(len(m[0]))]


def matmul(a: Sequence[Sequence], b: Sequence[Sequence]) -> Rows:
    """``a b`` for 3x3 matrices given as rows."""
    return [[_sum(a[r][k] * b[k][c] for k in range(3)) for c in range(3)] for r in range(3)]


def transpose(m: Sequence[Sequence]) -> Rows:
    return [[m[r][c] for r in range(len(m))] for c in range(len(m[0]))]


def identity3() -> Rows:
    return [[int(r == c) for c in range(3)] for r in range(3)]


# ---------------------------------------------------------------------------------------------- poses
def compose(r1: Sequence[Sequence], p1: Sequence, r2: Sequence[Sequence], p2: Sequence,
            name: Name = unnamed) -> tuple[Rows, Vec]:
    """``C1 C2 = (R1 R2, R1 p2 + p1)``; the hook names each row of the rotation, then the translation."""
    return [name(row) for row in matmul(r1, r2)], name(add(matvec(r1, p2), p1))


def quaternion_rotation(quat: Sequence, scale2, name: Name = unnamed) -> Rows:
    """The rotation of the quaternion ``quat = (x, y, z, w)`` stored as Pinocchio stores it, with ``scale2 =
    2 / (x^2 + y^2 + z^2 + w^2)``: ``R = 1 + s (w u~ + u~^2)`` for ``u = (x, y, z)`` (the rotation of the normalised
    quaternion; ``s = 2`` for a unit one, Eigen's ``toRotationMatrix``). The hook names each row."""
    x, y, z, w = quat
    s = scale2
    return [
        name([1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)]),
        name([s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)]),
        name([s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)]),
    ]


def screw_exp(w: Sequence, v: Sequence, q, sin_cos: tuple | None, name: Name = unnamed) -> tuple[Rows, Vec]:
    """``(R, p)`` of ``exp(X q)`` for the unit screw ``X = (w, v)`` (Lynch & Park, "Modern Robotics",
    2017, eq. 3.51 and 3.88)::

        R = 1 + sin(q) w~ + (1 - cos(q)) w~^2,    p = (1 - R)(w x v) + w (w . v) q.

    ``sin_cos`` is ``(sin q, cos q)`` for a joint that rotates (``|w| = 1``), or ``None`` for a prismatic
    joint (``w = 0``), where ``exp(X q) = (1, v q)``. The hook names each row of R, then p.
    """
    if sin_cos is None:
        return identity3(), name(scale(v, q))
    s, c = sin_cos
    wx = skew(w)
    wx2 = matmul(wx, wx)
    r = [name([int(a == b) + s * wx[a][b] + (1 - c) * wx2[a][b] for b in range(3)]) for a in range(3)]
    wv = cross(w, v)
    pitch = dot(w, v)
    return r, name([wv[a] - dot(r[a], wv) + w[a] * pitch * q for a in range(3)])


# ---------------------------------------------------------------------------------------------- 6-vectors
def ad_apply(v: Sequence, x: Sequence) -> Vec:
    """``ad(V) X = [V, X] = (w x w_X, v x w_X + w x v_X)``."""
    w, u = v[:3], v[3:]
    return [*cross(w, x[:3]), *add(cross(u, x[:3]), cross(w, x[3:]))]


def coad_apply(v: Sequence, f: Sequence) -> Vec:
    """``V x* F = -ad(V)^T F = (w x n + v x f, w x f)``, the cross product of a twist and a wrench."""
    w, u = v[:3], v[3:]
    return [*add(cross(w, f[:3]), cross(u, f[3:])), *cross(w, f[3:])]


def adT_apply(x: Sequence, f: Sequence) -> Vec:
    """``ad(X)^T F``."""
    return [-e for e in coad_apply(x, f)]


def inertia_apply(m: Sequence[Sequence], v: Sequence) -> Vec:
    """``M V`` for a 6x6 matrix given as rows."""
    return matvec(m, v)


def inertia_parts(m: Sequence[Sequence]) -> tuple:
    """``(m, h, I)`` of a 6x6 mass-inertia ``[[I, h~], [-h~, m 1]]`` given as rows: the mass, the first
    moment ``h = m c`` and the rotational inertia about the frame origin (rows)."""
    return m[5][5], [m[2][4], m[0][5], m[1][3]], [[m[r][c] for c in range(3)] for r in range(3)]


def apply_inertia_parts(parts: tuple, x: Sequence) -> Vec:
    """``M X = (I w + h x v, m v + w x h)`` for ``parts = (m, h, I)`` and a twist ``X = (w, v)``."""
    m, h, inert = parts
    w, v = x[:3], x[3:]
    return [*add(matvec(inert, w), cross(h, v)), *add(scale(v, m), cross(w, h))]


_UPPER = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def add_inertia_parts(acc: tuple, r: Sequence[Sequence], p: Sequence, parts: tuple, name: Name = unnamed) -> tuple:
    """``acc`` plus the inertia ``parts = (m, h, I)`` of a body in the frame of ``C = (R, p)``, moved to the
    reference frame, all as ``(m, h, I)``: with ``h_R = R h``, the moved inertia is ``(m, h_R + m p,
    R I R^T + m (|p|^2 1 - p p^T) - (h_R p^T + p h_R^T - 2 (p . h_R) 1))``, the parallel-axis theorem
    with the centre of mass at ``h_R / m``. The upper triangle of I is computed and mirrored. The hook
    names ``h_R``, each row of ``R I``, the upper triangle of ``R I R^T``, then ``|p|^2`` and ``p . h_R``.
    """
    mass, h, inert = acc
    mc, hc, ic = parts
    hr = name(matvec(r, hc))
    ri = [name(row) for row in matmul(r, ic)]
    rirt = dict(zip(_UPPER, name([dot(ri[a], r[b]) for a, b in _UPPER])))
    pp = name([dot(p, p)])[0]
    ph = name([dot(p, hr)])[0]
    new = [[None] * 3 for _ in range(3)]
    for a, b in _UPPER:
        e = inert[a][b] + rirt[a, b] - mc * p[a] * p[b] - hr[a] * p[b] - p[a] * hr[b]
        if a == b:
            e = e + mc * pp + 2 * ph
        new[a][b] = new[b][a] = e
    return mass + mc, add(h, hr, scale(p, mc)), new


def act_motion(r: Sequence[Sequence], p: Sequence, v: Sequence) -> Vec:
    """``Ad(C) V = (R w, R v + p x R w)``: a twist in the frame of ``C = (R, p)``, in its reference frame."""
    rw = matvec(r, v[:3])
    return [*rw, *add(matvec(r, v[3:]), cross(p, rw))]


def act_inv_motion(r: Sequence[Sequence], p: Sequence, v: Sequence) -> Vec:
    """``Ad(C^-1) V = (R^T w, R^T (v + w x p))``: a twist in the reference frame of ``C``, in its frame."""
    w, u = v[:3], v[3:]
    return [*matTvec(r, w), *matTvec(r, add(u, cross(w, p)))]


def act_force(r: Sequence[Sequence], p: Sequence, f: Sequence, name: Name = unnamed) -> Vec:
    """``Ad(C^-1)^T F = (R n + p x R f, R f)``: a wrench in the frame of ``C``, in its reference frame.

    The hook names ``R f`` before the moment uses it.
    """
    rf = name(matvec(r, f[3:]))
    return [*add(matvec(r, f[:3]), cross(p, rf)), *rf]
