"""The energy regressors: kinetic and potential energy, momentum and friction power, linear in the standard parameters.

Each body's energies are linear in its 10 standard parameters ``pi_i = (m, h, I)`` (``h = m c``, ``I`` about
the body frame's origin, in the order of :mod:`jaxskid.model._standard`). jaxskid writes the rows in closed
form from the body twist ``V_i = (w, v)`` and world pose ``(R_i, p_i)`` that the energies themselves use
(:mod:`._energy`), never by differentiating K or U with respect to the parameters (Gautier & Khalil,
"On the identification of the inertial parameters of robots", CDC 1988, the energy model):

* ``K_i = 1/2 V_i^T M_i V_i = 1/2 m |v|^2 + h . (v x w) + 1/2 w^T I w``: the row
  ``(|v|^2 / 2, (v x w)_x, (v x w)_y, (v x w)_z, w_x^2 / 2, w_x w_y, w_y^2 / 2, w_x w_z, w_y w_z, w_z^2 / 2)``;
* ``U_i = -g^T (R_i h + m p_i)``: the row ``(-g . p_i, -(R_i^T g)_x, -(R_i^T g)_y, -(R_i^T g)_z, 0, ..., 0)``;
* the momentum ``M(q) qd = sum_i J_i^T M_i V_i`` with ``M_i V_i = K(V_i) pi_i``
  (:func:`._regressor.inertia_columns`): ``Y[j, 10 k + c] = J_{k,j}^T K(V_k)[:, c]`` for the joints j that
  support body k (:func:`momentum_entries`), as the torque regressor is built from the bodies' wrench
  columns, and on the same body Jacobian columns.

The drives' columns follow, 4 per driven joint ``(Ia, fv, fc, fo)`` as in the torque regressor: the rotor's
``1/2 Ia qd_j^2`` gives K the column ``qd_j^2 / 2`` and the momentum ``qd_j`` in row j; the potential energy
has none. Friction and offset do no conservative work: their power ``qd^T (fv qd + fc sign(qd) + fo)`` is its
own row, ``(0, qd_j^2, qd_j sign(qd_j), qd_j)`` per driven joint (``tanh(qd_j / eps)`` for ``sign`` with
friction smoothing, :func:`._drives.coulomb`), so that along any motion

    d/dt (K + U) = qd^T tau - P_friction,   (K_row + U_row)(t1) - (K_row + U_row)(t0) + int P_row dt = int qd^T tau dt

(the power balance, Gautier, "Dynamic identification of robots with power model", ICRA 1997). A floating
base (body ``-1``) is a body like the others, its 10 columns first, its momentum the first six rows.
"""

from __future__ import annotations

import sympy as sp

from ..model import _spatial as sa
from ..model._standard import N_STANDARD
from ._derivation import Derivation
from ._drives import coulomb
from ._jacobians import jacobian_columns
from ._kinematics import Vec, absolute, gravity, twist

_ZERO = sp.Integer(0)


def _drives(d: Derivation, columns) -> list:
    """The drive columns of a row: ``columns(i)``, 4 entries ``(Ia, fv, fc, fo)``, for every driven joint i."""
    return [e for i in d.robot.driven for e in columns(i)]


def body_kinetic_row(d: Derivation, i: int) -> Vec:
    """The 10 entries of ``K_i = 1/2 V_i^T M_i V_i`` in body i's standard parameters (module docstring)."""
    t = d.tape
    v = twist(d, i)
    w, u = v[:3], v[3:]
    half = sp.Rational(1, 2)
    w0, w1, w2 = w
    row = [half * sa.dot(u, u), *sa.cross(u, w)]
    row += [half * w0 * w0, w0 * w1, half * w1 * w1, w0 * w2, w1 * w2, half * w2 * w2]
    return t.vec(row)


def body_potential_row(d: Derivation, i: int) -> Vec:
    """The 10 entries of ``U_i = -g^T (R_i h + m p_i)`` in body i's standard parameters."""
    g = gravity(d)
    r, p = absolute(d, i)
    g_body = sa.matTvec(r, g)  # R_i^T g: gravity in body i's axes
    return d.tape.vec([-sa.dot(g, p), *(-x for x in g_body)]) + [_ZERO] * 6


def kinetic_energy_regressor(d: Derivation) -> Vec:
    """``K(q, qd) = row pi``, shape ``(10 n_b + 4 n_driven,)`` (``n_b`` bodies, a floating base included)."""
    bodies = [e for i in d.bodies for e in body_kinetic_row(d, i)]
    rotor = _drives(d, lambda i: [d.tape(d.qd[i] ** 2 / 2), _ZERO, _ZERO, _ZERO])
    return bodies + rotor


def potential_energy_regressor(d: Derivation) -> Vec:
    """``U(q) = row pi``, shape ``(10 n_b + 4 n_driven,)``."""
    bodies = [e for i in d.bodies for e in body_potential_row(d, i)]
    return bodies + _drives(d, lambda i: [_ZERO] * 4)


def friction_power_regressor(d: Derivation) -> Vec:
    """``qd^T (fv qd + fc sign(qd) + fo) = row pi``, shape ``(10 n_b + 4 n_driven,)``: zero but in the
    friction and offset columns of the driven joints."""
    def columns(i):
        v = d.qd[i]
        return [_ZERO, d.tape(v**2), d.tape(v * coulomb(d, v)), v]

    return [_ZERO] * (N_STANDARD * len(d.bodies)) + _drives(d, columns)


def momentum_entries(jac: Vec, v: Vec) -> Vec:
    """``J^T K(V)``, the 10 entries of ``J^T M V`` in the standard parameters of ``M``, for a Jacobian column
    ``J = (J_w, J_v)`` and a twist ``V = (w, v)``: ``(J_v . v, J_v x w + v x J_w, J_w w^T`` symmetrised``)``.
    The columns of :func:`._regressor.inertia_columns` dotted with J, written out."""
    jw, jv, w, u = jac[:3], jac[3:], v[:3], v[3:]
    (a0, a1, a2), (w0, w1, w2) = jw, w
    return [sa.dot(jv, u), *sa.add(sa.cross(jv, w), sa.cross(u, jw)),
            a0 * w0, a0 * w1 + a1 * w0, a1 * w1, a0 * w2 + a2 * w0, a1 * w2 + a2 * w1, a2 * w2]


def momentum_regressor(d: Derivation) -> list[Vec]:
    """``M(q) qd = Y pi`` (with the rotors' ``Ia qd``), nv x (10 n_b + 4 n_driven)."""
    y = [[_ZERO] * (N_STANDARD * len(d.bodies)) for _ in range(d.nv)]
    for b, k in enumerate(d.bodies):
        v = twist(d, k)
        for j, jac in jacobian_columns(d, k).items():
            y[d.position(j)][N_STANDARD * b: N_STANDARD * (b + 1)] = d.tape.vec(momentum_entries(jac, v))
    driven = d.robot.driven
    return [row + [e for i in driven for e in ((d.qd[i] if d.position(i) == r else _ZERO), _ZERO, _ZERO, _ZERO)]
            for r, row in enumerate(y)]
