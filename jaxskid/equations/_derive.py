"""Named equations: which quantities exist, their arguments and shapes, and how each is derived.

:func:`derive` builds only the requested quantities on one shared :class:`~jaxskid._symbolic.Tape`, so
quantities requested together share their intermediates. The result, :class:`Equations`, is what the
lowering stage (JAX) and the code generators (C, Julia, ...) print.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import sympy as sp

from .._errors import RequestError
from ..model._robot import Robot
from ..symbolic._kinematics import Kinematics, Tape

log = logging.getLogger("jaxskid")


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
class QuantitySpec:
    """How to derive a quantity: arguments, shape and a builder over :class:`Kinematics`."""

    name: str
    args: tuple[str, ...]
    shape: Callable[[Robot], tuple[int, ...]]
    build: Callable[[Kinematics], list]
    equation: str
    doc: str
    needs_end_effector: bool = False


QUANTITIES: dict[str, QuantitySpec] = {}
"""Every quantity jaxskid can derive, by name."""

DEFAULT_QUANTITIES = (
    "mass_matrix",
    "coriolis_matrix",
    "coriolis_torques",
    "gravity_torques",
    "inverse_dynamics",
    "forward_dynamics",
    "forward_kinematics",
)


def register(spec: QuantitySpec) -> QuantitySpec:
    QUANTITIES[spec.name] = spec
    return spec


def _flat(rows) -> list:
    out = []
    for r in rows:
        if isinstance(r, (list, tuple)):
            out.extend(_flat(r))
        else:
            out.append(r)
    return out


def _pose_entries(r, p) -> list:
    return [r[0][0], r[0][1], r[0][2], p[0], r[1][0], r[1][1], r[1][2], p[1], r[2][0], r[2][1], r[2][2], p[2], 0, 0, 0, 1]


def _frame_jacobians(kin: Kinematics, hybrid: bool) -> list:
    out = []
    for name in kin.robot.end_effectors:
        cols = kin.frame_jacobian(name)
        if hybrid:
            r, _ = kin.frame_pose(name)
            cols = [hybridize(kin, r, c) for c in cols]
        out.append([[cols[j][k] for j in range(kin.n)] for k in range(6)])
    return _flat(out)


def hybridize(kin: Kinematics, r, v) -> list:
    """Body-fixed 6-vector -> hybrid (frame origin, world axes): ``(R w, R v)``."""
    if all(e == 0 for e in v):
        return [sp.Integer(0)] * 6
    rw = [sum((r[a][b] * v[b] for b in range(3)), sp.Integer(0)) for a in range(3)]
    rv = [sum((r[a][b] * v[3 + b] for b in range(3)), sp.Integer(0)) for a in range(3)]
    return kin.tape.vec([*rw, *rv])


def _ext(kin: Kinematics) -> list:
    w = kin.wrench_symbols
    return kin.external_torques({name: list(w[e]) for e, name in enumerate(kin.robot.end_effectors)})


register(QuantitySpec(
    "mass_matrix", ("q",), lambda r: (r.n_dof, r.n_dof),
    lambda k: _flat(k.mass_matrix().tolist()),
    "M(q) = J^T diag(M_i) J", "Joint-space mass (inertia) matrix, symmetric positive definite.",
))
register(QuantitySpec(
    "coriolis_matrix", ("q", "qd"), lambda r: (r.n_dof, r.n_dof),
    lambda k: _flat(k.coriolis_matrix().tolist()),
    "C(q, qd) = J^T (diag(M_i) dJ/dt + B(V) J)",
    "Coriolis/centrifugal matrix; C qd are the Coriolis forces and dM/dt - 2C is skew-symmetric.",
))
register(QuantitySpec(
    "coriolis_torques", ("q", "qd"), lambda r: (r.n_dof,),
    lambda k: k.rnea(velocity=True, accel=False, gravity=False),
    "C(q, qd) qd", "Coriolis and centrifugal generalized forces (recursive Newton-Euler).",
))
register(QuantitySpec(
    "gravity_torques", ("q",), lambda r: (r.n_dof,),
    lambda k: k.rnea(velocity=False, accel=False, gravity=True),
    "Q_grav(q)", "Generalized gravity forces: the torques that hold the robot still.",
))
register(QuantitySpec(
    "inverse_dynamics", ("q", "qd", "qdd"), lambda r: (r.n_dof,),
    lambda k: k.rnea(velocity=True, accel=True, gravity=True),
    "tau = M(q) qdd + C(q, qd) qd + Q_grav(q)",
    "Joint forces for a motion (recursive Newton-Euler); add external_torques for end-effector loads.",
))
register(QuantitySpec(
    "external_torques", ("q", "wrench"), lambda r: (r.n_dof,),
    _ext,
    "Q_ext = sum_e J_e(q)^T W_e",
    "Generalized forces of end-effector wrenches W_e (moment, force) in each end-effector's frame; "
    "W_e is what the end-effector exerts on its environment, so tau = M qdd + C qd + Q_grav + Q_ext.",
    needs_end_effector=True,
))
register(QuantitySpec(
    "forward_kinematics", ("q",), lambda r: (len(r.frame_names), 4, 4),
    lambda k: _flat([_pose_entries(*k.frame_pose(name)) for name in k.robot.frame_names]),
    "C_f(q) = C_body(q) T_f", "World pose of every named frame (bodies, merged links, end-effectors).",
))
register(QuantitySpec(
    "body_jacobian", ("q",), lambda r: (len(r.end_effectors), 6, r.n_dof),
    lambda k: _frame_jacobians(k, hybrid=False),
    "V_e = J_e(q) qd, body-fixed", "Body Jacobian of each end-effector: twist (omega, v) in its own frame.",
    needs_end_effector=True,
))
register(QuantitySpec(
    "hybrid_jacobian", ("q",), lambda r: (len(r.end_effectors), 6, r.n_dof),
    lambda k: _frame_jacobians(k, hybrid=True),
    "V_e^h = J_e^h(q) qd", "Hybrid Jacobian of each end-effector: (omega, velocity of the origin) in world axes.",
    needs_end_effector=True,
))


@dataclass(frozen=True)
class Options:
    """How the closed form is built: a trade between derive time, run time and round-off.

    Attributes:
        cse: ``"tape"`` (default) names every intermediate and shares identical ones; ``"sympy"`` also
            runs ``sympy.cse`` over the whole program; ``"none"`` substitutes everything into one tree
            per output entry (Skidy's form: it swells quickly beyond 3-4 joints).
        simplify: ``"none"`` (default), ``"expand"`` (``sympy.expand`` of each assignment) or
            ``"trigsimp"`` (``sympy.trigsimp`` of each assignment).
        trig: ``"symbols"`` (default) names sin(q_i) and cos(q_i) once; ``"inline"`` leaves the calls
            in place.
    """

    cse: str = "tape"
    simplify: str = "none"
    trig: str = "symbols"

    def __post_init__(self):
        for field_name, allowed in (("cse", ("tape", "sympy", "none")), ("simplify", ("none", "expand", "trigsimp")),
                                    ("trig", ("symbols", "inline"))):
            value = getattr(self, field_name)
            if value not in allowed:
                raise RequestError(f"Options.{field_name}: expected one of {', '.join(allowed)}, got {value!r}")


def _postprocess(assignments: list, outputs: dict, options: Options) -> tuple[list, dict]:
    """Apply the simplification level and CSE strategy to a derived program."""
    if options.simplify != "none":
        simp = sp.expand if options.simplify == "expand" else sp.trigsimp
        assignments = [(s, simp(e)) for s, e in assignments]
        outputs = {k: [simp(e) for e in v] for k, v in outputs.items()}
    if options.cse == "none":
        values: dict = {}
        for s, e in assignments:
            values[s] = e.xreplace(values)
        return [], {k: [sp.sympify(e).xreplace(values) for e in v] for k, v in outputs.items()}
    if options.cse == "sympy":
        keys = list(outputs)
        sizes = [len(outputs[k]) for k in keys]
        flat = [e for _, e in assignments] + [sp.sympify(e) for k in keys for e in outputs[k]]
        repl, reduced = sp.cse(flat, symbols=sp.numbered_symbols("_c", real=True), order="none")
        na = len(assignments)
        merged = [*repl, *((s, reduced[i]) for i, (s, _) in enumerate(assignments))]
        rest, new_outputs, i = reduced[na:], {}, 0
        for k, size in zip(keys, sizes):
            new_outputs[k] = rest[i:i + size]
            i += size
        return _toposort(merged), new_outputs
    return assignments, outputs


def _toposort(assignments: list) -> list:
    defined = {s for s, _ in assignments}
    by_symbol = dict(assignments)
    order, done = [], set()
    for s, _ in assignments:
        stack = [(s, False)]
        while stack:
            sym, expanded = stack.pop()
            if sym in done:
                continue
            if expanded:
                done.add(sym)
                order.append((sym, by_symbol[sym]))
                continue
            stack.append((sym, True))
            stack.extend((d, False) for d in by_symbol[sym].free_symbols if d in defined and d not in done)
    return order


@dataclass(frozen=True)
class Equations:
    """The requested quantities of one robot as a shared straight-line program.

    ``assignments`` are ``(symbol, expression)`` pairs in dependency order; each quantity's outputs are
    expressions of these symbols, of the argument symbols and of the parameter symbols.
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
        raise RequestError(
            f"unknown quantity {', '.join(map(repr, unknown))}; available: {', '.join(sorted(QUANTITIES))}"
        )
    if not robot.end_effectors:
        if quantities is None or quantities == "all":
            names = [q for q in names if not QUANTITIES[q].needs_end_effector]
        else:
            bad = [q for q in names if QUANTITIES[q].needs_end_effector]
            if bad:
                raise RequestError(f"{', '.join(bad)} need an end-effector, and robot {robot.name!r} has none")
    order = list(QUANTITIES)
    return tuple(sorted(dict.fromkeys(names), key=order.index))


def derive(
    robot: Robot,
    quantities: Sequence[str] | str | None = None,
    *,
    options: Options | None = None,
    progress: bool = False,
) -> Equations:
    """Derive the requested quantities of ``robot`` in closed form (nothing else is derived)."""
    options = options or Options()
    names = resolve(robot, quantities)
    kin = Kinematics(robot, Tape(), trig=options.trig)
    n = robot.n_dof
    n_ee = len(robot.end_effectors)
    wrench = tuple(sp.Symbol(f"_w{e}_{k}", real=True) for e in range(n_ee) for k in range(6))
    kin.wrench_symbols = [wrench[6 * e: 6 * e + 6] for e in range(n_ee)]
    arguments = {
        k: Argument(k, (n,), tuple(kin.state[k]), doc)
        for k, doc in (
            ("q", "joint positions"),
            ("qd", "joint velocities"),
            ("qdd", "joint accelerations"),
            ("q3d", "joint jerks"),
            ("q4d", "joint jounces"),
        )
    }
    kin.tau_symbols = tuple(sp.Symbol(f"_tau{i}", real=True) for i in range(n))
    arguments["tau"] = Argument("tau", (n,), kin.tau_symbols, "joint forces")
    arguments["wrench"] = Argument("wrench", (n_ee, 6), wrench, "end-effector wrenches (moment, force)")
    for k, doc in (("wrench_d", "first time derivatives of the end-effector wrenches"),
                   ("wrench_dd", "second time derivatives of the end-effector wrenches")):
        syms = tuple(sp.Symbol(f"_{k}{e}_{c}", real=True) for e in range(n_ee) for c in range(6))
        setattr(kin, f"{k}_symbols", [syms[6 * e: 6 * e + 6] for e in range(n_ee)])
        arguments[k] = Argument(k, (n_ee, 6), syms, doc)
    built: dict[str, list] = {}
    for name in _progress(names, progress):
        spec = QUANTITIES[name]
        outs = spec.build(kin)
        size = 1
        for d in spec.shape(robot):
            size *= d
        if len(outs) != size:
            raise AssertionError(f"{name}: built {len(outs)} entries for shape {spec.shape(robot)}")
        built[name] = [sp.sympify(e) for e in outs]
    assignments, built = _postprocess(list(kin.tape.defs.items()), built, options)
    quantities = {
        name: Quantity(name, QUANTITIES[name].args, QUANTITIES[name].shape(robot), tuple(outs),
                       QUANTITIES[name].equation, QUANTITIES[name].doc)
        for name, outs in built.items()
    }
    return Equations(
        robot=robot,
        parameters=robot.parameters,
        param_symbols=tuple(kin.params),
        arguments=arguments,
        quantities=quantities,
        assignments=tuple(assignments),
        options=options,
    )


def _progress(names, enabled):
    if not enabled:
        return names
    from tqdm.auto import tqdm

    return tqdm(names, desc="derive", unit="quantity", leave=False)
