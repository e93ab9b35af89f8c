"""One derivation: the robot, the symbols its equations are functions of, one tape and one memo.

Every algorithm of the symbolic stage is a function ``f(d, *args)`` of a :class:`Derivation` ``d``. The
ones whose results other algorithms reuse are declared :func:`memoized`: their result is computed once
per derivation and argument tuple, so quantities derived together share their intermediates (a body's
twist, its Jacobian columns, a composite inertia) and name each only once on the tape.

The algorithms work body by body: ``d.n`` is the number of bodies and ``d.q[i]`` body i's joint position.
With a floating base (:attr:`Robot.floating_base`), body ``-1``, the parent of the root joints, is the base:
a body whose "joint" is the free-flyer, with screw matrix ``X = I_6``, relative configuration ``C = (R, p)``
(the base pose) and velocity the base twist; its symbols are :attr:`Inputs.base`. Velocity-space quantities
then have ``d.nv = 6 + n`` rows or columns, the base's first; the columns of a Jacobian are keyed by body
index, and the base's six by :data:`BASE_COLUMNS` (:meth:`Derivation.position` gives an entry's index).
A mimic joint's position and its derivatives (:mod:`jaxskid.model._mimic`) are symbols of their own, the
first assignments of the tape (``_q_m{i} = a q_k + b``, ``_qd_m{i} = a qd_k``, ...), so every algorithm
is in closed form in the independent coordinates and the tape's differentiation (:mod:`._adjoint`) follows
the coupling.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field

import sympy as sp

from ..model._constraint import n_rows
from ..model._robot import Robot, symbol
from ._tape import Tape

STATE_ORDERS = ("q", "qd", "qdd", "q3d", "q4d")
"""The names of ``q`` and its time derivatives, by order."""

WRENCH_ORDERS = ("wrench", "wrench_d", "wrench_dd")
"""The names of the end-effector wrenches and their time derivatives, by order."""

COTANGENTS = ("cotangent", "cotangent_matrix", "cotangent_ee", "cotangent_pose", "cotangent_constraint",
              "cotangent_rows")
"""The names of the weights of a vector-Jacobian product: of joint forces ``(nv,)``, of a square matrix in velocity
space ``(nv, nv)``, of a 6-vector per end-effector ``(n_ee, 6)``, of a pose per end-effector ``(n_ee, 4, 4)``, of the
constraint Jacobian ``(m, nv)`` and of a value per constraint row ``(m,)``."""

BASE_COLUMNS = tuple(("base", c) for c in range(6))
"""The keys of the floating base's six velocity coordinates ``(omega, v)`` among a Jacobian's columns."""


def _symbols(prefix: str, n: int) -> tuple[sp.Symbol, ...]:
    return tuple(sp.Symbol(f"{prefix}{i}", real=True) for i in range(n))


def _wrench_symbols(prefix: str, n_ee: int) -> tuple[tuple[sp.Symbol, ...], ...]:
    return tuple(tuple(sp.Symbol(f"{prefix}{e}_{c}", real=True) for c in range(6)) for e in range(n_ee))


@dataclass(frozen=True)
class Inputs:
    """The symbols the derived equations are functions of.

    ``state[k]`` holds the k-th time derivative of every body's joint position, shape ``(n_bodies,)``: the
    coordinates ``_q{k}``, ``_qd{k}``, ``_qdd{k}``, ``_q3d{k}``, ``_q4d{k}`` (k in the order of ``q``), and
    for a mimic joint ``_q_m{i}``, ``_qd_m{i}``, ... (body i), which the derivation defines on its tape;
    ``coordinates`` the body of each coordinate. ``tau`` the joint forces ``_tau{k}``; ``wrenches[r]``
    the r-th time derivative of the end-effector wrenches (moment, force), one 6-tuple per end-effector
    (``_w{e}_{c}``, ``_wrench_d{e}_{c}``, ``_wrench_dd{e}_{c}``); ``params`` the robot's parameters;
    ``cotangent`` the weights ``_ct{k}`` of a vector-Jacobian product of joint forces (shape ``(n,)``),
    ``cotangent_matrix`` those ``_cm{k}`` of one of a square matrix in velocity space (``(n, n)``, row-major),
    ``cotangent_ee`` those ``_ce{k}`` of one of a 6-vector per end-effector (``(n_ee, 6)``) and ``cotangent_pose``
    those ``_cp{k}`` of one of a 4 x 4 pose per end-effector (``(n_ee, 4, 4)``); ``cotangent_constraint`` those
    ``_cc{k}`` of one of the constraint Jacobian (``(m, nv)``, m constraint rows) and ``cotangent_rows`` those
    ``_cr{k}`` of one of a value per constraint row (``(m,)``).
    With a floating base, ``base[k]`` holds the base's symbols of order k: the position and unit quaternion
    ``(x, y, z, qx, qy, qz, qw)`` (``_q_b0`` .. ``_q_b6``) for k = 0, then the base twist ``(omega, v)`` in the
    base frame and its derivatives (``_qd_b0`` .. ``_qd_b5``, ...); ``tau`` and ``cotangent`` start with the base's
    six entries (shape ``(6 + n,)``), and :meth:`coordinate` puts the base's symbols first.
    """

    state: tuple[tuple[sp.Symbol, ...], ...]
    tau: tuple[sp.Symbol, ...]
    wrenches: tuple[tuple[tuple[sp.Symbol, ...], ...], ...]
    params: tuple[sp.Symbol, ...]
    cotangent: tuple[sp.Symbol, ...] = ()
    cotangent_matrix: tuple[sp.Symbol, ...] = ()
    cotangent_ee: tuple[sp.Symbol, ...] = ()
    cotangent_pose: tuple[sp.Symbol, ...] = ()
    cotangent_constraint: tuple[sp.Symbol, ...] = ()
    cotangent_rows: tuple[sp.Symbol, ...] = ()
    coordinates: tuple[int, ...] | None = None
    """The body of each coordinate (``None``: every body, in order)."""
    base: tuple[tuple[sp.Symbol, ...], ...] = ()
    """The floating base's symbols by order (``()``: a fixed base)."""

    @classmethod
    def of(cls, robot: Robot) -> Inputs:
        """The inputs of ``robot``'s equations."""
        n, n_ee, nv = robot.n_dof, len(robot.end_effectors), robot.nv
        body = {i: k for k, i in enumerate(robot.coordinates)}

        def state(order: str) -> tuple[sp.Symbol, ...]:
            coords = _symbols(f"_{order}", n)
            return tuple(coords[body[i]] if i in body else sp.Symbol(f"_{order}_m{i}", real=True)
                         for i in range(robot.n_bodies))

        return cls(
            state=tuple(state(k) for k in STATE_ORDERS),
            tau=_symbols("_tau", nv),
            wrenches=(_wrench_symbols("_w", n_ee), _wrench_symbols("_wrench_d", n_ee),
                      _wrench_symbols("_wrench_dd", n_ee)),
            params=tuple(symbol(p) for p in robot.parameters),
            cotangent=_symbols("_ct", nv),
            cotangent_matrix=_symbols("_cm", nv * nv),
            cotangent_ee=_symbols("_ce", 6 * n_ee),
            cotangent_pose=_symbols("_cp", 16 * n_ee),
            cotangent_constraint=_symbols("_cc", n_rows(robot.constraints) * nv),
            cotangent_rows=_symbols("_cr", n_rows(robot.constraints)),
            coordinates=None if n == robot.n_bodies else robot.coordinates,
            base=tuple(_symbols(f"_{k}_b", 7 if k == "q" else 6) for k in STATE_ORDERS) if robot.floating_base else (),
        )

    def coordinate(self, k: int) -> tuple[sp.Symbol, ...]:
        """The symbols of the k-th time derivative of the coordinates ``q`` (shape ``(nq,)`` for k = 0, else
        ``(nv,)``): the floating base's first, if any."""
        base = self.base[k] if self.base else ()
        if self.coordinates is None:
            return (*base, *self.state[k])
        return (*base, *(self.state[k][i] for i in self.coordinates))

    @property
    def q(self) -> tuple[sp.Symbol, ...]:
        return self.state[0]

    @property
    def qd(self) -> tuple[sp.Symbol, ...]:
        return self.state[1]

    @property
    def qdd(self) -> tuple[sp.Symbol, ...]:
        return self.state[2]

    def by_name(self, name: str) -> tuple[sp.Symbol, ...]:
        """The flat symbols of the input ``name`` (one of :data:`STATE_ORDERS`, ``"tau"``, one of
        :data:`COTANGENTS` or one of :data:`WRENCH_ORDERS`), row-major."""
        if name in STATE_ORDERS:
            return self.coordinate(STATE_ORDERS.index(name))
        if name in WRENCH_ORDERS:
            return tuple(s for w in self.wrenches[WRENCH_ORDERS.index(name)] for s in w)
        if name == "tau":
            return self.tau
        if name in COTANGENTS:
            return getattr(self, name)
        raise KeyError(name)


@dataclass(frozen=True, eq=False)
class Derivation:
    """The robot, its :class:`Inputs`, the tape every intermediate is named on, and the memo of the
    :func:`memoized` algorithms.

    ``friction_smoothing`` is ``0`` (Coulomb friction as ``sign(qd)``) or ``eps > 0`` (``tanh(qd / eps)``).
    ``trig`` is ``"symbols"`` (sin and cos of each ``q_i`` named once on the tape) or ``"inline"`` (left
    in every expression). ``coriolis`` is the factorisation of the Coriolis matrix, ``"christoffel"`` or
    ``"skidy"`` (:mod:`._coriolis`). The mimic joints' states are the first assignments of the tape (module
    docstring).
    """

    robot: Robot
    inputs: Inputs
    trig: str = "symbols"
    friction_smoothing: float = 0.0
    coriolis: str = "christoffel"
    tape: Tape = field(default_factory=Tape)
    memo: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        for i, (k, a, b) in enumerate(self.robot.coupling()):
            if self.robot.joints[i].mimic is None:
                continue
            for order, states in enumerate(self.inputs.state):
                source = self.inputs.state[order][self.inputs.coordinates[k]]
                self.tape.define(states[i], a * source + (b if order == 0 else 0))

    @property
    def n(self) -> int:
        """The number of bodies (and of joints, mimic joints included)."""
        return self.robot.n_bodies

    @property
    def floating(self) -> bool:
        """Whether body ``-1`` is a floating base (else it is the world, at rest)."""
        return self.robot.floating_base

    @property
    def offset(self) -> int:
        """The index of body 0's coordinate in a velocity-space vector: 6 with a floating base, else 0."""
        return 6 if self.robot.floating_base else 0

    @property
    def nv(self) -> int:
        """The size of a velocity-space vector over the bodies: ``offset + n``."""
        return self.offset + self.n

    @property
    def bodies(self) -> tuple[int, ...]:
        """The moving bodies, parents first: ``-1`` (the floating base), if any, then ``0 .. n - 1``."""
        return tuple(range(-1 if self.robot.floating_base else 0, self.n))

    @property
    def columns(self) -> tuple:
        """The keys of the velocity coordinates, in order: :data:`BASE_COLUMNS` (floating base), then bodies."""
        return (*(BASE_COLUMNS if self.robot.floating_base else ()), *range(self.n))

    def position(self, key) -> int:
        """The index in a velocity-space vector of a column key (a body index or one of :data:`BASE_COLUMNS`)."""
        return key[1] if isinstance(key, tuple) else key + self.offset

    def is_body(self, i: int) -> bool:
        """Whether body ``i`` moves: every body, and ``-1`` if it is a floating base."""
        return i >= 0 or self.robot.floating_base

    @property
    def q(self) -> tuple[sp.Symbol, ...]:
        return self.inputs.q

    @property
    def qd(self) -> tuple[sp.Symbol, ...]:
        return self.inputs.qd

    @property
    def qdd(self) -> tuple[sp.Symbol, ...]:
        return self.inputs.qdd


def memoized(fn: Callable) -> Callable:
    """Declare ``fn(d, *args)`` memoised on the :class:`Derivation` ``d``: computed once per ``args``
    (hashable, positional), then shared by every quantity of the derivation."""

    @functools.wraps(fn)
    def cached(d: Derivation, *args):
        key = (fn, args)
        try:
            return d.memo[key]
        except KeyError:
            pass
        out = d.memo[key] = fn(d, *args)
        return out

    return cached
