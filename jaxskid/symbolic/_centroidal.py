"""The centre of mass, its Jacobian and the centroidal momentum matrix, on the tape.

With body i's pose ``(R_i, p_i)`` in the world, mass ``m_i`` and first moment ``h_i = m_i c_i`` in its frame
(:func:`jaxskid.model._spatial.inertia_parts`), and its momentum ``M_i V_i = (k_i, l_i)`` in its frame (the
angular momentum about the frame's origin and the linear momentum; :func:`._energy.body_momentum`):

* centre of mass ``c = sum_i (m_i p_i + R_i h_i) / m``, ``m = sum_i m_i``;
* its Jacobian, ``dc/dt = J_c qd`` with ``J_c = sum_i R_i (M_i J_i)_force / m`` (``dp_i/dt = R_i v_i`` and
  ``dR_i/dt h_i = R_i (omega_i x h_i)``, so ``m dc/dt = sum_i R_i l_i``), 3 x nv;
* the centroidal momentum matrix ``A_G`` (Orin, Goswami & Lee, "Centroidal dynamics of a humanoid robot",
  Auton Robots 35, 2013, eq. 15): ``h_G = A_G qd`` is the system's angular momentum about the centre of mass and
  its linear momentum, in world axes, ``h_G = sum_i (R_i k_i + (p_i - c) x R_i l_i, R_i l_i)``; 6 x nv, angular
  rows first as every (moment, force) pair in jaxskid.

Column by column, ``M_i V_i`` becomes ``M_i J_{i,j}`` for the columns of body i's Jacobian. The sums run over
every moving body, a floating base included (:attr:`._derivation.Derivation.bodies`); a fixed base's world
does not move and carries no mass of its own here.
"""

from __future__ import annotations

import sympy as sp

from ..model import _spatial as sa
from ._derivation import Derivation, memoized
from ._jacobians import jacobian_columns
from ._kinematics import Vec, absolute, inertia


@memoized
def total_mass(d: Derivation) -> sp.Expr:
    """``m = sum_i m_i`` over the moving bodies."""
    return d.tape(sp.Add(*(sa.inertia_parts(inertia(d, i))[0] for i in d.bodies)))


@memoized
def center_of_mass(d: Derivation) -> Vec:
    """``c = sum_i (m_i p_i + R_i h_i) / m`` in the world frame, (3,)."""
    t = d.tape
    moments = []
    for i in d.bodies:
        m, h, _ = sa.inertia_parts(inertia(d, i))
        r, p = absolute(d, i)
        moments.append(t.vec(sa.add(sa.scale(p, m), sa.matvec(r, h))))
    inv = t(1 / total_mass(d))
    return t.vec(sa.scale(sa.add(*moments), inv))


def _column_momenta(d: Derivation) -> dict:
    """Column key -> list of ``(i, R_i (M_i J_{i,j}))`` world-aligned momenta ``(k, l)`` of the bodies moved by
    that column."""
    out: dict = {}
    for i in d.bodies:
        parts = sa.inertia_parts(inertia(d, i))
        r, _ = absolute(d, i)
        for key, col in jacobian_columns(d, i).items():
            mom = d.tape.vec(sa.apply_inertia_parts(parts, col))
            world = d.tape.vec([*sa.matvec(r, mom[:3]), *sa.matvec(r, mom[3:])])
            out.setdefault(key, []).append((i, world))
    return out


def center_of_mass_jacobian(d: Derivation) -> list[Vec]:
    """``J_c``, 3 x nv, as rows: ``dc/dt = J_c qd``."""
    inv = d.tape(1 / total_mass(d))
    cols = [[sp.Integer(0)] * 3 for _ in range(d.nv)]
    for key, terms in _column_momenta(d).items():
        cols[d.position(key)] = d.tape.vec(sa.scale(sa.add(*(w[3:] for _, w in terms)), inv))
    return [[cols[c][r] for c in range(d.nv)] for r in range(3)]


def centroidal_momentum_matrix(d: Derivation) -> list[Vec]:
    """``A_G``, 6 x nv, as rows: ``h_G = A_G qd``, (angular momentum about the centre of mass, linear momentum)
    in world axes."""
    t = d.tape
    c = center_of_mass(d)
    arms = {i: t.vec([a - b for a, b in zip(absolute(d, i)[1], c)]) for i in d.bodies}
    cols = [[sp.Integer(0)] * 6 for _ in range(d.nv)]
    for key, terms in _column_momenta(d).items():
        angular = sa.add(*(sa.add(w[:3], sa.cross(arms[i], w[3:])) for i, w in terms))
        linear = sa.add(*(w[3:] for _, w in terms))
        cols[d.position(key)] = t.vec([*angular, *linear])
    return [[cols[col][r] for col in range(d.nv)] for r in range(6)]
