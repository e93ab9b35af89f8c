"""Constrained dynamics: the accelerations and multipliers of a robot held by its constraints, and the
actuated forces of a closed chain.

With the constraints' Jacobian ``A(q)`` (m x nv), drift ``Adot(q, qd) qd`` and residual ``phi(q)`` (the
quantities of :data:`CONSTRAINT_QUANTITIES`, :mod:`jaxskid.symbolic._constraints`), the equations of motion
with the multipliers ``lambda`` (m) are (Featherstone, "Rigid Body Dynamics Algorithms", 2008, ch. 8)

    M(q) qdd + h(q, qd) = tau + A(q)^T lambda,
    A(q) qdd = gamma = -Adot qd - 2 alpha A qd - beta^2 phi,

the second the constraint twice differentiated, with Baumgarte's stabilisation (Baumgarte, "Stabilization
of constraints and integrals of motion in dynamical systems", Comput. Methods Appl. Mech. Eng. 1, 1972):
the violation then obeys ``e'' + 2 alpha e' + beta^2 e = 0`` instead of drifting. They are solved by the
Schur complement of ``M`` in the KKT matrix, with ``M`` factored once along the tree's sparsity and the
constraint rows kept sparse (:func:`jaxskid.runtime._sparse.kkt`, on the quantities' nonzero entries):

    lambda = (A M^-1 A^T + eps 1)^-1 (gamma - A M^-1 (tau - h)),    qdd = M^-1 (tau - h + A^T lambda).

``eps = 0`` by default; ``eps > 0`` (``regularization``) solves redundant constraints (dependent rows of
``A``, where ``A M^-1 A^T`` is singular): rows that vanish identically get exactly ``lambda = 0``, and
otherwise ``A qdd = gamma - eps lambda``.

The derivatives follow from the implicit function theorem on the residuals ``R1 = ID(q, qd, qdd, p) - tau -
A^T lambda`` and ``R2 = A qdd + eps lambda - gamma`` (as :mod:`jaxskid.runtime._implicit` does for forward
dynamics): a directional derivative is one forward-mode pass of inverse dynamics and of the constraint
quantities at the solution, then the same Schur solve; reverse mode solves the transposed system, which is the
same Schur solve of other right-hand sides, and pulls the result back through the residuals (the quantities'
closed-form pullbacks), without transposing the elimination.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp

from .._errors import RequestError
from ._batching import batch_shape, vmapped
from ._ffi import native_call
from ._forward import _bias
from ._jit import jit
from ._ldl import assemble, materialize
from ._parameters import inexact_inputs
from ._pullback import Rule, tangent_p
from ._sparse import kkt, minus, plus

CONSTRAINT_QUANTITIES = ("constraint_jacobian", "constraint_drift", "constraint_residual")
"""The quantities of a robot's constraints (:meth:`jaxskid.Robot.with_constraints`)."""


@dataclass(frozen=True)
class Baumgarte:
    """Baumgarte stabilisation of the constraints: ``A qdd = -Adot qd - 2 alpha A qd - beta^2 phi``.

    ``alpha`` (1/s) damps the velocity violation ``A qd``, ``beta`` (1/s) pulls the position violation ``phi``
    back; ``alpha = beta`` is critical damping, a violation decaying as ``exp(-alpha t)``. The defaults
    (10/s: a time constant of 0.1 s) keep a 10 s RK4 rollout of a four-bar swinging under gravity (1 ms steps,
    ``tests/test_constraints.py``) within ``|phi| = 5e-12`` and ``|A qd| = 6e-11`` of its constraints, where
    it drifts to ``|phi| = 2e-9`` without; with an explicit integrator keep ``alpha dt`` and ``beta dt`` well
    below 1 (at 50/s the same rollout's ``|A qd|`` grew to 6e-9).
    """

    alpha: float = 10.0
    beta: float = 10.0

    def __post_init__(self):
        for key in ("alpha", "beta"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise RequestError(f"Baumgarte: {key}: expected a finite number >= 0 (1/s), got {value!r}")


def require_constraints(dyn, what: str) -> None:
    """Raise :class:`RequestError` unless ``dyn`` has the quantities constrained dynamics needs."""
    have = set(dyn.quantities)
    bias = "inverse_dynamics" in have or ({"coriolis_torques", "gravity_torques"} <= have and not dyn.driven)
    missing = [q for q in (*CONSTRAINT_QUANTITIES, "mass_matrix") if q not in have]
    if missing or not bias:
        need = ", ".join([*missing, *([] if bias else ["inverse_dynamics"])])
        raise RequestError(f"{what} needs the quantities {need}; lowered: {', '.join(dyn.quantities)}. Ask for them "
                           f"with jaxskid.lower(robot, quantities=[..., {', '.join(map(repr, need.split(', ')))}]) "
                           "(the robot needs constraints)")


def options(stabilization, regularization) -> tuple[Baumgarte | None, float]:
    """``(stabilization, regularization)`` checked: ``None`` or a :class:`Baumgarte`, and a float ``>= 0``."""
    if stabilization is not None and not isinstance(stabilization, Baumgarte):
        raise RequestError(f"stabilization: expected None or jaxskid.Baumgarte(alpha, beta), got {stabilization!r}")
    if isinstance(regularization, bool) or not isinstance(regularization, (int, float)) or not (
            math.isfinite(regularization) and regularization >= 0):
        raise RequestError(f"regularization: expected a finite number >= 0, got {regularization!r}")
    return stabilization, float(regularization)


def _functions(dyn) -> dict[str, Callable]:
    """The lowered functions of one state, unbroadcast (see :meth:`jaxskid.Dynamics.raw`), for the
    forward-mode passes of the derivative and for closed-chain inverse dynamics: the constraint quantities
    and ``inverse(q, qd, qdd, p)``."""
    def raw(name: str) -> Callable:
        return dyn.generated(name, False)

    out = {key: raw(name) for key, name in zip(("jacobian", "drift", "residual"), CONSTRAINT_QUANTITIES)}
    if "inverse_dynamics" in dyn.quantities:
        out["inverse"] = raw("inverse_dynamics")
    else:
        mass, bias = raw("mass_matrix"), _bias(dyn, raw)
        out["inverse"] = lambda q, qd, qdd, p: mass(q, p) @ qdd + bias(q, qd, p)
    return out


def _entry_functions(dyn) -> dict[str, Callable]:
    """The lowered quantities the solve uses, as their nonzero entries of one state
    (:meth:`jaxskid.Dynamics.entries`)."""
    entries = dyn.entries
    out = {key: entries(name) for key, name in zip(("jacobian", "drift", "residual"), CONSTRAINT_QUANTITIES)}
    out["mass"] = entries("mass_matrix")
    if "inverse_dynamics" in dyn.quantities:
        rnea = entries("inverse_dynamics")
        out["bias"] = lambda q, qd, p: rnea(q, qd, jnp.zeros_like(qd), p)
    else:
        cor, grav = entries("coriolis_torques"), entries("gravity_torques")

        def bias(q, qd, p):
            c, g = cor(q, qd, p), grav(q, p)
            return {k: plus(c.get(k), g[k]) if k in g else c[k] for k in {*c, *g}}

        out["bias"] = bias
    return out


def _right_sides(fn: dict, rows: int, stabilization: Baumgarte | None) -> Callable:
    """``(r1, r2)`` of the KKT system as lists of scalars (``None``: zero): ``r1 = tau - h(q, qd)`` and
    ``r2 = gamma = -Adot qd - 2 alpha A qd - beta^2 phi``, from the entries of ``A`` (``rows`` x nv)."""
    alpha = stabilization.alpha if stabilization is not None else 0.0
    beta = stabilization.beta if stabilization is not None else 0.0

    def sides(q, qd, tau, p, a):
        nv, bias, drift = qd.shape[-1], fn["bias"](q, qd, p), fn["drift"](q, qd, p)
        residual = fn["residual"](q, p) if beta else {}
        r1 = [tau[i] - bias[i] if i in bias else tau[i] for i in range(nv)]
        r2 = []
        for c in range(rows):
            g = -drift[c] if c in drift else None
            if alpha:
                velocity = None
                for i in range(nv):
                    if c * nv + i in a:
                        velocity = plus(velocity, a[c * nv + i] * qd[i])
                if velocity is not None:
                    g = minus(g, 2.0 * alpha * velocity)
            if c in residual:
                g = minus(g, beta**2 * residual[c])
            r2.append(g)
        return r1, r2

    return sides


def _gamma(fn: dict, stabilization: Baumgarte | None) -> Callable:
    """``gamma(q, qd, p, A) = -Adot qd - 2 alpha A qd - beta^2 phi`` as a vector (the tangent's residual)."""
    drift, residual = fn["drift"], fn["residual"]

    def gamma(q, qd, p, a):
        out = -drift(q, qd, p)
        if stabilization is not None and stabilization.alpha:
            out = out - 2.0 * stabilization.alpha * (a @ qd)
        if stabilization is not None and stabilization.beta:
            out = out - stabilization.beta**2 * residual(q, p)
        return out

    return gamma


def constrained(dyn, stabilization: Baumgarte | None = None, regularization: float = 0.0) -> Callable:
    """The single-state function ``(qdd, lambda) = f(q, qd, tau, p)`` with ``p`` a parameter vector and its
    derivative rules (module docstring). It works on the quantities' entries, one scalar at a time, so the
    same function serves a single state and ``jax.vmap``."""
    solve = _joined(dyn, stabilization, regularization)
    nv = dyn.signature("constraint_jacobian")[1][1]

    def split(q, qd, tau, p):
        y = solve(q, qd, tau, p)
        return y[..., :nv], y[..., nv:]

    return split


def _joined(dyn, stabilization: Baumgarte | None, regularization: float) -> Callable:
    """``[qdd; lambda] = f(q, qd, tau, p)`` of one state, with two derivative rules by the implicit function
    theorem on the residuals ``R1 = ID(q, qd, qdd, p) - A^T lambda - tau`` and ``R2 = A qdd + eps lambda -
    gamma``, whose Jacobian with respect to ``(qdd, lambda)`` is the KKT matrix ``K = [[M, -A^T], [A, eps]]``:

    - forward mode: ``K [dqdd; dlambda] = [dtau - d1; -d2]``, ``(d1, d2)`` one forward-mode pass of the
      residuals at the solution;
    - reverse mode (the transpose of that tangent, :mod:`jaxskid.runtime._pullback`): ``K^T y = w`` is the same
      KKT solve, ``M y1 - A^T u = w1``, ``A y1 + eps u = -w2``, ``y2 = -u``; then the cotangent of ``tau`` is
      ``y1`` and that of ``(q, qd, p)`` is minus the pullback of ``y1^T R1 + y2^T R2``, one reverse pass of the
      residuals (the quantities' closed-form pullbacks). The reverse pass runs the solve as the forward pass
      does, instead of transposing its elimination, and keeps only the states and the solution.
    """
    require_constraints(dyn, "constrained dynamics")
    stabilization, eps = options(stabilization, regularization)
    fn, entry = _functions(dyn), _entry_functions(dyn)
    rows, nv = dyn.signature("constraint_jacobian")[1]
    sides, plain_gamma = _right_sides(entry, rows, stabilization), _gamma(fn, stabilization)

    def residuals(q, qd, p, qdd, lam):
        a = fn["jacobian"](q, p)
        return fn["inverse"](q, qd, qdd, p) - lam @ a, a @ qdd + eps * lam - plain_gamma(q, qd, p, a)

    def solution(q, qd, tau, p):
        a = entry["jacobian"](q, p)
        x, lam = kkt(entry["mass"](q, p), a, *sides(q, qd, tau, p, a), eps)
        return assemble([*x, *lam], qd.dtype)

    def tangent(q, qd, tau, p, qdd, lam, dq, dqd, dtau, dp, _dqdd, _dlam):
        _, (d1, d2) = jax.jvp(lambda q, qd, p: residuals(q, qd, p, qdd, lam), (q, qd, p), (dq, dqd, dp))
        r1, r2 = dtau - d1, -d2
        x, dlam = kkt(entry["mass"](q, p), entry["jacobian"](q, p), [r1[i] for i in range(nv)],
                      [r2[c] for c in range(rows)], eps)
        return assemble([*x, *dlam], qd.dtype)

    def pullback(q, qd, tau, p, qdd, lam, w):
        y1, u = kkt(entry["mass"](q, p), entry["jacobian"](q, p), [w[i] for i in range(nv)],
                    [-w[nv + c] for c in range(rows)], eps)
        y = materialize(assemble([*y1, *u], qd.dtype))  # computed once, not inside each of its users
        y1, y2 = y[:nv], -y[nv:]
        _, pull = jax.vjp(lambda q, qd, p: residuals(q, qd, p, qdd, lam), q, qd, p)
        gq, gqd, gp = pull((-y1, -y2))
        return gq, gqd, y1, gp, jnp.zeros_like(qdd), jnp.zeros_like(lam)

    rule = Rule(tangent, _native_pullback(dyn, pullback, stabilization, eps), 6, (nv + rows,))

    @jax.custom_jvp
    def solve(q, qd, tau, p):
        return solution(q, qd, tau, p)

    @solve.defjvp
    def _derivative(primals, tangents):
        y = materialize(solution(*primals))  # once, for the result and for the pullback's residuals
        qdd, lam = y[:nv], y[nv:]
        return y, tangent_p.bind(*primals, qdd, lam, *tangents, jnp.zeros_like(qdd), jnp.zeros_like(lam),
                                 rule=rule, stack=())

    return solve


def _native_pullback(dyn, pullback: Callable, stabilization: Baumgarte | None, eps: float) -> Callable:
    """``pullback`` of :func:`_joined` computed by the native handler ``kkt_vjp`` on CPU where the robot's library
    has it (:mod:`jaxskid.lowering._ffi_kkt`: the same solve and pullback in one call), by ``pullback`` itself
    elsewhere, for other dtypes and for its own derivatives."""
    nq, n_out = dyn.argument_shape("q")[0], dyn.argument_shape("q")[0] + 2 * dyn.nv + len(dyn.parameters)
    alpha, beta = (stabilization.alpha, stabilization.beta) if stabilization is not None else (0.0, 0.0)

    def flat(q, qd, qdd, lam, w, consts, p):
        return jnp.concatenate(pullback(q, qd, None, p, qdd, lam, w)[:4])

    def native(q, qd, tau, p, qdd, lam, w):
        target = dyn.native_target("kkt_vjp")  # built (or waited for) when the gradient is traced
        if target is None:
            return pullback(q, qd, tau, p, qdd, lam, w)
        consts = jnp.asarray([alpha, beta, eps], qd.dtype)
        out = native_call(target, (n_out,), flat)(q, qd, qdd, lam, w, consts, p)
        n = dyn.nv
        return (out[:nq], out[nq:nq + n], out[nq + n:nq + 2 * n], out[nq + 2 * n:], jnp.zeros_like(qdd),
                jnp.zeros_like(lam))

    return native


def constrained_accelerations(dyn, batched: bool = True, stabilization: Baumgarte | None = None,
                              regularization: float = 0.0) -> Callable:
    """``qdd(q, qd, tau, p, wrench=None)`` of the constrained robot: the form of
    :func:`jaxskid.runtime._forward.accelerations` that rollouts use (the multipliers dropped)."""
    solve = constrained(dyn, stabilization, regularization)

    def qdd(q, qd, tau, p, wrench=None):
        if wrench is not None:
            tau = tau - dyn.generated("external_torques", batched)(q, wrench, p)
        return materialize(solve(q, qd, tau, p)[0])

    return qdd


def _state_batch(dyn, where: str, states: Sequence[tuple[str, jax.Array]], p: jax.Array) -> tuple:
    nv = dyn.signature("constraint_jacobian")[1][1]
    cores = {"q": (dyn.nq,), "qd": (nv,), "qdd": (nv,), "tau": (nv,)}
    states = [(a, x.shape, cores[a]) for a, x in states]
    return batch_shape(where, states, [("params", p.shape, (len(dyn.parameters),))])


@partial(jit, static_argnames=("dyn", "stabilization", "regularization"))
def _forward(dyn, q, qd, tau, params, stabilization, regularization):
    (q, qd, tau), p, dtype = inexact_inputs(dyn.layout, (q, qd, tau), params)
    batch = _state_batch(dyn, "constrained_forward_dynamics", [("q", q), ("qd", qd), ("tau", tau)], p)
    joined = _joined(dyn, stabilization, regularization)
    out = joined(q, qd, tau, p) if not batch else vmapped(joined, batch, [(q, 1), (qd, 1), (tau, 1), (p, 1)])
    nv = qd.shape[-1]
    return out[..., :nv], out[..., nv:]


def constrained_forward_dynamics(dyn, q, qd, tau, params=None, *, stabilization: Baumgarte | None = None,
                                 regularization: float = 0.0) -> tuple[jax.Array, jax.Array]:
    """Accelerations and multipliers of the constrained robot: ``M qdd + h = tau + A^T lambda`` with
    ``A qdd = -Adot qd`` (``- 2 alpha A qd - beta^2 phi`` with a :class:`Baumgarte` ``stabilization``).

    Args:
        dyn: a :class:`~jaxskid.Dynamics` of a robot with constraints, lowered with :data:`CONSTRAINT_QUANTITIES`,
            ``mass_matrix`` and ``inverse_dynamics`` (or ``coriolis_torques`` and ``gravity_torques``); the
            default quantities of such a robot have them all.
        q ``(nq,)``, qd ``(nv,)``, tau ``(nv,)``: or ``(..., nq)``, ``(..., nv)`` for a batch.
        params: as for :func:`jaxskid.forward_dynamics`.
        stabilization: ``None`` (the constraint's second derivative alone) or :class:`Baumgarte` gains.
        regularization: ``eps >= 0`` added to the diagonal of ``A M^-1 A^T``, for redundant constraints.

    Returns:
        ``(qdd (..., nv), lambda (..., m))``; lambda are the constraint wrenches on the constrained world axes
        (:mod:`jaxskid.model._constraint`). ``jax.jit``, ``jax.vmap`` and ``jax.grad`` apply (exact derivatives:
        module docstring).
    """
    require_constraints(dyn, "constrained_forward_dynamics")
    stabilization, regularization = options(stabilization, regularization)
    return _forward(dyn, q, qd, tau, dyn.packed_params(params), stabilization, regularization)


def _actuated(dyn, actuated) -> tuple[int, ...]:
    """The velocity coordinates of the actuated joints (names or indices into ``dyn.joint_names``)."""
    items = [actuated] if isinstance(actuated, (str, int)) else list(actuated)
    offset = dyn.signature("constraint_jacobian")[1][1] - dyn.n_dof  # a floating base's six come first
    out = []
    for a in items:
        if isinstance(a, str) and a in dyn.joint_names:
            k = dyn.joint_names.index(a)
        elif isinstance(a, int) and not isinstance(a, bool) and 0 <= a < dyn.n_dof:
            k = a
        else:
            raise RequestError(f"actuated: expected joint names or indices into {', '.join(dyn.joint_names)}, "
                               f"got {a!r}")
        if offset + k in out:
            raise RequestError(f"actuated: joint {dyn.joint_names[k]!r} given twice")
        out.append(offset + k)
    return tuple(out)


@partial(jit, static_argnames=("dyn", "columns"))
def _inverse(dyn, q, qd, qdd, params, columns):
    (q, qd, qdd), p, dtype = inexact_inputs(dyn.layout, (q, qd, qdd), params)
    batch = _state_batch(dyn, "constrained_inverse_dynamics", [("q", q), ("qd", qd), ("qdd", qdd)], p)
    fn = _functions(dyn)
    nv = qd.shape[-1]

    def one(q, qd, qdd, p):
        a = fn["jacobian"](q, p)
        k = jnp.concatenate([jnp.eye(nv, dtype=a.dtype)[:, list(columns)], a.T], axis=1)
        return jnp.linalg.pinv(k) @ fn["inverse"](q, qd, qdd, p)

    out = one(q, qd, qdd, p) if not batch else vmapped(one, batch, [(q, 1), (qd, 1), (qdd, 1), (p, 1)])
    return out[..., :len(columns)], out[..., len(columns):]


def constrained_inverse_dynamics(dyn, q, qd, qdd, actuated, params=None) -> tuple[jax.Array, jax.Array]:
    """The actuated joints' forces and the multipliers that make a closed chain move with ``(q, qd, qdd)``:
    ``B tau_a + A(q)^T lambda = ID(q, qd, qdd)``, ``B`` the columns of the actuated joints.

    The motion must satisfy the constraints (``phi = 0``, ``A qd = 0``, ``A qdd = -Adot qd``); then feeding
    ``tau = B tau_a`` to :func:`constrained_forward_dynamics` gives ``qdd`` back. With as many actuated joints
    as the chain has degrees of freedom (``k + m = nv``) the solution is unique; otherwise it is the
    least-squares one of least norm (``pinv([B, A^T]) ID``).

    Args:
        dyn: as for :func:`constrained_forward_dynamics` (``inverse_dynamics`` or M and the bias lowered).
        q, qd, qdd: a consistent motion, ``(nq,)``, ``(nv,)``, ``(nv,)`` or batches of them.
        actuated: the actuated joints, names or indices into ``dyn.joint_names`` (a floating base is never
            actuated).
        params: as for :func:`jaxskid.forward_dynamics`.

    Returns:
        ``(tau_a (..., k), lambda (..., m))``, ``tau_a`` in the order of ``actuated``.
    """
    require_constraints(dyn, "constrained_inverse_dynamics")
    return _inverse(dyn, q, qd, qdd, dyn.packed_params(params), _actuated(dyn, actuated))
