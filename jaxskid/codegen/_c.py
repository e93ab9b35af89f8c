"""C99 and C++ emitters: a header with the declarations and layouts, and one source file.

C: ``<stem>.h`` / ``<stem>.c``, one function per quantity,

    void <stem>_<quantity>(const double *q, ..., const double *p, double *out);

with every array flat and row-major, plus ``<stem>_default_params`` and ``<stem>_parameter_names``.
C++: ``<stem>.hpp`` / ``<stem>.cpp``, the same functions in ``namespace <stem>``, and overloads taking and
returning ``std::array`` (``p`` defaults to ``default_params``). Both compile warning-free with
``-Wall -Wextra -Werror -pedantic``.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Iterator, Sequence

import sympy as sp
from sympy.printing.c import C99CodePrinter
from sympy.printing.cxx import CXX11CodePrinter

from .._generated import GPU_ONLY, KKT_QUANTITIES, NativeKernel, NativeSource, Statement, VectorKernel
from ._common import Program, Layout, NumberTweaks, comment, double, portable_names, shape_str, statements
from ._printing import FastArithmetic


class CPrinter(NumberTweaks, FastArithmetic, C99CodePrinter):
    """C99 expressions with jaxskid's number and power conventions."""

    def _print_sign(self, expr):
        """``copysign((double)(x != 0), x)``, a double. SymPy's ``(x > 0) - (x < 0)`` is an int, and in the
        vector kernels of :mod:`jaxskid.lowering._ffi` (GCC vector extensions) a comparison is a mask of
        -1s, read back as the bits of a double; a call keeps such a body on the scalar path."""
        x = self._print(expr.args[0])
        return f"copysign((double)(({x}) != 0), {x})"


class NoVectorForm(Exception):
    """An expression that :class:`VectorPrinter` cannot print (a call other than sine, cosine and sign)."""


class VectorPrinter(CPrinter):
    """C over vectors of states, for the kernels of :mod:`jaxskid.lowering._ffi` (GCC/Clang vector extensions):
    the scalar C's text, with sine, cosine and the sign of a variable calling the glue's lane-wise
    ``@V@sin``, ``@V@cos`` and ``@V@sign``, where ``@V@`` stands for the vector type (filled in when a library
    is built). Only sums, products, powers of a small integer exponent, numbers and these three have a vector
    form; any other expression raises :class:`NoVectorForm`."""

    def _print(self, expr, **kwargs):
        if isinstance(expr, sp.Basic) and not _has_vector_form(expr):
            raise NoVectorForm(type(expr).__name__)
        return super()._print(expr, **kwargs)

    def _lane_wise(self, expr) -> str:
        return f"@V@{type(expr).__name__}({self._print(expr.args[0])})"

    _print_sin = _print_cos = _print_sign = _lane_wise


_VECTOR_FORMS = (sp.Symbol, sp.Number, sp.NumberSymbol, sp.Add, sp.Mul, sp.sin, sp.cos)


def _has_vector_form(e) -> bool:
    """Sums, products, numbers, sine and cosine; powers of a small integer exponent (printed as products by
    NumberTweaks; the others call sqrt or pow); the sign of a variable."""
    small_power = e.is_Pow and e.exp.is_Integer and 0 < abs(int(e.exp)) <= 8
    return isinstance(e, _VECTOR_FORMS) or bool(small_power) or (isinstance(e, sp.sign) and e.args[0].is_Symbol)


def vector_kernel(k: Program, printer: VectorPrinter) -> VectorKernel | None:
    """The program of ``k`` over vectors of states, as :class:`~jaxskid._generated.Statement` objects (the
    statements of :func:`body_lines`, a number made a vector with ``@V@LIFT``), or None where it has no vector
    form (:class:`VectorPrinter`)."""

    def value(e) -> str:
        text = printer.doprint(e)
        return f"@V@LIFT({text})" if e.is_Number or e.is_NumberSymbol else text

    def reads(e) -> tuple[str, ...]:
        return tuple(sorted(s.name for s in e.free_symbols))

    try:
        lines = [Statement("unused", a, "", ()) for a in k.unused]
        lines += [Statement("input", s.name, f"{a}[{i}]", ()) for s, a, i in k.inputs]
        lines += [Statement("define", s.name, value(e), reads(e)) for s, e in k.body]
        lines += [Statement("output", str(i), value(e), reads(e)) for i, e in enumerate(k.outputs)]
    except NoVectorForm:
        return None
    zeros = tuple(i for i, e in enumerate(k.outputs) if e.is_Number and e == 0)
    return VectorKernel((*k.args, "p"), tuple(lines), zeros)


class CxxPrinter(NumberTweaks, FastArithmetic, CXX11CodePrinter):
    """C++ expressions (``std::sin``, ...) with jaxskid's number and power conventions."""

    _sqrt_name = "std::sqrt"


def body_lines(k: Program, printer, *, decl: str, indent: str = "    ", out: str = "out[{k}]") -> list[str]:
    """The statements of a C-like function body: read the inputs, assign, write the outputs."""
    lines = [f"{indent}(void){a};" for a in k.unused]
    lines += statements(k, printer, lambda a, i: f"{a}[{i}]", f"{indent}{decl} {{}} = {{}};")
    for i, e in enumerate(k.outputs):
        lines.append(f"{indent}{out.format(k=i)} = {printer.doprint(e)};")
    return lines


def _block(text: str) -> str:
    return text.replace("*/", "* /")


def _params(k: Program) -> str:
    return ", ".join([*(f"const double *{a}" for a in k.args), "const double *p", "double *out"])


def _calling(layout: Layout, cxx: bool) -> list[str]:
    s = layout.stem
    if cxx:
        return [
            f"Call: {s}::<quantity>(q, ..., p, out) with pointers to flat arrays, or with std::array arguments",
            f"(p defaults to {s}::default_params) to get a std::array back. Results are flat and row-major:",
            "entry (i, j) of an n x m result is out[i*m + j]. Indices above are 0-based.",
        ]
    return [
        f"Call: {s}_<quantity>(q, ..., p, out) with pointers to flat arrays of doubles; out has",
        f"{s.upper()}_<QUANTITY>_SIZE entries. Results are row-major: entry (i, j) of an n x m result is",
        f"out[i*m + j]. {s}_default_params holds the default p. Indices above are 0-based.",
    ]


def _initializer(values: Sequence[str]) -> str:
    rows = [", ".join(values[i:i + 4]) for i in range(0, len(values), 4)]
    return "{\n    " + ",\n    ".join(rows) + ",\n}" if rows else "{}"


def _c_double(x: float) -> str:
    return "NAN" if x != x else double(x)


def _c_string(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def emit_c(layout: Layout, bodies: Collection[str] | None = None) -> dict[str, str]:
    """``{<stem>.h, <stem>.c}``: the header declares a function per quantity; the source defines the parameter
    tables and the functions of ``bodies`` (default: every quantity)."""
    s, S = layout.stem, layout.stem.upper()
    n_par = len(layout.parameters)
    head = comment(layout.header("C99", _calling(layout, cxx=False)), "//")
    h = [head, f"#ifndef JAXSKID_{S}_H", f"#define JAXSKID_{S}_H", "", "#ifdef __cplusplus", 'extern "C" {',
         "#endif", "", f"#define {S}_N_DOF {layout.n_dof}", f"#define {S}_NQ {layout.robot.nq}",
         f"#define {S}_NV {layout.robot.nv}", f"#define {S}_N_PARAMS {n_par}"]
    for k in layout.programs:
        h.append(f"#define {S}_{k.name.upper()}_SIZE {k.size}")
    h.append("")
    if n_par:
        h += ["/* Parameter names and default values, in the order of p (NAN: no default). */",
              f"extern const char *const {s}_parameter_names[{S}_N_PARAMS];",
              f"extern const double {s}_default_params[{S}_N_PARAMS];", ""]
    for k in layout.programs:
        shapes = ", ".join(f"{a}: {shape_str(layout.arg_shape(a))}" for a in (*k.args, "p"))
        h += [f"/* {_block(k.equation)}", f" * {_block(k.doc)}",
              f" * {shapes} -> out: {shape_str(k.shape)}, row-major ({k.size} doubles). */",
              f"void {s}_{k.name}({_params(k)});", ""]
    h += ["#ifdef __cplusplus", "}", "#endif", "", f"#endif /* JAXSKID_{S}_H */", ""]

    printer = CPrinter()
    c = [head, "#include <math.h>", "", f'#include "{s}.h"', ""]
    if n_par:
        c.append(f"const char *const {s}_parameter_names[{S}_N_PARAMS] = "
                 f"{_initializer([_c_string(p) for p in layout.parameters])};")
        c.append(f"const double {s}_default_params[{S}_N_PARAMS] = "
                 f"{_initializer([_c_double(v) for v in layout.defaults])};")
        c.append("")
    for k in layout.programs:
        if bodies is None or k.name in bodies:
            c += [f"void {s}_{k.name}({_params(k)})", "{", *body_lines(k, printer, decl="const double"), "}", ""]
    return {f"{s}.h": "\n".join(h), f"{s}.c": "\n".join(c)}


FFI_QUANTITIES = ("mass_matrix", "inverse_dynamics_vjp")
"""The quantities whose C the native backward kernel of forward dynamics is built from
(:mod:`jaxskid.lowering._ffi`)."""


NATIVE_VECTORS = ("forward_dynamics", "inverse_dynamics_vjp", "mass_matrix_vjp", "coriolis_matrix_vjp",
                  "gravity_torques_vjp", "coriolis_torques_vjp", "ee_pose_vjp", "ee_hybrid_twist_vjp",
                  "external_torques_vjp")
"""Vector-valued quantities that get a native kernel too: the closed-form forward dynamics, whose XLA program
takes longest to compile (no XLA compile), and the pullbacks, long programs that reverse mode calls."""


def native_quantities(eqs, names: Sequence[str]) -> tuple[str, ...]:
    """The quantities of ``names`` that get a native kernel on CPU (:mod:`jaxskid.lowering._ffi`): those
    with matrix-valued results (M, C, the regressor, Jacobians, time derivatives, poses), whose many entries
    XLA compiles into programs whose cost grows faster than the arithmetic, and :data:`NATIVE_VECTORS`; and
    :data:`jaxskid._generated.GPU_ONLY`, whose kernel only a GPU runs. Other vectors stay in JAX, where XLA
    fuses them with the caller's program."""
    return tuple(n for n in names if len(eqs.quantities[n].shape) >= 2 or n in NATIVE_VECTORS or n in GPU_ONLY)


def native_sources(eqs, names: Sequence[str], naming=portable_names, first: Sequence[str] = ()) -> Iterator[NativeSource]:
    """The C of the native libraries of ``names``, each a :class:`~jaxskid._generated.NativeSource` built on
    its own. Its ``kernels`` list the library's :func:`native_quantities`, each a
    :class:`~jaxskid._generated.NativeKernel` (input sizes and core ranks with the parameters last, output
    size and rank); ``backward`` says whether it has the backward step of forward dynamics (when ``names`` hold
    :data:`FFI_QUANTITIES`), and with it the backward step of constrained forward dynamics when they hold
    :data:`~jaxskid._generated.KKT_QUANTITIES` too. The kernels of the quantities in ``first`` come in a library of their own,
    first; the others, with the backward step, in the next: the quantities that only come with the requested
    ones, for their derivatives. A generator: the caller can start building one library while the next is
    printed. ``naming``: the symbols' renaming (:class:`~jaxskid.codegen._common.Layout`); the JAX module's
    (:func:`jaxskid.codegen._jax.jax_names`) lets both share their kernels, and the C then sums and
    multiplies in the JAX form's order."""
    kernels = native_quantities(eqs, names)
    now = tuple(n for n in kernels if n in first)
    rest = tuple(n for n in kernels if n not in now)
    backward = set(FFI_QUANTITIES) <= set(names)
    # with the constraint quantities' pullbacks, the backward step of constrained forward dynamics too
    kkt = KKT_QUANTITIES if backward and set(KKT_QUANTITIES) <= set(names) else ()
    if now:
        yield _library(eqs, now, False, naming)
    if rest or backward:
        yield _library(eqs, rest, backward, naming, kkt)


def _library(eqs, kernels: tuple[str, ...], backward: bool, naming, kkt: tuple[str, ...] = ()) -> NativeSource:
    layout = Layout(eqs, tuple(dict.fromkeys([*(FFI_QUANTITIES if backward else ()), *kkt, *kernels])), naming)
    printer = VectorPrinter()
    vectors = {k.name: vector_kernel(k, printer) for k in layout.programs}
    # the handlers call the functions over vectors of states; the backward step falls back to the functions of
    # one state where one of its two has no vector form (jaxskid.lowering._ffi.glue_parts): only those are printed
    scalar = backward and any(vectors[n] is None for n in FFI_QUANTITIES)
    files = emit_c(layout, FFI_QUANTITIES if scalar else ())
    table = []
    for name in kernels:
        args = (*eqs.quantities[name].args, "p")
        table.append(NativeKernel(name, tuple(layout.arg_size(a) for a in args),
                                  tuple(len(layout.arg_shape(a)) for a in args),
                                  math.prod(eqs.quantities[name].shape), len(eqs.quantities[name].shape)))
    return NativeSource(layout.stem, files[f"{layout.stem}.h"], files[f"{layout.stem}.c"], backward, tuple(table),
                        vectors)


def native_block(native: Sequence[NativeSource]) -> str:
    """Python source assigning ``NATIVE_C`` (the libraries of :func:`native_sources`, as plain data) for
    appending to a generated JAX module; ``""`` for none."""
    return f"\nNATIVE_C = {tuple(n.as_dict() for n in native)!r}\n" if native else ""


def emit_cpp(layout: Layout) -> dict[str, str]:
    s, S = layout.stem, layout.stem.upper()
    n_par = len(layout.parameters)
    head = comment(layout.header("C++", _calling(layout, cxx=True)), "//")
    h = [head, f"#ifndef JAXSKID_{S}_HPP", f"#define JAXSKID_{S}_HPP", "", "#include <array>", "",
         f"namespace {s} {{", "", f"constexpr int n_dof = {layout.n_dof};",
         f"constexpr int nq = {layout.robot.nq};", f"constexpr int nv = {layout.robot.nv};",
         f"constexpr int n_params = {n_par};", "",
         "// Parameter names and default values, in the order of p (NaN: no default).",
         f"extern const std::array<const char *, {n_par}> parameter_names;",
         f"extern const std::array<double, {n_par}> default_params;", ""]
    for k in layout.programs:
        shapes = ", ".join(f"{a}: {shape_str(layout.arg_shape(a))}" for a in (*k.args, "p"))
        arrays = [f"const std::array<double, {layout.arg_size(a)}> &{a}" for a in k.args]
        arrays.append(f"const std::array<double, {n_par}> &p = default_params")
        h += [f"// {k.equation}", f"// {k.doc}", f"// {shapes} -> out: {shape_str(k.shape)}, row-major ({k.size} doubles).",
              f"void {k.name}({_params(k)});", "",
              f"inline std::array<double, {k.size}> {k.name}({', '.join(arrays)})", "{",
              f"    std::array<double, {k.size}> out{{}};",
              f"    {k.name}({', '.join(f'{a}.data()' for a in (*k.args, 'p'))}, out.data());",
              "    return out;", "}", ""]
    h += [f"}}  // namespace {s}", "", f"#endif  // JAXSKID_{S}_HPP", ""]

    printer = CxxPrinter()
    nan = "std::numeric_limits<double>::quiet_NaN()"
    c = [head, "#include <cmath>", "#include <limits>", "", f'#include "{s}.hpp"', "", f"namespace {s} {{", "",
         f"const std::array<const char *, {n_par}> parameter_names = "
         f"{_initializer([_c_string(p) for p in layout.parameters])};",
         f"const std::array<double, {n_par}> default_params = "
         f"{_initializer([nan if v != v else double(v) for v in layout.defaults])};", ""]
    for k in layout.programs:
        c += [f"void {k.name}({_params(k)})", "{", *body_lines(k, printer, decl="const double"), "}", ""]
    c += [f"}}  // namespace {s}", ""]
    return {f"{s}.hpp": "\n".join(h), f"{s}.cpp": "\n".join(c)}
