"""Code generation: print derived :class:`~jaxskid.Equations` for other languages.

One entry point, :func:`generate`, and one emitter per target (:data:`TARGETS`):

=========  ======================================================================
``jax``    ``<stem>_jax.py``: the module :func:`jaxskid.lower` generates and caches
``python`` ``<stem>_numpy.py``: NumPy, single states or batches with leading axes
``c``      ``<stem>.h`` and ``<stem>.c`` (C99)
``cpp``    ``<stem>.hpp`` and ``<stem>.cpp`` (C++17, ``namespace <stem>``)
``cython`` ``<stem>_cython.pyx`` and ``build_<stem>_cython.py``, which builds it in place
``julia``  ``<stem>.jl``: ``module <stem>``
``matlab`` ``<stem>_<quantity>.m`` per quantity (Matlab and GNU Octave), and the defaults
``latex``  ``<stem>.tex``: the equations as a document
=========  ======================================================================

Every target prints the same program representation (:class:`Layout`, :class:`Program`: the pruned
straight-line program of each quantity) with its own printer; the number rules are shared
(:mod:`jaxskid.codegen._printing`).

``<stem>`` is the robot's name made an identifier (:func:`stem`). Every generated function takes the
symbolic parameters as its last input ``p`` (in the order of ``Equations.parameters``) with the robot's
``assignments`` as defaults, prints the quantity's straight-line program so that common subexpressions
are computed once, and every file starts with a header naming the robot, the quantities and the layout of
each argument.

Example::

    eqs = jaxskid.derive(robot, ["mass_matrix", "inverse_dynamics"])
    paths = jaxskid.codegen.generate(eqs, "c", "generated/arm")

Several targets of one request can share the renamed programs: pass the same :class:`Layout`
(``layout = Layout(eqs, names)``) to :func:`emit` for each target.

A :class:`CodeStyle` changes how the files present the equations, not what they compute: Skidy's ``(n, 1)``
columns for vectors (``shapes="skidy"``), a landscape LaTeX page, a project name in every header::

    jaxskid.codegen.generate(eqs, "python", "out", style=jaxskid.codegen.CodeStyle(shapes="skidy"))
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from .._errors import RequestError
from ..equations._derive import Equations
from ._c import emit_c, emit_cpp
from ._common import CodeStyle, Layout, Program, portable_names, stem
from ._cython import emit_cython
from ._jax import emit_jax, jax_names
from ._julia import emit_julia
from ._latex import emit_latex
from ._matlab import emit_matlab
from ._python import emit_numpy


@dataclass(frozen=True)
class Target:
    """A code generation target: its name, a description, its emitter ``Layout -> {file name: text}``
    and the renaming of symbols its layout uses (:attr:`Layout.naming`)."""

    name: str
    description: str
    emit: Callable[[Layout], dict[str, str]]
    naming: Callable[[Equations], dict] = portable_names


TARGETS: dict[str, Target] = {
    t.name: t
    for t in (
        Target("jax", "JAX module, as jaxskid.lower generates it", emit_jax, jax_names),
        Target("python", "Python module using NumPy", emit_numpy),
        Target("c", "C99 source and header", emit_c),
        Target("cpp", "C++ source and header", emit_cpp),
        Target("cython", "Cython module and its build script", emit_cython),
        Target("julia", "Julia module", emit_julia),
        Target("matlab", "Matlab/Octave function files", emit_matlab),
        Target("latex", "LaTeX document", emit_latex),
    )
}
"""Every target :func:`generate` knows, by name."""


def emit(eqs: Equations | Layout, target: str, names: Sequence[str] | None = None, *,
         style: CodeStyle | None = None) -> dict[str, str]:
    """The files of ``target`` for the quantities ``names`` (default: all of ``eqs``), as
    ``{file name: text}``, without writing anything. Quantities appear in the order of ``eqs.quantities``.

    ``eqs`` may be a :class:`Layout` (then ``names`` must be None): its renamed programs serve every
    target that uses its naming, so emitting several targets of one request renames them once.
    ``style`` (:class:`CodeStyle`, default: the Layout's own, else ``CodeStyle()``) presents the files; the
    ``"jax"`` target keeps the runtime's shapes.
    """
    if target not in TARGETS:
        raise RequestError(f"unknown target {target!r}; targets are {', '.join(TARGETS)}")
    naming = TARGETS[target].naming
    if isinstance(eqs, Layout):
        if names is not None:
            raise RequestError("emit: pass the quantity names in the Layout, not beside it")
        style = style or eqs.style
        layout = eqs if eqs.naming is naming else Layout(eqs.eqs, eqs.names, naming)
    else:
        layout = Layout(eqs, _requested(eqs, names), naming)
    style = style or CodeStyle()
    if target == "jax":
        style = replace(style, shapes="jaxskid")
    if layout.style != style:
        layout = replace(layout, style=style)
    return TARGETS[target].emit(layout)


def _requested(eqs: Equations, names: Sequence[str] | str | None) -> tuple[str, ...]:
    """``names`` checked against what ``eqs`` holds, in the order of ``eqs.quantities``."""
    if names is None:
        return tuple(eqs.quantities)
    if isinstance(names, str):
        names = (names,)
    missing = [n for n in names if n not in eqs.quantities]
    if missing:
        raise RequestError(
            f"quantity {', '.join(map(repr, missing))} was not derived; derived: {', '.join(eqs.quantities)}"
        )
    wanted = set(names)
    return tuple(n for n in eqs.quantities if n in wanted)


def generate(
    eqs: Equations | Layout,
    target: str,
    out_dir: str | os.PathLike,
    *,
    names: Sequence[str] | None = None,
    force: bool = False,
    style: CodeStyle | None = None,
) -> list[Path]:
    """Write the code of ``target`` for the quantities ``names`` (default: all of ``eqs``) to ``out_dir``.

    Args:
        eqs: the derived equations (:func:`jaxskid.derive`), or a :class:`Layout` of them (see :func:`emit`).
        target: one of :data:`TARGETS` (``"c"``, ``"cpp"``, ``"python"``, ...).
        out_dir: the folder to write to; created if missing.
        names: the quantities to generate, a subset of ``eqs.quantities``.
        force: overwrite existing files. Without it, nothing is written if any file exists.
        style: how the files present the equations (:class:`CodeStyle`: Skidy's column shapes, landscape
            LaTeX, a project name); default ``CodeStyle()``.

    Returns:
        the paths written, in a stable order.

    Raises:
        RequestError: an unknown target or a quantity that ``eqs`` lacks.
        FileExistsError: a file exists and ``force`` is false.
    """
    return write(emit(eqs, target, names, style=style), out_dir, force=force)


def write(files: Mapping[str, str], out_dir: str | os.PathLike, *, force: bool = False) -> list[Path]:
    """Write ``{file name: text}`` (from :func:`emit`) to ``out_dir``, all or nothing.

    Raises:
        FileExistsError: a file exists and ``force`` is false; then nothing is written.
    """
    out = Path(out_dir)
    paths = [out / name for name in files]
    if not force:
        existing = [str(p) for p in paths if p.exists()]
        if existing:
            raise FileExistsError(
                f"{', '.join(existing)} already exist{'s' if len(existing) == 1 else ''}; pass force=True "
                "(--force) to overwrite"
            )
    out.mkdir(parents=True, exist_ok=True)
    for path, text in zip(paths, files.values()):
        path.write_text(text, encoding="utf-8")
    return paths


__all__ = ["TARGETS", "CodeStyle", "Layout", "Program", "Target", "emit", "generate", "stem", "write"]


def __getattr__(name: str):
    if name == "Kernel":  # the old name: "kernel" now means only the native kernels of jaxskid.lowering._ffi
        import warnings

        warnings.warn("jaxskid.codegen.Kernel is deprecated: use jaxskid.codegen.Program", DeprecationWarning,
                      stacklevel=2)
        return Program
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
