"""A function bound as one JAX primitive, so that partial evaluation keeps it whole.

Reverse mode through ``lax.scan`` partially evaluates the loop body, and JAX hoists out of the loop every
value that depends only on loop constants (``_scan_known_hoisting``). For a closed form that means each of
its parameter-only subexpressions: on the Panda's forward dynamics, 340 of them, which enter the loop's
kernel as separate buffers. XLA on CPU then compiled that kernel 5.7x slower than the same program without
the split (profiled: 224 against 39 ms for the 2,000 evaluations of a 500-step RK4 rollout of 64 states),
and the gradient of that rollout cost 9-10x its loss; whole, 3.5-4.8x. Partial evaluation also visited each
of the closed form's operations: tracing a gradient took 1.5 of the 1.9 s of its first call in a new process
that found the compiled program in the persistent cache; now 0.4-0.7 s in all.

:func:`whole` hides the function behind a primitive: partial evaluation stages it out as one equation, and
XLA compiles the same program it compiles for the function alone. The primitive evaluates, lowers, maps
(``jax.vmap``) and differentiates in forward mode as the function does; reverse mode transposes that.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
from jax.extend.core import Primitive
from jax.interpreters import ad, batching, mlir

_whole_p = Primitive("jaxskid_whole")
_whole_p.multiple_results = True


def whole(fun: Callable, like: int) -> Callable:
    """``fun`` as one primitive (see the module docstring): positional array arguments, one array out, of
    the shape of argument ``like`` and the arguments' promoted dtype. That result type is what JAX asks of
    the primitive, so ``fun`` is traced only to lower it, once per program."""
    flat = jax.jit(lambda *args: (fun(*args),))

    def call(*args):
        return _whole_p.bind(*args, fun=flat, shape=tuple(jnp.shape(args[like])))[0]

    call.__name__ = getattr(fun, "__name__", "whole")
    return call


@functools.lru_cache(maxsize=512)
def _mapped(fun: Callable, in_axes: tuple) -> Callable:
    """``fun`` mapped over the axes ``in_axes`` (None: not mapped), the results' batch axis first; one function
    object per pair, so that the primitive's parameters, and JAX's caches keyed by them, repeat."""
    return jax.jit(jax.vmap(fun, in_axes=in_axes))


def _impl(*args, fun, shape):
    return list(fun(*args))


def _abstract(*avals, fun, shape):
    strong = [a.dtype for a in avals if not a.weak_type]
    dtype = functools.reduce(jnp.promote_types, strong or [a.dtype for a in avals])
    # Inside jax.shard_map a result varies over the mesh axes its arguments vary over: it takes the manual
    # axis type (and sharding) of the argument of its rank that varies over the most.
    same_rank = [a for a in avals if a.ndim == len(shape)]
    if not same_rank:
        return [jax.core.ShapedArray(shape, dtype, weak_type=not strong)]
    template = max(same_rank, key=lambda a: len(getattr(getattr(a, "manual_axis_type", None), "varying", ())))
    return [template.update(shape=shape, dtype=dtype, weak_type=not strong)]


def _batch(args, dims, *, fun, shape):
    size = next(a.shape[d] for a, d in zip(args, dims) if d is not None)
    return _whole_p.bind(*args, fun=_mapped(fun, tuple(dims)), shape=(size, *shape)), [0]


def _jvp(primals, tangents, *, fun, shape):
    tangents = [ad.instantiate_zeros(t) for t in tangents]
    out, dout = jax.jvp(fun, tuple(primals), tuple(tangents))
    return list(out), list(dout)


_whole_p.def_impl(_impl)
_whole_p.def_abstract_eval(_abstract)
mlir.register_lowering(_whole_p, mlir.lower_fun(_impl, multiple_results=True))
batching.primitive_batchers[_whole_p] = _batch
ad.primitive_jvps[_whole_p] = _jvp
