"""Robot descriptions in Skidy's YAML/JSON schema: from a loaded mapping to a :class:`Robot`.

The schema is Skidy's (dfki-ric-underactuated-lab/skidy: README "YAML and JSON", ``src/skidy/parser.py``,
``src/skidy/matrices.py``); every Skidy key is read, and a few optional jaxskid keys are added.

Skidy keys
    ``joint_screw_coord`` (required): per joint, a 6-vector ``(omega, v)`` or ``{type, axis, vec}`` with
    ``v = vec x axis`` (``vec`` is a point on a revolute axis; prismatic joints take no ``vec``).
    ``body_ref_config`` (required): per body, a 4x4 matrix, ``{xyzrpy: [x, y, z, r, p, y]}`` or
    ``{rotation, translation}`` (either may be left out); ``rotation`` is a 3x3 matrix, ``{Q: [w, x, y, z]}``,
    ``{rpy: [r, p, y]}`` (R = Rz(y) Ry(p) Rx(r)) or ``{axis, angle}``.
    ``representation``: ``spatial`` (default: screws in world coordinates, each body's world pose at q = 0)
    or ``body_fixed`` (screws in the body's frame, each body's pose in its parent's frame).
    ``ee``: one pose or a list of poses, each relative to the frame of its ``ee_parent`` body in either
    representation (Skidy: ``FK[ee_parent] * ee``). ``ee_parent``: a 1-based body index (0 = world) or a
    list of them; default: the last body.
    ``mass_inertia``: per body, a 6x6 matrix ``[[I_o, m c~], [-m c~, m 1]]`` or
    ``{mass, inertia, com, frame}``. ``inertia`` is a 3x3 matrix, six values (Ixx, Ixy, Ixz, Iyy, Iyz, Izz),
    ``{Ixx: .., Iyz: ..}`` (missing entries are 0), a scalar (times the identity) or ``{index, pointmass}``
    (symbols Ixx<index>.. or I<index> times the identity). ``frame: body`` (the default, as Skidy's
    ``mass_matrix_mixed_data``) means the inertia is about the body frame's origin; ``frame: com`` means
    it is about the centre of mass, in the axes of a COM frame whose orientation in the body frame is
    ``rotation`` (any rotation form; default the identity): the inertia is turned, ``R I Rᵀ``, and moved by
    the parallel-axis theorem, as Skidy's ``mass_matrix_mixed_data``. ``rotation`` with ``frame: body`` is
    ignored, as Skidy ignores it, with a :class:`DescriptionWarning`. Without ``mass_inertia`` (or with a
    ``null`` entry for a body) the bodies' inertia is unknown: the robot serves kinematics, and a quantity
    that needs inertia is refused with the bodies named (:attr:`Robot.without_inertia`).
    ``parent`` (1-based, 0 = world; each parent must come before its child), ``support`` (root-to-body
    paths) and ``child``: the tree; ``support`` and ``child`` are checked against ``parent``.
    ``gravity`` (or ``gravity_vector``; required with ``mass_inertia``): see below.
    ``q``, ``qd``, ``q2d``, ``q3d``, ``q4d``: symbol names; the ``q`` names become the joint names.
    ``WEE``, ``WDEE``, ``W2DEE``: end-effector wrenches ``(moment, force)`` and their time derivatives, one
    6-vector for every end-effector or one per end-effector; Skidy applies each at the origin of the
    end-effector's parent body, in that body's frame. :func:`read_extras` returns them as written and
    converted to jaxskid's convention, at the end-effector frame (:mod:`._wrenches`).
    ``assignments``: parameter name -> number (an expression of numbers such as ``pi/2`` is allowed).

jaxskid keys
    ``name`` (default: the file stem), ``base`` (the world link's name, default ``world``),
    ``joint_names``, ``link_names`` (default ``link1``..), ``ee_names`` (default ``ee`` or ``ee1``..),
    ``frames: [{name, parent, pose}]`` (named frames that are not end-effectors, ``parent`` as
    ``ee_parent``), ``frame_order`` (the order of all named frames, written only when it is not
    end-effectors first), ``lock`` (joint name -> position, see :meth:`Robot.lock`), ``dh`` (a
    Denavit–Hartenberg table in place of ``joint_screw_coord``, ``body_ref_config`` and ``representation``:
    ``{convention: standard | modified, base: <pose>, joints: [{type, a, alpha, d, theta}, ...]}``, body i's
    frame is DH frame i; :mod:`._dh`), ``drives`` (per joint, ``null`` or its drive
    ``{armature, viscous, coulomb, offset}``, ``Ia qdd + fv qd + fc sign(qd) + fo`` added to its force; a key
    left out is 0, and ``gear_ratio`` with ``rotor_inertia`` may replace ``armature = gear_ratio^2
    rotor_inertia``; values are numbers or expressions of parameters; :mod:`._yaml_drives`). A joint with a
    drive here is driven without ``jaxskid.load(..., drives=True)``, which gives the others the parameters
    ``{joint}_Ia, {joint}_fv, {joint}_fc, {joint}_fo`` (default 0). ``mimic`` (per joint, ``null`` or
    ``{joint, multiplier, offset}``: it follows that joint, ``q = multiplier q_joint + offset``; :mod:`._yaml_mimic`).
    ``constraints`` (contacts and loop closures on named frames: :mod:`._yaml_constraints`).
    ``floating_base`` and ``base_inertia`` (a free-flyer base body and its mass-inertia: :mod:`._yaml_base`).

Gravity. Skidy builds the base acceleration as ``Vd_0 = (0, -gravity_vector)`` and adds
``Q_grav = J^T Mb U Vd_0`` to ``M q2d + C qd`` (``src/skidy/kinematics_generator.py``), and its templates and
tutorial write ``gravity: [0, 0, -g]`` "in negative z0-direction". So ``gravity`` is the physical
gravitational acceleration, the same convention as :attr:`Robot.gravity`, and it is taken as it is. (Skidy
releases before that change used ``Vd_0 = (0, gravity_vector)`` and wrote ``[0, 0, g]``; such files must
flip the sign.)

Validation. This module checks the schema: keys, types, sizes, names and the 1-based tree. The model
validates the robot (:meth:`Robot.create`); its errors, which name the model's paths (``joints[1].inertia``),
are mapped back to the description's keys (``mass_inertia[1]``) by :class:`KeyMap`. Strings are parsed by
:func:`jaxskid.model._validate.to_expr`; decimal literals become double-precision floats.
"""

from __future__ import annotations

import keyword
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sympy as sp

from .._errors import DescriptionWarning, ModelError
from ..model._robot import Frame, Joint, Robot, spatial_to_body
from ..model._validate import describe_value
from ._dh import dh_size, joint_variables, read_dh
from ._keymap import KeyMap
from ._wrenches import DescriptionExtras, end_effector_wrenches
from ._yaml_base import read_floating_base
from ._yaml_constraints import read_constraints
from ._yaml_drives import check_unlocked, read_drives
from ._yaml_file import load_mapping
from ._yaml_mimic import read_mimics
from ._yaml_skidy import check_dialect, skidy_reading
from ._yaml_tree import is_int, read_tree
from ._yaml_values import ValueReader

_SKIDY_KEYS = (
    "joint_screw_coord", "body_ref_config", "representation", "ee", "ee_parent", "mass_inertia", "parent",
    "support", "child", "gravity", "gravity_vector", "q", "qd", "q2d", "q3d", "q4d", "WEE", "WDEE", "W2DEE",
    "assignments",
)
_JAXSKID_KEYS = ("name", "base", "joint_names", "link_names", "ee_names", "frames", "frame_order", "lock", "dh",
                 "drives", "mimic", "constraints", "floating_base", "base_inertia")
_GEOMETRY_KEYS = ("joint_screw_coord", "body_ref_config", "representation")  # what a dh block replaces
_DERIVATIVES = ("q", "qd", "q2d", "q3d", "q4d")
_WRENCHES = ("WEE", "WDEE", "W2DEE")


# ---------------------------------------------------------------------------------------------- entry points
def read_description(path, *, lock: Mapping[str, float] | None = None, drives: bool = False,
                     dialect: str = "jaxskid") -> Robot:
    """The robot described by a ``.yaml``, ``.yml`` or ``.json`` file in Skidy's schema.

    ``lock`` (joint name -> position) is merged over the file's own ``lock`` key. ``drives`` gives every
    moving joint without a ``drives`` entry the drive parameters ``J_Ia, J_fv, J_fc, J_fo`` (default 0,
    :meth:`Robot.with_drives`). ``dialect="skidy"`` reads the file as Skidy does (:mod:`._yaml_skidy`).
    Every problem with the file raises :class:`ModelError` naming the file, the key path and what was expected.
    """
    path = Path(path)
    return parse_description(load_mapping(path), source=str(path), lock=lock, drives=drives, dialect=dialect)


def parse_description(data: Mapping, *, source: str = "<dict>", lock: Mapping[str, float] | None = None,
                      drives: bool = False, dialect: str = "jaxskid") -> Robot:
    """The robot described by an already loaded mapping; ``source`` names it in error messages."""
    parsed = _parse(data, source, dialect)
    try:
        robot = Robot.create(**parsed.arguments)
        locked = {**parsed.lock, **(lock or {})}
        check_unlocked(robot.joints, locked)
        robot = robot.lock(locked) if locked else robot
        return robot.with_drives() if drives else robot
    except ModelError as exc:
        raise parsed.keys.relocate(exc).located(source=source) from None
    except (ArithmeticError, np.linalg.LinAlgError) as exc:  # numeric checks on extreme default values
        raise ModelError(f"cannot check the model numerically with the default values ({exc})", source=source) from None


def read_extras(path, *, dialect: str = "jaxskid") -> DescriptionExtras:
    """The symbol names and end-effector wrenches of a description file (see :class:`DescriptionExtras`)."""
    path = Path(path)
    return parse_extras(load_mapping(path), source=str(path), dialect=dialect)


def parse_extras(data: Mapping, *, source: str = "<dict>", dialect: str = "jaxskid") -> DescriptionExtras:
    """:func:`read_extras` for an already loaded mapping; the whole description is validated."""
    parsed = _parse(data, source, dialect)
    try:
        Robot.create(**parsed.arguments)
    except ModelError as exc:
        raise parsed.keys.relocate(exc).located(source=source) from None
    return parsed.extras


def _parse(data, source: str, dialect: str = "jaxskid") -> "_Parsed":
    try:
        if check_dialect(dialect) == "skidy":
            data = skidy_reading(data, source, _SKIDY_KEYS + _JAXSKID_KEYS)
        return _Parser(data, source).parse()
    except ModelError as exc:
        raise exc.located(source=source) from None


@dataclass(frozen=True)
class _Parsed:
    arguments: dict  # the arguments of Robot.create
    lock: dict
    extras: DescriptionExtras
    keys: KeyMap


class _Parser(ValueReader):
    """One pass over a description mapping; every check reports the key path of what it reads."""

    def __init__(self, data, source: str):
        super().__init__(source)
        self.data = data
        self.keys = KeyMap({"defaults": "assignments", "end_effectors": "ee_names"})
        self.count_key = "joint_screw_coord"  # the key whose length is the number of joints

    def parse(self) -> _Parsed:
        d = self.data
        n = self.check_keys()
        names = {key: self.names(key, n, identifiers=True) for key in _DERIVATIVES}
        joint_names = self.names("joint_names", n, identifiers=False)
        joint_key = "joint_names" if joint_names else "q"
        joint_names = joint_names or names["q"] or [f"q{i + 1}" for i in range(n)]
        for key, values in [*names.items(), (joint_key, joint_names)]:
            for i, v in enumerate(values or ()):
                self.reserved.setdefault(v, f"{key}[{i}]")
        link_names = self.names("link_names", n, identifiers=False) or [f"link{i + 1}" for i in range(n)]
        base = self.name_value(d.get("base", "world"), "base")
        defaults = self.assignments()
        gravity = self.gravity()
        joints = self.joints(n, joint_names, link_names)
        for i in range(n):
            self.keys.add(f"joints[{i}].name", f"{joint_key}[{i}]")
            self.keys.add(f"joints[{i}].link", f"link_names[{i}]")
        frames, ee_entries = self.frames(n, link_names, base)
        ees = [name for name, *_ in ee_entries]
        extras = self.extras(names, joint_names, ees, [pose for _, _, pose, _ in ee_entries])
        name = self.name_value(d.get("name", _default_name(self.source)), "name")
        arguments = dict(name=name, joints=joints, gravity=gravity, frames=frames, end_effectors=ees,
                         defaults=defaults, base=base, without_inertia=self.without_inertia)
        arguments["constraints"] = read_constraints(self, d.get("constraints"), self.keys)
        arguments.update(read_floating_base(self, d, self.keys))
        return _Parsed(arguments, self.lock(), extras, self.keys)

    def check_keys(self) -> int:
        """The top level's keys; returns the number of joints."""
        d = self.data
        if not isinstance(d, Mapping):
            raise self.error(None, f"expected a mapping of keys at the top level, got {describe_value(d)}")
        allowed = _SKIDY_KEYS + _JAXSKID_KEYS
        for key in d:
            if key not in allowed:
                raise self.error(None, f"unknown key {key!r}; expected one of {', '.join(allowed)}")
        geometry = ("joint_screw_coord", "body_ref_config") if "dh" not in d else ()
        for key in geometry:
            if key not in d:
                raise self.error(key, "required key is missing")
        if "dh" in d:
            given = [key for key in _GEOMETRY_KEYS if key in d]
            if given:
                raise self.error(given[0], "give either a dh table or joint_screw_coord, body_ref_config and "
                                           "representation, not both")
            self.count_key = "dh.joints"
            return dh_size(d["dh"], self)
        screws = d["joint_screw_coord"]
        if not isinstance(screws, list) or not screws:
            raise self.error("joint_screw_coord", f"expected a non-empty list (one entry per joint), got {describe_value(screws)}")
        return len(screws)

    def joints(self, n, joint_names, link_names) -> list[Joint]:
        if "dh" in self.data:
            parents = read_tree(self, n)
            variables = {**joint_variables(joint_names), **joint_variables(self.data.get("q") or [])}
            types, screws, poses = read_dh(self.data["dh"], self, parents, variables)
            for i in range(n):
                self.keys.add(f"joints[{i}].screw", f"dh.joints[{i}]")
                self.keys.add(f"joints[{i}].origin", f"dh.joints[{i}]")
        else:
            types, screws, poses, parents = self.screws_and_poses(n)
        # without mass_inertia, or with a null entry, a body's inertia is unknown: kinematics only
        inertias_in = self.entries("mass_inertia", n) if "mass_inertia" in self.data else [None] * n
        inertias = [sp.zeros(6) if m is None else self.mass_inertia(m, f"mass_inertia[{i}]")
                    for i, m in enumerate(inertias_in)]
        self.without_inertia = [link_names[i] for i, m in enumerate(inertias_in) if m is None]
        for i in range(n):
            self.keys.add(f"joints[{i}].inertia", f"mass_inertia[{i}]")
        drives = read_drives(self, self.data.get("drives"), n, self.keys)
        mimics = read_mimics(self, self.data.get("mimic"), n, self.keys)
        return [Joint(joint_names[i], types[i], parents[i], poses[i], screws[i], inertias[i], link_names[i], drives[i],
                      mimics[i]) for i in range(n)]

    def screws_and_poses(self, n) -> tuple[list, list, list, list[int]]:
        """(types, body-fixed screws, body-fixed poses, parents) from ``joint_screw_coord`` and ``body_ref_config``."""
        representation = self.data.get("representation", "spatial")
        if representation not in ("spatial", "body_fixed"):
            raise self.error("representation", f"expected spatial or body_fixed, got {describe_value(representation)}")
        parents = read_tree(self, n)
        poses_in = self.entries("body_ref_config", n)
        typed = [self.screw(s, f"joint_screw_coord[{i}]") for i, s in enumerate(self.data["joint_screw_coord"])]
        poses = [self.pose(p, f"body_ref_config[{i}]") for i, p in enumerate(poses_in)]
        screws = [s for _, s in typed]
        if representation == "spatial":
            screws, poses = spatial_to_body(screws, poses, parents)
        for i in range(n):
            self.keys.add(f"joints[{i}].screw", f"joint_screw_coord[{i}]")
            self.keys.add(f"joints[{i}].origin", f"body_ref_config[{i}]{self.rotation_key(poses_in[i])}")
        return [t for t, _ in typed], screws, poses, parents

    def entries(self, key, n) -> list:
        value = self.data[key]
        if not isinstance(value, list):
            raise self.error(key, f"expected a list with one entry per joint, got {describe_value(value)}")
        if len(value) != n:
            raise self.error(key, f"expected {n} entries (one per joint in {self.count_key}), got {len(value)}")
        return value

    def names(self, key, n, *, identifiers) -> list[str] | None:
        value = self.data.get(key)
        if value is None:
            return None
        if not isinstance(value, list):
            raise self.error(key, f"expected a list of {n} names, got {describe_value(value)}")
        if len(value) != n:
            raise self.error(key, f"expected {n} names (one per joint in {self.count_key}), got {len(value)}")
        for i, v in enumerate(value):
            self.name_value(v, f"{key}[{i}]")
            if identifiers and (not v.isidentifier() or keyword.iskeyword(v)):
                raise self.error(f"{key}[{i}]", f"expected a symbol name (letters, digits, _), got {v!r}")
            if v in value[:i]:
                raise self.error(f"{key}[{i}]", f"duplicate name {v!r} (also {key}[{value.index(v)}])")
        return list(value)

    # ------------------------------------------------------------------ top-level entries
    def assignments(self) -> dict[str, float]:
        value = self.data.get("assignments", {})
        if not isinstance(value, Mapping):
            raise self.error("assignments", f"expected a mapping of parameter names to numbers, got {describe_value(value)}")
        out = {}
        for key, v in value.items():
            where = f"assignments.{key}"
            if not isinstance(key, str) or not key.isidentifier():
                raise self.error("assignments", f"expected parameter names as keys, got {key!r}")
            if key in self.reserved:
                raise self.error(where, f"{key!r} is a joint variable ({self.reserved[key]}); it cannot have a default value")
            expr = self.scalar(v, where)
            if expr.free_symbols:
                raise self.error(where, f"expected a number, got {v!r}, which depends on {', '.join(sorted(map(str, expr.free_symbols)))}")
            out[key] = float(expr)
        self.set_defaults(out)
        return out

    def gravity(self) -> list:
        d = self.data
        if "gravity" in d and "gravity_vector" in d:
            raise self.error("gravity", "give either gravity or gravity_vector, not both")
        key = "gravity" if "gravity" in d or "gravity_vector" not in d else "gravity_vector"
        if key not in d and "mass_inertia" not in d:
            return [0, 0, 0]  # kinematics only: no body has a mass
        if key not in d:
            raise self.error("gravity", "required key is missing (the gravitational acceleration in the world frame, "
                                        "e.g. [0, 0, -g] when z points up)")
        self.keys.add("gravity", key)
        return self.vector(d[key], 3, key)

    def frames(self, n, link_names, base) -> tuple[list[Frame], list[tuple]]:
        """Named frames (end-effectors first, then ``frames``) and the end-effectors' entries
        (:meth:`end_effector_entries`)."""
        ees = self.end_effector_entries(n)
        bodies = {base: 0, **{nm: i + 1 for i, nm in enumerate(link_names)}}  # 1-based, 0 = world
        frames, keys = [], []
        for i, (name, parent, pose, key) in enumerate(ees + self.frame_entries(n)):
            if i < len(ees) and bodies.get(name) == parent and (pose - sp.eye(4)).is_zero_matrix:
                continue  # the end-effector is a body's own frame (or the base's)
            frames.append(Frame(name, parent - 1, sp.ImmutableMatrix(pose)))
            keys.append(key)
        order = self.data.get("frame_order")
        if order is not None:
            names = [f.name for f in frames]
            if not isinstance(order, list) or sorted(map(str, order)) != sorted(names) or len(order) != len(names):
                raise self.error("frame_order", f"expected the names {names} in some order, got {describe_value(order)}")
            perm = [names.index(nm) for nm in order]
            frames, keys = [frames[j] for j in perm], [keys[j] for j in perm]
        for k, (name_key, pose_key) in enumerate(keys):
            self.keys.add(f"frames[{k}].name", name_key)
            self.keys.add(f"frames[{k}].offset", pose_key)
        return frames, ees

    def end_effector_entries(self, n) -> list[tuple]:
        """(name, 1-based parent, pose, (name key, pose key)) of every ``ee``."""
        d = self.data
        ee = d.get("ee")
        if ee is None:
            for key in ("ee_parent", "ee_names"):
                if key in d:
                    raise self.error(key, "given without ee")
            return []
        # one pose (a mapping or a 4x4 matrix: Skidy's test) or a list of poses
        single = isinstance(ee, Mapping) or (isinstance(ee, list) and len(ee) > 0 and isinstance(ee[0], list)
                                              and len(ee[0]) > 0 and not isinstance(ee[0][0], (list, Mapping)))
        if not single and not isinstance(ee, list):
            raise self.error("ee", f"expected a pose or a list of poses, got {describe_value(ee)}")
        entries = [ee] if single else ee
        pose_keys = ["ee"] if single else [f"ee[{i}]" for i in range(len(ee))]
        poses = [self.pose(p, key) for p, key in zip(entries, pose_keys)]
        pose_keys = [key + self.rotation_key(p) for p, key in zip(entries, pose_keys)]
        parents = self.ee_parents(n, len(poses))
        names = d.get("ee_names")
        k = len(poses)
        if names is None:
            names, name_keys = (["ee"] if k == 1 else [f"ee{i + 1}" for i in range(k)]), ["ee"] * k
        elif not isinstance(names, list) or len(names) != k:
            raise self.error("ee_names", f"expected {k} name(s), one per ee, got {describe_value(names)}")
        else:
            name_keys = [f"ee_names[{i}]" for i in range(k)]
        return [(self.name_value(nm, key), p, pose, (key, pk))
                for nm, p, pose, key, pk in zip(names, parents, poses, name_keys, pose_keys)]

    def ee_parents(self, n, k) -> list[int]:
        """The 1-based ``ee_parent`` of each of the ``k`` end-effectors (default: the last body)."""
        parents = self.data.get("ee_parent", n)
        if isinstance(parents, list):
            if len(parents) != k:
                raise self.error("ee_parent", f"expected {k} body indices (one per ee), got {len(parents)}")
            keys = [f"ee_parent[{i}]" for i in range(k)]
        else:
            parents, keys = [parents] * k, ["ee_parent"] * k
        for p, key in zip(parents, keys):
            if not is_int(p) or not 0 <= p <= n:
                raise self.error(key, f"expected a body index in 0..{n} (0 is the world), got {describe_value(p)}")
        return parents

    def frame_entries(self, n) -> list[tuple]:
        """(name, 1-based parent, pose, (name key, pose key)) of every entry of ``frames``."""
        value = self.data.get("frames", [])
        if not isinstance(value, list):
            raise self.error("frames", f"expected a list of {{name, parent, pose}}, got {describe_value(value)}")
        out = []
        for i, f in enumerate(value):
            where = f"frames[{i}]"
            f = self.mapping(f, where, ("name", "parent", "pose"), required=("name", "parent"))
            if not is_int(f["parent"]) or not 0 <= f["parent"] <= n:
                raise self.error(f"{where}.parent", f"expected a body index in 0..{n} (0 is the world), "
                                                    f"got {describe_value(f['parent'])}")
            pose = self.pose(f["pose"], f"{where}.pose") if "pose" in f else sp.eye(4)
            keys = (f"{where}.name", f"{where}.pose{self.rotation_key(f.get('pose'))}")
            out.append((self.name_value(f["name"], f"{where}.name"), f["parent"], pose, keys))
        return out

    def lock(self) -> dict:
        value = self.data.get("lock", {})
        if not isinstance(value, Mapping):
            raise self.error("lock", f"expected a mapping of joint names to positions, got {describe_value(value)}")
        return {str(k): self.scalar(v, f"lock.{k}") for k, v in value.items()}

    def extras(self, names, joint_names, end_effectors, offsets) -> DescriptionExtras:
        """Symbol names and wrenches; ``offsets``: each end-effector's pose in its parent body's frame."""
        q = names["q"] or joint_names
        derived = {key: tuple(names[key] or ["d" * k + v for v in q]) for k, key in enumerate(_DERIVATIVES)}
        skidy = [self.wrenches(key, end_effectors) for key in _WRENCHES]
        ours = [end_effector_wrenches(w, offsets) for w in skidy]
        return DescriptionExtras(*(derived[k] for k in _DERIVATIVES), tuple(end_effectors), *ours, *skidy)

    def wrenches(self, key, end_effectors) -> tuple:
        """One 6-vector per end-effector from ``key``: zeros when absent, one vector broadcast, or one each."""
        value = self.data.get(key)
        if value is None:
            return tuple(tuple(sp.Integer(0) for _ in range(6)) for _ in end_effectors)
        if not isinstance(value, list) or not value:
            raise self.error(key, f"expected a 6-vector (moment, force) or one per ee, got {describe_value(value)}")
        if isinstance(value[0], list):
            if len(value) != len(end_effectors):
                raise self.error(key, f"expected {len(end_effectors)} wrenches (one per ee), got {len(value)}")
            return tuple(tuple(self.vector(w, 6, f"{key}[{i}]")) for i, w in enumerate(value))
        w = tuple(self.vector(value, 6, key))
        if not end_effectors and any(not e.is_zero for e in w):
            raise self.error(key, "a wrench needs an end-effector, but the description has no ee")
        return tuple(w for _ in end_effectors)


def _default_name(source: str) -> str:
    return "robot" if source.startswith("<") else Path(source).stem
