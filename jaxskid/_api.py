"""The two entry points: :func:`load` a description, :func:`lower` it to JAX functions."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from .runtime._dynamics import Dynamics
from .equations._derive import QUANTITIES, Options
from ._errors import ModelError
from .lowering._jax import generate_module
from .model._robot import Robot


def load(path: str | os.PathLike, *, lock: Mapping[str, float] | None = None, **options) -> Robot:
    """Read a robot from ``.urdf``, ``.yaml``/``.yml`` or ``.json`` (chosen by the file extension).

    ``lock`` fixes the named joints at the given positions. Further keyword options go to the reader
    (for URDF: ``symbolic_inertia``, ``gravity``, ``end_effectors``).
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext == ".urdf":
        from .description._urdf import read_urdf

        return read_urdf(p, lock=lock, **options)
    if ext in (".yaml", ".yml", ".json"):
        from .description._yaml import read_description

        if options:
            raise ModelError(f"unknown option(s) {', '.join(options)} for a {ext} file", source=str(p))
        return read_description(p, lock=lock)
    raise ModelError(f"unknown file type {ext or '(none)'!r}; expected .urdf, .yaml, .yml or .json", source=str(p))


def lower(
    robot: Robot,
    quantities: Sequence[str] | str | None = None,
    *,
    symbolic: Iterable[str] | None = None,
    cache: bool = True,
    cache_dir: str | os.PathLike | None = None,
    options: Options | None = None,
    progress: bool = False,
) -> Dynamics:
    """Derive, lower and wrap the requested quantities of ``robot`` (only those).

    Args:
        robot: the model.
        quantities: names from :data:`jaxskid.QUANTITIES`; ``None`` for :data:`jaxskid.DEFAULT_QUANTITIES`,
            ``"all"`` for every quantity.
        symbolic: the parameters that stay inputs of the generated functions; every other parameter is
            replaced by its default value (the ``assignments``). ``None`` keeps all parameters symbolic.
        cache: reuse and write generated modules in ``cache_dir`` (default :func:`jaxskid.cache_dir`).
        options: how expressions are formed (:class:`jaxskid.Options`: CSE, simplification, trig).
        progress: show a progress bar while deriving.
    """
    if symbolic is not None:
        keep = set(symbolic)
        unknown = keep - set(robot.parameters)
        if unknown:
            raise ModelError(
                f"unknown parameter(s) {', '.join(sorted(unknown))}; parameters are {', '.join(robot.parameters)}",
                where="symbolic",
            )
        fixed = [p for p in robot.parameters if p not in keep]
        if fixed:
            robot = robot.substitute(fixed)
    ns, source, path = generate_module(
        robot, quantities, cache=cache, directory=cache_dir, options=options, progress=progress
    )
    return Dynamics(ns, source, path, catalogue=tuple(QUANTITIES))
