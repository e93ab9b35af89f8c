"""Optimal excitation trajectories for identification: finite Fourier series within the joint limits whose base
regressor is as well conditioned as possible.

A :class:`FourierTrajectory` is the finite Fourier series of Swevers, Ganseman, Tükel, de Schutter & Van Brussel,
"Optimal robot excitation and identification", IEEE T-RA 13(5), 1997, eq. (7): for joint ``i``, with
``w = 2 pi / period``,

    q_i(t)   = q0_i + sum_l  a_il / (w l) sin(w l t) - b_il / (w l) cos(w l t),
    qd_i(t)  =        sum_l  a_il cos(w l t) + b_il sin(w l t),
    qdd_i(t) =        sum_l  w l (b_il cos(w l t) - a_il sin(w l t)),     l = 1 .. H,

periodic with the period (it starts and ends in the same state, so that it can be repeated and averaged).
:func:`design_excitation` samples it at ``samples`` times over one period, stacks the regressor there,
``W = [Y_b(q(t_k), qd(t_k), qdd(t_k))]_k`` (``samples * n`` rows, one column per base parameter,
:func:`~jaxskid.base_parameters`), and minimises ``log cond(W)`` (Gautier & Khalil, "Exciting trajectories for
the identification of base inertial parameters of robots", IJRR 11(4), 1992), or maximises ``log det(W^T W)``
(D-optimality, Swevers et al. 1997), over the coefficients with ``jax.grad`` and optax, from several random
starts at once (``jax.vmap``).

**Limits by construction.** Since ``|a sin x - b cos x| <= sqrt(a^2 + b^2)``, every ``t`` satisfies
``|q_i - q0_i| <= sum_l r_il / (w l)``, ``|qd_i| <= sum_l r_il`` and ``|qdd_i| <= sum_l w l r_il`` with
``r_il = sqrt(a_il^2 + b_il^2)`` (:meth:`FourierTrajectory.amplitude_bounds`). The optimiser works on free
coefficients that are mapped into the limits: each joint's ``a, b`` are scaled down until these bounds meet the
velocity, acceleration and half the position range, and ``q0`` moves inside what is left of the range
(``tanh``). Every trajectory tried, random starts included, thus satisfies the limits at every instant, not
only at the samples; the result is checked on a fine time grid anyway.

**Gradient.** Reverse mode through the generated regressor (hundreds of outputs, each a chain of selects)
compiles in minutes on CPU. The regressor's Jacobian with respect to the state ``(q, qd, qdd)`` is computed
instead by forward mode (``3 n`` directions per sample) and contracted with the criterion's cotangent in a
``jax.custom_vjp``: ``jax.grad`` of the criterion with respect to the coefficients is exact and compiles in
seconds.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..._errors import IdentificationError, RequestError, ShapeError
from ...runtime._dynamics import Dynamics
from ...runtime._jit import jit
from ._identification import BaseParameters, base_parameters

CRITERIA = ("cond", "logdet")
_LIMIT_KEYS = ("lower", "upper", "velocity", "acceleration")
_SHRINK = 1.0 - 1e-9
"""The amplitude bounds are met with this factor, so that round-off never crosses a limit."""


# ---------------------------------------------------------------------------------------- trajectory
@functools.partial(jax.tree_util.register_dataclass, data_fields=["q0", "a", "b"], meta_fields=["period"])
@dataclass(frozen=True)
class FourierTrajectory:
    """A finite Fourier series per joint (Swevers et al. 1997, eq. 7; see the module docstring).

    A pytree (``q0``, ``a``, ``b`` are its leaves, ``period`` is static), so it passes through ``jax.jit``,
    ``jax.vmap`` and ``jax.grad``.

    Attributes:
        q0: ``(n,)`` the offset: the mean position over a period (not ``q(0)``).
        a: ``(n, H)`` velocity amplitudes of the cosines, ``qd_i = sum_l a_il cos(w l t) + ...``.
        b: ``(n, H)`` velocity amplitudes of the sines.
        period: the fundamental period ``T = 2 pi / w`` (s), a float.
    """

    q0: jax.Array
    a: jax.Array
    b: jax.Array
    period: float

    @property
    def n_dof(self) -> int:
        return self.a.shape[0]

    @property
    def harmonics(self) -> int:
        return self.a.shape[1]

    def _check(self) -> None:
        n, h = np.shape(self.a)[0], np.shape(self.a)[-1]
        if np.ndim(self.a) != 2 or np.shape(self.b) != (n, h) or np.shape(self.q0) != (n,):
            raise ShapeError(f"FourierTrajectory: expected q0 (n,), a and b (n, H), got q0 {np.shape(self.q0)}, "
                             f"a {np.shape(self.a)}, b {np.shape(self.b)}")

    def _frequencies(self, dtype) -> jax.Array:
        """``w l`` for ``l = 1 .. H``, shape ``(H,)``."""
        return (2.0 * math.pi / self.period) * jnp.arange(1, self.harmonics + 1, dtype=dtype)

    def evaluate(self, t) -> tuple[jax.Array, jax.Array, jax.Array]:
        """``(q, qd, qdd)`` at the times ``t`` (any shape), each of shape ``t.shape + (n,)``."""
        self._check()
        dtype = jnp.result_type(self.q0, self.a, self.b, float)
        t = jnp.asarray(t, dtype)
        wl = self._frequencies(dtype)
        lead = (1,) * t.ndim
        phase = t[..., None, None] * wl.reshape(*lead, 1, -1)  # (..., 1, H)
        s, c = jnp.sin(phase), jnp.cos(phase)
        a, b, wl = (x.reshape(*lead, *x.shape) for x in (self.a, self.b, jnp.broadcast_to(wl, self.a.shape)))
        q = self.q0.reshape(*lead, -1) + jnp.sum((a * s - b * c) / wl, axis=-1)
        qd = jnp.sum(a * c + b * s, axis=-1)
        qdd = jnp.sum(wl * (b * c - a * s), axis=-1)
        return q, qd, qdd

    def amplitude_bounds(self) -> tuple[jax.Array, jax.Array, jax.Array]:
        """``(Q, V, A)``, each ``(n,)``: ``|q - q0| <= Q``, ``|qd| <= V`` and ``|qdd| <= A`` at every time
        (sums over the harmonics of ``r_il / (w l)``, ``r_il`` and ``w l r_il``, ``r_il = |(a_il, b_il)|``)."""
        self._check()
        r = _norm(self.a, self.b)
        wl = self._frequencies(r.dtype)[None, :]
        return jnp.sum(r / wl, axis=-1), jnp.sum(r, axis=-1), jnp.sum(r * wl, axis=-1)


def _norm(a, b):
    """``sqrt(a^2 + b^2)`` with a finite gradient at 0 (double ``where``)."""
    r2 = a * a + b * b
    positive = r2 > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, r2, 1.0)), 0.0)


# ---------------------------------------------------------------------------------------- result
@dataclass(frozen=True, eq=False)
class ExcitationResult:
    """What :func:`design_excitation` found.

    Attributes:
        trajectory: the best trajectory (NumPy leaves).
        criterion: ``"cond"`` or ``"logdet"``.
        value: the criterion of ``trajectory``: ``cond(W)`` or ``log det(W^T W)`` (of ``W`` with unit columns
            where ``normalize`` was asked for, as every value below).
        initial_best: the best criterion among the random starting trajectories.
        initial_median: their median.
        history: ``(starts, steps + 1)`` the criterion of every start before each step and after the last.
        start: the index of the start that gave ``trajectory``.
        times: ``(samples,)`` the sample times ``t_k = k T / samples``.
        base: the base parameters whose regressor columns ``W`` holds.
    """

    trajectory: FourierTrajectory
    criterion: str
    value: float
    initial_best: float
    initial_median: float
    history: np.ndarray
    start: int
    times: np.ndarray
    base: BaseParameters


# ---------------------------------------------------------------------------------------- design
def design_excitation(
    dyn: Dynamics,
    harmonics: int,
    period: float,
    samples: int,
    *,
    robot=None,
    limits: Mapping | None = None,
    starts: int = 8,
    steps: int = 200,
    seed: int = 0,
    criterion: str = "cond",
    base: BaseParameters | None = None,
    params=None,
    normalize: bool = False,
    optimizer: optax.GradientTransformation | None = None,
    check_points: int = 4096,
) -> ExcitationResult:
    """An excitation trajectory: the :class:`FourierTrajectory` with ``harmonics`` harmonics of ``period`` whose
    stacked base regressor ``W`` over ``samples`` times is best conditioned, within the joint limits.

    Args:
        dyn: a :class:`Dynamics` lowered with ``regressor``.
        harmonics: ``H``, the number of harmonics per joint.
        period: the fundamental period ``T`` (s).
        samples: the number of equally spaced times ``t_k = k T / samples`` stacked into ``W``
            (``samples * n`` rows, at least the number of base parameters).
        robot: the :class:`~jaxskid.Robot` of ``dyn``, whose :meth:`~jaxskid.Robot.limits` give the position and
            velocity limits (a URDF's ``<limit>``).
        limits: bounds that replace the robot's: keys ``lower``, ``upper``, ``velocity`` (``|qd|``) and
            ``acceleration`` (``|qdd|``), each a number or ``(n,)`` values (``inf``: none). Every joint needs
            ``lower < upper``, positive velocity and acceleration bounds, and one of the three finite.
        starts: random starting trajectories, optimised together (``jax.vmap``); the best is kept.
        steps, seed: the number of optimiser steps; the seed of the random starts.
        criterion: ``"cond"``: minimise ``log cond(W)`` (the classic criterion); ``"logdet"``: maximise
            ``log det(W^T W)``.
        base: the base parameters (default: :func:`~jaxskid.base_parameters` of ``dyn`` at ``params``).
        params: the (kinematic) parameter values the regressor is evaluated at.
        normalize: if True, ``W``'s columns are scaled to unit norm before the criterion (invariant to the
            parameters' units, but blind to how strongly each parameter is excited); the default, False, is the
            classic criterion: the condition number of the base regressor as it is.
        optimizer: an optax ``GradientTransformation`` (default: Adam, learning rate 0.1 decaying to 0 along a
            cosine over the steps); optimisers that take the loss (``optax.lbfgs()``) get ``value``, ``grad``
            and ``value_fn``.
        check_points: the fine time grid on which the result is checked against the limits.

    Returns:
        an :class:`ExcitationResult`.

    Raises:
        RequestError: ``dyn`` has no regressor, or an argument is out of range.
        ShapeError: a limit of the wrong shape.
        IdentificationError: ``W`` has rank below ``base.n_base`` at every start, or the result leaves a limit
            on the fine grid (which the construction of the module docstring rules out).
    """
    _check_request(dyn, harmonics, period, samples, starts, steps, criterion, check_points)
    bounds = _limits(dyn, robot, limits)
    base = base if base is not None else base_parameters(dyn, params)
    if samples * dyn.n_dof < base.n_base:
        raise RequestError(f"design_excitation: expected samples * n_dof >= {base.n_base} (the base parameters),"
                           f" got samples={samples} and n_dof={dyn.n_dof}; give more samples")
    p = dyn.param_vector(params)
    times = np.arange(samples) * (period / samples)
    to_traj = functools.partial(_feasible, bounds=tuple(jnp.asarray(x) for x in bounds), period=float(period))
    loss = _loss(_stacked_regressor(dyn.raw("regressor"), np.asarray(base.independent), p), to_traj, times,
                 criterion, normalize)
    optimizer = optimizer if optimizer is not None else optax.adam(optax.cosine_decay_schedule(0.1, max(steps, 1)))
    theta0 = _random_starts(jax.random.PRNGKey(seed), starts, dyn.n_dof, harmonics)
    best, history = _optimise(loss, theta0, optimizer, steps)
    k, history = _best_start(np.asarray(history), base.n_base)
    traj = jax.tree_util.tree_map(np.asarray, to_traj(jax.tree_util.tree_map(lambda x: x[k], best)))
    _check_limits(traj, bounds, check_points, dyn.joint_names)
    y = base.reduce(np.asarray(dyn.regressor(*traj.evaluate(times), p))).reshape(-1, base.n_base)
    report = _report(criterion)
    return ExcitationResult(
        trajectory=traj, criterion=criterion, value=_measure(y, criterion, normalize),
        initial_best=float(report(np.nanmin(history[:, 0]))), initial_median=float(report(np.median(history[:, 0]))),
        history=report(history), start=k, times=times, base=base,
    )


def _best_start(history: np.ndarray, n_base: int) -> tuple[int, np.ndarray]:
    """The start with the lowest score at any step, and the scores; :class:`IdentificationError` if no start
    ever had a finite one (``W`` of rank below ``n_base``)."""
    finals = np.where(np.isfinite(history), history, np.inf).min(axis=1)
    if not np.isfinite(finals).any():
        raise IdentificationError(f"design_excitation: W has rank below {n_base} (the base parameters) at every "
                                  f"start; give more samples or harmonics")
    return int(np.argmin(finals)), history


def _check_request(dyn, harmonics, period, samples, starts, steps, criterion, check_points) -> None:
    if not isinstance(dyn, Dynamics) or "regressor" not in dyn.quantities:
        lowered = ", ".join(dyn.quantities) if isinstance(dyn, Dynamics) else type(dyn).__name__
        raise RequestError(f"design_excitation: expected a Dynamics lowered with the quantity regressor, got {lowered}")
    for name, value, least in (("harmonics", harmonics, 1), ("samples", samples, 1), ("starts", starts, 1),
                               ("steps", steps, 0), ("check_points", check_points, 2)):
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < least:
            raise RequestError(f"design_excitation: expected an integer {name} >= {least}, got {value!r}")
    if not (isinstance(period, (int, float, np.floating)) and math.isfinite(period) and period > 0):
        raise RequestError(f"design_excitation: expected a positive finite period, got {period!r}")
    if criterion not in CRITERIA:
        raise RequestError(f"design_excitation: expected criterion one of {', '.join(CRITERIA)}, got {criterion!r}")


def _limits(dyn: Dynamics, robot, limits: Mapping | None) -> tuple[np.ndarray, ...]:
    """``(lower, upper, velocity, acceleration)``, each ``(n,)``: the robot's, replaced by ``limits``."""
    n, names = dyn.n_dof, tuple(dyn.joint_names)
    inf = np.full(n, np.inf)
    values = {"lower": -inf, "upper": inf, "velocity": inf, "acceleration": inf}
    if robot is not None:
        if not callable(getattr(robot, "limits", None)) or tuple(robot.joint_names) != names:
            raise RequestError(f"design_excitation: expected robot= the Robot of dyn (joints {', '.join(names)}), "
                               f"got {getattr(robot, 'joint_names', type(robot).__name__)}")
        values.update(zip(("lower", "upper", "velocity"), robot.limits()[:3]))
    unknown = sorted(set(limits or {}) - set(_LIMIT_KEYS))
    if unknown:
        raise RequestError(f"design_excitation: unknown limit(s) {', '.join(unknown)}; expected "
                           f"{', '.join(_LIMIT_KEYS)}")
    for key, value in (limits or {}).items():
        array = np.asarray(value, dtype=float)
        if array.shape not in ((), (n,)):
            raise ShapeError(f"design_excitation: limits[{key!r}]: expected a number or shape ({n},), got "
                             f"{array.shape}")
        values[key] = np.broadcast_to(array, (n,)).copy()
    lower, upper, vel, acc = (values[k] for k in _LIMIT_KEYS)
    problems = [
        ("lower < upper", ~(lower < upper)),
        ("a positive velocity limit", ~(vel > 0)),
        ("a positive acceleration limit", ~(acc > 0)),
        ("a finite position range, velocity or acceleration limit",
         ~(np.isfinite(upper - lower) | np.isfinite(vel) | np.isfinite(acc))),
    ]
    for what, bad in problems:
        if bad.any():
            joints = ", ".join(f"{names[i]} (lower {lower[i]}, upper {upper[i]}, velocity {vel[i]}, acceleration "
                               f"{acc[i]})" for i in np.flatnonzero(bad))
            raise RequestError(f"design_excitation: expected {what} for every joint, got {joints}; "
                               f"give limits={{'lower': ..., 'upper': ..., 'velocity': ..., 'acceleration': ...}}")
    return lower, upper, vel, acc


def _feasible(theta, *, bounds, period: float) -> FourierTrajectory:
    """The trajectory of the free coefficients ``theta = (c, ra, rb)`` within the limits (module docstring):
    ``(a, b) = s (ra, rb)`` with ``s`` the largest factor <= 1 whose amplitude bounds meet the velocity,
    acceleration and half the position range, and ``q0 = mid + (half - Q) tanh(c)``."""
    c, ra, rb = theta
    lower, upper, vel, acc = bounds
    raw = FourierTrajectory(jnp.zeros_like(c), ra, rb, period)
    q_r, v_r, a_r = raw.amplitude_bounds()
    finite = jnp.isfinite(upper - lower)
    half = jnp.where(finite, 0.5 * (upper - lower), jnp.inf)
    mid = jnp.where(finite, 0.5 * (jnp.where(finite, upper, 0.0) + jnp.where(finite, lower, 0.0)), 0.0)

    def ratio(bound, value):  # bound / value, inf where value is 0 (no gradient through the guard)
        positive = value > 0
        return jnp.where(positive, bound / jnp.where(positive, value, 1.0), jnp.inf)

    s = _SHRINK * jnp.minimum(1.0, jnp.minimum(jnp.minimum(ratio(half, q_r), ratio(vel, v_r)), ratio(acc, a_r)))
    room = jnp.where(finite, _SHRINK * (jnp.where(finite, half, 0.0) - s * q_r), 0.0)
    q0 = jnp.where(finite, mid + room * jnp.tanh(c), c)
    return FourierTrajectory(q0, s[:, None] * ra, s[:, None] * rb, period)


def _random_starts(key, starts: int, n: int, harmonics: int):
    """Free coefficients of ``starts`` random trajectories: ``c ~ N(0, 0.5^2)``, ``ra, rb ~ N(0, 1)``."""
    kc, ka, kb = jax.random.split(key, 3)
    shape = (starts, n, harmonics)
    return (0.5 * jax.random.normal(kc, (starts, n)), jax.random.normal(ka, shape), jax.random.normal(kb, shape))


def _stacked_regressor(raw: Callable, columns: np.ndarray, p) -> Callable:
    """``stack(q, qd, qdd) -> (samples, n, n_base)``: the base columns of the regressor at every sample, with a
    VJP from the forward-mode Jacobian with respect to the state (see the module docstring)."""

    def one(x):  # x = (q, qd, qdd) concatenated, (3n,)
        n = x.shape[0] // 3
        return raw(x[:n], x[n:2 * n], x[2 * n:], p)[:, columns]

    def with_jacobian(x):  # (n, n_base) and (n, n_base, 3n) from one program: the JVP along every direction
        return jax.vmap(lambda v: jax.jvp(one, (x,), (v,)), out_axes=(None, -1))(jnp.eye(x.shape[0], dtype=x.dtype))

    @jax.custom_vjp
    def rows(x):
        return jax.vmap(one)(x)

    def fwd(x):
        return jax.vmap(with_jacobian)(x)  # (samples, n, n_base), (samples, n, n_base, 3n)

    def bwd(jac, g):
        return (jnp.einsum("sijk,sij->sk", jac, g),)

    rows.defvjp(fwd, bwd)

    def stack(q, qd, qdd):
        return rows(jnp.concatenate([q, qd, qdd], axis=-1))

    return stack


def _loss(stack: Callable, to_traj: Callable, times, criterion: str, normalize: bool) -> Callable:
    """``loss(theta)``, the score minimised over the free coefficients: ``log cond(W)`` or ``-log det(W^T W)``
    of the trajectory ``to_traj(theta)``."""
    times = jnp.asarray(times)

    def loss(theta):
        w = stack(*to_traj(theta).evaluate(times))
        w = w.reshape(-1, w.shape[-1])
        if normalize:
            w = w / jnp.sqrt(jnp.sum(w * w, axis=0, keepdims=True))
        sv = jnp.linalg.svd(w, compute_uv=False)
        if criterion == "cond":
            return jnp.log(sv[0]) - jnp.log(sv[-1])
        return -2.0 * jnp.sum(jnp.log(sv))

    return loss


def _report(criterion: str) -> Callable:
    """The reported criterion from the score: ``cond(W) = exp(score)`` or ``log det(W^T W) = -score``."""
    return np.exp if criterion == "cond" else np.negative


def _measure(y: np.ndarray, criterion: str, normalize: bool) -> float:
    """``cond(y)`` or ``log det(y^T y)``, of ``y`` with unit columns if ``normalize``."""
    sv = np.linalg.svd(y / np.linalg.norm(y, axis=0) if normalize else y, compute_uv=False)
    return float(sv[0] / sv[-1]) if criterion == "cond" else float(2.0 * np.sum(np.log(sv)))


def _optimise(loss: Callable, theta0, optimizer, steps: int):
    """Every start (leading axis of ``theta0``) optimised for ``steps`` steps under ``jax.vmap``: the best
    coefficients seen and the scores ``(starts, steps + 1)``."""
    value_and_grad = jax.value_and_grad(loss)

    def one(theta):
        def step(carry, _):
            theta, state, best, best_value = carry
            value, grad = value_and_grad(theta)
            better = value < best_value  # nan (rank-deficient W) is never better
            best = jax.tree_util.tree_map(lambda b, t: jnp.where(better, t, b), best, theta)
            best_value = jnp.where(better, value, best_value)
            grad = jax.tree_util.tree_map(lambda g: jnp.where(jnp.isfinite(g), g, 0.0), grad)
            updates, state = optimizer.update(grad, state, theta, value=value, grad=grad, value_fn=loss)
            return (optax.apply_updates(theta, updates), state, best, best_value), value

        init = (theta, optimizer.init(theta), theta, jnp.asarray(jnp.inf, jnp.result_type(float)))
        (theta, _, best, best_value), history = jax.lax.scan(step, init, None, length=steps)
        last = loss(theta)
        better = last < best_value
        best = jax.tree_util.tree_map(lambda b, t: jnp.where(better, t, b), best, theta)
        return best, jnp.concatenate([history, last[None]])

    return jit(jax.vmap(one))(theta0)


def _check_limits(traj: FourierTrajectory, bounds, points: int, names) -> None:
    """Raise :class:`IdentificationError` if ``traj`` leaves a limit anywhere on ``points`` times of a period."""
    q, qd, qdd = (np.asarray(x) for x in traj.evaluate(np.linspace(0.0, traj.period, points)))
    lower, upper, vel, acc = bounds
    excess = {
        "lower position limit": lower - q.min(axis=0),
        "upper position limit": q.max(axis=0) - upper,
        "velocity limit": np.abs(qd).max(axis=0) - vel,
        "acceleration limit": np.abs(qdd).max(axis=0) - acc,
    }
    for what, over in excess.items():
        if (over > 0).any():
            i = int(np.argmax(over))
            raise IdentificationError(f"design_excitation: the trajectory exceeds joint {names[i]}'s {what} by "
                                      f"{over[i]:.3g} on the check grid")
