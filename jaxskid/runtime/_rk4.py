"""One classical Runge-Kutta step of a fixed-base robot under a held torque, whose backward pass is one call
of a native kernel (:mod:`jaxskid.lowering._ffi_rk4`, where the recursion over the stages is written out).

A rollout's gradient otherwise runs, per step, a loop over the four stages with the backward step of forward
dynamics in each (:mod:`jaxskid.runtime._implicit`): on CPU four calls of a native kernel and the glue
between them, each a few microseconds at batch 1. :func:`held_torque_rk4` keeps the forward pass as it was
(a ``lax.scan`` over the stages, the same sums in the same order) and gives the step a ``jax.custom_vjp``
whose backward pass is one call, with the same recursion in JAX as the fallback off CPU and for derivatives
of the gradient.

:func:`feedback_rk4` does the same for a step under feedback, ``tau_i = u(t_i, x_i)`` at every stage (a policy
or a stateless :class:`~jaxskid.Controller` written in JAX, closing over whatever it likes). The controller's
Jacobian ``K_i = du/dx`` at the four stages (one batched reverse-mode pass: ``n`` cotangents, where forward
mode would take ``2n`` tangents) enters the native recursion, which returns each stage's torque cotangent
``lambda_i``; the controller's vector-Jacobian product with respect to
its closed-over values (gains, parameters) and the stage times is then one batched reverse pass over the four
stages, instead of four differentiated stages with a backward step each.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
from jax.extend.core import ClosedJaxpr, jaxpr_as_fun

from .._tableau import RK4_TABLEAU
from ._ffi import native_call
from ._forward import accelerations
from ._implicit import backward_kernel
from ._sparse import mass_solver

B, C = RK4_TABLEAU.b, RK4_TABLEAU.c


def _recursion(stage_backward, n: int, qs, qds, accs, ks, p, h, gq, gqd):
    """The native kernels' recursion in JAX (``jaxskid_rk4_vjp``, and ``jaxskid_rk4fb_vjp`` with the stages'
    controller Jacobians ``ks`` ``(4, n, 2n)``; ``None``: a held torque): a scan from the last stage, giving
    ``(ybar_q, ybar_qd, lambda (4, n), pbar, hbar)``."""

    def stage(carry, x):
        nq, nqd, yq, yqd, pbar, hbar = carry
        qi, qdi, ai, k, qd_prev, a_prev, b, c, c_next = x
        kq, kqd = h * b * gq + h * c_next * nq, h * b * gqd + h * c_next * nqd
        lam, w = stage_backward(qi, qdi, ai, kqd, p)
        nq, nqd = w[:n], kq + w[n:2 * n]
        if k is not None:
            nq, nqd = nq + lam @ k[:, :n], nqd + lam @ k[:, n:]
        hbar = hbar + b * (gq @ qdi + gqd @ ai) + c * (nq @ qd_prev + nqd @ a_prev)
        return (nq, nqd, yq + nq, yqd + nqd, pbar + w[2 * n:], hbar), lam

    def earlier(x):  # stage i's row holds stage i-1's (zero before the first, where c = 0)
        return jnp.concatenate([jnp.zeros_like(x[:1]), x[:-1]])

    dtype = gq.dtype
    xs = (qs, qds, accs, ks, earlier(qds), earlier(accs), jnp.asarray(B, dtype), jnp.asarray(C, dtype),
          jnp.asarray((*C[1:], 0.0), dtype))
    zero = jnp.zeros_like(gq)
    carry = (zero, zero, gq, gqd, jnp.zeros_like(p), jnp.zeros_like(h))
    (_, _, yq, yqd, pbar, hbar), lams = jax.lax.scan(stage, carry, xs, reverse=True)
    return yq, yqd, lams, pbar, hbar


def _stages(qdd, q, qd, p, h, torque):
    """The four stages of RK4 from ``(q, qd)`` (the integrator's sums, in its order), the stage ``i``'s torque
    ``torque(c_i)``: ``((q1, qd1), (q_i, qd_i, a_i, tau_i))``, the stages stacked ``(4, n)``."""

    def stage(carry, cb):
        (kq, kqd), (aq, aqd) = carry
        c, b = cb
        qi, qdi = q + c * h * kq, qd + c * h * kqd
        tau = torque(c, qi, qdi)
        ai = qdd(qi, qdi, tau, p)
        return ((qdi, ai), (aq + b * qdi, aqd + b * ai)), (qi, qdi, ai, tau)

    zero = jnp.zeros_like(qd)
    cb = (jnp.asarray(C, qd.dtype), jnp.asarray(B, qd.dtype))
    (_, (aq, aqd)), saved = jax.lax.scan(stage, ((zero, zero), (zero, zero)), cb)
    return (q + h * aq, qd + h * aqd), saved


def hoist(fn: Callable, *args) -> tuple[Callable, list]:
    """``(converted, consts)``: ``fn(*args) == converted(*args, *consts)`` with every value ``fn`` closes over
    that belongs to an enclosing trace among ``consts``, whatever its dtype. :func:`jax.closure_convert`
    leaves integer tracers (an index array a controller made inside ``jax.jit``) closed over, and they would
    leak into the backward pass, which runs in another trace."""
    closed, shape = jax.make_jaxpr(fn, return_shape=True)(*args)
    traced = [isinstance(c, jax.core.Tracer) for c in closed.consts]
    consts = [c for c, t in zip(closed.consts, traced) if t]
    kept = [c for c, t in zip(closed.consts, traced) if not t]
    tree = jax.tree.structure(shape)

    def converted(*inputs):
        given, hoisted = iter(kept), iter(inputs[len(args):])
        values = [next(hoisted) if t else next(given) for t in traced]
        flat = jax.tree.leaves(inputs[:len(args)])
        return jax.tree.unflatten(tree, jaxpr_as_fun(ClosedJaxpr(closed.jaxpr, values))(*flat))

    return converted, consts


def _available(dyn) -> bool:
    """Whether the one-call steps serve ``dyn``: a fixed base with ``inverse_dynamics_vjp`` lowered. The native
    kernel runs on CPU; elsewhere (a GPU, ``JAXSKID_NATIVE=0``) the same recursion in JAX, faster there too
    than every stage differentiated by JAX under feedback (``benchmarks/gpu_rollouts.py`` measures both on a
    GPU)."""
    return not dyn.floating_base and "inverse_dynamics_vjp" in dyn.quantities


def _stage_functions(dyn, batched: bool):
    """``(qdd, stage_backward)``: forward dynamics with its forward-mode rule (for gradients of the gradient)
    and the backward step of forward dynamics in JAX."""
    qdd = accelerations(dyn, batched, "forward")
    return qdd, backward_kernel(mass_solver(dyn), dyn.generated("inverse_dynamics_vjp", batched))


def held_torque_rk4(dyn, batched: bool) -> Callable | None:
    """``step(q, qd, tau, p, h) -> (q1, qd1)``, one RK4 step of ``h`` under the torque ``tau``, differentiable
    in reverse mode with respect to all five; None for a floating base or without ``inverse_dynamics_vjp``
    (:func:`_available`): the integrator's own step then serves, differentiated stage by stage. ``batched``: whether it will be mapped with
    ``jax.vmap`` (see :meth:`jaxskid.Dynamics.raw`)."""
    if not _available(dyn):
        return None
    n, n_params = dyn.nv, len(dyn.parameters)
    qdd, stage_backward = _stage_functions(dyn, batched)

    def recursion(qs, qds, accs, p, h, gq, gqd):
        yq, yqd, lams, pbar, hbar = _recursion(stage_backward, n, qs, qds, accs, None, p, h, gq, gqd)
        return jnp.concatenate([yq, yqd, lams.sum(axis=0), pbar, hbar[None]])

    @jax.custom_vjp
    def step(q, qd, tau, p, h):
        return _stages(qdd, q, qd, p, h, lambda c, qi, qdi: tau)[0]

    def fwd(q, qd, tau, p, h):
        y, saved = _stages(qdd, q, qd, p, h, lambda c, qi, qdi: tau)
        return y, (*saved[:3], p, h)

    def bwd(res, g):
        qs, qds, accs, p, h = res
        target = dyn.native_target("rk4_vjp")  # built (or waited for) when the gradient is traced
        kernel = recursion if target is None else native_call(target, (3 * n + n_params + 1,), recursion)
        out = kernel(qs, qds, accs, p, h, *g)
        return out[:n], out[n:2 * n], out[2 * n:3 * n], out[3 * n:3 * n + n_params], out[-1].reshape(jnp.shape(h))

    step.defvjp(fwd, bwd)
    return step


def feedback_rk4(dyn, batched: bool) -> Callable | None:
    """``step(control, q, qd, p, h, t, consts) -> (q1, qd1, tau0)``: one RK4 step of ``h`` from time ``t`` under
    the feedback ``tau = control(t, x, *consts)`` at every stage (``x = (q, qd)``; ``tau0``: the first stage's
    torque), differentiable in reverse mode with respect to all but ``control`` (module docstring).
    ``control`` is a function without closed-over tracers (:func:`hoist` makes one). None where
    :func:`held_torque_rk4` is None."""
    if not _available(dyn):
        return None
    n, n_params = dyn.nv, len(dyn.parameters)
    qdd, stage_backward = _stage_functions(dyn, batched)

    def recursion(qs, qds, accs, ks, p, h, gq, gqd):
        yq, yqd, lams, pbar, hbar = _recursion(stage_backward, n, qs, qds, accs, ks, p, h, gq, gqd)
        return jnp.concatenate([yq, yqd, lams.ravel(), pbar, hbar[None]])

    def run(control, q, qd, p, h, t, consts):
        def torque(c, qi, qdi):
            return control(t + c * h, jnp.concatenate([qi, qdi]), *consts)

        (q1, qd1), saved = _stages(qdd, q, qd, p, h, torque)
        return (q1, qd1, saved[3][0]), saved

    step = jax.custom_vjp(lambda control, *args: run(control, *args)[0], nondiff_argnums=(0,))

    def fwd(control, q, qd, p, h, t, consts):
        y, (qs, qds, accs, _) = run(control, q, qd, p, h, t, consts)
        return y, (qs, qds, accs, p, h, t, consts)

    def bwd(control, res, g):
        qs, qds, accs, p, h, t, consts = res
        gq, gqd, gtau = g
        ts, xs = t + jnp.asarray(C, h.dtype) * h, jnp.concatenate([qs, qds], axis=-1)

        def stage_torques(ts, consts):
            return jax.vmap(lambda ti, xi: control(ti, xi, *consts))(ts, xs)

        # reverse mode: n cotangents against 2n tangents, through the quantities' closed-form pullbacks
        ks = jax.vmap(jax.jacrev(lambda ti, xi: control(ti, xi, *consts), argnums=1))(ts, xs)
        target = dyn.native_target("rk4fb_vjp")
        kernel = recursion if target is None else native_call(target, (6 * n + n_params + 1,), recursion)
        out = kernel(qs, qds, accs, ks, p, h, gq, gqd)
        yq, yqd = out[:n] + gtau @ ks[0, :, :n], out[n:2 * n] + gtau @ ks[0, :, n:]
        lams = out[2 * n:6 * n].reshape(4, n).at[0].add(gtau)  # the first stage's torque is an output too
        tbar, cbar = jax.vjp(stage_torques, ts, consts)[1](lams)
        hbar = out[-1] + jnp.asarray(C, h.dtype) @ tbar
        return yq, yqd, out[6 * n:6 * n + n_params], hbar.reshape(jnp.shape(h)), tbar.sum().reshape(jnp.shape(t)), cbar

    step.defvjp(fwd, bwd)
    return step
