"""The time loops of a fixed-step rollout: nested ``lax.scan``s that stack only the saved states.

A loop is built from ``step(carry, u_k) -> (carry, tau_k)``, one step of the integrator with the held
torque ``u_k`` (``None`` for a policy or controller), and ``observe(carry)``, what a saved state keeps
(``(x, z)``). The carry holds the step number ``k``; ``us`` is the torque array ``(steps, n)`` or ``None``.
``tau_k`` is any pytree (``tau0`` of the same structure, zeros): the applied torque, or ``()`` when the
caller takes the torques from ``us`` itself.

* :func:`every_block`: an outer scan over blocks of ``k`` steps, an inner scan over the steps of a block;
  only the outer scan stacks its outputs, so ``steps / k + 1`` states are stored, not ``steps + 1``.
* :func:`at_steps`: given step numbers (possibly traced): one scan whose carry holds a buffer of the saved
  states, written in place (``dynamic_update_slice``, whose derivative needs only the index, so reverse
  mode stores no copy of the buffer).

Either may run its steps in segments under ``jax.checkpoint`` (:class:`~jaxskid.apps.simulation._saving.Checkpoint`).
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from ._saving import SaveAt


def _where(keep, new, old):
    return jax.tree.map(lambda a, b: jnp.where(keep, a, b), new, old)


def _cast(value, like):
    return jax.tree.map(lambda v, a: v.astype(a.dtype), value, like)


def _put(buffer, value, i):
    return jax.tree.map(lambda b, v: jax.lax.dynamic_update_index_in_dim(b, v.astype(b.dtype), i, 0), buffer, value)


def _segments(n: int, block: int | None) -> tuple[int, int]:
    """(count, length) of the segments that cover ``n`` steps, about ``block`` steps each (1 segment if None)."""
    if block is None or block >= n:
        return 1, n
    count = -(-n // block)
    return count, -(-n // count)


def _segmented(us, n: int, count: int, length: int, index: bool = True):
    """The scanned inputs of ``count`` segments of ``length`` steps: (torques, step index within the ``n``, or
    None where the steps do not need it: the fewer inputs a step reads, the fewer kernels it runs)."""
    pad = count * length - n
    if us is not None:
        us = jnp.concatenate([us, jnp.zeros((pad, *us.shape[1:]), us.dtype)]) if pad else us
        us = us.reshape((count, length, *us.shape[1:]))
    return us, (jnp.arange(count * length, dtype=jnp.int32).reshape(count, length) if index else None)


def _scan_segments(segment, carry, xs, count: int):
    """``segment`` over the ``count`` segments of ``xs`` (directly when there is one)."""
    if count == 1:
        return segment(carry, jax.tree.map(lambda a: a[0], xs))
    return jax.lax.scan(lambda c, x: (segment(c, x), None), carry, xs, length=count)[0]


def run_steps(step: Callable, carry, us, n: int, block: int | None, tau0):
    """``n`` steps from ``carry``: ``(carry after, tau of the first step)``. ``us``: ``(n, n_dof)`` or None.

    With ``block``, the steps run as segments of about ``block`` steps, each under ``jax.checkpoint``; padded
    steps of the last segment leave the carry unchanged. ``tau0 = ()``: no torque is kept.
    """
    if n == 1:
        return (step if block is None else jax.checkpoint(step))(carry, None if us is None else us[0])
    count, length = _segments(n, block)
    padded, keep = count * length > n, bool(jax.tree.leaves(tau0))

    def one(c, inp):
        carry, first = c
        u, i = inp
        new, tau = step(carry, u)
        if padded:
            new = _where(i < n, new, carry)
        if keep:
            first = _where(i == 0, _cast(tau, first), first)
        return (new, first), None

    def segment(c, xs):
        return jax.lax.scan(one, c, xs, length=length)[0]

    if block is not None:
        segment = jax.checkpoint(segment)
    return _scan_segments(segment, (carry, tau0), _segmented(us, n, count, length, padded or keep), count)


def every_block(step, observe, carry0, us, steps: int, k: int, block: int | None, tau0):
    """States every ``k`` steps, ``(steps / k + 1, ...)``, and the torques of the steps that leave them but the
    last, ``(steps / k, n)``."""
    m = steps // k
    us = None if us is None else us.reshape((m, k, *us.shape[1:]))

    def one_block(carry, u):
        new, first = run_steps(step, carry, u, k, block, tau0)
        return new, (observe(carry), first)

    if m == 1:
        carry, out = one_block(carry0, None if us is None else us[0])
        saved, taus = jax.tree.map(lambda a: a[None], out)
    else:
        carry, (saved, taus) = jax.lax.scan(one_block, carry0, us, length=m)
    return jax.tree.map(lambda a, b: jnp.concatenate([a, b[None]]), saved, observe(carry)), taus


def at_steps(step, observe, carry0, us, steps: int, index: jax.Array, block: int | None, tau0):
    """The states at the step numbers ``index`` ``(n_ts,)`` (non-decreasing, in ``[0, steps]``) and the torques
    of the steps that leave them but the last.

    Repeated numbers (from a traced ``dt``) are saved once and gathered at the end. Each segment of the
    steps fills a buffer of its own that the outer scan writes into the result at the next free slot, so a
    checkpointed segment's inputs are the carry and a counter, not the buffer.
    """
    n_ts = index.shape[0]
    fresh = jnp.concatenate([jnp.ones((1,), bool), index[1:] != index[:-1]])
    slot = jnp.cumsum(fresh) - 1  # the distinct step each requested one is saved as
    distinct = jnp.full((n_ts,), -1, jnp.int32).at[slot].set(index.astype(jnp.int32))
    count, length = _segments(steps, block)
    rows = n_ts + 1 if count == 1 else min(length, n_ts) + 1  # one spare row, written after the last save
    like = (observe(carry0), tau0)

    def empty(r):
        return jax.tree.map(lambda a: jnp.zeros((r, *a.shape), a.dtype), like)

    def one(c, inp):
        carry, buffer, i, j = c
        u, k = inp
        new, tau = step(carry, u)
        buffer = _put(buffer, (observe(carry), tau), i)
        if count * length > steps:
            new = _where(k < steps, new, carry)
        hit = (j < n_ts) & (distinct[jnp.minimum(j, n_ts - 1)] == k)
        return (new, buffer, i + hit, j + hit), None

    def segment(c, xs):
        carry, j = c
        (carry, buffer, _, j), _ = jax.lax.scan(one, (carry, empty(rows), jnp.int32(0), j), xs)
        return (carry, j), buffer

    if block is not None:
        segment = jax.checkpoint(segment)

    def outer(c, xs):
        carry, j, result = c
        (carry, j_next), buffer = segment((carry, j), xs)
        return (carry, j_next, _put_rows(result, buffer, j)), None

    xs = _segmented(us, steps, count, length)
    if count == 1:  # one segment: its buffer is the result
        (carry, j), result = segment((carry0, jnp.int32(0)), jax.tree.map(lambda a: a[0], xs))
    else:
        (carry, j, result), _ = jax.lax.scan(outer, (carry0, jnp.int32(0), empty(n_ts + rows)), xs)
    saved, taus = _put(result, (observe(carry), tau0), j)  # the final state, if it is saved
    return jax.tree.map(lambda a: a[slot], saved), jax.tree.map(lambda a: a[slot[:-1]], taus)


def _put_rows(result, buffer, j):
    return jax.tree.map(lambda r, b: jax.lax.dynamic_update_slice_in_dim(r, b, j, 0), result, buffer)


def saved_loop(saveat: SaveAt, step, observe, carry0, us, steps: int, index, block: int | None, tau0):
    """The states ``saveat`` keeps ``(n_saved, ...)`` and the torques ``(n_saved - 1, n)`` (see :class:`SaveAt`).

    ``index``: the step numbers of ``saveat.ts`` (else ``None``); ``block``: checkpoint segment length or None;
    ``tau0``: zeros of the structure and dtype of ``step``'s torque output.
    """
    k = saveat.block(steps)
    if k is None:
        return at_steps(step, observe, carry0, us, steps, index, block, tau0)
    saved, taus = every_block(step, observe, carry0, us, steps, k, block, tau0)
    if saveat.t1 and not saveat.t0:
        return jax.tree.map(lambda a: a[1:], saved), jax.tree.map(lambda a: a[:0], taus)
    return saved, taus
