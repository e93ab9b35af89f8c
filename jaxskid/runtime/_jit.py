"""Compilation of jaxskid's functions: :func:`jit` and the XLA options it gives at the outermost call.

The generated programs are long straight-line code; with XLA's default CPU emitters they compile slowly
into slow code, so every jitted entry point of the runtime and the applications goes through :func:`jit`.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable

import jax

CLASSIC_EMITTERS_FLAG = "--xla_cpu_use_fusion_emitters=false"
LAST_WITH_CLASSIC_EMITTERS = (0, 10)  # jaxlib 0.11's XLA no longer knows the switch


def classic_emitters_switch() -> bool:
    """Whether this jaxlib's XLA has the switch to its classic CPU emitters. It is gone from jaxlib 0.11,
    whose XLA aborts the process at an unknown flag in ``XLA_FLAGS`` and refuses an unknown compiler
    option, so neither is given there."""
    try:
        import jaxlib.version

        release = tuple(int(part) for part in jaxlib.version.__version__.split(".")[:2])
    except (ImportError, AttributeError, ValueError):
        return False
    return release <= LAST_WITH_CLASSIC_EMITTERS


def compiler_options() -> dict:
    """XLA options for the generated functions.

    On CPU, XLA's newer fusion emitters compile the long straight-line programs of jaxskid slowly and
    into slow code (the second time derivative of tau on the Panda: 1.45 ms against 270 ns per state;
    the Coriolis matrix: 747 us against 15 us), so the classic emitters are used there, where this XLA
    still has them (:func:`classic_emitters_switch`).
    """
    if jax.default_backend() == "cpu" and classic_emitters_switch():
        return {"xla_cpu_use_fusion_emitters": False}
    return {}


def prefer_classic_emitters() -> bool:
    """Make XLA's classic CPU emitters the process's default, so that a plain ``jax.jit`` of jaxskid's
    functions compiles as :func:`jit` does (a hand-written RK4 loop over the Panda's forward dynamics,
    batch 256: 0.19 us per evaluation under ``jax.jit`` against 0.09 us under :func:`jit` otherwise).

    Called when jaxskid is imported. It adds :data:`CLASSIC_EMITTERS_FLAG` to ``XLA_FLAGS`` only while
    JAX's backends have not started (XLA reads the variable once, when they do) and only if ``XLA_FLAGS``
    says nothing of the fusion emitters: ``XLA_FLAGS=--xla_cpu_use_fusion_emitters=true`` keeps XLA's
    default. Nothing is added where XLA has no such switch (:func:`classic_emitters_switch`). Returns
    whether the flag is in effect from this call.
    """
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_use_fusion_emitters" in flags or not classic_emitters_switch():
        return False
    try:
        from jax._src import xla_bridge

        if xla_bridge.backends_are_initialized():
            return False  # too late for this process; jit() still passes the option per program
    except (ImportError, AttributeError):
        return False
    os.environ["XLA_FLAGS"] = f"{flags} {CLASSIC_EMITTERS_FLAG}".strip()
    return True


def traced(tree) -> bool:
    """Whether any leaf of ``tree`` is a tracer (the call is inside a caller's ``jit``, ``grad`` or ``vmap``)."""
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(tree))


def outermost(top: Callable, nested: Callable, **jit_kwargs) -> Callable:
    """Call ``top`` jitted with :func:`compiler_options` from Python, ``nested`` plainly jitted inside a
    caller's trace (JAX accepts compiler options only on a top-level jit)."""
    nested_jit = jax.jit(nested, **jit_kwargs)
    top_jit: list = []  # compiled on first use: compiler_options() asks for the backend

    def call(*args, **kwargs):
        if traced((args, kwargs)):
            return nested_jit(*args, **kwargs)
        if not top_jit:
            top_jit.append(jax.jit(top, compiler_options=compiler_options(), **jit_kwargs))
        return top_jit[0](*args, **kwargs)

    return call


def jit(fn: Callable | None = None, **jit_kwargs) -> Callable:
    """``jax.jit`` with :func:`compiler_options` where they may be given: at the outermost call.

    Wrap your own functions of jaxskid's quantities with it (as jaxskid wraps its rollouts and fits): with
    XLA's default CPU emitters, the long straight-line programs compile into code up to 1000x slower.
    JAX accepts compiler options only on a top-level jit, so inside a caller's trace this is a plain
    ``jax.jit`` (and the caller's options apply). Keyword arguments go to ``jax.jit``; usable as a
    decorator, with or without them.
    """
    if fn is None:
        return functools.partial(jit, **jit_kwargs)
    return functools.wraps(fn)(outermost(fn, fn, **jit_kwargs))
