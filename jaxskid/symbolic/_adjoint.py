"""Reverse-mode differentiation of the tape: closed-form vector-Jacobian products.

Given outputs ``y(x)`` built on a :class:`~jaxskid.symbolic.Tape` and weights ``w``, :func:`vjp` names on the
same tape the gradient of ``w^T y`` with respect to chosen inputs ``x``. It is the adjoint sweep of
reverse-mode automatic differentiation (Griewank & Walther, "Evaluating Derivatives", 2nd ed., 2008,
sec. 3.2) run once, symbolically, over the straight-line program: every named intermediate ``s = e(a, b,
...)`` gets an adjoint ``s_bar``, the sum of the adjoints of its users, and passes ``s_bar de/da`` on to each
of its arguments. The result is a straight-line program a few times the length of the one it
differentiates, printed and compiled like every other quantity: the derivative of inverse dynamics that a
step of a differentiable simulation needs (:mod:`jaxskid.runtime._forward`), without asking JAX to transpose
a long program on every trace.
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
        for a in expr.free_symbols:
            if a in tape.defs or a in wanted:
                da = expr.diff(a)
                if da != 0:
                    bar.setdefault(a, []).append(weight * da)

    wanted = set(wrt)
    for y, w in zip(outputs, weights, strict=True):
        spread(sp.sympify(y), w)
    for s in reversed(list(tape.defs)):
        terms = bar.pop(s, None)
        if terms:
            spread(tape.defs[s], tape(sp.Add(*terms)))
    return [tape(sp.Add(*bar.get(x, ()))) for x in wrt]


def inverse_dynamics_vjp(d: Derivation) -> list:
    """``(w^T dtau/dq, w^T dtau/dqd, w^T dtau/dp)`` of inverse dynamics at fixed ``qdd``, with ``w`` the
    input ``cotangent``: ``2 n + n_params`` entries."""
    tau = inverse_dynamics(d)
    return vjp(d, tau, d.inputs.cotangent, (*d.q, *d.qd, *d.inputs.params))
