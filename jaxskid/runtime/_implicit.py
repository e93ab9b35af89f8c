"""The derivative of forward dynamics, from the equations of motion it solves.

Forward dynamics ``qdd = FD(q, qd, tau, p)`` solves ``ID(q, qd, qdd, p) = tau``. By the implicit function
theorem (Carpentier & Mansard, "Analytical derivatives of rigid body dynamics algorithms", RSS 2018,
sec. IV),

    d qdd = M(q)^-1 (d tau - dID/dq dq - dID/dqd dqd - dID/dp dp),     at qdd = FD(q, qd, tau, p),

so a directional derivative costs one forward-mode pass of inverse dynamics and one solve with M, and a
vector-Jacobian product with weights ``g`` costs one solve ``lambda = M^-1 g`` and the closed-form
vector-Jacobian product of inverse dynamics (the quantity ``inverse_dynamics_vjp``, derived by a symbolic
reverse sweep, :mod:`jaxskid.symbolic._adjoint`):

    g^T dqdd = lambda^T d tau - (lambda^T dID/dq) dq - (lambda^T dID/dqd) dqd - (lambda^T dID/dp) dp.

Without these rules JAX differentiates the closed form itself, a program many times longer whose
transpose XLA compiles for minutes into slow code. Each rule saves only ``(q, qd, qdd, p)`` for the
backward pass and recomputes M there, so a rollout's memory per step is a few state vectors. The forward
dynamics inside a rule is one primitive (:mod:`jaxskid.runtime._whole`), so that the partial evaluation of
a rollout's loop does not split it.
"""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Callable
from pathlib import Path

import jax

from .._errors import RequestError
from ._ffi import native_backward
from ._ldl import materialize
from ._sparse import mass_solver
from ._whole import whole

AUTODIFF = ("forward", "reverse")
"""The ways :func:`differentiable` can differentiate forward dynamics."""


def differentiable(dyn, solve: Callable, batched: bool, autodiff: str) -> Callable:
    """``solve(q, qd, tau, p) -> qdd`` with the derivative rule of the module docstring.

    ``autodiff="forward"``: a ``jax.custom_jvp`` (forward and reverse mode; reverse mode transposes the
    forward-mode pass of inverse dynamics); ``"reverse"``: a ``jax.custom_vjp`` with the closed-form
    vector-Jacobian product (reverse mode only, several times faster to run and to compile). A rule needs
    ``mass_matrix`` and ``inverse_dynamics`` (forward) or ``inverse_dynamics_vjp`` (reverse); without them,
    JAX differentiates ``solve`` itself.
    """
    if autodiff not in AUTODIFF:
        raise RequestError(f"autodiff must be one of {', '.join(map(repr, AUTODIFF))}, got {autodiff!r}")
    have = set(dyn.quantities)
    if "mass_matrix" not in have:
        return solve
    mass = mass_solver(dyn)
    # a rule's solve, not split by the partial evaluation of a loop around it; its lowered forms are kept
    # beside the cached module, so that a new process reads them instead of tracing the closed form
    store = None
    if getattr(dyn, "path", None) is not None:
        route = "closed form" if "forward_dynamics" in have else "mass solve"
        key = (Path(dyn.path).stem, _runtime_version(), "forward_dynamics", route, str(batched))
        store = (Path(dyn.path).parent / "exports", key)
    kept = whole(solve, like=1, store=store)
    if autodiff == "reverse" and "inverse_dynamics_vjp" in have:
        return _reverse(kept, mass, dyn.generated("inverse_dynamics_vjp", batched), dyn)
    if "inverse_dynamics" in have:
        return _forward(kept, mass, dyn.generated("inverse_dynamics", False))
    return solve


@functools.lru_cache(maxsize=1)
def _runtime_version() -> str:
    """A hash of the code that builds a solve around the generated module (this package and the fused
    helpers of :mod:`jaxskid._fused`): a stored export of it holds that code's operations, so a changed runtime makes new ones."""
    root = Path(__file__).parent
    digest = hashlib.sha256()
    for path in sorted([*root.glob("*.py"), root.parent / "_fused.py"]):
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _forward(solve: Callable, mass: Callable, inverse: Callable) -> Callable:
    @jax.custom_jvp
    def fd(q, qd, tau, p):
        return solve(q, qd, tau, p)

    @jax.checkpoint  # reverse mode keeps (q, qd, qdd, p), not the linearisation of inverse dynamics
    def tangent(q, qd, a, p, dq, dqd, dtau, dp):
        _, did = jax.jvp(lambda q, qd, p: inverse(q, qd, a, p), (q, qd, p), (dq, dqd, dp))
        return mass(q, p, dtau - did)

    @fd.defjvp
    def rule(primals, tangents):
        q, qd, tau, p = primals
        a = solve(q, qd, tau, p)
        return a, tangent(q, qd, a, p, *tangents)

    return fd


def backward_kernel(mass: Callable, vjp: Callable) -> Callable:
    """The backward step of forward dynamics in JAX, ``(q, qd, a, g, p) -> (lambda, w)`` with ``lambda = M^-1
    g`` and ``w = -lambda^T dID/d(q, qd, p)`` (what the native ``fd_vjp`` computes), from a mass solve
    ``mass(q, p, g)`` (:func:`~jaxskid.runtime._sparse.mass_solver`) and ``inverse_dynamics_vjp``."""

    def kernel(q, qd, a, g, p):
        # computed once each: XLA on CPU would fuse them into each of their users (materialize)
        lam = materialize(mass(q, p, g))
        return lam, materialize(-vjp(q, qd, a, lam, p))

    return kernel


def _reverse(solve: Callable, mass: Callable, vjp: Callable, dyn) -> Callable:
    nq, n = dyn.argument_shape("q")[0], dyn.argument_shape("qd")[0]
    kernel = backward_kernel(mass, vjp)

    @jax.custom_vjp
    def fd(q, qd, tau, p):
        return solve(q, qd, tau, p)

    def fwd(q, qd, tau, p):
        a = solve(q, qd, tau, p)
        return a, (q, qd, a, p)

    def bwd(res, g):
        q, qd, a, p = res
        target = dyn.native_target()  # on CPU, one native kernel (jaxskid.runtime._ffi); looked up when traced
        step = kernel if target is None else native_backward(target, n, nq + n + len(dyn.parameters), kernel)
        lam, w = step(q, qd, a, g, p)  # w = -lambda^T d ID/d(q, qd, p)
        return w[:nq], w[nq:nq + n], lam, w[nq + n:]

    fd.defvjp(fwd, bwd)
    return fd
