"""Forward dynamics: the joint accelerations from the lowered quantities.

Forward dynamics solves the equations of motion for the accelerations,

    M(q) qdd = tau - C(q, qd) qd - Q_grav(q) - Q_ext(q, W),

in closed form when the quantity ``forward_dynamics`` was lowered (:mod:`jaxskid.symbolic._forward`),
otherwise with the bias ``C qd + Q_grav`` from one recursive Newton-Euler pass (``inverse_dynamics`` at
``qdd = 0``, measured faster than ``coriolis_torques + gravity_torques``) and a square-root-free Cholesky
factorisation of M written out on its nonzero entries, along the tree's sparsity
(:func:`jaxskid.runtime._sparse.mass_solver`), which runs and compiles faster than the dense unrolled
factorisation of the assembled M, the more so the larger the tree (``benchmarks/floating_base.py`` times
it against Pinocchio's ``aba``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial

import jax
import jax.numpy as jnp

from .._errors import RequestError
from ._batching import batch_shape, vmapped
from ._ffi import native_quantity
from ._checks import check_inputs
from ._jit import jit, top_level, traced
from ._implicit import differentiable
from ._ldl import materialize
from ._parameters import inexact_inputs
from ._sparse import mass_solver


def require_solver(dyn, what: str) -> None:
    """Raise :class:`RequestError` unless ``dyn`` has the quantities :func:`accelerations` needs."""
    have = set(dyn.quantities)
    if "forward_dynamics" in have:
        return
    if "mass_matrix" not in have or not ({"inverse_dynamics"} <= have or {"coriolis_torques", "gravity_torques"} <= have):
        raise RequestError(
            f"{what} needs the quantity forward_dynamics, or mass_matrix and inverse_dynamics (or "
            f"coriolis_torques and gravity_torques); lowered: {', '.join(dyn.quantities)}. Ask for them with "
            "jaxskid.lower(robot, quantities=[..., 'forward_dynamics'])"
        )
    if dyn.driven and "inverse_dynamics" not in have:
        raise RequestError(
            f"{what} needs forward_dynamics, or mass_matrix and inverse_dynamics: robot {dyn.robot_name!r} has "
            "drives, whose friction and offset coriolis_torques and gravity_torques leave out; lowered: "
            f"{', '.join(dyn.quantities)}"
        )


def _bias(dyn, raw: Callable) -> Callable:
    """``b(q, qd, p) = C(q, qd) qd + Q_grav(q)`` (plus the drives' ``fv qd + fc sign(qd) + fo``) from the
    lowered quantities."""
    if "inverse_dynamics" in dyn.quantities:
        rnea = raw("inverse_dynamics")
        return lambda q, qd, p: rnea(q, qd, jnp.zeros_like(qd), p)
    cor, grav = raw("coriolis_torques"), raw("gravity_torques")
    return lambda q, qd, p: cor(q, qd, p) + grav(q, p)


def accelerations(dyn, batched: bool = True, autodiff: str = "forward") -> Callable:
    """The single-state function ``qdd(q, qd, tau, p, wrench=None)`` with ``p`` a parameter vector.

    With the quantity ``forward_dynamics`` lowered, this is the closed form (:mod:`jaxskid.symbolic._forward`);
    otherwise M and the bias are evaluated and solved by :func:`~jaxskid.runtime._sparse.mass_solver`. ``batched``: whether the
    function will be mapped with ``jax.vmap`` (see :meth:`jaxskid.Dynamics.raw`). ``autodiff``: how it is
    differentiated, ``"forward"`` (forward and reverse mode) or ``"reverse"`` (reverse mode only, faster);
    see :func:`jaxskid.runtime._implicit.differentiable`.
    """
    require_solver(dyn, "forward_dynamics")

    def raw(name: str) -> Callable:
        return dyn.mapped(name) if batched else dyn.generated(name, False)

    if "forward_dynamics" in dyn.quantities:
        solve = raw("forward_dynamics")
    else:
        mass_solve, bias = mass_solver(dyn), _bias(dyn, raw)

        def solve(q, qd, tau, p):
            return mass_solve(q, p, tau - bias(q, qd, p))

    solve = differentiable(dyn, solve, batched, autodiff)

    def qdd(q, qd, tau, p, wrench=None):
        if wrench is not None:
            tau = tau - raw("external_torques")(q, wrench, p)
        return materialize(solve(q, qd, tau, p))

    return qdd


@partial(jit, static_argnames=("dyn", "native"))
def _forward_dynamics(dyn, q, qd, tau, params, wrench, native=None):
    (q, qd, tau), p, dtype = inexact_inputs(dyn.layout, (q, qd, tau), params)
    extras = [("params", p.shape, (len(dyn.parameters),))]
    if wrench is not None:
        wrench = jnp.asarray(wrench, dtype)
        extras.append(("wrench", wrench.shape, (len(dyn.end_effectors), 6)))
    nq, nv = dyn.argument_shape("q"), dyn.argument_shape("qd")
    batch = batch_shape("forward_dynamics", [("q", q.shape, nq), ("qd", qd.shape, nv), ("tau", tau.shape, nv)], extras)
    f = accelerations(dyn, batched=bool(batch))
    if native is not None:  # the C kernel, with the closed form's derivatives (jaxskid.runtime._ffi)
        kernel = native_quantity(native, nv, f)
        f = lambda q, qd, tau, p, wrench: kernel(q, qd, tau, p)  # noqa: E731 - no wrench on this path
    if not batch:
        return f(q, qd, tau, p, wrench)
    return vmapped(f, batch, [(q, 1), (qd, 1), (tau, 1), (p, 1), (wrench, 2)])


def forward_dynamics(dyn, q, qd, tau, params=None, *, wrench=None) -> jax.Array:
    """Joint accelerations ``qdd = M(q)^-1 (tau - C(q, qd) qd - Q_grav(q) - Q_ext(q, W))``.

    Args:
        dyn: a :class:`~jaxskid.Dynamics` lowered with ``forward_dynamics`` (the closed form, fastest), or
            with ``mass_matrix`` and ``inverse_dynamics`` (or ``coriolis_torques`` and ``gravity_torques``);
            with ``external_torques`` too if ``wrench`` is given.
        q, qd, tau: shape ``(n,)``, or ``(..., n)`` for a batch (the same for the three); with a floating base,
            q ``(..., 7 + n)`` and qd, tau ``(..., 6 + n)`` (:attr:`jaxskid.Robot.floating_base`).
        params: ``None`` (defaults), a dict name -> value (missing names take their defaults), or a vector
            ``(n_params,)``; a batch of vectors ``(..., n_params)`` or a dict of batched values broadcasts
            against the batch of the states.
        wrench: end-effector wrenches ``(n_ee, 6)`` (moment, force), exerted by the robot on its
            environment, as in ``inverse_dynamics``; ``(..., n_ee, 6)`` for a batch.

    Returns:
        qdd ``(..., n)``. One jitted call; a dict of plain numbers is packed on the host before it.
    """
    require_solver(dyn, "forward_dynamics")
    if wrench is not None and "external_torques" not in dyn.quantities:
        raise RequestError("forward_dynamics with a wrench needs the quantity external_torques; lower it too")
    check_inputs(dyn.checks, "forward_dynamics", [("q", q), ("qd", qd), ("tau", tau), ("wrench", wrench)])
    params = dyn.packed_params(params)
    # Called from Python without a wrench: the native kernel, where there is one. Inside a caller's trace
    # (a rollout, a user's loop) the JAX form stays, which XLA fuses with the rest of the program.
    native = None if wrench is not None or not top_level((q, qd, tau, params)) else dyn.native_target("forward_dynamics")
    return _forward_dynamics(dyn, q, qd, tau, params, wrench, native=native)


def mass_matrix_condition(dyn, q, params=None) -> jax.Array:
    """The 2-norm condition number ``lambda_max / lambda_min`` of ``M(q)``, shape ``q.shape[:-1]``.

    A large value warns that :func:`forward_dynamics` loses about ``log10(cond)`` digits; ``inf`` means M
    is not positive definite in floating point.
    """
    m = dyn.mass_matrix(q, params)
    ev = jnp.linalg.eigvalsh(m)
    return jnp.where(ev[..., 0] > 0, ev[..., -1] / ev[..., 0], jnp.inf)
