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

    def __call__(self, e) -> sp.Expr:
        """The name of ``e`` (a new one, or the one it already has; ``-name`` for ``-e``); atoms and
        ``number * atom`` are returned as they are."""
        e = sp.sympify(e)
        if _is_trivial(e):
            return e
        hit = self._lookup.get(e)
        if hit is not None:
            return hit
        neg = self._lookup.get(-e)
        if neg is not None:
            return -neg
        s = sp.Symbol(f"{self.prefix}{len(self.defs)}", real=True)
        self.defs[s] = e
        self._lookup[e] = s
        return s

    def define(self, name: sp.Symbol, e) -> None:
        """Record ``name = e`` as the next assignment, under a name of the caller's (an input that other
        inputs determine, such as a mimic joint's position)."""
        e = sp.sympify(e)
        if name in self.defs:
            raise ValueError(f"{name} is already defined on the tape")
        self.defs[name] = e
        self._lookup.setdefault(e, name)

    def vec(self, es) -> list:
        """Each entry of ``es`` named, in order."""
        return [self(e) for e in es]


def _is_trivial(e: sp.Expr) -> bool:
    if e.is_Atom:
        return True
    if e.is_Mul and len(e.args) == 2 and e.args[0].is_Number and e.args[1].is_Atom:
        return True
    return False
