"""The inertial-parameter regressor ``tau = Y(q, qd, qdd) pi``, built from its linear structure.

The Newton-Euler equations are linear in each body's 10 standard inertial parameters (Atkeson, An &
Hollerbach, "Estimation of inertial parameters of manipulator loads and links", IJRR 5(3), 1986)

    pi_i = (m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz),

the inertia about body ``i``'s frame origin, in its axes (Pinocchio's ``Inertia.toDynamicParameters``
order, :mod:`jaxskid.model._standard`). jaxskid never differentiates tau with
respect to the parameters; it writes the 6x10 block of each body's wrench in closed form instead:

* ``M y = K(y) pi_i`` for any 6-vector ``y = (w, v)``: ``M y = (I w - v x mc, m v + w x mc)``;
* the body's Newton-Euler wrench ``M_i Vd_i - ad(V_i)^T M_i V_i = A_i pi_i`` with
  ``A_i = K(Vd_i) + coad(V_i) K(V_i)`` (twist ``V_i`` and acceleration ``Vd_i`` with the fictitious
  base acceleration ``(0, -g)``, shared with the inverse dynamics on one tape);
* joint ``j`` feels body ``k``'s wrench through ``J_{k,j}^T``, the column ``Ad(C_k^-1 C_j) X_j`` of body
  k's body Jacobian, so ``Y[j, 10k:10k+10] = J_{k,j}^T A_k`` for the joints ``j`` that support ``k`` and
  zero otherwise. This equals propagating ``A_k`` to the root with the RNEA's ``T^T`` maps and projecting
  on each screw (``X_j^T T^T...T^T A_k = (T...T X_j)^T A_k``), at a sixth of the operations.

A floating base is body ``-1``, whose 10 columns come first; its six rows are the base wrench, in which
every body's ``A_k`` enters through the base columns ``J_{k,b}`` of its body Jacobian (Ayusawa, Venture &
Nakamura, "Identifiability and identification of inertial parameters using the underactuated base-link
dynamics for legged multibody systems", IJRR 33(3), 2014: the base rows alone are the dynamics without
joint torques).

The drives' parameters follow, 4 per driven joint in joint order (:func:`._drives.drive_columns`): the drive
torque ``Ia qdd + fv qd + fc sign(qd) + fo`` of joint j is linear in ``(Ia, fv, fc, fo)`` with the row-j
entries ``(qdd_j, qd_j, sign(qd_j), 1)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ..model import _spatial as sa
from ..model._standard import N_STANDARD
from ._derivation import Derivation, memoized
from ._drives import drive_columns
from ._jacobians import jacobian_columns
from ._kinematics import Terms, Vec, acceleration, twist


ROTATIONAL = range(4, N_STANDARD)
"""The columns of the rotational inertia (``Ixx ... Izz``) in a body's 10. Their entries need only the bodies'
rotations, angular velocities and accelerations: :func:`regressor` puts all of them on the tape before the
entries of ``m`` and ``m c``. Generated code computes the entries in the tape's order, and the gathered form of
the JAX form (:mod:`jaxskid.runtime._gathered`) groups them into kernels in that order, each kernel computing
the statements its entries need: so grouped, the G1 with hands' kernels (43 DOF) compute 42,500 statements
between them instead of 52,200 body by body (XLA's optimized program: 72,000 lines instead of 78,000; its
compile on one core: 18.2 instead of 18.6 s)."""


def inertia_columns(y: Sequence) -> list[Vec]:
    """The 10 columns of ``K(y)``, with ``M y = K(y) pi`` for a 6x6 mass-inertia ``M`` (omega, v order).

    ``M y = (I w - v x mc, m v + w x mc)`` for ``y = (w, v)``; ``I w`` is linear in
    ``(Ixx, Ixy, Iyy, Ixz, Iyz, Izz)``.
    """
    w, v = list(y[:3]), list(y[3:])
    z = sp.Integer(0)
    cols: list[Vec] = [[z, z, z, *v]]  # m
    for k in range(3):  # m c_k
        e = [sp.Integer(int(r == k)) for r in range(3)]
        cols.append([*(-x for x in sa.cross(v, e)), *sa.cross(w, e)])
    w0, w1, w2 = w
    for n in ([w0, z, z], [w1, w0, z], [z, w1, z], [w2, z, w0], [z, w2, w1], [z, z, w2]):  # Ixx ... Izz
        cols.append([*n, z, z, z])
    return cols


@memoized
def body_wrench_columns(d: Derivation, i: int, group: range) -> dict[int, Vec]:
    """The columns ``c`` in ``group`` of ``A_i``: ``M_i Vd_i - ad(V_i)^T M_i V_i = A_i pi_i`` with gravity, on
    the shared tape (a group at a time, in the order of :data:`ROTATIONAL`)."""
    v = twist(d, i)
    vd = acceleration(d, i, Terms.INVERSE_DYNAMICS)
    pairs = list(zip(inertia_columns(vd), inertia_columns(v)))
    return {c: d.tape.vec([x + y for x, y in zip(pairs[c][0], sa.coad_apply(v, pairs[c][1]))]) for c in group}


def regressor(d: Derivation) -> list[Vec]:
    """``Y(q, qd, qdd)``, nv x (10 n_b + 4 n_driven), with ``tau = Y pi`` (``n_b`` bodies, the floating base
    first; see the module docstring)."""
    bodies = d.bodies
    y = [[sp.Integer(0)] * (N_STANDARD * len(bodies)) for _ in range(d.nv)]
    for group in (ROTATIONAL, range(ROTATIONAL.start)):  # the order on the tape: see ROTATIONAL
        for b, k in enumerate(bodies):
            cols = body_wrench_columns(d, k, group)
            for j, jac in jacobian_columns(d, k).items():
                for c in group:
                    y[d.position(j)][N_STANDARD * b + c] = d.tape(sa.dot(jac, cols[c]))
    drives = drive_columns(d)
    return [row + [col[j] for col in drives] for j, row in enumerate(y)]
