"""Closed-form time derivatives of the equations of motion, and the full kinematic set.

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

With these, the twist recursion ``V_i = T_i V_p + X_i qd_i`` gives ``V_i^(k) = (T_i V_p)^(k) + X_i q_i^(k+1)``;
the body Jacobian columns ``J_{i,j} = T_i J_{p,j}`` give their derivatives; Newton-Euler's body wrench
``W_i = M_i A_i - ad(V_i)^T M_i V_i`` is bilinear in the twists, so ``W_i^(k)`` is a Leibniz sum; and the
backward pass ``F_i = W_i + sum_c T_c^T F_c`` is differentiated with the wrench rule above. Each
derivative of tau, Q_grav and Q_ext is thus a Newton-Euler pass over differentiated kinematics, dM/dt a
composite-rigid-body pass over differentiated composite inertias, and dC/dt the column-wise Newton-Euler
pass of :meth:`Kinematics.coriolis_matrix` over differentiated Jacobian columns and twists. Every
intermediate is named on the shared tape, so the quantities requested together share their work.

Kinematic set (Müller, "Screw and Lie group theory in multibody kinematics", Multibody Syst Dyn 43, 2018):
*body* quantities are in the moving frame's own coordinates; *hybrid* ones are at the frame's origin in
world axes, ``V^h = (R omega^b, R v^b) = (omega, dp/dt)``, and the hybrid acceleration is the time derivative of
the hybrid twist, ``dV^h/dt = (domega/dt, d^2p/dt^2) = (R domega^b/dt, R (dv^b/dt + omega^b x v^b))``
(the classical acceleration of the origin). The body acceleration ``dV^b/dt`` is Pinocchio's spatial
acceleration in ``LOCAL``; Pinocchio's ``LOCAL_WORLD_ALIGNED`` spatial acceleration is
``(R domega^b/dt, R dv^b/dt)`` and differs from ours by ``(0, omega x v)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from math import comb, factorial

import sympy as sp

from ..model import _lie as lie
from ..equations._derive import QuantitySpec, _flat, hybridize, register
from ._kinematics import Kinematics, Vec, ad_apply, add, coad_apply, cross, dot, inertia_apply, matvec, scale

MAX_ORDER = 3
"""Highest derivative of a relative transform used (``P_3`` holds q3d; tau's second derivative needs it)."""


def _zero() -> Vec:
    return [sp.Integer(0)] * 6


def _is_zero(v: Sequence) -> bool:
    return all(e == 0 for e in v)


def _combine(terms) -> Vec:
    """``sum c_k v_k`` over (coefficient, 6-vector) pairs, skipping zero terms."""
    out = _zero()
    for c, v in terms:
        if c != 0 and not _is_zero(v):
            out = add(out, scale(v, c))
    return out


def _adT_apply(x: Sequence, f: Sequence) -> Vec:
    """``ad(X)^T F``."""
    return [-e for e in coad_apply(x, f)]


class TimeDerivatives:
    """Time derivatives of the body-fixed recursions of one :class:`Kinematics` (on its tape).

    ``k`` is always the derivative order; results are memoised. Use :func:`time_derivatives` to get the
    instance that belongs to a ``Kinematics``.
    """

    def __init__(self, kin: Kinematics):
        self.kin = kin
        self.tape = kin.tape
        self.n = kin.n
        self._memo: dict = {}

    # ------------------------------------------------------------------ transform derivatives
    def _state(self, i: int, order: int):
        return self.kin.state[Kinematics.ORDERS[order]][i]

    def coefficients(self, i: int, m: int) -> list:
        """Coefficients ``c_p`` of ``P_m = sum_p c_p ad(X_i)^p`` (``T_i^(m) = P_m T_i``)."""
        if m > MAX_ORDER:
            raise ValueError(f"transform derivatives of order {m} > {MAX_ORDER} are not available")
        key = ("P", i, m)
        if key in self._memo:
            return self._memo[key]
        if m == 0:
            out = [sp.Integer(1)]
        else:
            prev = self.coefficients(i, m - 1)
            syms = [self._state(i, k) for k in range(m + 1)]

            def ddt(c):
                return sum((sp.diff(c, syms[k]) * syms[k + 1] for k in range(m)), sp.Integer(0))

            prev = [*prev, sp.Integer(0)]
            out = [sp.expand(ddt(prev[p]) - (syms[1] * prev[p - 1] if p else 0)) for p in range(m + 1)]
        self._memo[key] = out
        return out

    def _horner(self, i: int, parts: list[Vec], apply) -> Vec:
        """``sum_p a^p parts[p]`` with ``a`` = ad(X_i) (``apply = ad_apply``) or its transpose."""
        x = self.kin.screw(i)
        acc = self.tape.vec(parts[-1])
        for p in range(len(parts) - 2, -1, -1):
            acc = self.tape.vec(add(parts[p], apply(x, acc)) if not _is_zero(acc) else parts[p])
        return acc

    def _weighted(self, i: int, values: list[Vec], k: int) -> list[Vec]:
        """``B_p = sum_{m >= p} C(k, m) c_{m,p} values[k - m]`` for p = 0..k."""
        return [
            _combine((self.tape(comb(k, m) * self.coefficients(i, m)[p]), values[k - m]) for m in range(p, k + 1))
            for p in range(k + 1)
        ]

    def transported(self, i: int, jet: Sequence[Vec], k: int) -> Vec:
        """``(T_i Y)^(k)`` from the derivatives ``jet = [Y, Y', ...]`` of a motion vector in the parent's frame."""
        moved = [self.kin.to_child(i, jet[j]) for j in range(k + 1)]
        return self._horner(i, self._weighted(i, moved, k), ad_apply)

    def pulled(self, i: int, jet: Sequence[Vec], k: int) -> Vec:
        """``(T_i^T F)^(k)`` from the derivatives ``jet = [F, F', ...]`` of a wrench in body i's frame."""
        if all(_is_zero(jet[j]) for j in range(k + 1)):
            return _zero()
        inner = self._horner(i, self._weighted(i, [list(v) for v in jet[: k + 1]], k), _adT_apply)
        return self.kin.to_parent(i, inner)

    def _p_matrix(self, i: int, m: int) -> sp.Matrix:
        key = ("Pm", i, m)
        if key not in self._memo:
            a = lie.ad(self.kin.screw(i))
            out, power = sp.zeros(6), sp.eye(6)
            for c in self.coefficients(i, m):
                out += c * power
                power = power * a
            self._memo[key] = out
        return self._memo[key]

    # ------------------------------------------------------------------ differentiated kinematics
    def twist(self, i: int, k: int) -> Vec:
        """``V_i^(k)``: body twist (k = 0), body acceleration without gravity (k = 1), jerk, ..."""
        if i < 0:
            return _zero()
        if k == 0:
            return self.kin.twist(i)
        if k == 1:
            return self.kin.acceleration(i)
        key = ("V", i, k)
        if key not in self._memo:
            parent = self.kin.robot.joints[i].parent
            base = self.transported(i, [self.twist(parent, j) for j in range(k + 1)], k) if parent >= 0 else _zero()
            self._memo[key] = self.tape.vec(add(base, scale(self.kin.screw(i), self._state(i, k + 1))))
        return self._memo[key]

    def gravity(self, i: int, k: int) -> Vec:
        """``u_i^(k)`` with ``u_i = Ad(C_i^-1) (0, -g)``: the fictitious base acceleration in body i's frame."""
        if k == 0:
            return self.kin.acceleration(i, velocity=False, accel=False, gravity=True)
        key = ("u", i, k)
        if key not in self._memo:
            parent = self.kin.robot.joints[i].parent
            if parent >= 0:
                jet = [self.gravity(parent, j) for j in range(k + 1)]
            else:
                jet = [[0, 0, 0, *(-g for g in self.kin.gravity)]] + [_zero()] * k
            self._memo[key] = self.transported(i, jet, k)
        return self._memo[key]

    def jacobian_column(self, i: int, j: int, k: int) -> Vec:
        """``J_{i,j}^(k)``: derivative of column j of body i's body Jacobian (j supports i)."""
        if j == i:
            return self.kin.screw(i) if k == 0 else _zero()
        if k == 0:
            return self.kin.jacobian_columns(i)[j]
        if k == 1:
            return self.kin.jacobian_dot_columns(i)[j]
        key = ("J", i, j, k)
        if key not in self._memo:
            parent = self.kin.robot.joints[i].parent
            jet = [self.jacobian_column(parent, j, r) for r in range(k + 1)]
            self._memo[key] = self.transported(i, jet, k)
        return self._memo[key]

    def composite_inertia(self, i: int, k: int) -> sp.Matrix:
        """``Ic_i^(k)``, the derivative of the composite inertia of the subtree of body i (body i's frame)."""
        if k == 0:
            return self.kin.composite_inertia(i)
        key = ("Ic", i, k)
        if key in self._memo:
            return self._memo[key]
        out = sp.zeros(6)
        for c in self.kin.robot.children(i):
            inner = sp.zeros(6)
            for a in range(k + 1):
                for b in range(k + 1 - a):
                    e = k - a - b
                    w = factorial(k) // (factorial(a) * factorial(b) * factorial(e))
                    inner += w * self._p_matrix(c, a).T * self.composite_inertia(c, b) * self._p_matrix(c, e)
            inner = sp.Matrix(6, 6, lambda r, s: self.tape(sp.expand(inner[min(r, s), max(r, s)])))
            out += self.kin.transform_inertia_to_parent(c, inner)
        out = sp.Matrix(6, 6, lambda r, s: self.tape(out[min(r, s), max(r, s)]))
        self._memo[key] = out
        return out

    # ------------------------------------------------------------------ differentiated dynamics
    def backward(self, wrench: list, k: int) -> list[Vec]:
        """``tau^(k)`` of the Newton-Euler backward pass ``F_i = W_i + sum_c T_c^T F_c``, ``tau_i = X_i^T F_i``.

        ``wrench[i]`` holds the derivatives ``[W_i, W_i', ..., W_i^(k)]`` of body i's own wrench.
        """
        f = [[list(w) for w in wrench[i]] for i in range(self.n)]
        tau = [sp.Integer(0)] * self.n
        for i in reversed(range(self.n)):
            jet = [self.tape.vec(w) for w in f[i]]
            tau[i] = self.tape(dot(self.kin.screw(i), jet[k]))
            parent = self.kin.robot.joints[i].parent
            if parent >= 0:
                for r in range(k + 1):
                    moved = self.pulled(i, jet, r)
                    if not _is_zero(moved):
                        f[parent][r] = add(f[parent][r], moved)
        return tau

    def body_wrench(self, i: int, k: int, *, velocity: bool, gravity: bool) -> Vec:
        """``W_i^(k)`` of ``W_i = M_i (Vd_i + u_i) - ad(V_i)^T M_i V_i`` (``velocity=False``: only ``M_i u_i``)."""
        if k == 0:
            return self.kin.body_wrench(i, velocity=velocity, accel=velocity, gravity=gravity)
        key = ("W", i, k, velocity, gravity)
        if key in self._memo:
            return self._memo[key]
        m = self.kin.inertia(i)
        terms = []
        if velocity:
            terms.append(self.twist(i, k + 1))
        if gravity:
            terms.append(self.gravity(i, k))
        out = inertia_apply(m, self.tape.vec(add(*terms)))
        if velocity:
            for r in range(k + 1):
                h = self.tape.vec(inertia_apply(m, self.twist(i, k - r)))
                out = add(out, scale(coad_apply(self.twist(i, r), h), comb(k, r)))
        self._memo[key] = out = self.tape.vec(out)
        return out

    def newton_euler(self, k: int, *, velocity: bool, gravity: bool) -> list[Vec]:
        """``tau^(k)`` (``velocity=True``: inverse dynamics) or ``Q_grav^(k)`` (``velocity=False``)."""
        jets = [[self.body_wrench(i, r, velocity=velocity, gravity=gravity) for r in range(k + 1)] for i in range(self.n)]
        return self.backward(jets, k)

    def external_torques(self, wrenches: Sequence[Sequence[Sequence]], k: int) -> list[Vec]:
        """``Q_ext^(k)``; ``wrenches[e][r]`` is the r-th derivative of end-effector e's wrench."""
        per_body = [[_zero() for _ in range(k + 1)] for _ in range(self.n)]
        for e, name in enumerate(self.kin.robot.end_effectors):
            f = self.kin.robot.frame(name)
            if f.body < 0:
                continue
            for r in range(k + 1):
                per_body[f.body][r] = add(per_body[f.body][r], wrench_to_body(self.kin, name, wrenches[e][r]))
        return self.backward(per_body, k)

    def mass_matrix(self, k: int) -> sp.Matrix:
        """``M^(k)``: ``M_ij = X_j^T (T^T ... Ic_i X_i)``, the composite-rigid-body pass over ``Ic^(r)``."""
        n = self.n
        m = sp.zeros(n)
        for i in range(n):
            x = self.kin.screw(i)
            jet = [self.tape.vec(self.kin.apply_composite(i, x) if r == 0 else
                                 inertia_apply(self.composite_inertia(i, r), x)) for r in range(k + 1)]
            m[i, i] = self.tape(dot(x, jet[k]))
            j = i
            while self.kin.robot.joints[j].parent >= 0:
                jet = [self.pulled(j, jet, r) for r in range(k + 1)]
                j = self.kin.robot.joints[j].parent
                m[i, j] = m[j, i] = self.tape(dot(self.kin.screw(j), jet[k]))
        return m

    def coriolis_matrix(self, k: int) -> sp.Matrix:
        """``C^(k)`` of :meth:`Kinematics.coriolis_matrix`: column c is the backward pass of
        ``W_i = M_i Jd_{i,c} + B(V_i) J_{i,c}``, with ``B`` bilinear in (V, J), differentiated by Leibniz."""
        n = self.n
        out = sp.zeros(n)
        for c in range(n):
            wrench = []
            for i in range(n):
                if c not in self.kin.jacobian_columns(i):
                    wrench.append([_zero()] * (k + 1))
                    continue
                wrench.append([self._coriolis_wrench(i, c, r) for r in range(k + 1)])
            col = self.backward(wrench, k)
            for i in range(n):
                out[i, c] = col[i]
        return out

    def _coriolis_wrench(self, i: int, c: int, r: int) -> Vec:
        """``d^r/dt^r (M J'_{i,c} + B(V_i) J_{i,c})``, ``B(V) X = 1/2 (M [V, X] + V x* (M X) + X x* (M V))``.

        B is bilinear, so the Leibniz sum ``sum_s C(r, s) B(V^(s), J^(r-s))`` applies M once to the sum of
        the brackets, and the products ``M J^(j)`` and ``M V^(s)`` are shared between orders.
        """
        m = self.kin.inertia(i)
        if r == 0:  # the same expressions as Kinematics.coriolis_matrix, so both share the tape
            v = self.kin.twist(i)
            h = self.tape.vec(inertia_apply(m, v))
            return add(inertia_apply(m, self.jacobian_column(i, c, 1)),
                       self.kin.christoffel_gyro(m, v, h, self.jacobian_column(i, c, 0)))
        key = ("Cw", i, c, r)
        if key in self._memo:
            return self._memo[key]
        brackets, duals = [], []
        for s in range(r + 1):
            v, x, w = self.twist(i, s), self.jacobian_column(i, c, r - s), comb(r, s)
            if _is_zero(x):
                continue
            h = self.tape.vec(inertia_apply(m, v))
            mx = self.tape.vec(inertia_apply(m, x))
            brackets.append(scale(ad_apply(v, x), w))
            duals.append(scale(add(coad_apply(v, mx), coad_apply(x, h)), w))
        inner = add(self.jacobian_column(i, c, r + 1), scale(add(_zero(), *brackets), sp.Rational(1, 2)))
        out = add(inertia_apply(m, self.tape.vec(inner)), scale(add(_zero(), *duals), sp.Rational(1, 2)))
        self._memo[key] = out = self.tape.vec(out)
        return out


def time_derivatives(kin: Kinematics) -> TimeDerivatives:
    """The :class:`TimeDerivatives` of ``kin`` (one per Kinematics, so requests share work)."""
    key = ("time_derivatives",)
    if key not in kin._memo:
        kin._memo[key] = TimeDerivatives(kin)
    return kin._memo[key]


# ---------------------------------------------------------------------------------------------- frames
def _offset(kin: Kinematics, name: str):
    f = kin.robot.frame(name)
    off = sp.Matrix(f.offset)
    return f.body, [[off[a, b] for b in range(3)] for a in range(3)], [off[a, 3] for a in range(3)]


def to_frame(kin: Kinematics, name: str, v: Sequence) -> Vec:
    """A motion vector of the frame's body, in body coordinates -> the frame's: ``Ad(T_f^-1) v``."""
    _, r, p = _offset(kin, name)
    if _is_zero(v) or (r == [[1, 0, 0], [0, 1, 0], [0, 0, 1]] and all(e == 0 for e in p)):
        return list(v)
    w, u = v[:3], v[3:]
    rt = [[r[b][a] for b in range(3)] for a in range(3)]
    return kin.tape.vec([*matvec(rt, w), *matvec(rt, add(u, cross(w, p)))])


def wrench_to_body(kin: Kinematics, name: str, w: Sequence) -> Vec:
    """A wrench (moment, force) in the frame's coordinates -> the body's: ``Ad(T_f^-1)^T W``."""
    _, r, p = _offset(kin, name)
    f2 = matvec(r, w[3:])
    return [*add(matvec(r, w[:3]), cross(p, f2)), *f2]


def frame_motion(kin: Kinematics, name: str, k: int) -> Vec:
    """Body twist (k = 0) or body acceleration (k = 1) of a named frame, in its own coordinates."""
    body = kin.robot.frame(name).body
    if body < 0:
        return _zero()
    return to_frame(kin, name, time_derivatives(kin).twist(body, k))


def hybrid_acceleration(kin: Kinematics, r, v: Sequence, vd: Sequence) -> Vec:
    """``d/dt (R omega, R v) = (R domega, R (dv + omega x v))`` from body twist v and its derivative vd."""
    return hybridize(kin, r, [*vd[:3], *add(vd[3:], cross(v[:3], v[3:]))])


def _frame_jacobian_dot(kin: Kinematics, name: str) -> list[Vec]:
    body = kin.robot.frame(name).body
    if body < 0:
        return [_zero() for _ in range(kin.n)]
    cols = kin.jacobian_dot_columns(body)
    return [to_frame(kin, name, cols[j]) if j in cols else _zero() for j in range(kin.n)]


# ---------------------------------------------------------------------------------------------- builders
def _matrix(m: sp.Matrix) -> list:
    return _flat(m.tolist())


def _wrench_jet(kin: Kinematics, k: int):
    names = ("wrench_symbols", "wrench_d_symbols", "wrench_dd_symbols")
    return [[list(getattr(kin, names[r])[e]) for r in range(k + 1)] for e in range(len(kin.robot.end_effectors))]


def _bodies(kin: Kinematics, fn) -> list:
    return _flat([fn(i) for i in range(kin.n)])


def _ees(kin: Kinematics, fn) -> list:
    return _flat([fn(name) for name in kin.robot.end_effectors])


def _body_hybrid_twist(kin, i):
    return hybridize(kin, kin.absolute(i)[0], kin.twist(i))


def _body_hybrid_acceleration(kin, i):
    return hybrid_acceleration(kin, kin.absolute(i)[0], kin.twist(i), kin.acceleration(i))


def _ee_hybrid_twist(kin, name):
    return hybridize(kin, kin.frame_pose(name)[0], frame_motion(kin, name, 0))


def _ee_hybrid_acceleration(kin, name):
    r = kin.frame_pose(name)[0]
    return hybrid_acceleration(kin, r, frame_motion(kin, name, 0), frame_motion(kin, name, 1))


def _system_jacobian(kin: Kinematics, dot_: bool) -> list:
    rows = []
    for i in range(kin.n):
        cols = kin.jacobian_dot_columns(i) if dot_ else kin.jacobian_columns(i)
        full = [cols.get(j, _zero()) for j in range(kin.n)]
        rows.extend([[full[j][r] for j in range(kin.n)] for r in range(6)])
    return _flat(rows)


def _jacobian_dot(kin: Kinematics, hybrid: bool) -> list:
    out = []
    for name in kin.robot.end_effectors:
        jd = _frame_jacobian_dot(kin, name)
        if hybrid:
            j = kin.frame_jacobian(name)
            r = kin.frame_pose(name)[0]
            w = frame_motion(kin, name, 0)[:3]
            jd = [hybridize(kin, r, add(jd[c], [*cross(w, j[c][:3]), *cross(w, j[c][3:])])) for c in range(kin.n)]
        out.append([[jd[c][r] for c in range(kin.n)] for r in range(6)])
    return _flat(out)


def _td(kin):
    return time_derivatives(kin)


# ---------------------------------------------------------------------------------------------- shapes
def _SQUARE(r):
    return (r.n_dof, r.n_dof)


def _VECTOR(r):
    return (r.n_dof,)


def _BODIES(r):
    return (r.n_dof, 6)


def _EES(r):
    return (len(r.end_effectors), 6)


def _EE_JACOBIAN(r):
    return (len(r.end_effectors), 6, r.n_dof)


def _SYSTEM(r):
    return (6 * r.n_dof, r.n_dof)


# ---------------------------------------------------------------------------------------------- registry

for _k, _suffix, _word in ((1, "_dot", "First"), (2, "_ddot", "Second")):
    _d = "d/dt" if _k == 1 else "d^2/dt^2"
    register(QuantitySpec(
        "mass_matrix" + _suffix, ("q", "qd", "qdd")[: _k + 1], _SQUARE,
        lambda kin, k=_k: _matrix(_td(kin).mass_matrix(k)),
        f"{_d} M(q)",
        f"{_word} time derivative of the mass matrix: composite-rigid-body pass over the derivatives of the "
        "composite inertias (Müller & Kumar 2021); dM/dt = C + C^T.",
    ))
    register(QuantitySpec(
        "coriolis_matrix" + _suffix, ("q", "qd", "qdd", "q3d")[: _k + 2], _SQUARE,
        lambda kin, k=_k: _matrix(_td(kin).coriolis_matrix(k)),
        f"{_d} C(q, qd)",
        f"{_word} time derivative of the Christoffel-consistent Coriolis matrix of coriolis_matrix.",
    ))
    register(QuantitySpec(
        "gravity_torques" + _suffix, ("q", "qd", "qdd")[: _k + 1], _VECTOR,
        lambda kin, k=_k: _td(kin).newton_euler(k, velocity=False, gravity=True),
        f"{_d} Q_grav(q)",
        f"{_word} time derivative of the generalized gravity forces (differentiated Newton-Euler pass).",
    ))
    register(QuantitySpec(
        "inverse_dynamics" + _suffix, ("q", "qd", "qdd", "q3d", "q4d")[: _k + 3], _VECTOR,
        lambda kin, k=_k: _td(kin).newton_euler(k, velocity=True, gravity=True),
        f"{_d} tau = {_d} (M qdd + C qd + Q_grav)",
        f"{_word} time derivative of the joint forces along a motion with jerk q3d"
        + (" and jounce q4d" if _k == 2 else "") + " (differentiated Newton-Euler pass).",
    ))
    register(QuantitySpec(
        "external_torques" + _suffix, (*("q", "qd", "qdd")[: _k + 1], *("wrench", "wrench_d", "wrench_dd")[: _k + 1]),
        _VECTOR,
        lambda kin, k=_k: _td(kin).external_torques(_wrench_jet(kin, k), k),
        f"{_d} Q_ext = {_d} sum_e J_e^T W_e",
        f"{_word} time derivative of the generalized end-effector forces, from the wrenches and their "
        "time derivatives (wrench_d" + (", wrench_dd" if _k == 2 else "") + "), (moment, force) in each "
        "end-effector's frame.",
        needs_end_effector=True,
    ))

register(QuantitySpec(
    "body_twist", ("q", "qd"), _BODIES, lambda kin: _bodies(kin, kin.twist),
    "V_i^ = C_i^-1 dC_i/dt, (omega, v)", "Body twist of every moving body, in its own frame.",
))
register(QuantitySpec(
    "hybrid_twist", ("q", "qd"), _BODIES, lambda kin: _bodies(kin, lambda i: _body_hybrid_twist(kin, i)),
    "V_i^h = (R_i omega_i, dp_i/dt)",
    "Hybrid twist of every moving body: angular velocity and velocity of the frame origin, world axes.",
))
register(QuantitySpec(
    "body_acceleration", ("q", "qd", "qdd"), _BODIES, lambda kin: _bodies(kin, kin.acceleration),
    "dV_i/dt", "Time derivative of the body twist of every moving body (Pinocchio's LOCAL spatial "
    "acceleration); gravity not included.",
))
register(QuantitySpec(
    "hybrid_acceleration", ("q", "qd", "qdd"), _BODIES,
    lambda kin: _bodies(kin, lambda i: _body_hybrid_acceleration(kin, i)),
    "dV_i^h/dt = (domega_i/dt, d^2p_i/dt^2)",
    "Time derivative of the hybrid twist of every moving body: angular acceleration and classical "
    "acceleration of the frame origin, world axes; gravity not included.",
))
register(QuantitySpec(
    "ee_body_twist", ("q", "qd"), _EES, lambda kin: _ees(kin, lambda f: frame_motion(kin, f, 0)),
    "V_e = J_e qd", "Body twist (omega, v) of each end-effector, in its own frame.", needs_end_effector=True,
))
register(QuantitySpec(
    "ee_hybrid_twist", ("q", "qd"), _EES, lambda kin: _ees(kin, lambda f: _ee_hybrid_twist(kin, f)),
    "V_e^h = J_e^h qd = (omega, dp_e/dt)", "Hybrid twist of each end-effector (world axes, at its origin).",
    needs_end_effector=True,
))
register(QuantitySpec(
    "ee_body_acceleration", ("q", "qd", "qdd"), _EES, lambda kin: _ees(kin, lambda f: frame_motion(kin, f, 1)),
    "dV_e/dt = J_e qdd + dJ_e/dt qd", "Time derivative of each end-effector's body twist; gravity not included.",
    needs_end_effector=True,
))
register(QuantitySpec(
    "ee_hybrid_acceleration", ("q", "qd", "qdd"), _EES,
    lambda kin: _ees(kin, lambda f: _ee_hybrid_acceleration(kin, f)),
    "dV_e^h/dt = J_e^h qdd + dJ_e^h/dt qd = (domega/dt, d^2p_e/dt^2)",
    "Time derivative of each end-effector's hybrid twist (classical acceleration of its origin, world axes).",
    needs_end_effector=True,
))
register(QuantitySpec(
    "system_jacobian", ("q",), _SYSTEM, lambda kin: _system_jacobian(kin, False),
    "V = J qd, J = (I - A)^-1 X",
    "Body-fixed system Jacobian: block row i is body i's body Jacobian (rows (omega, v) in body i's frame).",
))
register(QuantitySpec(
    "system_jacobian_dot", ("q", "qd"), _SYSTEM, lambda kin: _system_jacobian(kin, True),
    "dJ/dt, dV/dt = J qdd + dJ/dt qd", "Time derivative of the body-fixed system Jacobian.",
))
register(QuantitySpec(
    "body_jacobian_dot", ("q", "qd"), _EE_JACOBIAN, lambda kin: _jacobian_dot(kin, hybrid=False),
    "dJ_e/dt", "Time derivative of each end-effector's body Jacobian.", needs_end_effector=True,
))
register(QuantitySpec(
    "hybrid_jacobian_dot", ("q", "qd"), _EE_JACOBIAN, lambda kin: _jacobian_dot(kin, hybrid=True),
    "dJ_e^h/dt = blockdiag(R, R) (omega~ J_e + dJ_e/dt)",
    "Time derivative of each end-effector's hybrid Jacobian.", needs_end_effector=True,
))
