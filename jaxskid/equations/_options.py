"""How the closed form is built (:class:`Options`), and how a derived program is reshaped by them."""

from __future__ import annotations

import math
from dataclasses import dataclass

import sympy as sp

from .._errors import RequestError

_ALLOWED = {
    "cse": ("tape", "sympy", "none"),
    "simplify": ("none", "expand", "trigsimp"),
    "trig": ("symbols", "inline"),
    "route": ("screw", "lagrange"),
    "coriolis": ("christoffel", "skidy"),
}


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
        friction_smoothing: Coulomb friction of the joints' drives (:class:`jaxskid.Drive`): ``0`` (default)
            ``fc sign(qd)``, exact, with zero derivative in qd; ``eps > 0`` ``fc tanh(qd / eps)``, smooth, for
            stiff integration and gradients through rollouts (rad/s or m/s; the regressor's Coulomb columns
            follow).
        route: how M, C qd, Q_grav, tau and the kinetic energy are derived. ``"screw"`` (default): the
            Lie-group recursions (Newton-Euler, composite rigid body). ``"lagrange"``: the Euler-Lagrange
            equations of the link energies (:mod:`jaxskid.symbolic._lagrange`), the seed blog's route, a
            larger program. Every other quantity is the same on both routes.
        coriolis: the factorisation of the Coriolis matrix ``coriolis_matrix`` and its time derivatives
            (:mod:`jaxskid.symbolic._coriolis`); ``C qd`` is the same for both. ``"christoffel"`` (default):
            Christoffel-consistent, ``dM/dt - 2C`` skew-symmetric, as Pinocchio's ``computeCoriolisMatrix``.
            ``"skidy"``: ``C = -J^T (M A a + b^T M) J`` of Müller & Kumar (2021), as Skidy computes it.
    """

    cse: str = "tape"
    simplify: str = "none"
    trig: str = "symbols"
    route: str = "screw"
    friction_smoothing: float = 0.0
    coriolis: str = "christoffel"

    def __post_init__(self):
        for field_name, allowed in _ALLOWED.items():
            value = getattr(self, field_name)
            if value not in allowed:
                raise RequestError(f"Options.{field_name}: expected one of {', '.join(allowed)}, got {value!r}")
        eps = self.friction_smoothing
        if isinstance(eps, bool) or not isinstance(eps, (int, float)) or not math.isfinite(eps) or eps < 0:
            raise RequestError(f"Options.friction_smoothing: expected a finite number >= 0 (0: sign), got {eps!r}")


def apply_options(assignments: list, outputs: dict, options: Options) -> tuple[list, dict]:
    """Apply the simplification level and CSE strategy to a derived program.

    ``assignments`` are ``(symbol, expression)`` pairs in dependency order and ``outputs`` maps each
    quantity to its output expressions; returns both, reshaped.
    """
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
        return _sympy_cse(assignments, outputs)
    return assignments, outputs


def _sympy_cse(assignments: list, outputs: dict) -> tuple[list, dict]:
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


def _toposort(assignments: list) -> list:
    """The assignments in dependency order; ties keep the given order, so the result is reproducible."""
    position = {s: k for k, (s, _) in enumerate(assignments)}
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
            deps = [d for d in by_symbol[sym].free_symbols if d in position and d not in done]
            stack.extend((d, False) for d in sorted(deps, key=position.__getitem__, reverse=True))
    return order
