"""What a scalar expression of a description may contain, and its value in floating point without SymPy.

A description's numbers and expressions become SymPy expressions that every code generator prints (JAX, C,
C++, Cython, NumPy, Julia, Matlab, LaTeX). Only what all of them print is allowed: numbers, ``pi``, parameter
names, ``+ - * / **`` and the elementary functions of :data:`FUNCTIONS`. SymPy parses much more (``Max``,
``Integral``, ``LambertW``, ``Lambda``); such an expression would pass the checks and fail later, in a
printer or inside a compiled function, far from the file.

Exact arithmetic is also a hazard at load: SymPy evaluates ``10**10**10`` exactly (ten billion digits) while
it parses, and ``float(exp(exp(exp(100))))`` runs mpmath for as long as the number has digits. So text is first
parsed unevaluated and its numbers are evaluated in floating point (:func:`float_value`): a number beyond the
range of a double is refused before SymPy ever computes it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import sympy as sp
from sympy.core.function import AppliedUndef, Application

FUNCTIONS = {
    sp.sin: math.sin, sp.cos: math.cos, sp.tan: math.tan, sp.cot: lambda x: 1 / math.tan(x),
    sp.sec: lambda x: 1 / math.cos(x), sp.csc: lambda x: 1 / math.sin(x),
    sp.asin: math.asin, sp.acos: math.acos, sp.atan: math.atan, sp.atan2: math.atan2,
    sp.sinh: math.sinh, sp.cosh: math.cosh, sp.tanh: math.tanh,
    sp.asinh: math.asinh, sp.acosh: math.acosh, sp.atanh: math.atanh,
    sp.exp: math.exp, sp.log: math.log, sp.Abs: abs, sp.sign: lambda x: float((x > 0) - (x < 0)),
    sp.floor: math.floor, sp.ceiling: math.ceil,
}
"""The functions a scalar may call, with their floating-point values."""

ALLOWED = "numbers, pi, parameter names, + - * / ** and " + ", ".join(sorted(f.__name__ for f in FUNCTIONS))


def unsupported(expr: sp.Basic) -> str | None:
    """The first part of ``expr`` that is not allowed (module docstring), as ``function 'Max'``, ``unknown function
    'f'``, ``term 'Integral'`` or ``imaginary unit 'I'``, or None."""
    for node in sp.preorder_traversal(expr):
        if isinstance(node, (sp.Symbol, sp.Number, sp.Add, sp.Mul, sp.Pow)) or node in (sp.pi, sp.E):
            continue
        if isinstance(node, sp.Function) and node.func in FUNCTIONS:
            continue
        if isinstance(node, AppliedUndef):
            return f"unknown function {type(node).__name__!r}"
        if node == sp.I:
            return "imaginary unit 'I'"
        called = isinstance(node, Application)  # sin(x), Max(x, y); not Integral, Lambda
        return f"{'function' if called else 'term'} {type(node).__name__!r}"
    return None


class _Overflow(Exception):
    pass


def float_value(expr: sp.Basic, values: Mapping | None = None) -> float | None:
    """``expr`` in double precision, evaluated or not: ``inf`` where a part overflows, ``nan`` outside a
    function's domain (or a complex result), None where a symbol has no value in ``values`` (symbol ->
    number) or a part is not allowed (:func:`unsupported`)."""
    try:
        return _value(expr, values or {})
    except _Overflow:
        return math.inf
    except (ValueError, TypeError, ZeroDivisionError):
        return math.nan
    except RecursionError:
        return None


def _value(node, values):
    if isinstance(node, sp.Symbol):
        return None if node not in values else float(values[node])
    if isinstance(node, sp.Number) or node in (sp.pi, sp.E):
        x = float(node)
        if math.isinf(x):
            raise _Overflow
        return x
    args = [_value(a, values) for a in node.args]
    if None in args:
        return None
    try:
        if isinstance(node, sp.Add):
            x = math.fsum(args)
        elif isinstance(node, sp.Mul):
            x = math.prod(args)
        elif isinstance(node, sp.Pow):
            x = _power(*args)
        elif isinstance(node, sp.Function) and node.func in FUNCTIONS:
            x = float(FUNCTIONS[node.func](*args))
        else:
            return None
    except OverflowError:
        raise _Overflow from None
    if math.isinf(x):
        raise _Overflow
    return x


def _power(base: float, exponent: float) -> float:
    if base < 0 and exponent != int(exponent):
        return math.nan  # not a real number
    if base == 0 and exponent < 0:
        raise ZeroDivisionError
    return math.pow(base, exponent)


_PERIODIC = (sp.sin, sp.cos, sp.tan, sp.cot, sp.sec, sp.csc)
FAR_ANGLE = 1e4
"""Constant angles from this magnitude on are evaluated when read: the generated JAX programs' sine and cosine
reduce their argument exactly only below it (:mod:`jaxskid._fused`)."""


def folded(expr: sp.Expr) -> sp.Expr:
    """``expr`` with every periodic function of a constant angle of magnitude :data:`FAR_ANGLE` or more replaced by
    its value (``sin(10**15)``: the 17 significant digits SymPy computes)."""

    def far(e) -> bool:
        if not (isinstance(e, sp.Function) and e.func in _PERIODIC) or e.free_symbols:
            return False
        x = float_value(e.args[0])
        return x is not None and math.isfinite(x) and abs(x) >= FAR_ANGLE

    return expr.replace(far, lambda e: sp.Float(e.evalf(17), 17)) if expr.has(*_PERIODIC) else expr
