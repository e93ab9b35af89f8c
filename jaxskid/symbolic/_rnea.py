"""The recursive Newton-Euler algorithm: tau, C qd, Q_grav and Q_ext on the tape.

Body-fixed (Featherstone, "Rigid Body Dynamics Algorithms", 2008, Alg. 5.1; Müller 2018, sec. 3): after
the forward pass of :mod:`._kinematics`, body i's own wrench is ``W_i = M_i Vd_i - ad(V_i)^T M_i V_i``; the
backward pass sums ``F_i = W_i + sum_children T_c^T F_c`` and projects ``tau_i = X_i^T F_i``. A floating
base (body ``-1``, ``X = I_6``) is one more body: its six rows are ``F_b = W_b + sum_roots T_r^T F_r``, the
base wrench (moment, force) in the base frame (Featherstone 2008, sec. 9.2). The joints' drives
(:mod:`._drives`) add to tau and to the bias, not to C qd or Q_grav.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from ..model import _spatial as sa
from ._derivation import Derivation, memoized
from ._drives import with_drives
from ._frames import body_loads
from ._kinematics import Terms, Vec, acceleration, inertia, is_zero, screw, to_parent, twist, zero6


@memoized
def body_wrench(d: Derivation, i: int, terms: Terms) -> Vec:
    """Newton-Euler wrench of body i alone: ``M_i Vd_i - ad(V_i)^T M_i V_i`` with the chosen terms."""
    m = inertia(d, i)
    parts = [sa.inertia_apply(m, acceleration(d, i, terms))]
    if terms.velocity:
        v = twist(d, i)
        h = d.tape.vec(sa.inertia_apply(m, v))
        parts.append(sa.coad_apply(v, h))
    return d.tape.vec(sa.add(*parts))


def backward(d: Derivation, wrenches: Mapping[int, Sequence]) -> Vec:
    """The backward pass: ``F_i = W_i + sum_c T_c^T F_c`` from the bodies' own wrenches ``W_i`` (in
    body frames, by body index, ``-1`` the floating base; a body left out has none), and ``tau_i = X_i^T F_i``.
    Returns tau, shape (nv,): the floating base's ``F_b`` first, if any."""
    f = {i: list(w) for i, w in wrenches.items()}
    tau: Vec = [None] * d.n
    for i in reversed(range(d.n)):
        w = d.tape.vec(f.get(i, zero6()))
        tau[i] = d.tape(sa.dot(screw(d, i), w))
        parent = d.robot.joints[i].parent
        if d.is_body(parent) and not is_zero(w):
            f[parent] = sa.add(f.get(parent, zero6()), to_parent(d, i, w))
    if d.floating:
        return [*d.tape.vec(f.get(-1, zero6())), *tau]
    return tau


def newton_euler(d: Derivation, terms: Terms, loads: Mapping[int, Vec] | None = None) -> Vec:
    """Generalized forces of the Newton-Euler recursion with the chosen terms.

    ``loads`` adds wrenches (in body frames, by body index) that act like inertial loads, e.g. ``-F_ext``.
    """
    wrenches = {}
    for i in d.bodies:
        parts = []
        if terms is not Terms.NONE:
            parts.append(body_wrench(d, i, terms))
        if loads and i in loads:
            parts.append(loads[i])
        wrenches[i] = sa.add(*parts) if parts else zero6()
    return backward(d, wrenches)


def inverse_dynamics(d: Derivation) -> Vec:
    """``tau = M(q) qdd + C(q, qd) qd + Q_grav(q) + tau_drive``, ``tau_drive = Ia qdd + fv qd + fc sign(qd) + fo``
    (0 without drives)."""
    return with_drives(d, newton_euler(d, Terms.INVERSE_DYNAMICS))


def coriolis_torques(d: Derivation) -> Vec:
    """``C(q, qd) qd``."""
    return newton_euler(d, Terms.CORIOLIS)


def gravity_torques(d: Derivation) -> Vec:
    """``Q_grav(q)``."""
    return newton_euler(d, Terms.GRAVITY)


def bias_forces(d: Derivation) -> Vec:
    """``C(q, qd) qd + Q_grav(q) + fv qd + fc sign(qd) + fo`` (the drives' friction and offset, if any)."""
    return with_drives(d, newton_euler(d, Terms.BIAS), inertial=False)


def external_torques(d: Derivation, wrenches: Mapping[str, Sequence]) -> Vec:
    """``Q_ext = sum_e J_e^T W_e`` with W in (moment, force) order in each end-effector's frame."""
    return newton_euler(d, Terms.NONE, body_loads(d, wrenches))
