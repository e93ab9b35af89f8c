"""Symbolic identities: two derived closed forms compared exactly, not at sample points.

:func:`closed_form` substitutes a quantity's program into its outputs (one expression per entry, the form
Skidy prints); :func:`vanishes` decides whether an expression of sines and cosines of the joint positions is
identically zero. It writes ``s_i = sin(q_i)`` and ``c_i = cos(q_i)``, expands the polynomial, and reduces it
modulo ``s_i^2 + c_i^2 - 1``. These relations form a Groebner basis (their leading terms ``c_i^2`` are
coprime in the lexicographic order with the ``c_i`` first), so the remainder is zero exactly when the
expression is (Cox, Little & O'Shea, "Ideals, Varieties, and Algorithms", 4th ed., 2015, ch. 2 sec. 6,
Corollary 2). Numbers in the expressions are kept as they are: a float round-off makes the answer False.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ..equations import Equations


def closed_form(eqs: Equations, name: str) -> list[sp.Expr]:
    """The outputs of quantity ``name`` of ``eqs`` with every intermediate substituted, row-major."""
    values: dict = {}
    for s, e in eqs.program([name]):
        values[s] = e.xreplace(values)
    return [sp.sympify(e).xreplace(values) for e in eqs.quantities[name].outputs]


def vanishes(expr: sp.Expr, q: Sequence[sp.Symbol]) -> bool:
    """True if ``expr``, a polynomial in ``sin(q_i)``, ``cos(q_i)`` and other symbols (and rational
    functions of the other symbols), is identically zero."""
    s = [sp.Dummy(f"s{i}") for i in range(len(q))]
    c = [sp.Dummy(f"c{i}") for i in range(len(q))]
    trig = {**{sp.sin(x): si for x, si in zip(q, s)}, **{sp.cos(x): ci for x, ci in zip(q, c)}}
    e = sp.together(sp.expand_trig(sp.sympify(expr)).xreplace(trig))
    numerator = sp.expand(sp.numer(e))
    if numerator == 0:
        return True
    if numerator.has(*q):
        raise ValueError("vanishes: the expression has the joint positions outside sin(q_i) and cos(q_i)")
    others = sorted(numerator.free_symbols - set(s) - set(c), key=str)
    _, remainder = sp.reduced(numerator, [ci**2 + si**2 - 1 for si, ci in zip(s, c)], *c, *s, *others, order="lex")
    return sp.expand(remainder) == 0
