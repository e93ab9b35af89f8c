"""The Euler-Lagrange route: the equations of motion from the link energies.

The second derivation of M, C qd, Q_grav and tau, independent of the Newton-Euler recursions, after the seed
blog "Dynamic Modeling of Robotic Systems: Part 1" and the classic Lagrangian formulation of Uicker (1965)
and Paul ("Robot Manipulators", 1981, ch. 6):

* each body's world pose ``T_i(q)`` (the product of exponentials of :mod:`._kinematics`) and its chain-rule
  time derivative ``dT_i/dt = sum_j dT_i/dq_j qd_j`` (:func:`~._adjoint.jvp` along ``q -> qd``);
* the kinetic energy in the pseudo-inertia form (plus the rotors' ``1/2 Ia qd^2`` of the joints' drives) ``K = 1/2 sum_i tr(dT_i/dt J_i dT_i/dt^T)``, with
  ``J_i = [[tr(I_i)/2 1 - I_i, h_i], [h_i^T, m_i]]`` (``I_i`` about the body origin, ``h_i = m_i c_i``; the
  second moments of the body's mass, ``sum m r r^T``), and the potential energy ``U`` of :mod:`._energy`;
* the Euler-Lagrange equations ``d/dt dK/dqd - dK/dq + dU/dq = tau``:

  - ``H = d^2 K / dqd^2`` (the mass matrix),
  - ``d = (d^2 K / dqd dq) qd - dK/dq`` (the Coriolis and centrifugal forces, C qd),
  - ``g = dU/dq`` (the gravity forces),
  - ``tau = H qdd + d + g`` (plus the drives' friction and offset, forces that no energy gives).

The derivatives are taken by SymPy on the tape (:func:`~._adjoint.vjp` for the gradients of the scalar
energies, :func:`~._adjoint.jvp` for the time derivative of the momenta ``dK/dqd``), so the program stays a
DAG of small assignments, but it is several times the Newton-Euler one: the route is a cross-check and the
blog's workflow, not the fast path.
"""

from __future__ import annotations

import sympy as sp

from ..model import _spatial as sa
from ._adjoint import jvp, vjp
from ._derivation import Derivation, memoized
from ._drives import with_drives, with_rotor_energy
from ._energy import potential_energy
from ._kinematics import Vec, absolute, inertia


def _seeds(d: Derivation) -> tuple:
    """The tangents of a time derivative at zero acceleration: ``q_i -> qd_i``."""
    return tuple(zip(d.q, d.qd))


def pseudo_inertia(d: Derivation, i: int) -> list[Vec]:
    """Body i's 4x4 pseudo-inertia ``[[tr(I)/2 1 - I, h], [h^T, m]]`` about its frame origin, as rows."""
    m, h, inert = sa.inertia_parts(inertia(d, i))
    half_trace = (inert[0][0] + inert[1][1] + inert[2][2]) / 2
    rows = [[(half_trace if r == c else 0) - inert[r][c] for c in range(3)] + [h[r]] for r in range(3)]
    return [*rows, [*h, m]]


@memoized
def kinetic_energy(d: Derivation) -> sp.Expr:
    """``K = 1/2 sum_i tr(dT_i/dt J_i dT_i/dt^T)``, summed over the three non-zero rows of ``dT_i/dt``."""
    t = d.tape
    total = []
    for i in range(d.n):
        r, p = absolute(d, i)
        pose = [[*r[k], p[k]] for k in range(3)]
        rate = jvp(d, [e for row in pose for e in row], _seeds(d))
        j = pseudo_inertia(d, i)
        for k in range(3):
            row = rate[4 * k: 4 * k + 4]
            total.append(t(sa.dot(row, t.vec(sa.matvec(j, row)))))
    return with_rotor_energy(d, t(sp.Add(*total) / 2))


@memoized
def momenta(d: Derivation) -> Vec:
    """The generalized momenta ``dK/dqd`` (``= H qd``)."""
    return vjp(d, [kinetic_energy(d)], [1], d.qd)


@memoized
def mass_matrix(d: Derivation) -> sp.Matrix:
    """``H = d^2 K / dqd^2``, n x n: row j is the gradient of the momentum ``dK/dqd_j`` in qd."""
    rows = [vjp(d, [pj], [1], d.qd) for pj in momenta(d)]
    h = sp.zeros(d.n)
    for a in range(d.n):
        for b in range(a + 1):
            h[a, b] = h[b, a] = rows[a][b]
    return h


@memoized
def coriolis_torques(d: Derivation) -> Vec:
    """``d = (d^2 K / dqd dq) qd - dK/dq``: the momenta's rate at zero acceleration minus ``dK/dq``."""
    rate = jvp(d, momenta(d), _seeds(d))
    grad = vjp(d, [kinetic_energy(d)], [1], d.q)
    return d.tape.vec([a - b for a, b in zip(rate, grad)])


@memoized
def gravity_torques(d: Derivation) -> Vec:
    """``g = dU/dq``."""
    return vjp(d, [potential_energy(d)], [1], d.q)


def inverse_dynamics(d: Derivation) -> Vec:
    """``tau = H qdd + d + g``, plus the drives' friction and offset (non-conservative forces; the rotors'
    inertia is in K, hence in H)."""
    h = mass_matrix(d)
    c, g = coriolis_torques(d), gravity_torques(d)
    tau = d.tape.vec([sa.dot(h.row(a), d.qdd) + c[a] + g[a] for a in range(d.n)])
    return with_drives(d, tau, inertial=False)
