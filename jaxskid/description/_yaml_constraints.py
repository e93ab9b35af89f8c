"""The ``constraints`` key of a YAML/JSON description: contacts and loop closures (jaxskid's key).

Each entry names its kind by its first key, whose value is the frame (or the two frames) it holds; frames
are named as everywhere in the description (links, ``ee_names``, ``frames``, the ``base``)::

    constraints:
      - loop_closure: [coupler_end, rocker_tip]   # the two frames coincide ...
        kind: [x, z]                              # ... on these world axes (or point, the default, or frame)
      - point_contact: foot                       # the frame's origin stays at position
        position: [0.2, 0, 0]                     # default: where it is at the configuration at (or q = 0)
        axes: [x, z]                              # default: x, y, z
      - frame_contact: hand                       # the frame stays at pose (any pose form); axes: of rx .. z
        at: {q1: 0.3, q2: -0.5}                   # joint name -> position; the others at 0

:mod:`jaxskid.model._constraint` gives the meaning of each and checks the rest (unknown frames and joints, a
loop on one body, frames that cannot meet); its errors are mapped back to these keys
(``constraints[0].loop_closure[1]``, ``constraints[1].position[2]``, ``constraints[2].at.q1``).
"""

from __future__ import annotations

from collections.abc import Mapping

from ..model._constraint import FrameContact, LoopClosure, PointContact
from ..model._validate import describe_value
from ._keymap import KeyMap
from ._yaml_values import ValueReader

_KINDS = {"point_contact": ("position", "axes", "at"), "frame_contact": ("pose", "axes", "at"),
          "loop_closure": ("kind",)}
"""Each kind of entry and its other keys."""


def read_constraints(reader: ValueReader, value, keys: KeyMap) -> tuple:
    """The constraints of the ``constraints`` list ``value`` (``None``: none); records in ``keys`` where the
    model's paths of their frames came from."""
    if value is None:
        return ()
    if not isinstance(value, list):
        raise reader.error("constraints", f"expected a list of point_contact, frame_contact or loop_closure "
                                          f"entries, got {describe_value(value)}")
    return tuple(_entry(reader, item, f"constraints[{k}]", keys) for k, item in enumerate(value))


def _entry(reader: ValueReader, item, where: str, keys: KeyMap):
    kinds = [k for k in _KINDS if isinstance(item, Mapping) and k in item]
    if len(kinds) != 1:
        raise reader.error(where, f"expected a mapping with one of the keys {', '.join(_KINDS)}, got {describe_value(item)}")
    kind = kinds[0]
    d = reader.mapping(item, where, (kind, *_KINDS[kind]))
    if kind == "loop_closure":
        frames = d[kind]
        if not isinstance(frames, list) or len(frames) != 2:
            raise reader.error(f"{where}.{kind}", f"expected the names of two frames, got {describe_value(frames)}")
        names = [reader.name_value(f, f"{where}.{kind}[{k}]") for k, f in enumerate(frames)]
        keys.add(f"{where}.frame_a", f"{where}.{kind}[0]")
        keys.add(f"{where}.frame_b", f"{where}.{kind}[1]")
        return LoopClosure(*names, kind=_axes(reader, d.get("kind", "point"), f"{where}.kind"))
    frame = reader.name_value(d[kind], f"{where}.{kind}")
    keys.add(f"{where}.frame", f"{where}.{kind}")
    axes = _axes(reader, d["axes"], f"{where}.axes") if "axes" in d else None
    at = d.get("at")
    if at is not None:
        if not isinstance(at, Mapping):
            raise reader.error(f"{where}.at", f"expected a mapping of joint names to positions, got {describe_value(at)}")
        at = {str(k): reader.scalar(v, f"{where}.at.{k}") for k, v in at.items()}
    if kind == "point_contact":
        position = tuple(reader.vector(d["position"], 3, f"{where}.position")) if "position" in d else None
        return PointContact(frame, position, axes, at)
    pose = reader.pose(d["pose"], f"{where}.pose") if "pose" in d else None
    return FrameContact(frame, pose, axes, at)


def _axes(reader: ValueReader, value, where: str):
    """A kind (``point``, ``frame``) or a list of axis names, as written (the model checks the names)."""
    if isinstance(value, str):
        return value
    if not isinstance(value, list) or not all(isinstance(a, str) for a in value):
        raise reader.error(where, f"expected a list of axis names (rx, ry, rz, x, y, z), got {describe_value(value)}")
    return tuple(value)
