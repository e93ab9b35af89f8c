"""Physically consistent least squares: the numerical parts of :class:`PhysicallyConsistent` and of the
least-squares warm start of :class:`GradientFit`.

The loss ``|W (Y pi - tau)|^2`` over all samples equals ``|R pi - c|^2 + rest`` with ``W Y = U S V^T`` (the
rank-``r`` part: ``R = S_r V_r^T``, ``c = U_r^T W tau``), so a fit needs only ``r`` residuals (at most the
number of standard parameters) whatever the number of samples.

The warm start alternates projections (von Neumann; Bauschke & Borwein, SIAM Review 38(3), 1996) between the
least-squares solutions ``{pi : V_r^T pi = S_r^-1 c}`` and the consistent set (every body's pseudo-inertia
``J`` positive semidefinite, Wensing, Kim & Slotine, RA-L 3(1), 2017; ``Ia, fv, fc >= 0``), both convex, in
the coordinates where the distance is the Frobenius norm of ``J``: where they meet, it nears a consistent
least-squares solution. From there Levenberg-Marquardt minimises ``|R pi(theta) - c|^2`` over the
log-Cholesky numbers ``theta`` (Rucker & Wensing, RA-L 7(2), 2022), with the Jacobian ``R d pi/d theta``
(``d pi/d theta`` block diagonal, each body's block from ``jax.jacfwd``): the residual is linear in ``pi`` and
``pi(theta)`` smooth, so damped Gauss-Newton steps converge in tens of steps where first-order methods take
thousands. The damping is Levenberg's ``lambda I`` (scaled by the largest diagonal entry of ``J^T J``): its
steps have no component in the directions the data leave free. Measured on the Panda (43 base parameters)
from the same start: Marquardt's ``lambda diag(J^T J)`` stalled at 200 times the least-squares error with a
body on the boundary of the consistent set; ``scipy.optimize.least_squares`` (``"trf"``, bounded) took 100
residual evaluations, far longer than the loop here, compiled, and also ended with a body on the boundary.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.linalg

from ..._errors import IdentificationError
from ...runtime._jit import jit
from ._parameterizations import (
    LogCholesky, _split_drives, _standard_to_pseudo, drive_lower_bounds, nearest_consistent,
)


class Reduced(NamedTuple):
    """``|W (Y pi - tau)|^2 = |r pi - c|^2 + rest`` for every ``pi``; ``basis`` ``(p, rank)`` spans the
    identifiable directions and ``s`` holds their singular values (``r = s basis^T``); ``leverage``
    ``(samples, n)`` is the diagonal of the hat matrix, each equation's share of the ``rank`` fitted degrees
    of freedom."""

    r: np.ndarray
    c: np.ndarray
    rest: float
    basis: np.ndarray
    s: np.ndarray
    leverage: np.ndarray


def reduce(y, tau, weight, rtol: float = 1e-10) -> Reduced:
    """The rank-revealing reduction of the weighted problem; ``y (samples, n, p)``, ``tau (samples, n)``,
    ``weight (n,)`` (``1 / sigma`` per joint). Singular values below ``rtol`` times the largest count as zero."""
    s_, n, p = y.shape
    a = (y * weight[None, :, None]).reshape(s_ * n, p)
    b = (tau * weight[None, :]).reshape(s_ * n)
    q, r0 = scipy.linalg.qr(a, mode="economic")
    u, s, vt = np.linalg.svd(r0)
    rank = int(np.sum(s > rtol * s[0])) if s.size and s[0] > 0 else 0
    if rank == 0:
        raise IdentificationError("identify: the regressor is zero on every sample; nothing can be identified")
    c = u[:, :rank].T @ (q.T @ b)
    leverage = np.sum((q @ u[:, :rank]) ** 2, axis=1).reshape(s_, n)
    return Reduced(s[:rank, None] * vt[:rank], c, max(float(b @ b - c @ c), 0.0), vt[:rank].T, s[:rank], leverage)


def joint_residual_std(res, leverage) -> np.ndarray:
    """Per joint, ``sqrt(|res_j|^2 / (samples - h_j))`` with ``h_j`` the leverages of joint j's equations: for
    least-squares residuals ``E |res_j|^2 = sigma_j^2 (samples - h_j)`` (equal noise; close otherwise)."""
    dof = np.maximum(res.shape[0] - np.sum(leverage, axis=0), 1.0)
    return np.sqrt(np.sum(res * res, axis=0) / dof)


def least_squares_std(y, tau) -> np.ndarray:
    """The joints' noise standard deviations estimated from the residuals of ordinary least squares (the
    minimum-norm solution: any rank)."""
    red = reduce(y, tau, np.ones(y.shape[1]))
    res = tau - np.einsum("snp,p->sn", y, least_squares_near(red, np.zeros(y.shape[2])))
    return joint_residual_std(res, red.leverage)


def least_squares_near(red: Reduced, reference) -> np.ndarray:
    """The least-squares solution closest to ``reference (p,)``: its identifiable part replaced by the data's."""
    v = red.basis
    return reference - v @ (v.T @ reference) + v @ (red.c / red.s)


# ---------------------------------------------------------------------------------------- warm start
_UPPER = np.triu_indices(4)
_FROBENIUS = np.where(_UPPER[0] == _UPPER[1], 1.0, np.sqrt(2.0))  # |J|_F = |J[upper] * _FROBENIUS|


def _pseudo_coordinates(p: int, drives: int) -> np.ndarray:
    """``T (p, p)``: ``z = T pi`` holds each body's ``J`` entries (upper triangle, off-diagonal times sqrt 2),
    so ``|z|`` is the Frobenius norm of the ``J``; the drive entries pass through."""
    bodies = (p - 4 * drives) // 10
    unit = np.asarray(_standard_to_pseudo(np.eye(10)))  # J is linear in pi: J of each unit vector
    block = (unit[:, _UPPER[0], _UPPER[1]] * _FROBENIUS).T
    return scipy.linalg.block_diag(*([block] * bodies), np.eye(4 * drives))


def consistent_start(red: Reduced, drives: int = 0, reference=None, iterations: int = 100,
                     margin: float = 1e-6) -> np.ndarray:
    """A physically consistent standard vector near the least-squares solutions: ``iterations`` alternating
    projections from the least-squares solution closest to ``reference`` (default 0), ending with the
    projection onto the consistent set (strictly inside, :func:`nearest_consistent`)."""
    p = red.r.shape[1]
    bodies = len(_split_drives(np.zeros(p), drives)[0]) // 10
    t = _pseudo_coordinates(p, drives)
    t_inv = np.linalg.inv(t)
    a = red.basis.T @ t_inv  # the least-squares solutions: a z = d
    d = red.c / red.s
    a_pinv = np.linalg.pinv(a)
    low = drive_lower_bounds(p, drives)[10 * bodies:]
    z = t @ least_squares_near(red, np.zeros(p) if reference is None else np.asarray(reference, dtype=float))
    for _ in range(iterations):
        j = np.zeros((bodies, 4, 4))
        j[:, _UPPER[0], _UPPER[1]] = z[: 10 * bodies].reshape(bodies, 10) / _FROBENIUS
        j = j + np.triu(j, 1).swapaxes(-1, -2)
        lam, vec = np.linalg.eigh(j)
        j = (vec * np.maximum(lam, 0.0)[:, None, :]) @ vec.swapaxes(-1, -2)
        z = np.concatenate([(j[:, _UPPER[0], _UPPER[1]] * _FROBENIUS).reshape(-1), np.maximum(z[10 * bodies:], low)])
        z = z - a_pinv @ (a @ z - d)
    return nearest_consistent(t_inv @ z, drives, margin)


# ---------------------------------------------------------------------------------------- Levenberg-Marquardt
class LMResult(NamedTuple):
    """``theta`` at the end, the ``history`` of ``|residual|^2`` (steps,; NaN after the last step) and the
    number of ``steps`` taken."""

    theta: jax.Array
    history: jax.Array
    steps: jax.Array


def levenberg_marquardt(residual, theta0, lower, *, jacobian=None, steps: int = 500, tol: float = 1e-10,
                        scale: float = 0.0) -> LMResult:
    """Minimise ``|residual(theta)|^2`` from ``theta0`` with ``theta >= lower``: Levenberg-Marquardt steps
    ``(J^T J + lambda max(diag J^T J) 1) delta = -J^T r`` (Nocedal & Wright, "Numerical Optimization", 2006,
    sec. 10.3), clipped at the bounds, the coordinates held at a bound that the gradient pushes against left out
    of the step (projected Newton, Bertsekas, SIAM J. Control Optim. 20(2), 1982). A step is kept when it lowers
    the loss (then ``lambda / 3``, else ``lambda * 4``); the loop stops after ``steps``, or when a kept step lowers
    the loss by at most ``tol (loss + scale)``, or when ``lambda`` passes 1e10. ``jacobian(theta)`` defaults to
    ``jax.jacfwd(residual)``. Traceable: call it under ``jit``.
    """
    jacobian = jacobian or jax.jacfwd(residual)
    lower = jnp.asarray(lower, dtype=float)

    def cost(theta):
        r = residual(theta)
        return r @ r

    def step(state):
        k, theta, lam, loss, _, history = state
        r, jm = residual(theta), jacobian(theta)
        g, h = jm.T @ r, jm.T @ jm
        free = ~((theta <= lower) & (g > 0))
        a = jnp.where(free[:, None] & free[None, :], h, 0.0)
        a = a + jnp.diag(lam * jnp.max(jnp.diag(h)) + jnp.where(free, 0.0, 1.0))
        trial = jnp.maximum(theta - jnp.linalg.solve(a, jnp.where(free, g, 0.0)), lower)
        new = cost(trial)
        keep = jnp.isfinite(new) & (new < loss)
        done = (keep & (loss - new <= tol * (loss + scale))) | (lam > 1e10)
        return (k + 1, jnp.where(keep, trial, theta), jnp.where(keep, lam / 3, lam * 4), jnp.where(keep, new, loss),
                done, history.at[k].set(loss))

    theta0 = jnp.maximum(jnp.asarray(theta0, dtype=float), lower)
    state = (0, theta0, 1e-3, cost(theta0), False, jnp.full(steps, jnp.nan, dtype=theta0.dtype))
    k, theta, _, _, _, history = jax.lax.while_loop(lambda s: (s[0] < steps) & ~s[4], step, state)
    return LMResult(theta, history, k)


_BODY = LogCholesky()  # one body: 10 log-Cholesky numbers -> 10 standard parameters


@functools.partial(jit, static_argnames=("drives", "steps"))
def _log_cholesky_lm(theta0, r, c, reference, weight, scale, tol, *, drives: int, steps: int) -> LMResult:
    """Levenberg-Marquardt on ``[r; weight 1] pi(theta) - [c; weight reference]``. ``d pi / d theta`` is block
    diagonal (10 x 10 per body, the identity for the drives): the Jacobian is built body by body."""
    par = LogCholesky(drives=drives)
    p = theta0.shape[0]
    cut = p - 4 * drives
    a = jnp.concatenate([r, weight * jnp.eye(p)])
    b = jnp.concatenate([c, weight * reference])
    a_bodies = a[:, :cut].reshape(a.shape[0], -1, 10)

    def residual(theta):
        return a @ par.standard(theta) - b

    def jacobian(theta):
        blocks = jax.vmap(jax.jacfwd(_BODY.standard))(theta[:cut].reshape(-1, 10))
        bodies = jnp.einsum("rki,kij->rkj", a_bodies, blocks).reshape(a.shape[0], cut)
        return jnp.concatenate([bodies, a[:, cut:]], axis=1)

    return levenberg_marquardt(residual, theta0, par.lower_bounds(p), jacobian=jacobian, steps=steps, tol=tol,
                               scale=scale)


@functools.partial(jit, static_argnames=("drives",))
def log_cholesky_init(pi, *, drives: int):
    """:meth:`LogCholesky.init`, compiled once per size."""
    return LogCholesky(drives=drives).init(pi)


def consistent_fit(red: Reduced, drives: int, theta0, *, prior: float = 0.0, reference=None, steps: int = 500,
                   tol: float = 1e-10) -> LMResult:
    """Levenberg-Marquardt on ``|r pi(theta) - c|^2 + prior s_max^2 |pi(theta) - reference|^2`` over the
    log-Cholesky numbers ``theta`` (:class:`LogCholesky` with ``drives``); ``s_max`` is the largest singular value
    of ``r``, so ``prior`` is relative to the best-determined direction. The history is of the whole loss
    (``+ rest``). Compiled once per problem size."""
    p = red.r.shape[1]
    reference = np.zeros(p) if reference is None else np.asarray(reference, dtype=float)
    weight = float(np.sqrt(prior) * red.s[0])
    out = _log_cholesky_lm(jnp.asarray(theta0, dtype=float), red.r, red.c, reference, weight, red.rest, tol,
                           drives=drives, steps=steps)
    return out._replace(history=out.history + red.rest)
