"""A rollout under held torques as one CUDA kernel on a GPU, its gradient as two more
(:mod:`jaxskid.lowering._cuda_rollout`): :func:`held_torque_rollout` is the whole rollout of a fixed-base robot
under classical RK4, with a ``jax.custom_vjp`` whose backward pass is the adjoint kernel (the recursion from the
last step) and then the parameters' kernel (a thread per block of steps: that part needs no recursion).

Written as a ``lax.scan`` of steps, a rollout on a GPU launches several kernels per step, and a gradient about
as many again in its backward loop: a batch of one rollout is bound by launches, a large one by the states
written and read between them. The forward and adjoint kernels run all steps of one rollout in one thread.

Elsewhere than on a CUDA GPU, the rollout runs as the scan of :func:`jaxskid.runtime._rk4.held_torque_rk4` steps
(the kernels serve only where :meth:`jaxskid.Dynamics.cuda_rollout` has them); for complex inputs and derivatives
of the gradient, the kernels' fallback is the same RK4 sums in JAX, differentiated stage by stage.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from .._generated import ROLLOUT_PARAMETERS, ROLLOUT_PARTS, ROLLOUT_PROGRAMS, ROLLOUT_STRIDE, rollout_layout
from ._cuda import CudaKernel, architecture
from ._ffi import ffi_kernel, native_call, platform_kernel
from ._forward import accelerations
from ._rk4 import _stages

class RolloutKernel(CudaKernel):
    """The rollout kernel ``part`` (:data:`jaxskid._generated.ROLLOUT_PARTS`) of ``steps`` steps of a robot of
    ``n`` velocities and ``n_params`` parameters, from the vector programs ``vectors``, compiled by ``build``."""

    def __init__(self, build, vectors, n: int, n_params: int, steps: int, part: str):
        super().__init__(build, f"rollout ({part})")
        self.vectors, self.n, self.n_params, self.steps, self.part = vectors, n, n_params, steps, part

    def _parameters(self) -> tuple[int, int]:
        return ROLLOUT_PARAMETERS[self.part], self.n_params

    def _image(self, dtype: str, shared: bool) -> tuple[bytes, int]:
        return self.build.cuda_rollout_image(self.vectors, self.n, self.n_params, self.steps, dtype, architecture(),
                                             self.part, shared)

    def _shape(self) -> tuple:
        return (*rollout_layout(self.part, self.n, self.n_params, self.steps), False)

    def columns(self) -> bool:
        return False


def rollout_kernels(builds, n: int, n_params: int, steps: int) -> tuple[RolloutKernel, ...] | None:
    """The rollout kernels of :data:`jaxskid._generated.ROLLOUT_PARTS` from a lowering's native libraries
    ``builds``, or None where they lack a program of :data:`jaxskid._generated.ROLLOUT_PROGRAMS`."""
    vectors = {}
    for build in builds:
        vectors.update({k: v for k, v in build.sources.vectors.items() if v is not None})
    owner = next((b for b in builds if "forward_dynamics" in b.sources.vectors), None)
    if owner is None or any(name not in vectors for name in ROLLOUT_PROGRAMS):
        return None
    vectors = {name: vectors[name] for name in ROLLOUT_PROGRAMS}
    return tuple(RolloutKernel(owner, vectors, n, n_params, steps, part) for part in ROLLOUT_PARTS)


def held_torque_rollout(dyn, steps: int, batched: bool) -> Callable | None:
    """``rollout(x0, u, p, h) -> x``: ``steps`` RK4 steps of ``h[0]`` from ``x0 = (q, qd)`` under the torque rows
    ``u (steps, n)``, every state ``(steps + 1, 2n)``; its reverse-mode derivative with respect to all four is the
    adjoint kernel, then the parameters' kernel on the adjoint's stage cotangents. None where
    :meth:`jaxskid.Dynamics.cuda_rollout` has no kernels (not on a CUDA GPU, a floating base, no pullback of
    inverse dynamics lowered). ``batched``: whether it will be mapped with ``jax.vmap`` (the fallback's steps)."""
    kernels = dyn.cuda_rollout(steps)
    if kernels is None:
        return None
    n, n_params = dyn.nv, len(dyn.parameters)
    blocks = -(-steps // ROLLOUT_STRIDE)
    qdd = accelerations(dyn, batched, "forward")

    def plain(x0, u, p, h):  # the steps in JAX, differentiable in both modes (the kernels' derivatives)
        def one(x, tau):
            x1 = jnp.concatenate(_stages(qdd, x[:n], x[n:], p, h[0], lambda c, qi, qdi: tau)[0])
            return x1, x1

        return jnp.concatenate([x0[None], jax.lax.scan(one, x0, u)[1]])

    def plain_backward(x, u, p, h, g):
        return jnp.concatenate([c.ravel() for c in jax.vjp(plain, x[0], u, p, h)[1](g)])

    adjoint = ffi_kernel(kernels[1], (rollout_layout("adjoint", n, n_params, steps)[2],), "expand_dims")
    parameters = ffi_kernel(kernels[2], (blocks, n_params), "expand_dims")

    def kernel_backward(x, u, p, h, g):
        out = adjoint(x, u, p, h, g)
        cut = 2 * n + steps * n
        lam = out[cut + 1:].reshape(steps, 4 * n)
        j = jnp.arange(blocks, dtype=x.dtype)
        pbar = parameters(x[None], u[None], lam[None], p, h, j).sum(axis=0)
        return jnp.concatenate([out[:cut], pbar, out[cut:cut + 1]])  # plain_backward's layout

    forward = native_call(kernels[0], (steps + 1, 2 * n), plain, vmap_method="expand_dims")
    backward = platform_kernel(kernel_backward, plain_backward, "cuda")

    @jax.custom_vjp
    def rollout(x0, u, p, h):
        return forward(x0, u, p, h)

    def fwd(x0, u, p, h):
        x = forward(x0, u, p, h)
        return x, (x, u, p, h)

    def bwd(res, g):
        x, u, p, h = res
        exact = jnp.result_type(x, g) in (jnp.float32, jnp.float64)
        out = backward(x, u, p, h, g) if exact else plain_backward(x, u, p, h, g)
        cut = 2 * n + steps * n
        return out[:2 * n], out[2 * n:cut].reshape(steps, n), out[cut:cut + n_params], out[cut + n_params:]

    rollout.defvjp(fwd, bwd)
    return rollout
