"""Forward dynamics, integrators and rollouts on top of a lowered :class:`~jaxskid.Dynamics`.

Forward dynamics solves the equations of motion for the accelerations,

    M(q) qdd = tau - C(q, qd) qd - Q_grav(q) - Q_ext(q, W),

with the bias ``C qd + Q_grav`` from one recursive Newton-Euler pass (``inverse_dynamics`` at ``qdd = 0``,
measured faster than ``coriolis_torques + gravity_torques``) and an unrolled square-root-free Cholesky
factorisation ``M = L D L^T`` (Golub & Van Loan, "Matrix Computations", 4th ed., Alg. 4.1.2). Rollouts
integrate ``(q, qd)`` with an integrator object under ``lax.scan``; batches are ``vmap``-ed and, when
several devices are given, split across them with ``shard_map``.

State convention: ``x = (q, qd)`` concatenated, shape ``(2 n,)``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, PartitionSpec

from ..runtime._dynamics import Dynamics, jit
from .._errors import RequestError, ShapeError
from .._kernels import recip


# ---------------------------------------------------------------------------------------- helpers
def _assemble(values: Sequence, dtype) -> jax.Array:
    """A vector from scalars by a chain of ``where`` selects (the output form XLA fuses into one loop,
    see :mod:`jaxskid.codegen._jax`); ``jnp.stack`` would split the computation into slow kernels."""
    out = jnp.zeros((len(values),), dtype)
    index = jnp.arange(len(values))
    for k, v in enumerate(values):
        out = jnp.where(index == k, v, out)
    return out


_reciprocal = recip
"""``1 / d`` by Newton's iteration from a bit-level first guess, the same as in generated modules
(:mod:`jaxskid._kernels`): XLA on CPU will not fuse a division whose result has several users, so
each pivot reciprocal of the factorisation would cut the fused kernel in pieces that recompute their
shared inputs (measured: 1.2 us instead of 0.9 us per Panda state, and 5 us with a division per entry)."""


def _materialize(x: jax.Array) -> jax.Array:
    """``x``, computed once. XLA on CPU fuses a producer made of cheap operations into every consumer
    fusion, so chaining accelerations (the stages of RK4) recomputed each stage inside the next one's
    kernels: 0.46 us per evaluation alone, 1.4 us per evaluation in a chain of four (3-DOF arm, batch
    1024). A dot is never fused on CPU and ``optimization_barrier`` is dropped by the compiler, so
    ``x @ I`` (n^2 multiply-adds) materialises ``x``."""
    return x @ jnp.eye(x.shape[-1], dtype=x.dtype)


def ldl_solve(m: jax.Array, b: jax.Array) -> jax.Array:
    """Solve ``m x = b`` for one symmetric positive definite ``m`` (n, n) by ``m = L D L^T``, unrolled.

    Square-root free Cholesky (Golub & Van Loan, Alg. 4.1.2), written entry by entry so that XLA fuses it
    with the computation of ``m`` and ``b``; vmap it for a batch. A matrix that is not positive definite
    (a pivot <= 0, e.g. from non-physical inertial parameters) gives nan, as ``jnp.linalg.cholesky`` does.
    """
    n = b.shape[-1]
    lo = [[None] * n for _ in range(n)]
    d, dinv = [None] * n, [None] * n
    for j in range(n):
        s = m[j, j]
        for k in range(j):
            s = s - lo[j][k] * lo[j][k] * d[k]
        d[j], dinv[j] = s, jnp.where(s > 0, _reciprocal(s), jnp.nan)  # as jnp.linalg.cholesky: nan if not SPD
        for i in range(j + 1, n):
            s = m[i, j]
            for k in range(j):
                s = s - lo[i][k] * lo[j][k] * d[k]
            lo[i][j] = s * dinv[j]
    y = [None] * n
    for i in range(n):  # L y = b
        s = b[i]
        for k in range(i):
            s = s - lo[i][k] * y[k]
        y[i] = s
    x = [None] * n
    for i in reversed(range(n)):  # D L^T x = y
        s = y[i] * dinv[i]
        for k in range(i + 1, n):
            s = s - lo[k][i] * x[k]
        x[i] = s
    return _assemble(x, b.dtype)


def _require(dyn: Dynamics, what: str) -> None:
    have = set(dyn.quantities)
    if "forward_dynamics" in have:
        return
    if "mass_matrix" not in have or not ({"inverse_dynamics"} <= have or {"coriolis_torques", "gravity_torques"} <= have):
        raise RequestError(
            f"{what} needs the quantity forward_dynamics, or mass_matrix and inverse_dynamics (or "
            f"coriolis_torques and gravity_torques); lowered: {', '.join(dyn.quantities)}. Ask for them with "
            "jaxskid.lower(robot, quantities=[..., 'forward_dynamics'])"
        )


def accelerations(dyn: Dynamics, batched: bool = True) -> Callable:
    """The single-state function ``qdd(q, qd, tau, p, wrench=None)`` with ``p`` a parameter vector.

    With the quantity ``forward_dynamics`` lowered, this is the closed form (:mod:`jaxskid.symbolic._forward`);
    otherwise M and the bias are evaluated and solved by :func:`ldl_solve`. ``batched``: whether the
    function will be mapped with ``jax.vmap`` (see :meth:`jaxskid.Dynamics.raw`).
    """
    _require(dyn, "forward_dynamics")

    def raw(name: str) -> Callable:
        return dyn.raw(name, batched)

    if "forward_dynamics" in dyn.quantities:
        solve = raw("forward_dynamics")
    else:
        mass = raw("mass_matrix")
        if "inverse_dynamics" in dyn.quantities:
            rnea = raw("inverse_dynamics")

            def bias(q, qd, p):
                return rnea(q, qd, jnp.zeros_like(qd), p)
        else:
            cor, grav = raw("coriolis_torques"), raw("gravity_torques")

            def bias(q, qd, p):
                return cor(q, qd, p) + grav(q, p)

        def solve(q, qd, tau, p):
            return ldl_solve(mass(q, p), tau - bias(q, qd, p))

    def qdd(q, qd, tau, p, wrench=None):
        if wrench is not None:
            tau = tau - raw("external_torques")(q, wrench, p)
        return _materialize(solve(q, qd, tau, p))

    return qdd


def _param_array(dyn: Dynamics, params, dtype) -> jax.Array:
    """params as an array (..., n_params): a vector, a batch of vectors or a dict of (batched) values."""
    if isinstance(params, Mapping):
        missing = [k for k in dyn.parameters if k not in params]
        if missing:
            raise RequestError(f"params is missing {', '.join(missing)} (expected the names in Dynamics.parameters)")
        if not dyn.parameters:
            return jnp.zeros((0,), dtype)
        vals = jnp.broadcast_arrays(*[jnp.asarray(params[k], dtype) for k in dyn.parameters])
        return jnp.stack(vals, axis=-1)
    if params is None:
        return dyn.param_vector(None, dtype)
    p = jnp.asarray(params, dtype)
    if p.ndim == 0 or p.shape[-1] != len(dyn.parameters):
        raise ShapeError(f"params: expected a dict or shape (..., {len(dyn.parameters)}), got {p.shape}")
    return p


def _float_dtype(*arrays):
    dt = jnp.result_type(*arrays)
    return dt if jnp.issubdtype(dt, jnp.floating) else jnp.result_type(float)


@partial(jit, static_argnames=("dyn",))
def _forward_dynamics(dyn, q, qd, tau, params, wrench):
    dtype = _float_dtype(q, qd, tau)
    q, qd, tau = (jnp.asarray(x, dtype) for x in (q, qd, tau))
    p = _param_array(dyn, params, dtype)
    batch = q.shape[:-1]
    f = accelerations(dyn, batched=bool(batch))
    if wrench is not None:
        wrench = jnp.asarray(wrench, dtype)
    if not batch:
        return f(q, qd, tau, p, wrench)
    n = q.shape[-1]
    flat = [x.reshape((-1, n)) for x in (q, qd, tau)]
    p_axis = 0 if p.ndim > 1 else None
    if p_axis == 0:
        p = p.reshape((-1, p.shape[-1]))
    w_axis = None
    if wrench is not None and wrench.ndim > 2:
        wrench, w_axis = wrench.reshape((-1, *wrench.shape[-2:])), 0
    out = jax.vmap(f, in_axes=(0, 0, 0, p_axis, w_axis))(*flat, p, wrench)
    return out.reshape((*batch, n))


def forward_dynamics(dyn: Dynamics, q, qd, tau, params=None, wrench=None) -> jax.Array:
    """Joint accelerations ``qdd = M(q)^-1 (tau - C(q, qd) qd - Q_grav(q) - Q_ext(q, W))``.

    Args:
        dyn: lowered with ``forward_dynamics`` (the closed form, fastest), or with ``mass_matrix`` and
            ``inverse_dynamics`` (or ``coriolis_torques`` and ``gravity_torques``); with
            ``external_torques`` too if ``wrench`` is given.
        q, qd, tau: shape ``(n,)``, or ``(..., n)`` for a batch.
        params: ``None`` (defaults), a dict name -> value, or a vector ``(n_params,)``; a batch of vectors
            ``(..., n_params)`` or a dict of batched values pairs one parameter set with each state.
        wrench: end-effector wrenches ``(n_ee, 6)`` (moment, force), exerted by the robot on its
            environment, as in ``inverse_dynamics``; ``(..., n_ee, 6)`` for a batch.

    Returns:
        qdd with the shape of ``q``. One jitted call (validation reads shapes only).
    """
    _require(dyn, "forward_dynamics")
    n = dyn.n_dof
    shapes = [jnp.shape(x) for x in (q, qd, tau)]
    for name, shape in zip(("q", "qd", "tau"), shapes):
        if len(shape) < 1 or shape[-1] != n:
            raise ShapeError(f"forward_dynamics: {name}: expected shape ({n},) or (..., {n}), got {shape}")
    if not shapes[0] == shapes[1] == shapes[2]:
        raise ShapeError(f"forward_dynamics: q, qd and tau differ in shape: {shapes}")
    if params is None:
        missing = [k for k in dyn.parameters if k not in dyn.defaults]
        if missing:
            raise RequestError(f"parameter(s) {', '.join(missing)} have no default value; pass params")
    elif isinstance(params, Mapping):
        missing = [k for k in dyn.parameters if k not in params]
        if missing:
            raise RequestError(f"params is missing {', '.join(missing)} (expected the names in Dynamics.parameters)")
    else:
        pshape = jnp.shape(params)
        if len(pshape) < 1 or pshape[-1] != len(dyn.parameters) or (len(pshape) > 1 and pshape[:-1] != shapes[0][:-1]):
            raise ShapeError(f"forward_dynamics: params: expected a dict or shape ({len(dyn.parameters)},) or "
                             f"(*batch, {len(dyn.parameters)}) with the batch of q, got {pshape}")
    if wrench is not None and "external_torques" not in dyn.quantities:
        raise RequestError("forward_dynamics with a wrench needs the quantity external_torques; lower it too")
    return _forward_dynamics(dyn, q, qd, tau, params, wrench)


def mass_matrix_condition(dyn: Dynamics, q, params=None) -> jax.Array:
    """The 2-norm condition number ``lambda_max / lambda_min`` of ``M(q)``, shape ``q.shape[:-1]``.

    A large value warns that :func:`forward_dynamics` loses about ``log10(cond)`` digits; ``inf`` means M
    is not positive definite in floating point.
    """
    m = dyn.mass_matrix(q, params)
    ev = jnp.linalg.eigvalsh(m)
    return jnp.where(ev[..., 0] > 0, ev[..., -1] / ev[..., 0], jnp.inf)


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

        k1, aux = f(t, y)
        k2, _ = f(t + dt / 2, axpy(dt / 2, k1, y))
        k3, _ = f(t + dt / 2, axpy(dt / 2, k2, y))
        k4, _ = f(t + dt, axpy(dt, k3, y))
        incr = jax.tree.map(lambda a, b, c, d: (a + 2 * b + 2 * c + d) / 6, k1, k2, k3, k4)
        return axpy(dt, incr, y), aux


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


def _rollout_one(dyn, controller, integrator, steps, x0, p, u, dt, batched=False) -> Trajectory:
    n = dyn.n_dof
    qdd = accelerations(dyn, batched)
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


_rollout_single = jit(_rollout_one, static_argnames=("dyn", "controller", "integrator", "steps"))


@partial(jit, static_argnames=("dyn", "controller", "integrator", "steps", "p_batched", "u_batched", "devices"))
def _rollout_batch(dyn, controller, integrator, steps, p_batched, u_batched, devices, x0, p, u, dt):
    one = partial(_rollout_one, dyn, controller, integrator, steps, batched=True)
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
            parameter set with each rollout of a batch.
        devices: where a batch runs; default ``jax.local_devices()``. With several devices the batch is
            split across them (``jax.shard_map`` over a one-axis mesh; padded to a multiple of their
            number). For several hosts, call ``jax.distributed.initialize()`` first and pass
            ``jax.devices()``.

    Returns:
        a :class:`Trajectory`; ``x`` has shape ``(..., steps+1, 2n)``.

    ``rollout`` is traceable: ``jax.vmap``, ``jax.grad`` and ``jax.jit`` apply to it for a single rollout.
    """
    n = dyn.n_dof
    _require(dyn, "rollout")
    x0 = jnp.asarray(x0)
    if x0.ndim < 1 or x0.shape[-1] != 2 * n:
        raise ShapeError(f"rollout: x0: expected shape ({2 * n},) or (..., {2 * n}) = (q, qd), got {x0.shape}")
    steps = int(steps)
    controller = None
    u_list = [x0]
    if isinstance(controls, Controller):
        controller = controls
    elif callable(controls):
        controller = _Policy(controls)
    else:
        u_list.append(jnp.asarray(controls))
    dtype = _float_dtype(*u_list)
    x0 = x0.astype(dtype)
    batch = x0.shape[:-1]
    p = _param_array(dyn, params, dtype)
    p_batched = p.ndim > 1
    if p_batched and p.shape[:-1] != batch:
        raise ShapeError(f"rollout: params batch {p.shape[:-1]} differs from the x0 batch {batch}")
    if controller is None:
        u = u_list[1].astype(dtype)
        if u.shape[-2:] != (steps, n) or u.shape[:-2] not in ((), batch):
            raise ShapeError(f"rollout: controls: expected shape ({steps}, {n}) or (*batch, {steps}, {n}), got {u.shape}")
        u_batched = u.ndim > 2
    else:
        u, u_batched = None, False
    dt = jnp.asarray(dt, dtype)
    if not batch:
        if p_batched or u_batched:
            raise ShapeError("rollout: batched params or controls need a batch of initial states x0 (..., 2n)")
        return _rollout_single(dyn, controller, integrator, steps, x0, p, u, dt)
    size = int(np.prod(batch))
    devices = tuple(devices) if devices is not None else tuple(jax.local_devices())
    if len(devices) > size:
        devices = devices[:max(1, size)]
    pad = -size % len(devices)

    def flat(a, batched, tail):
        if not batched:
            return a
        a = a.reshape((size, *a.shape[a.ndim - tail:]))
        return jnp.concatenate([a, jnp.repeat(a[-1:], pad, axis=0)], axis=0) if pad else a

    out = _rollout_batch(
        dyn, controller, integrator, steps, p_batched, u_batched, devices,
        flat(x0, True, 1), flat(p, p_batched, 1), flat(u, u_batched, 2), dt,
    )
    return jax.tree.map(lambda a: a[:size].reshape((*batch, *a.shape[1:])), out)
