"""The one program representation every target prints, and what the emitters share.

Each generated function is the program of one quantity (``Equations.program([name])``), pruned to the
assignments it needs and to the input entries it reads (:class:`Program`), printed as one assignment per
line, so common subexpressions stay shared exactly as the derivation named them. A :class:`Layout` is a
request (equations and quantity names) with the programs of its quantities, the header every file starts
with and the metadata the runtime reads.

Symbols are renamed by the layout's ``naming``. :func:`portable_names` gives names that are valid in every
target language: the inputs ``q_0``, ``qd_3``, ... (flat, 0-based), the parameters ``p_0``, ``p_1``, ...
(in the order of ``Equations.parameters``) and the intermediates ``x0``, ``x1``, .... The JAX target keeps
the derivation's own names (:func:`jaxskid.codegen._jax.jax_names`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import cached_property

import sympy as sp

from .._errors import RequestError
from .._version import __version__
from ..equations._derive import Equations
from ..model._constraint import n_rows
from ..model._standard import standard_parameter_names
from ._printing import NumberTweaks, double  # noqa: F401  (re-exported for the emitters)

# Words that cannot be a module, namespace or function name in one of the target languages.
_RESERVED = frozenset(
    "and as assert async await auto begin break case catch char class const continue def default del do double "
    "elif else end enum except export extern false finally float for from function global goto if import in "
    "inline int is lambda let local long macro module namespace new nonlocal not or otherwise pass quote raise "
    "register restrict return short signed sizeof static struct switch template this throw true try typedef "
    "typename union unsigned using void volatile while with yield".split()
)


def stem(robot_name: str) -> str:
    """The identifier the generated files and functions are named after (``"Panda arm"`` -> ``panda_arm``)."""
    s = re.sub(r"[^0-9A-Za-z_]+", "_", robot_name).strip("_").lower()[:40] or "robot"
    if s[0].isdigit() or s in _RESERVED:
        s = f"robot_{s}"
    return s


@dataclass(frozen=True)
class Program:
    """One quantity as a straight-line program over renamed symbols.

    ``inputs`` are the entries of the arguments (and of ``p``) that the program reads, as
    ``(local symbol, argument name, flat 0-based index)``; ``body`` the assignments in order; ``outputs``
    the entries of the result, flat and row-major.
    """

    name: str
    args: tuple[str, ...]
    shape: tuple[int, ...]
    equation: str
    doc: str
    inputs: tuple[tuple[sp.Symbol, str, int], ...]
    body: tuple[tuple[sp.Symbol, sp.Expr], ...]
    outputs: tuple[sp.Expr, ...]

    @property
    def size(self) -> int:
        return math.prod(self.shape)

    @property
    def unused(self) -> tuple[str, ...]:
        """Arguments (``p`` included) that the program does not read."""
        used = {a for _, a, _ in self.inputs}
        return tuple(a for a in (*self.args, "p") if a not in used)


SHAPES = ("jaxskid", "skidy")


@dataclass(frozen=True)
class CodeStyle:
    """How generated files present the equations; the numbers they compute do not change.

    Attributes:
        shapes: ``"jaxskid"`` (default): outputs have the quantity's shape, a vector ``(n,)``; ``"skidy"``:
            a vector is an ``(n, 1)`` column, as Skidy's generated functions return it (the ``"jax"``
            target keeps the runtime's shapes; C and C++ write the same ``n`` doubles either way).
        landscape: the LaTeX document on landscape pages, for long equations (Skidy's ``landscape=True``).
        project: a project name every file's header states (Skidy's ``--project``); ``None``: none.
    """

    shapes: str = "jaxskid"
    landscape: bool = False
    project: str | None = None

    def __post_init__(self):
        if self.shapes not in SHAPES:
            raise RequestError(f"CodeStyle.shapes: expected one of {', '.join(SHAPES)}, got {self.shapes!r}")
        if not isinstance(self.landscape, bool):
            raise RequestError(f"CodeStyle.landscape: expected true or false, got {self.landscape!r}")
        if self.project is not None and (not isinstance(self.project, str) or not self.project.strip()
                                         or "\n" in self.project):
            raise RequestError(f"CodeStyle.project: expected a one-line name, got {self.project!r}")


def portable_names(eqs: Equations) -> dict:
    """Symbol -> a name valid in every target language: ``q_0``, ``p_0``, ``x0`` (module docstring)."""
    ren: dict = {}
    for a, arg in eqs.arguments.items():
        for k, s in enumerate(arg.symbols):
            ren[s] = sp.Symbol(f"{a}_{k}", real=True)
    for k, s in enumerate(eqs.param_symbols):
        ren[s] = sp.Symbol(f"p_{k}", real=True)
    for k, (s, _) in enumerate(eqs.assignments):
        ren[s] = sp.Symbol(f"x{k}", real=True)
    return ren


@dataclass(frozen=True)
class Layout:
    """A request as the emitters see it: the robot, its arguments, parameters and defaults, and the
    programs of the quantities ``names`` with their symbols renamed by ``naming`` (a function
    ``Equations -> {symbol: new symbol}``; a symbol it leaves out keeps its name), presented in ``style``."""

    eqs: Equations
    names: tuple[str, ...]
    naming: Callable[[Equations], dict] = portable_names
    style: CodeStyle = CodeStyle()

    @property
    def robot(self):
        return self.eqs.robot

    @cached_property
    def stem(self) -> str:
        return stem(self.robot.name)

    @property
    def n_dof(self) -> int:
        return self.robot.n_dof

    @property
    def parameters(self) -> tuple[str, ...]:
        return tuple(self.eqs.parameters)

    @cached_property
    def defaults(self) -> tuple[float, ...]:
        """Default value of every parameter, NaN where the robot gives none."""
        d = self.robot.default_params()
        return tuple(float(d.get(k, math.nan)) for k in self.parameters)

    @property
    def uses_wrench(self) -> bool:
        """Whether a quantity takes an (n_ee, 6) wrench argument."""
        return any(len(self.arg_shape(a)) == 2 for k in self.programs for a in k.args)

    def arg_shape(self, arg: str) -> tuple[int, ...]:
        return (len(self.parameters),) if arg == "p" else tuple(self.eqs.arguments[arg].shape)

    def arg_size(self, arg: str) -> int:
        return math.prod(self.arg_shape(arg))

    @cached_property
    def programs(self) -> tuple[Program, ...]:
        """The programs of ``names``, made once per equations, quantity and naming: the layouts of one
        lowering (the JAX module and its native C) share them (for the G1's Coriolis matrix, seconds)."""
        made = self.eqs.__dict__.setdefault("_programs", {})  # frozen, but this cache is its own
        renamed = self.eqs.__dict__.setdefault("_renamed", {}).setdefault(self.naming, {})
        rename = None
        for n in self.names:
            if (n, self.naming) not in made:
                rename = self.naming(self.eqs) if rename is None else rename
                made[(n, self.naming)] = program(self.eqs, n, rename, renamed)
        programs = tuple(made[(n, self.naming)] for n in self.names)
        if self.style.shapes == "skidy":  # vectors as (n, 1) columns
            programs = tuple(replace(k, shape=(*k.shape, 1)) if len(k.shape) == 1 else k for k in programs)
        return programs

    @property
    def kernels(self) -> tuple[Program, ...]:
        """Deprecated: :attr:`programs` ("kernel" now means only the native kernels of the runtime)."""
        import warnings

        warnings.warn("Layout.kernels is deprecated: use Layout.programs", DeprecationWarning, stacklevel=2)
        return self.programs

    def metadata(self) -> dict:
        """What the runtime needs to call the generated functions, as plain JSON data: ``robot``,
        ``joint_names``, ``frame_names``, ``end_effectors``, ``parameters`` (the order of ``p``),
        ``defaults`` (name -> value, for the parameters that have one), ``quantities`` (name ->
        ``args``, ``shape``, ``equation``, ``doc``), ``standard_names`` (the regressor's columns,
        :func:`~jaxskid.standard_parameter_names`), only for a robot with drives, ``driven`` (the names of
        the joints that have one: their friction and offset are in tau and the bias, not in C qd + Q_grav),
        and only for a floating base, ``floating_base: 1`` (``q`` has ``7 + n`` entries, velocities ``6 + n``; an
        int, since the JAX module writes this as a Python literal), only for ``Options(coriolis="skidy")``,
        ``coriolis: "skidy"``, and only for a robot with constraints, ``constraint_rows`` (their number of rows,
        the size of ``cotangent_rows``)."""
        r = self.robot
        quantities = {n: self.eqs.quantities[n] for n in self.names}
        driven = {"driven": [r.joints[i].name for i in r.driven]} if r.driven else {}
        if r.floating_base:
            driven["floating_base"] = 1
        if self.eqs.options.coriolis != "christoffel":
            driven["coriolis"] = self.eqs.options.coriolis
        if r.constraints:
            driven["constraint_rows"] = n_rows(r.constraints)
        return {
            "robot": r.name,
            "joint_names": list(r.joint_names),
            "frame_names": list(r.frame_names),
            "end_effectors": list(r.end_effectors),
            "parameters": list(self.parameters),
            "defaults": r.default_params(),
            "standard_names": list(standard_parameter_names(r)),
            "quantities": {n: quantity_metadata(q.args, q.shape, q.equation, q.doc) for n, q in quantities.items()},
            **driven,
        }

    def header(self, target: str, calling: Sequence[str], *, base: int = 0) -> list[str]:
        """The header every generated file starts with (without comment markers).

        ``calling`` describes how the target's functions are called; ``base`` is the index base of the
        target language, used in the parameter table.
        """
        r = self.robot
        lines = [
            f"Generated by jaxskid {__version__} ({target}) for robot {r.name!r}: "
            f"{r.n_dof} joint(s), {len(self.parameters)} parameter(s). Do not edit.",
            *([f"Project: {self.style.project}"] if self.style.project else []),
            "",
            "Quantities (name(arguments) -> shape: equation):",
        ]
        for k in self.programs:
            lines.append(f"  {k.name}({', '.join((*k.args, 'p'))}) -> {_shape_str(k.shape)}: {k.equation}")
            lines.append(f"      {k.doc}")
        lines += ["", "Arguments (float64):"]
        args = [a for a in self.eqs.arguments if any(a in k.args for k in self.programs)]
        joints = ", ".join(r.joint_names)
        for a in args:
            arg = self.eqs.arguments[a]
            what = f"{arg.doc}, in joint order" if arg.shape == (r.n_dof,) else arg.doc
            lines.append(f"  {a:<6} {_shape_str(arg.shape):<8} {what}")
            if len(arg.shape) == 2:
                lines.append(f"         one row (moment, force) per end-effector: {', '.join(r.end_effectors)}")
        lines.append(f"  joint order: {joints}")
        lines.append(f"  {'p':<6} {_shape_str((len(self.parameters),)):<8} parameters, in this order (default value):")
        for i, (name, value) in enumerate(zip(self.parameters, self.defaults)):
            shown = "no default" if math.isnan(value) else repr(value)
            lines.append(f"    {i + base:>4}  {name} = {shown}")
        if "forward_kinematics" in self.names:
            lines.append("forward_kinematics: one 4x4 pose per frame, frames in this order:")
            lines.append(f"  {', '.join(r.frame_names)}")
        for name in ("body_jacobian", "hybrid_jacobian"):
            if name in self.names:
                lines.append(f"{name}: one 6 x {r.n_dof} Jacobian (rows omega, v) per end-effector, in this order:")
                lines.append(f"  {', '.join(r.end_effectors)}")
        lines += ["", *calling]
        return lines


def quantity_metadata(args: Sequence[str], shape: Sequence[int], equation: str, doc: str) -> dict:
    """A quantity's entry in a generated module's ``METADATA["quantities"]`` (:meth:`Layout.metadata`)."""
    return {"args": list(args), "shape": list(shape), "equation": equation, "doc": doc}


def program(eqs: Equations, name: str, rename: dict, renamed: dict) -> Program:
    """The program of one quantity, pruned and renamed (see the module docstring). ``renamed``: the renamed
    assignments by symbol, shared by the programs of one renaming (their programs overlap: forward dynamics
    holds most of the mass matrix and inverse dynamics)."""
    qty = eqs.quantities[name]
    prog = eqs.program([name])
    used: set = set()
    body = []
    for s, e in prog:
        free = e.free_symbols
        used |= free
        if s not in renamed:
            renamed[s] = e if rename.keys().isdisjoint(free) else e.xreplace(rename)
        body.append((rename.get(s, s), renamed[s]))
    outputs = []
    for e in qty.outputs:
        e = sp.sympify(e)
        used |= e.free_symbols
        outputs.append(e.xreplace(rename))
    inputs = []
    for a in qty.args:
        for k, s in enumerate(eqs.arguments[a].symbols):
            if s in used:
                inputs.append((rename.get(s, s), a, k))
    for k, s in enumerate(eqs.param_symbols):
        if s in used:
            inputs.append((rename.get(s, s), "p", k))
    return Program(name, tuple(qty.args), tuple(qty.shape), qty.equation, qty.doc, tuple(inputs), tuple(body),
                  tuple(outputs))


def statements(k: Program, printer, read: Callable[[str, int], str], assign: str = "{} = {}") -> list[str]:
    """The straight-line body of a generated function, one line per input entry it reads and per
    assignment: ``assign.format(name, value)``, where an input's value is ``read(argument, flat index)``
    and an assignment's is the printed expression."""
    lines = [assign.format(s.name, read(a, i)) for s, a, i in k.inputs]
    lines += [assign.format(s.name, printer.doprint(e)) for s, e in k.body]
    return lines


def _shape_str(shape: Sequence[int]) -> str:
    return "(" + ", ".join(map(str, shape)) + ("," if len(shape) == 1 else "") + ")"


def shape_str(shape: Sequence[int]) -> str:
    """``(7,)``, ``(7, 7)``: a shape as Python writes it."""
    return _shape_str(shape)


def unravel(k: int, shape: Sequence[int]) -> tuple[int, ...]:
    """Row-major multi-index of the flat index ``k``."""
    idx = []
    for d in reversed(shape):
        idx.append(k % d)
        k //= d
    return tuple(reversed(idx))


def comment(lines: Sequence[str], marker: str) -> str:
    """``lines`` as line comments (``//``, ``#``, ``%``), without trailing blanks."""
    return "\n".join(f"{marker} {line}".rstrip() for line in lines) + "\n"
