"""A long program called from Python, compiled in parts on several cores.

XLA compiles one program on one core, apart from LLVM's code generation at its end; the longest programs of
the JAX form take it 15 s and more (the G1 with hands' regressor: 25,000 operations). On a machine with
several cores, a batch of such a quantity called from Python is computed by several programs, each writing a
block of the result's rows (:func:`~jaxskid.runtime._gathered.rows_gathered` of those rows,
:func:`~jaxskid.runtime._emitted.rows`), and its first call compiles them at once, one thread each: XLA
releases Python's lock while it compiles.

- Each part is the gathered form of its rows, so the result is the same to rounding. The parts run one after
  the other, each writing its rows into the result that the one before it returned (donated), so the result is
  written once, as one program writes it.
- On two cores the G1 with hands' regressor took 11.5 s to compile in two parts and 16.0 s as one program,
  and ran as fast (30.4 and 31.5 us per state at a batch of 4,096). One part after the other, the parts of
  these programs took longer than the whole (19.3 s), and programs of fewer operations gain nothing (the G1's
  regressor, 12,000 operations: 6.2 against 6.6 s; the G1 with hands' Ṁ, 18,000: 7.2 against 7.1 s). So a
  quantity is split from :data:`MIN_OPERATIONS` operations and :data:`MIN_VALUES` distinct entries a part, into
  at most as many parts as the process may use cores, and only where the parts repeat little of each other's
  work (:func:`plan`): the G1 with hands' Coriolis matrix stays one program.
- Inside a caller's trace (``jit``, ``grad``, ``vmap``), for one state, and for complex states, the quantity is
  one program as always: only a call from Python holds the parts' compiled programs, per argument shape.

``JAXSKID_COMPILE_PARTS`` in the environment sets the number of parts, whatever the program (``1``: never
split), read when a quantity is first used.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import jax
import jax.numpy as jnp
import numpy as np

from .._generated import GeneratedQuantity
from ._batching import batch_shape, vmapped
from ._emitted import VARIABLE as RECORD, operands, recorded, rows
from ._gathered import CHUNK, padded_batch, rows_gathered
from ._jit import compiler_options, top_level
from ._parameters import inexact_inputs

VARIABLE = "JAXSKID_COMPILE_PARTS"
"""The number of parts, instead of one per core (module docstring)."""

MIN_OPERATIONS = 20_000
"""Operations of a program from which a call from Python compiles in parts (module docstring)."""

MIN_VALUES = 2 * CHUNK
"""Distinct entries of a part, at least: two of the gathered form's kernels."""

MAX_PARTS = 8
"""Parts of a quantity, at most."""

MAX_REPEATED = 0.05
"""How much more work than the whole's its parts may do between them (:func:`plan`)."""


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def count(quantity: GeneratedQuantity) -> int:
    """The number of parts a batch of ``quantity`` called from Python is computed in (module docstring)."""
    if len(quantity.shape) < 2 or os.environ.get(RECORD, "1") == "0":
        return 1
    wanted = os.environ.get(VARIABLE)
    if wanted is not None and not wanted.strip().isdigit():
        raise ValueError(f"{VARIABLE}={wanted!r} in the environment: expected a number of parts (1: one program)")
    parts = min(int(wanted) if wanted is not None else min(_cores(), MAX_PARTS), quantity.shape[0])
    rec = recorded(quantity) if parts > 1 else None
    if rec is None:
        return 1
    if wanted is None and len(rec.ops) < MIN_OPERATIONS:
        return 1
    return max(1, parts if wanted is not None else min(parts, len(rec.outputs) // MIN_VALUES))


def plan(quantity: GeneratedQuantity, parts: int, checked: bool = True) -> list[tuple[int, int]] | None:
    """``parts`` ranges of the result's rows with about as many distinct entries each, or None where computing
    them apart repeats more than :data:`MAX_REPEATED` of the whole's work (``checked``; a number of parts set
    in the environment is taken as it is): each part's kernels compute the
    statements their entries share, as the whole's do between them (``kernels_work``). The G1 with hands'
    regressor (43 DOF) in two parts: 1.00 to 1.05 times the whole's operations for any cut; its Coriolis matrix,
    whose entries share the subtrees' composite quantities: 1.13 to 1.29 times for a cut that leaves each part
    at least a third, and it ran 1.4 times slower per state in two parts. A window of columns is not considered:
    XLA writes it into the result element by element (the regressor in two such parts ran 1.4 times slower)."""
    rec = recorded(quantity)
    index = rec.index.reshape(quantity.shape[0], -1)
    used = [np.unique(r[r < len(rec.outputs)]) for r in index]
    cumulative = np.cumsum([u.size for u in used])
    cuts = {int(np.searchsorted(cumulative, cumulative[-1] * k / parts)) + 1 for k in range(1, parts)}
    edges = sorted({0, quantity.shape[0], *(min(max(c, 1), quantity.shape[0] - 1) for c in cuts)})
    ranges = list(zip(edges[:-1], edges[1:]))
    if not checked or len(ranges) < 2:
        return ranges if len(ranges) > 1 else None
    whole = kernels_work(rec, np.arange(len(rec.outputs)))
    split = sum(kernels_work(rec, np.unique(np.concatenate(used[a:b]))) for a, b in ranges)
    return ranges if split <= (1 + MAX_REPEATED) * whole else None


def kernels_work(rec, values: np.ndarray) -> int:
    """The operations that the gathered form's kernels of ``rec``'s outputs ``values`` (positions in
    ``rec.outputs``, in the program's order, :data:`CHUNK` a kernel) run between them."""
    reads = operands(rec)
    total = 0
    for start in range(0, len(values), CHUNK):
        seen = bytearray(len(rec.ops))
        stack = [rec.outputs[k] for k in values[start:start + CHUNK]]
        while stack:
            at = stack.pop()
            if not seen[at]:
                seen[at] = 1
                total += 1
                stack.extend(reads[at])
    return total


def in_parts(dyn, name: str, whole: Callable) -> Callable:
    """``whole`` (``f(*state, params, out)``, the quantity's program for a call from Python), or, for a long one
    on several cores (:func:`count`, :func:`plan`), a function that computes a batch called from Python in
    parts and ``whole`` otherwise."""
    quantity = dyn.module.quantities[name]
    parts = count(quantity)
    ranges = plan(quantity, parts, checked=VARIABLE not in os.environ) if parts > 1 else None
    if ranges is None:
        return whole
    args, shape = dyn.signature(name)
    cores = [len(dyn.argument_shape(a)) for a in args]
    n_params = (len(dyn.parameters),)

    def piece(start: int, stop: int, first: bool, options: dict) -> Callable:
        part = rows(quantity, start, stop)

        def body(*state, params=None, into=None):
            arrays, p, dtype = inexact_inputs(dyn.layout, state, params)
            fn = rows_gathered(part, start, dyn.default_constants() if params is None else None)
            batch = batch_shape(name, [(a, x.shape, dyn.argument_shape(a)) for a, x in zip(args, arrays)],
                                [("params", p.shape, n_params)])
            if first:  # into: the caller's out, donated, whose memory XLA gives to the result
                into = jnp.zeros((*batch, *shape), dtype)
            pad = functools.partial(padded_batch, dtype=dtype, shape=shape)
            return vmapped(fn, batch, [*zip(arrays, cores), (p, 1), (into, len(shape))], pad)

        return jax.jit(body, donate_argnames="into", keep_unused=True, compiler_options=options)

    jits: list = []
    made: dict = {}

    def call(*state, params=None, out=None):
        if not top_level((state, params, out)) or not _batched(state, cores) or _complex(state):
            return whole(*state, params=params, out=out)
        if not jits:
            options = compiler_options()
            jits.extend(piece(a, b, k == 0, options) for k, (a, b) in enumerate(ranges))
        leaves, tree = jax.tree_util.tree_flatten((state, params, out))
        key = (tree, *((np.shape(x), _dtype(x), type(x), getattr(x, "sharding", None)) for x in leaves))
        if key not in made:
            made[key] = _compiled(jits, state, params, out)
        result = out
        for compiled in made[key]:
            result = compiled(*state, params=params, into=result)
        return result

    return call


def _compiled(jits: list, state, params, out) -> list:
    """The parts' programs for these arguments, compiled at once, one thread each."""
    first = jits[0].lower(*state, params=params, into=out)
    info = first.out_info
    result = jax.ShapeDtypeStruct(info.shape, info.dtype, sharding=info.sharding)
    lowered = [first, *(j.lower(*state, params=params, into=result) for j in jits[1:])]
    with ThreadPoolExecutor(len(lowered), thread_name_prefix="jaxskid-compile") as pool:
        return list(pool.map(lambda low: low.compile(), lowered))


def _dtype(x):
    return x.dtype if hasattr(x, "dtype") else np.result_type(x)


def _batched(state, cores: list[int]) -> bool:
    return len(state) == len(cores) and any(np.ndim(x) > core for x, core in zip(state, cores))


def _complex(state) -> bool:
    return any(jnp.issubdtype(_dtype(x), jnp.complexfloating) for x in state)
