"""Compilation of jaxskid's functions: :func:`jit` and the XLA options it gives at the outermost call.

The generated programs are long straight-line code; with XLA's default CPU emitters they compile slowly
into slow code, so every jitted entry point of the runtime and the applications goes through :func:`jit`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax

from .._xla_flags import classic_emitters_switch, prefer_synchronous_cpu_dispatch

prefer_synchronous_cpu_dispatch()


def compiler_options() -> dict:
    """XLA options for the generated functions.

    On CPU, XLA's newer fusion emitters compile the long straight-line programs of jaxskid slowly and
    into code that is orders of magnitude slower (the second time derivative of tau, the Coriolis matrix;
    ``benchmarks/derivatives.py --emitters default`` compares), so the classic emitters are used there,
    where this XLA still has them (:func:`classic_emitters_switch`).
    """
    if jax.default_backend() == "cpu" and classic_emitters_switch():
        return {"xla_cpu_use_fusion_emitters": False}
    return {}


def traced(tree) -> bool:
    """Whether any leaf of ``tree`` is a tracer (the call is inside a caller's ``jit``, ``grad`` or ``vmap``)."""
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(tree))


def _trace_context():
    """JAX's trace context (``is_top_level()``: no transformation is tracing), where this JAX has one."""
    try:
        from jax._src.core import trace_ctx
    except ImportError:  # pragma: no cover - a JAX without it: the arguments alone decide
        return None
    return trace_ctx if hasattr(trace_ctx, "is_top_level") else None


_TRACE_CONTEXT = _trace_context()


def top_level(tree=()) -> bool:
    """Whether a call made now is outside every ``jit``, ``grad``, ``vmap`` (or other transformation).

    JAX's own trace state decides, so a function that closes over a caller's traced values (a policy
    capturing the gains being differentiated) counts as nested although none of its arguments is a tracer.
    ``tree``: the call's arguments, also checked (a tracer among them is nested whatever the state says).
    """
    if _TRACE_CONTEXT is not None and not _TRACE_CONTEXT.is_top_level():
        return False
    return not traced(tree)


def forward_mode() -> bool:
    """Whether the innermost differentiation around a call made now is forward mode (``jax.jvp``,
    ``jax.jacfwd``), where a ``jax.custom_vjp`` cannot serve; False under reverse mode (``jax.grad``,
    ``jax.vjp``, ``jax.hessian``'s inner ``jacrev``), under no differentiation, and where this JAX does not
    tell (its trace state has no parent chain)."""
    if _TRACE_CONTEXT is None:
        return False
    trace, seen = _TRACE_CONTEXT.trace, 0
    while trace is not None and seen < 64:  # innermost first, to the evaluation at the bottom
        kind = type(trace).__name__
        if kind == "JVPTrace":
            return True
        if kind == "LinearizeTrace":
            return False
        trace, seen = getattr(trace, "parent_trace", None), seen + 1
    return False


def outermost(top: Callable, nested: Callable, donate_argnames=None, **jit_kwargs) -> Callable:
    """Call ``top`` jitted with :func:`compiler_options` from Python, ``nested`` plainly jitted inside a
    caller's trace (JAX accepts compiler options only on a top-level jit, and donates buffers only there:
    ``donate_argnames`` applies to ``top``). Nesting is JAX's trace state (:func:`top_level`), not only
    whether the arguments are tracers: a closure's traced values count."""
    nested_jit = jax.jit(nested, **jit_kwargs)
    top_jit: list = []  # compiled on first use: compiler_options() asks for the backend

    def call(*args, **kwargs):
        if not top_level((args, kwargs)):
            return nested_jit(*args, **kwargs)
        if not top_jit:
            top_jit.append(jax.jit(top, compiler_options=compiler_options(), donate_argnames=donate_argnames,
                                   **jit_kwargs))
        return top_jit[0](*args, **kwargs)

    return call


def jit(fn: Callable | None = None, **jit_kwargs) -> Callable:
    """``jax.jit`` with :func:`compiler_options` where they may be given: at the outermost call.

    Wrap your own functions of jaxskid's quantities with it (as jaxskid wraps its rollouts and fits): with
    XLA's default CPU emitters, the long straight-line programs compile into far slower code.
    JAX accepts compiler options only on a top-level jit, so inside a caller's trace this is a plain
    ``jax.jit`` (and the caller's options apply). Keyword arguments go to ``jax.jit``; usable as a
    decorator, with or without them.
    """
    if fn is None:
        return functools.partial(jit, **jit_kwargs)
    return functools.wraps(fn)(outermost(fn, fn, **jit_kwargs))
