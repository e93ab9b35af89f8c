"""What a rollout keeps: :class:`SaveAt` (which states) and :class:`Checkpoint` (what reverse mode stores).

A rollout of ``steps`` steps of ``dt`` visits the states ``x_k`` at ``t_k = k dt``, ``k = 0 .. steps``. A
:class:`SaveAt` names the step numbers ``k`` whose states are returned; the others are never stacked
(:mod:`jaxskid.apps.simulation._loop` builds the loops). A :class:`Checkpoint` makes the reverse pass of ``jax.grad``
store the state only every ``block`` steps and recompute the steps in between.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..._errors import RequestError


def _count(value, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise RequestError(f"{what}: expected a whole number >= 1, got {value!r}")
    return int(value)


@dataclass(frozen=True, init=False)
class SaveAt:
    """Which states of a rollout are returned: one of

    * ``SaveAt(every=k)``: ``x_0, x_k, x_2k, ..., x_steps`` (``steps`` a multiple of ``k``), by an outer scan
      over blocks of ``k`` steps whose inner scan stacks nothing. The default, ``SaveAt()``, is ``every=1``:
      every state.
    * ``SaveAt(ts=[...])``: the states at the given times, which must lie on the step grid ``t = k dt`` of
      every rollout (``|t / dt - k| <= 64 eps max(k, 1)``) in ``[0, steps dt]``, strictly increasing. With a
      traced ``dt`` (a rollout inside ``jax.jit``, or ``jax.grad`` with respect to ``dt``) this cannot be
      checked: each time is taken to the nearest step, ``round(t / dt)`` clipped to ``[0, steps]``. The
      states are written into a buffer of ``len(ts)`` rows as the loop passes them.
    * ``SaveAt(t1=True)``: the final state only (the loop keeps nothing but its carry);
      ``SaveAt(t0=True, t1=True)`` the initial and final states.

    ``Trajectory.t`` holds the saved times ``k dt``. The torques are saved with the states: ``tau[i]`` is the
    torque applied at the start of the step that leaves the ``i``-th saved state, for every saved state but
    the last (``n_saved - 1`` rows; for the default, every step's torque). With an adaptive diffrax solver
    the same states are asked of ``diffrax.SaveAt`` (``ts`` at the grid times, or ``t0``/``t1``); between the
    solver's steps they come from its dense output. A ``SaveAt`` is a static argument of the compiled
    rollout: another one compiles another program.
    """

    every: int | None
    ts: tuple[float, ...] | None
    t0: bool
    t1: bool

    def __init__(self, *, every: int | None = None, ts=None, t0: bool = False, t1: bool = False):
        given = [name for name, on in (("every", every is not None), ("ts", ts is not None), ("t1", t1)) if on]
        if len(given) > 1:
            raise RequestError(f"SaveAt: give one of every=, ts= or t1=True, got {' and '.join(given)}")
        if t0 and not t1:
            raise RequestError("SaveAt: t0=True goes with t1=True (the initial and final states); "
                               "every= and ts= choose the initial state themselves")
        if every is not None:
            every = _count(every, "SaveAt: every")
        elif not given:
            every = 1
        if ts is not None:
            ts = _times(ts)
        for name, value in (("every", every), ("ts", ts), ("t0", bool(t0)), ("t1", bool(t1))):
            object.__setattr__(self, name, value)

    def block(self, steps: int) -> int | None:
        """Steps between saved states (``steps`` for the final state), ``None`` for ``ts``."""
        if self.ts is not None:
            return None
        k = steps if self.t1 else self.every
        if steps % k:
            raise RequestError(f"rollout: SaveAt(every={k}) needs steps to be a multiple of {k}, got steps={steps}")
        return k

    def steps_saved(self, steps: int) -> np.ndarray | None:
        """The saved step numbers ``(n_saved,)`` when they do not depend on ``dt`` (``None`` for ``ts``)."""
        k = self.block(steps)
        if k is None:
            return None
        if self.t1:
            return np.array([0, steps] if self.t0 else [steps])
        return np.arange(0, steps + 1, k)

    def steps_of_times(self, dt, steps: int, dtype) -> np.ndarray | jax.Array:
        """The step numbers of ``ts`` for the step ``dt`` (a scalar, or one per rollout: ``(...,)``), shape
        ``(..., n_ts)``: checked on the host for a concrete ``dt``, rounded on the device for a traced one."""
        if isinstance(dt, jax.core.Tracer):
            ts = jnp.asarray(self.ts, dtype)
            ratio = ts / dt[..., None] if dt.ndim else ts / dt
            return jnp.clip(jnp.round(ratio), 0, steps).astype(jnp.int32)
        dt = np.asarray(np.asarray(dt, dtype), np.float64)
        ratio = np.asarray(self.ts, np.float64) / dt[..., None]  # numpy: no rank-promotion check
        k = np.rint(ratio)
        off = np.abs(ratio - k) > 64 * np.finfo(dtype).eps * np.maximum(k, 1.0)
        late = k > steps
        for bad, why in ((off, "is not on the step grid t = k dt"), (late, "is after the final time steps * dt")):
            if bad.any():
                where = np.argwhere(bad)[0]
                which = f" (rollout {tuple(int(w) for w in where[:-1])})" if dt.ndim else ""
                i, step = where[-1], float(dt[tuple(where[:-1])])
                raise RequestError(
                    f"rollout: SaveAt(ts): ts[{i}] = {self.ts[i]:g} {why}{which}, with dt = {step:g} and "
                    f"steps = {steps} (nearest step {int(k[tuple(where)])} at t = {k[tuple(where)] * step:g})"
                )
        return k.astype(np.int32)


def _times(ts) -> tuple[float, ...]:
    try:
        a = np.asarray(ts, dtype=np.float64)
    except (TypeError, ValueError):
        raise RequestError(f"SaveAt: ts: expected a sequence of times, got {ts!r}") from None
    if a.ndim != 1 or a.size == 0:
        raise RequestError(f"SaveAt: ts: expected a non-empty 1-D sequence of times, got shape {a.shape}")
    if not np.all(np.isfinite(a)) or a[0] < 0:
        raise RequestError(f"SaveAt: ts: expected finite times >= 0, got {a.tolist()}")
    if np.any(np.diff(a) <= 0):
        i = int(np.argmax(np.diff(a) <= 0))
        raise RequestError(f"SaveAt: ts: expected strictly increasing times, got ts[{i}] = {a[i]:g} "
                           f"then ts[{i + 1}] = {a[i + 1]:g}")
    return tuple(a.tolist())


@dataclass(frozen=True)
class Checkpoint:
    """Bound the memory of reverse-mode differentiation through a rollout.

    The steps run as an outer ``lax.scan`` over segments of ``block`` steps (default about ``sqrt(steps)``),
    each an inner scan under ``jax.checkpoint``: the forward pass stores the state at segment boundaries
    only, and the reverse pass recomputes one segment at a time, so ``jax.grad`` keeps
    ``O(steps / block + block)`` (``O(sqrt(steps))``) states' worth of residuals instead of ``O(steps)``,
    for about one more forward pass of work (Griewank & Walther, "Evaluating Derivatives", 2nd ed., 2008,
    sec. 12.3). A trailing partial segment is padded with steps that leave the state unchanged. Saved
    states (:class:`SaveAt`) are stored as usual. With an adaptive diffrax solver this sets
    ``diffrax.RecursiveCheckpointAdjoint(checkpoints=ceil(steps / block))``.
    """

    block: int | None = None

    def __post_init__(self):
        if self.block is not None:
            object.__setattr__(self, "block", _count(self.block, "Checkpoint: block"))

    def size(self, steps: int) -> int:
        """The segment length for ``steps`` steps: ``block``, or the divisor of ``steps`` nearest to
        ``sqrt(steps)`` within a factor 2 (no padded steps), else ``round(sqrt(steps))``."""
        if self.block is not None:
            return self.block
        root = math.sqrt(steps)
        divisors = [d for d in range(max(1, math.ceil(root / 2)), math.floor(2 * root) + 1) if steps % d == 0]
        return min(divisors, key=lambda d: abs(d - root)) if divisors else max(1, round(root))
