"""Python's cyclic garbage collector, paused while jaxskid builds large graphs of objects.

Loading a large robot, deriving its quantities with SymPy, printing them and tracing their programs into JAX
allocate millions of objects, few of them in reference cycles; the collector's passes over everything still
alive took about a quarter of the G1 with hands' cold first Coriolis matrix outside XLA (12.8 against 9.8 s
with the collector off, one core, the peak memory the same). :func:`paused_gc` turns the collector off for
such a step and on again after it, where it was on; memory that reference counting frees is freed as before.
"""

from __future__ import annotations

import functools
import gc
from collections.abc import Callable


class _Paused:
    """The context manager of :func:`paused_gc` (a class: a call's pause costs a fraction of a microsecond)."""

    __slots__ = ("_was_on",)

    def __enter__(self) -> None:
        self._was_on = gc.isenabled()
        if self._was_on:
            gc.disable()

    def __exit__(self, *exc) -> None:
        if self._was_on:
            gc.enable()


def paused_gc() -> _Paused:
    """The cyclic collector off for the ``with`` block, where it was on (module docstring)."""
    return _Paused()


def gc_paused(fn: Callable) -> Callable:
    """``fn`` run with the cyclic collector paused (:func:`paused_gc`)."""

    @functools.wraps(fn)
    def run(*args, **kwargs):
        with paused_gc():
            return fn(*args, **kwargs)

    return run
