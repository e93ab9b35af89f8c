"""Integrators and rollouts on top of a lowered :class:`~jaxskid.Dynamics`.

Rollouts integrate ``(q, qd)`` with an integrator object under ``lax.scan``, with the joint accelerations
of :func:`jaxskid.forward_dynamics` (:mod:`jaxskid.runtime._forward`); batches are ``vmap``-ed and, when
several devices are given, split across them with ``shard_map``.

State convention: ``x = (q, qd)`` concatenated, shape ``(2 n,)``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, PartitionSpec

from ..runtime._dynamics import Dynamics
from ..runtime._batching import batch_shape, float_arrays
from .._errors import RequestError
from ..runtime._forward import accelerations, require_solver
from ..runtime._implicit import AUTODIFF
from ..runtime._jit import jit


# ---------------------------------------------------------------------------------------- integrators
@dataclass(frozen=True)
class SemiImplicitEuler:
    """Semi-implicit Euler: ``qd' = qd + dt qdd(q, qd)``, ``q' = q + dt qd'``. Order 1.

    The velocity is updated first and the position with the new velocity; other states (a controller's)
    take an explicit Euler step. It is symplectic when the mass matrix is constant (Hairer, Lubich & Wanner,
    "Geometric Numerical Integration", 2006, sec. VI.3), not for a configuration-dependent M.
    """

    order = 1

    def step(self, f: Callable, t, y, dt):
        (_, qdd, zdot), aux = f(t, y)
        q, qd, z = y
        qd1 = qd + dt * qdd
        z1 = jax.tree.map(lambda a, b: a + dt * b, z, zdot)
        return (q + dt * qd1, qd1, z1), aux


@dataclass(frozen=True)
class RK4:
    """The classical fourth-order Runge-Kutta method (Hairer, Norsett & Wanner, "Solving Ordinary
    Differential Equations I", Table 1.2). Order 4."""

    order = 4

    def step(self, f: Callable, t, y, dt):
        def axpy(a, dy, base):
            return jax.tree.map(lambda u, v: u + a * v, base, dy)

        def stage(carry, cb):
            k, acc = carry
            c, b = cb
            ki, aux = f(t + c * dt, axpy(c * dt, k, y))
            return (ki, axpy(b, ki, acc)), aux

        zero = jax.tree.map(jnp.zeros_like, y)
        dtype = jnp.result_type(dt)
        cb = (jnp.asarray([0.0, 0.5, 0.5, 1.0], dtype), jnp.asarray([1 / 6, 1 / 3, 1 / 3, 1 / 6], dtype))
        (_, incr), aux = jax.lax.scan(stage, (zero, zero), cb)
        return axpy(dt, incr, y), jax.tree.map(lambda a: a[0], aux)


# ---------------------------------------------------------------------------------------- controllers
class Controller:
    """A feedback law with an internal state: ``tau = u(t, x, z)``, ``dz/dt = h(t, x, z)``.

    ``__call__(t, x, z)`` returns ``(tau, dz/dt)``; :func:`rollout` integrates ``z`` with the robot.
    Stateless laws keep ``z = ()``. Subclasses are compared by identity (they are jit's static arguments).
    """

    def init(self, x0: jax.Array) -> Any:
        return ()

    def __call__(self, t, x, z):
        raise NotImplementedError


class _Policy(Controller):
    """A stateless ``policy(t, x)``; equal to another wrapper of the same policy (no recompilation)."""

    def __init__(self, fn: Callable):
        self.fn = fn

    def __call__(self, t, x, z):
        return self.fn(t, x), ()

    def __eq__(self, other):
        return isinstance(other, _Policy) and other.fn is self.fn

    def __hash__(self):
        return hash((_Policy, id(self.fn)))


class Trajectory(NamedTuple):
    """A rollout: ``t (steps+1,)``, states ``x (steps+1, 2n)``, torques ``tau (steps, n)`` applied at the
    start of each step, controller states ``z`` (``()`` if none). Batched rollouts add leading axes."""

    t: jax.Array
    x: jax.Array
    tau: jax.Array
    z: Any

    @property
    def q(self) -> jax.Array:
        return self.x[..., : self.x.shape[-1] // 2]

    @property
    def qd(self) -> jax.Array:
        return self.x[..., self.x.shape[-1] // 2:]


def _rollout_one(dyn, controller, integrator, steps, autodiff, x0, p, u, dt, batched=False) -> Trajectory:
    n = dyn.n_dof
    qdd = accelerations(dyn, batched, autodiff)
    z0 = controller.init(x0) if controller is not None else ()

    def step(carry, u_k):
        t, q, qd, z = carry

        def f(t, y):
            q, qd, z = y
            x = jnp.concatenate([q, qd])
            if controller is None:
                tau, zdot = u_k, ()
            else:
                tau, zdot = controller(t, x, z)
            return (qd, qdd(q, qd, tau, p), zdot), tau

        (q1, qd1, z1), tau = integrator.step(f, t, (q, qd, z), dt)
        return (t + dt, q1, qd1, z1), (jnp.concatenate([q1, qd1]), tau, z1)

    carry0 = (jnp.zeros((), x0.dtype), x0[:n], x0[n:], z0)
    _, (xs, taus, zs) = jax.lax.scan(step, carry0, u, length=steps)
    t = dt * jnp.arange(steps + 1, dtype=x0.dtype)
    x = jnp.concatenate([x0[None, :], xs], axis=0)
    z = jax.tree.map(lambda a, b: jnp.concatenate([jnp.asarray(a)[None], b], axis=0), z0, zs)
    return Trajectory(t, x, taus, z)


_rollout_single = jit(_rollout_one, static_argnames=("dyn", "controller", "integrator", "steps", "autodiff"))


@partial(jit, static_argnames=("dyn", "controller", "integrator", "steps", "autodiff", "p_batched", "u_batched",
                               "devices"))
def _rollout_batch(dyn, controller, integrator, steps, autodiff, p_batched, u_batched, devices, x0, p, u, dt):
    one = partial(_rollout_one, dyn, controller, integrator, steps, autodiff, batched=True)
    run = jax.vmap(one, in_axes=(0, 0 if p_batched else None, 0 if u_batched else None, None))
    if len(devices) > 1:
        mesh = Mesh(np.asarray(devices), ("batch",))
        spec = PartitionSpec("batch")
        run = jax.shard_map(
            run, mesh=mesh,
            in_specs=(spec, spec if p_batched else PartitionSpec(), spec if u_batched else PartitionSpec(), PartitionSpec()),
            out_specs=spec,
        )
    return run(x0, p, u, dt)


def rollout(
    dyn: Dynamics,
    x0,
    controls,
    dt: float,
    steps: int,
    integrator=RK4(),
    params=None,
    *,
    autodiff: str = "reverse",
    devices: Sequence[jax.Device] | None = None,
) -> Trajectory:
    """Simulate ``M qdd + C qd + Q_grav = tau`` from ``x0 = (q0, qd0)`` for ``steps`` steps of ``dt``.

    Args:
        dyn: lowered with the quantities :func:`forward_dynamics` needs.
        x0: initial state ``(2n,)``, or ``(..., 2n)`` for a batch of rollouts.
        controls: the torques: an array ``(steps, n)`` held constant over each step (``(..., steps, n)``:
            one sequence per rollout of a batch); a policy ``tau = policy(t, x)``; or a
            :class:`Controller` (``(tau, dz/dt) = controller(t, x, z)``), whose state is integrated too.
            Policies and controllers are evaluated at every stage of the integrator.
        dt: the step, in seconds.
        steps: the number of steps.
        integrator: :class:`RK4` or :class:`SemiImplicitEuler` (any object with ``step(f, t, y, dt)``).
        params: as for :func:`forward_dynamics`; ``(..., n_params)`` or a dict of batched values pairs one
            parameter set with each rollout of a batch (batch axes broadcast against those of ``x0``).
        autodiff: how JAX differentiates the rollout: ``"reverse"`` (``jax.grad``, ``jax.vjp``: each step's
            derivative is the closed-form vector-Jacobian product of inverse dynamics and one solve with M,
            see :mod:`jaxskid.runtime._implicit`) or ``"forward"`` (``jax.jvp``, ``jax.jacfwd``; reverse
            mode works too, more slowly). As diffrax's ``adjoint=ForwardMode()``: forward mode needs asking.
        devices: where a batch runs; default ``jax.local_devices()``. With several devices the batch is
            split across them (``jax.shard_map`` over a one-axis mesh; padded to a multiple of their
            number). For several hosts, call ``jax.distributed.initialize()`` first and pass
            ``jax.devices()``.

    Returns:
        a :class:`Trajectory`; ``x`` has shape ``(..., steps+1, 2n)``.

    ``rollout`` is traceable: ``jax.vmap``, ``jax.grad`` and ``jax.jit`` apply to it for a single rollout.
    """
    n = dyn.n_dof
    require_solver(dyn, "rollout")
    if autodiff not in AUTODIFF:
        raise RequestError(f"rollout: autodiff must be one of {', '.join(map(repr, AUTODIFF))}, got {autodiff!r}")
    steps = int(steps)
    controller, u = _controls(controls)
    arrays, dtype = float_arrays([x0] if u is None else [x0, u])
    x0, u = arrays[0], (arrays[1] if u is not None else None)
    p = dyn.param_vector(params, dtype)
    extras = [("params", p.shape, (len(dyn.parameters),))]
    if u is not None:
        extras.append(("controls", u.shape, (steps, n)))
    batch = batch_shape("rollout", [("x0", x0.shape, (2 * n,))], extras)
    dt = jnp.asarray(dt, dtype)
    if not batch:
        return _rollout_single(dyn, controller, integrator, steps, autodiff, x0, p, u, dt)
    return _rollout_spread(dyn, controller, integrator, steps, autodiff, batch, devices, x0, p, u, dt)


def _controls(controls) -> tuple[Controller | None, jax.Array | None]:
    """(controller, torque array): a :class:`Controller`, a policy ``tau(t, x)`` or an array."""
    if isinstance(controls, Controller):
        return controls, None
    if callable(controls):
        return _Policy(controls), None
    return None, jnp.asarray(controls)


def _rollout_spread(dyn, controller, integrator, steps, autodiff, batch, devices, x0, p, u, dt) -> Trajectory:
    """A batch of rollouts, flattened to one axis and split over ``devices`` (padded to a multiple)."""
    size = int(np.prod(batch))
    devices = tuple(devices) if devices is not None else tuple(jax.local_devices())
    devices = devices[:max(1, min(len(devices), size))]
    pad = -size % len(devices)

    def flat(a, tail, always=False):
        if a is None or (a.ndim == tail and not always):
            return a
        a = jnp.broadcast_to(a, (*batch, *a.shape[a.ndim - tail:])).reshape((size, *a.shape[a.ndim - tail:]))
        return jnp.concatenate([a, jnp.repeat(a[-1:], pad, axis=0)], axis=0) if pad else a

    p_batched, u_batched = p.ndim > 1, u is not None and u.ndim > 2
    out = _rollout_batch(
        dyn, controller, integrator, steps, autodiff, p_batched, u_batched, devices, flat(x0, 1, True), flat(p, 1),
        flat(u, 2), dt,
    )
    return jax.tree.map(lambda a: a[:size].reshape((*batch, *a.shape[1:])), out)
