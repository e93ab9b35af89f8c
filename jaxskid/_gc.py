"""Python's cyclic garbage collector, paused while jaxskid builds large graphs of objects.

Loading a large robot, deriving its quantities with SymPy, printing them and tracing their programs into JAX
allocate millions of objects, few of them in reference cycles; the collector's passes over everything still
alive took about a quarter of the G1 with hands' cold first Coriolis matrix outside XLA (12.8 against 9.8 s
with the collector off, one core, the peak memory the same). :func:`paused_gc` turns the collector off for
such a step and on again after it, where it was on; memory that reference counting frees is freed as before.
"""

from __future__ import annotations

import contextlib
import functools
import gc
from collections.abc import Callable, Iterator


@contextlib.contextmanager
def paused_gc() -> Iterator[None]:
    """The cyclic collector off for the ``with`` block, where it was on (module docstring)."""
    if not gc.isenabled():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.enable()


def gc_paused(fn: Callable) -> Callable:
    """``fn`` run with the cyclic collector paused (:func:`paused_gc`)."""

    @functools.wraps(fn)
    def run(*args, **kwargs):
        with paused_gc():
            return fn(*args, **kwargs)

    return run
