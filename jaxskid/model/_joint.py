"""The parts of a robot model: a joint with the body it moves, and a named frame on a body.

Conventions (body-fixed representation, Müller 2018, sec. 2.3): ``Joint.origin`` (``B_i``) is the 4x4
pose of body ``i``'s frame in its parent's frame at ``q = 0``; ``Joint.screw`` (``X_i``) the joint's unit
screw coordinates ``(omega, v)`` in body ``i``'s frame; ``Joint.inertia`` the 6x6 mass-inertia matrix of
body ``i`` in its own frame (see :mod:`jaxskid.model._lie`); ``Joint.drive`` the joint's drive
(:mod:`jaxskid.model._drive`), ``None`` for none.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from ._drive import Drive


@dataclass(frozen=True)
class Joint:
    """One joint and the body it moves (see the module docstring for the conventions)."""

    name: str
    type: str
    parent: int
    origin: sp.ImmutableMatrix
    screw: tuple
    inertia: sp.ImmutableMatrix
    link: str
    drive: Drive | None = None


@dataclass(frozen=True)
class Frame:
    """A named frame rigidly attached to body ``body`` (``-1``: the world) at pose ``offset``."""

    name: str
    body: int
    offset: sp.ImmutableMatrix
