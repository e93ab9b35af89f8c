"""Matlab/Octave emitter: one function file per quantity, ``<stem>_<quantity>.m``, plus
``<stem>_default_params.m`` and ``<stem>_parameter_names.m``.

``out = <stem>_<quantity>(q, ..., p)`` takes vectors (``wrench``: an ``n_ee x 6`` matrix) and returns an
array of the quantity's shape (vectors as columns); ``p`` may be left out for the defaults.
"""

from __future__ import annotations

from sympy.printing.octave import OctaveCodePrinter

from ._common import Layout, NumberTweaks, comment, double, shape_str, statements, unravel


class OctavePrinter(NumberTweaks, OctaveCodePrinter):
    """Scalar Matlab/Octave expressions with jaxskid's number and power conventions."""

    def __init__(self):
        super().__init__({"allow_unknown_functions": False})


def _string(s: str) -> str:
    return "'" + s.replace("'", "''") + "'"


def _size(shape) -> str:
    return f"{shape[0]}, 1" if len(shape) == 1 else ", ".join(map(str, shape))


def emit_matlab(layout: Layout) -> dict[str, str]:
    s = layout.stem
    calling = [
        f"Call: out = {s}_<quantity>(q, ..., p); leave p out for {s}_default_params(). Vectors are columns"
        + ("; wrenches are n_ee x 6 matrices." if layout.uses_wrench else "."),
        "The numbered parameter list above is 1-based, as p(k).",
    ]
    head = comment(layout.header("Matlab/Octave", calling, base=1), "%")
    printer = OctavePrinter()

    def read(a: str, i: int) -> str:
        return f"{a}({', '.join(str(j + 1) for j in unravel(i, layout.arg_shape(a)))})"

    files: dict[str, str] = {}
    values = "; ".join("NaN" if v != v else double(v) for v in layout.defaults)
    files[f"{s}_default_params.m"] = (
        f"function p = {s}_default_params()\n"
        f"%{s.upper()}_DEFAULT_PARAMS Default parameter vector ({len(layout.parameters)} x 1, NaN: no default).\n"
        f"%   Order: {s}_parameter_names().\n{head}p = [{values}];\nend\n"
    )
    names = "; ".join(_string(n) for n in layout.parameters)
    files[f"{s}_parameter_names.m"] = (
        f"function names = {s}_parameter_names()\n"
        f"%{s.upper()}_PARAMETER_NAMES Names of the entries of p, as a cell column.\n{head}names = {{{names}}};\nend\n"
    )
    for k in layout.programs:
        fn = f"{s}_{k.name}"
        args = (*k.args, "p")
        lines = [f"function out = {fn}({', '.join(args)})",
                 f"%{fn.upper()} {k.equation}",
                 f"%   {k.doc}",
                 f"%   out = {fn}({', '.join(args)}) -> size {shape_str(k.shape)}; p is optional.",
                 head.rstrip("\n"),
                 f"if nargin < {len(args)}",
                 f"  p = {s}_default_params();",
                 "end"]
        for a in args:
            shape = layout.arg_shape(a)
            want = f"[{shape[0]} 1]" if len(shape) == 1 else f"[{' '.join(map(str, shape))}]"
            check = f"numel({a}) ~= {shape[0]}" if len(shape) == 1 else f"~isequal(size({a}), {want})"
            msg = _string(f"{fn}: {a}: expected size {shape_str(shape)}")
            lines += [f"if {check}", f"  error('jaxskid:size', {msg});", "end"]
        lines += statements(k, printer, read, "{} = {};")
        lines.append(f"out = zeros({_size(k.shape)});")
        for i, e in enumerate(k.outputs):
            if e != 0:
                idx = ", ".join(str(j + 1) for j in unravel(i, k.shape))
                lines.append(f"out({idx}) = {printer.doprint(e)};")
        lines.append("end")
        files[f"{fn}.m"] = "\n".join(lines) + "\n"
    return files
