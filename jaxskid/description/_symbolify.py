"""Numbers of a robot made named parameters with their values as defaults (``jaxskid convert --symbolify``).

Every nonzero number in the translation of a joint's pose (its body's frame in the parent's frame at
q = 0) becomes ``<joint>_x``, ``<joint>_y`` or ``<joint>_z``, and likewise for the frames
(``<frame>_x``, ...); every numeric 6x6 mass-inertia becomes its 10 standard parameters
``<link>_m, <link>_mcx, ..., <link>_Izz`` (:func:`jaxskid.model._lie.standard_parameters`, the names of
``jaxskid.load(urdf, symbolic_inertia=True)``). Rotations stay numbers: a rotation written with symbols
would have to stay orthogonal for every value of them. The robot's dynamics at the defaults do not change.
"""

from __future__ import annotations

import re
from dataclasses import replace

import sympy as sp

from .._errors import ModelError
from ..model import _lie as lie
from ..model._robot import Robot
from ..model._validate import symbol


def _identifier(name: str) -> str:
    prefix = re.sub(r"[^0-9A-Za-z_]", "_", name)
    return f"_{prefix}" if prefix[:1].isdigit() else prefix


def _translation(c: sp.Matrix, prefix: str, new: dict) -> sp.ImmutableMatrix:
    """``c`` with each nonzero number of its translation replaced by ``<prefix>_<axis>``, added to ``new``."""
    c = sp.Matrix(c)
    for row, axis in enumerate("xyz"):
        e = sp.sympify(c[row, 3])
        if e.is_number and e != 0:
            new[f"{prefix}_{axis}"] = float(e)
            c[row, 3] = symbol(f"{prefix}_{axis}")
    return sp.ImmutableMatrix(c)


def _inertia(m6: sp.Matrix, prefix: str, new: dict) -> sp.ImmutableMatrix:
    """A numeric mass-inertia written with its 10 standard parameters, added to ``new``; else ``m6``."""
    if sp.Matrix(m6).free_symbols:
        return m6
    names = [f"{prefix}_{k}" for k in lie.STANDARD_PARAMETER_NAMES]
    new.update({n: float(v) for n, v in zip(names, lie.standard_parameters(sp.Matrix(m6)))})
    return sp.ImmutableMatrix(lie.inertia_from_parameters(*(symbol(n) for n in names)))


def symbolify_robot(robot: Robot) -> Robot:
    """``robot`` with its translations and numeric inertias as parameters whose defaults are their values.

    Raises:
        ModelError: a new name that is already a parameter, or that two joints, links or frames share.
    """
    taken = set(robot.parameters) | {k for k, _ in robot.defaults}
    defaults = dict(robot.defaults)

    def add(new: dict, where: str) -> None:
        clash = sorted(set(new) & taken)
        if clash:
            raise ModelError(f"cannot name the numbers {', '.join(clash)}: the name is already taken", where=where)
        taken.update(new)
        defaults.update(new)

    joints = []
    for k, j in enumerate(robot.joints):
        new: dict = {}
        origin = _translation(j.origin, _identifier(j.name), new)
        inertia = _inertia(j.inertia, _identifier(j.link), new)
        add(new, f"joints[{k}]")
        joints.append(replace(j, origin=origin, inertia=inertia))
    frames = []
    for k, f in enumerate(robot.frames):
        new = {}
        frames.append(replace(f, offset=_translation(f.offset, _identifier(f.name), new)))
        add(new, f"frames[{k}]")
    return robot._recreate(joints=joints, frames=frames, defaults=defaults)
