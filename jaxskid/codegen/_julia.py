"""Julia emitter: ``<stem>.jl``, a module with one function per quantity.

``name(q, ..., p=DEFAULT_PARAMS)`` takes vectors (``wrench``: an ``n_ee x 6`` matrix) and returns an array
of the quantity's shape, with the element type promoted from the inputs (so dual numbers pass through).
"""

from __future__ import annotations

from sympy.printing.julia import JuliaCodePrinter

from ._common import Layout, NumberTweaks, comment, double, shape_str, statements, unravel


class JuliaPrinter(NumberTweaks, JuliaCodePrinter):
    """Scalar Julia expressions with jaxskid's number and power conventions."""

    def __init__(self):
        super().__init__({"allow_unknown_functions": False})


def _string(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"').replace("$", "\\$") + '"'


def _jl_float(x: float) -> str:
    return "NaN" if x != x else double(x)


def emit_julia(layout: Layout) -> dict[str, str]:
    s = layout.stem
    r = layout.robot
    calling = [
        f"Use: include(\"{s}.jl\"); using .{s}",
        "Call: name(q, ..., p=DEFAULT_PARAMS) -> Array of the shape above"
        + ("; wrenches are n_ee x 6 matrices." if layout.uses_wrench else "."),
        "The numbered parameter list above is 1-based, as p[k] in Julia.",
    ]
    printer = JuliaPrinter()

    def read(a: str, i: int) -> str:
        return f"{a}[{', '.join(str(j + 1) for j in unravel(i, layout.arg_shape(a)))}]"

    out = [comment(layout.header("Julia", calling, base=1), "#").rstrip("\n"), "",
           f"module {s}", "", f"export {', '.join(layout.names)}", "",
           f"const ROBOT = {_string(r.name)}",
           f"const JOINT_NAMES = [{', '.join(_string(n) for n in r.joint_names)}]",
           f"const FRAME_NAMES = [{', '.join(_string(n) for n in r.frame_names)}]",
           f"const END_EFFECTORS = String[{', '.join(_string(n) for n in r.end_effectors)}]",
           f"const PARAMETERS = String[{', '.join(_string(n) for n in layout.parameters)}]",
           f"const DEFAULT_PARAMS = Float64[{', '.join(_jl_float(v) for v in layout.defaults)}]", ""]
    for k in layout.programs:
        sig = [f"{a}::{'AbstractMatrix' if len(layout.arg_shape(a)) == 2 else 'AbstractVector'}" for a in k.args]
        sig.append("p::AbstractVector=DEFAULT_PARAMS")
        out += ['"""', f"    {k.name}({', '.join((*k.args, 'p'))}) -> Array, size {shape_str(k.shape)}", "",
                _string(f"{k.equation}: {k.doc}")[1:-1], '"""', f"function {k.name}({', '.join(sig)})"]
        for a in (*k.args, "p"):
            shape = layout.arg_shape(a)
            what = _string(f"{k.name}: {a}: expected size {shape_str(shape)}")
            out.append(f"    size({a}) == {shape_str(shape)} || throw(DimensionMismatch({what}))")
        out += ["    " + line for line in statements(k, printer, read)]
        eltypes = ", ".join(f"eltype({a})" for a in (*k.args, "p"))
        out.append(f"    out = zeros(promote_type({eltypes}), {', '.join(map(str, k.shape))})")
        for i, e in enumerate(k.outputs):
            if e != 0:
                idx = ", ".join(str(j + 1) for j in unravel(i, k.shape))
                out.append(f"    out[{idx}] = {printer.doprint(e)}")
        out += ["    return out", "end", ""]
    out += [f"end  # module {s}", ""]
    return {f"{s}.jl": "\n".join(out)}
