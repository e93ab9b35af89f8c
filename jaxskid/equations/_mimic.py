"""The quantities of a robot with mimic joints, in its independent coordinates.

The symbolic algorithms work body by body, and a mimic joint's state is defined from the coordinates on the
tape (:mod:`jaxskid.symbolic._derivation`), so every quantity is first built in the joint space of the
bodies, then projected with the constant ``G`` of ``q_bodies = G q + b`` (:mod:`jaxskid.model._mimic`):

* an axis of generalized forces (the rows of ``M``, ``C``, the regressor; ``tau``, ``Q_grav``, ``C qd``,
  ``Q_ext``, the momentum and their time derivatives) by ``G^T``: the virtual work ``qd_bodies^T f =
  qd^T G^T f``;
* an axis of joint velocities (the columns of ``M``, ``C`` and of every Jacobian) by ``G``: ``V = J_bodies
  qd_bodies = J_bodies G qd``;
* quantities per body, per frame or per end-effector (poses, twists, accelerations, energies and their
  rows in the standard parameters) need nothing: they are functions of the bodies' states, already closed
  form in ``q``.

``G`` is constant, so the time derivatives project the same way. Two quantities are rebuilt instead:
forward dynamics solves ``(G^T M G) qdd = tau - G^T bias`` by the symbolic ``L^T D L`` with the projected
matrix's own sparsity, and the vector-Jacobian product of inverse dynamics differentiates ``G^T tau`` on
the tape, whose mimic states carry the chain rule to ``q`` and ``qd``. A quantity not listed here
(:data:`AXES`) is refused for a robot with mimic joints (:class:`~jaxskid.RequestError`). A floating base's
six velocity coordinates are coordinates of both spaces: ``G`` passes them through.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import sympy as sp

from .. import symbolic as sym
from .._errors import RequestError
from ..symbolic import Derivation
from ..symbolic._forward import solve
from ..symbolic._rnea import bias_forces

_ROWS, _COLUMNS, _BOTH, _NONE = "rows", "columns", "both", "none"


def _groups(d: Derivation) -> list[list[tuple[int, sp.Expr]]]:
    """Per coordinate k, the velocity-space entries it moves and their multipliers: the non-zeros of column
    k of G (a floating base's six first, each its own)."""
    groups: list[list] = [[(c, sp.Integer(1))] for c in range(d.offset)] + [[] for _ in range(d.robot.n_dof)]
    for i, (k, a, _) in enumerate(d.robot.coupling()):
        groups[d.offset + k].append((d.position(i), a))
    return groups


def _combine(d: Derivation, terms) -> sp.Expr:
    """``sum a x`` over ``(a, x)`` pairs, named on the tape."""
    return d.tape(sp.Add(*(a * x for a, x in terms if x != 0 and a != 0)))


def project(d: Derivation, outs: Sequence, kind: str) -> list:
    """Flat, row-major ``outs`` of a quantity in the bodies' joint space, projected onto the coordinates:
    the leading axis by ``G^T`` (``"rows"``), the last by ``G`` (``"columns"``), both (``"both"``, square)."""
    groups, n = _groups(d), d.nv
    outs = list(outs)
    if kind in (_ROWS, _BOTH):
        r = len(outs) // n
        outs = [_combine(d, [(a, outs[i * r + c]) for i, a in g]) for g in groups for c in range(r)]
    if kind in (_COLUMNS, _BOTH):
        rows = len(outs) // n
        outs = [_combine(d, [(a, outs[row * n + i]) for i, a in g]) for row in range(rows) for g in groups]
    return outs


def _matrix(d: Derivation, m: sp.Matrix) -> sp.Matrix:
    n = d.robot.nv
    return sp.Matrix(n, n, project(d, list(m), _BOTH))


def forward_dynamics(d: Derivation) -> list:
    """``qdd = (G^T M G)^-1 (tau - G^T bias)``, factored symbolically (dense order, structural zeros skipped)."""
    m = _matrix(d, sym.mass_matrix(d))
    bias = project(d, bias_forces(d), _ROWS)
    return solve(d.tape, m, d.inputs.tau, bias, list(range(-1, d.robot.nv - 1)))


def inverse_dynamics_vjp(d: Derivation) -> list:
    """``(w^T dtau/dq, w^T dtau/dqd, w^T dtau/dp)`` of ``tau = G^T tau_bodies`` in the coordinates."""
    tau = project(d, sym.inverse_dynamics(d), _ROWS)
    wrt = (*d.inputs.coordinate(0), *d.inputs.coordinate(1), *d.inputs.params)
    return sym.vjp(d, tau, d.inputs.cotangent, wrt)


def _time(kind: str, *names: str) -> dict[str, str]:
    return {f"{n}{s}": kind for n in names for s in ("", "_dot", "_ddot")}


AXES: dict[str, str | Callable[[Derivation], list]] = {
    **_time(_BOTH, "mass_matrix", "coriolis_matrix"),
    **_time(_ROWS, "gravity_torques", "inverse_dynamics", "external_torques"),
    "coriolis_torques": _ROWS,
    "momentum": _ROWS,
    "regressor": _ROWS,
    "momentum_regressor": _ROWS,
    **{n: _COLUMNS for n in ("body_jacobian", "hybrid_jacobian", "system_jacobian", "system_jacobian_dot",
                             "body_jacobian_dot", "hybrid_jacobian_dot", "ee_parent_hybrid_jacobian",
                             "ee_parent_hybrid_jacobian_dot")},
    **{n: _NONE for n in ("forward_kinematics", "body_twist", "hybrid_twist", "body_acceleration",
                          "hybrid_acceleration", "ee_body_twist", "ee_hybrid_twist", "ee_body_acceleration",
                          "ee_hybrid_acceleration", "kinetic_energy", "potential_energy",
                          "kinetic_energy_regressor", "potential_energy_regressor", "friction_power_regressor")},
    "forward_dynamics": forward_dynamics,
    "inverse_dynamics_vjp": inverse_dynamics_vjp,
    "constraint_jacobian": _COLUMNS,
    "constraint_drift": _NONE,
    "constraint_residual": _NONE,
    "center_of_mass": _NONE,
    "ee_pose": _NONE,
    "center_of_mass_jacobian": _COLUMNS,
    "centroidal_momentum_matrix": _COLUMNS,
}
"""How each quantity reaches the coordinates (module docstring): a projection, or its own builder."""


def check(robot, names: Sequence[str], route: str) -> None:
    """Refuse, for a robot with mimic joints, a quantity without a projection and the Euler-Lagrange route."""
    if not robot.mimic_joints:
        return
    which = f"robot {robot.name!r} has mimic joints ({', '.join(robot.mimic_joints)})"
    missing = [n for n in names if n not in AXES and _base(n) not in AXES]
    if missing:
        raise RequestError(f"{', '.join(missing)} not available: {which}")
    if route == "lagrange":
        raise RequestError(f"Options(route='lagrange') not available: {which}; use the default route 'screw'")


def supported(robot, names: Sequence[str]) -> list[str]:
    """``names`` without the quantities a robot with mimic joints does not have (for ``None`` and ``"all"``)."""
    return [n for n in names if n in AXES or _base(n) in AXES] if robot.mimic_joints else list(names)


def _base(name: str) -> str | None:
    """The quantity a pullback (``<name>_vjp``, built from its quantity's projected outputs) differentiates."""
    return name[: -len("_vjp")] if name.endswith("_vjp") else None


def build(name: str, builder: Callable[[Derivation], list], d: Derivation) -> list:
    """The outputs of quantity ``name`` in the coordinates of ``d``'s robot (which has mimic joints)."""
    how = AXES[name]
    if callable(how):
        return how(d)
    outs = builder(d)
    return list(outs) if how == _NONE else project(d, outs, how)
