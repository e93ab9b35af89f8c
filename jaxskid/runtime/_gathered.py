"""The gathered form of an array-valued quantity: how the JAX form computes a batch on CPU.

The generated function assembles its result with select chains over the result's axes (see
:mod:`jaxskid.codegen._jax`). XLA on CPU compiles those into one loop over the entries in which every vector
of entries runs the selects of every row, so their cost grows with the square of the number of entries and
outgrows the arithmetic from about a hundred entries (the G1 with hands' mass matrix, 577 nonzero entries:
about 90 % of its time). A vector has one chain, and still runs faster gathered: the G1 with hands'
inverse dynamics (43 entries) took 1.24 us per state mapped with ``jax.vmap``, 0.44 gathered, and its forward
dynamics 2.94 and 0.97. The gathered form computes the same program and assembles the result in three
steps whose cost is linear in the entries:

1. every distinct nonzero entry (a symmetric matrix's pair is one) is an output of a variadic
   ``lax.reduce`` (by ``max`` over two equal lanes, exact): XLA compiles a reduce with many outputs into one
   loop over the batch that runs the program once per state and stores each output in its own array.
   At most :data:`CHUNK` outputs per reduce (XLA refuses a kernel of more than 1,000 outputs, and long
   kernels run slower), taken in the order the program computes them (the order of the generated entries),
   so that a reduce's outputs share their statements: in row-major order, the five reduces of the G1 with
   hands' Coriolis matrix in its column-wise form ran 3.0 times its 57,800 statements between them, in the
   program's order 1.4 times;
2. the outputs stacked into a ``(batch, distinct + 1)`` array, its last column zero; beyond :data:`STAGED`
   chunks, each chunk's outputs are stacked apart, behind optimization barriers, and the chunks concatenated;
3. one gather with a constant index, which also places the zeros and the repeated entries.

A batch of large results (:func:`tiled`) runs these steps in a loop, :data:`TILE` states at a time, each tile
written into its place in the result. XLA gives a program's intermediate arrays one block of memory per call:
for a whole batch of 4,096 of the G1's regressor, 85 MB (the table and the reduces' outputs), which glibc's
allocator maps afresh at every call and the operating system clears page by page before the program writes
it. A tile's intermediates take a few megabytes, which stay in the cache and in memory the allocator reuses.

Each output of the reduce is an array of the batch. When the batch's rows span an even number of cache
lines, those arrays lie at strides that map them to a few cache sets and the stores evict each other (a
batch of 4,096 float64 states ran the G1 with hands' mass matrix 4x slower than one of 4,000), so
:func:`padded_batch` pads a batch to an odd number of lines, and a tile spans an odd number.

``python benchmarks/output_forms.py --forms broadcast-nested,gathered`` compares the two forms.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from .._generated import GeneratedQuantity
from ._emitted import traced, values as recorded_values
from ._recycle import MIN_BYTES

CHUNK = 128
"""Outputs of one reduce, at most (module docstring, step 1). The outputs come in the order the program computes
them, so that a reduce's share most of their statements; long kernels run slower per operation (LLVM's code
for them spills more), and chunks of 100-150 outputs ran fastest: the reduces of the G1 with hands' Coriolis
matrix in its column-wise form (43 DOF, 569 outputs, 58,000 operations) took 10.5 ms at batch 4,104 in chunks
of 128, 27.3 ms in chunks of 300, 18.8 ms in chunks of 50; its regressor's 14.5, 46.4 and 16.0 ms; its mass
matrix's 1.8, 4.5 and 2.1 ms (compile times within 10 %). Chunks of 128 also compile fastest: the regressor in
18.4 s (one core), in 20.8 s in chunks of 64 and in 20.1 s in chunks of 256, though those repeat 2.9 and 1.6
times its statements between them, against 2.2 times. Computing the statements that several chunks share once,
in reduces of their own whose outputs the chunks read, compiled slower still (the regressor's XLA compile 19.6
instead of 15.6 s on two cores, its Coriolis matrix's 21.4 instead of 15.4): LLVM's loop vectorizer then
analyses every pair of the hundreds of arrays a kernel reads and the arrays it writes."""

LANES = 2
"""The reduced axis: two copies of every value."""

TILE = 264
"""States computed at a time in a large batch (module docstring): 33 cache lines of float64 values. At a batch
of 4,096 on one core, written into an earlier result, a loop of such tiles ran the G1's regressor (29 DOF) in
10.3 instead of 21.2 us per state, the G1 with hands' Coriolis matrix (43 DOF) in 5.0 instead of 8.9 and its
mass matrix in 2.3 instead of 3.3, with the same results to the last bit."""

TILED_BYTES = MIN_BYTES
"""Results from this size on are computed a tile at a time: the size from which a call's result is recycled
(:data:`jaxskid.runtime._recycle.MIN_BYTES`, which says why), so that neither the result nor the intermediates of
a whole batch (tens of megabytes) are blocks that glibc maps afresh or not depending on the process's history.
The same benchmark run (``benchmarks/scaling.py``, one core, batch 4,096) with this at 32 MiB and at 8 MiB: the
G1 with hands' C in float32 (29 MB) 5.56 and 2.89 us per state, its Ṁ 4.66 and 2.27, its mass matrix 1.15 and
1.96 (float64: 2.33 and 2.37); the G1's mass matrix (28 MB in float64) 0.80 and 1.01, its Ṁ 0.92 and 1.20.
Below it the loop costs more than it spares."""


STAGED = 8
"""Chunks above which the table is built chunk by chunk (module docstring, step 2). One stack of thousands of
columns is a loop whose body reads every column: LLVM's loop vectorizer analyses its memory accesses pairwise,
and XLA took longer over that loop than over the whole program. The barriers keep XLA's simplifier from merging
the chunks' stacks back into one. The G1 with hands' regressor (2,886 distinct entries, 23 chunks, batch 4,104,
one core) compiled in 33-38 s stacked at once and in 17-19 s chunk by chunk, and ran as fast either way (110 and
108 us per state); the G1's (1,362 entries) in 9.4 s and 7.0 s. The Coriolis matrix of the G1 with hands (569
entries, 5 chunks) ran 4x slower chunk by chunk: XLA reads a small table's columns straight from the reduces."""


def tiled(size: int, dtype, shape: tuple) -> bool:
    """Whether a batch of ``size`` results of ``shape`` is computed a tile at a time (:data:`TILED_BYTES`)."""
    return size > TILE and size * math.prod(shape) * jnp.dtype(dtype).itemsize >= TILED_BYTES


def _maximum(x: tuple, y: tuple) -> tuple:
    return tuple(jax.lax.max(a, b) for a, b in zip(x, y))


def _table(quantity: GeneratedQuantity, args, batch: int | None = None,
           constants: tuple | None = None) -> tuple[jax.Array, np.ndarray]:
    """``(table, index)``: steps 1 and 2 of the gathered form (module docstring) on one state, or with ``batch``
    on a batch whose arrays carry it on their last axis (the program reads an entry as a vector of the batch),
    and the constant index of step 3. The program's entries are written into the lowered module from its
    recording (:mod:`jaxskid.runtime._emitted`), or traced where it has none."""
    dtype = jnp.result_type(*args)
    lanes_shape = (LANES,) if batch is None else (LANES, batch)
    lanes, index = recorded_values(quantity, args, lanes_shape, constants) or traced(quantity, args, lanes_shape)
    staged = len(lanes) > STAGED * CHUNK
    columns = []  # each chunk's columns of the table (module docstring, step 2)
    for start in range(0, len(lanes), CHUNK):
        part = tuple(lanes[start:start + CHUNK])
        low = (jnp.asarray(-jnp.inf, dtype),) * len(part)
        outputs = jax.lax.reduce(part, low, _maximum, (0,))
        if staged:
            outputs = jax.lax.optimization_barrier(tuple(outputs))
        stacked = jnp.stack(outputs, axis=-1)
        columns.append(jax.lax.optimization_barrier(stacked) if staged else stacked)
    return jnp.concatenate([*columns, jnp.zeros((*lanes_shape[1:], 1), dtype)], axis=-1), index


def _assembled(quantity: GeneratedQuantity, args, batch: int | None = None,
               constants: tuple | None = None) -> jax.Array:
    """The result of ``quantity``'s program by the gathered form (module docstring): on one state, or with
    ``batch``, on a batch whose arrays carry it on their last axis, the result's batch first."""
    table, index = _table(quantity, args, batch, constants)
    if batch is None:
        return jnp.take(table, index, mode="clip").reshape(quantity.shape)
    return jnp.take(table, index, axis=1, mode="clip").reshape((batch, *quantity.shape))


def _tiled(quantity: GeneratedQuantity, args, batched, batch: int, dtype, into=None, at: tuple = (),
           constants: tuple | None = None) -> jax.Array:
    """``_assembled`` of a large batch (:func:`tiled`), :data:`TILE` states at a time (module docstring): a loop
    whose every pass computes one tile and writes it into the result. The last tile ends with the batch and
    overlaps the one before it, so that no state is padded and the result is not copied. With ``into`` (a batch
    of a larger result), the tiles are written into it at the index ``at`` of one state (:func:`rows_gathered`).

    A tile's table is computed in a branch of a conditional that is always taken (``k >= 0``): XLA's loop
    passes (loop-invariant code motion, constant sinking, dead-element removal) clone the loop's body each time
    they change it, and a branch's computation is not part of the body they clone. The G1 with hands' Coriolis
    matrix (43 DOF) compiled in 16.3 s instead of 18.1 s on one core, its regressor in 18.6 s instead of 19.8 s;
    they ran as fast (4.1 and 25.3 us per state at a batch of 4,096, against 4.0 and 25.8). The gather stays
    outside the branch, which would otherwise return the tile's result, a copy of 40 MB for the regressor (it
    then ran at 39 us per state)."""

    def step(k, result):
        start = jnp.minimum(k * TILE, batch - TILE)
        tile = [jax.lax.dynamic_slice_in_dim(a, start, TILE, axis=-1) if b else a for a, b in zip(args, batched)]
        made = {}

        def computed(t):
            made["table"], made["index"] = _table(quantity, t, TILE, constants)
            return made["table"]

        def skipped(t):  # never taken; its zeros take the table's shape from the branch traced first
            table = made["table"] if "table" in made else computed(t)
            return jnp.zeros(table.shape, table.dtype)

        table = jax.lax.cond(k >= 0, computed, skipped, tile)
        part = jnp.take(table, made["index"], axis=1, mode="clip").reshape((TILE, *quantity.shape))
        return jax.lax.dynamic_update_slice(result, part, (start, *(at or [0] * len(quantity.shape))))

    if into is None:
        into = jnp.zeros((batch, *quantity.shape), dtype)
    return jax.lax.fori_loop(0, -(-batch // TILE), step, into)


def _one_state(quantity: GeneratedQuantity, constants: tuple | None = None) -> Callable:
    """``_assembled`` of one state, which ``jax.vmap`` maps by tracing the program once on vectors of the batch
    (``custom_vmap``) instead of through its batching of every scalar operation: the G1's Coriolis matrix
    (27,000 operations) traced in 3.0 s and lowered to XLA in 0.35 s so, in 3.6 s and 2.5 s through ``vmap``.

    JAX traces a ``custom_vmap``'s own function at every call, mapped or not, for the result's shape. The
    runtime calls this one only under ``jax.vmap``, where the rule runs instead, so that function is the
    program on the host (:func:`_on_host`): tracing the program there too took as long as the rule's own
    trace (2.8 s of the 5.7 s that tracing and lowering the G1 with hands' Coriolis matrix took)."""

    program = jax.jit(quantity.single())

    @jax.custom_batching.custom_vmap
    def one(*args):
        return _on_host(program, quantity.shape, args)

    @one.def_vmap
    def _mapped(size, batched, *args):
        return _batch(quantity, size, batched, args, constants), True

    return one


def _batch(quantity: GeneratedQuantity, size: int, batched, args, constants: tuple | None, into=None,
           at: tuple = ()) -> jax.Array:
    """The gathered form of ``size`` states, as a ``custom_vmap`` rule receives them (``args`` with the batch first
    where ``batched``): a tile at a time where the result is large (:func:`tiled`), else at once; with ``into``
    (a batch of a larger result), written into it at the index ``at`` of one state."""
    last = [jnp.moveaxis(a, 0, -1) if b else a for a, b in zip(args, batched)]
    dtype = jnp.result_type(*args)
    if tiled(size, dtype, quantity.shape if into is None else into.shape[1:]):
        return _tiled(quantity, last, batched, size, dtype, into=into, at=at, constants=constants)
    result = _assembled(quantity, last, size, constants)
    return result if into is None else jax.lax.dynamic_update_slice(into, result, (0, *at))


def _on_host(program: Callable, shape: tuple, args) -> jax.Array:
    """``program`` (the jitted one-state program) as a host callback: a few equations to trace, and correct,
    though slow, if it runs. The select against a sum of the inputs gives the result the inputs' type under
    ``jax.shard_map`` (varying over the axes they vary over), which the callback's own result does not have."""

    def run(*values):
        return np.asarray(program(*values))

    result = jax.pure_callback(run, jax.ShapeDtypeStruct(shape, jnp.result_type(*args)), *args)
    return jnp.where(True, result, sum(jnp.sum(a) for a in args).astype(result.dtype))


def gathered(quantity: GeneratedQuantity, constants: tuple | None = None) -> Callable:
    """``f(*state, p)`` of one state, to map with ``jax.vmap``: ``quantity``'s program by the gathered form,
    differentiated in forward mode through the program on unbroadcast values (:meth:`GeneratedQuantity.single`),
    as the generated function is. The generated function serves complex inputs: ``max`` has no order on them.
    With ``constants`` (the values of ``p``, which is then not read: the defaults of a call without parameters),
    the parameters are constants of the compiled program (:func:`jaxskid.runtime._emitted.values`)."""
    single, one = quantity.single(), _one_state(quantity, constants)

    @jax.custom_jvp
    def f(*args):
        if jnp.issubdtype(jnp.result_type(*args), jnp.complexfloating):
            return quantity.function(*args)
        return one(*args)

    @f.defjvp
    def _derivative(primals, tangents):
        return f(*primals), jax.jvp(single, primals, tangents)[1]

    return f


def rows_gathered(part: GeneratedQuantity, row: int, constants: tuple | None = None) -> Callable:
    """``f(*state, p, into) -> into`` of one state, to map with ``jax.vmap``: ``into`` (a whole result of the
    quantity that ``part`` is rows of, from row ``row`` on: :func:`jaxskid.runtime._emitted.rows`) with those
    rows replaced by ``part``'s, computed by the gathered form (a large batch written tile by tile into
    ``into``). It is what a call in parts runs (:mod:`jaxskid.runtime._parts`), from Python only: it has no
    derivative rules, and real inputs only. ``constants``: as for :func:`gathered`."""
    program = jax.jit(part.single())
    at = (row, *([0] * (len(part.shape) - 1)))

    @jax.custom_batching.custom_vmap
    def one(*args):
        *args, into = args
        return jax.lax.dynamic_update_slice(into, _on_host(program, part.shape, args).astype(into.dtype), at)

    @one.def_vmap
    def _mapped(size, batched, *args):
        *args, into = args
        *batched, into_batched = batched
        if not into_batched:
            into = jnp.broadcast_to(into, (size, *into.shape))
        return _batch(part, size, batched, args, constants, into, at), True

    return one


def padded_batch(size: int, dtype, shape: tuple = ()) -> int:
    """The batch to compute ``size`` results of ``shape`` in: ``size``, or a little more so that a row of the
    batch spans an odd number of 64-byte cache lines (module docstring). A batch computed a tile at a time
    (:func:`tiled`) is not padded."""
    item = jnp.dtype(dtype).itemsize
    lines = -(-size * item // 64)
    if size < 64 or lines % 2 or tiled(size, dtype, shape):
        return size
    return (lines + 1) * 64 // item
