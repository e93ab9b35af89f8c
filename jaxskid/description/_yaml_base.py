"""The ``floating_base`` and ``base_inertia`` keys of a YAML/JSON description.

``floating_base: true`` makes the base (``base``, default ``world``) a free-flyer body
(:attr:`~jaxskid.Robot.floating_base`): ``q`` is then ``(x, y, z, qx, qy, qz, qw, q_1, ..., q_n)`` and the
velocities ``(omega, v, qd_1, ..., qd_n)``, the base twist in the base frame. ``base_inertia`` is that body's
mass-inertia in its own frame, in any form of a ``mass_inertia`` entry (a 6x6 matrix or ``{mass, inertia,
com, frame, rotation}``); left out, the base is massless. The model checks the values (``floating_base`` must
be ``true`` or ``false``), and its errors name these keys.
"""

from __future__ import annotations

from collections.abc import Mapping

from ._keymap import KeyMap
from ._yaml_values import ValueReader


def read_floating_base(reader: ValueReader, data: Mapping, keys: KeyMap) -> dict:
    """The :meth:`Robot.create <jaxskid.Robot.create>` arguments ``floating_base`` and ``base_inertia`` that
    ``data`` gives (none if it gives neither); records in ``keys`` where each came from."""
    out = {}
    if "floating_base" in data:
        out["floating_base"] = data["floating_base"]
        keys.add("floating_base", "floating_base")
    if "base_inertia" in data:
        if data.get("floating_base", False) is False:  # a value that is no bool: the model names floating_base
            raise reader.error("base_inertia", "a fixed base has no inertia; give floating_base: true or leave it out")
        out["base_inertia"] = reader.mass_inertia(data["base_inertia"], "base_inertia")
        keys.add("base_inertia", "base_inertia")
    return out
