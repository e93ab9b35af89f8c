"""Inertial-parameter identification: base parameters, (weighted) least squares, gradient fits.

The equations of motion are linear in the standard parameters, ``tau = Y(q, qd, qdd) pi``
(:mod:`jaxskid.symbolic._regressor`, standard parameters in :mod:`jaxskid.model._standard`). Not every combination of ``pi`` moves the joints; the identifiable ones are
the **base parameters** ``pi_b = K pi``, found numerically by QR with column pivoting of the regressor
stacked over random states (Gautier & Khalil, "Direct calculation of minimum set of inertial parameters
of serial robots", IEEE T-RA 6(3), 1990; Gautier, "Numerical calculation of the base inertial parameters
of robots", J. Robotic Systems 8(4), 1991): with ``W P = Q R``, ``R = [[R1, R2], [0, 0]]`` of rank r,
``pi_b = pi_1 + R1^-1 R2 pi_2`` and ``Y pi = Y[:, P1] pi_b``.

:func:`identify` estimates them with one of several methods: :class:`LeastSquares`,
:class:`WeightedLeastSquares`, or :class:`GradientFit`, a gradient-descent fit of the standard parameters
through any :class:`Parameterization` (e.g. :class:`LogCholesky`, physically consistent by construction,
Rucker & Wensing, "Smooth parameterization of rigid-body inertia", RA-L 7(2), 2022). :func:`fit` minimises
any differentiable loss, e.g. one through a lowered quantity (:func:`quantity_loss`) or through whole
simulated trajectories (:func:`trajectory_loss`).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax
import scipy.linalg

from .._errors import IdentificationError, IdentificationWarning, RequestError, ShapeError
from ..runtime._dynamics import Dynamics
from ..runtime._jit import jit
from ._integrators import RK4
from ._simulate import Trajectory, rollout


# ---------------------------------------------------------------------------------------- base parameters
@dataclass(frozen=True, eq=False)
class BaseParameters:
    """The identifiable combinations ``pi_b = K pi`` of the standard parameters.

    Attributes:
        independent: ``(n_base,)`` indices of the standard parameters kept (the pivot columns).
        projection: ``K``, shape ``(n_base, n_std)``: ``pi_b = K pi`` and ``Y = Y[:, independent] K``.
        names: the standard parameters' names, if known (for :meth:`describe`).
    """

    independent: np.ndarray
    projection: np.ndarray
    names: tuple[str, ...] = ()

    @property
    def n_base(self) -> int:
        return len(self.independent)

    def reduce(self, y):
        """The reduced regressor ``Y_b = Y[..., independent]`` (..., n_base): ``Y pi = Y_b pi_b``."""
        return y[..., self.independent]

    def project(self, pi):
        """``pi_b = K pi`` for standard parameters ``pi`` (..., n_std)."""
        return pi @ self.projection.T

    def describe(self, digits: int = 4) -> list[str]:
        """Each base parameter as a readable combination, e.g. ``"link2.Izz + 0.09 link2.m"``."""
        names = self.names or tuple(f"pi[{k}]" for k in range(self.projection.shape[1]))
        out = []
        for row in self.projection:
            text = ""
            for k in np.flatnonzero(row):
                c = float(row[k])
                c = round(c) if abs(c - round(c)) < 1e-9 else c
                sign = "-" if c < 0 else "+"
                mag = "" if abs(c) == 1 else f"{abs(c):.{digits}g} "
                text += f" {sign} {mag}{names[k]}"
            out.append(text[3:] if text.startswith(" + ") else "-" + text[3:])
        return out


def random_states(n: int, samples: int, seed: int = 0, *, scale: float = 1.0) -> tuple[np.ndarray, ...]:
    """``(q, qd, qdd)``, each ``(samples, n)``: q uniform in [-pi, pi], qd and qdd standard normal x scale."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, size=(samples, n))
    return q, scale * rng.normal(size=(samples, n)), scale * rng.normal(size=(samples, n))


def base_parameters(
    source,
    params=None,
    *,
    samples: int = 100,
    seed: int = 0,
    tol: float = 1e-8,
    names: Sequence[str] = (),
    n_dof: int | None = None,
) -> BaseParameters:
    """The base parameters of a regressor (QR with column pivoting of it stacked over states).

    Args:
        source: any regressor: a :class:`Dynamics` lowered with ``regressor`` (evaluated at ``samples`` random
            states), a function ``f(q, qd, qdd) -> (samples, n, p)`` of batched states ``(samples, n)`` (give
            ``n_dof``; e.g. the regressor with extra columns of your own), or a sampled regressor, an array
            ``(samples, n, p)`` or ``(rows, p)``.
        params: the (kinematic) parameter values a :class:`Dynamics` regressor is evaluated at.
        samples: random states stacked (``samples * n`` rows; more than ``p / n`` needed).
        seed: the random states' seed.
        tol: a pivot below ``tol * |R_00|`` counts as zero (the regressor entries are O(1) here).
        names: names of the columns (``jaxskid.standard_parameter_names`` for the standard regressor).
        n_dof: the number of joints, for a function ``source``.
    """
    if isinstance(source, Dynamics):
        if "regressor" not in source.quantities:
            raise RequestError(f"base_parameters needs the quantity regressor; lowered: {', '.join(source.quantities)}")
        q, qd, qdd = random_states(source.n_dof, samples, seed)
        y = source.regressor(q, qd, qdd, params)
    elif callable(source):
        if n_dof is None:
            raise RequestError("base_parameters: give n_dof= with a regressor function f(q, qd, qdd)")
        y = source(*random_states(n_dof, samples, seed))
    else:
        y = source
    y = np.asarray(y, dtype=float)
    if y.ndim not in (2, 3):
        raise ShapeError(f"base_parameters: expected a regressor (samples, n, p) or (rows, p), got shape {y.shape}")
    return base_parameters_from(y.reshape(-1, y.shape[-1]), tol=tol, names=names)


def base_parameters_from(w: np.ndarray, *, tol: float = 1e-8, names: Sequence[str] = ()) -> BaseParameters:
    """Base parameters of a stacked regressor ``w`` (rows, n_std), by Gautier & Khalil's method."""
    w = np.asarray(w, dtype=float)
    _, r, perm = scipy.linalg.qr(w, mode="economic", pivoting=True)
    diag = np.abs(np.diag(r))
    rank = int(np.sum(diag > tol * diag[0])) if diag.size and diag[0] > 0 else 0
    beta = scipy.linalg.solve_triangular(r[:rank, :rank], r[:rank, rank:]) if rank else np.zeros((0, w.shape[1]))
    beta[np.abs(beta) < 1e3 * tol] = 0.0  # exact zeros where the combination does not involve a parameter
    k = np.zeros((rank, w.shape[1]))
    k[:, perm[:rank]] = np.eye(rank)
    k[:, perm[rank:]] = beta
    order = np.argsort(perm[:rank])  # keep the standard order of the independent parameters
    return BaseParameters(perm[:rank][order], k[order], tuple(names))


# ---------------------------------------------------------------------------------------- methods
@dataclass(frozen=True)
class LeastSquares:
    """Ordinary least squares ``min |Y theta - tau|^2``; covariance ``sigma^2 (Y^T Y)^-1`` with the residual
    variance ``sigma^2 = |r|^2 / (rows - p)``."""


@dataclass(frozen=True)
class WeightedLeastSquares:
    """Least squares weighted by each joint's noise: ``min sum_j |Y_j theta - tau_j|^2 / sigma_j^2``.

    ``sigma`` ``(n,)`` gives the joint noise standard deviations; ``None`` estimates them from the residuals
    of an ordinary least-squares fit, joint by joint (Gautier & Poignet, "Extended Kalman filtering and
    weighted least squares dynamic identification of robot", Control Eng. Practice 9(12), 2001).
    """

    sigma: Any = None


@dataclass(frozen=True)
class GradientFit:
    """Gradient descent on ``mean |Y pi(theta) - tau|^2 + prior |pi(theta) - prior_pi|^2`` over a
    :class:`Parameterization` of the standard parameters (``Y`` must be the full regressor, not reduced).

    ``init``: the standard parameters to start from (mapped to theta by the parameterization);
    ``optimizer``: any optax ``GradientTransformation`` (default ``optax.adam(1e-2)``);
    ``prior``: weight of a pull toward ``init`` that fixes the directions the data leave free.
    """

    init: Any
    parameterization: Any = None
    optimizer: Any = None
    steps: int = 2000
    prior: float = 0.0


class Estimate(NamedTuple):
    """An identification result: ``params`` (the estimate), their ``covariance`` (None for gradient fits),
    the per-joint residual standard deviations ``residual_std`` and the loss ``history`` (gradient fits)."""

    params: np.ndarray
    covariance: np.ndarray | None
    residual_std: np.ndarray
    history: np.ndarray | None = None


def identify(y, tau, method=LeastSquares(), *, names: Sequence[str] = ()) -> Estimate:
    """Estimate ``theta`` in ``tau = Y theta + noise`` from stacked samples.

    Args:
        y: the regressor over the samples, ``(samples, n, p)`` (reduced to base parameters with
            :meth:`BaseParameters.reduce` for the least-squares methods).
        tau: the measured joint forces ``(samples, n)``.
        method: :class:`LeastSquares`, :class:`WeightedLeastSquares` or :class:`GradientFit`.
        names: the columns' names, for the messages below.

    Raises:
        IdentificationError: for least squares, fewer equations than unknowns, or columns of ``y`` that are
            linear combinations of others (the message names them and the combination; reduce ``y`` to base
            parameters, or excite the motion that separates them).

    Warns:
        IdentificationWarning: the weighted regressor's condition number is above 1e8; the estimate's
            covariance says which combinations are poorly determined.
    """
    y = np.asarray(y, dtype=float)
    tau = np.asarray(tau, dtype=float)
    if y.ndim != 3 or tau.shape != y.shape[:2]:
        raise ShapeError(f"identify: expected y (samples, n, p) and tau (samples, n), got {y.shape} and {tau.shape}")
    s, n, p = y.shape
    if isinstance(method, GradientFit):
        return _gradient_fit(y, tau, method)
    if isinstance(method, WeightedLeastSquares):
        if method.sigma is None:
            first = _lstsq(y, tau, np.ones(n), names)
            sigma = first.residual_std
        else:
            sigma = np.broadcast_to(np.asarray(method.sigma, dtype=float), (n,))
        return _lstsq(y, tau, 1.0 / sigma, names)
    if isinstance(method, LeastSquares):
        return _lstsq(y, tau, np.ones(n), names)
    raise RequestError(f"identify: unknown method {method!r}; expected LeastSquares, WeightedLeastSquares or GradientFit")


def _lstsq(y, tau, weight, names: Sequence[str] = ()) -> Estimate:
    s, n, p = y.shape
    a = (y * weight[None, :, None]).reshape(s * n, p)
    b = (tau * weight[None, :]).reshape(s * n)
    if s * n <= p:
        raise IdentificationError(f"identify: {s * n} equations for {p} unknowns; stack more samples")
    qm, rm, perm = scipy.linalg.qr(a, mode="economic", pivoting=True)
    _check_rank(rm, perm, names)
    theta = np.empty(p)
    theta[perm] = scipy.linalg.solve_triangular(rm, qm.T @ b)
    res = (tau - np.einsum("snp,p->sn", y, theta))
    dof = (s * n - p) / (s * n)
    residual_std = np.sqrt(np.mean(res * res, axis=0) / dof)
    sigma2 = np.sum((res * weight[None, :]) ** 2) / (s * n - p)
    rinv = np.zeros((p, p))
    rinv[perm] = scipy.linalg.solve_triangular(rm, np.eye(p))
    return Estimate(theta, sigma2 * rinv @ rinv.T, residual_std)


RANK_TOL = 1e-10
"""A pivot of the column-pivoted QR below ``RANK_TOL |R_00|`` makes its column dependent on the earlier ones."""
WARN_COND = 1e8
"""The condition number above which :func:`identify` warns."""


def _check_rank(r: np.ndarray, perm: np.ndarray, names: Sequence[str]) -> None:
    """Raise for dependent columns of ``Y P = Q R``, naming the first and its combination; warn when
    ``cond(R)`` exceeds :data:`WARN_COND`."""
    label = (lambda k: names[k]) if len(names) == r.shape[1] else (lambda k: f"column {k}")
    diag = np.abs(np.diag(r))
    rank = int(np.sum(diag > RANK_TOL * diag[0])) if diag.size and diag[0] > 0 else 0
    if rank < r.shape[1]:
        first = int(perm[rank])
        beta = scipy.linalg.solve_triangular(r[:rank, :rank], r[:rank, rank]) if rank else np.zeros(0)
        order = np.argsort(-np.abs(beta))[:6]
        terms = [f"{'-' if beta[k] < 0 else '+'} {abs(beta[k]):.4g} {label(int(perm[k]))}" for k in order
                 if abs(beta[k]) > 1e-9 * np.abs(beta).max()]
        combo = " ".join(terms).removeprefix("+ ") or "0"
        dependent = ", ".join(label(int(k)) for k in perm[rank:])
        verb = "depends" if r.shape[1] - rank == 1 else "depend"
        raise IdentificationError(
            f"identify: the regressor has rank {rank} < {r.shape[1]} columns: {dependent} {verb} on the others "
            f"(e.g. {label(first)} = {combo}); reduce it to base parameters (jaxskid.base_parameters(Y).reduce(Y)) "
            "or use samples that separate them")
    cond = diag[0] / diag[-1] if diag.size else 1.0
    if cond > WARN_COND:
        # the direction R^-1 e_last is the worst determined; name its largest columns
        v = np.zeros(r.shape[1])
        v[perm] = scipy.linalg.solve_triangular(r, np.eye(r.shape[1])[:, -1])
        worst = ", ".join(label(int(k)) for k in np.argsort(-np.abs(v))[:4])
        warnings.warn(f"identify: the regressor's condition number is {cond:.2g}; the worst-determined "
                      f"combination is mostly {worst}", IdentificationWarning, stacklevel=3)


def _gradient_fit(y, tau, method: GradientFit) -> Estimate:
    par = method.parameterization or Standard()
    init = jnp.asarray(method.init, dtype=float)
    yj, tj = jnp.asarray(y), jnp.asarray(tau)
    scale = 1.0 / jnp.mean(tj * tj)

    def loss(theta):
        pi = par.standard(theta)
        r = jnp.einsum("snp,p->sn", yj, pi) - tj
        return scale * jnp.mean(r * r) + method.prior * jnp.sum((pi - init) ** 2)

    result = fit(loss, par.init(init), optimizer=method.optimizer, steps=method.steps)
    pi = np.asarray(par.standard(result.theta))
    res = tau - np.einsum("snp,p->sn", y, pi)
    return Estimate(pi, None, np.sqrt(np.mean(res * res, axis=0)), np.asarray(result.history))


# ---------------------------------------------------------------------------------------- parameterizations
@dataclass(frozen=True)
class Standard:
    """theta = pi: the standard parameters themselves (no physical-consistency constraint)."""

    def init(self, pi):
        return jnp.asarray(pi)

    def standard(self, theta):
        return theta


@dataclass(frozen=True)
class LogCholesky:
    """Per body, 10 unconstrained numbers ``theta = (alpha, d1, d2, d3, s12, s23, s13, t1, t2, t3)`` that
    map onto every physically consistent inertia and only those (Rucker & Wensing 2022, eq. 9):

        J = U U^T,  U = e^alpha [[e^d1, s12, s13, t1], [0, e^d2, s23, t2], [0, 0, e^d3, t3], [0, 0, 0, 1]],

    with the pseudo-inertia ``J = [[Sigma, h], [h^T, m]]``, ``Sigma = tr(I)/2 1 - I``, ``h = m c``
    (Wensing, Kim & Slotine, RA-L 3(1), 2017). ``J`` positive definite is equivalent to positive mass and
    the triangle inequalities of the inertia about the centre of mass.

    ``drives``: the number of driven joints, whose 4 standard parameters ``(Ia, fv, fc, fo)`` each follow the
    bodies' (``len(robot.driven)``); they pass through unchanged (theta = pi there, not constrained).
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


# ---------------------------------------------------------------------------------------- gradient fits
def Adam(learning_rate: float = 1e-2, b1: float = 0.9, b2: float = 0.999, eps: float = 1e-8) -> optax.GradientTransformation:  # noqa: N802
    """Adam (Kingma & Ba, "Adam: a method for stochastic optimization", ICLR 2015): ``optax.adam``.

    A shorthand kept for :func:`fit` and :class:`GradientFit`; any optax transformation may be passed instead.
    """
    return optax.adam(learning_rate, b1=b1, b2=b2, eps=eps)


def GradientDescent(learning_rate: float = 1e-2) -> optax.GradientTransformation:  # noqa: N802
    """Plain gradient descent ``theta <- theta - learning_rate * grad``: ``optax.sgd``."""
    return optax.sgd(learning_rate)


class FitResult(NamedTuple):
    """``theta`` after the last step and the loss ``history`` (steps,) before each step."""

    theta: Any
    history: jax.Array


def fit(loss: Callable, theta0, *, optimizer: optax.GradientTransformation | None = None, steps: int = 1000) -> FitResult:
    """Minimise a differentiable ``loss(theta)`` from ``theta0`` (any pytree) with ``jax.grad``.

    ``optimizer``: any optax ``GradientTransformation`` (default ``optax.adam(1e-2)``; :func:`Adam` and
    :func:`GradientDescent` are shorthands). The steps run in one compiled ``lax.scan``.
    """
    optimizer = optimizer or optax.adam(1e-2)
    value_and_grad = jax.value_and_grad(loss)

    @jit
    def run(theta0):
        def step(carry, _):
            theta, state = carry
            value, grads = value_and_grad(theta)
            updates, state = optimizer.update(grads, state, theta)
            return (optax.apply_updates(theta, updates), state), value

        (theta, _), history = jax.lax.scan(step, (theta0, optimizer.init(theta0)), None, length=steps)
        return theta, history

    theta, history = run(theta0)
    return FitResult(theta, history)


def quantity_loss(dyn: Dynamics, name: str, inputs: Sequence, target, to_params: Callable, weights=None) -> Callable:
    """``loss(theta) = mean(w * (dyn.<name>(*inputs, to_params(theta)) - target)^2)``, for :func:`fit`.

    ``inputs`` are the quantity's state arrays with a batch axis (e.g. ``(q, qd, qdd)`` for
    ``inverse_dynamics``); ``to_params(theta)`` returns the parameters (a dict or a vector) of ``dyn``.
    """
    if name not in dyn.quantities:
        raise RequestError(f"quantity_loss: {name!r} was not lowered; lowered: {', '.join(dyn.quantities)}")
    raw = dyn.raw(name)
    inputs = [jnp.asarray(x) for x in inputs]
    target = jnp.asarray(target)
    w = 1.0 if weights is None else jnp.asarray(weights)

    def loss(theta):
        p = dyn.param_vector(to_params(theta), target.dtype)
        out = jax.vmap(raw, in_axes=(*([0] * len(inputs)), None))(*inputs, p)
        r = out - target
        return jnp.mean(w * r * r)

    return loss


def trajectory_loss(
    dyn: Dynamics, measured: Trajectory, controls, to_params: Callable, integrator=RK4(), weights=None
) -> Callable:
    """``loss(theta)``: mean squared state error of a rollout with ``to_params(theta)`` against ``measured``.

    The rollout starts at ``measured.x[..., 0, :]`` and uses its time step and length; ``controls`` are
    those that produced it (an array or a policy, see :func:`jaxskid.rollout`). The gradient flows through
    the whole simulation (``lax.scan``).
    """
    x = jnp.asarray(measured.x)
    t = jnp.asarray(measured.t)
    dt = t[..., 1] - t[..., 0]
    steps = x.shape[-2] - 1
    w = 1.0 if weights is None else jnp.asarray(weights)
    if x.ndim != 2:
        raise ShapeError(f"trajectory_loss: expected one measured trajectory x (steps+1, 2n), got {x.shape}")

    def loss(theta):
        sim = rollout(dyn, x[0], controls, dt, steps, integrator, to_params(theta))
        r = sim.x - x
        return jnp.mean(w * r * r)

    return loss
