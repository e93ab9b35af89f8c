"""The Coriolis matrix C(q, qd), on the tape, in one of two factorisations (``Options.coriolis``).

``C = J^T (M Jd + B(V) J)`` with the body Jacobian J (Müller & Kumar 2021, sec. 2.2) and a per-body
factorisation ``B(V)`` of the gyroscopic wrench, ``B(V) V = V x* (M V)``:

* ``"christoffel"`` (default): the Christoffel-consistent ``B(V)`` of Echeandia & Wensing (2021), in
  body-fixed form, ``B(V) X = 1/2 (M [V, X] + V x* (M X) + X x* (M V))``, which is skew-symmetric
  (:func:`skew_christoffel`). Then ``dM/dt - 2C`` is skew-symmetric and ``C(q, x) y = C(q, y) x``, as for Pinocchio's
  ``computeCoriolisMatrix``.
* ``"skidy"``: ``B(V) X = V x* (M X) = -ad(V)^T M X``, Müller & Kumar's (2021, eq. 9) closed form
  ``C = -J^T (M A a + b^T M) J`` with ``a = diag(ad(X_i) qd_i)``, ``b = diag(ad(V_i))`` and ``-A a J = Jd``,
  as Skidy computes it (``closed_form_inv_dyn_body_fixed``). Its ``C qd`` is the same, its C is not.

Column k is assembled by a Newton-Euler backward pass over the bodies' wrenches ``M_i Jd_{i,k} +
B(V_i) J_{i,k}``. The Christoffel ``B(V_i)`` is formed once per body as a skew-symmetric matrix
(:func:`christoffel_matrix`), so that each column costs a body one product with it: the G1's C (29 DOF) has
26,800 operations so, where the three terms applied per column make 46,600.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ..model import _spatial as sa
from ._derivation import Derivation, memoized
from ._jacobians import jacobian_columns, jacobian_dot_columns
from ._kinematics import Vec, inertia, twist
from ._rnea import backward


def skidy_gyro(d: Derivation, m: Sequence[Sequence], v: Sequence, x: Sequence) -> Vec:
    """``B(V) X = V x* (M X)``, the ``-b^T M`` term of Müller & Kumar's closed form."""
    return sa.coad_apply(v, d.tape.vec(sa.inertia_apply(m, x)))


def skew_christoffel(d: Derivation, m: Sequence[Sequence], v: Sequence) -> list[list]:
    """``B(V)`` of the Christoffel factorisation for the inertia ``m`` and twist ``v``, as a 6x6 matrix (rows).
    It is skew-symmetric (``M ad(V) - ad(V)^T M`` is, for a symmetric ``M``, and so is ``X -> X x* h``), so
    its 15 entries above the diagonal are computed, from its columns ``B e_c``."""
    h = d.tape.vec(sa.inertia_apply(m, v))
    rows = [[sp.Integer(0)] * 6 for _ in range(6)]
    for c in range(1, 6):
        e = [sp.Integer(int(r == c)) for r in range(6)]
        t1 = sa.inertia_apply(m, sa.ad_apply(v, e))
        t2 = sa.coad_apply(v, sa.inertia_apply(m, e))
        t3 = sa.coad_apply(e, h)
        for r in range(c):
            rows[r][c] = d.tape((t1[r] + t2[r] + t3[r]) / 2)
            rows[c][r] = -rows[r][c]
    return rows


@memoized
def christoffel_matrix(d: Derivation, i: int) -> list[list]:
    """Body i's ``B(V_i)`` (:func:`skew_christoffel`), once per body: each column of C then costs the body a
    product with it instead of the three terms of ``B(V) X``."""
    return skew_christoffel(d, inertia(d, i), twist(d, i))


def coriolis_wrench(d: Derivation, i: int, k: int) -> Vec:
    """Body i's wrench for column k: ``M_i Jd_{i,k} + B(V_i) J_{i,k}`` (k must support i), with the ``B`` of
    ``d.coriolis``."""
    m = inertia(d, i)
    jdk = jacobian_dot_columns(d, i)[k]
    v = twist(d, i)
    x = jacobian_columns(d, i)[k]
    if d.coriolis == "skidy":
        return sa.add(sa.inertia_apply(m, jdk), skidy_gyro(d, m, v, x))
    return sa.add(sa.inertia_apply(m, jdk), sa.matvec(christoffel_matrix(d, i), x))


def coriolis_matrix(d: Derivation) -> sp.Matrix:
    """C(q, qd), nv x nv (a floating base's column keys :data:`~._derivation.BASE_COLUMNS` included)."""
    c = sp.zeros(d.nv)
    for k in d.columns:
        wrenches = {i: coriolis_wrench(d, i, k) for i in d.bodies if k in jacobian_columns(d, i)}
        for i, e in enumerate(backward(d, wrenches)):
            c[i, d.position(k)] = e
    return c
