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

The Skidy factorisation assembles column k by a Newton-Euler backward pass over the bodies' wrenches
``M_i Jd_{i,k} + B(V_i) J_{i,k}``. The Christoffel one is assembled from the subtrees' composite quantities
(:func:`christoffel_column_force`): in joint k's frame, the wrench that column k's pass carries into body k
is ``F_k = 1/2 Ic_k' X_k + 1/2 (Ic_k [V_k, X_k] + V_k x* (Ic_k X_k) + X_k x* h_k)``, with the subtree's
composite inertia ``Ic_k``, its time derivative and its momentum ``h_k`` (each body's ``M_i V_i`` carried into
frame k). ``F_k`` carried up the tree gives the entries ``C_jk = X_j^T F_k`` above the diagonal, and
``dM/dt = C + C^T`` those below: ``C_kj = dM_jk/dt - C_jk``, where ``dM_jk/dt`` comes from the pass of
:func:`jaxskid.symbolic.mass_matrix_derivative` (the jet of :func:`composite_jet`). The G1 with hands' C (43
DOF, every inertial parameter symbolic) has 31,600 operations so, where the column-wise passes make 59,000.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ..model import _spatial as sa
from ._derivation import Derivation, memoized
from ._jacobians import jacobian_columns, jacobian_dot_columns
from ._crba import apply_composite
from ._kinematics import Vec, inertia, screw, to_parent, twist
from ._rnea import backward
from ._time_kinematics import composite_inertia_derivative, pulled


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


@memoized
def composite_momentum(d: Derivation, i: int) -> Vec:
    """``h_i``: the momentum of the subtree of body i, each body's ``M_b V_b`` carried into body i's frame."""
    h = sa.inertia_apply(inertia(d, i), twist(d, i))
    for c in d.robot.children(i):
        h = sa.add(h, to_parent(d, c, composite_momentum(d, c)))
    return d.tape.vec(h)


def composite_jet(d: Derivation, i: int, x: Sequence) -> list[Vec]:
    """``[Ic X, Ic' X]`` in body i's frame: the jet that the pass of
    :func:`jaxskid.symbolic.mass_matrix_derivative` carries up the tree."""
    return [d.tape.vec(apply_composite(d, i, x)),
            d.tape.vec(sa.inertia_apply(composite_inertia_derivative(d, i, 1).tolist(), x))]


def christoffel_column_force(d: Derivation, i: int, x: Sequence, jet: Sequence[Vec]) -> Vec:
    """``F = 1/2 Ic' X + 1/2 (Ic [V, X] + V x* (Ic X) + X x* h)`` in body i's frame for its screw ``X`` and
    ``jet = composite_jet(d, i, X)`` (module docstring): ``sum_b T_b^T (M_b Jd_b + B(V_b) J_b)`` over the
    subtree of body i, ``J_b = T_b X``."""
    v = twist(d, i)
    gyro = sa.add(apply_composite(d, i, sa.ad_apply(v, x)), sa.coad_apply(v, jet[0]),
                  sa.coad_apply(x, composite_momentum(d, i)))
    return d.tape.vec([(a + b) / 2 for a, b in zip(jet[1], gyro)])


def _unit(r: int) -> Vec:
    return [sp.Integer(int(s == r)) for s in range(6)]


def _christoffel_coriolis(d: Derivation) -> sp.Matrix:
    """The Christoffel C from the subtrees' composite quantities (module docstring)."""
    c = sp.zeros(d.nv)
    for i in range(d.n):
        x = screw(d, i)
        jet = composite_jet(d, i, x)
        f = christoffel_column_force(d, i, x, jet)
        a = d.position(i)
        c[a, a] = d.tape(sa.dot(x, f))
        j = i
        while j >= 0 and d.is_body(d.robot.joints[j].parent):
            jet = [pulled(d, j, jet, r) for r in range(2)]
            f = to_parent(d, j, f)
            j = d.robot.joints[j].parent
            rows = [(d.position(j), screw(d, j))] if j >= 0 else [(r, _unit(r)) for r in range(6)]
            for b, xj in rows:
                c[b, a] = d.tape(sa.dot(xj, f))
                c[a, b] = d.tape(sa.dot(xj, jet[1]) - c[b, a])
    if d.floating:
        for col in range(6):
            e = _unit(col)
            for r, entry in enumerate(christoffel_column_force(d, -1, e, composite_jet(d, -1, e))):
                c[r, col] = entry
    return c


def coriolis_matrix(d: Derivation) -> sp.Matrix:
    """C(q, qd), nv x nv (a floating base's column keys :data:`~._derivation.BASE_COLUMNS` included)."""
    if d.coriolis != "skidy":
        return _christoffel_coriolis(d)
    c = sp.zeros(d.nv)
    for k in d.columns:
        wrenches = {i: coriolis_wrench(d, i, k) for i in d.bodies if k in jacobian_columns(d, i)}
        for i, e in enumerate(backward(d, wrenches)):
            c[i, d.position(k)] = e
    return c
