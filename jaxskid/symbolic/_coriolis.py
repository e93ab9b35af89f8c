"""The Coriolis matrix C(q, qd), on the tape, in one of two factorisations (``Options.coriolis``).

``C = J^T (M Jd + B(V) J)`` with the body Jacobian J (Müller & Kumar 2021, sec. 2.2) and a per-body
factorisation ``B(V)`` of the gyroscopic wrench, ``B(V) V = V x* (M V)``:

* ``"christoffel"`` (default): the Christoffel-consistent ``B(V)`` of Echeandia & Wensing (2021), in
  body-fixed form, ``B(V) X = 1/2 (M [V, X] + V x* (M X) + X x* (M V))``, so that ``B(V) - M ad(V)`` is
  skew-symmetric. Then ``dM/dt - 2C`` is skew-symmetric and ``C(q, x) y = C(q, y) x``, as for Pinocchio's
  ``computeCoriolisMatrix``.
* ``"skidy"``: ``B(V) X = V x* (M X) = -ad(V)^T M X``, Müller & Kumar's (2021, eq. 9) closed form
  ``C = -J^T (M A a + b^T M) J`` with ``a = diag(ad(X_i) qd_i)``, ``b = diag(ad(V_i))`` and ``-A a J = Jd``,
  as Skidy computes it (``closed_form_inv_dyn_body_fixed``). Its ``C qd`` is the same, its C is not.

Column k is assembled by a Newton-Euler backward pass over the bodies' wrenches ``M_i Jd_{i,k} +
B(V_i) J_{i,k}``.
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


def skidy_gyro(d: Derivation, m: Sequence[Sequence], v: Sequence, x: Sequence) -> Vec:
    """``B(V) X = V x* (M X)``, the ``-b^T M`` term of Müller & Kumar's closed form."""
    return sa.coad_apply(v, d.tape.vec(sa.inertia_apply(m, x)))


def coriolis_wrench(d: Derivation, i: int, k: int) -> Vec:
    """Body i's wrench for column k: ``M_i Jd_{i,k} + B(V_i) J_{i,k}`` (k must support i), with the ``B`` of
    ``d.coriolis``."""
    m = inertia(d, i)
    jdk = jacobian_dot_columns(d, i)[k]
    v = twist(d, i)
    x = jacobian_columns(d, i)[k]
    if d.coriolis == "skidy":
        return sa.add(sa.inertia_apply(m, jdk), skidy_gyro(d, m, v, x))
    h = d.tape.vec(sa.inertia_apply(m, v))
    return sa.add(sa.inertia_apply(m, jdk), christoffel_gyro(d, m, v, h, x))


def coriolis_matrix(d: Derivation) -> sp.Matrix:
    """C(q, qd), nv x nv (a floating base's column keys :data:`~._derivation.BASE_COLUMNS` included)."""
    c = sp.zeros(d.nv)
    for k in d.columns:
        wrenches = {i: coriolis_wrench(d, i, k) for i in d.bodies if k in jacobian_columns(d, i)}
        for i, e in enumerate(backward(d, wrenches)):
            c[i, d.position(k)] = e
    return c
