"""Compilation of jaxskid's functions: :func:`jit` and the XLA options it gives at the outermost call.

The generated programs are long straight-line code; with XLA's default CPU emitters they compile slowly
into slow code, so every jitted entry point of the runtime and the applications goes through :func:`jit`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax

from .._xla_flags import classic_emitters_switch


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


def traced(tree) -> bool:
    """Whether any leaf of ``tree`` is a tracer (the call is inside a caller's ``jit``, ``grad`` or ``vmap``)."""
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(tree))


def outermost(top: Callable, nested: Callable, donate_argnames=None, **jit_kwargs) -> Callable:
    """Call ``top`` jitted with :func:`compiler_options` from Python, ``nested`` plainly jitted inside a
    caller's trace (JAX accepts compiler options only on a top-level jit, and donates buffers only there:
    ``donate_argnames`` applies to ``top``)."""
    nested_jit = jax.jit(nested, **jit_kwargs)
    top_jit: list = []  # compiled on first use: compiler_options() asks for the backend

    def call(*args, **kwargs):
        if traced((args, kwargs)):
            return nested_jit(*args, **kwargs)
        if not top_jit:
            top_jit.append(jax.jit(top, compiler_options=compiler_options(), donate_argnames=donate_argnames,
                                   **jit_kwargs))
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
