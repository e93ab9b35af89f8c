"""The number rules every printer of :mod:`jaxskid.codegen` shares, the JAX target's included."""

from __future__ import annotations

import math

import sympy as sp
from sympy.printing.precedence import PRECEDENCE


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
