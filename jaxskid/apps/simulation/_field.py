"""The equations of motion as a first-order system, driven by torques, a policy or a controller.

The state is ``y = (q, qd, z)``: joint positions and velocities ``(n,)`` each and the state ``z`` of a
controller (``()`` if none), and

    dq/dt = qd,    dqd/dt = qdd = M(q)^-1 (tau - C(q, qd) qd - Q_grav(q)),    dz/dt = h(t, x, z),

with ``x = (q, qd)`` concatenated ``(2n,)`` and ``tau`` from the controls. With a floating base ``q`` is
``(p, quat, q_j)`` ``(nq,)`` and ``qd`` the velocity ``(omega, v, qd_j)`` ``(nv,)``: ``dq/dt`` is then
:func:`jaxskid.runtime._free_flyer.configuration_rate` (``dp/dt = R v``, ``dquat/dt = quat (omega, 0) / 2``),
and ``x`` is ``(nq + nv,)``, its first ``(len(x) + 1) // 2`` entries ``q`` in either case. The controls are: an array held constant over each
step of a grid ``t_k = k dt``, a policy ``tau(t, x)``, a :class:`Controller` ``(tau, dz/dt)(t, x, z)``, or a
controller fed an input array held over each step (:class:`HeldInput`: ``(tau, dz/dt)(t, x, z, u_k)``, e.g. the
voltages of :class:`jaxskid.DCMotors`).
The accelerations are those of :func:`jaxskid.forward_dynamics` (:mod:`jaxskid.runtime._forward`).
:func:`vector_field` gives the same system in diffrax's form, ``f(t, y, args)``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from ..._errors import RequestError, ShapeError
from ...runtime._batching import float_arrays
from ...runtime._dynamics import Dynamics
from ...runtime._constrained import (
    CONSTRAINT_QUANTITIES, Baumgarte, constrained_accelerations, options, require_constraints,
)
from ...runtime._forward import accelerations, require_solver
from ...runtime._free_flyer import configuration_rate


class Controller:
    """A feedback law with an internal state: ``tau = u(t, x, z)``, ``dz/dt = h(t, x, z)``.

    ``__call__(t, x, z)`` returns ``(tau, dz/dt)``; :func:`rollout` integrates ``z`` with the robot.
    Stateless laws keep ``z = ()``. Subclasses are compared by identity (they are jit's static arguments).
    A controller given inputs through :class:`HeldInput` is called as ``(t, x, z, u_k)``.
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


class HeldInput(NamedTuple):
    """A :class:`Controller` ``controller`` fed an array ``inputs`` ``(steps, n)`` (``(..., steps, n)``: one per
    rollout of a batch) held over each step exactly as array torques are: every stage of a step sees ``u[k]``, and the
    controller gives ``(tau, dz/dt) = controller(t, x, z, u_k)``. The array is an input of the compiled
    rollout (a new one does not recompile; it can be batched and differentiated), not part of the controller.
    """

    controller: Controller
    inputs: Any


def as_controls(controls) -> tuple[Controller | None, jax.Array | None]:
    """(controller, array): a :class:`Controller`, a policy ``tau(t, x)``, a torque array (no controller), or
    a :class:`HeldInput` (its controller and its input array)."""
    if isinstance(controls, HeldInput):
        if not isinstance(controls.controller, Controller):
            raise RequestError(f"HeldInput: expected a jaxskid.Controller, got {type(controls.controller).__name__}")
        return controls.controller, jnp.asarray(controls.inputs)
    if isinstance(controls, Controller):
        return controls, None
    if callable(controls):
        return _Policy(controls), None
    return None, jnp.asarray(controls)


def dynamics_field(dyn: Dynamics, controller: Controller | None, p: jax.Array, batched: bool,
                   autodiff: str = "forward", constraints: tuple | None = None) -> Callable:
    """``f(t, y, u_k) -> (dy/dt, tau)`` for ``y = (q, qd, z)``; ``u_k`` is the held row ``(n,)`` of an array:
    the torque without a controller, the controller's input with one (:class:`HeldInput`); else ``None``.
    ``batched``: whether ``f`` will be mapped with ``jax.vmap`` (see :meth:`jaxskid.Dynamics.raw`);
    ``autodiff``: how the accelerations are differentiated (:func:`jaxskid.runtime._implicit.differentiable`);
    ``constraints``: ``(stabilization, regularization)`` of a constrained robot (:func:`constraint_forces`), whose
    accelerations are then :func:`jaxskid.constrained_forward_dynamics`'.
    ``f.rate(q, v)`` is ``dq/dt`` at the velocity ``v`` (``v`` itself for a fixed base), for an integrator that
    moves the positions with an updated velocity (:class:`jaxskid.SemiImplicitEuler`)."""
    if constraints is None:
        qdd = accelerations(dyn, batched, autodiff)
    else:
        qdd = constrained_accelerations(dyn, batched, *constraints)
    floating = dyn.floating_base

    def rate(q, v):
        return configuration_rate(q, v, floating)

    def f(t, y, u_k):
        q, qd, z = y
        if controller is None:
            tau, zdot = u_k, ()
        elif u_k is None:
            tau, zdot = controller(t, jnp.concatenate([q, qd]), z)
        else:
            tau, zdot = controller(t, jnp.concatenate([q, qd]), z, u_k)
        return (rate(q, qd), qdd(q, qd, tau, p), zdot), tau

    f.rate = rate
    return f


def constraint_forces(dyn: Dynamics, stabilization, regularization: float, what: str) -> tuple | None:
    """``None`` for a robot without lowered constraint quantities; else ``(stabilization, regularization)``,
    checked, for :func:`dynamics_field` (:func:`jaxskid.constrained_forward_dynamics` gives their meaning)."""
    if not set(CONSTRAINT_QUANTITIES) & set(dyn.quantities):
        return None
    require_constraints(dyn, what)
    return options(stabilization, regularization)


def with_input(f: Callable, u_k) -> Callable:
    """``(t, y) -> f(t, y, u_k)``, keeping ``f.rate``: the field one step of an integrator sees."""

    def g(t, y):
        return f(t, y, u_k)

    g.rate = f.rate
    return g


def held(u: jax.Array, grid: jax.Array, t) -> jax.Array:
    """The row of ``u (steps, n)`` in force at time ``t`` on the grid ``t_k`` ``(steps+1,)``: ``u[k]`` for
    ``t_k <= t < t_{k+1}`` (right-continuous), the first row before ``t_0`` and the last from ``t_steps`` on.

    A diffrax solve that stops at a jump steps to just before it and restarts just after it
    (``ClipStepSizeController(jump_ts=...)``), so each step sees the row of its own interval.
    """
    k = jnp.searchsorted(grid, t, side="right") - 1
    return u[jnp.clip(k, 0, u.shape[0] - 1)]


def vector_field(dyn: Dynamics, controls, params=None, *, dt=None,
                 stabilization: Baumgarte | None = Baumgarte(), regularization: float = 0.0) -> Callable:  # noqa: B008
    """The robot's equations of motion as a diffrax vector field ``f(t, y, args) -> dy/dt``.

    ``diffrax.ODETerm(vector_field(dyn, controls))`` solves ``M qdd + C qd + Q_grav = tau`` with any diffrax
    solver; ``args`` is not used.

    Args:
        dyn: lowered with the quantities :func:`jaxskid.forward_dynamics` needs.
        controls: an array ``(steps, n)`` held constant over each step of the grid ``t_k = k dt``
            (``u[k]`` for ``t_k <= t < t_{k+1}``; pass the grid as ``jump_ts`` of a
            ``diffrax.ClipStepSizeController`` so that steps stop at the jumps); a policy ``tau(t, x)``; a
            :class:`Controller`; or a :class:`HeldInput` (its inputs held over the same grid).
        params: as for :func:`jaxskid.forward_dynamics`: ``None``, a dict, or one vector ``(n_params,)``.
        dt: the grid's step in seconds; needed for (only for) array controls.
        stabilization, regularization: for a robot with constraints, as for :func:`jaxskid.rollout`.

    Returns:
        ``f(t, y, args)``. ``y`` is the state ``x = (q, qd)`` ``(2n,)``, and the pair ``(x, z)`` for a
        :class:`Controller` with a state (``z0 = controller.init(x0)``, not empty); ``dy/dt`` has the same
        form. One state; ``jax.vmap`` it, or the solve, for a batch.
    """
    require_solver(dyn, "vector_field")
    n, nq = dyn.nv, dyn.nq
    controller, u = as_controls(controls)
    if u is not None:
        (u,), dtype = float_arrays([u])
        if dt is None:
            raise RequestError("vector_field: dt: array controls are held over a grid t_k = k dt; pass dt")
        if u.ndim != 2 or u.shape[1] != n:
            raise ShapeError(f"vector_field: controls: expected shape (steps, {n}), got {u.shape}")
        grid = jnp.asarray(dt, dtype) * jnp.arange(u.shape[0] + 1, dtype=dtype)
    else:
        dtype = jnp.result_type(float)
    constraints = constraint_forces(dyn, stabilization, regularization, "vector_field")
    f = dynamics_field(dyn, controller, dyn.param_vector(params, dtype), batched=False, constraints=constraints)
    stateful = controller is not None and bool(
        jax.tree.leaves(jax.eval_shape(controller.init, jax.ShapeDtypeStruct((nq + n,), dtype)))
    )

    def field(t, y, args):
        x, z = y if stateful else (y, ())
        (dq, dqd, dz), _ = f(t, (x[:nq], x[nq:], z), None if u is None else held(u, grid, t))
        dx = jnp.concatenate([dq, dqd])
        return (dx, dz) if stateful else dx

    return field
