"""Closed-form kinematics and dynamics as a straight-line SymPy program.

Expression swell is what makes closed-form equations of motion slow to derive and slow to run. jaxskid
never multiplies the products out: every intermediate quantity (relative poses, twists, accelerations,
wrenches, composite inertias) is *named* on a :class:`Tape` as soon as it is formed, so each new
expression is a few operations on earlier names, and identical sub-expressions share one name
(hash-consing). The result is a DAG of small assignments; the lowering stage prunes it to what a quantity
needs and prints it.

All recursions are in the body-fixed representation (Müller 2018, "Screw and Lie group theory in multibody
dynamics", sec. 3, and Müller & Kumar 2021, sec. 2), with twists (omega, v) and wrenches (moment, force):

* relative pose ``C_{p,i} = B_i exp(X_i q_i)``, ``T_i = Ad(C_{p,i}^-1)``;
* twist ``V_i = T_i V_p + X_i qd_i``;
* acceleration ``Vd_i = T_i Vd_p + X_i qdd_i + ad(V_i) X_i qd_i``, with ``Vd_0 = (0, -g)`` for gravity;
* Newton-Euler wrench ``W_i = M_i Vd_i - ad(V_i)^T M_i V_i + sum_children T_c^T W_c``; ``tau_i = X_i^T W_i``.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import sympy as sp

from ..model import _lie as lie
from ..model._robot import Robot, symbol

Vec = list  # a list of SymPy expressions


class Tape:
    """Records named intermediate expressions ``_x{k} = expr`` in creation order, sharing duplicates."""

    def __init__(self, prefix: str = "_x"):
        self.prefix = prefix
        self.defs: dict[sp.Symbol, sp.Expr] = {}
        self._lookup: dict[sp.Expr, sp.Symbol] = {}

    def __call__(self, e) -> sp.Expr:
        e = sp.sympify(e)
        if _is_trivial(e):
            return e
        hit = self._lookup.get(e)
        if hit is not None:
            return hit
        neg = self._lookup.get(-e)
        if neg is not None:
            return -neg
        s = sp.Symbol(f"{self.prefix}{len(self.defs)}", real=True)
        self.defs[s] = e
        self._lookup[e] = s
        return s

    def vec(self, es) -> Vec:
        return [self(e) for e in es]


def _is_trivial(e: sp.Expr) -> bool:
    if e.is_Atom:
        return True
    if e.is_Mul and len(e.args) == 2 and e.args[0].is_Number and e.args[1].is_Atom:
        return True
    return False


# ---------------------------------------------------------------------------------------------- 3-vectors
def cross(a: Sequence, b: Sequence) -> Vec:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def matvec(m: Sequence[Sequence], v: Sequence) -> Vec:
    return [sum((m[r][c] * v[c] for c in range(len(v))), sp.Integer(0)) for r in range(len(m))]


def matTvec(m: Sequence[Sequence], v: Sequence) -> Vec:
    return [sum((m[r][c] * v[r] for r in range(len(v))), sp.Integer(0)) for c in range(len(m[0]))]


def matmul(a, b) -> list[Vec]:
    return [[sum((a[r][k] * b[k][c] for k in range(3)), sp.Integer(0)) for c in range(3)] for r in range(3)]


def dot(a: Sequence, b: Sequence):
    return sum((x * y for x, y in zip(a, b)), sp.Integer(0))


def add(*vs) -> Vec:
    return [sum(items, sp.Integer(0)) for items in zip(*vs)]


def scale(v: Sequence, s) -> Vec:
    return [x * s for x in v]


# ---------------------------------------------------------------------------------------------- 6-vectors
def ad_apply(v: Sequence, x: Sequence) -> Vec:
    """ad(V) X = [V, X] = (w x wx, v x wx + w x vx)."""
    w, u = v[:3], v[3:]
    return [*cross(w, x[:3]), *add(cross(u, x[:3]), cross(w, x[3:]))]


def coad_apply(v: Sequence, f: Sequence) -> Vec:
    """-ad(V)^T F = (w x n + v x f, w x f), the wrench "cross product" V x* F."""
    w, u = v[:3], v[3:]
    return [*add(cross(w, f[:3]), cross(u, f[3:])), *cross(w, f[3:])]


def inertia_apply(m6: sp.Matrix, v: Sequence) -> Vec:
    return [sum((m6[r, c] * v[c] for c in range(6) if m6[r, c] != 0), sp.Integer(0)) for r in range(6)]


class Kinematics:
    """Body-by-body symbolic recursions for one robot, with every intermediate on one shared tape.

    The state symbols are ``q[i]``, ``qd[i]``, ... (names ``_q{i}``, ``_qd{i}``, ...); the robot's
    parameters keep their own symbols. Results are memoised, so quantities requested together share work.
    """

    ORDERS = ("q", "qd", "qdd", "q3d", "q4d")

    def __init__(self, robot: Robot, tape: Tape | None = None, *, trig: str = "symbols"):
        self.robot = robot
        self.tape = tape or Tape()
        self.trig = trig  # "symbols": sin/cos of each q_i named once; "inline": left in every expression
        self.n = robot.n_dof
        self.state = {k: [sp.Symbol(f"_{k}{i}", real=True) for i in range(self.n)] for k in self.ORDERS}
        self.params = [symbol(p) for p in robot.parameters]
        self._memo: dict = {}

    # -- inputs
    @property
    def q(self):
        return self.state["q"]

    @property
    def qd(self):
        return self.state["qd"]

    @property
    def qdd(self):
        return self.state["qdd"]

    @cached_property
    def gravity(self) -> Vec:
        return [sp.sympify(g) for g in self.robot.gravity]

    def screw(self, i: int) -> Vec:
        return [sp.sympify(x) for x in self.robot.joints[i].screw]

    def inertia(self, i: int) -> sp.Matrix:
        return sp.Matrix(self.robot.joints[i].inertia)

    # -- poses
    def relative(self, i: int) -> tuple[list[Vec], Vec]:
        """(R, p) of ``C_{p,i}(q_i) = B_i exp(X_i q_i)``: body i's pose in its parent's frame."""
        key = ("rel", i)
        if key in self._memo:
            return self._memo[key]
        t = self.tape
        j = self.robot.joints[i]
        x = self.screw(i)
        qi = self.q[i]
        b = sp.Matrix(j.origin)
        rb = [[b[r, c] for c in range(3)] for r in range(3)]
        pb = [b[r, 3] for r in range(3)]
        w, v = x[:3], x[3:]
        if all(e == 0 for e in w):  # prismatic: exp = (1, v q)
            re = [[sp.Integer(int(r == c)) for c in range(3)] for r in range(3)]
            pe = [t(e * qi) for e in v]
        else:
            s, c = (t(sp.sin(qi)), t(sp.cos(qi))) if self.trig == "symbols" else (sp.sin(qi), sp.cos(qi))
            wx = lie.skew(w)
            wx2 = wx * wx
            re = [[t(sp.Integer(int(r == k)) + s * wx[r, k] + (1 - c) * wx2[r, k]) for k in range(3)] for r in range(3)]
            wv = cross(w, v)
            pitch = dot(w, v)
            # (1 - R) (w x v) + w (w . v) q
            pe = [t(wv[r] - dot(re[r], wv) + w[r] * pitch * qi) for r in range(3)]
        r = [[t(e) for e in row] for row in matmul(rb, re)]
        p = [t(e) for e in add(matvec(rb, pe), pb)]
        self._memo[key] = (r, p)
        return r, p

    def absolute(self, i: int) -> tuple[list[Vec], Vec]:
        """(R, p) of body i's pose in the world frame."""
        key = ("abs", i)
        if key in self._memo:
            return self._memo[key]
        r, p = self.relative(i)
        parent = self.robot.joints[i].parent
        if parent >= 0:
            rp, pp = self.absolute(parent)
            r = [self.tape.vec(row) for row in matmul(rp, r)]
            p = self.tape.vec(add(matvec(rp, p), pp))
        self._memo[key] = (r, p)
        return r, p

    def frame_pose(self, name: str) -> tuple[list[Vec], Vec]:
        """(R, p) of a named frame (body, merged link or end-effector) in the world frame."""
        f = self.robot.frame(name)
        off = sp.Matrix(f.offset)
        ro = [[off[r, c] for c in range(3)] for r in range(3)]
        po = [off[r, 3] for r in range(3)]
        if f.body < 0:
            return ro, po
        rb, pb = self.absolute(f.body)
        if off == sp.eye(4):
            return rb, pb
        r = [self.tape.vec(row) for row in matmul(rb, ro)]
        p = self.tape.vec(add(matvec(rb, po), pb))
        return r, p

    # -- motion transforms
    def to_child(self, i: int, v: Sequence) -> Vec:
        """``T_i V = Ad(C_{p,i}^-1) V``: a twist in the parent's frame, expressed in body i's frame."""
        r, p = self.relative(i)
        w, u = v[:3], v[3:]
        if all(e == 0 for e in w) and all(e == 0 for e in u):
            return [sp.Integer(0)] * 6
        w2 = matTvec(r, w)
        u2 = matTvec(r, add(u, cross(w, p)))
        return self.tape.vec([*w2, *u2])

    def to_parent(self, i: int, f: Sequence) -> Vec:
        """``T_i^T F``: a wrench in body i's frame, expressed in the parent's frame."""
        r, p = self.relative(i)
        n2 = matvec(r, f[:3])
        f2 = self.tape.vec(matvec(r, f[3:]))
        n2 = add(n2, cross(p, f2))
        return self.tape.vec([*n2, *f2])

    # -- twists and accelerations
    def twist(self, i: int) -> Vec:
        """Body twist ``V_i`` (omega, v) of body i in its own frame."""
        key = ("V", i)
        if key not in self._memo:
            parent = self.robot.joints[i].parent
            base = self.to_child(i, self.twist(parent)) if parent >= 0 else [sp.Integer(0)] * 6
            self._memo[key] = self.tape.vec(add(base, scale(self.screw(i), self.qd[i])))
        return self._memo[key]

    def acceleration(self, i: int, *, velocity: bool = True, accel: bool = True, gravity: bool = False) -> Vec:
        """Body acceleration ``Vd_i``, optionally with the fictitious base acceleration ``(0, -g)``.

        ``velocity=False`` sets qd = 0, ``accel=False`` sets qdd = 0 (for the terms of tau).
        """
        key = ("Vd", i, velocity, accel, gravity)
        if key in self._memo:
            return self._memo[key]
        parent = self.robot.joints[i].parent
        if parent >= 0:
            base = self.to_child(i, self.acceleration(parent, velocity=velocity, accel=accel, gravity=gravity))
        elif gravity:
            base = self.to_child(i, [0, 0, 0, *(-g for g in self.gravity)])
        else:
            base = [sp.Integer(0)] * 6
        x = self.screw(i)
        terms = [base]
        if accel:
            terms.append(scale(x, self.qdd[i]))
        if velocity:
            terms.append(scale(ad_apply(self.twist(i), x), self.qd[i]))
        out = self.tape.vec(add(*terms))
        self._memo[key] = out
        return out

    # -- dynamics
    def body_wrench(self, i: int, *, velocity: bool, accel: bool, gravity: bool) -> Vec:
        """Newton-Euler wrench of body i alone: ``M_i Vd_i - ad(V_i)^T M_i V_i``."""
        key = ("F", i, velocity, accel, gravity)
        if key in self._memo:
            return self._memo[key]
        m = self.inertia(i)
        vd = self.acceleration(i, velocity=velocity, accel=accel, gravity=gravity)
        terms = [inertia_apply(m, vd)]
        if velocity:
            v = self.twist(i)
            h = self.tape.vec(inertia_apply(m, v))
            terms.append(coad_apply(v, h))
        out = self.tape.vec(add(*terms))
        self._memo[key] = out
        return out

    def rnea(self, *, velocity: bool, accel: bool, gravity: bool, extra: dict[int, Vec] | None = None) -> Vec:
        """Generalized forces of the Newton-Euler recursion (Featherstone 2008, Alg. 5.1, body-fixed).

        ``extra`` adds wrenches (in body frames) that act like inertial loads, e.g. ``-F_ext``.
        """
        n = self.n
        wrench = [None] * n
        for i in range(n):
            parts = []
            if velocity or accel or gravity:
                parts.append(self.body_wrench(i, velocity=velocity, accel=accel, gravity=gravity))
            if extra and i in extra:
                parts.append(extra[i])
            wrench[i] = add(*parts) if parts else [sp.Integer(0)] * 6
        tau = [None] * n
        for i in reversed(range(n)):
            w = self.tape.vec(wrench[i])
            tau[i] = self.tape(dot(self.screw(i), w))
            parent = self.robot.joints[i].parent
            if parent >= 0 and any(e != 0 for e in w):
                wrench[parent] = add(wrench[parent], self.to_parent(i, w))
        return tau

    def composite_inertia_parts(self, i: int) -> tuple:
        """Composite inertia of the subtree at body i as ``(m, h, I)`` in body i's frame: mass, first
        moment ``h = m c`` and rotational inertia about the frame origin (CRBA, Featherstone 2008,
        Alg. 6.2, in the 10-parameter form). A child's ``(m, h, I)`` at pose ``(R, p)`` moves to the
        parent as ``h' = R h + m p`` and ``I' = R I R^T + m(|p|^2 1 - p p^T) - (h_R p^T + p h_R^T - 2 (p.h_R) 1)``.
        """
        key = ("Icp", i)
        if key in self._memo:
            return self._memo[key]
        t = self.tape
        m6 = self.inertia(i)
        mass = m6[5, 5]
        h = [m6[2, 4], m6[0, 5], m6[1, 3]]
        inert = [[m6[r, c] for c in range(3)] for r in range(3)]
        for c in self.robot.children(i):
            mc, hc, ic = self.composite_inertia_parts(c)
            r, p = self.relative(c)
            hr = t.vec(matvec(r, hc))
            ri = [t.vec(row) for row in matmul(r, ic)]  # R I
            rirt = [[t(sum((ri[a][k] * r[b][k] for k in range(3)), sp.Integer(0))) if a <= b else None
                     for b in range(3)] for a in range(3)]
            pp = t(dot(p, p))
            ph = t(dot(p, hr))
            mass = mass + mc
            h = add(h, hr, scale(p, mc))
            new_i = [[None] * 3 for _ in range(3)]
            for a_ in range(3):
                for b_ in range(a_, 3):
                    e = inert[a_][b_] + rirt[a_][b_] - mc * p[a_] * p[b_] - hr[a_] * p[b_] - p[a_] * hr[b_]
                    if a_ == b_:
                        e = e + mc * pp + 2 * ph
                    new_i[a_][b_] = new_i[b_][a_] = e
            inert = new_i
        mass = t(mass)
        h = t.vec(h)
        inert_t = [[None] * 3 for _ in range(3)]
        for a_ in range(3):
            for b_ in range(a_, 3):
                inert_t[a_][b_] = inert_t[b_][a_] = t(inert[a_][b_])
        out = (mass, h, inert_t)
        self._memo[key] = out
        return out

    def composite_inertia(self, i: int) -> sp.Matrix:
        """The composite inertia of :meth:`composite_inertia_parts` as a 6x6 matrix."""
        m, h, inert = self.composite_inertia_parts(i)
        hx = lie.skew(h)
        top = sp.Matrix(inert).row_join(hx)
        bottom = (-hx).row_join(m * sp.eye(3))
        return top.col_join(bottom)

    def apply_composite(self, i: int, x: Sequence) -> Vec:
        """``Ic_i X = (I w + h x v, m v + w x h)`` for a twist ``X = (w, v)``."""
        m, h, inert = self.composite_inertia_parts(i)
        w, v = x[:3], x[3:]
        return [*add(matvec(inert, w), cross(h, v)), *add(scale(v, m), cross(w, h))]

    def transform_inertia_to_parent(self, i: int, m6: sp.Matrix) -> sp.Matrix:
        """``T_i^T M T_i``: a 6x6 inertia in body i's frame, expressed in its parent's frame."""
        cols = []
        for k in range(6):  # T_i e_k, column by column, then T_i^T applied to M (T_i e_k)
            e = [0] * 6
            e[k] = 1
            cols.append(self.to_child(i, e))
        mt = [inertia_apply(m6, col) for col in cols]  # M T e_k
        out = sp.zeros(6)
        for k in range(6):
            w = self.to_parent(i, self.tape.vec(mt[k]))
            for r in range(6):
                out[r, k] = w[r]
        return sp.Matrix(6, 6, lambda r, k: out[r, k] if r <= k else out[k, r])

    def mass_matrix(self) -> sp.Matrix:
        """M(q) by the composite-rigid-body algorithm; only the lower triangle is computed."""
        n = self.n
        m = sp.zeros(n)
        for i in range(n):
            f = self.tape.vec(self.apply_composite(i, self.screw(i)))
            m[i, i] = self.tape(dot(self.screw(i), f))
            j = i
            while self.robot.joints[j].parent >= 0:
                f = self.to_parent(j, f)
                j = self.robot.joints[j].parent
                m[i, j] = m[j, i] = self.tape(dot(self.screw(j), f))
        return m

    def jacobian_columns(self, i: int) -> dict[int, Vec]:
        """Columns of body i's body Jacobian: joint j -> ``Ad(C_i^-1 C_j) X_j`` for j supporting i."""
        key = ("J", i)
        if key in self._memo:
            return self._memo[key]
        parent = self.robot.joints[i].parent
        cols = {}
        if parent >= 0:
            for j, col in self.jacobian_columns(parent).items():
                cols[j] = self.to_child(i, col)
        cols[i] = self.screw(i)
        self._memo[key] = cols
        return cols

    def jacobian_dot_columns(self, i: int) -> dict[int, Vec]:
        """Time derivative of :meth:`jacobian_columns`: ``Jd_i,j = T_i Jd_p,j - qd_i ad(X_i) J_i,j``."""
        key = ("Jd", i)
        if key in self._memo:
            return self._memo[key]
        parent = self.robot.joints[i].parent
        x = self.screw(i)
        cols = {}
        if parent >= 0:
            cur = self.jacobian_columns(i)
            for j, col in self.jacobian_dot_columns(parent).items():
                moved = self.to_child(i, col)
                cols[j] = self.tape.vec(add(moved, scale(ad_apply(x, cur[j]), -self.qd[i])))
        cols[i] = [sp.Integer(0)] * 6
        self._memo[key] = cols
        return cols

    def coriolis_matrix(self) -> sp.Matrix:
        """C(q, qd), the Coriolis matrix of the Christoffel symbols of the first kind.

        ``C = J^T (M Jd + B(V) J)`` with the body Jacobian J (Müller & Kumar 2021, sec. 2.2) and the
        per-body factorisation :meth:`christoffel_gyro`; ``C qd`` are the Coriolis/centrifugal forces,
        ``dM/dt - 2C`` is skew-symmetric and ``C(q, x) y = C(q, y) x``, as for Pinocchio's
        ``computeCoriolisMatrix``. Column k is assembled by a Newton-Euler backward pass.
        """
        n = self.n
        c = sp.zeros(n)
        for k in range(n):
            wrench: list = [None] * n
            for i in range(n):
                jc = self.jacobian_columns(i)
                if k not in jc:
                    wrench[i] = [sp.Integer(0)] * 6
                    continue
                m = self.inertia(i)
                jdk = self.jacobian_dot_columns(i)[k]
                v = self.twist(i)
                h = self.tape.vec(inertia_apply(m, v))
                col = jc[k]
                wrench[i] = add(inertia_apply(m, jdk), self.christoffel_gyro(m, v, h, col))
            for i in reversed(range(n)):
                w = self.tape.vec(wrench[i])
                c[i, k] = self.tape(dot(self.screw(i), w))
                parent = self.robot.joints[i].parent
                if parent >= 0 and any(e != 0 for e in w):
                    wrench[parent] = add(wrench[parent], self.to_parent(i, w))
        return c

    def christoffel_gyro(self, m: sp.Matrix, v: Sequence, h: Sequence, x: Sequence) -> Vec:
        """``B(V) X = 1/2 (M [V, X] + V x* (M X) + X x* (M V))`` with ``h = M V``.

        The body-fixed form of the Christoffel-consistent factorisation of Echeandia & Wensing (2021):
        ``B(V) V = V x* (M V)`` and ``B(V) - M ad(V)`` is skew-symmetric, so ``dM/dt - 2C`` is skew.
        """
        t1 = inertia_apply(m, ad_apply(v, x))
        t2 = coad_apply(v, self.tape.vec(inertia_apply(m, x)))
        t3 = skew_gyro(h, x)
        return [e / 2 for e in add(t1, t2, t3)]

    def frame_jacobian(self, name: str) -> list[Vec]:
        """Body Jacobian (6 x n, rows (omega, v)) of a named frame, in that frame's own coordinates."""
        f = self.robot.frame(name)
        cols = [[sp.Integer(0)] * 6 for _ in range(self.n)]
        if f.body < 0:
            return cols
        off = sp.Matrix(f.offset)
        inv = lie.inverse(off)
        ro = [[inv[r, c] for c in range(3)] for r in range(3)]
        po = [inv[r, 3] for r in range(3)]
        for j, col in self.jacobian_columns(f.body).items():
            if off == sp.eye(4):
                cols[j] = col
                continue
            # Ad(T^-1) col with T = offset: omega' = R^T w, v' = R^T (v + w x p)
            w, u = col[:3], col[3:]
            ro_t = [[ro[r][c] for c in range(3)] for r in range(3)]
            w2 = matvec(ro_t, w)
            u2 = add(matvec(ro_t, u), cross(po, w2))
            cols[j] = self.tape.vec([*w2, *u2])
        return cols

    def external_torques(self, wrenches: dict[str, Vec]) -> Vec:
        """``Q_ext = sum_ee J_ee^T W_ee`` with W in (moment, force) order in the end-effector's frame."""
        extra: dict[int, Vec] = {}
        for name, w in wrenches.items():
            f = self.robot.frame(name)
            if f.body < 0:
                continue
            # a wrench in the frame at pose T (relative to the body) expressed in the body frame: Ad(T^-1)^T W
            off = sp.Matrix(f.offset)
            r = [[off[a, b] for b in range(3)] for a in range(3)]
            p = [off[a, 3] for a in range(3)]
            f2 = matvec(r, w[3:])
            n2 = add(matvec(r, w[:3]), cross(p, f2))
            extra[f.body] = add(extra.get(f.body, [0] * 6), [*n2, *f2])
        return self.rnea(velocity=False, accel=False, gravity=False, extra=extra)


def skew_gyro(h: Sequence, x: Sequence) -> Vec:
    """``B(V) X = X x* h`` with ``h = M V``: ``(w_X x h_n + v_X x h_f, w_X x h_f)``.

    As a linear map of X this is skew-symmetric, and ``B(V) V = V x* (M V) = -ad(V)^T M V``.
    """
    w, u = x[:3], x[3:]
    hn, hf = h[:3], h[3:]
    return [*add(cross(w, hn), cross(u, hf)), *cross(w, hf)]
