"""Writing a :class:`Robot` as a description in Skidy's YAML/JSON schema, and rounding it first.

The writer emits the body-fixed representation with 6x6 inertias, integers and floats as YAML numbers
(floats with ``repr`` precision) and other entries as SymPy strings, so that
``parse_description(robot_to_dict(robot)) == robot`` (:mod:`jaxskid.description._yaml_schema`).
"""

from __future__ import annotations

import json
from pathlib import Path

import sympy as sp
import yaml
from sympy.printing.str import StrPrinter

from .._errors import ModelError
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


def robot_to_dict(robot: Robot) -> dict:
    """The description of ``robot`` in Skidy's schema (body-fixed, 6x6 inertias) plus jaxskid's keys."""
    out: dict = {"name": robot.name}
    if robot.base != "world":
        out["base"] = robot.base
    out["representation"] = "body_fixed"
    out["gravity"] = [_value(g) for g in robot.gravity]
    out["joint_names"] = list(robot.joint_names)
    out["link_names"] = list(robot.link_names)
    out["parent"] = [p + 1 for p in robot.parents]
    out["joint_screw_coord"] = [[_value(e) for e in j.screw] for j in robot.joints]
    out["body_ref_config"] = [_rows(j.origin) for j in robot.joints]
    out["mass_inertia"] = [_rows(j.inertia) for j in robot.joints]
    if robot.end_effectors:
        ee = [robot.frame(name) for name in robot.end_effectors]
        out["ee"] = [_rows(f.offset) for f in ee]
        out["ee_parent"] = [f.body + 1 for f in ee]
        out["ee_names"] = list(robot.end_effectors)
    others = [f for f in robot.frames if f.name not in robot.end_effectors]
    if others:
        out["frames"] = [{"name": f.name, "parent": f.body + 1, "pose": _rows(f.offset)} for f in others]
    frame_names = {f.name for f in robot.frames}
    default_order = [nm for nm in robot.end_effectors if nm in frame_names] + [f.name for f in others]
    if default_order != [f.name for f in robot.frames]:
        out["frame_order"] = [f.name for f in robot.frames]
    if robot.defaults:
        out["assignments"] = {k: v for k, v in robot.defaults}
    return out


class _Dumper(yaml.SafeDumper):
    def increase_indent(self, flow=False, indentless=False):
        return super().increase_indent(flow, False)  # indent lists under their key


def _represent_list(dumper, data):
    flow = all(not isinstance(x, (list, dict)) for x in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


_Dumper.add_representer(list, _represent_list)


def write_description(robot: Robot, path, *, force: bool = False) -> None:
    """Write ``robot`` as YAML (``.yaml``/``.yml``) or JSON (``.json``); an existing file needs ``force=True``."""
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise ModelError(f"expected a file name ending in .yaml, .yml or .json, got {path.suffix or 'none'!r}",
                         source=str(path))
    data = robot_to_dict(robot)
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


def round_robot(robot: Robot, tol: float) -> Robot:
    """A copy of ``robot`` with every number within ``tol`` of 0, 1 or -1 (in poses, screws, inertias,
    gravity and default values) replaced by exactly that, e.g. ``cos(pi/2)`` computed in floats -> 0."""
    def snap(x: float):
        for target in (0, 1, -1):
            if abs(x - target) <= tol:
                return target
        return None

    def fix(e):
        subs = {f: sp.Integer(s) for f in sp.sympify(e).atoms(sp.Float) if (s := snap(float(f))) is not None}
        return e.xreplace(subs) if subs else e

    defaults = {k: v if snap(v) is None else float(snap(v)) for k, v in robot.defaults}
    return robot.map_expressions(fix, defaults=defaults)
