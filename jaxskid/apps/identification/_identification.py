"""Inertial-parameter identification: base parameters, (weighted) least squares, gradient fits.

The equations of motion are linear in the standard parameters, ``tau = Y(q, qd, qdd) pi``
(:mod:`jaxskid.symbolic._regressor`, standard parameters in :mod:`jaxskid.model._standard`). Not every combination of ``pi`` moves the joints; the identifiable ones are
the **base parameters** ``pi_b = K pi``, found numerically by QR with column pivoting of the regressor
stacked over random states (Gautier & Khalil, "Direct calculation of minimum set of inertial parameters
of serial robots", IEEE T-RA 6(3), 1990; Gautier, "Numerical calculation of the base inertial parameters
of robots", J. Robotic Systems 8(4), 1991): with ``W P = Q R``, ``R = [[R1, R2], [0, 0]]`` of rank r,
``pi_b = pi_1 + R1^-1 R2 pi_2`` and ``Y pi = Y[:, P1] pi_b``.

:func:`identify` estimates them with one of several methods: :class:`LeastSquares`,
:class:`WeightedLeastSquares`, :class:`PhysicallyConsistent` (least squares over the physically consistent
standard parameters, :mod:`._consistent`), or :class:`GradientFit`, a gradient-descent fit of the standard
parameters through a parameterization (:mod:`._parameterizations`; e.g. :class:`LogCholesky`, physically
consistent by construction, Rucker & Wensing, "Smooth parameterization of rigid-body inertia", RA-L 7(2),
2022). :func:`fit` minimises any differentiable loss, e.g. one through a lowered quantity
(:func:`quantity_loss`) or through whole simulated trajectories (:func:`trajectory_loss`).
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

from ..._errors import IdentificationError, IdentificationWarning, RequestError, ShapeError
from ...runtime._dynamics import Dynamics
from ...runtime._checks import check_finite
from ...runtime._jit import jit
from ..simulation import RK4, Trajectory, rollout
from . import _consistent
from ._parameterizations import LogCholesky, Standard, bounded


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


def random_states(n: int, samples: int, seed: int = 0, *, scale: float = 1.0,
                  floating_base: bool = False) -> tuple[np.ndarray, ...]:
    """``(q, qd, qdd)``, each ``(samples, n)``: q uniform in [-pi, pi], qd and qdd standard normal x scale.
    With ``floating_base``, q ``(samples, 7 + n)`` starts with a standard normal base position and a unit
    quaternion uniform on the sphere, and qd, qdd ``(samples, 6 + n)`` with the base's twist and its rate."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, size=(samples, n))
    if not floating_base:
        return q, scale * rng.normal(size=(samples, n)), scale * rng.normal(size=(samples, n))
    quat = rng.normal(size=(samples, 4))
    base = np.concatenate([rng.normal(size=(samples, 3)), quat / np.linalg.norm(quat, axis=1, keepdims=True)], axis=1)
    nv = 6 + n
    return np.concatenate([base, q], axis=1), scale * rng.normal(size=(samples, nv)), scale * rng.normal(size=(samples, nv))


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
        names: names of the columns; for a :class:`Dynamics` the standard parameters' names by default
            (:attr:`Dynamics.standard_names`, as :func:`jaxskid.standard_parameter_names` gives them).
        n_dof: the number of joints, for a function ``source``.
    """
    if isinstance(source, Dynamics):
        if "regressor" not in source.quantities:
            raise RequestError(f"base_parameters needs the quantity regressor; lowered: {', '.join(source.quantities)}")
        q, qd, qdd = random_states(source.n_dof, samples, seed, floating_base=source.floating_base)
        y = source.regressor(q, qd, qdd, params)
        if not names and len(source.standard_names) == y.shape[-1]:
            names = source.standard_names
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
    """Gradient descent on ``mean |Y pi(theta) - tau|^2 / mean |tau|^2 + prior |pi(theta) - init|^2`` over a
    parameterization of the standard parameters (``Y`` must be the full regressor, not reduced).

    ``init``: the standard parameters to start from (mapped to theta by the parameterization), or
    ``"lstsq"``: a least-squares warm start, made physically consistent for :class:`LogCholesky` (alternating
    projections, as :class:`PhysicallyConsistent` starts);
    ``parameterization``: :class:`Standard` (default) or :class:`LogCholesky`, whose drive bounds
    ``Ia, fv, fc >= 0`` every step keeps (projected);
    ``optimizer``: any optax ``GradientTransformation`` (default ``optax.adam(1e-2)``);
    ``prior``: weight of a pull toward ``init`` that fixes the directions the data leave free.

    For a physically consistent least-squares fit prefer :class:`PhysicallyConsistent`: on the Panda (43 base
    parameters, consistent noisy data) it reaches the least-squares base parameters in tens of
    Levenberg-Marquardt steps, where from the same warm start Adam (thousands of steps) and L-BFGS (hundreds)
    stay a sizeable fraction of the least-squares error away from them, and take longer.
    """

    init: Any = "lstsq"
    parameterization: Any = None
    optimizer: Any = None
    steps: int = 2000
    prior: float = 0.0


@dataclass(frozen=True)
class PhysicallyConsistent:
    """Least squares over the physically consistent standard parameters: ``min |W (Y pi - tau)|^2`` with every
    body's pseudo-inertia positive definite (:class:`LogCholesky`) and each drive's ``Ia, fv, fc >= 0``
    (``Y`` the full regressor, 10 columns per body then 4 per drive; ``W = diag(1 / sigma_j)``).

    Where the least-squares base parameters are those of some consistent ``pi``, the fit reaches them (and
    ``pi`` is one such vector); otherwise it finds the consistent ``pi`` that fits the data best.

    The fit starts from the least-squares solution closest to ``init`` (standard parameters, e.g. the CAD
    values; ``None``: the minimum-norm one), made consistent by ``projections`` alternating projections, then
    takes at most ``steps`` Levenberg-Marquardt steps on the log-Cholesky numbers (:mod:`._consistent`).

    Attributes:
        drives: the number of driven joints (``len(robot.driven)``) whose 4 parameters end each row of ``Y``.
        init: standard parameters whose unidentifiable part the estimate keeps, or ``None``.
        sigma: the joints' noise standard deviations ``(n,)`` or a scalar (weights ``1 / sigma``; default 1: all
            joints alike), or ``"estimate"`` (or ``None``): from the residuals of ordinary least squares, as
            :class:`WeightedLeastSquares` does.
        prior: weight of ``|pi - init|^2`` (relative to the best-determined direction of the data); 0 leaves the
            unidentifiable part where the start put it.
        steps: the most Levenberg-Marquardt steps; tol: stop when a step lowers the loss by less than ``tol``
            times the loss.
    """

    drives: int = 0
    init: Any = None
    sigma: Any = 1.0
    prior: float = 0.0
    steps: int = 500
    projections: int = 100
    tol: float = 1e-10


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
    check_finite("identify", [("y", y), ("tau", tau)])
    s, n, p = y.shape
    if isinstance(method, GradientFit):
        return _gradient_fit(y, tau, method)
    if isinstance(method, PhysicallyConsistent):
        return _consistent_fit(y, tau, method)
    if isinstance(method, WeightedLeastSquares):
        return _lstsq(y, tau, 1.0 / _joint_sigma(y, tau, method.sigma), names)
    if isinstance(method, LeastSquares):
        return _lstsq(y, tau, np.ones(n), names)
    raise RequestError(f"identify: unknown method {method!r}; expected LeastSquares, WeightedLeastSquares, "
                       "GradientFit or PhysicallyConsistent")


def _joint_sigma(y, tau, sigma) -> np.ndarray:
    """The joints' noise standard deviations ``(n,)``: given, or (``None`` / ``"estimate"``) those of the
    ordinary least-squares residuals, floored at 1e-9 of the largest so that a joint fitted exactly does not
    take all the weight."""
    n = y.shape[1]
    if sigma is None or (isinstance(sigma, str) and sigma == "estimate"):
        sigma = _consistent.least_squares_std(y, tau)
        return np.maximum(sigma, 1e-9 * sigma.max()) if sigma.max() > 0 else np.ones(n)
    sigma = np.asarray(sigma, dtype=float)
    if sigma.ndim > 1 or sigma.size not in (1, n) or not np.all(sigma > 0):
        raise RequestError(f"identify: sigma must be a positive scalar or {n} positive values, got {sigma}")
    return np.broadcast_to(sigma, (n,))


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
    residual_std = _consistent.joint_residual_std(res, np.sum(qm * qm, axis=1).reshape(s, n))
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
    low = par.lower_bounds(y.shape[2]) if hasattr(par, "lower_bounds") else np.full(y.shape[2], -np.inf)
    init = method.init
    if isinstance(init, str):
        if init != "lstsq":
            raise RequestError(f"GradientFit: init must be standard parameters or 'lstsq', got {init!r}")
        red = _consistent.reduce(y, tau, np.ones(y.shape[1]))
        init = (_consistent.consistent_start(red, par.drives) if isinstance(par, LogCholesky)
                else np.maximum(_consistent.least_squares_near(red, np.zeros(y.shape[2])), low))
    init = jnp.asarray(init, dtype=float)
    if init.shape != (y.shape[2],):
        raise ShapeError(f"GradientFit: init has shape {init.shape}; expected ({y.shape[2]},), one per column of y")
    yj, tj = jnp.asarray(y), jnp.asarray(tau)
    scale = 1.0 / jnp.mean(tj * tj)

    def loss(theta):
        pi = par.standard(theta)
        r = jnp.einsum("snp,p->sn", yj, pi) - tj
        return scale * jnp.mean(r * r) + method.prior * jnp.sum((pi - init) ** 2)

    optimizer = bounded(method.optimizer or optax.adam(1e-2), low)
    result = fit(loss, par.init(init), optimizer=optimizer, steps=method.steps)
    pi = np.asarray(par.standard(result.theta))
    res = tau - np.einsum("snp,p->sn", y, pi)
    return Estimate(pi, None, np.sqrt(np.mean(res * res, axis=0)), np.asarray(result.history))


def _consistent_fit(y, tau, method: PhysicallyConsistent) -> Estimate:
    if method.init is not None and np.shape(method.init) != (y.shape[2],):
        raise ShapeError(f"PhysicallyConsistent: init has shape {np.shape(method.init)}; expected ({y.shape[2]},), "
                         "one per column of y")
    weight = 1.0 / _joint_sigma(y, tau, method.sigma)
    red = _consistent.reduce(y, tau, weight)
    start = _consistent.consistent_start(red, method.drives, method.init, method.projections)
    par = LogCholesky(drives=method.drives)
    theta0 = _consistent.log_cholesky_init(start, drives=method.drives)
    out = _consistent.consistent_fit(red, method.drives, theta0, prior=method.prior, reference=method.init,
                                     steps=method.steps, tol=method.tol)
    pi = np.asarray(par.standard(out.theta))
    res = tau - np.einsum("snp,p->sn", y, pi)
    history = np.asarray(out.history)[: int(out.steps)]
    return Estimate(pi, None, np.sqrt(np.mean(res * res, axis=0)), history)


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
    :func:`GradientDescent` are shorthands), also those with a line search such as ``optax.lbfgs()`` (each
    update gets ``value``, ``grad`` and ``value_fn``). The steps run in one compiled ``lax.scan``.
    """
    optimizer = optax.with_extra_args_support(optimizer or optax.adam(1e-2))
    value_and_grad = jax.value_and_grad(loss)

    @jit
    def run(theta0):
        def step(carry, _):
            theta, state = carry
            value, grads = value_and_grad(theta)
            updates, state = optimizer.update(grads, state, theta, value=value, grad=grads, value_fn=loss)
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
