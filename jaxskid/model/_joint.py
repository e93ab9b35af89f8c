"""The parts of a robot model: a joint with the body it moves, and a named frame on a body.

Conventions (body-fixed representation, Müller 2018, sec. 2.3): ``Joint.origin`` (``B_i``) is the 4x4
pose of body ``i``'s frame in its parent's frame at ``q = 0``; ``Joint.screw`` (``X_i``) the joint's unit
screw coordinates ``(omega, v)`` in body ``i``'s frame; ``Joint.inertia`` the 6x6 mass-inertia matrix of
body ``i`` in its own frame (see :mod:`jaxskid.model._lie`); ``Joint.drive`` the joint's drive
(:mod:`jaxskid.model._drive`), ``None`` for none; ``Joint.mimic`` the joint it follows
(:mod:`jaxskid.model._mimic`), ``None`` for an independent joint; ``Joint.limits`` its
:class:`JointLimits`, ``None`` where none are given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import sympy as sp

from .._errors import ModelError
from ._drive import Drive
from ._mimic import Mimic


@dataclass(frozen=True)
class Joint:
    """One joint and the body it moves (see the module docstring for the conventions).

    Args:
        name: the joint's name.
        type: ``"revolute"`` or ``"prismatic"``.
        parent: the index of the parent body (``-1``: the world, or the floating base).
        origin: ``B_i``, the 4x4 pose of the body's frame in its parent's frame at ``q = 0``.
        screw: ``X_i``, the joint's unit screw coordinates ``(omega, v)`` in the body's frame.
        inertia: the body's 6x6 mass-inertia matrix in its own frame.
        link: the name of the body (its URDF link).
        drive: the joint's :class:`~jaxskid.Drive`, ``None`` for none.
        mimic: the joint this one follows (below), ``None``: independent.
        limits: its :class:`~jaxskid.JointLimits` (below), ``None``: none given.
    """

    name: str
    type: str
    parent: int
    origin: sp.ImmutableMatrix
    screw: tuple
    inertia: sp.ImmutableMatrix
    link: str
    drive: Drive | None = None
    mimic: Mimic | tuple | str | None = None
    """The joint this one follows, ``q = multiplier * q_joint + offset``: a :class:`Mimic`, a tuple
    ``(joint, multiplier, offset)`` or a joint name (multiplier 1, offset 0); ``None``: independent."""
    limits: JointLimits | None = None
    """Position, velocity and effort bounds (metadata: no equation, cache key or fingerprint depends on
    them); ``None``: none given."""


@dataclass(frozen=True)
class JointLimits:
    """Bounds of a joint, as a URDF ``<limit lower upper velocity effort>`` gives them: ``lower <= q <= upper``,
    ``|qd| <= velocity``, ``|tau| <= effort`` (rad, rad/s and N m for a revolute joint; m, m/s and N for a
    prismatic one). Unknown bounds are infinite: ``-inf``/``inf`` positions (a continuous joint), ``inf``
    velocity and effort."""

    lower: float = -math.inf
    upper: float = math.inf
    velocity: float = math.inf
    effort: float = math.inf

    def checked(self, where: str = "limits") -> "JointLimits":
        """The same limits as floats; :class:`ModelError` at ``where`` unless ``lower <= upper`` and the
        velocity and effort are non-negative (nan nowhere)."""
        values = {}
        for key in ("lower", "upper", "velocity", "effort"):
            value = getattr(self, key)
            try:
                values[key] = float(value)
            except (TypeError, ValueError):
                values[key] = math.nan
            if math.isnan(values[key]):
                raise ModelError(f"expected a number (or +-inf), got {value!r}", where=f"{where}.{key}")
        if values["lower"] > values["upper"]:
            raise ModelError(f"expected lower <= upper, got lower {values['lower']} > upper {values['upper']}",
                             where=f"{where}.lower")
        for key in ("velocity", "effort"):
            if values[key] < 0:
                raise ModelError(f"expected a non-negative bound, got {values[key]}", where=f"{where}.{key}")
        return JointLimits(**values)


@dataclass(frozen=True)
class Frame:
    """A frame called ``name`` rigidly attached to body ``body`` (its index; ``-1``: the world) at the 4x4 pose
    ``offset`` in that body's frame."""

    name: str
    body: int
    offset: sp.ImmutableMatrix
