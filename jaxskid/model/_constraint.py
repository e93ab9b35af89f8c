"""Constraints with multipliers: contacts that hold a frame to the world, and loop closures between two frames.

A constraint is a set of scalar equations ``phi(q) = 0`` on named frames (:meth:`Robot.frame
<jaxskid.Robot.frame>`), one per *axis*. Every axis is world-aligned: ``rx, ry, rz`` are rotations about
the world's axes and ``x, y, z`` translations along them (:data:`AXES`, rotations first as in a twist):

* :class:`PointContact` ``(frame, position)``: the frame's origin stays at the world point ``position``,
  ``phi = p_f(q) - position`` (axes ``x, y, z``);
* :class:`FrameContact` ``(frame, pose)``: the frame stays at the world pose ``pose`` (all six axes);
* :class:`LoopClosure` ``(frame_a, frame_b, kind)``: the two frames of the tree coincide: their origins
  (``kind="point"``), their poses (``"frame"``), or a subset of the axes (``("x", "z")`` for a planar
  linkage in the x-z plane, whose out-of-plane rows would vanish identically).

Contacts take ``axes=`` too, a subset of their own. With ``R_a, p_a`` frame a's world pose and ``R_b, p_b``
frame b's (or the anchor's), the rows of ``phi`` are ``p_a - p_b`` along the translation axes and, about the
rotation axes, ``vee(E - E^T) / 2 = sin(angle) axis`` of ``E = R_a R_b^T``. The velocity rows are those of
the hybrid Jacobians, ``A(q) qd = (omega_a - omega_b, dp_a/dt - dp_b/dt)`` on the axes: ``A qd = dphi/dt``
exactly along translations, and about rotations where the constraint holds (``R_a = R_b``). The multipliers
``lambda`` of ``M qdd + h = tau + A^T lambda`` are then the wrench (moment, force), in world axes and on the
axes, that holds frame a at its origin (and its opposite on frame b).

A contact's anchor is given, or is where its frame is at the configuration ``at`` (joint name -> position;
joints left out at 0; by default the reference configuration ``q = 0``, with a floating base at the
identity): :meth:`Robot.create <jaxskid.Robot.create>` computes it (an expression of the parameters) and
keeps it, with ``at`` cleared. It also checks every rule (:func:`check_constraints`): the frames exist, a
loop closure joins two different bodies, a contact holds a moving body, the axes are known and not repeated,
and the constraints can be satisfied near the reference configuration (:mod:`jaxskid.model._closure`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import sympy as sp

from .._errors import ModelError
from . import _lie as lie
from ._closure import check_satisfiable
from ._lie import AXES
from ._validate import check_pose, describe_value, matrix, to_expr

KINDS = {"point": AXES[3:], "frame": AXES}
"""The named sets of axes of a :class:`LoopClosure`."""


@dataclass(frozen=True)
class PointContact:
    """The origin of ``frame`` held at the world point ``position`` (3 values; ``None``: where it is at ``at``),
    along the world ``axes`` (a subset of ``("x", "y", "z")``; ``None``: all three); ``at``: joint name ->
    position of the configuration that gives the anchor (``None``: ``q = 0``)."""

    frame: str
    position: tuple | None = None
    axes: tuple[str, ...] | None = None
    """A subset of ``("x", "y", "z")``; ``None``: all three."""
    at: Mapping[str, float] | None = None
    """Joint name -> position of the configuration that gives the anchor (``None``: ``q = 0``)."""

    own_axes = AXES[3:]

    @property
    def frames(self) -> tuple[str, None]:
        return (self.frame, None)

    @property
    def anchor(self) -> sp.ImmutableMatrix:
        """The anchor's world pose (identity rotation)."""
        return lie.pose(None, self.position)

    def _resolved(self, anchor: sp.Matrix, axes: tuple, where: str, values: Mapping) -> "PointContact":
        return replace(self, position=tuple(anchor[:3, 3]), axes=axes, at=None)

    def _given(self, where: str) -> sp.Matrix | None:
        if self.position is None:
            return None
        try:
            values = None if isinstance(self.position, (str, Mapping)) else list(self.position)
        except TypeError:
            values = None
        if values is None or len(values) != 3:
            raise ModelError(f"expected 3 values (x, y, z), got {describe_value(self.position)}", where=f"{where}.position")
        return lie.pose(None, [to_expr(v, where=f"{where}.position[{k}]") for k, v in enumerate(values)])

    def mapped(self, fn: Callable) -> "PointContact":
        position = None if self.position is None else tuple(fn(sp.sympify(e)) for e in self.position)
        return replace(self, position=position)


@dataclass(frozen=True)
class FrameContact:
    """``frame`` held at the world pose ``pose`` (4x4; ``None``: where it is at ``at``), along ``axes`` (a subset
    of :data:`AXES`; ``None``: all six); ``at``: joint name -> position of the configuration that gives the
    anchor (``None``: ``q = 0``)."""

    frame: str
    pose: sp.ImmutableMatrix | None = None
    axes: tuple[str, ...] | None = None
    """A subset of :data:`AXES`; ``None``: all six."""
    at: Mapping[str, float] | None = None
    """Joint name -> position of the configuration that gives the anchor (``None``: ``q = 0``)."""

    own_axes = AXES

    @property
    def frames(self) -> tuple[str, None]:
        return (self.frame, None)

    @property
    def anchor(self) -> sp.ImmutableMatrix:
        return self.pose

    def _resolved(self, anchor: sp.Matrix, axes: tuple, where: str, values: Mapping) -> "FrameContact":
        if self.pose is not None:
            check_pose(anchor, values, f"{where}.pose")
        return replace(self, pose=sp.ImmutableMatrix(anchor), axes=axes, at=None)

    def _given(self, where: str) -> sp.Matrix | None:
        if self.pose is None:
            return None
        return matrix(self.pose, (4, 4), f"{where}.pose")

    def mapped(self, fn: Callable) -> "FrameContact":
        return replace(self, pose=None if self.pose is None else sp.ImmutableMatrix(sp.Matrix(self.pose).applyfunc(fn)))


@dataclass(frozen=True)
class LoopClosure:
    """Two frames of the tree, ``frame_a`` and ``frame_b``, held together: ``kind`` is ``"point"`` (their
    origins), ``"frame"`` (their poses) or a subset of :data:`AXES` (world-aligned rows)."""

    frame_a: str
    frame_b: str
    kind: str | tuple[str, ...] = "point"

    own_axes = AXES

    @property
    def frames(self) -> tuple[str, str]:
        return (self.frame_a, self.frame_b)

    @property
    def anchor(self) -> None:
        return None

    @property
    def axes(self) -> tuple[str, ...]:
        return KINDS[self.kind] if isinstance(self.kind, str) else tuple(self.kind)

    def mapped(self, fn: Callable) -> "LoopClosure":
        return self


CONSTRAINT_TYPES = (PointContact, FrameContact, LoopClosure)
Constraint = PointContact | FrameContact | LoopClosure


def n_rows(constraints: Sequence[Constraint]) -> int:
    """The number of scalar constraints: the rows of ``A(q)`` and of ``phi(q)``."""
    return sum(len(c.axes) for c in constraints)


def row_names(constraints: Sequence[Constraint]) -> tuple[str, ...]:
    """A name per row of ``A(q)``: ``constraints[k].<axis>``."""
    return tuple(f"constraints[{k}].{a}" for k, c in enumerate(constraints) for a in c.axes)


# ---------------------------------------------------------------------------------------------- checks
def check_constraints(robot, constraints: Sequence, values: Mapping) -> tuple[Constraint, ...]:
    """The constraints of ``robot`` (fixed joints already merged), normalised: frames checked, axes in the order
    of :data:`AXES`, contacts' anchors computed and ``at`` cleared; then checked to be satisfiable near the
    reference configuration with the default parameter ``values`` (symbol -> number). Errors name
    ``constraints[k]`` and the key."""
    if isinstance(constraints, CONSTRAINT_TYPES) or not isinstance(constraints, Sequence):
        raise ModelError(f"expected a list of constraints, got {describe_value(constraints)}", where="constraints")
    out, starts = [], []
    for k, c in enumerate(constraints):
        where = f"constraints[{k}]"
        if not isinstance(c, CONSTRAINT_TYPES):
            raise ModelError(f"expected a PointContact, FrameContact or LoopClosure, got {describe_value(c)}", where=where)
        bodies = [_body(robot, name, f"{where}.{key}") if name is not None else None
                  for name, key in zip(c.frames, _frame_keys(c))]
        _check_bodies(robot, c, bodies, where)
        if isinstance(c, LoopClosure):
            out.append(replace(c, kind=_kind(c.kind, f"{where}.kind")))
            starts.append({})
            continue
        axes = _axes(c.own_axes if c.axes is None else c.axes, c.own_axes, f"{where}.axes")
        at = _configuration(robot, c.at, f"{where}.at")
        anchor = c._given(where)
        if anchor is None:
            anchor = reference_pose(robot, c.frame, at)
        out.append(c._resolved(anchor, axes, where, values))
        starts.append(at)
    check_satisfiable(robot, out, starts, values)
    return tuple(out)


def _frame_keys(c) -> tuple[str, str]:
    return ("frame_a", "frame_b") if isinstance(c, LoopClosure) else ("frame", "")


def _body(robot, name, where: str) -> int:
    if not isinstance(name, str):
        raise ModelError(f"expected a frame name, got {describe_value(name)}", where=where)
    try:
        return robot.frame(name).body
    except ModelError as exc:
        raise ModelError(exc.message, where=where) from None


def _body_name(robot, body: int) -> str:
    return robot.base if body < 0 else robot.joints[body].link


def _check_bodies(robot, c, bodies, where: str) -> None:
    fixed = -1 if not getattr(robot, "floating_base", False) else None  # the world, unless the base floats
    if isinstance(c, LoopClosure):
        if bodies[0] == bodies[1]:
            body = _body_name(robot, bodies[0])
            raise ModelError(f"frames {c.frame_a!r} and {c.frame_b!r} are both on body {body!r}, fixed to each other; "
                             "a loop closure joins frames on two different bodies", where=where)
    elif bodies[0] == fixed:
        raise ModelError(f"frame {c.frame!r} is fixed to the world, which a contact cannot move; hold a frame of a "
                         "moving body", where=f"{where}.frame")


def _axes(given, allowed: Sequence[str], where: str) -> tuple[str, ...]:
    """A non-empty subset of ``allowed`` without repeats, in the order of :data:`AXES`."""
    items = [given] if isinstance(given, str) else given
    if not isinstance(items, (list, tuple)) or not items:
        raise ModelError(f"expected a list of axes from {', '.join(allowed)}, got {describe_value(given)}", where=where)
    for k, a in enumerate(items):
        if a not in allowed:
            raise ModelError(f"unknown axis {a!r}; expected some of {', '.join(allowed)}", where=f"{where}[{k}]")
        if a in items[:k]:
            raise ModelError(f"axis {a!r} given twice", where=f"{where}[{k}]")
    return tuple(a for a in AXES if a in items)


def _kind(kind, where: str) -> str | tuple[str, ...]:
    if isinstance(kind, str) and kind in KINDS:
        return kind
    if isinstance(kind, str) and kind not in AXES:
        raise ModelError(f"expected 'point', 'frame' or a list of axes from {', '.join(AXES)}, got {kind!r}",
                         where=where)
    return _axes(kind, AXES, where)


def _configuration(robot, at, where: str) -> dict[str, sp.Expr]:
    """``at`` as independent joint name -> position (checked; joints left out are at 0)."""
    if at is None:
        return {}
    if not isinstance(at, Mapping):
        raise ModelError(f"expected a mapping of joint names to positions, got {describe_value(at)}", where=where)
    out = {}
    for name, value in at.items():
        if name not in robot.joint_names:
            raise ModelError(f"unknown joint {name!r}; independent joints: {', '.join(robot.joint_names)}",
                             where=f"{where}.{name}")
        out[name] = to_expr(value, where=f"{where}.{name}")
    return out


def reference_pose(robot, name: str, at: Mapping[str, sp.Expr]) -> sp.ImmutableMatrix:
    """The world pose of frame ``name`` at the configuration ``at`` (joint name -> position, others 0; a
    floating base at the identity), a product of ``B_i exp(X_i q_i)`` down the tree (Müller 2018, eq. 9)."""
    values = [at.get(j, 0) for j in robot.joint_names]
    frame = robot.frame(name)
    pose, body = sp.Matrix(frame.offset), frame.body
    coupling = robot.coupling()
    while body >= 0:
        k, a, b = coupling[body]
        joint = robot.joints[body]
        pose = joint.origin * lie.screw_exp(joint.screw, a * values[k] + b) * pose
        body = joint.parent
    return sp.ImmutableMatrix(pose.applyfunc(sp.expand))


def constraint_symbols(constraints: Sequence[Constraint]):
    """Every expression of the constraints (the anchors), for the parameters they hold."""
    for c in constraints:
        anchor = c.anchor
        if anchor is not None:
            yield from sp.Matrix(anchor)


__all__ = ["AXES", "CONSTRAINT_TYPES", "Constraint", "FrameContact", "LoopClosure", "PointContact", "check_constraints",
           "n_rows", "row_names", "reference_pose"]
