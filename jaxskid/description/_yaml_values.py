"""The value forms of Skidy's schema: scalars, vectors, matrices, poses, rotations, screws, inertias.

Each method reads one entry of a loaded description into SymPy and reports problems at the entry's key
path. It checks the entry's syntax (types, sizes, keys) and the forms that never reach the model as
written: a quaternion and an axis-angle axis (the model sees the rotation they give), the axis of a
``{type, axis, vec}`` screw, a 3x3 inertia, a ``mass`` key and the ``rotation`` of a COM frame (the model
sees the 6x6 matrix). It checks them with the model's own rules (:mod:`jaxskid.model._validate`);
everything else, poses, screws and 6x6 mass-inertia matrices as the model holds them, is left to
:meth:`Robot.create <jaxskid.Robot.create>`.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping

import sympy as sp

from .._errors import DescriptionWarning, ModelError
from ..model import _lie as lie
from ..model._validate import (
    check_mass, check_rotation, check_symmetric, check_unit, describe_value, numeric, symbol, to_expr,
)

INERTIA_KEYS = ("Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz")


class ValueReader:
    """Reads entries of the description named ``source``. The default parameter values
    (:meth:`set_defaults`) serve the checks that need numbers; a name in ``reserved`` (a joint variable ->
    the key that defines it) may not be a parameter."""

    def __init__(self, source: str = "<dict>"):
        self.source = source  # names the description in warnings
        self.values: dict = {}  # parameter symbol -> default value, for numeric checks
        self.reserved: dict[str, str] = {}

    def set_defaults(self, defaults: Mapping[str, float]) -> None:
        self.values = {symbol(k): sp.Float(v) for k, v in defaults.items()}

    @staticmethod
    def error(where, message) -> ModelError:
        return ModelError(message, where=where)

    # ------------------------------------------------------------------ scalars, vectors, matrices
    def scalar(self, value, where) -> sp.Expr:
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise self.error(where, f"expected a number or an expression, got {describe_value(value)}")
        expr = to_expr(value, where=where)
        for s in expr.free_symbols:
            if s.name in self.reserved:
                raise self.error(where, f"{s.name!r} is a joint variable ({self.reserved[s.name]}); it cannot be a parameter")
        return expr

    def vector(self, value, size, where) -> list:
        if not isinstance(value, list):
            raise self.error(where, f"expected a list of {size} values, got {describe_value(value)}")
        if len(value) != size:
            raise self.error(where, f"expected {size} values, got {len(value)}")
        return [self.scalar(v, f"{where}[{k}]") for k, v in enumerate(value)]

    def matrix(self, value, rows, cols, where) -> sp.Matrix:
        if not isinstance(value, list) or not all(isinstance(r, list) for r in value):
            raise self.error(where, f"expected a {rows}x{cols} matrix (a list of {rows} rows), got {describe_value(value)}")
        if len(value) != rows:
            raise self.error(where, f"expected a {rows}x{cols} matrix with {rows} rows, got {len(value)} rows")
        return sp.Matrix([self.vector(r, cols, f"{where}[{k}]") for k, r in enumerate(value)])

    def mapping(self, value, where, allowed, required=()) -> Mapping:
        if not isinstance(value, Mapping):
            raise self.error(where, f"expected a mapping with keys {', '.join(allowed)}, got {describe_value(value)}")
        for key in value:
            if key not in allowed:
                raise self.error(where, f"unknown key {key!r}; expected one of {', '.join(allowed)}")
        for key in required:
            if key not in value:
                raise self.error(f"{where}.{key}", "required key is missing")
        return value

    def per_joint(self, value, key: str, n: int, what: str, entry) -> list:
        """One ``entry(item, where, i)`` or ``None`` per joint from the list ``value`` under ``key`` (``None``:
        ``None`` for every joint; a ``null`` item: ``None`` for that joint); ``what`` names an item for the
        error of a list of the wrong length."""
        if value is None:
            return [None] * n
        if not isinstance(value, list) or len(value) != n:
            raise self.error(key, f"expected a list of {n} entries ({what} or null per joint), got {describe_value(value)}")
        return [None if item is None else entry(item, f"{key}[{i}]", i) for i, item in enumerate(value)]

    def name_value(self, value, where) -> str:
        if not isinstance(value, str) or not value.strip():
            raise self.error(where, f"expected a non-empty name, got {describe_value(value)}")
        return value

    # ------------------------------------------------------------------ poses and screws
    def pose(self, value, where) -> sp.Matrix:
        """A 4x4 matrix, ``{xyzrpy}`` or ``{rotation, translation}``."""
        if isinstance(value, list):
            return self.matrix(value, 4, 4, where)
        d = self.mapping(value, where, ("rotation", "translation", "xyzrpy"))
        if "xyzrpy" in d:
            if len(d) > 1:
                raise self.error(where, "xyzrpy cannot be combined with rotation or translation")
            return sp.Matrix(lie.pose_xyzrpy(*self.vector(d["xyzrpy"], 6, f"{where}.xyzrpy")))
        r = self.rotation(d["rotation"], f"{where}.rotation") if "rotation" in d else None
        t = self.vector(d["translation"], 3, f"{where}.translation") if "translation" in d else None
        return sp.Matrix(lie.pose(r, t))

    @staticmethod
    def rotation_key(value) -> str:
        """Where the rotation of a pose entry sits: ``.rotation`` in a ``{rotation, ...}`` mapping."""
        return ".rotation" if isinstance(value, Mapping) and "rotation" in value else ""

    def rotation(self, value, where) -> sp.Matrix:
        """A 3x3 matrix, ``{Q: [w, x, y, z]}``, ``{rpy}`` or ``{axis, angle}``."""
        if isinstance(value, list):
            return self.matrix(value, 3, 3, where)
        d = self.mapping(value, where, ("Q", "rpy", "axis", "angle"))
        forms = [k for k in ("Q", "rpy", "axis") if k in d]
        if len(forms) != 1 or ("angle" in d and "axis" not in d):
            raise self.error(where, f"expected exactly one of Q, rpy or axis (with angle), got {', '.join(d) or 'none'}")
        if "Q" in d:
            quaternion = self.vector(d["Q"], 4, f"{where}.Q")
            check_unit(quaternion, self.values, f"{where}.Q", "quaternion [w, x, y, z] (write exact values such as sqrt(2)/2)")
            return lie.rot_quaternion(*quaternion)
        if "rpy" in d:
            return lie.rot_rpy(*self.vector(d["rpy"], 3, f"{where}.rpy"))
        axis = self.vector(d["axis"], 3, f"{where}.axis")
        check_unit(axis, self.values, f"{where}.axis", "rotation axis")
        return lie.rot_axis_angle(axis, self.scalar(d.get("angle", 0), f"{where}.angle"))

    def screw(self, value, where) -> tuple[str, tuple]:
        """(joint type, screw): a 6-vector ``(omega, v)`` (prismatic if ``omega = 0``) or ``{type, axis, vec}``."""
        if isinstance(value, list):
            s = self.vector(value, 6, where)
            return ("prismatic" if all(e.is_zero is True for e in s[:3]) else "revolute"), tuple(s)
        d = self.mapping(value, where, ("type", "axis", "vec"), required=("type", "axis"))
        jtype = d["type"]
        if jtype not in ("revolute", "prismatic"):
            raise self.error(f"{where}.type", f"unknown joint type {jtype!r}; expected revolute or prismatic")
        axis = self.vector(d["axis"], 3, f"{where}.axis")
        check_unit(axis, self.values, f"{where}.axis", "axis")
        if jtype == "prismatic":
            if "vec" in d:
                raise self.error(f"{where}.vec", "a prismatic joint takes no vec (a point on the axis); remove it")
            return "prismatic", (0, 0, 0, *axis)
        vec = self.vector(d.get("vec", [0, 0, 0]), 3, f"{where}.vec")
        return "revolute", tuple(lie.screw("revolute", axis, vec))

    # ------------------------------------------------------------------ inertias
    def mass_inertia(self, value, where) -> sp.Matrix:
        """A 6x6 matrix or ``{mass, inertia, com, frame, rotation}``.

        With ``frame: com``, ``inertia`` is about the centre of mass in the axes of the COM frame, whose
        orientation in the body frame is ``rotation`` (default: the identity). As Skidy's
        ``mass_matrix_mixed_data``, it is turned into the body's axes, ``R I Rᵀ``, and then moved to the
        body origin by the parallel-axis theorem. With ``frame: body`` the inertia is already in the body
        frame; Skidy ignores a ``rotation`` there, and so does jaxskid, with a :class:`DescriptionWarning`.
        """
        if isinstance(value, list):
            return self.matrix(value, 6, 6, where)
        d = self.mapping(value, where, ("mass", "inertia", "com", "frame", "rotation"), required=("mass",))
        mass = self.scalar(d["mass"], f"{where}.mass")
        check_mass(numeric(mass, self.values), f"{where}.mass")
        com = self.vector(d.get("com", [0, 0, 0]), 3, f"{where}.com")
        inertia = self.inertia(d.get("inertia", 0), f"{where}.inertia")
        frame = d.get("frame", "body")
        if frame not in ("body", "com"):
            raise self.error(f"{where}.frame", f"expected body (inertia about the body frame's origin) or com "
                                               f"(about the centre of mass), got {describe_value(frame)}")
        if "rotation" in d and frame == "com":
            r = self.rotation(d["rotation"], f"{where}.rotation")
            check_rotation(r, self.values, f"{where}.rotation")
            inertia = r * inertia * r.T
        elif "rotation" in d:
            warnings.warn(f"{self.source}: {where}.rotation: ignored, as Skidy ignores it: rotation orients the "
                          f"COM frame and applies only with frame: com; with frame: body the inertia is already "
                          f"about the body origin in the body frame", DescriptionWarning, stacklevel=2)
        return sp.Matrix(lie.spatial_inertia(mass, com, inertia, about="com" if frame == "com" else "origin"))

    def inertia(self, value, where) -> sp.Matrix:
        """A 3x3 matrix, six values, ``{Ixx: .., Iyz: ..}``, ``{index, pointmass}`` or a scalar."""
        if isinstance(value, list) and value and all(isinstance(r, list) for r in value):
            i3 = self.matrix(value, 3, 3, where)
            check_symmetric(i3, where, "3x3 inertia")
            return i3
        if isinstance(value, list):
            if len(value) != 6 or any(isinstance(v, (list, Mapping)) for v in value):
                raise self.error(where, f"expected 6 values, got {len(value)} (Ixx, Ixy, Ixz, Iyy, Iyz, Izz), or a 3x3 matrix")
            return lie.inertia_matrix(self.vector(value, 6, where))
        if isinstance(value, Mapping) and ("index" in value or "pointmass" in value):
            return self.indexed_inertia(value, where)
        if isinstance(value, Mapping):
            d = self.mapping(value, where, INERTIA_KEYS)
            return lie.inertia_matrix([self.scalar(d.get(k, 0), f"{where}.{k}") for k in INERTIA_KEYS])
        return self.scalar(value, where) * sp.eye(3)

    def indexed_inertia(self, value, where) -> sp.Matrix:
        """``{index, pointmass}``: the symbols ``Ixx<index>``.. or ``I<index>`` times the identity."""
        d = self.mapping(value, where, ("index", "pointmass"), required=("index",))
        index, pointmass = d["index"], d.get("pointmass", False)
        if isinstance(index, bool) or not isinstance(index, (int, str)) or not f"Ixx{index}".isidentifier():
            raise self.error(f"{where}.index", f"expected an integer or a name suffix, got {describe_value(index)}")
        if not isinstance(pointmass, bool):
            raise self.error(f"{where}.pointmass", f"expected true or false, got {describe_value(pointmass)}")
        if pointmass:
            return self.scalar(f"I{index}", f"{where}.index") * sp.eye(3)
        return lie.inertia_matrix([self.scalar(f"{k}{index}", f"{where}.index") for k in INERTIA_KEYS])
