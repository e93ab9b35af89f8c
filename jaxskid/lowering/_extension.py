"""The ``"capi"`` backend of :mod:`._native`: the generated C wrapped in a CPython extension module of its
own, one method per quantity, called with no layer in between.

cffi and ctypes cost a few hundred nanoseconds a call in their own machinery (a buffer view per argument, a
foreign-function call); for a 3-DOF robot that is most of a call. Here each quantity is a ``METH_FASTCALL``
function of the module: it checks every argument with NumPy's C API (a C-contiguous float64 array of the
expected shape is used in place), allocates the result with ``PyArray_SimpleNew`` and calls the generated C
directly. Anything else (a list, float32, a strided view, a dict of parameters, a wrong shape) goes to Python
converters that the module is given once (:func:`configure`), so conversions and error messages are those
of the other backends.

Calling convention of every method: ``name(*state, params=None)``; ``params`` may be passed by keyword;
``None`` takes the default vector compiled into the C (``<stem>_default_params``) when every default is
known, else the converter reports the missing ones.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from ._templates import fill, template


@dataclass(frozen=True)
class Method:
    """One method of the extension: the Python name, the generated C function, the state arguments with their
    shapes, the number of parameters, the result's shape and the docstring."""

    name: str
    c_name: str
    args: tuple[tuple[str, tuple[int, ...]], ...]
    n_params: int
    out_shape: tuple[int, ...]
    doc: str






def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _method(m: Method) -> str:
    dims = "".join(f"    static const npy_intp d{k}[{max(len(s), 1)}] = {{{', '.join(map(str, s)) or '0'}}};\n"
                   for k, (_, s) in enumerate(m.args))
    loads = "".join(
        f"    a[{k}] = as_doubles(args[{k}], {len(s)}, d{k}, \"{m.name}: {a}\");\n    if (a[{k}] == NULL) goto done;\n"
        for k, (a, s) in enumerate(m.args))
    pointers = "".join(f"(const double *)PyArray_DATA(a[{k}]), " for k in range(len(m.args)))
    out_dims = ", ".join(map(str, m.out_shape)) or "1"
    return fill(template("extension_method.c"), NAME=m.name, NSTATE=max(len(m.args), 1), DIMS=dims, LOADS=loads,
                N_PARAMS=m.n_params, OUT_ND=len(m.out_shape), OUT_ALLOC=max(len(m.out_shape), 1), OUT_DIMS=out_dims,
                C_NAME=m.c_name, POINTERS=pointers)


def extension_source(stem: str, modname: str, methods: Sequence[Method]) -> str:
    """The C of the extension module ``modname`` around ``<stem>.h``: one function per :class:`Method`."""
    entries = "".join(
        f"    {{\"{m.name}\", (PyCFunction)(void (*)(void))m_{m.name}, METH_FASTCALL | METH_KEYWORDS, "
        f"{_c_string(m.doc)}}},\n" for m in methods)
    return (fill(template("extension_prelude.c"), STEM=stem) + "".join(_method(m) for m in methods)
            + fill(template("extension_module.c"), ENTRIES=entries, MODNAME=modname))
