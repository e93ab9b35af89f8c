"""The inertial-parameter regressor ``tau = Y(q, qd, qdd) pi``, built from its linear structure.

The Newton-Euler equations are linear in each body's 10 standard inertial parameters (Atkeson, An &
Hollerbach, "Estimation of inertial parameters of manipulator loads and links", IJRR 5(3), 1986)

    pi_i = (m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz),

the inertia about body ``i``'s frame origin, in its axes (Pinocchio's ``Inertia.toDynamicParameters``
order, :data:`jaxskid._lie.STANDARD_PARAMETER_NAMES`). jaxskid never differentiates tau with respect to
the parameters; it writes the 6x10 block of each body's wrench in closed form instead:

* ``M y = K(y) pi_i`` for any 6-vector ``y = (w, v)``: ``M y = (I w - v x mc, m v + w x mc)``;
* the body's Newton-Euler wrench ``M_i Vd_i - ad(V_i)^T M_i V_i = A_i pi_i`` with
  ``A_i = K(Vd_i) + coad(V_i) K(V_i)`` (twist ``V_i`` and acceleration ``Vd_i`` with the fictitious
  base acceleration ``(0, -g)``, shared with the inverse dynamics on one tape);
* joint ``j`` feels body ``k``'s wrench through ``J_{k,j}^T``, the column ``Ad(C_k^-1 C_j) X_j`` of body
  k's body Jacobian, so ``Y[j, 10k:10k+10] = J_{k,j}^T A_k`` for the joints ``j`` that support ``k`` and
  zero otherwise. This equals propagating ``A_k`` to the root with the RNEA's ``T^T`` maps and projecting
  on each screw (``X_j^T T^T...T^T A_k = (T...T X_j)^T A_k``), at a sixth of the operations.

This module is symbolic (SymPy and NumPy only); it registers the quantity ``"regressor"``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

from ..model import _lie as lie
from ..equations._derive import QuantitySpec, register
from .._errors import ModelError, ShapeError
from ..model._robot import Robot, symbol
from ._kinematics import Kinematics, Vec, coad_apply, cross, dot

N_STANDARD = len(lie.STANDARD_PARAMETER_NAMES)  # 10 parameters per body


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
        cols.append([*(-x for x in cross(v, e)), *cross(w, e)])
    w0, w1, w2 = w
    for n in ([w0, z, z], [w1, w0, z], [z, w1, z], [w2, z, w0], [z, w2, w1], [z, z, w2]):  # Ixx ... Izz
        cols.append([*n, z, z, z])
    return cols


def body_wrench_columns(kin: Kinematics, i: int) -> list[Vec]:
    """Columns of ``A_i``: ``M_i Vd_i - ad(V_i)^T M_i V_i = A_i pi_i`` with gravity, on the shared tape."""
    key = ("A", i)
    memo = kin._memo
    if key not in memo:
        v = kin.twist(i)
        vd = kin.acceleration(i, velocity=True, accel=True, gravity=True)
        cols = []
        for a, h in zip(inertia_columns(vd), inertia_columns(v)):
            cols.append(kin.tape.vec([x + y for x, y in zip(a, coad_apply(v, h))]))
        memo[key] = cols
    return memo[key]


def regressor(kin: Kinematics) -> list[list]:
    """``Y(q, qd, qdd)``, n x 10 n_bodies, with ``tau = Y pi`` (see the module docstring)."""
    n = kin.n
    y = [[sp.Integer(0)] * (N_STANDARD * n) for _ in range(n)]
    for k in range(n):
        cols = body_wrench_columns(kin, k)
        for j, jac in kin.jacobian_columns(k).items():
            for c, col in enumerate(cols):
                y[j][N_STANDARD * k + c] = kin.tape(dot(jac, col))
    return y


register(QuantitySpec(
    "regressor", ("q", "qd", "qdd"), lambda r: (r.n_dof, N_STANDARD * r.n_dof),
    lambda k: [e for row in regressor(k) for e in row],
    "tau = Y(q, qd, qdd) pi",
    "Inertial-parameter regressor: tau is Y times the standard parameters pi (10 per body: m, m c, "
    "Ixx, Ixy, Iyy, Ixz, Iyz, Izz about the body frame origin), see jaxskid.standard_params.",
))


# ------------------------------------------------------------------------------ standard parameters
def standard_parameter_names(robot: Robot) -> tuple[str, ...]:
    """``{link}.{m, mcx, ..., Izz}`` for every body, in the order of :func:`standard_params`."""
    return tuple(f"{link}.{p}" for link in robot.link_names for p in lie.STANDARD_PARAMETER_NAMES)


def standard_parameter_expressions(robot: Robot) -> list[sp.Expr]:
    """The 10 n_bodies standard parameters as expressions of the robot's own parameter symbols."""
    return [e for j in robot.joints for e in lie.standard_parameters(j.inertia)]


def _values(robot: Robot, params) -> dict[str, float]:
    names = robot.parameters
    if params is None:
        values = robot.default_params()
    elif isinstance(params, Mapping):
        values = {**robot.default_params(), **{k: float(v) for k, v in params.items()}}
    else:
        vec = np.asarray(params, dtype=float)
        if vec.shape != (len(names),):
            raise ShapeError(f"params: expected a dict or a vector of shape ({len(names)},), got {vec.shape}")
        values = dict(zip(names, vec.tolist()))
    return values


def standard_params(robot: Robot, params: Mapping[str, float] | Sequence[float] | None = None) -> np.ndarray:
    """The standard inertial parameters ``pi`` (10 per body) of ``robot`` at these parameter values.

    ``pi`` is what :func:`regressor` multiplies: ``dyn.regressor(q, qd, qdd, params) @ pi`` equals
    ``dyn.inverse_dynamics(q, qd, qdd, params)``. Per body, in the order of ``q``:
    ``(m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)``, the inertia about the body frame's
    origin in its axes (Pinocchio's ``Inertia.toDynamicParameters``).

    Args:
        robot: the model.
        params: ``None`` for the defaults, a dict name -> value (missing names take their defaults), or a
            vector in the order of ``robot.parameters``.

    Returns:
        a float64 array of shape ``(10 * robot.n_dof,)``.
    """
    values = _values(robot, params)
    exprs = standard_parameter_expressions(robot)
    sub = {symbol(k): sp.Float(v) for k, v in values.items()}
    out = np.empty(len(exprs))
    for k, e in enumerate(exprs):
        e = sp.sympify(e).xreplace(sub)
        if e.free_symbols:
            missing = ", ".join(sorted(s.name for s in e.free_symbols))
            raise ModelError(f"no value for parameter(s) {missing}; pass them in params", where="standard_params")
        out[k] = float(e)
    return out


def params_from_standard(robot: Robot, pi: Sequence[float], params: Mapping[str, float] | None = None) -> dict[str, float]:
    """The robot's own inertial parameters that reproduce the standard parameters ``pi``.

    The inverse of :func:`standard_params` where it exists: the parameters that appear only in the
    inertias (not in poses, screws or gravity) are solved for, by least squares, provided the inertias
    are affine in them (as for URDF robots read with ``symbolic_inertia``, where the map is the identity
    up to names); the other parameters keep the values in ``params`` (or their defaults).

    Raises:
        ModelError: if the inertias are not affine in those parameters or ``pi`` cannot be reproduced.
    """
    pi = np.asarray(pi, dtype=float)
    if pi.shape != (N_STANDARD * robot.n_dof,):
        raise ShapeError(f"pi: expected shape ({N_STANDARD * robot.n_dof},), got {pi.shape}")
    exprs = standard_parameter_expressions(robot)
    kinematic: set = set()
    for j in robot.joints:
        kinematic |= j.origin.free_symbols | set().union(*(sp.sympify(x).free_symbols for x in j.screw))
    for g in robot.gravity:
        kinematic |= sp.sympify(g).free_symbols
    for f in robot.frames:
        kinematic |= f.offset.free_symbols
    unknowns = [symbol(p) for p in robot.parameters if symbol(p) not in kinematic]
    fixed = {k: v for k, v in _values(robot, params or {}).items() if symbol(k) not in unknowns}
    sub = {symbol(k): sp.Float(v) for k, v in fixed.items()}
    exprs = [sp.expand(sp.sympify(e).xreplace(sub)) for e in exprs]
    a = np.zeros((len(exprs), len(unknowns)))
    b = np.zeros(len(exprs))
    for r, e in enumerate(exprs):
        poly = sp.Poly(e, *unknowns) if unknowns else None
        if poly is not None and poly.total_degree() > 1:
            raise ModelError(
                f"the inertia of body {robot.link_names[r // N_STANDARD]!r} is not affine in its parameters "
                f"({lie.STANDARD_PARAMETER_NAMES[r % N_STANDARD]} = {e}); cannot invert",
                where="params_from_standard",
            )
        for c, s in enumerate(unknowns):
            a[r, c] = float(e.coeff(s)) if poly is not None else 0.0
        b[r] = float(e.subs({s: 0 for s in unknowns}))
    x, *_ = np.linalg.lstsq(a, pi - b, rcond=None) if unknowns else (np.zeros(0),)
    err = np.abs(a @ x + b - pi).max() if len(pi) else 0.0
    if err > 1e-9 * max(1.0, float(np.abs(pi).max())):
        raise ModelError(
            f"the robot's inertial parameters cannot reproduce pi (residual {err:.3g}); its inertias are "
            "constrained (e.g. point masses or shared symbols)",
            where="params_from_standard",
        )
    return {**{s.name: float(v) for s, v in zip(unknowns, x)}}
