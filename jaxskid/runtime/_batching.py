"""Batches of states and parameters: leading axes checked, broadcast and mapped with ``jax.vmap``.

Every function of the runtime takes its state arrays with their own trailing shape (``(n,)``, a wrench
``(n_ee, 6)``), or with leading batch axes. One rule holds for every argument, states and parameters
``(..., n_params)`` (and wrenches) alike: their batch axes broadcast against each other (NumPy's rule), so
a batch of parameter sets pairs with a batch of states or sweeps one state, and one ``qd`` serves a batch
of ``q``. The batch is flattened to one axis and mapped.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ShapeError


def float_arrays(values: Sequence) -> tuple[list[jax.Array], jnp.dtype]:
    """The inputs as arrays of one inexact dtype: their common one (complex kept, for complex-step
    derivatives), or the default float for integers and booleans."""
    arrays = [jnp.asarray(x) for x in values]
    dtype = jnp.result_type(*arrays) if arrays else jnp.result_type(float)
    if not jnp.issubdtype(dtype, jnp.inexact):
        dtype = jnp.result_type(float)
    return [x.astype(dtype) for x in arrays], dtype


def leading(where: str, arg: str, shape: tuple, core: tuple) -> tuple:
    """The batch axes of an argument of shape ``shape`` whose trailing axes must be ``core``."""
    k = len(shape) - len(core)
    if k < 0 or tuple(shape[k:]) != tuple(core):
        dims = ", ".join(map(str, core))
        raise ShapeError(f"{where}: {arg}: expected shape {tuple(core)} (or (..., {dims}) for a batch), got {tuple(shape)}")
    return tuple(shape[:k])


def batch_shape(where: str, states: Sequence[tuple[str, tuple, tuple]], extras: Sequence[tuple[str, tuple, tuple]] = ()):
    """The batch shape of a call: the batch axes of ``states`` and ``extras`` (name, shape, trailing shape),
    the states' and the extras' (parameters, wrenches) alike, broadcast against each other."""
    batch = ()
    for arg, shape, core in states:
        lead = leading(where, arg, shape, core)
        try:
            batch = tuple(np.broadcast_shapes(batch, lead))
        except ValueError:
            raise ShapeError(f"{where}: {arg}: batch {lead} does not broadcast with the batch {batch} of the "
                             f"arguments before it") from None
    for arg, shape, core in extras:
        lead = leading(where, arg, shape, core)
        try:
            batch = tuple(np.broadcast_shapes(batch, lead))
        except ValueError:
            raise ShapeError(f"{where}: {arg}: batch {lead} does not broadcast with the state batch {batch}") from None
    return batch


def vmapped(fn: Callable, batch: tuple, inputs: Sequence[tuple[jax.Array | None, int]],
            pad: Callable[[int], int] | None = None) -> jax.Array:
    """``fn`` of one state, mapped over ``batch``: ``(..., *out)``.

    ``inputs`` are ``(array, number of trailing axes)``; an array with batch axes is broadcast to ``batch``
    and flattened (mapped axis 0), one without (or ``None``) is passed whole to every call. ``pad(size)``, if
    given, is the number of states to compute the flattened batch in: the mapped inputs are padded with
    copies of their last state and the result sliced back.
    """
    size = int(np.prod(batch))
    padded = pad(size) if pad is not None else size
    args, axes = [], []
    for x, core in inputs:
        if x is None or x.ndim == core:
            args.append(x)
            axes.append(None)
            continue
        tail = x.shape[x.ndim - core:]
        flat = jnp.broadcast_to(x, (*batch, *tail)).reshape((-1, *tail))
        if padded > size:
            flat = jnp.pad(flat, ((0, padded - size), *((0, 0),) * len(tail)), mode="edge")
        args.append(flat)
        axes.append(0)
    out = jax.vmap(fn, in_axes=tuple(axes))(*args)
    if padded > size:
        out = out[:size]
    return out.reshape((*batch, *out.shape[1:]))
