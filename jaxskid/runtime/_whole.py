"""A function bound as one JAX primitive, so that partial evaluation keeps it whole.

Reverse mode through ``lax.scan`` partially evaluates the loop body, and JAX hoists out of the loop every
value that depends only on loop constants (``_scan_known_hoisting``). For a closed form that means each of
its parameter-only subexpressions: on the Panda's forward dynamics, 340 of them, which enter the loop's
kernel as separate buffers. XLA on CPU then compiles that kernel into a much slower loop than the same
program without the split (a ``jax.profiler`` trace of a batched RK4 rollout's gradient shows it), and the
gradient costs several times more against its loss than with the function whole. Partial evaluation also
visits each of the closed form's operations, which was most of the tracing time of a gradient's first call
(``benchmarks/gradients.py`` and ``benchmarks/first_call.py`` measure both).

:func:`whole` hides the function behind a primitive: partial evaluation stages it out as one equation, and
XLA compiles the same program it compiles for the function alone. The primitive evaluates, lowers, maps
(``jax.vmap``) and differentiates in forward mode as the function does; reverse mode transposes that.

With a ``store`` (a folder and a key naming the function), the lowered function is also kept there, as
``jax.export`` serialises it, one file per argument types, mapping and platform. A program that uses the
primitive again, in this process or a new one, lowers the stored StableHLO instead of tracing the function:
for a closed form of thousands of operations that tracing was most of a rollout's first call in a new
process that found its compiled program in JAX's persistent cache. Whatever cannot be stored or read back
(a function with a foreign call, an argument varying over a mesh) is traced as before.
"""

from __future__ import annotations

import functools
import hashlib
import logging
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
from jax.extend.core import Primitive
from jax.interpreters import ad, batching, mlir

from .._files import write_atomic

log = logging.getLogger("jaxskid")

_whole_p = Primitive("jaxskid_whole")
_whole_p.multiple_results = True

_EXPORTED: dict[Path, object] = {}  # export file -> the deserialised export, once per process


def whole(fun: Callable, like: int, store: tuple[Path, tuple] | None = None) -> Callable:
    """``fun`` as one primitive (see the module docstring): positional array arguments, one array out, of
    the shape of argument ``like`` and the arguments' promoted dtype. That result type is what JAX asks of
    the primitive, so ``fun`` is traced only to lower it, once per program. ``store``: ``(folder, key)``,
    where ``key`` (a tuple of strings) names ``fun`` among every function kept in ``folder``; its lowered
    forms are kept there."""
    flat = jax.jit(lambda *args: (fun(*args),))
    store = None if store is None else (Path(store[0]), tuple(store[1]))

    def call(*args):
        return _whole_p.bind(*args, fun=flat, shape=tuple(jnp.shape(args[like])), store=store)[0]

    call.__name__ = getattr(fun, "__name__", "whole")
    return call


@functools.lru_cache(maxsize=512)
def _mapped(fun: Callable, in_axes: tuple) -> Callable:
    """``fun`` mapped over the axes ``in_axes`` (None: not mapped), the results' batch axis first; one function
    object per pair, so that the primitive's parameters, and JAX's caches keyed by them, repeat."""
    return jax.jit(jax.vmap(fun, in_axes=in_axes))


def _impl(*args, fun, shape, store):
    return list(fun(*args))


def _abstract(*avals, fun, shape, store):
    strong = [a.dtype for a in avals if not a.weak_type]
    dtype = functools.reduce(jnp.promote_types, strong or [a.dtype for a in avals])
    return [result_aval(avals, shape, dtype, weak_type=not strong)]


def result_aval(avals, shape: tuple, dtype, weak_type: bool = False):
    """The type of a primitive's result of ``shape`` and ``dtype`` computed from arguments of types ``avals``.
    Inside ``jax.shard_map`` a result varies over the mesh axes its arguments vary over: it takes the manual axis
    type (and sharding) of the argument of its rank that varies over the most."""
    same_rank = [a for a in avals if a.ndim == len(shape)]
    if not same_rank:
        return jax.core.ShapedArray(shape, dtype, weak_type=weak_type)
    template = max(same_rank, key=lambda a: len(getattr(getattr(a, "manual_axis_type", None), "varying", ())))
    return template.update(shape=shape, dtype=dtype, weak_type=weak_type)


def _batch(args, dims, *, fun, shape, store):
    size = next(a.shape[d] for a, d in zip(args, dims) if d is not None)
    if store is not None:
        store = (store[0], (*store[1], f"vmap{tuple(dims)}"))
    return _whole_p.bind(*args, fun=_mapped(fun, tuple(dims)), shape=(size, *shape), store=store), [0]


def _jvp(primals, tangents, *, fun, shape, store):
    tangents = [ad.instantiate_zeros(t) for t in tangents]
    out, dout = jax.jvp(fun, tuple(primals), tuple(tangents))
    return list(out), list(dout)


def _lower(ctx, *args, fun, shape, store):
    exported = None if store is None else _exported(fun, store, ctx)
    if exported is None:
        return mlir.lower_fun(_impl, multiple_results=True)(ctx, *args, fun=fun, shape=shape, store=store)
    return mlir.lower_fun(lambda *a: list(exported.call(*a)), multiple_results=True)(ctx, *args)


def _exported(fun: Callable, store: tuple[Path, tuple], ctx):
    """The stored export of ``fun`` for the argument types and platform of ``ctx``, made and stored now if
    there is none; None where the export fails (then ``fun`` is traced)."""
    avals, platforms = ctx.avals_in, tuple(ctx.module_context.platforms)
    if len(platforms) != 1 or any(getattr(getattr(a, "manual_axis_type", None), "varying", ()) for a in avals):
        return None
    folder, key = store
    types = [(a.shape, str(a.dtype), a.weak_type) for a in avals]
    name = hashlib.sha256(repr((key, types, platforms, jax.__version__)).encode()).hexdigest()[:32]
    path = folder / f"{name}.jaxexport"
    if path in _EXPORTED:
        return _EXPORTED[path]
    try:
        if path.exists():
            exported = jax.export.deserialize(bytearray(path.read_bytes()))
        else:
            specs = [jax.ShapeDtypeStruct(a.shape, a.dtype, weak_type=a.weak_type) for a in avals]
            exported = jax.export.export(fun, platforms=platforms)(*specs)
            write_atomic(path, bytes(exported.serialize()))
    except Exception as exc:  # a foreign call, an unwritable folder, a file of another version: trace instead
        log.debug("jaxskid: no stored export %s (%s)", path, exc)
        exported = None
    _EXPORTED[path] = exported
    return exported


_whole_p.def_impl(_impl)
_whole_p.def_abstract_eval(_abstract)
mlir.register_lowering(_whole_p, _lower)
batching.primitive_batchers[_whole_p] = _batch
ad.primitive_jvps[_whole_p] = _jvp
