"""Kinetic and potential energy of the robot, on the tape.

* ``K(q, qd) = 1/2 sum_i V_i^T M_i V_i``, with ``V_i`` the body twist and ``M_i`` the 6x6 mass-inertia of
  body i in its frame (Featherstone 2008, eq. 2.61); ``K = 1/2 qd^T M(q) qd``.
* ``U(q) = -sum_i g^T (R_i h_i + m_i p_i)``, with ``h_i = m_i c_i``: zero when every centre of mass is at the
  world origin, so ``dU/dq = Q_grav``.
* the generalized momentum ``p(q, qd) = dK/dqd = M(q) qd = sum_i J_i^T M_i V_i``: the body momenta ``M_i V_i``
  carried to the joints by a Newton-Euler backward pass.

The sums run over every moving body, a floating base (body ``-1``) included. The Euler-Lagrange route
(:mod:`._lagrange`) forms K its own way, from the pose's time derivative.
"""

from __future__ import annotations

import sympy as sp

from ..model import _spatial as sa
from ._derivation import Derivation, memoized
from ._kinematics import Vec, absolute, gravity, inertia, twist
from ._rnea import backward


@memoized
def body_momentum(d: Derivation, i: int) -> Vec:
    """``M_i V_i``, body i's momentum in its own frame."""
    return d.tape.vec(sa.apply_inertia_parts(sa.inertia_parts(inertia(d, i)), twist(d, i)))


@memoized
def kinetic_energy(d: Derivation) -> sp.Expr:
    """``K = 1/2 sum_i V_i^T M_i V_i``."""
    t = d.tape
    total = []
    for i in d.bodies:
        total.append(t(sa.dot(twist(d, i), body_momentum(d, i))))
    return t(sp.Add(*total) / 2)


@memoized
def potential_energy(d: Derivation) -> sp.Expr:
    """``U = -sum_i g^T (R_i h_i + m_i p_i)``."""
    t, g = d.tape, gravity(d)
    total = []
    for i in d.bodies:
        m, h, _ = sa.inertia_parts(inertia(d, i))
        r, p = absolute(d, i)
        total.append(t(-sa.dot(g, t.vec(sa.add(sa.matvec(r, h), sa.scale(p, m))))))
    return t(sp.Add(*total))


def momentum(d: Derivation) -> Vec:
    """``p = M(q) qd``, the backward pass of the body momenta ``M_i V_i``."""
    return backward(d, {i: body_momentum(d, i) for i in d.bodies})
