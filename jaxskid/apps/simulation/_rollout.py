"""Rollouts on top of a lowered :class:`~jaxskid.Dynamics`.

A rollout integrates ``y = (q, qd, z)`` (:mod:`jaxskid.apps.simulation._field`) with a fixed-step integrator
(:mod:`jaxskid.apps.simulation._integrators`, or a diffrax solver's step) in ``lax.scan`` loops that stack only the
saved states (:mod:`jaxskid.apps.simulation._loop`, :class:`SaveAt`), or with an adaptive diffrax solve
(:mod:`jaxskid.apps.simulation._diffrax`). Batches are ``vmap``-ed and, when several devices are given, split across
them with ``shard_map``; all of it is one compiled call.

A robot with constraints whose quantities are lowered (:data:`jaxskid.runtime._constrained.CONSTRAINT_QUANTITIES`,
among the default quantities of such a robot) moves held by them (:func:`jaxskid.constrained_forward_dynamics`),
with :class:`~jaxskid.Baumgarte` stabilisation by default.

State convention: ``x = (q, qd)`` concatenated, shape ``(2 n,)``; with a floating base ``(nq + nv,)``, the
configuration ``q = (p, quat, q_j)`` and the velocity ``(omega, v, qd_j)`` (:mod:`jaxskid.apps.simulation._field`), the
quaternion renormalised after every fixed step.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
import sys
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, PartitionSpec

from ..._errors import RequestError
from ...runtime._batching import batch_shape, float_arrays
from ...runtime._dynamics import Dynamics
from ...runtime._forward import require_solver
from ...runtime._implicit import AUTODIFF
from ...runtime._checks import check_inputs
from ...runtime._jit import forward_mode, jit, top_level, traced
from ...runtime._free_flyer import normalize
from ...runtime._rk4 import feedback_rk4, held_torque_rk4, hoist
from ...runtime._constrained import Baumgarte
from ...runtime._cuda_rollout import held_torque_rollout
from ._field import as_controls, constraint_forces, dynamics_field, with_input
from ._integrators import RK4, classical_rk4, fixed_step
from ._loop import saved_loop
from ._saving import Checkpoint, SaveAt


class Trajectory(NamedTuple):
    """A rollout's saved states (:class:`SaveAt`; by default every state, ``n_saved = steps + 1``).

    ``t``: the saved times, ``(n_saved,)`` when the rollouts share one ``dt`` (broadcast against the batch
    axes, not copied), ``(..., n_saved)`` with one ``dt`` per rollout; ``x (..., n_saved, 2n)`` (a floating
    base: ``nq + nv``, so ``q`` is the first ``(len(x) + 1) // 2`` entries either way);
    ``tau (..., n_saved - 1, n)``: the torque applied at the start of the step that leaves each saved state
    but the last (by default, every step's); controller states ``z`` at the saved states (``()`` if none).
    """

    t: jax.Array
    x: jax.Array
    tau: jax.Array
    z: Any

    @property
    def q(self) -> jax.Array:
        return self.x[..., : (self.x.shape[-1] + 1) // 2]

    @property
    def qd(self) -> jax.Array:
        return self.x[..., (self.x.shape[-1] + 1) // 2:]


def _observe(y):
    q, qd, z = y
    return jnp.concatenate([q, qd]), z


def _rollout_one(dyn, controller, integrator, steps, saveat, checkpoint, autodiff, constraints, x0, p, u, dt, index,
                 batched=False):
    """One rollout: ``(x, tau, z)`` at the saved steps (the times are the caller's). ``p = None``: the default
    parameters, constants of the compiled program (as in :meth:`Dynamics.raw` calls with ``params=None``:
    measured faster on the Panda than passing them)."""
    n, nq, floating = dyn.nv, dyn.nq, dyn.floating_base
    p = dyn.param_vector(None, x0.dtype) if p is None else p
    f = dynamics_field(dyn, controller, p, batched, autodiff, constraints)
    z0 = controller.init(x0) if controller is not None else ()
    tau0 = jnp.zeros((n,), x0.dtype)
    if getattr(integrator, "adaptive", False):  # a diffrax solver with an adaptive controller
        y0 = (x0[:nq], x0[nq:], z0)
        (x, z), tau = integrator.run(f, _observe, y0, u, dt, steps, saveat, index, checkpoint, tau0)
        return x, tau, z

    rows = controller is None and u is not None  # the torques are the rows of u
    record = not rows and not (saveat.t1 and not saveat.t0)  # torques the loop must keep
    # open-loop torques on a fixed base: an RK4 step whose backward pass is one native call
    one_call = constraints is None and autodiff == "reverse" and classical_rk4(integrator)
    # on a GPU, the whole rollout one kernel and its gradient another
    whole = held_torque_rollout(dyn, steps, batched) if rows and one_call and saveat.every == 1 else None
    if whole is not None:
        return whole(x0, u, p, jnp.reshape(dt, (1,))), u, z0
    fused = held_torque_rk4(dyn, batched) if rows and one_call else None
    # a stateless feedback law: its step's backward pass is one native call too
    stateless = controller is not None and u is None and not jax.tree.leaves(z0)
    feedback = feedback_rk4(dyn, batched) if one_call and stateless else None

    def step(carry, u_k):
        k, q, qd, z = carry
        if fused is not None:
            q1, qd1 = fused(q, qd, u_k, p, dt)
            return (k + 1, q1, qd1, z), ()
        if feedback is not None:
            t = k.astype(dt.dtype) * dt
            control, consts = hoist(lambda t, x: controller(t, x, ())[0], t, jnp.concatenate([q, qd]))
            q1, qd1, tau = feedback(control, q, qd, p, dt, t, consts)
            return (k + 1, q1, qd1, z), (tau if record else ())
        (q1, qd1, z1), tau = integrator.step(with_input(f, u_k), k.astype(dt.dtype) * dt, (q, qd, z), dt)
        return (k + 1, normalize(q1, floating), qd1, z1), (tau if record else ())

    block = None if checkpoint is None else checkpoint.size(steps)
    carry0 = (jnp.int32(0), x0[:nq], x0[nq:], z0)
    (x, z), tau = saved_loop(saveat, step, lambda c: _observe(c[1:]), carry0, u, steps, index, block,
                             tau0 if record else ())
    if not record:  # array torques are the rows of u; only the final state saved: none
        tau = _held_rows(u, saveat, steps, index) if rows else jnp.zeros((0, n), x0.dtype)
    return x, tau, z


def _held_rows(u, saveat, steps, index):
    """The torques ``u`` applied from the saved steps but the last: ``(n_saved - 1, n)``."""
    if index is not None:
        return u[jnp.minimum(index[:-1], steps - 1)]
    k = saveat.steps_saved(steps)
    return u[k[:-1]] if saveat.t1 else u[::saveat.every]


def _times(saveat, steps, dt, index):
    """The saved times: ``k dt`` at the saved step numbers ``k``."""
    k = jnp.asarray(saveat.steps_saved(steps) if index is None else index, dt.dtype)
    if dt.ndim and k.ndim == 1:
        k = jnp.broadcast_to(k, (*dt.shape, k.shape[0]))
    return k * (dt[..., None] if dt.ndim else dt)


STATIC = ("dyn", "controller", "integrator", "steps", "saveat", "checkpoint", "autodiff", "constraints")


@partial(jit, static_argnames=STATIC)
def _rollout_single(dyn, controller, integrator, steps, saveat, checkpoint, autodiff, constraints, x0, p, u, dt, index
                    ) -> Trajectory:
    x, tau, z = _rollout_one(dyn, controller, integrator, steps, saveat, checkpoint, autodiff, constraints, x0, p, u,
                             dt, index)
    return Trajectory(_times(saveat, steps, dt, index), x, tau, z)


@partial(jit, static_argnames=(*STATIC, "batch", "devices"))
def _rollout_batch(dyn, controller, integrator, steps, saveat, checkpoint, autodiff, constraints, batch, devices, x0, p,
                   u, dt,
                   index):
    """A batch of rollouts: the inputs flattened to one axis, padded to a multiple of the number of
    ``devices`` and split over them; the outputs reshaped to ``batch``. Inputs without batch axes (the
    parameters, torques, step or saved step numbers) are passed whole to every rollout."""
    size = int(np.prod(batch))
    pad = -size % len(devices)
    one = partial(_rollout_one, dyn, controller, integrator, steps, saveat, checkpoint, autodiff, constraints,
                  batched=True)
    args, tails = (x0, p, u, dt, index), (1, 1, 2, 0, 1)
    mapped = tuple(a is not None and (a.ndim > t or a is x0) for a, t in zip(args, tails))

    def flat(a, tail):
        a = jnp.broadcast_to(a, (*batch, *a.shape[a.ndim - tail:])).reshape((size, *a.shape[a.ndim - tail:]))
        return jnp.concatenate([a, jnp.repeat(a[-1:], pad, axis=0)]) if pad else a

    args = tuple(flat(a, t) if m else a for a, t, m in zip(args, tails, mapped))
    run = jax.vmap(one, in_axes=tuple(0 if m else None for m in mapped))
    if len(devices) > 1:
        spec = PartitionSpec("batch")
        run = jax.shard_map(run, mesh=Mesh(np.asarray(devices), ("batch",)), out_specs=spec,
                            in_specs=tuple(spec if m else PartitionSpec() for m in mapped))
    x, tau, z = jax.tree.map(lambda a: a[:size].reshape((*batch, *a.shape[1:])), run(*args))
    if dt.ndim:  # one step per rollout: one time axis per rollout
        dt = jnp.broadcast_to(dt, batch)
    if index is not None and index.ndim > 1:
        index = jnp.broadcast_to(index, (*batch, index.shape[-1]))
    return Trajectory(_times(saveat, steps, dt, index), x, tau, z)


def rollout(
    dyn: Dynamics,
    x0,
    controls,
    dt,
    steps: int,
    integrator=RK4(),  # noqa: B008  (a frozen dataclass: immutable)
    params=None,
    *,
    saveat: SaveAt | None = None,
    checkpoint: Checkpoint | None = None,
    stepsize_controller=None,
    autodiff: str = "auto",
    devices: Sequence[jax.Device] | None = None,
    stabilization: Baumgarte | None = Baumgarte(), regularization: float = 0.0,  # noqa: B008  (frozen dataclass)
    health: bool | None = None,
) -> Trajectory:
    """Simulate ``M qdd + C qd + Q_grav = tau`` from ``x0 = (q0, qd0)`` for ``steps`` steps of ``dt``.

    Args:
        dyn: lowered with the quantities :func:`forward_dynamics` needs.
        x0: initial state ``(2n,)``, or ``(..., 2n)`` for a batch of rollouts (a floating base: ``nq + nv``).
        controls: the torques: an array ``(steps, n)`` held constant over each step (``(..., steps, n)``:
            one sequence per rollout of a batch); a policy ``tau = policy(t, x)``; a :class:`Controller` (``(tau,
            dz/dt) = controller(t, x, z)``, ``z`` integrated too); or a :class:`HeldInput`: a controller fed an
            array held like torques (:meth:`DCMotors.drive`'s voltages). All are evaluated at every stage.
        dt: the step in seconds, a scalar, or one per rollout of a batch (its batch axes broadcast against
            those of ``x0``; ``steps`` is shared).
        steps: the number of steps (a Python int); the rollout ends at ``steps * dt``.
        integrator: :class:`RK4`, :class:`SemiImplicitEuler` (any object with ``step(f, t, y, dt)``), or a
            diffrax solver (``diffrax.Tsit5()``, ``diffrax.Kvaerno5()``, ...), which takes fixed steps of ``dt``
            unless ``stepsize_controller`` is adaptive; see :mod:`jaxskid.apps.simulation._diffrax`.
        params: as for :func:`forward_dynamics`; ``(..., n_params)`` or a dict of batched values pairs one
            parameter set with each rollout of a batch (batch axes broadcast against those of ``x0``).
        saveat: which states are returned (:class:`SaveAt`); ``None`` is ``SaveAt()``, every state. The
            others are never stored.
        checkpoint: ``Checkpoint()`` bounds the memory of ``jax.grad`` through the rollout to
            ``O(sqrt(steps))`` states by recomputing blocks of steps (:class:`Checkpoint`); ``None`` stores
            every step's residuals.
        stepsize_controller: with a diffrax solver, an adaptive diffrax controller
            (``diffrax.PIDController(rtol=1e-8, atol=1e-8)``): the solver chooses its steps from ``dt`` on, and
            array controls stay held over the grid ``t_k = k dt``. ``None``: fixed steps of ``dt``.
        autodiff: ``"reverse"`` for ``jax.grad`` (closed-form step derivatives, :mod:`jaxskid.runtime._rk4`),
            ``"forward"`` for ``jax.jvp``/``jax.jacfwd`` (``jax.grad`` too, slower), or ``"auto"``: forward where
            the innermost differentiation around the call is forward mode, else reverse (``jax.hessian`` too).
        devices: where a batch runs; default ``jax.local_devices()``. With several devices the batch is
            split across them (``jax.shard_map`` over a one-axis mesh; padded to a multiple of their
            number). For several hosts, call ``jax.distributed.initialize()`` first and pass
            ``jax.devices()``.
        stabilization, regularization: a constrained robot's (module docstring; :func:`constrained_forward_dynamics`).
        health: from Python, warn (:class:`RolloutWarning`) where RK4's step does not integrate the closed loop
            at the final states stably, naming the rollouts and a step that would, and where a floating base ends
            below the ground with no contact frame on it (``None``: with contact; :mod:`._health`); unless False,
            also where a rollout's last saved state is not finite, naming when it diverged.

    Returns:
        a :class:`Trajectory` of the saved states; by default ``x`` has shape ``(..., steps+1, 2n)``.

    ``jax.vmap``, ``jax.grad``, ``jax.jacfwd``, ``jax.hessian`` and ``jax.jit`` compose with it, and ``controls``
    may close over values they trace; a batch is one compiled call (no slower than ``jax.vmap`` of rollouts).
    """
    require_solver(dyn, "rollout")
    steps = _steps(steps)
    integrator = _stepping(integrator, stepsize_controller)
    saveat, autodiff = _check_choices(saveat, checkpoint, autodiff, _implicit(integrator))
    controller, u = as_controls(controls)
    x0, u, p, dtype = _with_params(dyn, *_inputs(dyn, x0, u), params)
    dt = _step(dt, dtype)
    batch = _batch(dyn, x0, p, u, dt, steps)
    saveat.block(steps)  # every= must divide steps
    index = None if saveat.ts is None else saveat.steps_of_times(dt, steps, dtype)
    constraints = constraint_forces(dyn, stabilization, regularization, "rollout")
    static = (dyn, controller, integrator, steps, saveat, checkpoint, autodiff, constraints)
    if not batch:
        traj = _rollout_single(*static, x0, p, u, dt, index)
    else:
        devices = tuple(devices) if devices is not None else tuple(jax.local_devices())
        devices = devices[:max(1, min(len(devices), int(np.prod(batch))))]
        traj = _rollout_batch(*static, batch, devices, x0, p, u, dt, index)
    return _checked(traj, static, controls, dt, params, health)


def _batch(dyn, x0, p, u, dt, steps: int) -> tuple:
    """The batch shape of a rollout's inputs (:func:`~jaxskid.runtime._batching.batch_shape`)."""
    n, n_params = dyn.nv, (len(dyn.parameters),)
    extras = [("params", n_params if p is None else p.shape, n_params), ("dt", dt.shape, ())]
    if u is not None:
        extras.append(("controls", u.shape, (steps, n)))
    return batch_shape("rollout", [("x0", x0.shape, (dyn.nq + n,))], extras)


def _checked(traj: Trajectory, static: tuple, controls, dt, params, health) -> Trajectory:
    """``traj``, after :func:`~jaxskid.apps.simulation._health.warn_if_not_finite` (unless ``health`` is False),
    :func:`~jaxskid.apps.simulation._health.warn_if_unstable` on its final states where ``health`` asks for it
    (``None``: a scene with ground contact), outside any trace, for RK4 with one parameter set, and
    :func:`~jaxskid.apps.simulation._health.warn_if_below_ground` in a scene with ground contact."""
    from ._contact import GroundContact
    from ._health import warn_if_below_ground, warn_if_not_finite, warn_if_unstable

    dyn, controller, integrator = static[:3]

    def one_rk4() -> bool:  # the step check's scope: RK4, one step, one parameter set
        one_set = params is None or np.ndim(dyn.param_vector(params)) < 2
        return classical_rk4(integrator) and not np.ndim(dt) and one_set

    if health is not False and top_level((traj.x, dt)):
        if not warn_if_not_finite(dyn, controls, traj, dt, params, one_rk4, stacklevel=4):
            return traj
    if health is None:
        health = isinstance(controller, GroundContact)
    if health and isinstance(controller, GroundContact) and top_level((traj.x,)):
        warn_if_below_ground(controller, traj.x[..., -1, :], stacklevel=4)
    if not health or not top_level((traj.x, dt)) or not one_rk4():
        return traj

    warn_if_unstable(dyn, controls, traj.x[..., -1, :], dt, params, stacklevel=4)
    return traj


def _with_params(dyn, x0, u, dtype, params):
    """``(x0, u, p, dtype)``: the parameters as a vector (``None``: the defaults, compiled in); complex ones (a
    complex step) make the states and torques complex too, ``dtype`` (the time's) staying real."""
    p = None if params is None else dyn.param_vector(params, dtype)
    if p is not None and p.dtype != x0.dtype:
        x0, u = x0.astype(p.dtype), None if u is None else u.astype(p.dtype)
    return x0, u, p, dtype


def _inputs(dyn, x0, u):
    """``(x0, u, dtype)``: the initial states and the torque or input array (or None) in one floating dtype,
    checked for NaN and inf (:func:`~jaxskid.runtime._checks.check_inputs`)."""
    check_inputs(dyn.checks, "rollout", [("x0", x0), ("controls", u)])
    arrays, dtype = float_arrays([x0] if u is None else [x0, u])
    return arrays[0], (arrays[1] if u is not None else None), dtype


def _stepping(integrator, stepsize_controller):
    """The rollout's integrator, checked; diffrax is imported only when a diffrax object may be involved."""
    if stepsize_controller is None and "diffrax" not in sys.modules:  # then no diffrax solver exists here
        return fixed_step(integrator)
    from ._diffrax import stepping

    return stepping(integrator, stepsize_controller)


def _steps(steps) -> int:
    if isinstance(steps, (bool, jax.Array)) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise RequestError(f"rollout: steps: expected a whole number >= 1 (a Python int, it fixes the loop "
                           f"length), got {steps!r}")
    return int(steps)


def _implicit(integrator) -> bool:
    """Whether ``integrator`` is an implicit diffrax solver, whose root finder differentiates the dynamics in
    forward mode at every step."""
    solver, diffrax = getattr(integrator, "solver", None), sys.modules.get("diffrax")
    return solver is not None and diffrax is not None and isinstance(solver, diffrax.AbstractImplicitSolver)


def _check_choices(saveat, checkpoint, autodiff, implicit: bool = False) -> tuple[SaveAt, str]:
    """The rollout's ``saveat`` (``None``: :class:`SaveAt`), ``checkpoint`` and ``autodiff`` checked; returns
    ``(saveat, autodiff)``, ``"auto"`` resolved by the differentiation around the call (forward mode for an
    ``implicit`` solver, which differentiates the dynamics itself)."""
    saveat = SaveAt() if saveat is None else saveat
    if autodiff not in (*AUTODIFF, "auto"):
        raise RequestError(f"rollout: autodiff must be one of {', '.join(map(repr, (*AUTODIFF, 'auto')))}, "
                           f"got {autodiff!r}")
    if not isinstance(saveat, SaveAt):
        got = f"{type(saveat).__module__.split('.')[0]}.{type(saveat).__name__}"
        raise RequestError(f"rollout: saveat: expected a jaxskid.SaveAt (diffrax solvers too), got {got}")
    if checkpoint is not None and not isinstance(checkpoint, Checkpoint):
        raise RequestError(f"rollout: checkpoint: expected None or jaxskid.Checkpoint(), got {checkpoint!r}")
    if implicit and autodiff == "reverse":
        raise RequestError("rollout: autodiff='reverse' with an implicit solver: its root finder differentiates the "
                           "dynamics in forward mode at every step; use autodiff='auto' or 'forward'")
    if autodiff == "auto":
        autodiff = "forward" if implicit or forward_mode() else "reverse"
    return saveat, autodiff


def _step(dt, dtype):
    """``dt`` in the rollout's dtype; a concrete one is checked to be finite and positive and stays a NumPy
    array (the jitted call takes it in faster than a JAX array made here)."""
    if traced(dt):
        return jnp.asarray(dt, dtype)
    try:
        host = np.asarray(dt, dtype=np.float64)
    except (TypeError, ValueError):
        raise RequestError(f"rollout: dt: expected a step in seconds (a number or an array), got {dt!r}") from None
    if not np.all(np.isfinite(host) & (host > 0)):
        bad = host if host.ndim == 0 else host[~(np.isfinite(host) & (host > 0))][0]
        raise RequestError(f"rollout: dt: expected finite steps > 0, got {bad}")
    return host.astype(dtype)
