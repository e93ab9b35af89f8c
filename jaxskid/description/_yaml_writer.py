"""Writing a :class:`Robot` as a description in Skidy's YAML/JSON schema, and rounding it first.

The writer emits the body-fixed representation with 6x6 inertias, integers and floats as YAML numbers
(floats with ``repr`` precision) and other entries as SymPy strings, so that
``parse_description(robot_to_dict(robot)) == robot`` (:mod:`jaxskid.description._yaml_schema`).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import sympy as sp
import yaml
from sympy.printing.str import StrPrinter

from .._errors import ModelError
from ..model import _lie as lie
from ..model._constraint import LoopClosure, PointContact
from ..model._robot import Robot
from ._yaml_file import SUFFIXES


class _ExprPrinter(StrPrinter):
    """SymPy's str, with doubles printed to full precision and e written so that it parses back."""

    def _print_Float(self, expr):
        return repr(float(expr)) if expr._prec == 53 else super()._print_Float(expr)

    def _print_Exp1(self, expr):
        return "exp(1)"


def _value(e):
    e = sp.sympify(e)
    if e.is_Integer:
        return int(e)
    if e.is_Float:
        return float(e)
    return _ExprPrinter().doprint(e)


def _rows(m) -> list:
    m = sp.Matrix(m)
    return [[_value(m[r, c]) for c in range(m.cols)] for r in range(m.rows)]


ROTATIONS = ("matrix", "rpy")


def _pose(c, rotations: str):
    """A 4x4 matrix, or with ``rotations="rpy"`` ``{translation, rotation: {rpy}}`` when the rotation is
    exactly ``lie.rot_rpy`` of angles 0 or k pi/q (so that it reads back to the same matrix)."""
    c = sp.Matrix(c)
    if rotations == "rpy":
        r = lie.rotation_of(c)
        angles = _rpy_angles(r, 1e-12) if not any(sp.sympify(e).atoms(sp.Float) for e in r) else None
        if angles is not None and lie.rot_rpy(*angles) == r:
            entry: dict = {"translation": [_value(e) for e in lie.translation_of(c)]}
            if any(angles):
                entry["rotation"] = {"rpy": [_value(a) for a in angles]}
            return entry
    return _rows(c)


def robot_to_dict(robot: Robot, *, rotations: str = "matrix") -> dict:
    """The description of ``robot`` in Skidy's schema (body-fixed, 6x6 inertias) plus jaxskid's keys.

    ``rotations``: ``"matrix"`` writes every pose as a 4x4 matrix; ``"rpy"`` writes a pose whose rotation
    is exact with angles 0 or k pi/q as ``{translation: [x, y, z], rotation: {rpy: [roll, pitch, yaw]}}``.
    """
    if rotations not in ROTATIONS:
        raise ModelError(f"expected rotations to be one of {', '.join(ROTATIONS)}, got {rotations!r}")
    out: dict = {"name": robot.name}
    if robot.base != "world":
        out["base"] = robot.base
    out["representation"] = "body_fixed"
    out["gravity"] = [_value(g) for g in robot.gravity]
    out["joint_names"] = [j.name for j in robot.joints]
    out["link_names"] = list(robot.link_names)
    out["parent"] = [p + 1 for p in robot.parents]
    out["joint_screw_coord"] = [[_value(e) for e in j.screw] for j in robot.joints]
    out["body_ref_config"] = [_pose(j.origin, rotations) for j in robot.joints]
    if len(robot.without_inertia) < robot.n_bodies:  # a body without one is null; none at all: no key
        out["mass_inertia"] = [None if j.link in robot.without_inertia else _rows(j.inertia) for j in robot.joints]
    if robot.floating_base:
        out["floating_base"] = True
        out["base_inertia"] = _rows(robot.base_inertia)
    if robot.driven:
        out["drives"] = [None if j.drive is None else dict(zip(("armature", "viscous", "coulomb", "offset"),
                                                               map(_value, j.drive.values())))
                         for j in robot.joints]
    if robot.mimic_joints:
        out["mimic"] = [None if j.mimic is None else {"joint": j.mimic.joint, "multiplier": _value(j.mimic.multiplier),
                                                      "offset": _value(j.mimic.offset)} for j in robot.joints]
    if robot.end_effectors:
        ee = [robot.frame(name) for name in robot.end_effectors]
        out["ee"] = [_pose(f.offset, rotations) for f in ee]
        out["ee_parent"] = [f.body + 1 for f in ee]
        out["ee_names"] = list(robot.end_effectors)
    others = [f for f in robot.frames if f.name not in robot.end_effectors]
    if others:
        out["frames"] = [{"name": f.name, "parent": f.body + 1, "pose": _pose(f.offset, rotations)} for f in others]
    frame_names = {f.name for f in robot.frames}
    default_order = [nm for nm in robot.end_effectors if nm in frame_names] + [f.name for f in others]
    if default_order != [f.name for f in robot.frames]:
        out["frame_order"] = [f.name for f in robot.frames]
    if robot.constraints:
        out["constraints"] = [_constraint(c, rotations) for c in robot.constraints]
    if robot.defaults:
        out["assignments"] = {k: v for k, v in robot.defaults}
    return out


def _constraint(c, rotations: str) -> dict:
    """A ``constraints`` entry (:mod:`jaxskid.description._yaml_constraints`), its anchor written out."""
    if isinstance(c, LoopClosure):
        return {"loop_closure": list(c.frames), "kind": c.kind if isinstance(c.kind, str) else list(c.kind)}
    if isinstance(c, PointContact):
        out = {"point_contact": c.frame, "position": [_value(e) for e in c.position]}
    else:
        out = {"frame_contact": c.frame, "pose": _pose(c.pose, rotations)}
    if c.axes != c.own_axes:
        out["axes"] = list(c.axes)
    return out


class _Dumper(yaml.SafeDumper):
    def increase_indent(self, flow=False, indentless=False):
        return super().increase_indent(flow, False)  # indent lists under their key


def _represent_list(dumper, data):
    flow = all(not isinstance(x, (list, dict)) for x in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


_Dumper.add_representer(list, _represent_list)


def write_description(robot: Robot, path, *, force: bool = False, rotations: str = "matrix") -> None:
    """Write ``robot`` as YAML (``.yaml``/``.yml``) or JSON (``.json``); an existing file needs ``force=True``.
    ``rotations`` as in :func:`robot_to_dict`."""
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise ModelError(f"expected a file name ending in .yaml, .yml or .json, got {path.suffix or 'none'!r}",
                         source=str(path))
    data = robot_to_dict(robot, rotations=rotations)
    if path.suffix.lower() == ".json":
        text = json.dumps(data, indent=2) + "\n"
    else:
        header = f"# {robot.name}: robot description written by jaxskid (Skidy's schema, body-fixed representation)\n"
        text = header + yaml.dump(data, Dumper=_Dumper, sort_keys=False, width=100)
    try:
        with path.open("w" if force else "x", encoding="utf-8") as f:
            f.write(text)
    except FileExistsError:
        raise FileExistsError(f"{path} already exists; pass force=True to overwrite it") from None


# ---------------------------------------------------------------------------------------------- rounding
MAX_DENOMINATOR = 12
_ALGEBRAIC = tuple(dict.fromkeys(sp.cos(k * sp.pi / 12) for k in (1, 2, 3, 5)))  # cos, sin of multiples of 15 deg


def snap(x: float, tol: float) -> sp.Expr | None:
    """The simple exact number within ``tol`` of ``x``, or None: an integer, a fraction p/q, a multiple
    k pi/q (q <= 12; simplest first), or +-cos(k pi/12) (``sqrt(2)/2``, ``sqrt(3)/2``, ...)."""
    if not math.isfinite(x):
        return None
    for q in range(1, MAX_DENOMINATOR + 1):
        p = round(x * q)
        if abs(x - p / q) <= tol:
            return sp.Rational(p, q)
    for q in range(1, MAX_DENOMINATOR + 1):
        k = round(x * q / math.pi)
        if k and abs(x - k * math.pi / q) <= tol:
            return sp.Rational(k, q) * sp.pi
    for c in _ALGEBRAIC:
        for value in (c, -c):
            if abs(x - float(value)) <= tol:
                return value
    return None


def _rpy_angles(r: sp.Matrix, tol: float) -> list | None:
    """Exact angles (roll, pitch, yaw), each 0 or k pi/q, with ``lie.rot_rpy`` within ``tol`` of the
    numeric rotation ``r`` entry by entry; None when there are none (or ``r`` has symbols)."""
    try:
        m = np.array(r, dtype=float)
    except TypeError:
        return None
    if abs(m[2, 0]) < 1 - 1e-12:
        angles = (math.atan2(m[2, 1], m[2, 2]), math.asin(-m[2, 0]), math.atan2(m[1, 0], m[0, 0]))
    else:  # gimbal lock: only yaw - roll (or yaw + roll) is defined; take roll = 0
        angles = (0.0, math.copysign(math.pi / 2, -m[2, 0]), math.atan2(-m[0, 1], m[1, 1]))
    exact = [sp.Integer(0) if abs(a) <= tol else snap(a, tol) for a in angles]
    if any(a is None or (a / sp.pi).is_Rational is not True for a in exact):
        return None
    rebuilt = lie.rot_rpy(*exact)
    return exact if np.abs(np.array(rebuilt, dtype=float) - m).max() <= 4 * tol else None


def _round_pose(c: sp.Matrix, tol: float, fix) -> sp.Matrix:
    """``c`` with its rotation rebuilt from exact angles if it has them, and ``fix`` on every entry."""
    c = sp.Matrix(c)
    angles = _rpy_angles(lie.rotation_of(c), tol)
    if angles is not None:
        c[:3, :3] = lie.rot_rpy(*angles)
    return c.applyfunc(fix)


def round_robot(robot: Robot, tol: float) -> Robot:
    """A copy of ``robot`` with every number within ``tol`` of a simple exact number (:func:`snap`: 0, +-1,
    p/q, k pi/q, sqrt(2)/2, ...) replaced by it, in poses, screws, inertias, gravity and default values.
    A rotation within ``tol`` of one with angles 0 or k pi/q is rebuilt from them, as the writer's
    ``rotations="rpy"`` writes it. ``tol`` near round-off (1e-10) keeps measured numbers such as 0.0825."""
    def fix(e):
        subs = {f: s for f in sp.sympify(e).atoms(sp.Float) if (s := snap(float(f), tol)) is not None}
        return e.xreplace(subs) if subs else e

    defaults = {k: v if snap(v, tol) is None else float(snap(v, tol)) for k, v in robot.defaults}
    joints = [replace(j, origin=_round_pose(j.origin, tol, fix)) for j in robot.joints]
    frames = [replace(f, offset=_round_pose(f.offset, tol, fix)) for f in robot.frames]
    return robot._recreate(joints=joints, frames=frames).map_expressions(fix, defaults=defaults)
