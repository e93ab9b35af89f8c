"""One classical Runge-Kutta step of a fixed-base robot under a held torque, whose backward pass is one call
of a native kernel (:mod:`jaxskid.lowering._ffi_rk4`, where the recursion over the stages is written out).

A rollout's gradient otherwise runs, per step, a loop over the four stages with the backward step of forward
dynamics in each (:mod:`jaxskid.runtime._implicit`): on CPU four calls of a native kernel and the glue
between them, each a few microseconds at batch 1. :func:`held_torque_rk4` keeps the forward pass as it was
(a ``lax.scan`` over the stages, the same sums in the same order) and gives the step a ``jax.custom_vjp``
whose backward pass is one call, with the same recursion in JAX as the fallback off CPU and for derivatives
of the gradient.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from ._ffi import native_call
from ._forward import accelerations
from ._implicit import backward_kernel
from ._sparse import mass_solver

B = (1 / 6, 1 / 3, 1 / 3, 1 / 6)
C = (0.0, 0.5, 0.5, 1.0)


def held_torque_rk4(dyn, batched: bool) -> Callable | None:
    """``step(q, qd, tau, p, h) -> (q1, qd1)``, one RK4 step of ``h`` under the torque ``tau``, differentiable
    in reverse mode with respect to all five; None where the native kernel is not to be had (a floating
    base, ``JAXSKID_NATIVE=0``, not on CPU, or ``inverse_dynamics_vjp`` not lowered): the integrator's own
    step then serves, differentiated stage by stage. ``batched``: whether it will be mapped with
    ``jax.vmap`` (see :meth:`jaxskid.Dynamics.raw`)."""
    if dyn.floating_base or not dyn.native_planned("rk4_vjp"):
        return None
    n, n_params = dyn.nv, len(dyn.parameters)
    qdd = accelerations(dyn, batched, "forward")  # its forward-mode rule: for gradients of the gradient
    stage_backward = backward_kernel(mass_solver(dyn), dyn.generated("inverse_dynamics_vjp", batched))

    def stages(q, qd, tau, p, h):
        def stage(carry, cb):
            (kq, kqd), (aq, aqd) = carry
            c, b = cb
            qi, qdi = q + c * h * kq, qd + c * h * kqd
            ai = qdd(qi, qdi, tau, p)
            return ((qdi, ai), (aq + b * qdi, aqd + b * ai)), (qi, qdi, ai)

        zero = jnp.zeros_like(qd)
        cb = (jnp.asarray(C, qd.dtype), jnp.asarray(B, qd.dtype))
        (_, (aq, aqd)), saved = jax.lax.scan(stage, ((zero, zero), (zero, zero)), cb)
        return (q + h * aq, qd + h * aqd), saved

    def recursion(qs, qds, accs, p, h, gq, gqd):  # the native kernel's, in JAX: a scan from the last stage
        def stage(carry, x):
            nq, nqd, yq, yqd, taubar, pbar, hbar = carry
            qi, qdi, ai, qd_prev, a_prev, b, c, c_next = x
            kq, kqd = h * b * gq + h * c_next * nq, h * b * gqd + h * c_next * nqd
            lam, w = stage_backward(qi, qdi, ai, kqd, p)
            nq, nqd = w[:n], kq + w[n:2 * n]
            hbar = hbar + b * (gq @ qdi + gqd @ ai) + c * (nq @ qd_prev + nqd @ a_prev)
            return (nq, nqd, yq + nq, yqd + nqd, taubar + lam, pbar + w[2 * n:], hbar), None

        def earlier(x):  # stage i's row holds stage i-1's (zero before the first, where c = 0)
            return jnp.concatenate([jnp.zeros_like(x[:1]), x[:-1]])

        dtype = gq.dtype
        xs = (qs, qds, accs, earlier(qds), earlier(accs), jnp.asarray(B, dtype), jnp.asarray(C, dtype),
              jnp.asarray((*C[1:], 0.0), dtype))
        zero = jnp.zeros_like(gq)
        carry = (zero, zero, gq, gqd, zero, jnp.zeros_like(p), jnp.zeros_like(h))
        (_, _, yq, yqd, taubar, pbar, hbar), _ = jax.lax.scan(stage, carry, xs, reverse=True)
        return jnp.concatenate([yq, yqd, taubar, pbar, hbar[None]])

    @jax.custom_vjp
    def step(q, qd, tau, p, h):
        return stages(q, qd, tau, p, h)[0]

    def fwd(q, qd, tau, p, h):
        y, saved = stages(q, qd, tau, p, h)
        return y, (*saved, p, h)

    def bwd(res, g):
        qs, qds, accs, p, h = res
        target = dyn.native_target("rk4_vjp")  # built (or waited for) when the gradient is traced
        kernel = recursion if target is None else native_call(target, (3 * n + n_params + 1,), recursion)
        out = kernel(qs, qds, accs, p, h, *g)
        return out[:n], out[n:2 * n], out[2 * n:3 * n], out[3 * n:3 * n + n_params], out[-1].reshape(jnp.shape(h))

    step.defvjp(fwd, bwd)
    return step
