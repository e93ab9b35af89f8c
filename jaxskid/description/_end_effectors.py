"""End-effectors placed on a loaded robot: ``load(path, end_effectors={"tool": ("link6", pose)})``.

Each end-effector is a frame ``pose`` away from a named frame of the robot (a body's link, a fixed link
merged into a body, or the base), as a description's ``ee`` with ``ee_parent`` is: its pose in the world is
``C_link(q) pose``. The robot's end-effectors become the given ones, in the given order; the frames that
were end-effectors before stay named frames. ``pose`` takes the forms of a description's pose
(:meth:`~._yaml_values.ValueReader.pose`): a 4x4 matrix (nested lists, a NumPy array or a SymPy matrix),
``{"xyzrpy": [x, y, z, roll, pitch, yaw]}`` or ``{"translation": [...], "rotation": ...}``; ``None`` is the
link's own frame. ``{name: (name, None)}`` keeps the robot's frame ``name`` (a foot) as an end-effector, beside
new ones (:func:`jaxskid.collision_points`).
"""

from __future__ import annotations

from collections.abc import Mapping

import sympy as sp

from .._errors import ModelError
from ..model._joint import Frame
from ..model._robot import Robot
from ..model._validate import describe_value
from ._keymap import KeyMap
from ._yaml_values import ValueReader


def with_end_effectors(robot: Robot, end_effectors: Mapping, *, source: str | None = None) -> Robot:
    """``robot`` whose end-effectors are ``{name: (link, pose)}`` (module docstring).

    Raises:
        ModelError: at ``end_effectors.<name>``: an entry that is not ``(link, pose)``, an unknown link, a
            pose that is no rigid transformation, a name that another frame has.
    """
    if not isinstance(end_effectors, Mapping) or not end_effectors:
        raise ModelError(f"expected a mapping of names to (link, pose), got {describe_value(end_effectors)}",
                         where="end_effectors", source=source)
    reader, frames, keys = ValueReader(source or "<robot>"), list(robot.frames), KeyMap()
    try:
        for name, entry in end_effectors.items():
            where = f"end_effectors.{name}"
            if not isinstance(entry, (tuple, list)) or len(entry) != 2 or not isinstance(entry[0], str):
                raise ModelError(f"expected (link name, pose), got {describe_value(entry)}", where=where)
            link, pose = entry
            if name == link and pose is None and link in robot.frame_names:  # the frame itself, kept
                continue
            if link not in robot.frame_names:
                raise ModelError(f"unknown link {link!r}; expected one of {', '.join(robot.frame_names)}", where=where)
            parent = robot.frame(link)
            keys.add(f"frames[{len(frames)}]", where)
            frames.append(Frame(str(name), parent.body, sp.ImmutableMatrix(parent.offset * _pose(reader, pose, where))))
        return robot._recreate(frames=frames, end_effectors=tuple(str(k) for k in end_effectors))
    except ModelError as exc:
        raise keys.relocate(exc).located(source=source) from None


def _pose(reader: ValueReader, pose, where: str) -> sp.Matrix:
    if pose is None:
        return sp.eye(4)
    if isinstance(pose, sp.MatrixBase):
        return sp.Matrix(pose)
    if hasattr(pose, "tolist"):  # a NumPy array
        pose = pose.tolist()
    return reader.pose(pose, where)
