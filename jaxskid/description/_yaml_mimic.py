"""The ``mimic`` key of a YAML/JSON description: per joint, ``null`` or the joint it follows.

``mimic: [null, {joint: q1, multiplier: -1, offset: 0.1}, ...]`` lists, in the order of the joints, each
joint's coupling ``q_i = multiplier * q_joint + offset`` (:class:`~jaxskid.model._mimic.Mimic`, URDF's
``<mimic>``): ``joint`` names another joint (as ``joint_names`` or ``q`` name it; default ``q1``, ``q2``,
...), ``multiplier`` (default 1) and ``offset`` (default 0) are numbers or expressions of numbers
(``pi/2``), not parameters. A name alone, ``mimic: [null, q1]``, means multiplier 1 and offset 0. A mimic
joint is no coordinate: ``q`` holds the other joints only. The model checks the rest (an unknown joint,
a loop; a chain is composed), and its errors name ``mimic[i]``.
"""

from __future__ import annotations

from ..model._mimic import Mimic
from ._keymap import KeyMap
from ._yaml_values import ValueReader

_KEYS = ("joint", "multiplier", "offset")


def read_mimics(reader: ValueReader, value, n: int, keys: KeyMap) -> list[Mimic | None]:
    """One :class:`Mimic` or ``None`` per joint from the ``mimic`` list ``value`` (``None``: no mimic
    joints); records in ``keys`` where each came from."""

    def mimic(entry, where: str, i: int) -> Mimic:
        if isinstance(entry, str):
            entry = {"joint": entry}
        d = reader.mapping(entry, where, _KEYS, required=("joint",))
        joint = reader.name_value(d["joint"], f"{where}.joint")
        numbers = [reader.scalar(d.get(k, v), f"{where}.{k}") for k, v in (("multiplier", 1), ("offset", 0))]
        keys.add(f"joints[{i}].mimic", where)
        return Mimic(joint, *numbers)

    return reader.per_joint(value, "mimic", n, "the joint followed", mimic)
