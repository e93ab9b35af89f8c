"""The tape: a straight-line SymPy program of named intermediates.

Expression swell is what makes closed-form equations of motion slow to derive and slow to run. jaxskid
never multiplies the products out: every intermediate quantity (relative poses, twists, accelerations,
wrenches, composite inertias) is *named* on a :class:`Tape` as soon as it is formed, so each new
expression is a few operations on earlier names, and identical sub-expressions share one name
(hash-consing). The result is a DAG of small assignments; the lowering stage prunes it to what a quantity
needs and prints it.
"""

from __future__ import annotations

import sympy as sp


class Tape:
    """Records named intermediate expressions ``_x{k} = expr`` in creation order, sharing duplicates."""

    def __init__(self, prefix: str = "_x"):
        self.prefix = prefix
        self.defs: dict[sp.Symbol, sp.Expr] = {}
        self._lookup: dict[sp.Expr, sp.Symbol] = {}
        self._terms: dict[frozenset, sp.Symbol] = {}  # _terms(e) -> the name of e, to find -e without forming it

    def __call__(self, e) -> sp.Expr:
        """The name of ``e`` (a new one, or the one it already has; ``-name`` for ``-e``); atoms and
        ``number * atom`` are returned as they are."""
        e = sp.sympify(e)
        if _is_trivial(e):
            return e
        hit = self._lookup.get(e)
        if hit is not None:
            return hit
        terms = _terms(e)
        neg = self._terms.get(frozenset((-c, t) for c, t in terms))
        if neg is not None:
            return -neg
        s = sp.Symbol(f"{self.prefix}{len(self.defs)}", real=True)
        self.defs[s] = e
        self._lookup[e] = s
        self._terms[terms] = s
        return s

    def define(self, name: sp.Symbol, e) -> None:
        """Record ``name = e`` as the next assignment, under a name of the caller's (an input that other
        inputs determine, such as a mimic joint's position)."""
        e = sp.sympify(e)
        if name in self.defs:
            raise ValueError(f"{name} is already defined on the tape")
        self.defs[name] = e
        self._lookup.setdefault(e, name)
        self._terms.setdefault(_terms(e), name)

    def vec(self, es) -> list:
        """Each entry of ``es`` named, in order."""
        return [self(e) for e in es]


def _terms(e: sp.Expr) -> frozenset:
    """The terms of ``e`` as ``(number, rest)`` pairs. SymPy keeps a sum's like terms collected (one term per
    ``rest``), so two expressions are equal exactly when their pairs are, and ``-e`` has every number
    negated: the tape finds a negated expression from these without forming it (SymPy's negation of a sum
    builds and flattens every term again, a quarter of the G1's Coriolis derivation)."""
    return frozenset(t.as_coeff_Mul() for t in sp.Add.make_args(e))


def _is_trivial(e: sp.Expr) -> bool:
    if e.is_Atom:
        return True
    if e.is_Mul and len(e.args) == 2 and e.args[0].is_Number and e.args[1].is_Atom:
        return True
    return False
