"""Time derivatives of the dynamics: dM/dt, dC/dt, dQ_grav/dt, dtau/dt, dQ_ext/dt and the second ones.

Built from the differentiated kinematics of :mod:`._time_kinematics` (Müller & Kumar 2021). Newton-Euler's
body wrench ``W_i = M_i A_i - ad(V_i)^T M_i V_i`` is bilinear in the twists, so ``W_i^(k)`` is a Leibniz
sum; the backward pass ``F_i = W_i + sum_c T_c^T F_c`` is differentiated with the wrench rule
``(T^T F)^(k) = T^T sum_m C(k, m) P_m^T F^(k-m)``. Each derivative of tau, Q_grav and Q_ext is thus a
Newton-Euler pass over differentiated kinematics, dM/dt a composite-rigid-body pass over differentiated
composite inertias, and dC/dt the column-wise Newton-Euler pass of :mod:`._coriolis` over differentiated
Jacobian columns and twists. Every intermediate is named on the shared tape, so the quantities requested
together share their work. A floating base (body ``-1``) is one more body of these passes, as in
:mod:`._rnea` and :mod:`._crba`: its wrench jet gives the first six rows, and ``M^(k)``'s base block is the
derivative of the whole tree's composite inertia.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from math import comb

import sympy as sp

from ..model import _spatial as sa
from ._coriolis import christoffel_matrix, coriolis_wrench, skew_christoffel
from ._crba import apply_composite
from ._derivation import Derivation, memoized
from ._drives import with_drives
from ._frames import body_loads
from ._jacobians import jacobian_columns
from ._kinematics import Terms, Vec, inertia, is_zero, screw, zero6
from ._rnea import body_wrench
from ._time_kinematics import (
    composite_inertia_derivative, gravity_derivative, jacobian_column_derivative, pulled, twist_derivative,
)


def backward_derivative(d: Derivation, wrenches: Mapping[int, Sequence[Vec]], k: int) -> Vec:
    """``tau^(k)`` of the Newton-Euler backward pass ``F_i = W_i + sum_c T_c^T F_c``, ``tau_i = X_i^T F_i``.

    ``wrenches[i]`` holds the derivatives ``[W_i, W_i', ..., W_i^(k)]`` of body i's own wrench (by body
    index, ``-1`` the floating base; a body left out has none). Returns shape (nv,), the base's six first.
    """
    f = {i: [list(w) for w in wrenches.get(i, [zero6()] * (k + 1))] for i in d.bodies}
    tau: Vec = [sp.Integer(0)] * d.n
    for i in reversed(range(d.n)):
        jet = [d.tape.vec(w) for w in f[i]]
        tau[i] = d.tape(sa.dot(screw(d, i), jet[k]))
        parent = d.robot.joints[i].parent
        if d.is_body(parent):
            for r in range(k + 1):
                moved = pulled(d, i, jet, r)
                if not is_zero(moved):
                    f[parent][r] = sa.add(f[parent][r], moved)
    if d.floating:
        return [*d.tape.vec(f[-1][k]), *tau]
    return tau


@memoized
def body_wrench_derivative(d: Derivation, i: int, k: int, terms: Terms) -> Vec:
    """``W_i^(k)`` of ``W_i = M_i (Vd_i + u_i) - ad(V_i)^T M_i V_i`` for ``Terms.INVERSE_DYNAMICS``, or of
    ``W_i = M_i u_i`` for ``Terms.GRAVITY``."""
    if k == 0:
        return body_wrench(d, i, terms)
    m = inertia(d, i)
    parts = []
    if terms.velocity:
        parts.append(twist_derivative(d, i, k + 1))
    if terms.gravity:
        parts.append(gravity_derivative(d, i, k))
    out = sa.inertia_apply(m, d.tape.vec(sa.add(*parts)))
    if terms.velocity:
        for r in range(k + 1):
            h = d.tape.vec(sa.inertia_apply(m, twist_derivative(d, i, k - r)))
            out = sa.add(out, sa.scale(sa.coad_apply(twist_derivative(d, i, r), h), comb(k, r)))
    return d.tape.vec(out)


def newton_euler_derivative(d: Derivation, k: int, terms: Terms) -> Vec:
    """``tau^(k)`` (``Terms.INVERSE_DYNAMICS``, with the drives' ``Ia q^(k+2) + fv q^(k+1)``) or
    ``Q_grav^(k)`` (``Terms.GRAVITY``)."""
    jets = {i: [body_wrench_derivative(d, i, r, terms) for r in range(k + 1)] for i in d.bodies}
    tau = backward_derivative(d, jets, k)
    return with_drives(d, tau, k) if terms is Terms.INVERSE_DYNAMICS else tau


def external_torques_derivative(d: Derivation, wrenches: Sequence[Mapping[str, Sequence]], k: int) -> Vec:
    """``Q_ext^(k)``; ``wrenches[r]`` maps each end-effector to the r-th derivative of its wrench
    (moment, force), in its frame."""
    loads = [body_loads(d, wrenches[r]) for r in range(k + 1)]
    jets = {i: [loads[r].get(i, zero6()) for r in range(k + 1)] for i in d.bodies}
    return backward_derivative(d, jets, k)


def mass_matrix_derivative(d: Derivation, k: int) -> sp.Matrix:
    """``M^(k)``: ``M_ij = X_j^T (T^T ... Ic_i X_i)``, the composite-rigid-body pass over ``Ic^(r)``."""
    m = sp.zeros(d.nv)
    for i in range(d.n):
        x = screw(d, i)
        jet = [d.tape.vec(apply_composite(d, i, x) if r == 0 else
                          sa.inertia_apply(composite_inertia_derivative(d, i, r).tolist(), x)) for r in range(k + 1)]
        a = d.position(i)
        m[a, a] = d.tape(sa.dot(x, jet[k]))
        j = i
        while j >= 0 and d.is_body(d.robot.joints[j].parent):
            jet = [pulled(d, j, jet, r) for r in range(k + 1)]
            j = d.robot.joints[j].parent
            if j >= 0:
                m[a, d.position(j)] = m[d.position(j), a] = d.tape(sa.dot(screw(d, j), jet[k]))
            else:
                top = d.tape.vec(jet[k])
                for c in range(6):
                    m[a, c] = m[c, a] = top[c]
    if d.floating:
        m[:6, :6] = composite_inertia_derivative(d, -1, k)
    return m


def coriolis_matrix_derivative(d: Derivation, k: int) -> sp.Matrix:
    """``C^(k)``: column c is the backward pass of ``W_i = M_i Jd_{i,c} + B(V_i) J_{i,c}``, with ``B``
    bilinear in (V, J), differentiated by Leibniz."""
    out = sp.zeros(d.nv)
    for c in d.columns:
        wrenches = {i: [coriolis_wrench_derivative(d, i, c, r) for r in range(k + 1)]
                    for i in d.bodies if c in jacobian_columns(d, i)}
        for i, e in enumerate(backward_derivative(d, wrenches, k)):
            out[i, d.position(c)] = e
    return out


@memoized
def coriolis_wrench_derivative(d: Derivation, i: int, c: int, r: int) -> Vec:
    """``d^r/dt^r (M J'_{i,c} + B(V_i) J_{i,c})``, ``B(V) X = 1/2 (M [V, X] + V x* (M X) + X x* (M V))``
    (``d.coriolis == "christoffel"``) or ``B(V) X = V x* (M X)`` (``"skidy"``).

    B is bilinear, so the Leibniz sum is ``M J^(r+1) + sum_s C(r, s) B(V^(s)) J^(r-s)``, with the matrix
    ``B(V^(s))`` formed once per body and order.
    """
    if r == 0:
        return coriolis_wrench(d, i, c)
    if d.coriolis == "skidy":
        return _skidy_wrench_derivative(d, i, c, r)
    out = sa.inertia_apply(inertia(d, i), jacobian_column_derivative(d, i, c, r + 1))
    for s in range(r + 1):
        x = jacobian_column_derivative(d, i, c, r - s)
        if not is_zero(x):
            out = sa.add(out, sa.scale(sa.matvec(_christoffel_derivative(d, i, s), x), comb(r, s)))
    return d.tape.vec(out)


@memoized
def _christoffel_derivative(d: Derivation, i: int, s: int) -> list[list]:
    """``B(V_i^(s))``, skew-symmetric (:func:`~._coriolis.skew_christoffel`), once per body and order (the
    order 0 is C's own)."""
    if s == 0:
        return christoffel_matrix(d, i)
    return skew_christoffel(d, inertia(d, i), twist_derivative(d, i, s))


def _skidy_wrench_derivative(d: Derivation, i: int, c: int, r: int) -> Vec:
    """``d^r/dt^r (M J'_{i,c} + V_i x* (M J_{i,c})) = M J^(r+1) + sum_s C(r, s) V^(s) x* (M J^(r-s))``: the
    r-th derivative of the body wrench of Müller & Kumar's (2021) ``C = -J^T (M A a + b^T M) J``."""
    m = inertia(d, i)
    out = sa.inertia_apply(m, jacobian_column_derivative(d, i, c, r + 1))
    for s in range(r + 1):
        x = jacobian_column_derivative(d, i, c, r - s)
        if is_zero(x):
            continue
        mx = d.tape.vec(sa.inertia_apply(m, x))
        out = sa.add(out, sa.scale(sa.coad_apply(twist_derivative(d, i, s), mx), comb(r, s)))
    return d.tape.vec(out)
