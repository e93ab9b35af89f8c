"""Named equations: derive the requested quantities of the catalogue into one straight-line program.

:func:`derive` builds only the requested quantities on one shared :class:`~jaxskid.symbolic.Tape`, so
quantities requested together share their intermediates. The result, :class:`Equations`, is what the
lowering stage (JAX) and the code generators (C, Julia, ...) print.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import sympy as sp

from .._gc import gc_paused
from .._errors import RequestError, unknown_names
from ..model._constraint import n_rows
from ..model._robot import Robot
from .. import symbolic as sym
from ..symbolic import STATE_ORDERS, WRENCH_ORDERS, Derivation, Inputs
from . import _mimic as mimic
from ._catalogue import DEFAULT_QUANTITIES, QUANTITIES
from ._options import Options, apply_options

log = logging.getLogger("jaxskid")

_ARGUMENT_DOCS = {
    "q": "joint positions",
    "qd": "joint velocities",
    "qdd": "joint accelerations",
    "q3d": "joint jerks",
    "q4d": "joint jounces",
    "tau": "joint forces",
    "cotangent": "weights w of a vector-Jacobian product w^T d(joint forces)",
    "cotangent_matrix": "weights W of a vector-Jacobian product sum_ij W_ij d(matrix entry ij)",
    "cotangent_ee": "weights W of a vector-Jacobian product sum_ek W_ek d(entry k of end-effector e)",
    "cotangent_pose": "weights W of a vector-Jacobian product sum_eij W_eij d(pose entry ij of end-effector e)",
    "cotangent_constraint": "weights W of a vector-Jacobian product sum_ij W_ij d(constraint Jacobian entry ij)",
    "cotangent_rows": "weights w of a vector-Jacobian product w^T d(one value per constraint row)",
    "wrench": "end-effector wrenches (moment, force)",
    "wrench_d": "first time derivatives of the end-effector wrenches",
    "wrench_dd": "second time derivatives of the end-effector wrenches",
}
_BASE_DOCS = {
    "q": "base position (x, y, z) and quaternion (qx, qy, qz, qw)",
    "qd": "base twist (omega, v) in the base frame",
    "qdd": "its time derivative",
    "q3d": "its second time derivative",
    "q4d": "its third time derivative",
    "tau": "base wrench (moment, force) in the base frame",
    "cotangent": "weights of the base wrench",
}


@dataclass(frozen=True)
class Argument:
    """An input of the generated functions: its name, shape and the flat symbols standing for it."""

    name: str
    shape: tuple[int, ...]
    symbols: tuple[sp.Symbol, ...]
    doc: str


@dataclass(frozen=True)
class Quantity:
    """One derived quantity: ``name(*args, params) -> array of shape``, entries row-major in outputs."""

    name: str
    args: tuple[str, ...]
    shape: tuple[int, ...]
    outputs: tuple[sp.Expr, ...]
    equation: str
    doc: str


@dataclass(frozen=True)
class Equations:
    """The requested quantities of one robot as a shared straight-line program. Made by :func:`jaxskid.derive`.

    Args:
        robot: the :class:`~jaxskid.Robot` they were derived for.
        parameters: the parameter names, the order of the parameter vector ``p``.
        param_symbols: the SymPy symbols of ``parameters``, in the same order.
        arguments: argument name (``q``, ``qd``, ...) -> its symbols and shape.
        quantities: quantity name -> its outputs, argument signature, shape and equation.
        assignments: ``(symbol, expression)`` pairs in dependency order; each quantity's outputs are
            expressions of these symbols, of the argument symbols and of the parameter symbols.
        options: the :class:`~jaxskid.Options` they were derived with.
    """

    robot: Robot
    parameters: tuple[str, ...]
    param_symbols: tuple[sp.Symbol, ...]
    arguments: dict[str, Argument]
    quantities: dict[str, Quantity]
    assignments: tuple[tuple[sp.Symbol, sp.Expr], ...]
    options: Options = Options()
    _index: dict = field(default_factory=dict, compare=False, repr=False)

    def program(self, names: Iterable[str]) -> list[tuple[sp.Symbol, sp.Expr]]:
        """The assignments that the named quantities need, in order."""
        if not self._index:
            self._index.update({s: k for k, (s, _) in enumerate(self.assignments)})
        need: set[int] = set()
        stack = []
        for n in names:
            for e in self.quantities[n].outputs:
                stack.extend(sp.sympify(e).free_symbols)
        while stack:
            s = stack.pop()
            k = self._index.get(s)
            if k is None or k in need:
                continue
            need.add(k)
            stack.extend(self.assignments[k][1].free_symbols)
        return [self.assignments[k] for k in sorted(need)]

    def operation_count(self, names: Iterable[str]) -> int:
        names = list(names)
        ops = sum(sp.count_ops(e) for _, e in self.program(names))
        return ops + sum(sp.count_ops(e) for n in names for e in self.quantities[n].outputs)


def resolve(robot: Robot, quantities: Sequence[str] | str | None) -> tuple[str, ...]:
    """Validate a request and return the quantity names in a canonical order."""
    if quantities is None:
        names = [q for q in DEFAULT_QUANTITIES]
    elif quantities == "all":
        names = list(QUANTITIES)
    elif isinstance(quantities, str):
        names = [quantities]
    else:
        names = list(quantities)
    unknown = [q for q in names if q not in QUANTITIES]
    if unknown:
        named, listed = unknown_names(unknown, sorted(QUANTITIES), shown=len(QUANTITIES))
        raise RequestError(f"unknown quantity {named}; available: {listed}")
    if quantities is None or quantities == "all":
        names = mimic.supported(robot, names)
    if not robot.end_effectors:
        if quantities is None or quantities == "all":
            names = [q for q in names if not QUANTITIES[q].needs_end_effector]
        else:
            bad = [q for q in names if QUANTITIES[q].needs_end_effector]
            if bad:
                raise RequestError(f"{', '.join(bad)} need an end-effector, and robot {robot.name!r} has none")
    if not robot.constraints:
        if quantities is None or quantities == "all":
            names = [q for q in names if not QUANTITIES[q].needs_constraints]
        elif bad := [q for q in names if QUANTITIES[q].needs_constraints]:
            raise RequestError(f"{', '.join(bad)} need constraints, and robot {robot.name!r} has none; give them with "
                               "robot.with_constraints([...]) or a constraints block")
    if robot.without_inertia:
        names = _without_inertia(robot, names, quantities is None or quantities == "all")
    order = list(QUANTITIES)
    return tuple(sorted(dict.fromkeys(names), key=order.index))


def _without_inertia(robot: Robot, names: list[str], default: bool) -> list[str]:
    """``names`` for a robot with bodies :attr:`~Robot.without_inertia`: the default request keeps the kinematic
    quantities; a request that names one that needs inertia is a :class:`RequestError` naming the bodies."""
    if default:
        return [q for q in names if not QUANTITIES[q].needs_inertia]
    bad = [q for q in names if QUANTITIES[q].needs_inertia]
    if not bad:
        return names
    bodies, kinematic = ", ".join(robot.without_inertia), [q for q in QUANTITIES if not QUANTITIES[q].needs_inertia]
    raise RequestError(
        f"{', '.join(bad)} need{'s' * (len(bad) == 1)} the mass and inertia of every body, and robot "
        f"{robot.name!r} has none for body {bodies}: its description gives no mass_inertia for "
        f"{'them' if len(robot.without_inertia) > 1 else 'it'}. Expected a mass_inertia entry per body, or a "
        f"kinematic quantity ({', '.join(kinematic)})")


def _arguments(robot: Robot, inputs: Inputs) -> dict[str, Argument]:
    """The arguments' shapes: ``q`` ``(nq,)``, the velocity-space ones ``(nv,)`` (``n`` each for a fixed base; a
    floating base's position and quaternion, or its twist or wrench, first), the wrenches ``(n_ee, 6)``."""
    n_ee, rows = len(robot.end_effectors), n_rows(robot.constraints)
    shapes = {**{k: (robot.nq if k == "q" else robot.nv,) for k in (*STATE_ORDERS, "tau", "cotangent")},
              "cotangent_matrix": (robot.nv, robot.nv), "cotangent_ee": (n_ee, 6), "cotangent_pose": (n_ee, 4, 4),
              "cotangent_constraint": (rows, robot.nv), "cotangent_rows": (rows,),
              **{k: (n_ee, 6) for k in WRENCH_ORDERS}}
    docs = dict(_ARGUMENT_DOCS)
    if robot.floating_base:
        docs.update({k: f"{_BASE_DOCS[k]}, then the {docs[k]}" for k in _BASE_DOCS})
    return {k: Argument(k, shape, inputs.by_name(k), docs[k]) for k, shape in shapes.items()}


@gc_paused
def derive(
    robot: Robot,
    quantities: Sequence[str] | str | None = None,
    *,
    options: Options | None = None,
    progress: bool = False,
) -> Equations:
    """Derive the requested quantities of ``robot`` in closed form (nothing else is derived); for a robot
    with mimic joints, in its independent coordinates (:mod:`jaxskid.equations._mimic`)."""
    options = options or Options()
    names = resolve(robot, quantities)
    mimic.check(robot, names, options.route)
    if robot.floating_base and options.route == "lagrange":
        raise RequestError(f"Options(route='lagrange') not available: robot {robot.name!r} has a floating base; "
                           "use the default route 'screw'")
    inputs = Inputs.of(robot)
    d = Derivation(robot, inputs, trig=options.trig, friction_smoothing=float(options.friction_smoothing),
                   coriolis=options.coriolis)
    built: dict[str, list] = {}
    for name in _progress(names, progress):
        spec = QUANTITIES[name]
        outs = _outputs(spec, d, options.route)
        size = 1
        for n in spec.shape(robot):
            size *= n
        if len(outs) != size:
            raise AssertionError(f"{name}: built {len(outs)} entries for shape {spec.shape(robot)}")
        built[name] = [sp.sympify(e) for e in outs]
    assignments, built = apply_options(list(d.tape.defs.items()), built, options)
    quantities = {
        name: Quantity(name, QUANTITIES[name].args, QUANTITIES[name].shape(robot), tuple(outs),
                       QUANTITIES[name].equation, QUANTITIES[name].doc)
        for name, outs in built.items()
    }
    return Equations(
        robot=robot,
        parameters=robot.parameters,
        param_symbols=inputs.params,
        arguments=_arguments(robot, inputs),
        quantities=quantities,
        assignments=tuple(assignments),
        options=options,
    )


def _outputs(spec, d: Derivation, route: str) -> list:
    """The flat outputs of one quantity on ``d``'s tape, by ``route``; a pullback from its quantity's outputs.
    Built once per derivation: a quantity and its pullback share them."""
    key = ("outputs", spec.name, route)
    if key not in d.memo:
        if spec.pullback_of is not None:
            base = QUANTITIES[spec.pullback_of]
            out = sym.pullback(d, _outputs(base, d, route), base.args, spec.args[-1])
        else:
            builder = spec.builder(route)
            out = mimic.build(spec.name, builder, d) if d.robot.mimic_joints else builder(d)
        d.memo[key] = out
    return d.memo[key]


def _progress(names, enabled):
    if not enabled:
        return names
    from tqdm.auto import tqdm

    return tqdm(names, desc="derive", unit="quantity", leave=False)
