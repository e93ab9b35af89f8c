"""Time derivatives of the kinematic recursions: twists, gravity, Jacobian columns, composite inertias.

Every time derivative is built by the body-fixed recursions themselves, never by differentiating their
results (Müller & Kumar, "Closed-form time derivatives of the equations of motion of rigid body systems",
Multibody Syst Dyn 53:257-273, 2021, in their Lie-group setting; organised as the Newton-Euler and
composite-rigid-body recursions). One identity drives all of them: with the relative transform
``T_i = Ad(C_{p,i}^-1)`` and ``C_{p,i} = B_i exp(X_i q_i)``,

    dT_i/dt = -qd_i ad(X_i) T_i,

so ``T_i^(m) = P_m T_i`` with ``P_0 = 1`` and ``P_{m+1} = dP_m/dt - qd_i P_m ad(X_i)``: a polynomial in
``ad(X_i)`` whose coefficients are polynomials in ``qd_i, qdd_i, ...`` (``P_1 = -qd a``,
``P_2 = -qdd a + qd^2 a^2``, ``P_3 = -q3d a + 3 qd qdd a^2 - qd^3 a^3``). By Leibniz,

* a twist-like vector moved to a child:  ``(T Y)^(k) = sum_m C(k, m) P_m T Y^(k-m)``;
* a wrench-like vector moved to a parent: ``(T^T F)^(k) = T^T sum_m C(k, m) P_m^T F^(k-m)``;
* an inertia moved to a parent: ``(T^T L T)^(k) = T^T (sum_{a+b+c=k} k!/(a! b! c!) P_a^T L^(b) P_c) T``.

With these, the twist recursion ``V_i = T_i V_p + X_i qd_i`` gives ``V_i^(k) = (T_i V_p)^(k) + X_i q_i^(k+1)``
and the body Jacobian columns ``J_{i,j} = T_i J_{p,j}`` give their derivatives. ``k`` is always the
derivative order; every intermediate is named on the derivation's tape.

A floating base (body ``-1``, :mod:`._kinematics`) is moved by ``C_b = (R, p)`` with ``C_b^-1 dC_b/dt = V_b``,
so ``d/dt Ad(C_b^-1) = -ad(V_b) Ad(C_b^-1)``: its twist's derivatives are its own symbols (``qdd``, ``q3d``,
... of the base), its gravity term ``u_b = Ad(C_b^-1) (0, -g)`` has ``u_b^(k) = -sum_m C(k-1, m) ad(V_b^(m))
u_b^(k-1-m)``, and its Jacobian columns ``e_c`` are constant; the root joints' relative transforms are
differentiated as every other joint's.
"""

from __future__ import annotations

from collections.abc import Sequence
from math import comb, factorial

import sympy as sp

from ..model import _lie as lie
from ..model import _spatial as sa
from ._crba import composite_inertia
from ._derivation import Derivation, memoized
from ._jacobians import jacobian_columns, jacobian_dot_columns
from ._kinematics import (
    Terms, Vec, acceleration, gravity, is_zero, relative, screw, to_child, to_parent, twist, zero6,
)

MAX_ORDER = 3
"""Highest derivative of a relative transform used (``P_3`` holds q3d; tau's second derivative needs it)."""


def _combine(terms) -> Vec:
    """``sum c_k v_k`` over (coefficient, 6-vector) pairs, skipping zero terms."""
    out = zero6()
    for c, v in terms:
        if c != 0 and not is_zero(v):
            out = sa.add(out, sa.scale(v, c))
    return out


# ---------------------------------------------------------------------------------------------- transforms
@memoized
def coefficients(d: Derivation, i: int, m: int) -> list:
    """Coefficients ``c_p`` of ``P_m = sum_p c_p ad(X_i)^p`` (``T_i^(m) = P_m T_i``)."""
    if m > MAX_ORDER:
        raise ValueError(f"transform derivatives of order {m} > {MAX_ORDER} are not available")
    if m == 0:
        return [sp.Integer(1)]
    prev = [*coefficients(d, i, m - 1), sp.Integer(0)]
    syms = [d.inputs.state[k][i] for k in range(m + 1)]

    def ddt(c):
        return sum((sp.diff(c, syms[k]) * syms[k + 1] for k in range(m)), sp.Integer(0))

    return [sp.expand(ddt(prev[p]) - (syms[1] * prev[p - 1] if p else 0)) for p in range(m + 1)]


@memoized
def transform_derivative(d: Derivation, i: int, m: int) -> sp.Matrix:
    """``P_m`` as a 6x6 matrix."""
    a = lie.ad(screw(d, i))
    out, power = sp.zeros(6), sp.eye(6)
    for c in coefficients(d, i, m):
        out += c * power
        power = power * a
    return out


def _horner(d: Derivation, i: int, parts: list[Vec], apply) -> Vec:
    """``sum_p a^p parts[p]`` with ``a`` = ad(X_i) (``apply = ad_apply``) or its transpose."""
    x = screw(d, i)
    acc = d.tape.vec(parts[-1])
    for p in range(len(parts) - 2, -1, -1):
        acc = d.tape.vec(sa.add(parts[p], apply(x, acc)) if not is_zero(acc) else parts[p])
    return acc


def _weighted(d: Derivation, i: int, values: list[Vec], k: int) -> list[Vec]:
    """``B_p = sum_{m >= p} C(k, m) c_{m,p} values[k - m]`` for p = 0..k."""
    return [
        _combine((d.tape(comb(k, m) * coefficients(d, i, m)[p]), values[k - m]) for m in range(p, k + 1))
        for p in range(k + 1)
    ]


def transported(d: Derivation, i: int, jet: Sequence[Vec], k: int) -> Vec:
    """``(T_i Y)^(k)`` from the derivatives ``jet = [Y, Y', ...]`` of a motion vector in the parent's frame."""
    moved = [to_child(d, i, jet[j]) for j in range(k + 1)]
    return _horner(d, i, _weighted(d, i, moved, k), sa.ad_apply)


def pulled(d: Derivation, i: int, jet: Sequence[Vec], k: int) -> Vec:
    """``(T_i^T F)^(k)`` from the derivatives ``jet = [F, F', ...]`` of a wrench in body i's frame."""
    if all(is_zero(jet[j]) for j in range(k + 1)):
        return zero6()
    inner = _horner(d, i, _weighted(d, i, [list(v) for v in jet[: k + 1]], k), sa.adT_apply)
    return to_parent(d, i, inner)


# ---------------------------------------------------------------------------------------------- kinematics
@memoized
def twist_derivative(d: Derivation, i: int, k: int) -> Vec:
    """``V_i^(k)``: body twist (k = 0), body acceleration without gravity (k = 1), jerk, ... (``i = -1``: the
    floating base's, its own symbols; zero for the world)."""
    if k == 0:
        return twist(d, i)
    if k == 1:
        return acceleration(d, i, Terms.MOTION)
    if i < 0:
        return list(d.inputs.base[k + 1]) if d.floating else zero6()
    parent = d.robot.joints[i].parent
    base = zero6()
    if d.is_body(parent):
        base = transported(d, i, [twist_derivative(d, parent, j) for j in range(k + 1)], k)
    return d.tape.vec(sa.add(base, sa.scale(screw(d, i), d.inputs.state[k + 1][i])))


@memoized
def gravity_derivative(d: Derivation, i: int, k: int) -> Vec:
    """``u_i^(k)`` with ``u_i = Ad(C_i^-1) (0, -g)``: the fictitious base acceleration in body i's frame."""
    if k == 0:
        return acceleration(d, i, Terms.GRAVITY)
    if i < 0:  # the floating base: d/dt u_b = -ad(V_b) u_b
        terms = [(-comb(k - 1, m), sa.ad_apply(twist_derivative(d, -1, m), gravity_derivative(d, -1, k - 1 - m)))
                 for m in range(k)]
        return d.tape.vec(_combine(terms))
    parent = d.robot.joints[i].parent
    if d.is_body(parent):
        jet = [gravity_derivative(d, parent, j) for j in range(k + 1)]
    else:
        jet = [[0, 0, 0, *(-g for g in gravity(d))]] + [zero6()] * k
    return transported(d, i, jet, k)


@memoized
def jacobian_column_derivative(d: Derivation, i: int, j: int, k: int) -> Vec:
    """``J_{i,j}^(k)``: derivative of column j of body i's body Jacobian (j supports i)."""
    if i < 0:  # the floating base's own columns, constant
        return jacobian_columns(d, i)[j] if k == 0 else zero6()
    if j == i:
        return screw(d, i) if k == 0 else zero6()
    if k == 0:
        return jacobian_columns(d, i)[j]
    if k == 1:
        return jacobian_dot_columns(d, i)[j]
    parent = d.robot.joints[i].parent
    jet = [jacobian_column_derivative(d, parent, j, r) for r in range(k + 1)]
    return transported(d, i, jet, k)


@memoized
def composite_inertia_derivative(d: Derivation, i: int, k: int) -> sp.Matrix:
    """``Ic_i^(k)``, the derivative of the composite inertia of the subtree of body i (body i's frame)."""
    if k == 0:
        return composite_inertia(d, i)
    # A derivative of an inertia [[I, h~], [-h~, m 1]] has that form with m' = 0: each child's term moves to
    # the parent as (0, h', I'), by the parallel-axis rule of the composite inertia itself (about 100
    # operations), not as a general 6x6 congruence (about 800).
    zero = sp.Integer(0)
    parts = (zero, [zero] * 3, [[zero] * 3 for _ in range(3)])
    for c in d.robot.children(i):
        inner = sp.zeros(6)
        for a in range(k + 1):
            for b in range(k + 1 - a):
                e = k - a - b
                w = factorial(k) // (factorial(a) * factorial(b) * factorial(e))
                inner += (w * transform_derivative(d, c, a).T * composite_inertia_derivative(d, c, b)
                          * transform_derivative(d, c, e))
        inner = sp.Matrix(6, 6, lambda r, s: d.tape(sp.expand(inner[min(r, s), max(r, s)])))
        _, h, rot = sa.inertia_parts(inner.tolist())
        parts = sa.add_inertia_parts(parts, *relative(d, c), (zero, h, rot), d.tape.vec)
    _, h, rot = parts
    h = d.tape.vec(h)
    hx = lie.skew(h)
    top = sp.Matrix(3, 3, lambda r, s: d.tape(rot[min(r, s)][max(r, s)])).row_join(hx)
    return top.col_join((-hx).row_join(sp.zeros(3)))
