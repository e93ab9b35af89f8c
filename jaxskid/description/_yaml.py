"""Robot descriptions in Skidy's YAML/JSON schema: reader and writer.

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
    ``mass_inertia`` (required): per body, a 6x6 matrix ``[[I_o, m c~], [-m c~, m 1]]`` or
    ``{mass, inertia, com, frame}``. ``inertia`` is a 3x3 matrix, six values (Ixx, Ixy, Ixz, Iyy, Iyz, Izz),
    ``{Ixx: .., Iyz: ..}`` (missing entries are 0), a scalar (times the identity) or ``{index, pointmass}``
    (symbols Ixx<index>.. or I<index> times the identity). ``frame: body`` (the default, as Skidy's
    ``mass_matrix_mixed_data``) means the inertia is about the body frame's origin; ``frame: com`` means
    it is about the centre of mass (the parallel-axis theorem moves it, as ``mass_matrix_URDF_data``).
    ``parent`` (1-based, 0 = world; each parent must come before its child), ``support`` (root-to-body
    paths) and ``child``: the tree; ``support`` and ``child`` are checked against ``parent``.
    ``gravity`` (or ``gravity_vector``, required): see below.
    ``q``, ``qd``, ``q2d``, ``q3d``, ``q4d``: symbol names; the ``q`` names become the joint names.
    ``WEE``, ``WDEE``, ``W2DEE``: end-effector wrenches and their time derivatives (:func:`read_extras`).
    ``assignments``: parameter name -> number (an expression of numbers such as ``pi/2`` is allowed).

jaxskid keys
    ``name`` (default: the file stem), ``base`` (the world link's name, default ``world``),
    ``joint_names``, ``link_names`` (default ``link1``..), ``ee_names`` (default ``ee`` or ``ee1``..),
    ``frames: [{name, parent, pose}]`` (named frames that are not end-effectors, ``parent`` as
    ``ee_parent``), ``frame_order`` (the order of all named frames, written only when it is not
    end-effectors first), ``lock`` (joint name -> position, see :meth:`Robot.lock`).

Gravity. Skidy builds the base acceleration as ``Vd_0 = (0, -gravity_vector)`` and adds
``Q_grav = J^T Mb U Vd_0`` to ``M q2d + C qd`` (``src/skidy/kinematics_generator.py``), and its templates and
tutorial write ``gravity: [0, 0, -g]`` "in negative z0-direction". So ``gravity`` is the physical
gravitational acceleration, the same convention as :attr:`Robot.gravity`, and it is taken as it is. (Skidy
releases before that change used ``Vd_0 = (0, gravity_vector)`` and wrote ``[0, 0, g]``; such files must
flip the sign.)

Strings are parsed by :func:`jaxskid._model.to_expr` after a check that they contain only arithmetic;
decimal literals become double-precision floats. The writer emits the body-fixed representation with 6x6
inertias, integers and floats as YAML numbers (floats with ``repr`` precision) and other entries as SymPy
strings, so that ``parse_description(robot_to_dict(robot)) == robot``.
"""

from __future__ import annotations

import json
import keyword
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sympy as sp
import yaml
from sympy.core.function import AppliedUndef
from sympy.printing.str import StrPrinter

from ..model import _lie as lie
from .._errors import ModelError
from ..model._robot import Frame, Joint, Robot, spatial_to_body, symbol, to_expr

_SKIDY_KEYS = (
    "joint_screw_coord", "body_ref_config", "representation", "ee", "ee_parent", "mass_inertia", "parent",
    "support", "child", "gravity", "gravity_vector", "q", "qd", "q2d", "q3d", "q4d", "WEE", "WDEE", "W2DEE",
    "assignments",
)
_JAXSKID_KEYS = ("name", "base", "joint_names", "link_names", "ee_names", "frames", "frame_order", "lock")
_SUFFIXES = (".yaml", ".yml", ".json")
_DERIVATIVES = ("q", "qd", "q2d", "q3d", "q4d")
_WRENCHES = ("WEE", "WDEE", "W2DEE")
_INERTIA_KEYS = ("Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")
_TOL = 1e-6
_LARGEST = 1e30  # larger numbers are mistakes in any unit system, and overflow the numeric checks
_ARITHMETIC = re.compile(r"[A-Za-z0-9_+\-*/^().,\s]*")
_DECIMAL = re.compile(r"(\d+\.\d*|\.\d+)([eE][+-]?\d+)?")


@dataclass(frozen=True)
class DescriptionExtras:
    """What a description gives beyond the :class:`Robot`: symbol names and end-effector wrenches.

    ``q``..``q4d``: the names of the joint positions and their time derivatives (n each; Skidy's defaults
    ``d<q>``, ``dd<q>``.. when absent). ``wrench``, ``wrench_d``, ``wrench_2d``: one 6-vector
    ``(moment, force)`` per end-effector (``WEE``, ``WDEE``, ``W2DEE``; zeros when absent), acting on the
    end-effector's parent body in that body's frame, as in Skidy: ``Q = M q2d + C qd + Q_grav + J_p^T W``.
    """

    q: tuple[str, ...]
    qd: tuple[str, ...]
    q2d: tuple[str, ...]
    q3d: tuple[str, ...]
    q4d: tuple[str, ...]
    end_effectors: tuple[str, ...]
    wrench: tuple[tuple[sp.Expr, ...], ...]
    wrench_d: tuple[tuple[sp.Expr, ...], ...]
    wrench_2d: tuple[tuple[sp.Expr, ...], ...]


# ---------------------------------------------------------------------------------------------- reading
def read_description(path, *, lock: Mapping[str, float] | None = None) -> Robot:
    """The robot described by a ``.yaml``, ``.yml`` or ``.json`` file in Skidy's schema.

    ``lock`` (joint name -> position) is merged over the file's own ``lock`` key. Every problem with the
    file raises :class:`ModelError` naming the file, the key path and what was expected.
    """
    path = Path(path)
    return parse_description(_load(path), source=str(path), lock=lock)


def parse_description(data: Mapping, *, source: str = "<dict>", lock: Mapping[str, float] | None = None) -> Robot:
    """The robot described by an already loaded mapping; ``source`` names it in error messages."""
    parsed = _Parser(data, source).parse()
    try:
        robot = Robot.create(parsed.name, parsed.joints, parsed.gravity, parsed.frames, parsed.end_effectors,
                             parsed.defaults, parsed.base)
    except ModelError as exc:
        raise _relocate(exc, parsed.keys, source) from None
    except (ArithmeticError, np.linalg.LinAlgError) as exc:  # numeric checks on extreme default values
        raise ModelError(f"cannot check the model numerically with the default values ({exc})", source=source) from None
    locked = {**parsed.lock, **(lock or {})}
    if not locked:
        return robot
    try:
        return robot.lock(locked)
    except ModelError as exc:
        raise exc.located(source=source) from None


def read_extras(path) -> DescriptionExtras:
    """The symbol names and end-effector wrenches of a description file (see :class:`DescriptionExtras`)."""
    path = Path(path)
    return parse_extras(_load(path), source=str(path))


def parse_extras(data: Mapping, *, source: str = "<dict>") -> DescriptionExtras:
    """:func:`read_extras` for an already loaded mapping; the whole description is validated."""
    return _Parser(data, source).parse().extras


def _load(path: Path):
    source = str(path)
    if path.suffix.lower() not in _SUFFIXES:
        raise ModelError(f"expected a .yaml, .yml or .json file, got {path.suffix or 'no extension'!r}", source=source)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ModelError(f"cannot read the file: {exc.strerror or exc}", source=source) from exc
    if b"\x00" in raw:
        raise ModelError("expected a text file (YAML or JSON), found binary data", source=source)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ModelError(f"expected UTF-8 text, found an invalid byte at offset {exc.start}", source=source) from None
    if not text.strip():
        raise ModelError("the file is empty; expected a robot description", source=source)
    try:
        if path.suffix.lower() == ".json":
            data = json.loads(text, object_pairs_hook=_json_object)
        else:
            data = yaml.load(text, Loader=_Loader)  # a SafeLoader that also rejects duplicate keys
    except json.JSONDecodeError as exc:
        raise ModelError(f"line {exc.lineno}, column {exc.colno}: invalid JSON: {exc.msg}", source=source) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        raise ModelError(f"{where}invalid YAML: {exc.problem or exc.context}", source=source) from None
    except yaml.YAMLError as exc:
        raise ModelError(f"invalid YAML: {exc}", source=source) from None
    except ModelError as exc:
        raise exc.located(source=source) from None
    if data is None:
        raise ModelError("the file is empty; expected a robot description", source=source)
    return data


class _Loader(yaml.SafeLoader):
    pass


def _yaml_mapping(loader, node, deep=False):
    loader.flatten_mapping(node)
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        try:
            duplicate = key in seen
        except TypeError:  # unhashable: construct_mapping reports it
            continue
        if duplicate:
            raise yaml.constructor.ConstructorError(
                "while reading a mapping", node.start_mark, f"duplicate key {key!r}", key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep=deep)


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _yaml_mapping)


def _json_object(pairs):
    out = {}
    for key, value in pairs:
        if key in out:
            raise ModelError(f"invalid JSON: duplicate key {key!r}")
        out[key] = value
    return out


@dataclass(frozen=True)
class _Parsed:
    name: str
    base: str
    joints: list
    gravity: list
    frames: list
    end_effectors: list
    defaults: dict
    lock: dict
    extras: DescriptionExtras
    keys: dict  # where-prefix in the Robot -> key path in the description


class _Parser:
    """One pass over a description mapping; every check reports the key path of what it reads."""

    def __init__(self, data, source: str):
        self.data = data
        self.source = source
        self.numeric: dict = {}  # parameter symbol -> default value, for numeric checks
        self.reserved: dict[str, str] = {}  # joint-variable name -> key defining it

    def error(self, where, message) -> ModelError:
        return ModelError(message, where=where, source=self.source)

    # ------------------------------------------------------------------ the whole description
    def parse(self) -> _Parsed:
        d = self.data
        if not isinstance(d, Mapping):
            raise self.error(None, f"expected a mapping of keys at the top level, got {_describe(d)}")
        allowed = _SKIDY_KEYS + _JAXSKID_KEYS
        for key in d:
            if key not in allowed:
                raise self.error(None, f"unknown key {key!r}; expected one of {', '.join(allowed)}")
        for key in ("joint_screw_coord", "body_ref_config", "mass_inertia"):
            if key not in d:
                raise self.error(key, "required key is missing" + (
                    " (the 6x6 mass-inertia matrix of every body; jaxskid does not assume massless bodies)"
                    if key == "mass_inertia" else ""))
        screws_in = d["joint_screw_coord"]
        if not isinstance(screws_in, list) or not screws_in:
            raise self.error("joint_screw_coord", f"expected a non-empty list (one entry per joint), got {_describe(screws_in)}")
        n = len(screws_in)

        names = {key: self.names(key, n, identifiers=True) for key in _DERIVATIVES}
        joint_names = self.names("joint_names", n, identifiers=False)
        joint_key = "joint_names" if joint_names else "q"
        joint_names = joint_names or names["q"] or [f"q{i + 1}" for i in range(n)]
        for key, values in [*names.items(), (joint_key, joint_names)]:
            for i, v in enumerate(values or ()):
                self.reserved.setdefault(v, f"{key}[{i}]")
        link_names = self.names("link_names", n, identifiers=False) or [f"link{i + 1}" for i in range(n)]
        base = self.name_value(d.get("base", "world"), "base")
        if base in link_names:
            raise self.error(f"link_names[{link_names.index(base)}]", f"{base!r} is already the name of the base")
        defaults = self.assignments()
        gravity = self.gravity()
        representation = d.get("representation", "spatial")
        if representation not in ("spatial", "body_fixed"):
            raise self.error("representation", f"expected spatial or body_fixed, got {_describe(representation)}")
        parents = self.tree(n)

        poses_in = self.entries("body_ref_config", n)
        inertias_in = self.entries("mass_inertia", n)
        typed = [self.screw(s, f"joint_screw_coord[{i}]") for i, s in enumerate(screws_in)]
        poses = [self.pose(p, f"body_ref_config[{i}]") for i, p in enumerate(poses_in)]
        inertias = [self.mass_inertia(m, f"mass_inertia[{i}]") for i, m in enumerate(inertias_in)]
        screws = [s for _, s in typed]
        if representation == "spatial":
            screws, poses = spatial_to_body(screws, poses, parents)
        joints = [Joint(joint_names[i], typed[i][0], parents[i], poses[i], screws[i], inertias[i], link_names[i])
                  for i in range(n)]

        frames, frame_keys, ees = self.frames(n, link_names, base)
        keys = {"joints": {"name": joint_key, "link": "link_names", "parent": "parent", "screw": "joint_screw_coord",
                           "origin": "body_ref_config", "inertia": "mass_inertia"},
                "frames": frame_keys}
        extras = self.extras(names, joint_names, ees)
        name = self.name_value(d.get("name", _default_name(self.source)), "name")
        return _Parsed(name, base, joints, gravity, frames, ees, defaults, self.lock(), extras, keys)

    # ------------------------------------------------------------------ scalars, vectors, matrices
    def scalar(self, value, where) -> sp.Expr:
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise self.error(where, f"expected a number or an expression, got {_describe(value)}")
        if isinstance(value, str) and (not value.strip() or not _ARITHMETIC.fullmatch(value) or "__" in value
                                       or "." in _DECIMAL.sub("", value)):
            raise self.error(where, f"expected an arithmetic expression of numbers and parameter names, got {value!r}")
        try:
            expr = to_expr(value, where=where)
        except ModelError as exc:
            raise exc.located(source=self.source) from None
        except Exception as exc:  # noqa: BLE001 - sympify fails in many ways on malformed text
            raise self.error(where, f"cannot parse {value!r} as an expression ({type(exc).__name__})") from None
        floats = {f: sp.Float(float(f)) for f in expr.atoms(sp.Float) if f._prec != 53}
        expr = expr.xreplace(floats) if floats else expr
        if expr.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
            raise self.error(where, f"expected a finite value, got {value!r}")
        functions = sorted(str(f.func) for f in expr.atoms(AppliedUndef))
        if functions:
            raise self.error(where, f"unknown function {functions[0]!r} in {value!r}")
        for s in expr.free_symbols:
            if s.name.lower() in ("inf", "infinity", "nan"):
                raise self.error(where, f"expected a finite value, got {value!r}")
            if s.name in self.reserved:
                raise self.error(where, f"{s.name!r} is a joint variable ({self.reserved[s.name]}); it cannot be a parameter")
        if not expr.free_symbols:
            if expr.is_extended_real is False:
                raise self.error(where, f"expected a real value, got {value!r}")
            try:
                x = float(expr)
            except (TypeError, ValueError, OverflowError):
                x = math.inf
            if not math.isfinite(x):
                raise self.error(where, f"expected a finite real value, got {value!r}")
            if abs(x) > _LARGEST:
                raise self.error(where, f"expected a magnitude of at most {_LARGEST:g} (check the units), got {value!r}")
        return expr

    def vector(self, value, size, where) -> list:
        if not isinstance(value, list):
            raise self.error(where, f"expected a list of {size} values, got {_describe(value)}")
        if len(value) != size:
            raise self.error(where, f"expected {size} values, got {len(value)}")
        return [self.scalar(v, f"{where}[{k}]") for k, v in enumerate(value)]

    def matrix(self, value, rows, cols, where) -> sp.Matrix:
        if not isinstance(value, list) or not all(isinstance(r, list) for r in value):
            raise self.error(where, f"expected a {rows}x{cols} matrix (a list of {rows} rows), got {_describe(value)}")
        if len(value) != rows:
            raise self.error(where, f"expected a {rows}x{cols} matrix with {rows} rows, got {len(value)} rows")
        return sp.Matrix([self.vector(r, cols, f"{where}[{k}]") for k, r in enumerate(value)])

    def mapping(self, value, where, allowed, required=()) -> Mapping:
        if not isinstance(value, Mapping):
            raise self.error(where, f"expected a mapping with keys {', '.join(allowed)}, got {_describe(value)}")
        for key in value:
            if key not in allowed:
                raise self.error(where, f"unknown key {key!r}; expected one of {', '.join(allowed)}")
        for key in required:
            if key not in value:
                raise self.error(f"{where}.{key}", "required key is missing")
        return value

    def entries(self, key, n) -> list:
        value = self.data[key]
        if not isinstance(value, list):
            raise self.error(key, f"expected a list with one entry per joint, got {_describe(value)}")
        if len(value) != n:
            raise self.error(key, f"expected {n} entries (one per joint in joint_screw_coord), got {len(value)}")
        return value

    def name_value(self, value, where) -> str:
        if not isinstance(value, str) or not value.strip():
            raise self.error(where, f"expected a non-empty name, got {_describe(value)}")
        return value

    def names(self, key, n, *, identifiers) -> list[str] | None:
        value = self.data.get(key)
        if value is None:
            return None
        if not isinstance(value, list):
            raise self.error(key, f"expected a list of {n} names, got {_describe(value)}")
        if len(value) != n:
            raise self.error(key, f"expected {n} names (one per joint in joint_screw_coord), got {len(value)}")
        for i, v in enumerate(value):
            self.name_value(v, f"{key}[{i}]")
            if identifiers and (not v.isidentifier() or keyword.iskeyword(v)):
                raise self.error(f"{key}[{i}]", f"expected a symbol name (letters, digits, _), got {v!r}")
            if v in value[:i]:
                raise self.error(f"{key}[{i}]", f"duplicate name {v!r} (also {key}[{value.index(v)}])")
        return list(value)

    def num(self, expr) -> float | None:
        """The value of ``expr`` with the parameters' default values, or None if some have none."""
        e = expr.xreplace(self.numeric) if expr.free_symbols else expr
        if e.free_symbols:
            return None
        try:
            return float(e)
        except (TypeError, ValueError, OverflowError):
            return None

    def check_unit(self, vec, where, what) -> None:
        values = [self.num(e) for e in vec]
        if None not in values:
            norm = math.sqrt(sum(x * x for x in values))
            if abs(norm - 1.0) > _TOL:
                raise self.error(where, f"expected a unit {what}, got norm {norm:.6g}")

    def check_rotation(self, r, where) -> None:
        values = [self.num(e) for e in r]
        if None in values:
            return
        a = np.array(values, dtype=float).reshape(3, 3)
        if not np.allclose(a.T @ a, np.eye(3), atol=_TOL, rtol=0) or np.linalg.det(a) < 0:
            raise self.error(where, f"expected a rotation matrix (orthonormal, determinant +1), got {a.round(6).tolist()}")

    # ------------------------------------------------------------------ top-level entries
    def assignments(self) -> dict[str, float]:
        value = self.data.get("assignments", {})
        if not isinstance(value, Mapping):
            raise self.error("assignments", f"expected a mapping of parameter names to numbers, got {_describe(value)}")
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
        self.numeric = {symbol(k): sp.Float(v) for k, v in out.items()}
        return out

    def gravity(self) -> list:
        d = self.data
        if "gravity" in d and "gravity_vector" in d:
            raise self.error("gravity", "give either gravity or gravity_vector, not both")
        key = "gravity" if "gravity" in d or "gravity_vector" not in d else "gravity_vector"
        if key not in d:
            raise self.error("gravity", "required key is missing (the gravitational acceleration in the world frame, "
                                        "e.g. [0, 0, -g] when z points up)")
        return self.vector(d[key], 3, key)

    def tree(self, n) -> list[int]:
        """0-based parent indices (-1 = world) from ``parent``, or from ``support``, checked for consistency."""
        d = self.data
        support = d.get("support")
        if support is not None:
            if not isinstance(support, list) or len(support) != n:
                raise self.error("support", f"expected {n} lists (one per joint), got {_describe(support)}")
            for i, s in enumerate(support):
                if not isinstance(s, list) or not s or not all(_is_int(b) and 1 <= b <= n for b in s):
                    raise self.error(f"support[{i}]", f"expected a non-empty list of body indices in 1..{n}, got {_describe(s)}")
                if s[-1] != i + 1:
                    raise self.error(f"support[{i}]", f"expected the path from the root to body {i + 1}, ending with {i + 1}, got {s}")
        if "parent" in d:
            key, given = "parent", d["parent"]
            if not isinstance(given, list) or len(given) != n:
                raise self.error("parent", f"expected {n} body indices (one per joint), got {_describe(given)}")
            for i, p in enumerate(given):
                if not _is_int(p) or not 0 <= p <= n:
                    raise self.error(f"parent[{i}]", f"expected a body index in 0..{n} (0 is the world), got {_describe(p)}")
        elif support is not None:
            key, given = "support", [s[-2] if len(s) > 1 else 0 for s in support]
        else:
            key, given = "parent", list(range(n))
        for i in range(n):  # a chain of parents that comes back to a body is a cycle
            chain, body = [], i + 1
            while body != 0 and body not in chain:
                chain.append(body)
                body = given[body - 1]
            if body != 0:
                loop = " -> ".join(f"body {b}" for b in [*chain[chain.index(body):], body])
                raise self.error(key, f"the parent indices form a cycle: {loop}")
        for i, p in enumerate(given):
            if p > i + 1:
                raise self.error(f"{key}[{i}]", f"body {i + 1}'s parent is body {p}, which comes after it; list every "
                                                f"body after its parent (1-based, 0 is the world)")
        paths = []
        for i in range(n):
            path = [i + 1]
            while given[path[0] - 1] != 0:
                path.insert(0, given[path[0] - 1])
            paths.append(path)
        if support is not None:
            for i, s in enumerate(support):
                if s != paths[i]:
                    raise self.error(f"support[{i}]", f"expected {paths[i]} (the bodies from the root to body {i + 1} "
                                                      f"given by {key}), got {s}")
        child = d.get("child")
        if child is not None:
            if not isinstance(child, list) or len(child) != n:
                raise self.error("child", f"expected {n} lists (one per joint), got {_describe(child)}")
            for i, c in enumerate(child):
                expected = [k + 1 for k in range(n) if given[k] == i + 1]
                if not isinstance(c, list) or not all(_is_int(b) for b in c) or sorted(c) != expected:
                    raise self.error(f"child[{i}]", f"expected {expected} (the bodies whose parent is body {i + 1}), "
                                                    f"got {_describe(c) if not isinstance(c, list) else c}")
        return [p - 1 for p in given]

    def screw(self, value, where) -> tuple[str, tuple]:
        if isinstance(value, list):
            s = self.vector(value, 6, where)
            w, v = s[:3], s[3:]
            if all(e.is_zero is True for e in w):
                self.check_unit(v, where, "translation axis (omega = 0: a prismatic joint)")
                return "prismatic", tuple(s)
            self.check_unit(w, where, "rotation axis omega")
            values = [self.num(e) for e in s]
            if None not in values and abs(np.dot(values[:3], values[3:])) > _TOL:
                raise self.error(where, f"expected a revolute screw (omega . v = 0) or a prismatic one (omega = 0), got "
                                        f"omega . v = {np.dot(values[:3], values[3:]):.6g} (a helical joint)")
            return "revolute", tuple(s)
        d = self.mapping(value, where, ("type", "axis", "vec"), required=("type", "axis"))
        jtype = d["type"]
        if jtype not in ("revolute", "prismatic"):
            raise self.error(f"{where}.type", f"unknown joint type {jtype!r}; expected revolute or prismatic")
        axis = self.vector(d["axis"], 3, f"{where}.axis")
        self.check_unit(axis, f"{where}.axis", "axis")
        if jtype == "prismatic":
            if "vec" in d:
                raise self.error(f"{where}.vec", "a prismatic joint takes no vec (a point on the axis); remove it")
            return "prismatic", (0, 0, 0, *axis)
        vec = self.vector(d.get("vec", [0, 0, 0]), 3, f"{where}.vec")
        return "revolute", tuple(lie.screw("revolute", axis, vec))

    def pose(self, value, where) -> sp.Matrix:
        if isinstance(value, list):
            m = self.matrix(value, 4, 4, where)
            if not all((m[3, k] - (1 if k == 3 else 0)).is_zero for k in range(4)):
                raise self.error(f"{where}[3]", f"expected the last row of a pose to be [0, 0, 0, 1], got {list(m[3, :])}")
            m[3, :] = sp.Matrix([[0, 0, 0, 1]])
            self.check_rotation(m[:3, :3], where)
            return m
        d = self.mapping(value, where, ("rotation", "translation", "xyzrpy"))
        if "xyzrpy" in d:
            if len(d) > 1:
                raise self.error(where, "xyzrpy cannot be combined with rotation or translation")
            return sp.Matrix(lie.pose_xyzrpy(*self.vector(d["xyzrpy"], 6, f"{where}.xyzrpy")))
        r = self.rotation(d["rotation"], f"{where}.rotation") if "rotation" in d else None
        t = self.vector(d["translation"], 3, f"{where}.translation") if "translation" in d else None
        return sp.Matrix(lie.pose(r, t))

    def rotation(self, value, where) -> sp.Matrix:
        if isinstance(value, list):
            r = self.matrix(value, 3, 3, where)
            self.check_rotation(r, where)
            return r
        d = self.mapping(value, where, ("Q", "rpy", "axis", "angle"))
        forms = [k for k in ("Q", "rpy", "axis") if k in d]
        if len(forms) != 1 or ("angle" in d and "axis" not in d):
            raise self.error(where, f"expected exactly one of Q, rpy or axis (with angle), got {', '.join(d) or 'none'}")
        if "Q" in d:
            quaternion = self.vector(d["Q"], 4, f"{where}.Q")
            self.check_unit(quaternion, f"{where}.Q", "quaternion [w, x, y, z] (write exact values such as sqrt(2)/2)")
            return lie.rot_quaternion(*quaternion)
        if "rpy" in d:
            return lie.rot_rpy(*self.vector(d["rpy"], 3, f"{where}.rpy"))
        axis = self.vector(d["axis"], 3, f"{where}.axis")
        self.check_unit(axis, f"{where}.axis", "rotation axis")
        return lie.rot_axis_angle(axis, self.scalar(d.get("angle", 0), f"{where}.angle"))

    def mass_inertia(self, value, where) -> sp.Matrix:
        if isinstance(value, list):
            m6 = self.matrix(value, 6, 6, where)
            self.check_mass_inertia(m6, where)
            return m6
        d = self.mapping(value, where, ("mass", "inertia", "com", "frame"), required=("mass",))
        mass = self.scalar(d["mass"], f"{where}.mass")
        m = self.num(mass)
        if m is not None and m < 0:
            raise self.error(f"{where}.mass", f"expected a non-negative mass, got {m:.6g}")
        com = self.vector(d.get("com", [0, 0, 0]), 3, f"{where}.com")
        inertia = self.inertia(d.get("inertia", 0), f"{where}.inertia")
        frame = d.get("frame", "body")
        if frame not in ("body", "com"):
            raise self.error(f"{where}.frame", f"expected body (inertia about the body frame's origin) or com "
                                               f"(about the centre of mass), got {_describe(frame)}")
        return sp.Matrix(lie.spatial_inertia(mass, com, inertia, about="com" if frame == "com" else "origin"))

    def inertia(self, value, where) -> sp.Matrix:
        if isinstance(value, list) and value and all(isinstance(r, list) for r in value):
            i3 = self.matrix(value, 3, 3, where)
            for r, c in ((0, 1), (0, 2), (1, 2)):
                if not sp.expand(i3[r, c] - i3[c, r]).is_zero:
                    raise self.error(where, f"expected a symmetric 3x3 inertia; entries [{r}][{c}] and [{c}][{r}] differ")
            return i3
        if isinstance(value, list):
            if len(value) != 6 or any(isinstance(v, (list, Mapping)) for v in value):
                raise self.error(where, f"expected 6 values, got {len(value)} (Ixx, Ixy, Ixz, Iyy, Iyz, Izz), or a 3x3 matrix")
            return lie.inertia_matrix(self.vector(value, 6, where))
        if isinstance(value, Mapping) and ("index" in value or "pointmass" in value):
            d = self.mapping(value, where, ("index", "pointmass"), required=("index",))
            index, pointmass = d["index"], d.get("pointmass", False)
            if isinstance(index, bool) or not isinstance(index, (int, str)) or not f"Ixx{index}".isidentifier():
                raise self.error(f"{where}.index", f"expected an integer or a name suffix, got {_describe(index)}")
            if not isinstance(pointmass, bool):
                raise self.error(f"{where}.pointmass", f"expected true or false, got {_describe(pointmass)}")
            if pointmass:
                return self.scalar(f"I{index}", f"{where}.index") * sp.eye(3)
            return lie.inertia_matrix([self.scalar(f"{k}{index}", f"{where}.index") for k in _INERTIA_KEYS])
        if isinstance(value, Mapping):
            d = self.mapping(value, where, _INERTIA_KEYS)
            return lie.inertia_matrix([self.scalar(d.get(k, 0), f"{where}.{k}") for k in _INERTIA_KEYS])
        return self.scalar(value, where) * sp.eye(3)

    def check_mass_inertia(self, m6, where) -> None:
        """The structure [[I_o, m c~], [-m c~, m 1]] of a 6x6 mass-inertia matrix; Robot checks the values."""
        def differ(a, b):
            return not sp.expand(a - b).is_zero

        for r in range(6):
            for c in range(r + 1, 6):
                if differ(m6[r, c], m6[c, r]):
                    raise self.error(where, f"expected a symmetric 6x6 matrix; entries [{r}][{c}] and [{c}][{r}] differ")
        for r in range(3):
            for c in range(3):
                if differ(m6[3 + r, 3 + c], m6[5, 5] if r == c else 0):
                    raise self.error(where, f"expected the lower-right 3x3 block to be mass * identity; entry [{3 + r}][{3 + c}] is not")
            for c in range(r, 3):
                if differ(m6[r, 3 + c], -m6[c, 3 + r]):
                    raise self.error(where, f"expected the upper-right 3x3 block to be skew-symmetric (m c~); "
                                            f"entry [{r}][{3 + c}] is not")
        m = self.num(m6[5, 5])
        if m is not None and m < 0:
            raise self.error(where, f"expected a non-negative mass (entry [5][5]), got {m:.6g}")

    def frames(self, n, link_names, base) -> tuple[list[Frame], list[str], list[str]]:
        """Named frames (end-effectors first, then ``frames``), their key paths, and the end-effector names."""
        ees = self.end_effector_entries(n)
        taken = {base: "base", **{nm: f"link_names[{i}]" for i, nm in enumerate(link_names)}}
        bodies = {base: 0, **{nm: i + 1 for i, nm in enumerate(link_names)}}  # 1-based, 0 = world
        frames, keys = [], []
        for i, (name, parent, pose, key) in enumerate(ees + self.frame_entries(n)):
            if i < len(ees) and bodies.get(name) == parent and (pose - sp.eye(4)).is_zero_matrix:
                continue  # the end-effector is a body's own frame (or the base's)
            if name in taken:
                raise self.error(key, f"duplicate frame name {name!r} (also {taken[name]})")
            taken[name] = key
            frames.append(Frame(name, parent - 1, sp.ImmutableMatrix(pose)))
            keys.append(key)
        order = self.data.get("frame_order")
        if order is not None:
            names = [f.name for f in frames]
            if not isinstance(order, list) or sorted(map(str, order)) != sorted(names) or len(order) != len(names):
                raise self.error("frame_order", f"expected the names {names} in some order, got {_describe(order)}")
            perm = [names.index(nm) for nm in order]
            frames, keys = [frames[j] for j in perm], [keys[j] for j in perm]
        return frames, keys, [name for name, *_ in ees]

    def end_effector_entries(self, n) -> list[tuple]:
        """(name, 1-based parent, pose, key path) of every ``ee``."""
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
            raise self.error("ee", f"expected a pose or a list of poses, got {_describe(ee)}")
        poses = [self.pose(ee, "ee")] if single else [self.pose(p, f"ee[{i}]") for i, p in enumerate(ee)]
        k = len(poses)
        parents = d.get("ee_parent", n)
        if isinstance(parents, list):
            if len(parents) != k:
                raise self.error("ee_parent", f"expected {k} body indices (one per ee), got {len(parents)}")
            parent_keys = [f"ee_parent[{i}]" for i in range(k)]
        else:
            parents, parent_keys = [parents] * k, ["ee_parent"] * k
        for p, key in zip(parents, parent_keys):
            if not _is_int(p) or not 0 <= p <= n:
                raise self.error(key, f"expected a body index in 0..{n} (0 is the world), got {_describe(p)}")
        names = d.get("ee_names")
        if names is None:
            names, name_keys = (["ee"] if k == 1 else [f"ee{i + 1}" for i in range(k)]), ["ee"] * k
        elif not isinstance(names, list) or len(names) != k:
            raise self.error("ee_names", f"expected {k} name(s), one per ee, got {_describe(names)}")
        else:
            name_keys = [f"ee_names[{i}]" for i in range(k)]
        return [(self.name_value(nm, key), p, pose, key) for nm, p, pose, key in zip(names, parents, poses, name_keys)]

    def frame_entries(self, n) -> list[tuple]:
        """(name, 1-based parent, pose, key path) of every entry of ``frames``."""
        value = self.data.get("frames", [])
        if not isinstance(value, list):
            raise self.error("frames", f"expected a list of {{name, parent, pose}}, got {_describe(value)}")
        out = []
        for i, f in enumerate(value):
            where = f"frames[{i}]"
            f = self.mapping(f, where, ("name", "parent", "pose"), required=("name", "parent"))
            if not _is_int(f["parent"]) or not 0 <= f["parent"] <= n:
                raise self.error(f"{where}.parent", f"expected a body index in 0..{n} (0 is the world), "
                                                    f"got {_describe(f['parent'])}")
            pose = self.pose(f["pose"], f"{where}.pose") if "pose" in f else sp.eye(4)
            out.append((self.name_value(f["name"], f"{where}.name"), f["parent"], pose, f"{where}.name"))
        return out

    def lock(self) -> dict:
        value = self.data.get("lock", {})
        if not isinstance(value, Mapping):
            raise self.error("lock", f"expected a mapping of joint names to positions, got {_describe(value)}")
        return {str(k): self.scalar(v, f"lock.{k}") for k, v in value.items()}

    def extras(self, names, joint_names, end_effectors) -> DescriptionExtras:
        q = names["q"] or joint_names
        derived = {key: tuple(names[key] or ["d" * k + v for v in q]) for k, key in enumerate(_DERIVATIVES)}
        wrenches = []
        for key in _WRENCHES:
            value = self.data.get(key)
            zero = tuple(sp.Integer(0) for _ in range(6))
            if value is None:
                wrenches.append(tuple(zero for _ in end_effectors))
                continue
            if not isinstance(value, list) or not value:
                raise self.error(key, f"expected a 6-vector (moment, force) or one per ee, got {_describe(value)}")
            if isinstance(value[0], list):
                if len(value) != len(end_effectors):
                    raise self.error(key, f"expected {len(end_effectors)} wrenches (one per ee), got {len(value)}")
                per_ee = tuple(tuple(self.vector(w, 6, f"{key}[{i}]")) for i, w in enumerate(value))
            else:
                w = tuple(self.vector(value, 6, key))
                if not end_effectors and any(not e.is_zero for e in w):
                    raise self.error(key, "a wrench needs an end-effector, but the description has no ee")
                per_ee = tuple(w for _ in end_effectors)
            wrenches.append(per_ee)
        return DescriptionExtras(*(derived[k] for k in _DERIVATIVES), tuple(end_effectors), *wrenches)


def _relocate(err: ModelError, keys: dict, source: str) -> ModelError:
    """A ModelError from Robot.create, with its ``joints[i].field`` path mapped back to the description's keys."""
    where = err.where or ""
    m = re.fullmatch(r"joints\[(\d+)\]\.(\w+)(.*)", where)
    if m and m.group(2) in keys["joints"]:
        return ModelError(err.message, where=f"{keys['joints'][m.group(2)]}[{m.group(1)}]{m.group(3)}", source=source)
    m = re.fullmatch(r"frames\[(\d+)\](.*)", where)
    if m and int(m.group(1)) < len(keys["frames"]):
        return ModelError(err.message, where=keys["frames"][int(m.group(1))], source=source)
    return err.located(source=source)


def _default_name(source: str) -> str:
    return "robot" if source.startswith("<") else Path(source).stem


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _describe(value) -> str:
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, (int, float)):
        return f"the number {value!r}"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, list):
        return f"a list of {len(value)} item{'s' if len(value) != 1 else ''}"
    if isinstance(value, Mapping):
        return f"a mapping with keys {', '.join(map(str, value)) or '(none)'}"
    return f"a {type(value).__name__}"


# ---------------------------------------------------------------------------------------------- writing
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
    if path.suffix.lower() not in _SUFFIXES:
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
