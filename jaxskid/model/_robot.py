"""The immutable robot model: an open chain or tree of rigid bodies on a fixed or a floating base.

Body ``i`` is moved by joint ``i``; its parent is body ``parents[i]`` (``-1`` is the world, or the floating
base with :attr:`Robot.floating_base`, whose inertia is :attr:`Robot.base_inertia`). Every
quantity is stored in the **body-fixed representation** (Müller 2018, sec. 2.3):

* ``Joint.origin`` (``B_i``): the 4x4 pose of body ``i``'s frame in its parent's frame at ``q = 0``;
* ``Joint.screw`` (``X_i``): the joint's unit screw coordinates ``(omega, v)`` in body ``i``'s frame;
* the relative pose at ``q`` is ``C_{p,i}(q_i) = B_i exp(X_i q_i)``;
* ``Joint.inertia``: the 6x6 mass-inertia matrix of body ``i`` in its own frame (see :mod:`jaxskid.model._lie`);
* ``Joint.drive``: the joint's drive (armature, friction, offset; :mod:`jaxskid.model._drive`), or ``None``;
* ``Joint.mimic``: the joint it follows, ``q_i = a q_j + b`` (:mod:`jaxskid.model._mimic`), or ``None``.

Only the independent joints are coordinates: ``q`` has :attr:`Robot.n_dof` entries, one per joint that
mimics no other, in the order of the bodies (:attr:`Robot.coordinates`); without mimic joints every body's
joint is one.

Descriptions in the spatial representation are converted with :func:`spatial_to_body`. :meth:`Robot.create`
validates what it is given (:mod:`jaxskid.model._validate`), then merges fixed joints into their parent body
(:mod:`jaxskid.model._fixed`); the merged link stays reachable as a named frame. Parameters are the free
symbols of these expressions; ``defaults`` gives numbers for some or all of them.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import sympy as sp

from . import _lie as lie
from .._errors import ModelError, unknown_names
from ._constraint import check_constraints, constraint_symbols
from ._drive import Drive, drive_parameter_names
from ._fixed import lock_joint, merge_fixed
from ._joint import Frame, Joint, JointLimits
from ._lie import spatial_to_body
from ._mimic import Mimic, follow_locks, resolve
from ._validate import (check_defaults, check_mass_inertia, check_model, check_parents, describe_value, matrix, symbol,
                        to_expr)

__all__ = ["JOINT_TYPES", "Drive", "Frame", "Joint", "JointLimits", "Mimic", "Robot", "spatial_to_body", "symbol", "to_expr"]

JOINT_TYPES = ("revolute", "prismatic")


def _column(attr: str, doc: str) -> property:
    """A property: the tuple of one attribute of every joint, in the order of ``q``."""
    return property(lambda self: tuple(getattr(j, attr) for j in self.joints), doc=doc)


@dataclass(frozen=True)
class Robot:
    """A fixed-base kinematic tree with symbolic parameters. Build it with :meth:`Robot.create`.

    Attributes:
        name: the robot's name.
        joints: the moving joints, one per body, parents before children; the independent ones (no
            ``mimic``) in the order of ``q``.
        gravity: the gravitational acceleration in the world frame, e.g. ``(0, 0, -9.81)``.
        frames: named frames besides the bodies: merged fixed links and end-effectors.
        end_effectors: names of the frames that are end-effectors.
        defaults: parameter name -> default value, as ``(name, value)`` pairs.
        base: name of the world (root) link; with ``floating_base``, the name of the floating base body.
        floating_base: whether the root is a free-flyer: the base body moves with 6 degrees of freedom,
            ``q = (x, y, z, qx, qy, qz, qw, q_1..q_n)`` (base position in the world, unit quaternion of its
            orientation, as Pinocchio's ``JointModelFreeFlyer``) and velocities ``(omega, v, qd_1..qd_n)`` (the
            base twist in the base frame, angular first). The root joints' parent (body ``-1``) is then the base.
            A quaternion that is not unit-norm gives the rotation of the normalised one (a zero one gives nan).
        base_inertia: the 6x6 mass-inertia of the floating base body in its own frame (``None`` for a fixed
            base; zero unless given); fixed links welded to the root are added to it.
        constraints: contacts and loop closures (:mod:`jaxskid.model._constraint`), their anchors computed.
        without_inertia: the bodies (link names) whose mass-inertia the description does not give: their
            inertia is zero, the robot serves kinematics, and a quantity that needs inertia is refused
            (:func:`jaxskid.equations.resolve`).
    """

    name: str
    joints: tuple[Joint, ...]
    gravity: tuple
    frames: tuple[Frame, ...] = ()
    end_effectors: tuple[str, ...] = ()
    defaults: tuple[tuple[str, float], ...] = ()
    base: str = "world"
    floating_base: bool = False
    base_inertia: sp.ImmutableMatrix | None = None
    constraints: tuple = ()
    without_inertia: tuple[str, ...] = ()
    _parameters: tuple[str, ...] = field(default=(), compare=False, repr=False)

    # ------------------------------------------------------------------ construction
    @classmethod
    def create(
        cls,
        name: str,
        joints: Sequence[Joint],
        gravity: Sequence = (0, 0, -9.81),
        frames: Sequence[Frame] = (),
        end_effectors: Sequence[str] = (),
        defaults: Mapping[str, float] | None = None,
        base: str = "world",
        floating_base: bool = False,
        base_inertia=None,
        constraints: Sequence = (),
        without_inertia: Sequence[str] = (),
    ) -> "Robot":
        """Build and validate a robot. Joints of type ``"fixed"`` are merged into their parent body; with
        ``floating_base``, those welded to the root are merged into the base body, whose own 6x6 mass-inertia is
        ``base_inertia`` (zero if not given). ``without_inertia`` names the bodies (links, or fixed links merged
        into a body) whose mass-inertia is unknown (a reader gives them zero inertia).

        Raises:
            ModelError: the first invariant that does not hold, at the caller's key path
                (``joints[2].inertia``, ``frames[0].offset[3]``, ``defaults.m1``, ``gravity[1]``,
                ``floating_base``, ``base_inertia``, ``constraints[0].frame_b``).
        """
        floating_base, base_inertia = _normalize_base(floating_base, base_inertia)
        _check_arguments(name, joints, defaults)
        end_effectors = (end_effectors,) if isinstance(end_effectors, str) else end_effectors
        joints = [_normalize_joint(j, i) for i, j in enumerate(joints)]
        frames = [_normalize_frame(f, k) for k, f in enumerate(frames)]
        check_parents([j.parent for j in joints])
        if isinstance(gravity, (str, bytes, Mapping)) or not isinstance(gravity, Iterable) or len(
                gravity := list(gravity)) != 3:
            raise ModelError(f"expected 3 values, got {describe_value(gravity)}", where="gravity")
        gravity = tuple(to_expr(g, where=f"gravity[{k}]") for k, g in enumerate(gravity))
        clean = check_defaults(defaults or {})
        check_model(joints, frames, gravity, end_effectors, clean, base)
        if base_inertia is not None:
            check_mass_inertia(base_inertia, {symbol(k): v for k, v in clean.items()}, "base_inertia")
        joints = _resolve_mimics(joints)
        joints, frames, base_inertia = merge_fixed(joints, frames, base_inertia)
        robot = cls(name=name, joints=tuple(joints), gravity=gravity, frames=tuple(frames),
                    end_effectors=tuple(end_effectors), defaults=tuple(clean.items()), base=base,
                    floating_base=floating_base, base_inertia=base_inertia)
        if constraints:  # checked on the merged tree, whose frames they name
            values = {symbol(k): v for k, v in clean.items()}
            object.__setattr__(robot, "constraints", check_constraints(robot, constraints, values))
        if without_inertia:
            object.__setattr__(robot, "without_inertia", _bodies_of(robot, without_inertia))
        object.__setattr__(robot, "_parameters", robot._find_parameters())
        return robot

    def _recreate(self, **changes) -> "Robot":
        """:meth:`create` with this robot's arguments, some of them replaced."""
        args = dict(name=self.name, joints=self.joints, gravity=self.gravity, frames=self.frames,
                    end_effectors=self.end_effectors, defaults=dict(self.defaults), base=self.base,
                    floating_base=self.floating_base, base_inertia=self.base_inertia,
                    constraints=self.constraints, without_inertia=self.without_inertia)
        return Robot.create(**{**args, **changes})

    # ------------------------------------------------------------------ views
    @property
    def n_dof(self) -> int:
        """The number of coordinates: the independent joints (every joint without mimic joints)."""
        return len(self.coordinates)

    @property
    def nq(self) -> int:
        """The size of ``q``: ``7 + n_dof`` with a floating base (position and quaternion first), else ``n_dof``."""
        return self.n_dof + 7 * self.floating_base

    @property
    def nv(self) -> int:
        """The size of ``qd``, ``qdd`` and ``tau``: ``6 + n_dof`` with a floating base (its twist or wrench
        first), else ``n_dof``."""
        return self.n_dof + 6 * self.floating_base

    def __repr__(self) -> str:
        kinds: dict[str, int] = {}
        for j in self.joints:
            kind = "mimic" if j.mimic is not None else j.type
            kinds[kind] = kinds.get(kind, 0) + 1
        joints = ", ".join(f"{v} {k}" for k, v in kinds.items()) or "none"
        defaults = sum(1 for k in self.parameters if k in dict(self.defaults))
        extras = ["floating_base=True"] if self.floating_base else []
        if self.end_effectors:
            extras.append(f"end_effectors={list(self.end_effectors)}")
        if self.constraints:
            extras.append(f"{len(self.constraints)} constraint{'s' * (len(self.constraints) != 1)}")
        if self.driven:
            extras.append(f"{len(self.driven)} drive{'s' * (len(self.driven) != 1)}")
        return (f"Robot({self.name!r}, n_dof={self.n_dof}, joints: {joints}, bodies={self.n_bodies}, "
                f"parameters={len(self.parameters)} ({defaults} with defaults)"
                + "".join(f", {e}" for e in extras) + ")")

    @property
    def n_bodies(self) -> int:
        """The number of moving bodies (and of joints, mimic joints included)."""
        return len(self.joints)

    @property
    def coordinates(self) -> tuple[int, ...]:
        """The body of each coordinate: the indices of the joints that mimic no other, in the order of ``q``."""
        return tuple(i for i, j in enumerate(self.joints) if j.mimic is None)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the independent joints, in the order of ``q`` (mimic joints: :attr:`mimic_joints`)."""
        return tuple(self.joints[i].name for i in self.coordinates)

    @property
    def joint_types(self) -> tuple[str, ...]:
        """``revolute`` or ``prismatic``, per independent joint, in the order of ``q``."""
        return tuple(self.joints[i].type for i in self.coordinates)

    @property
    def mimic_joints(self) -> tuple[str, ...]:
        """Names of the joints that follow another (``Joint.mimic``), in body order."""
        return tuple(j.name for j in self.joints if j.mimic is not None)

    def coupling(self) -> tuple[tuple[int, sp.Expr, sp.Expr], ...]:
        """Per body, ``(k, a, b)`` with its joint's position ``a q[k] + b`` (``(k, 1, 0)`` for coordinate k):
        the rows of ``q_bodies = G q + b`` (:mod:`jaxskid.model._mimic`)."""
        index = {self.joints[i].name: k for k, i in enumerate(self.coordinates)}
        one, zero = sp.Integer(1), sp.Integer(0)
        return tuple((index[j.name], one, zero) if j.mimic is None else
                     (index[j.mimic.joint], sp.sympify(j.mimic.multiplier), sp.sympify(j.mimic.offset))
                     for j in self.joints)

    link_names = _column("link", "Names of the moving bodies, in body order (the order of ``q`` without mimic joints).")
    parents = _column("parent", "Parent body of every body (``-1``: the world).")

    @property
    def frame_names(self) -> tuple[str, ...]:
        """Every named frame: the base (world) link, the bodies, then merged links and end-effectors."""
        return (self.base, *self.link_names, *(f.name for f in self.frames))

    def frame(self, name: str) -> Frame:
        """The frame ``name`` as (body index, offset); bodies are frames at their own origin, and the
        base (world) link is the frame at the world origin."""
        if name == self.base:
            return Frame(name, -1, sp.ImmutableMatrix(sp.eye(4)))
        for i, j in enumerate(self.joints):
            if j.link == name:
                return Frame(name, i, sp.ImmutableMatrix(sp.eye(4)))
        for f in self.frames:
            if f.name == name:
                return f
        raise ModelError(f"unknown frame {name!r}; known: {', '.join(self.frame_names)}")

    @property
    def parameters(self) -> tuple[str, ...]:
        """Names of all symbolic parameters, in order of first appearance, body by body; within a body its
        inertial parameters in the standard order (``m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz``, that of
        :func:`jaxskid.standard_params` and of the regressor's columns)."""
        return self._parameters

    def default_params(self) -> dict[str, float]:
        """Parameter name -> default value, for the parameters that have one."""
        names = set(self._parameters)
        return {k: v for k, v in self.defaults if k in names}

    def children(self, i: int) -> tuple[int, ...]:
        return tuple(k for k, j in enumerate(self.joints) if j.parent == i)

    def support(self, i: int) -> tuple[int, ...]:
        """Bodies from the root to ``i`` (inclusive), root first."""
        path = []
        while i >= 0:
            path.append(i)
            i = self.joints[i].parent
        return tuple(reversed(path))

    @property
    def driven(self) -> tuple[int, ...]:
        """Indices (in the order of ``q``) of the joints that have a drive."""
        return tuple(i for i, j in enumerate(self.joints) if j.drive is not None)

    def limits(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(lower, upper, velocity, effort)``, each of shape ``(n_dof,)`` in the order of ``q``, from every
        joint's :class:`JointLimits` (``-inf``, ``inf``, ``inf``, ``inf`` where a joint has none)."""
        by_name = {j.name: j.limits or JointLimits() for j in self.joints}
        rows = [by_name[name] for name in self.joint_names]
        return tuple(np.array([getattr(r, key) for r in rows], dtype=float).reshape(len(rows))
                     for key in ("lower", "upper", "velocity", "effort"))

    def fingerprint(self) -> str:
        """A stable hash of everything that determines the equations of motion (joint limits do not)."""
        h = hashlib.sha256()
        for j in self.joints:
            h.update(repr((j.name, j.type, j.parent, j.link)).encode())
            h.update(sp.srepr(j.origin).encode())
            h.update(sp.srepr(tuple(j.screw)).encode())
            h.update(sp.srepr(j.inertia).encode())
            if j.drive is not None:  # a robot without drives hashes as it did before drives existed
                h.update(sp.srepr(("drive", *j.drive.values())).encode())
            if j.mimic is not None:  # the same for mimic joints
                h.update(sp.srepr(("mimic", j.mimic.joint, j.mimic.multiplier, j.mimic.offset)).encode())
        h.update(sp.srepr(self.gravity).encode())
        for f in self.frames:
            h.update(repr((f.name, f.body)).encode())
            h.update(sp.srepr(f.offset).encode())
        h.update(repr((self.end_effectors, self.base, self.name)).encode())
        if self.floating_base:  # a fixed-base robot hashes as it did before floating bases existed
            h.update(sp.srepr(("floating_base", self.base_inertia)).encode())
        for c in self.constraints:  # a robot without constraints hashes as it did before they existed
            h.update(repr((type(c).__name__, c.frames, c.axes)).encode())
            h.update(sp.srepr(c.anchor).encode())
        if self.without_inertia:  # the same for a robot whose inertias are all known
            h.update(repr(("without_inertia", self.without_inertia)).encode())
        return h.hexdigest()

    # ------------------------------------------------------------------ derived models
    def lock(self, values: Mapping[str, float]) -> "Robot":
        """A new robot with the named joints fixed at the given positions.

        The locked body's inertia is added to its parent's. With per-link symbolic inertias the merged
        body then carries both links' symbols; for identification, lock while reading
        (``jaxskid.load(path, lock=...)``) so that each moving body keeps 10 parameters. The mimic joints
        of a locked joint are locked with it (:func:`~jaxskid.model._mimic.follow_locks`).
        """
        names = [j.name for j in self.joints]
        unknown = [k for k in values if k not in names]
        if unknown:
            raise ModelError(
                f"cannot lock unknown joint(s) {', '.join(map(repr, unknown))}; joints are {', '.join(names)}",
                where="lock",
            )
        values = {k: to_expr(v, where=f"lock.{k}") for k, v in values.items()}
        values = follow_locks({j.name: j.mimic for j in self.joints if j.mimic is not None}, values)
        joints = [lock_joint(j, values[j.name]) if j.name in values else j for j in self.joints]
        return self._recreate(joints=joints)

    def with_drives(self, defaults: Mapping[str, float] | None = None) -> "Robot":
        """A new robot in which every joint without a drive gets :meth:`Drive.symbolic`: the parameters
        ``{joint}_Ia, {joint}_fv, {joint}_fc, {joint}_fo``, with ``defaults`` (name -> value) or 0."""
        joints, values = [], dict(self.defaults)
        for j in self.joints:
            if j.drive is None:
                values.update({k: 0.0 for k in drive_parameter_names(j.name) if k not in values})
                j = replace(j, drive=Drive.symbolic(j.name))
            joints.append(j)
        return self._recreate(joints=joints, defaults={**values, **(defaults or {})})

    def with_constraints(self, constraints: Sequence) -> "Robot":
        """A new robot with ``constraints`` (:class:`~jaxskid.PointContact`, :class:`~jaxskid.FrameContact`,
        :class:`~jaxskid.LoopClosure`) in place of its own, checked as :meth:`create` checks them."""
        return self._recreate(constraints=tuple(constraints))

    def renamed(self, name: str) -> "Robot":
        """The same robot under another name (generated code and files are named after it)."""
        return replace(self, name=name)

    def with_defaults(self, values: Mapping[str, float]) -> "Robot":
        """A new robot with ``values`` added to (or replacing) the default parameter values."""
        return self._recreate(defaults={**dict(self.defaults), **values})

    def substitute(self, values: Mapping[str, float] | Iterable[str]) -> "Robot":
        """A new robot in which the given parameters are replaced by numbers.

        ``values`` maps names to numbers, or is a list of names whose defaults are used. What stays
        symbolic is what remains: the generated functions then take only those as parameters.
        """
        if not isinstance(values, Mapping):
            defaults = dict(self.defaults)
            missing = [k for k in values if k not in defaults]
            if missing:
                raise ModelError(f"no default value for parameter(s) {', '.join(missing)}", where="substitute")
            values = {k: defaults[k] for k in values}
        unknown = [k for k in values if k not in self._parameters]
        if unknown:
            named, listed = unknown_names(unknown, self._parameters)
            raise ModelError(f"unknown parameter(s) {named}; the parameters are {listed}", where="substitute")
        sub = {symbol(k): sp.Float(float(v)) if not isinstance(v, sp.Basic) else v for k, v in values.items()}
        defaults = {k: v for k, v in self.defaults if k not in values}
        return self.map_expressions(lambda e: e.xreplace(sub), defaults=defaults)

    def keep_symbolic(self, names: Iterable[str], *, where: str = "symbolic") -> "Robot":
        """A new robot in which only the parameters ``names`` stay symbolic: every other parameter is
        replaced by its default value (:meth:`substitute`). Unknown names raise :class:`ModelError` at
        ``where``."""
        keep = list(dict.fromkeys(names))
        unknown = [k for k in keep if k not in self._parameters]
        if unknown:
            named, listed = unknown_names(unknown, self._parameters)
            raise ModelError(f"unknown parameter(s) {named}; the parameters are {listed}", where=where)
        fixed = [p for p in self._parameters if p not in keep]
        return self.substitute(fixed) if fixed else self

    def map_expressions(self, fn: Callable[[sp.Expr], sp.Expr], *, defaults: Mapping | None = None) -> "Robot":
        """A new robot with ``fn`` applied to every expression (poses, screws, inertias, drives, frame
        offsets and gravity) and, if given, new ``defaults``."""
        def matrix(m):
            return sp.ImmutableMatrix(m.applyfunc(fn))

        joints = [replace(j, origin=matrix(j.origin), screw=tuple(fn(sp.sympify(x)) for x in j.screw),
                          inertia=matrix(j.inertia), drive=None if j.drive is None else j.drive.mapped(fn)) for j in self.joints]
        frames = [replace(f, offset=matrix(f.offset)) for f in self.frames]
        base_inertia = None if self.base_inertia is None else matrix(self.base_inertia)
        return self._recreate(joints=joints, frames=frames, gravity=tuple(fn(g) for g in self.gravity),
                              defaults=dict(self.defaults) if defaults is None else dict(defaults),
                              base_inertia=base_inertia, constraints=tuple(c.mapped(fn) for c in self.constraints))

    def expressions(self) -> Iterable[sp.Expr]:
        """Every expression of the model, the inertias first as their standard parameters (``m, mcx, mcy, mcz,
        Ixx, Ixy, Iyy, Ixz, Iyz, Izz``), so that :attr:`parameters` runs in the order of :func:`standard_params`."""
        if self.base_inertia is not None:
            yield from lie.standard_parameters(self.base_inertia)
            yield from self.base_inertia
        for j in self.joints:
            yield from j.origin
            yield from j.screw
            yield from lie.standard_parameters(j.inertia)
            yield from j.inertia
            yield from j.drive.values() if j.drive is not None else ()
        yield from self.gravity
        for f in self.frames:
            yield from f.offset
        yield from constraint_symbols(self.constraints)

    def _find_parameters(self) -> tuple[str, ...]:
        seen: dict[str, None] = {}
        for e in self.expressions():
            for s in sorted(sp.sympify(e).free_symbols, key=lambda s: s.name):
                seen.setdefault(s.name, None)
        return tuple(seen)


def _bodies_of(robot: Robot, links: Sequence[str]) -> tuple[str, ...]:
    """The moving bodies that ``links`` are or were merged into (a link welded to the world drops out), in
    body order; an unknown name is a :class:`ModelError` at ``without_inertia``."""
    known = set(robot.frame_names)
    if bad := [k for k in links if k not in known]:
        raise ModelError(f"unknown link(s) {', '.join(map(repr, bad))}", where="without_inertia")
    bodies = {robot.frame(k).body for k in links}
    return tuple(j.link for i, j in enumerate(robot.joints) if i in bodies)


def _check_arguments(name, joints, defaults) -> None:
    """:meth:`Robot.create`'s containers: a name, a sequence of joints, a mapping of defaults."""
    if not isinstance(name, str) or not name:
        raise ModelError(f"expected a non-empty string, got {describe_value(name)}", where="name")
    if isinstance(joints, (str, bytes, Mapping)) or not isinstance(joints, Iterable):
        raise ModelError(f"expected a sequence of Joint, got {describe_value(joints)}", where="joints")
    if defaults is not None and not isinstance(defaults, Mapping):
        raise ModelError(f"expected a mapping parameter name -> value, got {describe_value(defaults)}",
                         where="defaults")


def _normalize_joint(j: Joint, i: int) -> Joint:
    where = f"joints[{i}]"
    if not isinstance(j, Joint):
        raise ModelError(f"expected a Joint, got {type(j).__name__}", where=where)
    for key, value in (("name", j.name), ("link", j.link)):
        if not isinstance(value, str) or not value:
            raise ModelError(f"expected a non-empty string, got {describe_value(value)}", where=f"{where}.{key}")
    if j.type not in (*JOINT_TYPES, "fixed"):
        raise ModelError(
            f"unknown joint type {j.type!r}; expected one of revolute, prismatic, fixed", where=f"{where}.type"
        )
    origin = matrix(j.origin, (4, 4), f"{where}.origin")
    inertia = matrix(j.inertia, (6, 6), f"{where}.inertia")
    screw = list(j.screw) if j.type != "fixed" or j.screw is not None else [0] * 6
    if len(screw) != 6:
        raise ModelError(f"expected 6 screw coordinates, got {len(screw)}", where=f"{where}.screw")
    screw = tuple(to_expr(x, where=f"{where}.screw[{k}]") for k, x in enumerate(screw))
    drive = j.drive
    if drive is not None:
        if not isinstance(drive, Drive):
            raise ModelError(f"expected a Drive or None, got {type(drive).__name__}", where=f"{where}.drive")
        drive = drive.normalized(f"{where}.drive")
    mimic = Mimic.of(j.mimic, f"{where}.mimic")
    limits = j.limits
    if limits is not None:
        if not isinstance(limits, JointLimits):
            raise ModelError(f"expected a JointLimits or None, got {type(limits).__name__}", where=f"{where}.limits")
        limits = limits.checked(f"{where}.limits")
    return Joint(str(j.name), j.type, j.parent, origin, screw, inertia, str(j.link), drive, mimic, limits)


def _normalize_base(floating_base, base_inertia) -> tuple[bool, sp.ImmutableMatrix | None]:
    """``(floating_base, base_inertia)`` checked: a bool, and a 6x6 matrix (zero if not given) for a floating
    base, ``None`` for a fixed one."""
    if not isinstance(floating_base, (bool, np.bool_)):
        raise ModelError(f"expected true or false, got {describe_value(floating_base)}", where="floating_base")
    if not floating_base:
        if base_inertia is not None:
            raise ModelError("a fixed base has no inertia of its own; give floating_base=True or leave it out",
                             where="base_inertia")
        return False, None
    if base_inertia is None:
        return True, sp.ImmutableMatrix(sp.zeros(6))
    return True, matrix(base_inertia, (6, 6), "base_inertia")


def _resolve_mimics(joints: list[Joint]) -> list[Joint]:
    """The joints with every mimic coupling composed down to an independent joint (:func:`resolve`)."""
    mimics = {j.name: j.mimic for j in joints if j.mimic is not None}
    if not mimics:
        return joints
    position = {j.name: i for i, j in enumerate(joints)}
    done = resolve(mimics, {j.name: j.type for j in joints}, lambda name: f"joints[{position[name]}].mimic")
    return [replace(j, mimic=done[j.name]) if j.name in done else j for j in joints]


def _normalize_frame(f: Frame, k: int) -> Frame:
    return Frame(str(f.name), f.body, matrix(f.offset, (4, 4), f"frames[{k}].offset"))
