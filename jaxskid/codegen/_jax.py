"""JAX emitter: ``<stem>_jax.py``, the module :func:`jaxskid.lower` generates, caches and loads.

The module has one pure function per quantity, ``name(*state, p) -> array``, for a single state; batching
is ``jax.vmap``'s job. It carries the fused helpers of :mod:`jaxskid._fused` and ``METADATA``, what the
runtime needs to call it (:meth:`jaxskid.codegen.Layout.metadata`).

Output form. How the result array is assembled decides how fast XLA on CPU runs the function in a batch.
``python benchmarks/output_forms.py`` measures the forms on the Panda (float64, batch 65536, per state):

- ``jnp.stack`` / ``jnp.array([...])`` of the entries: XLA computes each distinct entry in a kernel of
  its own that redoes the shared work;
- one chain ``jnp.where(index == k, value_k, out)`` over the flattened entries: the shared work is
  hoisted out of the loop over entries, but every entry runs the whole chain of compares and selects
  against an index held in memory, n^2 selects for n entries;
- nested chains, one per axis, on ``lax.broadcasted_iota`` of that axis: the innermost index is a loop
  constant after unrolling, so those selects fold away, and the outer chains select whole rows (faster
  still with the fusible sine and cosine of :mod:`jaxskid._fused`);
- the same, with every input entry first broadcast to the output's shape (what is generated): every
  operation is then elementwise on one shape, so XLA's estimate of how often a shared value would be
  recomputed stays low and the whole function is one kernel (the Coriolis matrix: one kernel instead of
  153). The shared work still runs once per state:
  it depends only on the state, and LLVM hoists it out of the loops over the entries.

Names. The program keeps the derivation's own symbol names (``_q1``, ``_x27``) and the parameters are
``_p0``, ``_p1``, ... (:func:`jax_names`): SymPy orders the terms of a sum or product by their symbols'
names, and with these names the generated code, and its rounding, stays what it has been.
"""

from __future__ import annotations

import json
import math

import sympy as sp
from sympy.printing.numpy import JaxPrinter as _SympyJaxPrinter
from sympy.printing.precedence import PRECEDENCE

from .._fused import SOURCE as FUSED_SOURCE
from ..equations._derive import Equations
from ._common import Program, Layout, NumberTweaks, statements, unravel
from ._printing import FastArithmetic

GENERATOR_VERSION = "25"
"""Changes whenever the generated module changes, so that cached modules of an older generator are not reused."""


class JaxPrinter(NumberTweaks, FastArithmetic, _SympyJaxPrinter):
    """JAX printer with the shared number rules (:class:`~jaxskid.codegen._printing.NumberTweaks`): plain
    Python float literals are weakly typed, so constants take the inputs' dtype. Sine, cosine and
    negative powers call the fused helpers of :mod:`jaxskid._fused`."""

    _sqrt_name = "jax.numpy.sqrt"

    def __init__(self):
        super().__init__({"fully_qualified_modules": True, "inline": True, "allow_unknown_functions": False})

    def _print_Pow(self, expr, rational=False):
        base, exp = expr.args
        if exp.is_Integer and -8 <= int(exp) < 0 or exp == -sp.Rational(1, 2):  # 1/x by Newton (jaxskid._fused)
            return f"_recip({self._print(sp.Pow(base, -exp, evaluate=False))})"
        return super()._print_Pow(expr, rational)

    def _print_Mul(self, expr):
        # sympy prints a/b for negative powers inside a product; keep them as factors so that
        # _print_Pow turns them into _recip
        factors = [self._print_Pow(f) if f.is_Pow and f.exp.is_Rational and f.exp < 0 else None for f in expr.args]
        if not any(factors):
            return super()._print_Mul(expr)
        rest = sp.Mul(*[f for f, printed in zip(expr.args, factors) if printed is None], evaluate=False)
        parts = [p for p in factors if p] + ([self.parenthesize(rest, PRECEDENCE["Mul"])] if rest != 1 else [])
        return "*".join(parts)

    def _print_sin(self, expr):
        return f"_sin({self._print(expr.args[0])})"

    def _print_cos(self, expr):
        return f"_cos({self._print(expr.args[0])})"


def jax_names(eqs: Equations) -> dict:
    """The renaming of the JAX target: parameters become ``_p0``, ``_p1``, ...; every other symbol keeps
    the derivation's name (see the module docstring)."""
    return {s: sp.Symbol(f"_p{k}", real=True) for k, s in enumerate(eqs.param_symbols)}


def assembly_shape(shape: tuple[int, ...]) -> tuple[int, ...]:
    """The shape a result is built in: ``shape``, except that a long vector (more than 32 entries) is built
    as a matrix of about ``sqrt(N)`` rows and columns (zero-padded) and reshaped on return. A chain of
    selects over one long axis costs each entry the whole chain; two short ones cost about ``2 sqrt(N)``
    (the vector-Jacobian product of the Panda's inverse dynamics, 84 entries, ran several times faster
    as a 6 x 14 or 12 x 7 matrix than as a vector)."""
    if len(shape) != 1 or shape[0] <= 32:
        return shape
    cols = math.isqrt(shape[0] - 1) + 1
    return (-(-shape[0] // cols), cols)


def _assemble(shape: tuple[int, ...], outputs: tuple, printer: JaxPrinter, dtype: str) -> list[str]:
    """Lines that build the output array (see the module docstring) and return it."""
    if not shape:
        value = "0.0" if outputs[0] == 0 else printer.doprint(outputs[0])
        return [f"return jnp.zeros((), {dtype}) + {value}"]
    built = assembly_shape(shape)
    if built != shape:
        size = len(outputs)
        outputs = tuple(outputs) + (0,) * (built[0] * built[1] - size)
        lines = _assemble(built, outputs, printer, dtype)
        lines[-1] = f"return ({lines[-1][len('return '):]}).reshape(-1)[:{size}]"
        return lines
    lines = [f"_z = jnp.zeros({shape!r}, {dtype})"]
    lines += [f"_i{a} = jax.lax.broadcasted_iota(jnp.int32, {shape!r}, {a})" for a in range(len(shape))]
    stride = [1] * len(shape)
    for a in reversed(range(len(shape) - 1)):
        stride[a] = stride[a + 1] * shape[a + 1]
    count = [0]

    def build(axis: int, offset: int) -> str:
        """Expression for the block of entries from ``offset`` that share the indices before ``axis``."""
        acc, depth = "_z", 0
        for i in range(shape[axis]):
            k = offset + i * stride[axis]
            if axis == len(shape) - 1:
                if outputs[k] == 0:
                    continue
                value = printer.doprint(outputs[k])
            else:
                value = build(axis + 1, k)
                if value == "_z":
                    continue
                if len(value) > 60:  # name a nested block once rather than repeat it inline
                    count[0] += 1
                    lines.append(f"_b{count[0]} = {value}")
                    value = f"_b{count[0]}"
            acc = f"jnp.where(_i{axis} == {i}, {value}, {acc})"
            depth += 1
            if depth == _MAX_NESTING:  # Python's parser refuses 200 nested parentheses: name the chain so far
                count[0] += 1
                lines.append(f"_b{count[0]} = {acc}")
                acc, depth = f"_b{count[0]}", 0
        return acc

    lines.append(f"return {build(0, 0)}")
    return lines


_MAX_NESTING = 64
"""Selects nested in one expression of an output's where chain, at most (see :func:`_assemble`)."""


def computed_order(k: Program) -> list[int]:
    """The flat indices of ``k``'s structurally nonzero entries in the order its program computes them (by the
    last statement each reads; row-major among equals). Entries computed near each other share most of their
    statements, which is what :mod:`jaxskid.runtime._gathered` groups them by."""
    position = {s: i for i, (s, _) in enumerate(k.body)}

    def last(i: int) -> int:
        return max((position.get(s, -1) for s in k.outputs[i].free_symbols), default=-1)

    return sorted((i for i, v in enumerate(k.outputs) if v != 0), key=last)


def function_source(layout: Layout, k: Program, printer: JaxPrinter) -> str:
    """Source of one quantity: ``_name(*args, p, spread, entries=False)``, the program (``spread`` broadcasts
    each input entry to the output's shape, or is the identity; ``entries=True`` returns the structurally
    nonzero entries by flat index, unassembled, for a quantity with a shape), and ``name(*args, p)``, the ``jax.custom_jvp``
    that runs it broadcast and differentiates it unbroadcast (see the module docstring and
    :mod:`jaxskid._fused`)."""
    args = ", ".join((*k.args, "p"))

    def read(a: str, i: int) -> str:
        return f"spread({a}[{', '.join(map(str, unravel(i, layout.arg_shape(a))))}])"

    lines = [f"def _{k.name}({args}, spread{', entries=False' if k.shape else ''}):"]
    lines += ["    " + line for line in statements(k, printer, read)]
    if k.shape:  # the entries form: the structurally nonzero entries by flat index, unassembled
        nonzero = ", ".join(f"{i}: {printer.doprint(k.outputs[i])}" for i in computed_order(k))
        lines += ["    if entries:", f"        return {{{nonzero}}}"]
    lines += ["    " + line for line in _assemble(k.shape, k.outputs, printer, f"jnp.result_type({k.args[0]}, p)")]
    spread = f"_spread({assembly_shape(k.shape)!r})" if k.shape else "_same"
    lines += [
        "",
        "",
        "@jax.custom_jvp",
        f"def {k.name}({args}):",
        f'    """{k.equation}: {k.doc}"""',
        f"    return _{k.name}({args}, {spread})",
        "",
        "",
        f"{k.name}.defjvp(_plain_jvp(_{k.name}))",
    ]
    return "\n".join(lines) + "\n"


def module_source(layout: Layout) -> str:
    """The complete module for the quantities of ``layout`` (which must use :func:`jax_names`)."""
    header = [
        f"# Generated by jaxskid (generator {GENERATOR_VERSION}) for robot {layout.robot.name!r}.",
        f"# Quantities: {', '.join(layout.names)}.",
        "# Each function takes the state arrays named in its signature, shape (n,), and p, the parameter",
        "# vector in the order of METADATA['parameters']; it returns one array. Batch with jax.vmap.",
        "import jax",
        "import jax.numpy as jnp",
        FUSED_SOURCE,
        f"METADATA = {json.dumps(layout.metadata())}",  # in order: the quantities as the catalogue lists them
        "",
    ]
    printer = JaxPrinter()
    body = "\n\n".join(function_source(layout, k, printer) for k in layout.programs)
    return "\n".join(header) + "\n" + body


def emit_jax(layout: Layout) -> dict[str, str]:
    """``{<stem>_jax.py: module}``, for a layout made with :func:`jax_names`."""
    return {f"{layout.stem}_jax.py": module_source(layout)}
