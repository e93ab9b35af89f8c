"""The joints' drives on the tape: armature on the diagonal of M, friction and offset in the bias.

Joint ``j``'s drive (:mod:`jaxskid.model._drive`) adds ``Ia_j qdd_j + fv_j qd_j + fc_j sign(qd_j) + fo_j``
to its generalized force (``tanh(qd_j / eps)`` for ``sign`` with ``Options(friction_smoothing=eps)``) (Pinocchio's ``model.armature`` in ``crba``, ``rnea`` and ``aba`` for ``Ia``). This
module is the one place the drive terms are formed; the algorithms built on M and tau add them:
:func:`armature` to the diagonal of M (:mod:`._crba`), :func:`drive_torques` to tau and to the bias
(:mod:`._rnea`, hence forward dynamics, the vector-Jacobian product of inverse dynamics and rollouts) and
its time derivatives to those of tau (:mod:`._time_dynamics`), :func:`drive_columns` to the regressor, and
:func:`with_rotor_energy` and :func:`with_rotor_momentum` the rotors' ``1/2 Ia qd^2`` and ``Ia qd`` to the
kinetic energy and momentum (as Pinocchio's ``computeKineticEnergy`` does).
Robots without drives get nothing added: their programs are those of a model without this module. A
floating base has no drive: the vectors over the velocity coordinates get nothing in its six entries.
"""

from __future__ import annotations

import sympy as sp

from ._derivation import Derivation
from ._kinematics import Vec


class sign(sp.sign):  # noqa: N801 - printed by every code printer under SymPy's name ``sign``
    """``sign(x)`` whose derivative is 0, as JAX's ``jnp.sign`` (the Coulomb term is piecewise constant).

    SymPy differentiates its ``sign`` to ``2 DiracDelta(x)``, which no printer writes; the tape's adjoint
    (:mod:`._adjoint`) and tangents differentiate this one to 0.
    """

    def fdiff(self, argindex=1):
        return sp.Integer(0)

    def _eval_derivative(self, x):
        return sp.Integer(0)


def coulomb(d: Derivation, v: sp.Expr) -> sp.Expr:
    """The Coulomb friction's shape of velocity ``v``, named on the tape: ``sign(v)``, or ``tanh(v / eps)``
    with the derivation's ``friction_smoothing`` ``eps > 0`` (a smooth approximation whose slope at rest is
    ``1 / eps``)."""
    eps = d.friction_smoothing
    return d.tape(sp.tanh(v / sp.Float(eps)) if eps > 0 else sign(v))


def armature(d: Derivation) -> Vec:
    """``Ia``, one entry per joint (0 without a drive): ``M + diag(Ia)`` is the mass matrix with drives."""
    return [sp.Integer(0) if j.drive is None else j.drive.armature for j in d.robot.joints]


def _smooth_rate(d: Derivation, i: int, k: int) -> sp.Expr:
    """``d^k/dt^k tanh(qd_i / eps)`` in the state's time derivatives (Taylor in t of ``qd_i(t)``)."""
    t = sp.Dummy("t")
    state = d.inputs.state
    v = sum((state[1 + r][i] * t**r / sp.factorial(r) for r in range(k + 1)), sp.Integer(0))
    return sp.diff(sp.tanh(v / sp.Float(d.friction_smoothing)), t, k).subs(t, 0)


def drive_torques(d: Derivation, k: int = 0, *, inertial: bool = True) -> Vec:
    """The k-th time derivative of ``Ia qdd + fv qd + fc sign(qd) + fo``, one entry per joint.

    ``k = 0``: the drive torques (without ``Ia qdd`` if not ``inertial``: the drives' share of the bias);
    ``k >= 1``: ``Ia q^(k+2) + fv q^(k+1)`` (armature and friction coefficients are constant, and
    ``sign(qd)`` is piecewise constant), plus ``fc d^k/dt^k tanh(qd / eps)`` with friction smoothing.
    """
    state = d.inputs.state
    out = []
    for i, j in enumerate(d.robot.joints):
        if j.drive is None:
            out.append(sp.Integer(0))
            continue
        ia, fv, fc, fo = j.drive.values()
        terms = [fv * state[k + 1][i]]
        if inertial:
            terms.append(ia * state[k + 2][i])
        if k == 0:
            terms += [fc * coulomb(d, state[1][i]), fo]
        elif d.friction_smoothing > 0:
            terms.append(fc * _smooth_rate(d, i, k))
        out.append(d.tape(sp.Add(*terms)))
    return out


def with_drives(d: Derivation, tau: Vec, k: int = 0, *, inertial: bool = True) -> Vec:
    """``tau`` plus :func:`drive_torques` (``tau`` itself for a robot without drives)."""
    if not d.robot.driven:
        return tau
    drive = [0] * d.offset + drive_torques(d, k, inertial=inertial)
    return [d.tape(t + e) if e != 0 else t for t, e in zip(tau, drive, strict=True)]


def with_rotor_momentum(d: Derivation, p: Vec) -> Vec:
    """``p + Ia qd``: the generalized momentum ``(M + diag(Ia)) qd`` (``p`` itself without drives)."""
    rotors = [0] * d.offset + [ia * v for ia, v in zip(armature(d), d.qd)]
    return [d.tape(x + r) if r != 0 else x for x, r in zip(p, rotors, strict=True)]


def with_rotor_energy(d: Derivation, kinetic: sp.Expr) -> sp.Expr:
    """``K + 1/2 sum_j Ia_j qd_j^2``: the kinetic energy ``1/2 qd^T (M + diag(Ia)) qd``."""
    rotors = [ia * v**2 for ia, v in zip(armature(d), d.qd) if ia != 0]
    return d.tape(kinetic + sp.Add(*rotors) / 2) if rotors else kinetic


def drive_columns(d: Derivation) -> list[Vec]:
    """The regressor's columns of the drive parameters: 4 per driven joint j, in joint order,
    ``(Ia, fv, fc, fo) -> (qdd_j, qd_j, sign(qd_j), 1)`` in row j and 0 elsewhere. Shape: 4 n_driven x nv."""
    cols = []
    for i in d.robot.driven:
        for value in (d.qdd[i], d.qd[i], coulomb(d, d.qd[i]), sp.Integer(1)):
            cols.append([value if r == d.position(i) else sp.Integer(0) for r in range(d.nv)])
    return cols
