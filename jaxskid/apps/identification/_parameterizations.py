"""Parameterizations of the standard inertial parameters for fits, and physical consistency.

A parameterization maps unconstrained numbers ``theta`` onto standard parameters ``pi`` (``standard``) and
back (``init``). :class:`LogCholesky` reaches every physically consistent body and only those (Rucker &
Wensing, "Smooth parameterization of rigid-body inertia", RA-L 7(2), 2022); the drive parameters after the
bodies' pass through and carry bounds instead (``Ia, fv, fc >= 0``), which the fits enforce by projection.
:func:`nearest_consistent` projects any standard vector onto the consistent set (the pseudo-inertia's
eigenvalues clipped, Wensing, Kim & Slotine, "Linear matrix inequalities for physically consistent inertial
parameter identification", RA-L 3(1), 2017; the drive bounds clipped).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..._errors import ShapeError


@dataclass(frozen=True)
class Standard:
    """theta = pi: the standard parameters themselves (no physical-consistency constraint)."""

    def init(self, pi):
        return jnp.asarray(pi)

    def standard(self, theta):
        return theta

    def lower_bounds(self, size: int) -> np.ndarray:
        """The lower bounds of ``theta`` (size,): none."""
        return np.full(size, -np.inf)


@dataclass(frozen=True)
class LogCholesky:
    """Per body, 10 unconstrained numbers ``theta = (alpha, d1, d2, d3, s12, s23, s13, t1, t2, t3)`` that
    map onto every physically consistent inertia and only those (Rucker & Wensing 2022, eq. 9):

        J = U U^T,  U = e^alpha [[e^d1, s12, s13, t1], [0, e^d2, s23, t2], [0, 0, e^d3, t3], [0, 0, 0, 1]],

    with the pseudo-inertia ``J = [[Sigma, h], [h^T, m]]``, ``Sigma = tr(I)/2 1 - I``, ``h = m c``
    (Wensing, Kim & Slotine, RA-L 3(1), 2017). ``J`` positive definite is equivalent to positive mass and
    the triangle inequalities of the inertia about the centre of mass.

    ``drives``: the number of driven joints, whose 4 standard parameters ``(Ia, fv, fc, fo)`` each follow the
    bodies' (``len(robot.driven)``); they pass through unchanged (theta = pi there), with the lower bounds
    ``Ia, fv, fc >= 0`` (:meth:`lower_bounds`) that :class:`GradientFit` and :class:`PhysicallyConsistent`
    keep (projected steps, bounded trust regions).
    """

    drives: int = 0

    def standard(self, theta):
        """``(..., 10 k + 4 drives)`` log-Cholesky numbers (then drive parameters) -> standard parameters."""
        th, rest = _split_drives(theta, self.drives)
        pi = _pseudo_to_standard(_log_cholesky_to_pseudo(th.reshape((*th.shape[:-1], -1, 10))))
        return jnp.concatenate([pi.reshape(th.shape), rest], axis=-1)

    def init(self, pi):
        """Standard parameters (physically consistent, ``J`` positive definite) -> log-Cholesky numbers."""
        pi, rest = _split_drives(jnp.asarray(pi), self.drives)
        j = _standard_to_pseudo(pi.reshape((*pi.shape[:-1], -1, 10)))
        # U upper triangular with J = U U^T: reverse the order, take the lower Cholesky factor, reverse back.
        u = jnp.flip(jnp.linalg.cholesky(jnp.flip(j, (-2, -1))), (-2, -1))
        alpha = jnp.log(u[..., 3, 3])
        v = u / u[..., 3:4, 3:4]
        th = jnp.stack(
            [alpha, jnp.log(v[..., 0, 0]), jnp.log(v[..., 1, 1]), jnp.log(v[..., 2, 2]),
             v[..., 0, 1], v[..., 1, 2], v[..., 0, 2], v[..., 0, 3], v[..., 1, 3], v[..., 2, 3]], axis=-1)
        return jnp.concatenate([th.reshape(pi.shape), rest], axis=-1)

    def lower_bounds(self, size: int) -> np.ndarray:
        """The lower bounds of ``theta`` (size,): ``-inf`` for the bodies' numbers, ``(0, 0, 0, -inf)`` for each
        drive's ``(Ia, fv, fc, fo)``."""
        return drive_lower_bounds(size, self.drives)


def drive_lower_bounds(size: int, drives: int) -> np.ndarray:
    """``(size,)`` lower bounds of a standard vector: none for the bodies, ``Ia, fv, fc >= 0`` for each drive."""
    _split_drives(np.zeros(size), drives)  # checks the layout
    low = np.full(size, -np.inf)
    if drives:
        low[size - 4 * drives:] = np.tile([0.0, 0.0, 0.0, -np.inf], drives)
    return low


def _split_drives(x, drives: int):
    """``(x[..., :10 k], x[..., 10 k:])``: the bodies' standard parameters and the ``4 drives`` after them."""
    cut = x.shape[-1] - 4 * drives
    if cut < 0 or cut % 10:
        raise ShapeError(f"expected 10 entries per body and then 4 per drive ({drives} drives), got {x.shape[-1]}")
    return x[..., :cut], x[..., cut:]


def _log_cholesky_to_pseudo(th):
    alpha, d1, d2, d3, s12, s23, s13, t1, t2, t3 = (th[..., k] for k in range(10))
    zero, one = jnp.zeros_like(alpha), jnp.ones_like(alpha)
    u = jnp.stack([
        jnp.stack([jnp.exp(d1), s12, s13, t1], -1),
        jnp.stack([zero, jnp.exp(d2), s23, t2], -1),
        jnp.stack([zero, zero, jnp.exp(d3), t3], -1),
        jnp.stack([zero, zero, zero, one], -1),
    ], -2) * jnp.exp(alpha)[..., None, None]
    return u @ jnp.swapaxes(u, -1, -2)


def _eye3(like):
    return jnp.eye(3, dtype=like.dtype).reshape((1,) * like.ndim + (3, 3))


def _pseudo_to_standard(j):
    sigma = j[..., :3, :3]
    tr = jnp.trace(sigma, axis1=-2, axis2=-1)
    inertia = tr[..., None, None] * _eye3(tr) - sigma
    return jnp.stack([
        j[..., 3, 3], j[..., 0, 3], j[..., 1, 3], j[..., 2, 3],
        inertia[..., 0, 0], inertia[..., 0, 1], inertia[..., 1, 1], inertia[..., 0, 2], inertia[..., 1, 2], inertia[..., 2, 2],
    ], axis=-1)


def _standard_to_pseudo(pi):
    m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz = (pi[..., k] for k in range(10))
    inertia = jnp.stack([jnp.stack([ixx, ixy, ixz], -1), jnp.stack([ixy, iyy, iyz], -1), jnp.stack([ixz, iyz, izz], -1)], -2)
    tr = (ixx + iyy + izz) / 2
    sigma = tr[..., None, None] * _eye3(tr) - inertia
    h = jnp.stack([hx, hy, hz], -1)
    top = jnp.concatenate([sigma, h[..., :, None]], axis=-1)
    bottom = jnp.concatenate([h, m[..., None]], axis=-1)[..., None, :]
    return jnp.concatenate([top, bottom], axis=-2)


def physically_consistent(pi, tol: float = 0.0, drives: int = 0) -> np.ndarray:
    """Per body, whether the pseudo-inertia of the standard parameters ``pi (..., 10 k + 4 drives)`` is
    positive definite (smallest eigenvalue ``> tol``): shape ``(..., k)``. ``drives``: the number of driven
    joints (``len(robot.driven)``) whose parameters end ``pi``; they are not checked here."""
    pi, _ = _split_drives(jnp.asarray(pi), drives)
    j = _standard_to_pseudo(pi.reshape((*pi.shape[:-1], -1, 10)))
    return np.asarray(jnp.linalg.eigvalsh(j)[..., 0] > tol)


_pseudo_jit = jax.jit(_standard_to_pseudo)  # one compiled program instead of a dozen eager operations
_standard_jit = jax.jit(_pseudo_to_standard)


def nearest_consistent(pi, drives: int = 0, margin: float = 1e-6) -> np.ndarray:
    """The physically consistent standard vector nearest ``pi (10 k + 4 drives,)``: per body, the eigenvalues
    of the pseudo-inertia ``J`` raised to at least ``margin`` times its largest (the projection onto the positive
    definite cone in the Frobenius norm of ``J``, kept strictly inside so that :meth:`LogCholesky.init`
    applies); the drives' ``Ia, fv, fc`` raised to 0. A body whose ``J`` has no positive eigenvalue becomes
    ``margin`` times the largest of the others' (or of 1) times the identity."""
    pi = np.asarray(pi, dtype=float)
    bodies, rest = _split_drives(pi, drives)
    j = np.asarray(_pseudo_jit(bodies.reshape(-1, 10)))
    lam, vec = np.linalg.eigh(j)
    top = lam[:, -1]
    scale = top.max() if top.size and top.max() > 0 else 1.0
    floor = margin * np.where(top > 0, top, scale)[:, None]
    j = (vec * np.maximum(lam, floor)[:, None, :]) @ np.swapaxes(vec, -1, -2)
    out = np.asarray(_standard_jit(j)).reshape(-1)
    return np.concatenate([out, np.maximum(rest, drive_lower_bounds(pi.size, drives)[bodies.size:])])


def bounded(optimizer: optax.GradientTransformation, lower) -> optax.GradientTransformation:
    """``optimizer`` with every step projected onto ``theta >= lower`` (the optimizer itself where ``lower`` is
    ``-inf`` throughout); extra arguments of the update (a line search's ``value_fn``) pass through."""
    lower = np.asarray(lower, dtype=float)
    if not np.isfinite(lower).any():
        return optimizer
    inner = optax.with_extra_args_support(optimizer)
    low = jnp.asarray(lower)

    def update(grads, state, params, **extra):
        updates, state = inner.update(grads, state, params, **extra)
        return jnp.maximum(params + updates, low) - params, state

    return optax.GradientTransformationExtraArgs(inner.init, update)
