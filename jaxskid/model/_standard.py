"""The standard parameters: 10 per body, then 4 per driven joint, the parameters the regressor is linear in.

Per body, in body order (the order of ``q`` without mimic joints):
``pi_i = (m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)``, the inertia about the body frame's
origin in its axes (Atkeson, An & Hollerbach, IJRR 5(3), 1986; Pinocchio's ``Inertia.toDynamicParameters``
order, :data:`jaxskid.model._lie.STANDARD_PARAMETER_NAMES`).
They are named ``{link}_{p}``, the convention of the robot's own parameters (``upper_arm_link_m``).
A robot with drives (:mod:`jaxskid.model._drive`) has 4 more per driven joint, in body order:
``(Ia, fv, fc, fo)``, named ``{joint}_{p}`` (:func:`~jaxskid.model._drive.drive_parameter_names`).
A floating base is a body too: its 10 parameters, named after the root link (``Robot.base``), come first.
A robot's own parameters are read through :class:`~jaxskid.model._parameters.ParameterLayout`: a partial
dict takes the defaults for the rest, and an unknown name is an error that names the closest valid ones.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

from .._errors import ModelError, ShapeError
from . import _lie as lie
from ._drive import DRIVE_PARAMETER_NAMES, drive_parameter_names
from ._parameters import ParameterLayout
from ._robot import Robot, symbol

N_STANDARD = len(lie.STANDARD_PARAMETER_NAMES)  # 10 parameters per body


def n_standard(robot: Robot) -> int:
    """The number of standard parameters: ``10 n_bodies + 4 n_driven`` (10 more for a floating base)."""
    return N_STANDARD * (robot.n_bodies + robot.floating_base) + len(DRIVE_PARAMETER_NAMES) * len(robot.driven)


def standard_parameter_names(robot: Robot) -> tuple[str, ...]:
    """``{link}_{m, mcx, ..., Izz}`` for every body, then ``{joint}_{Ia, fv, fc, fo}`` for every driven
    joint, in the order of :func:`standard_params`."""
    links = ((robot.base,) if robot.floating_base else ()) + robot.link_names
    bodies = tuple(f"{link}_{p}" for link in links for p in lie.STANDARD_PARAMETER_NAMES)
    return bodies + tuple(n for i in robot.driven for n in drive_parameter_names(robot.joints[i].name))


def standard_parameter_expressions(robot: Robot) -> list[sp.Expr]:
    """The standard parameters (10 per body, 4 per driven joint) as expressions of the robot's own
    parameter symbols."""
    inertias = ([robot.base_inertia] if robot.floating_base else []) + [j.inertia for j in robot.joints]
    bodies = [e for m in inertias for e in lie.standard_parameters(m)]
    return bodies + [sp.sympify(e) for i in robot.driven for e in robot.joints[i].drive.values()]


def _layout(robot: Robot) -> ParameterLayout:
    return ParameterLayout(robot.parameters, robot.default_params())


def _values(robot: Robot, params, where: str) -> dict[str, float]:
    """``params`` (None, a dict or a vector in the order of ``robot.parameters``) as name -> float."""
    layout = _layout(robot)
    if params is None or isinstance(params, Mapping):
        values = layout.values(params, where)
    else:
        values = np.asarray(params, dtype=float)
        if values.shape != (len(layout),):
            raise ShapeError(f"{where}: expected a dict or a vector of shape ({len(layout)},), got {values.shape}")
    return {k: float(v) for k, v in zip(layout.names, values)}


def standard_params(robot: Robot, params: Mapping[str, float] | Sequence[float] | None = None) -> np.ndarray:
    """The standard parameters ``pi`` (10 per body, 4 per driven joint) of ``robot`` at these parameter values.

    ``pi`` is what the regressor multiplies: ``dyn.regressor(q, qd, qdd, params) @ pi`` equals
    ``dyn.inverse_dynamics(q, qd, qdd, params)``. Per body, in body order (the order of ``q`` without
    mimic joints): ``(m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)``, the inertia about the body frame's
    origin in its axes (Pinocchio's ``Inertia.toDynamicParameters``); then per driven joint, in body
    order: ``(Ia, fv, fc, fo)``.

    Args:
        robot: the model.
        params: ``None`` for the defaults, a dict name -> value (missing names take their defaults), or a
            vector in the order of ``robot.parameters``.

    Returns:
        a float64 array of shape ``(10 * robot.n_bodies + 4 * len(robot.driven),)``, with 10 more first for a
        floating base (its root link's).
    """
    sub = {symbol(k): sp.Float(v) for k, v in _values(robot, params, "standard_params: params").items()}
    return np.array([float(sp.sympify(e).xreplace(sub)) for e in standard_parameter_expressions(robot)])


def _kinematic_symbols(robot: Robot) -> set:
    """The symbols in poses, screws, gravity and frame offsets: everything but the inertias and drives."""
    out: set = set()
    for j in robot.joints:
        out |= j.origin.free_symbols | set().union(*(sp.sympify(x).free_symbols for x in j.screw))
    for g in robot.gravity:
        out |= sp.sympify(g).free_symbols
    for f in robot.frames:
        out |= f.offset.free_symbols
    return out


def _affine_system(robot: Robot, exprs: list, unknowns: list) -> tuple[np.ndarray, np.ndarray]:
    """``(A, b)`` with ``exprs = A x + b`` in the ``unknowns`` x; raises if an entry is not affine."""
    a = np.zeros((len(exprs), len(unknowns)))
    b = np.zeros(len(exprs))
    for r, e in enumerate(exprs):
        poly = sp.Poly(e, *unknowns) if unknowns else None
        if poly is not None and poly.total_degree() > 1:
            name = standard_parameter_names(robot)[r]
            raise ModelError(f"the standard parameter {name} = {e} is not affine in the robot's parameters; "
                             "cannot invert", where="params_from_standard")
        for c, s in enumerate(unknowns):
            a[r, c] = float(e.coeff(s)) if poly is not None else 0.0
        b[r] = float(e.subs({s: 0 for s in unknowns}))
    return a, b


def params_from_standard(
    robot: Robot, pi: Sequence[float], params: Mapping[str, float] | None = None
) -> dict[str, float]:
    """The robot's own inertial parameters that reproduce the standard parameters ``pi``.

    The inverse of :func:`standard_params` where it exists: the parameters that appear only in the
    inertias and drives (not in poses, screws or gravity) are solved for, by least squares, provided the
    inertias and drives are affine in them (as for URDF robots read with ``symbolic_inertia``, where the map is the identity
    up to names); the other parameters keep the values in ``params`` (missing ones take their defaults).

    Raises:
        ModelError: if the inertias are not affine in those parameters or ``pi`` cannot be reproduced.
    """
    pi = np.asarray(pi, dtype=float)
    if pi.shape != (n_standard(robot),):
        raise ShapeError(f"pi: expected shape ({n_standard(robot)},), got {pi.shape}")
    where = "params_from_standard: params"
    layout = _layout(robot)
    layout.check_names(params or {}, where)
    kinematic = _kinematic_symbols(robot)
    unknowns = [symbol(p) for p in robot.parameters if symbol(p) not in kinematic]
    fixed = ParameterLayout([p for p in robot.parameters if symbol(p) in kinematic], layout.defaults)
    given = {k: v for k, v in (params or {}).items() if k in fixed.names}
    sub = {symbol(k): sp.Float(float(v)) for k, v in zip(fixed.names, fixed.values(given, where))}
    exprs = [sp.expand(sp.sympify(e).xreplace(sub)) for e in standard_parameter_expressions(robot)]
    a, b = _affine_system(robot, exprs, unknowns)
    x, *_ = np.linalg.lstsq(a, pi - b, rcond=None) if unknowns else (np.zeros(0),)
    err = np.abs(a @ x + b - pi).max() if len(pi) else 0.0
    if err > 1e-9 * max(1.0, float(np.abs(pi).max())):
        raise ModelError(
            f"the robot's inertial parameters cannot reproduce pi (residual {err:.3g}); its inertias are "
            "constrained (e.g. point masses or shared symbols)",
            where="params_from_standard",
        )
    return {s.name: float(v) for s, v in zip(unknowns, x)}


def body_standard_map(robot: Robot):
    """``(f, bodies, involved)``: ``f(p) -> pi`` maps a vector ``p`` ``(..., n_params)`` of the robot's own
    parameters to the bodies' standard parameters ``(..., n_bodies, 10)`` (a floating base first), with NumPy;
    ``bodies`` names them; ``involved[k]`` is ``(mass, all)``: the parameters body ``k``'s mass depends on,
    and those its whole inertia depends on."""
    inertias = ([robot.base_inertia] if robot.floating_base else []) + [j.inertia for j in robot.joints]
    bodies = ((robot.base,) if robot.floating_base else ()) + robot.link_names
    symbols = [symbol(k) for k in robot.parameters]
    exprs = [[sp.sympify(e) for e in lie.standard_parameters(m)] for m in inertias]
    flat = sp.lambdify(symbols, [e for body in exprs for e in body], "numpy", cse=True)
    names = {symbol(k): k for k in robot.parameters}

    def used(es):
        return sorted({names[s] for e in es for s in e.free_symbols if s in names}, key=robot.parameters.index)

    involved = [(used(body[:1]), used(body)) for body in exprs]

    def standard(p):
        p = np.asarray(p, dtype=np.float64)
        values = flat(*(p[..., k] for k in range(p.shape[-1])))
        out = np.stack(np.broadcast_arrays(*values), axis=-1) if values else np.zeros((*p.shape[:-1], 0))
        return out.reshape((*p.shape[:-1], len(inertias), N_STANDARD))

    return standard, bodies, involved
