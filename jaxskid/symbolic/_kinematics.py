"""Poses, twists and accelerations of the bodies, on the tape.

All recursions of the symbolic stage are in the body-fixed representation (Müller 2018, "Screw and Lie
group theory in multibody dynamics", sec. 3, and Müller & Kumar 2021, sec. 2), with twists (omega, v) and
wrenches (moment, force):

* relative pose ``C_{p,i} = B_i exp(X_i q_i)``, ``T_i = Ad(C_{p,i}^-1)``;
* twist ``V_i = T_i V_p + X_i qd_i``;
* acceleration ``Vd_i = T_i Vd_p + X_i qdd_i + ad(V_i) X_i qd_i``, with ``Vd_0 = (0, -g)`` for gravity.

A floating base is body ``-1`` (:mod:`._derivation`): a joint with screw matrix ``X = I_6`` whose relative
configuration is the base pose ``C_b = (R, p)``, ``R`` the rotation of the quaternion in ``q`` (of the
normalised quaternion: :func:`base_pose`). Its twist ``V_b`` is the base velocity and its acceleration
``Vd_b = dV_b/dt + (0, -R^T g)``; it has no velocity-product term, since ``ad(V_b) V_b = 0``. Without a
floating base, body ``-1`` is the world: at rest, at the identity, with the acceleration ``(0, -g)``.

The spatial algebra is :mod:`jaxskid.model._spatial`'s; this module names its results on the tape.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence

import sympy as sp

from ..model import _spatial as sa
from ._derivation import Derivation, memoized

Vec = list  # a list of SymPy expressions


def zero6() -> Vec:
    return [sp.Integer(0)] * 6


def is_zero(v: Sequence) -> bool:
    """True if every entry is (structurally) zero."""
    return all(e == 0 for e in v)


def pose_rows(c: sp.Matrix) -> tuple[list[Vec], Vec]:
    """``(R, p)`` of a 4x4 pose, as rows and a 3-vector."""
    c = sp.Matrix(c)
    return [[c[r, k] for k in range(3)] for r in range(3)], [c[r, 3] for r in range(3)]


class Terms(enum.Enum):
    """Which terms of ``tau = M(q) qdd + C(q, qd) qd + Q_grav(q)`` a recursion keeps: the velocity terms
    (``qd``), the acceleration terms (``qdd``) and gravity (the fictitious base acceleration ``(0, -g)``).
    """

    INVERSE_DYNAMICS = (True, True, True)
    """``tau``: every term."""
    BIAS = (True, False, True)
    """``C(q, qd) qd + Q_grav(q)``."""
    CORIOLIS = (True, False, False)
    """``C(q, qd) qd``."""
    GRAVITY = (False, False, True)
    """``Q_grav(q)``."""
    MOTION = (True, True, False)
    """The motion alone: the body accelerations ``dV_i/dt``, without gravity."""
    NONE = (False, False, False)
    """No term: a Newton-Euler pass of external loads alone."""

    @property
    def velocity(self) -> bool:
        return self.value[0]

    @property
    def acceleration(self) -> bool:
        return self.value[1]

    @property
    def gravity(self) -> bool:
        return self.value[2]


# ---------------------------------------------------------------------------------------------- model data
def screw(d: Derivation, i: int) -> Vec:
    """Screw coordinates ``X_i`` (omega, v) of joint i, in body i's frame."""
    return [sp.sympify(x) for x in d.robot.joints[i].screw]


def inertia(d: Derivation, i: int) -> list[Vec]:
    """The 6x6 mass-inertia matrix of body i in its frame, as rows (``i = -1``: the floating base's)."""
    return sp.Matrix(d.robot.base_inertia if i < 0 else d.robot.joints[i].inertia).tolist()


def gravity(d: Derivation) -> Vec:
    """The gravity vector in the world frame."""
    return [sp.sympify(g) for g in d.robot.gravity]


# ---------------------------------------------------------------------------------------------- poses
@memoized
def relative(d: Derivation, i: int) -> tuple[list[Vec], Vec]:
    """(R, p) of ``C_{p,i}(q_i) = B_i exp(X_i q_i)``: body i's pose in its parent's frame."""
    t = d.tape
    x = screw(d, i)
    qi = d.q[i]
    w, v = x[:3], x[3:]
    if is_zero(w):  # prismatic
        sin_cos = None
    elif d.trig == "symbols":
        sin_cos = (t(sp.sin(qi)), t(sp.cos(qi)))
    else:
        sin_cos = (sp.sin(qi), sp.cos(qi))
    re, pe = sa.screw_exp(w, v, qi, sin_cos, t.vec)
    return sa.compose(*pose_rows(d.robot.joints[i].origin), re, pe, t.vec)


@memoized
def base_pose(d: Derivation) -> tuple[list[Vec], Vec]:
    """(R, p) of the floating base in the world: ``p = (x, y, z)`` and ``R`` the rotation of the quaternion
    ``(qx, qy, qz, qw)`` of ``q``, normalised: a quaternion that is not unit-norm gives the rotation of
    ``quat / |quat|`` (:func:`jaxskid.model._spatial.quaternion_rotation`), and a zero one gives no rotation
    (inf and nan)."""
    q = d.inputs.base[0]
    quat = q[3:7]
    scale2 = d.tape(2 / sp.Add(*(e**2 for e in quat)))
    return sa.quaternion_rotation(quat, scale2, d.tape.vec), list(q[:3])


@memoized
def absolute(d: Derivation, i: int) -> tuple[list[Vec], Vec]:
    """(R, p) of body i's pose in the world frame (``i = -1``: the floating base)."""
    if i < 0:
        return base_pose(d)
    r, p = relative(d, i)
    parent = d.robot.joints[i].parent
    if d.is_body(parent):
        r, p = sa.compose(*absolute(d, parent), r, p, d.tape.vec)
    return r, p


# ---------------------------------------------------------------------------------------------- transforms
def to_child(d: Derivation, i: int, v: Sequence) -> Vec:
    """``T_i V = Ad(C_{p,i}^-1) V``: a twist in the parent's frame, expressed in body i's frame."""
    if is_zero(v):
        return zero6()
    return d.tape.vec(sa.act_inv_motion(*relative(d, i), v))


def to_parent(d: Derivation, i: int, f: Sequence) -> Vec:
    """``T_i^T F``: a wrench in body i's frame, expressed in the parent's frame."""
    return d.tape.vec(sa.act_force(*relative(d, i), f, d.tape.vec))


# ---------------------------------------------------------------------------------------------- motion
@memoized
def twist(d: Derivation, i: int) -> Vec:
    """Body twist ``V_i`` (omega, v) of body i in its own frame (``i = -1``: the floating base's, or zero)."""
    if i < 0:
        return list(d.inputs.base[1]) if d.floating else zero6()
    parent = d.robot.joints[i].parent
    return d.tape.vec(sa.add(to_child(d, i, twist(d, parent)), sa.scale(screw(d, i), d.qd[i])))


def base_acceleration(d: Derivation, terms: Terms) -> Vec:
    """``Vd`` of body ``-1`` with the chosen terms: the floating base's acceleration (its symbols) and the
    fictitious ``(0, -R^T g)`` (gravity); for a fixed base, the world's ``(0, -g)`` or zero."""
    g = gravity(d)
    if not d.floating:
        return [0, 0, 0, *(-e for e in g)] if terms.gravity else zero6()
    parts = [zero6()]
    if terms.acceleration:
        parts.append(list(d.inputs.base[2]))
    if terms.gravity:
        parts.append([0, 0, 0, *(-e for e in sa.matTvec(base_pose(d)[0], g))])
    return d.tape.vec(sa.add(*parts))


@memoized
def acceleration(d: Derivation, i: int, terms: Terms) -> Vec:
    """Body acceleration ``Vd_i`` with the chosen terms: ``qd`` (velocity), ``qdd`` (acceleration) and
    the fictitious base acceleration ``(0, -g)`` (gravity); ``i = -1``: :func:`base_acceleration`."""
    if i < 0:
        return base_acceleration(d, terms)
    base = to_child(d, i, acceleration(d, d.robot.joints[i].parent, terms))
    x = screw(d, i)
    parts = [base]
    if terms.acceleration:
        parts.append(sa.scale(x, d.qdd[i]))
    if terms.velocity:
        parts.append(sa.scale(sa.ad_apply(twist(d, i), x), d.qd[i]))
    return d.tape.vec(sa.add(*parts))
