"""Denavit–Hartenberg tables: a robot from rows of (a, alpha, d, theta), converted exactly to the screw form.

Two conventions, each the pose ``T_i`` of DH frame i in frame i-1 as a product of elementary transforms:

* ``standard`` (Denavit & Hartenberg, J. Appl. Mech. 22, 1955; Spong, Hutchinson & Vidyasagar, "Robot
  Modeling and Control", 2006, eq. 3.10; Corke's ``DHRobot`` of ``RevoluteDH``/``PrismaticDH``)::

      T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)

* ``modified`` (Craig, "Introduction to Robotics", 1986, eq. 3.6; Corke's ``RevoluteMDH``/``PrismaticMDH``)::

      T_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)

  where row i of the table holds ``a_{i-1}, alpha_{i-1}, d_i, theta_i``, as Craig and Corke write it.

The joint variable ``q_i`` adds to ``theta_i`` (revolute) or ``d_i`` (prismatic). Body i's frame is DH frame
i, so its pose at q = 0 in its parent's frame is ``B_i = T_i`` with the table's theta and d (times the
table's ``base`` pose for a row that hangs from the world). With a tree (``parent``), row i is relative to
the frame of body i's parent.

The screw ``X_i`` of joint i in body i's frame, so that ``C_{p,i}(q_i) = B_i exp(X_i q_i)`` (Müller 2018,
sec. 2.3), written with ``Z = (0, 0, 1, 0, 0, 0)`` (rotation about z) and ``Z' = (0, 0, 0, 0, 0, 1)``
(translation along z), ``(omega, v)`` order:

* modified: the joint moves about (along) z_i, body i's own axis. ``Rz(q)`` and ``Tz(q)`` commute with
  ``Rz(theta) Tz(d)``, so ``T_i(q) = T_i Rz(q)`` (``T_i Tz(q)``) and ``X_i = Z`` (``Z'``).
* standard: the joint moves about (along) z_{i-1}, the axis of the parent's frame: ``T_i(q) = Rz(q) T_i``.
  Write ``T_i = S_i P_i`` with ``S_i = Rz(theta) Tz(d)``, which commutes with ``Rz(q)`` and ``Tz(q)``, and
  ``P_i = Tx(a) Rx(alpha)``; then ``Rz(q) S P = S P (P^-1 Rz(q) P) = B_i exp(Ad(P_i^-1) Z q)`` (Lynch & Park
  2017, Prop. 3.35: ``T exp([X] q) T^-1 = exp([Ad_T X] q)``), so ``X_i = Ad(P_i^-1) Z``: revolute
  ``(0, sin alpha, cos alpha, 0, a cos alpha, -a sin alpha)``, prismatic ``(0, 0, 0, 0, sin alpha, cos alpha)``.
  Neither theta nor d enters, and the entries are exact for numbers, ``pi/2`` and symbols alike.

Entries are numbers, expressions such as ``pi/2``, or names that become the robot's parameters (with
defaults from ``assignments`` or ``defaults``). A joint variable may not appear in a table: jaxskid adds
``q_i`` itself (see :func:`_check_constant`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields

import sympy as sp

from .._errors import ModelError
from ..model import _lie as lie
from ..model._robot import Frame, Joint, Robot
from ..model._validate import check_parents, check_pose, describe_value, to_expr
from ._keymap import KeyMap
from ._yaml_values import ValueReader

CONVENTIONS = ("standard", "modified")
ROW_KEYS = ("type", "a", "alpha", "d", "theta")
_MOVES = {"revolute": "theta", "prismatic": "d"}  # the entry the joint variable adds to


@dataclass(frozen=True)
class DH:
    """One row of a Denavit–Hartenberg table: the joint's type and its four parameters (all required).

    ``type``: ``"revolute"`` (``theta`` is the joint variable's offset) or ``"prismatic"`` (``d`` is);
    ``a``: the link length, ``alpha``: the link twist, ``d``: the link offset, ``theta``: the joint angle. In the ``modified`` convention ``a`` and ``alpha`` are Craig's ``a_{i-1}`` and ``alpha_{i-1}``. Entries are
    numbers, strings (``"pi/2"``, ``"a2"``) or SymPy expressions; angles in radians.
    """

    type: str
    a: object
    alpha: object
    d: object
    theta: object


# ---------------------------------------------------------------------------------------------- geometry
def _rot(axis: tuple, angle) -> sp.ImmutableMatrix:
    return lie.pose(lie.rot_axis_angle(axis, angle))


def _trans(axis: tuple, length) -> sp.ImmutableMatrix:
    return lie.pose(None, [sp.sympify(length) * e for e in axis])


_X, _Z = (1, 0, 0), (0, 0, 1)


def dh_transform(row: DH, convention: str) -> sp.ImmutableMatrix:
    """``T_i``: the pose of DH frame i in frame i-1 at q = 0 (exact; see the module docstring)."""
    screw_z = _rot(_Z, row.theta) * _trans(_Z, row.d)
    if convention == "standard":
        return sp.ImmutableMatrix(screw_z * _trans(_X, row.a) * _rot(_X, row.alpha))
    return sp.ImmutableMatrix(_rot(_X, row.alpha) * _trans(_X, row.a) * screw_z)


def dh_screw(row: DH, convention: str) -> tuple:
    """``X_i``: the unit screw ``(omega, v)`` of joint i in DH frame i (see the module docstring)."""
    z = (0, 0, 1, 0, 0, 0) if row.type == "revolute" else (0, 0, 0, 0, 0, 1)
    if convention == "modified":
        return tuple(sp.Integer(e) for e in z)
    p = _trans(_X, row.a) * _rot(_X, row.alpha)
    return tuple(lie.adjoint(lie.inverse(p)) * sp.Matrix(z))


def table_geometry(rows: Sequence[DH], convention: str, parents: Sequence[int], base=None
                   ) -> tuple[list[str], list[tuple], list[sp.ImmutableMatrix]]:
    """(types, screws X_i, reference poses B_i) of checked rows; ``parents`` 0-based (-1 the world); ``base``
    the pose of frame 0 in the world (default: the identity) for the rows that hang from the world."""
    base = sp.eye(4) if base is None else sp.Matrix(base)
    origins = [sp.ImmutableMatrix(base * dh_transform(r, convention)) if p < 0 else dh_transform(r, convention)
               for r, p in zip(rows, parents)]
    return [r.type for r in rows], [dh_screw(r, convention) for r in rows], origins


# ---------------------------------------------------------------------------------------------- reading rows
def check_convention(value, where: str) -> str:
    if value not in CONVENTIONS:
        got = repr(value) if isinstance(value, str) else describe_value(value)
        raise ModelError(f"unknown convention {got}; expected standard (Denavit-Hartenberg, Spong: "
                         f"Rz(theta) Tz(d) Tx(a) Rx(alpha)) or modified (Craig: Rx(alpha) Tx(a) Rz(theta) Tz(d))",
                         where=where)
    return value


def joint_variables(joint_names: Sequence[str]) -> dict[str, int]:
    """The names that stand for joint i's variable: ``q<i+1>`` and the joint's own name -> i."""
    out = {f"q{i + 1}": i for i in range(len(joint_names))}
    out.update({name: i for i, name in enumerate(joint_names)})
    return out


def read_rows(values, reader: ValueReader, where: str, variables: Mapping[str, int]) -> list[DH]:
    """Checked rows from a list of mappings (or :class:`DH` rows), each entry read by ``reader.scalar``;
    ``variables`` maps the names of joint variables to their joint's index."""
    if not isinstance(values, (list, tuple)) or not values:
        raise ModelError(f"expected a non-empty list of rows ({', '.join(ROW_KEYS)}), got {describe_value(values)}",
                         where=where)
    rows = []
    for i, value in enumerate(values):
        at = f"{where}[{i}]"
        if isinstance(value, DH):
            value = {f.name: getattr(value, f.name) for f in fields(DH)}
        row = reader.mapping(value, at, ROW_KEYS, required=ROW_KEYS)
        kind = row["type"]
        if kind not in _MOVES:
            got = repr(kind) if isinstance(kind, str) else describe_value(kind)
            raise ModelError(f"unknown joint type {got}; expected revolute or prismatic", where=f"{at}.type")
        entries = {}
        for key in ROW_KEYS[1:]:
            if isinstance(row[key], str):  # before the reader, whose message on a joint variable is generic
                _check_constant(to_expr(row[key], where=f"{at}.{key}"), key, kind, i, variables, f"{at}.{key}")
            entries[key] = reader.scalar(row[key], f"{at}.{key}")
            _check_constant(entries[key], key, kind, i, variables, f"{at}.{key}")
        rows.append(DH(kind, **entries))
    return rows


def _check_constant(expr, key: str, kind: str, i: int, variables: Mapping[str, int], where: str) -> None:
    """A DH entry holds constants and parameters, never a joint variable (``q<k>`` or a joint's name).

    jaxskid adds ``q_i`` to theta (revolute) or d (prismatic) itself, so a table that writes the variable in
    is inconsistent, in one of three ways: the joint's own variable in the entry it moves (``d: q3`` for a
    prismatic joint 3: q3 would be added twice), its own variable in an entry it does not move (``theta: q3``
    for that prismatic joint: the row's type and the table disagree), or another joint's variable.
    """
    for name in sorted(s.name for s in sp.sympify(expr).free_symbols):
        owner = variables.get(name)
        if owner is None:
            continue
        moves = _MOVES[kind]
        if owner != i:
            message = f"{name!r} is joint {owner + 1}'s variable; a DH entry holds numbers and parameters only"
        elif key == moves:
            message = (f"{name!r} is this joint's variable, which jaxskid adds to {key} of a {kind} joint; "
                       f"write {key} as its value at q = 0 (e.g. {key}: 0)")
        else:
            message = (f"{name!r} is this joint's variable, but a {kind} joint moves {moves}, not {key}; "
                       f"{key} holds a constant (or change the joint's type)")
        raise ModelError(message, where=where)


# ---------------------------------------------------------------------------------------------- YAML
def dh_size(block, reader: ValueReader) -> int:
    """The number of rows of the ``dh`` block of a description (its shape checked)."""
    d = reader.mapping(block, "dh", ("convention", "base", "joints"), required=("convention", "joints"))
    joints = d["joints"]
    if not isinstance(joints, list) or not joints:
        raise ModelError(f"expected a non-empty list (one row per joint), got {describe_value(joints)}", where="dh.joints")
    return len(joints)


def read_dh(block, reader: ValueReader, parents: Sequence[int], variables: Mapping[str, int]):
    """(types, screws, reference poses) of a description's ``dh`` block, in the body-fixed form.

    ``{convention: standard | modified, base: <pose>, joints: [{type, a, alpha, d, theta}, ...]}``; ``base``
    (any pose form of the schema, default the identity) is DH frame 0 in the world.
    """
    dh_size(block, reader)
    convention = check_convention(block["convention"], "dh.convention")
    base = reader.pose(block["base"], "dh.base") if "base" in block else None
    if base is not None:
        check_pose(base, reader.values, "dh.base" + reader.rotation_key(block["base"]))
    rows = read_rows(block["joints"], reader, "dh.joints", variables)
    return table_geometry(rows, convention, parents, base)


# ---------------------------------------------------------------------------------------------- Python
class _PythonValues(ValueReader):
    """Entries given in Python: numbers, strings or SymPy expressions."""

    def scalar(self, value, where) -> sp.Expr:
        return to_expr(value, where=where)


def dh_robot(
    name: str,
    rows: Sequence[DH | Mapping],
    inertias: Sequence,
    *,
    convention: str,
    gravity: Sequence = (0, 0, -9.81),
    base_pose=None,
    parents: Sequence[int] | None = None,
    joint_names: Sequence[str] | None = None,
    link_names: Sequence[str] | None = None,
    frames: Sequence[Frame] = (),
    end_effectors: Sequence[str] = (),
    defaults: Mapping[str, float] | None = None,
    base: str = "world",
) -> Robot:
    """A robot from a Denavit–Hartenberg table (the ``dh:`` block of a description, in Python).

    Args:
        name: the robot's name.
        rows: one :class:`DH` row (or a mapping with its keys) per joint, base to tip.
        inertias: per body, the 6x6 mass-inertia matrix in DH frame i (:func:`jaxskid.spatial_inertia`).
        convention: ``"standard"`` (``Rz(theta) Tz(d) Tx(a) Rx(alpha)``) or ``"modified"`` (Craig's
            ``Rx(alpha) Tx(a) Rz(theta) Tz(d)``); see :mod:`jaxskid.description._dh`.
        gravity, frames, end_effectors, defaults, base: as :meth:`Robot.create`; a frame's pose is in DH
            frame i of its body.
        base_pose: the 4x4 pose of DH frame 0 in the world (default: the identity).
        parents: 0-based parent body of each body (-1: the world); default: a serial chain.
        joint_names, link_names: default ``q1``.. and ``link1``..

    Raises:
        ModelError: at the argument's path, e.g. ``rows[2].d: expected a number or an expression, ...``.
    """
    n = len(rows) if isinstance(rows, (list, tuple)) else 0
    inertias = list(inertias)
    parents = list(range(-1, n - 1)) if parents is None else list(parents)
    joint_names = [f"q{i + 1}" for i in range(n)] if joint_names is None else list(joint_names)
    link_names = [f"link{i + 1}" for i in range(n)] if link_names is None else list(link_names)
    for key, given in (("inertias", inertias), ("parents", parents), ("joint_names", joint_names),
                       ("link_names", link_names)):
        if n and len(given) != n:
            raise ModelError(f"expected {n} entries (one per row), got {len(given)}", where=key)
    reader = _PythonValues("<python>")
    table = read_rows(rows, reader, "rows", joint_variables(joint_names))
    check_parents(parents, where=lambda i: f"parents[{i}]", where_all="parents")
    if base_pose is not None:
        given = base_pose.tolist() if hasattr(base_pose, "tolist") else base_pose  # SymPy or NumPy, or rows
        if isinstance(given, (list, tuple)):
            given = [list(r) if isinstance(r, (list, tuple)) else r for r in given]
        base_pose = reader.matrix(given, 4, 4, "base_pose")
        check_pose(base_pose, {}, "base_pose")
    types, screws, origins = table_geometry(table, check_convention(convention, "convention"), parents, base_pose)
    joints = [Joint(joint_names[i], types[i], parents[i], origins[i], screws[i], inertias[i], link_names[i])
              for i in range(n)]
    keys = KeyMap()
    for i in range(n):
        for part, key in (("origin", "rows"), ("screw", "rows"), ("inertia", "inertias"), ("name", "joint_names"),
                          ("link", "link_names"), ("parent", "parents")):
            keys.add(f"joints[{i}].{part}", f"{key}[{i}]")
    try:
        return Robot.create(name, joints, gravity, frames, end_effectors, defaults, base)
    except ModelError as exc:
        raise keys.relocate(exc) from None
