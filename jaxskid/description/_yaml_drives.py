"""The ``drives`` key of a YAML/JSON description: one drive (or ``null``) per joint.

``drives: [{armature, viscous, coulomb, offset}, null, ...]`` lists, in the order of the joints, each joint's
drive (:class:`~jaxskid.model._drive.Drive`: ``Ia qdd + fv qd + fc sign(qd) + fo`` added to its force);
``null`` means no drive, and a key left out is 0. ``armature`` may be replaced by
``gear_ratio`` with ``rotor_inertia`` (``armature = gear_ratio^2 * rotor_inertia``, the rotor's inertia
reflected through the gearbox). Values are numbers or expressions, whose names become parameters (with
defaults in ``assignments``). Armature, friction and rotor inertia must not be negative, and a locked joint
has no drive.
"""

from __future__ import annotations

from .._errors import ModelError
from ..model._drive import Drive
from ._keymap import KeyMap
from ._yaml_values import ValueReader

_FIELDS = {"armature": "armature", "viscous": "viscous", "coulomb": "coulomb", "offset": "offset"}
_KEYS = (*_FIELDS, "gear_ratio", "rotor_inertia")


def read_drives(reader: ValueReader, value, n: int, keys: KeyMap) -> list[Drive | None]:
    """One :class:`Drive` or ``None`` per joint from the ``drives`` list ``value`` (``None``: no drives);
    records in ``keys`` where each drive's values came from."""

    def drive(entry, where: str, i: int) -> Drive:
        d = reader.mapping(entry, where, _KEYS)
        geared = [k for k in ("gear_ratio", "rotor_inertia") if k in d]
        if geared and (len(geared) < 2 or "armature" in d):
            raise reader.error(where, "expected either armature or both gear_ratio and rotor_inertia, got "
                                      + ", ".join(k for k in ("armature", *geared) if k in d))
        values = {field: reader.scalar(d[key], f"{where}.{key}") for key, field in _FIELDS.items() if key in d}
        keys.add(f"joints[{i}].drive", where)
        if geared:
            rotor = reader.scalar(d["rotor_inertia"], f"{where}.rotor_inertia")
            values["armature"] = reader.scalar(d["gear_ratio"], f"{where}.gear_ratio") ** 2 * rotor
            keys.add(f"joints[{i}].drive.armature", f"{where}.rotor_inertia")
        return Drive(**values)

    return reader.per_joint(value, "drives", n, "a drive", drive)


def check_unlocked(joints, locked) -> None:
    """A locked joint (``lock``, from the file or the caller) has no drive (``joints``: the model's)."""
    for i, j in enumerate(joints):
        if j.drive is not None and j.name in locked:
            raise ModelError(f"joint {j.name!r} is locked (lock.{j.name}); a locked joint has no drive",
                             where=f"drives[{i}]")
