"""Memory for large results on CPU: a call's result takes the memory of an earlier result of the same quantity
that nothing references any more.

glibc's allocator maps every block above its mmap threshold (32 MiB at most) afresh, and the operating system
clears each page of it when the program first writes there: for the G1's regressor at a batch of 4,096 (a
276 MB result) the clearing costs more than computing the result. So each quantity keeps the last
:data:`KEPT` results from :data:`MIN_BYTES` to :data:`MAX_BYTES` that it returned to Python. A call whose
result would have the shape, dtype and device of one of them that only this pool references is given it as
``out`` (donated, as a quantity's own ``out=`` is), and the result is written into its memory. Two, so that a
loop ``Y = dyn.regressor(q, qd, qdd)`` reuses the result before last while it holds the last. A large call
with none to reuse is given a new array, so that a quantity compiles one program per shape (an ``out``
changes the program).

An array you reference, directly, through a container or through a NumPy view of its memory, is never taken.
The pool holds at most :data:`KEPT` results per quantity beyond those you hold, until the
:class:`~jaxskid.Dynamics` is freed; ``JAXSKID_RECYCLE=0`` in the environment turns it off.

:func:`check_out` and :func:`check_donated` check an ``out`` the caller passes.
"""

from __future__ import annotations

import math
import os
import sys
import threading

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ShapeError

MIN_BYTES = 8 * 2**20
"""Results from this size on are recycled. Above 32 MiB, glibc's largest mmap threshold, every block is mapped
afresh; below it, whether one is depends on what the process freed before (glibc raises its threshold to the
size of each mapped block it frees), so results of a few tens of megabytes ran fast or slow with the process's
history: in one benchmark run the G1 with hands' Coriolis matrix in float32 (29 MB at a batch of 4,096) at 5.6
us per state, where a run with another history took 2.3. From 8 MiB on, the JAX form's results are also
computed a tile at a time (:data:`jaxskid.runtime._gathered.TILED_BYTES`): with both, 2.9."""

MAX_BYTES = 2**30
"""Results above this size are not kept: the pool would hold gigabytes you dropped, where the pages' clearing
costs a call a fraction of its time."""

KEPT = 2
"""Results kept per quantity (module docstring)."""

VARIABLE = "JAXSKID_RECYCLE"
"""Set to 0 to turn recycling off."""


def _references(arrays: list, k: int) -> int:
    return sys.getrefcount(arrays[k])


_UNREFERENCED = _references([object()], 0)
"""What :func:`_references` counts for an object that only its list holds (the interpreter's own references
included, which differ between versions)."""


def enabled() -> bool:
    """Whether recycling is on (``JAXSKID_RECYCLE``, read at every call)."""
    return os.environ.get(VARIABLE, "1").strip().lower() not in ("0", "false", "no", "off")


class Recycler:
    """The kept results of one quantity (module docstring); safe to use from several threads."""

    def __init__(self):
        self._arrays: list[jax.Array] = []
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._arrays)

    def take(self, shape: tuple, dtype, device) -> jax.Array | None:
        """A kept result of ``shape``, ``dtype`` on ``device`` that nothing else references, removed from the
        pool; None if there is none."""
        with self._lock:
            for k in range(len(self._arrays)):
                if _references(self._arrays, k) != _UNREFERENCED:
                    continue
                a = self._arrays[k]
                if a.shape == shape and a.dtype == dtype and not a.is_deleted() and a.devices() == {device}:
                    del self._arrays[k]
                    return a
                del a
        return None

    def keep(self, result) -> None:
        """Keep ``result`` (a single-device array; anything else is not kept), dropping the oldest beyond
        :data:`KEPT`."""
        if not isinstance(result, jax.Array) or len(result.devices()) != 1:
            return
        with self._lock:
            self._arrays.append(result)
            del self._arrays[:-KEPT]

    def out(self, shape: tuple, dtype, device) -> jax.Array:
        """The array to give a call as ``out``: a kept one, or a new one."""
        kept = self.take(shape, dtype, device)
        return kept if kept is not None else jnp.empty(shape, dtype, device=device)


def check_out(name: str, out, shape: tuple, dtype) -> None:
    """``out`` of a call: the result's shape and dtype."""
    if tuple(out.shape) != tuple(shape) or out.dtype != dtype:
        raise ShapeError(f"{name}: out: expected {jnp.dtype(dtype).name}{list(shape)} (the result's shape and dtype), "
                         f"got {out.dtype.name}{list(out.shape)}")


def check_donated(name: str, out, inputs) -> None:
    """``out`` of a call from Python: a JAX array that is not deleted and not one of the call's inputs
    (JAX's own errors for these come from deep inside its runtime)."""
    if not isinstance(out, jax.Array):
        raise ShapeError(f"{name}: out: expected a JAX array (an earlier result of {name}, whose memory the result "
                         f"takes), got {type(out).__name__}")
    if isinstance(out, jax.core.Tracer):
        return
    if out.is_deleted():
        raise ShapeError(f"{name}: out: the array was deleted (donated to an earlier call as out, or deleted by "
                         f"you); pass the array that call returned")
    if any(x is out for x in jax.tree_util.tree_leaves(inputs)):
        raise ShapeError(f"{name}: out: the array is also an input of this call; its memory cannot be both read "
                         f"and written: pass an earlier result")


def recycled_result(states, cores, params, shape: tuple) -> tuple | None:
    """``(result shape, dtype, device)`` of a call from Python whose result is recycled, or None where it is
    not: a result smaller than :data:`MIN_BYTES` or larger than :data:`MAX_BYTES`, states that are not real
    arrays of one floating dtype (or integers), complex parameters, arrays on several devices or off the CPU.

    ``states``, ``cores``: the state arguments and the shape of one state of each; ``params``: ``(value,
    trailing shape)`` of the packed parameters (``None``: the defaults); ``shape``: the result's shape for one
    state. The dtype is the states' (as the call converts), the batch the broadcast of the leading axes (which
    the call checks anew).
    """
    leads = []  # the leading (batch) axes of each argument, from shapes alone: small calls end cheaply
    for x, core in (*zip(states, cores), params):
        axes = getattr(x, "shape", None)
        if axes is None:
            if x is None:
                continue
            return None
        if len(axes) > len(core):  # an argument without batch axes broadcasts with any batch
            leads.append(tuple(axes[:len(axes) - len(core)]))
    batch = () if not leads else leads[0] if all(lead == leads[0] for lead in leads) else _broadcast(leads)
    if batch is None:
        return None  # the call names the shapes
    result = (*batch, *shape)
    if math.prod(result) * 8 < MIN_BYTES or not enabled():  # 8: the largest real itemsize
        return None
    dtypes, devices = set(), set()
    for k, (x, core) in enumerate([*zip(states, cores), params]):
        if x is None:
            continue
        if not isinstance(x, (jax.Array, np.ndarray)) or isinstance(x, jax.core.Tracer):
            return None
        if isinstance(x, jax.Array):
            if len(x.devices()) != 1:
                return None
            devices |= x.devices()
        if np.dtype(x.dtype).kind not in "fiu":
            return None
        if k < len(states):
            dtypes.add(np.dtype(x.dtype))
    floats = {d for d in dtypes if d.kind == "f"}
    if len(devices) > 1 or len(floats) > 1:
        return None
    dtype = jnp.dtype(floats.pop() if floats else jnp.result_type(float))
    if jax.dtypes.canonicalize_dtype(dtype) != dtype:
        return None
    device = devices.pop() if devices else _default_device()
    if device is None or device.platform != "cpu":
        return None
    if not MIN_BYTES <= math.prod(result) * dtype.itemsize <= MAX_BYTES:
        return None
    return result, dtype, device


def _broadcast(leads: list) -> tuple | None:
    """The broadcast of the batch shapes ``leads``, or None where they do not broadcast."""
    try:
        return tuple(np.broadcast_shapes(*leads))
    except ValueError:
        return None


def _default_device():
    """The device that arrays without one go to, or None where it is not a device (a platform's name)."""
    device = jax.config.jax_default_device
    if device is None:
        return jax.devices()[0]
    return device if isinstance(device, jax.Device) else None
