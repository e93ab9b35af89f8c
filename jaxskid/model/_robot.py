"""The immutable robot model: a fixed-base open chain or tree of rigid bodies.

Body ``i`` is moved by joint ``i``; its parent is body ``parents[i]`` (``-1`` is the world). Every
quantity is stored in the **body-fixed representation** (Müller 2018, sec. 2.3):

* ``Joint.origin`` (``B_i``): the 4x4 pose of body ``i``'s frame in its parent's frame at ``q = 0``;
* ``Joint.screw`` (``X_i``): the joint's unit screw coordinates ``(omega, v)`` in body ``i``'s frame;
* the relative pose at ``q`` is ``C_{p,i}(q_i) = B_i exp(X_i q_i)``;
* ``Joint.inertia``: the 6x6 mass-inertia matrix of body ``i`` in its own frame (see :mod:`jaxskid.model._lie`).

Descriptions in the spatial representation are converted with :func:`spatial_to_body`. Fixed joints are
merged into their parent body when the model is built (:meth:`Robot.create`); the merged link stays
reachable as a named frame. Parameters are the free symbols of these expressions; ``defaults`` gives
numbers for some or all of them.
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import sympy as sp

from . import _lie as lie
from .._errors import ModelError

JOINT_TYPES = ("revolute", "prismatic")
_TOL = 1e-6


def symbol(name: str) -> sp.Symbol:
    """The SymPy symbol jaxskid uses for the parameter ``name`` (real-valued)."""
    return sp.Symbol(name, real=True)


_ARITHMETIC = re.compile(r"[A-Za-z0-9_+\-*/^().,\s]*")


def to_expr(value, *, where: str = "") -> sp.Expr:
    """A SymPy expression from a number, a string or an expression; symbols become real symbols.

    Strings may hold arithmetic on numbers, names and function calls only (no attribute access, no
    dunder names), so parsing never runs arbitrary code. Floats with an integer value become exact
    integers, so that structural zeros and ones stay exact in the derivation.
    """
    if isinstance(value, str) and (not value.strip() or not _ARITHMETIC.fullmatch(value) or "__" in value):
        raise ModelError(f"expected an arithmetic expression of numbers and parameter names, got {value!r}", where=where)
    try:
        expr = sp.sympify(value, locals=_SYMPIFY_LOCALS) if isinstance(value, str) else sp.sympify(value)
    except (sp.SympifyError, SyntaxError, TypeError, ValueError, AttributeError) as exc:
        raise ModelError(f"expected a number or a symbolic expression, got {value!r}", where=where) from exc
    if isinstance(expr, sp.MatrixBase) or not isinstance(expr, sp.Expr):
        raise ModelError(f"expected a scalar number or expression, got {value!r}", where=where)
    return _realify(expr)


# Names that must parse as symbols rather than SymPy's built-ins (S, N, E, I, Q, O, beta, gamma...).
_SYMPIFY_LOCALS = {n: sp.Symbol(n, real=True) for n in ("S", "N", "E", "I", "Q", "O", "beta", "gamma", "zeta", "lambda_")}
_SYMPIFY_LOCALS["pi"] = sp.pi


def _realify(expr):
    subs: dict = {s: symbol(s.name) for s in expr.free_symbols if not s.is_real}
    for f in expr.atoms(sp.Float):
        x = float(f)
        if math.isfinite(x) and x == int(x) and abs(x) < 2**53:
            subs[f] = sp.Integer(int(x))
    return expr.xreplace(subs) if subs else expr


def _check_finite(expr, where: str):
    if expr.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
        raise ModelError(f"expected a finite value, got {expr}", where=where)


@dataclass(frozen=True)
class Joint:
    """One joint and the body it moves (see the module docstring for the conventions)."""

    name: str
    type: str
    parent: int
    origin: sp.ImmutableMatrix
    screw: tuple
    inertia: sp.ImmutableMatrix
    link: str


@dataclass(frozen=True)
class Frame:
    """A named frame rigidly attached to body ``body`` (``-1``: the world) at pose ``offset``."""

    name: str
    body: int
    offset: sp.ImmutableMatrix


@dataclass(frozen=True)
class Robot:
    """A fixed-base kinematic tree with symbolic parameters. Build it with :meth:`Robot.create`.

    Attributes:
        name: the robot's name.
        joints: the moving joints in the order of ``q`` (parents before children).
        gravity: the gravitational acceleration in the world frame, e.g. ``(0, 0, -9.81)``.
        frames: named frames besides the bodies: merged fixed links and end-effectors.
        end_effectors: names of the frames that are end-effectors.
        defaults: parameter name -> default value, as ``(name, value)`` pairs.
        base: name of the world (root) link.
    """

    name: str
    joints: tuple[Joint, ...]
    gravity: tuple
    frames: tuple[Frame, ...] = ()
    end_effectors: tuple[str, ...] = ()
    defaults: tuple[tuple[str, float], ...] = ()
    base: str = "world"
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
    ) -> "Robot":
        """Build and validate a robot. Joints of type ``"fixed"`` are merged into their parent body."""
        joints = [_normalize_joint(j, i) for i, j in enumerate(joints)]
        frames = [_normalize_frame(f, i) for i, f in enumerate(frames)]
        _check_tree(joints)
        joints, frames = _merge_fixed(joints, list(frames))
        gravity = tuple(to_expr(g, where=f"gravity[{k}]") for k, g in enumerate(gravity))
        if len(gravity) != 3:
            raise ModelError(f"expected 3 values, got {len(gravity)}", where="gravity")
        defaults = dict(defaults or {})
        clean = []
        for k, v in defaults.items():
            try:
                fv = float(sp.sympify(v))
            except (TypeError, ValueError, sp.SympifyError) as exc:
                raise ModelError(f"expected a number, got {v!r}", where=f"assignments.{k}") from exc
            if not math.isfinite(fv):
                raise ModelError(f"expected a finite number, got {v!r}", where=f"assignments.{k}")
            clean.append((str(k), fv))
        robot = cls(
            name=name,
            joints=tuple(joints),
            gravity=gravity,
            frames=tuple(frames),
            end_effectors=tuple(end_effectors),
            defaults=tuple(clean),
            base=base,
        )
        robot._validate()
        object.__setattr__(robot, "_parameters", robot._find_parameters())
        return robot

    # ------------------------------------------------------------------ views
    @property
    def n_dof(self) -> int:
        return len(self.joints)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @property
    def joint_types(self) -> tuple[str, ...]:
        return tuple(j.type for j in self.joints)

    @property
    def link_names(self) -> tuple[str, ...]:
        """Names of the moving bodies, in the order of ``q``."""
        return tuple(j.link for j in self.joints)

    @property
    def parents(self) -> tuple[int, ...]:
        return tuple(j.parent for j in self.joints)

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
        """Names of all symbolic parameters, in order of first appearance."""
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

    def fingerprint(self) -> str:
        """A stable hash of everything that determines the equations of motion."""
        h = hashlib.sha256()
        for j in self.joints:
            h.update(repr((j.name, j.type, j.parent, j.link)).encode())
            h.update(sp.srepr(j.origin).encode())
            h.update(sp.srepr(tuple(j.screw)).encode())
            h.update(sp.srepr(j.inertia).encode())
        h.update(sp.srepr(self.gravity).encode())
        for f in self.frames:
            h.update(repr((f.name, f.body)).encode())
            h.update(sp.srepr(f.offset).encode())
        h.update(repr((self.end_effectors, self.base, self.name)).encode())
        return h.hexdigest()

    # ------------------------------------------------------------------ derived models
    def lock(self, values: Mapping[str, float]) -> "Robot":
        """A new robot with the named joints fixed at the given positions.

        The locked body's inertia is added to its parent's. With per-link symbolic inertias the merged
        body then carries both links' symbols; for identification, lock while reading
        (``jaxskid.load(path, lock=...)``) so that each moving body keeps 10 parameters.
        """
        names = set(self.joint_names)
        unknown = [k for k in values if k not in names]
        if unknown:
            raise ModelError(
                f"cannot lock unknown joint(s) {', '.join(map(repr, unknown))}; joints are {', '.join(self.joint_names)}",
                where="lock",
            )
        joints = []
        for j in self.joints:
            if j.name in values:
                value = to_expr(values[j.name], where=f"lock.{j.name}")
                origin = sp.ImmutableMatrix(j.origin * lie.screw_exp(j.screw, value))
                j = replace(j, type="fixed", origin=origin)
            joints.append(j)
        return Robot.create(
            self.name, joints, self.gravity, self.frames, self.end_effectors, dict(self.defaults), self.base
        )

    def with_defaults(self, values: Mapping[str, float]) -> "Robot":
        """A new robot with ``values`` added to (or replacing) the default parameter values."""
        d = dict(self.defaults)
        d.update(values)
        return Robot.create(self.name, self.joints, self.gravity, self.frames, self.end_effectors, d, self.base)

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
            raise ModelError(
                f"unknown parameter(s) {', '.join(unknown)}; parameters are {', '.join(self._parameters)}",
                where="substitute",
            )
        sub = {symbol(k): sp.Float(float(v)) if not isinstance(v, sp.Basic) else v for k, v in values.items()}

        def s(e):
            return e.xreplace(sub)

        joints = [
            replace(
                j,
                origin=sp.ImmutableMatrix(s(j.origin)),
                screw=tuple(s(sp.sympify(x)) for x in j.screw),
                inertia=sp.ImmutableMatrix(s(j.inertia)),
            )
            for j in self.joints
        ]
        frames = [replace(f, offset=sp.ImmutableMatrix(s(f.offset))) for f in self.frames]
        gravity = tuple(s(g) for g in self.gravity)
        defaults = {k: v for k, v in self.defaults if k not in values}
        return Robot.create(self.name, joints, gravity, frames, self.end_effectors, defaults, self.base)

    def expressions(self) -> Iterable[sp.Expr]:
        for j in self.joints:
            yield from j.origin
            yield from j.screw
            yield from j.inertia
        yield from self.gravity
        for f in self.frames:
            yield from f.offset

    # ------------------------------------------------------------------ invariants
    def _find_parameters(self) -> tuple[str, ...]:
        seen: dict[str, None] = {}
        for e in self.expressions():
            for s in sorted(sp.sympify(e).free_symbols, key=lambda s: s.name):
                seen.setdefault(s.name, None)
        return tuple(seen)

    def _validate(self) -> None:
        names: dict[str, str] = {}
        for i, j in enumerate(self.joints):
            where = f"joints[{i}]"
            if j.name in names and names[j.name] == "joint":
                raise ModelError(f"duplicate joint name {j.name!r}", where=f"{where}.name")
            names[j.name] = "joint"
        links: set[str] = {self.base}
        for i, j in enumerate(self.joints):
            if j.link in links:
                raise ModelError(f"duplicate link name {j.link!r}", where=f"joints[{i}].link")
            links.add(j.link)
        for k, f in enumerate(self.frames):
            if f.name in links:
                raise ModelError(f"duplicate frame name {f.name!r}", where=f"frames[{k}].name")
            links.add(f.name)
            if not -1 <= f.body < len(self.joints):
                raise ModelError(
                    f"expected a body index in -1..{len(self.joints) - 1}, got {f.body}", where=f"frames[{k}].body"
                )
        for e in self.end_effectors:
            if e not in links:
                raise ModelError(f"unknown end-effector frame {e!r}", where="end_effectors")
        for k, g in enumerate(self.gravity):
            _check_finite(g, f"gravity[{k}]")
        numeric = {symbol(k): v for k, v in self.defaults}
        for i, j in enumerate(self.joints):
            _check_joint(j, i, numeric)


def _normalize_joint(j: Joint, i: int) -> Joint:
    where = f"joints[{i}]"
    if not isinstance(j, Joint):
        raise ModelError(f"expected a Joint, got {type(j).__name__}", where=where)
    if j.type not in (*JOINT_TYPES, "fixed"):
        raise ModelError(
            f"unknown joint type {j.type!r}; expected one of revolute, prismatic, fixed", where=f"{where}.type"
        )
    if not isinstance(j.parent, int) or isinstance(j.parent, bool):
        raise ModelError(f"expected an integer parent index, got {j.parent!r}", where=f"{where}.parent")
    origin = _matrix(j.origin, (4, 4), f"{where}.origin")
    inertia = _matrix(j.inertia, (6, 6), f"{where}.inertia")
    screw = list(j.screw) if j.type != "fixed" or j.screw is not None else [0] * 6
    if len(screw) != 6:
        raise ModelError(f"expected 6 screw coordinates, got {len(screw)}", where=f"{where}.screw")
    screw = tuple(to_expr(x, where=f"{where}.screw[{k}]") for k, x in enumerate(screw))
    return Joint(str(j.name), j.type, j.parent, origin, screw, inertia, str(j.link))


def _normalize_frame(f: Frame, k: int) -> Frame:
    return Frame(str(f.name), f.body, _matrix(f.offset, (4, 4), f"frames[{k}].offset"))


def _matrix(value, shape, where) -> sp.ImmutableMatrix:
    try:
        m = sp.Matrix(value)
    except (TypeError, ValueError, sp.SympifyError) as exc:
        raise ModelError(f"expected a {shape[0]}x{shape[1]} matrix, got {value!r}", where=where) from exc
    if m.shape != shape:
        raise ModelError(f"expected a {shape[0]}x{shape[1]} matrix, got shape {m.shape[0]}x{m.shape[1]}", where=where)
    out = m.applyfunc(lambda e: to_expr(e, where=where))
    for e in out:
        _check_finite(e, where)
    return sp.ImmutableMatrix(out)


def _check_tree(joints: Sequence[Joint]) -> None:
    n = len(joints)
    for i, j in enumerate(joints):
        if not -1 <= j.parent < n:
            raise ModelError(f"expected a parent index in -1..{n - 1} (-1 is the world), got {j.parent}",
                             where=f"joints[{i}].parent")
    for i in range(n):  # a parent chain that does not reach the world within n steps is a cycle
        seen, k = [], i
        while k != -1:
            if k in seen:
                cyc = " -> ".join(joints[x].name for x in [*seen[seen.index(k):], k])
                raise ModelError(f"the parent indices form a cycle ({cyc})", where=f"joints[{i}].parent")
            seen.append(k)
            k = joints[k].parent
    for i, j in enumerate(joints):
        if j.parent >= i:
            raise ModelError(
                f"parent index {j.parent} points forward: every parent must come before its children",
                where=f"joints[{i}].parent",
            )


def _merge_fixed(joints: list[Joint], frames: list[Frame]) -> tuple[list[Joint], list[Frame]]:
    """Weld every fixed joint's body to its parent: inertia moved and added, children re-attached."""
    joints = list(joints)
    frames = list(frames)
    alive = [True] * len(joints)
    for i, j in enumerate(joints):
        if j.type != "fixed":
            continue
        alive[i] = False
        t = j.origin  # pose of body i in its parent's frame
        p = j.parent
        if p >= 0 and any(e != 0 for e in j.inertia):
            moved = lie.transform_inertia(j.inertia, t)
            moved = (moved + moved.T) / 2  # exact symmetry despite float round-off
            joints[p] = replace(joints[p], inertia=sp.ImmutableMatrix((joints[p].inertia + moved).applyfunc(_tidy)))
        for k in range(i + 1, len(joints)):
            if joints[k].parent == i:
                joints[k] = replace(joints[k], parent=p, origin=sp.ImmutableMatrix((t * joints[k].origin).applyfunc(_tidy)))
        frames = [
            replace(f, body=p, offset=sp.ImmutableMatrix((t * f.offset).applyfunc(_tidy))) if f.body == i else f
            for f in frames
        ]
        frames.append(Frame(j.link, p, t))
    # re-index the surviving bodies
    new_index = {-1: -1}
    for i in range(len(joints)):
        if alive[i]:
            new_index[i] = len(new_index) - 1
    kept = [replace(j, parent=new_index[j.parent]) for i, j in enumerate(joints) if alive[i]]
    frames = [replace(f, body=new_index[f.body]) for f in frames]
    return kept, frames


def _tidy(e):
    """Drop float round-off next to exact zeros and ones produced by merging numeric poses."""
    e = sp.sympify(e)
    if e.is_Float and abs(float(e)) < 1e-15:
        return sp.Integer(0)
    return e


def _check_joint(j: Joint, i: int, numeric: Mapping) -> None:
    where = f"joints[{i}]"
    w, v = j.screw[:3], j.screw[3:]
    wn = [_num(e, numeric) for e in w]
    vn = [_num(e, numeric) for e in v]
    if j.type == "revolute" and None not in wn:
        norm = math.sqrt(sum(x * x for x in wn))
        if abs(norm - 1.0) > _TOL:
            raise ModelError(f"expected a unit rotation axis, got norm {norm:.6g}", where=f"{where}.screw")
    if j.type == "prismatic":
        if any(x is None or abs(x) > _TOL for x in wn):
            raise ModelError("expected zero angular part (omega) for a prismatic joint", where=f"{where}.screw")
        if None not in vn:
            norm = math.sqrt(sum(x * x for x in vn))
            if abs(norm - 1.0) > _TOL:
                raise ModelError(f"expected a unit translation axis, got norm {norm:.6g}", where=f"{where}.screw")
    o = j.origin
    if [o[3, k] for k in range(4)] != [0, 0, 0, 1]:
        raise ModelError("expected the last row of a pose to be [0, 0, 0, 1]", where=f"{where}.origin")
    rn = [[_num(o[r, c], numeric) for c in range(3)] for r in range(3)]
    if all(x is not None for row in rn for x in row):
        for a in range(3):
            for b in range(3):
                dot = sum(rn[k][a] * rn[k][b] for k in range(3))
                if abs(dot - (1.0 if a == b else 0.0)) > _TOL:
                    raise ModelError("expected an orthonormal rotation in the pose", where=f"{where}.origin")
    m6 = j.inertia
    for r in range(6):
        for c in range(r + 1, 6):
            a, b = m6[r, c], m6[c, r]
            if a.is_Number and b.is_Number:
                asym = abs(float(a) - float(b)) > 1e-12 * max(1.0, abs(float(a)))
            else:
                asym = sp.expand(a - b) != 0
            if asym:
                raise ModelError(f"expected a symmetric 6x6 mass-inertia matrix (entry {r},{c})", where=f"{where}.inertia")
    _check_inertia_numeric(m6, numeric, f"{where}.inertia")


def _num(e, numeric):
    e = sp.sympify(e)
    if e.free_symbols:
        e = sp.sympify(e.xreplace(numeric))
        if e.free_symbols:
            return None
    try:
        return float(e)
    except (TypeError, ValueError):
        return None


def _check_inertia_numeric(m6, numeric, where) -> None:
    import numpy as np

    vals = [_num(e, numeric) for e in m6]
    if any(x is None for x in vals):
        return
    with np.errstate(all="ignore"):
        a = np.array(vals, dtype=float).reshape(6, 6)
        if not np.all(np.isfinite(a)) or np.abs(a).max() > 1e150:
            raise ModelError("expected finite mass-inertia values of a physical size", where=where)
        _check_inertia_values(a, where)


def _check_inertia_values(a, where) -> None:
    import numpy as np

    m = a[5, 5]
    if m < 0:
        raise ModelError(f"expected a non-negative mass, got {m:.6g}", where=where)
    if m == 0:
        if np.abs(a).max() > 0 and np.linalg.eigvalsh(a[:3, :3]).min() < -1e-9 * float(np.abs(a).max()):
            raise ModelError("expected a positive semi-definite inertia for a massless body", where=where)
        return
    c = np.array([a[2, 4], a[0, 5], a[1, 3]]) / m  # m c~ block, (omega, v) order
    cx = np.array([[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]])
    ic = a[:3, :3] + m * cx @ cx  # inertia about the centre of mass
    ev = np.linalg.eigvalsh(ic)
    if ev.min() < -1e-9 * float(np.abs(a[:3, :3]).max()):  # relative to I_o, which holds the m c^2 terms
        raise ModelError(
            f"expected a positive definite rotational inertia about the centre of mass, got eigenvalues {np.round(ev, 9).tolist()}",
            where=where,
        )


def spatial_to_body(
    screws_world: Sequence[Sequence],
    poses_world: Sequence[sp.Matrix],
    parents: Sequence[int],
) -> tuple[list[tuple], list[sp.ImmutableMatrix]]:
    """Convert the spatial representation to the body-fixed one.

    Given each joint's screw ``Y_i`` in world coordinates and each body's reference pose ``A_i`` in the
    world at ``q = 0``, returns ``X_i = Ad(A_i^-1) Y_i`` and ``B_i = A_{p(i)}^-1 A_i`` (Müller 2018, eq. 25).
    """
    screws, origins = [], []
    for i, (y, a) in enumerate(zip(screws_world, poses_world)):
        a = sp.Matrix(a)
        x = lie.adjoint(lie.inverse(a)) * sp.Matrix(list(y))
        screws.append(tuple(sp.expand(e) for e in x))
        p = parents[i]
        b = a if p < 0 else lie.inverse(poses_world[p]) * a
        origins.append(sp.ImmutableMatrix(b.applyfunc(sp.expand)))
    return screws, origins
