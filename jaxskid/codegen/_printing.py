"""The number rules every printer of :mod:`jaxskid.codegen` shares, the JAX target's included."""

from __future__ import annotations

import math

import sympy as sp
from sympy.core.function import Function
from sympy.printing.precedence import PRECEDENCE, precedence

_ATOM, _ADD, _MUL, _POW = (PRECEDENCE[k] for k in ("Atom", "Add", "Mul", "Pow"))


def double(x: float) -> str:
    """A float64 literal that reads back to the same double in C, C++, Julia, Matlab and Python."""
    if not math.isfinite(x):
        raise ValueError(f"cannot print the non-finite constant {x!r}")
    s = repr(float(x))
    return s if any(c in s for c in ".en") else s + ".0"


class NumberTweaks:
    """Printer mixin shared by every target (JAX, NumPy, C, C++, Cython, Julia, Matlab).

    Floats, rationals and integers print as round-trip double literals, pi and e as numbers (C99 has no
    ``M_PI``), small integer powers as products (``x*x``, ``1.0/(x*x)``) rather than a general ``pow``, and
    half-integer powers as ``sqrt``. Terms print in SymPy's stored order (``order="none"``): sorting them
    canonically took a third of the printing time.
    """

    def __init__(self, settings=None):
        super().__init__({"order": "none", **(settings or {})})

    def _print_Float(self, expr):
        return double(float(expr))

    def _print_Rational(self, expr):
        return double(float(expr))

    def _print_Integer(self, expr):
        return double(float(int(expr)))

    def _print_Pi(self, expr):
        return double(math.pi)

    def _print_Exp1(self, expr):
        return double(math.e)

    def _print_Pow(self, expr, rational=False):
        base, exp = expr.args
        if exp.is_Integer and 0 < abs(int(exp)) <= 8:
            b = self.parenthesize(base, PRECEDENCE["Mul"] + 1)
            prod = "*".join([b] * abs(int(exp)))
            return prod if exp > 0 else f"1.0/({prod})"
        if exp == sp.Rational(1, 2):
            return f"{self._sqrt_name}({self._print(base)})"
        if exp == -sp.Rational(1, 2):
            return f"1.0/{self._sqrt_name}({self._print(base)})"
        return super()._print_Pow(expr)

    _sqrt_name = "sqrt"


def _precedence(e) -> int:
    """SymPy's ``precedence(e)`` for a finite expression. For a product SymPy asks whether a minus sign can be
    taken out, which forms the product's negation (flattened and hashed again) to rule out ``zoo * x``: 40 %
    of the time to print the G1's Coriolis matrix. A finite product has a minus sign to take out exactly
    when its leading number is negative."""
    if e.is_Symbol:
        return _ATOM
    if e.is_Mul:
        if any(isinstance(a, Function) and getattr(a, "precedence", _MUL) < _MUL for a in e.args):
            return _MUL
        return _ADD if _negative(e.args[0]) else _MUL
    return precedence(e)


def _negative(c) -> bool:
    """Whether ``c`` is a negative number, without SymPy's assumption system (it deduced the facts of each
    new number: a quarter of the time to print the G1's Coriolis matrix as C)."""
    if c.is_Rational:
        return c.p < 0
    if c.is_Float:
        return bool(c < 0)
    return bool(c.is_Number and c.is_extended_negative)


class FastArithmetic:
    """Printer mixin for the targets that print sums and products as SymPy's code printers do (C, C++,
    JAX): the same text, with :func:`_precedence` in place of SymPy's. A product with a negative power in
    it (a denominator) is left to SymPy."""

    def parenthesize(self, item, level, strict=False):
        p = _precedence(item)
        return f"({self._print(item)})" if p < level or (not strict and p <= level) else self._print(item)

    def _print_Add(self, expr, order=None):
        parts = []
        for term in self._as_ordered_terms(expr, order=order):
            t = self._print(term)
            sign = "+"
            if t.startswith("-") and not term.is_Add:
                sign, t = "-", t[1:]
            parts += [sign, f"({t})" if term.is_Add or _precedence(term) < _ADD else t]
        first = parts.pop(0)
        return ("" if first == "+" else first) + " ".join(parts)

    def _handle_UnevaluatedExpr(self, expr):
        # SymPy rebuilds every expression to drop the re() of its UnevaluatedExpr nodes: a tenth of the time to
        # print the G1 with hands' Coriolis matrix, whose expressions (of real symbols) have none
        return super()._handle_UnevaluatedExpr(expr) if expr.has(sp.re) else expr

    def _print_Mul(self, expr, **kwargs):
        c, rest = expr.as_coeff_Mul()
        if c < 0:  # the factors of _keep_coeff(-c, rest), without forming that product
            sign, factors = "-", ((-c,) if c is not sp.S.NegativeOne else ()) + sp.Mul.make_args(rest)
        else:
            sign, factors = "", sp.Mul.make_args(expr)
        if any(f.is_Pow and f.exp.is_Rational and f.exp.is_negative for f in factors):
            return super()._print_Mul(expr, **kwargs)
        if sign and len(factors) == 1:  # a unary minus binds between a product and a power
            return sign + self.parenthesize(factors[0], (_POW + _MUL) / 2)
        level = _precedence(expr)
        return sign + "*".join(self.parenthesize(f, level) for f in factors)
