"""The shortcuts of the symbolic stages change nothing they produce.

- The tape finds a negated expression from its terms (:func:`jaxskid.symbolic._tape._terms`) rather than
  forming the negation: checked against SymPy's own negation on sums, products and functions.
- The C, C++ and JAX printers print sums and products with a precedence that skips SymPy's negation of
  each product (:class:`jaxskid.codegen._printing.FastArithmetic`): every statement of two robots' programs
  and a list of awkward expressions print exactly as SymPy's own methods print them.
"""

from __future__ import annotations

import pytest
import sympy as sp
from sympy.printing.codeprinter import CodePrinter
from sympy.printing.str import StrPrinter

import jaxskid
from helpers import load
from jaxskid.codegen import _printing
from jaxskid.codegen._c import CPrinter, CxxPrinter
from jaxskid.codegen._jax import JaxPrinter
from jaxskid.symbolic import Tape

x, y, z, w = sp.symbols("x y z w", real=True)

AWKWARD = [
    x * y + 2 * z - 3, -x * y, -x, -2 * x, -(x + y) * z, (x - y) * (z + w), -sp.Rational(3, 2) * x * (y - 1),
    sp.Float(-0.25) * x + y, x / y, -x / (y * z), -1 / (x + y), x ** 2 * y - z ** 3, -(x + 1) ** 2,
    sp.sqrt(x + y) - sp.sin(x) * sp.cos(y), -sp.sin(x), -sp.sin(x) * y, sp.sign(x) * y - z, x - (y - z) * w,
    1 - x, -1 + x * sp.Rational(-5, 7), (-x) ** 3, x ** -2 * y, sp.Float(1e-300) * x - sp.Float(-1e300) * y,
]


def _program(name: str, quantities) -> list:
    eqs = jaxskid.derive(load(name), quantities)
    exprs = [e for n in eqs.quantities for _, e in eqs.program([n])]
    return exprs + [sp.sympify(e) for n in eqs.quantities for e in eqs.quantities[n].outputs]


@pytest.fixture(scope="module")
def expressions():
    return AWKWARD + _program("hopping_leg", "all") + _program("arm_3dof", ["coriolis_matrix", "regressor"])


@pytest.mark.parametrize("printer", [CPrinter, CxxPrinter, JaxPrinter])
def test_printers_print_what_sympy_prints(printer, expressions, monkeypatch):
    fast = [printer().doprint(e) for e in expressions]
    monkeypatch.setattr(_printing.FastArithmetic, "parenthesize", StrPrinter.parenthesize)
    monkeypatch.setattr(_printing.FastArithmetic, "_print_Add", StrPrinter._print_Add)
    monkeypatch.setattr(_printing.FastArithmetic, "_print_Mul", CodePrinter._print_Mul)
    sympys = [printer().doprint(e) for e in expressions]
    assert len(expressions) > 200
    for e, a, b in zip(expressions, fast, sympys):
        assert a == b, f"{e}: {a!r} != {b!r}"


@pytest.mark.parametrize("e", [x * y + 2 * z - 3, x * y, -x * y * z, sp.sin(x) * y, sp.cos(x + y), x ** 2 - y,
                               sp.Rational(2, 3) * x - sp.Float(0.5) * y * z + 1])
def test_tape_names_a_negated_expression_by_the_name_of_the_expression(e):
    tape = Tape()
    name = tape(e)
    assert tape(e) == name
    assert tape(-e) == -name  # SymPy's negation, found without forming it
    assert tape(sp.expand(-e)) == -name
    assert tape(e + 1) not in (name, -name)
    assert list(tape.defs.values()).count(e) == 1 and -e not in tape.defs.values()


def test_tape_keeps_different_expressions_apart():
    tape = Tape()
    names = [tape(e) for e in (x * y + z, x * y - z, 2 * x * y + z, x * y + 2 * z, x * (y + z), x * y * z)]
    assert all(n.is_Symbol for n in names) and len(set(names)) == len(names)
    assert tape(z - x * y) == -names[1] and tape(-x * y - 2 * z) == -names[3]
