"""Differentiation of the tape: closed-form vector-Jacobian products (reverse mode) and directional
derivatives (forward mode).

Given outputs ``y(x)`` built on a :class:`~jaxskid.symbolic.Tape` and weights ``w``, :func:`vjp` names on the
same tape the gradient of ``w^T y`` with respect to chosen inputs ``x``. It is the adjoint sweep of
reverse-mode automatic differentiation (Griewank & Walther, "Evaluating Derivatives", 2nd ed., 2008,
sec. 3.2) run once, symbolically, over the straight-line program: every named intermediate ``s = e(a, b,
...)`` gets an adjoint ``s_bar``, the sum of the adjoints of its users, and passes ``s_bar de/da`` on to each
of its arguments. The result is a straight-line program a few times the length of the one it
differentiates, printed and compiled like every other quantity: the derivative of inverse dynamics that a
step of a differentiable simulation needs (:mod:`jaxskid.runtime._forward`), without asking JAX to transpose
a long program on every trace.

:func:`jvp` is the forward sweep: every named intermediate that depends on the seeded inputs gets a tangent,
``s_dot = sum_a (de/da) a_dot``, named on the tape. With the seeds ``q_i -> qd_i`` it is the chain-rule time
derivative along a motion at rest in acceleration (the Euler-Lagrange route, :mod:`._lagrange`).
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ._derivation import Derivation
from ._rnea import inverse_dynamics


def vjp(d: Derivation, outputs: Sequence, weights: Sequence, wrt: Sequence[sp.Symbol]) -> list:
    """``d(w^T y)/dx``: one entry per symbol of ``wrt``, named on ``d``'s tape.

    Args:
        d: the derivation whose tape the outputs are built on.
        outputs: the expressions ``y`` (of tape names and inputs).
        weights: ``w``, one expression per output (usually input symbols).
        wrt: the input symbols ``x`` to differentiate with respect to.
    """
    tape = d.tape
    bar: dict[sp.Symbol, list] = {}

    def spread(expr: sp.Expr, weight) -> None:
        for a, da in partials(expr).items():
            if a in live and da != 0:
                bar.setdefault(a, []).append(weight * da)

    wanted = set(wrt)
    live = set(wanted)  # the inputs of wrt and the intermediates that depend on them: the rest have no share
    for s, e in tape.defs.items():
        if not live.isdisjoint(e.free_symbols):
            live.add(s)
    for y, w in zip(outputs, weights, strict=True):
        spread(sp.sympify(y), w)
    for s in reversed(list(tape.defs)):
        terms = bar.pop(s, None)
        if terms:
            spread(tape.defs[s], tape(sp.Add(*terms)))
    return [tape(sp.Add(*bar.get(x, ()))) for x in wrt]


def jvp(d: Derivation, outputs: Sequence, seeds: Sequence[tuple[sp.Symbol, sp.Expr]]) -> list:
    """``sum_x x_dot dy/dx``: the directional derivative of each output along the tangents ``seeds``
    (``(input symbol, tangent)`` pairs; other inputs are held fixed), named on ``d``'s tape.

    The tangents of named intermediates are memoised on ``d`` per ``seeds``, so later calls with the same
    seeds reuse them.
    """
    seeds = tuple(seeds)
    dot = d.memo.setdefault(("jvp", seeds), dict(seeds))
    tape = d.tape
    outputs = [sp.sympify(y) for y in outputs]
    need, stack = set(), [a for y in outputs for a in y.free_symbols]
    while stack:
        a = stack.pop()
        if a in tape.defs and a not in dot and a not in need:
            need.add(a)
            stack.extend(tape.defs[a].free_symbols)
    order = {s: k for k, s in enumerate(tape.defs)} if need else {}
    for s in sorted(need, key=order.__getitem__):
        dot[s] = tape(_tangent(tape.defs[s], dot))
    return [tape(_tangent(y, dot)) for y in outputs]


def _tangent(expr: sp.Expr, dot: dict) -> sp.Expr:
    return sp.Add(*(da * dot[a] for a, da in partials(expr).items() if dot.get(a, 0) != 0))


def partials(expr: sp.Expr) -> dict[sp.Symbol, sp.Expr]:
    """``{a: d expr / d a}`` for every free symbol ``a`` of ``expr``, in one pass over its terms.

    The tape's assignments are short sums of products of names and numbers; for a term ``c x^k y ...`` the
    partial in ``x`` is ``c k x^(k-1) y ...``. Other terms (a sine, a product with a sum inside) go to
    ``sympy.diff``. ``expr.diff(a)`` for each ``a`` instead would walk a sum once per symbol in it.
    """
    if expr.is_Symbol:
        return {expr: sp.Integer(1)}
    out: dict[sp.Symbol, list] = {}
    for term in expr.args if expr.is_Add else (expr,):
        if term.is_Number:
            continue
        coeff, factors = term.as_coeff_mul(rational=False)  # a float coefficient too, not a factor
        simple = all(f.is_Symbol or (f.is_Pow and f.base.is_Symbol and f.exp.is_Integer and f.exp > 0)
                     for f in factors)
        if not simple:
            for a in term.free_symbols:
                out.setdefault(a, []).append(term.diff(a))
            continue
        for k, f in enumerate(factors):
            base, power = (f, 1) if f.is_Symbol else (f.base, f.exp)
            rest = sp.Mul(*factors[:k], *factors[k + 1:])
            out.setdefault(base, []).append(coeff * power * base ** (power - 1) * rest)
    return {a: sp.Add(*terms) for a, terms in out.items()}


def pullback(d: Derivation, outputs: Sequence, args: Sequence[str], cotangent: str) -> list:
    """The vector-Jacobian product of a quantity with respect to all its inputs: ``d(w^T y)/dx`` for ``x`` the
    state arguments ``args`` in order (``"q"``, ``"qd"``, ...), then the parameters, with ``w`` the input
    ``cotangent`` (one of :data:`~jaxskid.symbolic.COTANGENTS`: ``"cotangent"`` for a vector in velocity space,
    ``"cotangent_matrix"`` for a square matrix, ``"cotangent_ee"`` for a 6-vector and ``"cotangent_pose"`` for a
    pose per end-effector, row-major like ``outputs``)."""
    wrt = [s for a in args for s in d.inputs.by_name(a)]
    return vjp(d, outputs, d.inputs.by_name(cotangent), (*wrt, *d.inputs.params))


def inverse_dynamics_vjp(d: Derivation) -> list:
    """``(w^T dtau/dq, w^T dtau/dqd, w^T dtau/dp)`` of inverse dynamics at fixed ``qdd``, with ``w`` the
    input ``cotangent``: ``nq + nv + n_params`` entries (a floating base's derivatives with respect to its
    position, quaternion and twist first in the q and qd parts)."""
    tau = inverse_dynamics(d)
    return vjp(d, tau, d.inputs.cotangent, (*d.inputs.coordinate(0), *d.inputs.coordinate(1), *d.inputs.params))
