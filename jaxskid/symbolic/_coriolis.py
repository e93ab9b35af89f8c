"""The Coriolis matrix C(q, qd) of the Christoffel symbols of the first kind, on the tape.

``C = J^T (M Jd + B(V) J)`` with the body Jacobian J (Müller & Kumar 2021, sec. 2.2) and the per-body
Christoffel-consistent factorisation ``B(V)`` of Echeandia & Wensing (2021), in body-fixed form:
``B(V) X = 1/2 (M [V, X] + V x* (M X) + X x* (M V))``, so that ``B(V) V = V x* (M V)`` and
``B(V) - M ad(V)`` is skew-symmetric. Then ``C qd`` are the Coriolis/centrifugal forces, ``dM/dt - 2C``
is skew-symmetric and ``C(q, x) y = C(q, y) x``, as for Pinocchio's ``computeCoriolisMatrix``. Column k
is assembled by a Newton-Euler backward pass over the bodies' wrenches ``M_i Jd_{i,k} + B(V_i) J_{i,k}``.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ..model import _spatial as sa
from ._derivation import Derivation
from ._jacobians import jacobian_columns, jacobian_dot_columns
from ._kinematics import Vec, inertia, twist
from ._rnea import backward


def christoffel_gyro(d: Derivation, m: Sequence[Sequence], v: Sequence, h: Sequence, x: Sequence) -> Vec:
    """``B(V) X = 1/2 (M [V, X] + V x* (M X) + X x* (M V))`` with ``h = M V``."""
    t = d.tape
    t1 = sa.inertia_apply(m, t.vec(sa.ad_apply(v, x)))
    t2 = sa.coad_apply(v, t.vec(sa.inertia_apply(m, x)))
    t3 = sa.coad_apply(x, h)
    return t.vec([e / 2 for e in sa.add(t1, t2, t3)])


def coriolis_wrench(d: Derivation, i: int, k: int) -> Vec:
    """Body i's wrench for column k: ``M_i Jd_{i,k} + B(V_i) J_{i,k}`` (k must support i)."""
    m = inertia(d, i)
    jdk = jacobian_dot_columns(d, i)[k]
    v = twist(d, i)
    h = d.tape.vec(sa.inertia_apply(m, v))
    return sa.add(sa.inertia_apply(m, jdk), christoffel_gyro(d, m, v, h, jacobian_columns(d, i)[k]))


def coriolis_matrix(d: Derivation) -> sp.Matrix:
    """C(q, qd), nv x nv (a floating base's column keys :data:`~._derivation.BASE_COLUMNS` included)."""
    c = sp.zeros(d.nv)
    for k in d.columns:
        wrenches = {i: coriolis_wrench(d, i, k) for i in d.bodies if k in jacobian_columns(d, i)}
        for i, e in enumerate(backward(d, wrenches)):
            c[i, d.position(k)] = e
    return c
