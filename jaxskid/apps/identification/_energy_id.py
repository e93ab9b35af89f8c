"""Identification from the energy balance: the standard parameters without joint accelerations.

Along any motion the joint forces' work goes into the energy ``H = K + U`` and the drives' friction
(Gautier & Khalil, "On the identification of the inertial parameters of robots", CDC 1988; Gautier,
"Dynamic identification of robots with power model", ICRA 1997):

    H(t1) - H(t0) + int_t0^t1 qd^T (fv qd + fc sign(qd) + fo) dt = int_t0^t1 qd^T tau dt,

and every term is linear in the standard parameters ``pi`` (:func:`jaxskid.standard_params`): with the rows
``y_K``, ``y_U`` and ``y_P`` of the lowered quantities ``kinetic_energy_regressor``,
``potential_energy_regressor`` and ``friction_power_regressor`` (:mod:`jaxskid.symbolic._energy_regressor`),

    a = (y_K + y_U)(t1) - (y_K + y_U)(t0) + int y_P dt,   b = int qd^T tau dt,   a pi = b.

:func:`energy_balance` forms one such row per window of samples, the integrals by the trapezoid rule, from
measured ``q``, ``qd`` and ``tau`` only: no accelerations, and no differentiation of noisy velocities.

**Identifiable parameters.** A combination ``pi`` drops out of every window exactly when ``H(q, qd) pi`` is
constant and its friction power vanishes; differentiating along all motions, ``qd^T Y pi = 0`` for every
``(q, qd, qdd)`` (``Y`` the torque regressor), so ``M(pi) = 0`` (the ``qdd`` terms), then ``Q_grav(pi) = 0``
and the friction terms vanish: ``Y pi = 0``. The energy rows therefore have the torque model's base parameters
(:func:`jaxskid.base_parameters` of ``dyn.regressor``), given motions rich enough. What only the undifferenced
rows hold is a constant: the energy rows ``y_K + y_U`` themselves have columns that no difference sees (e.g.
the potential energy of a first body that turns about a vertical axis, ``-m g . p`` with ``p`` fixed), so the
base parameters must come from the differenced rows that :func:`energy_balance` returns (or from the torque
regressor), never from ``y_K + y_U`` sampled at single states. A single trajectory may excite fewer
combinations: ``jaxskid.base_parameters(balance.y)`` finds those it does.

**The momentum balance.** The energy balance gives one scalar equation per window. Integrating the equations
of motion themselves over a window gives n: with the generalized momentum ``p = M(q) qd`` (armature included)
and ``M qdd = dp/dt - Mdot qd``,

    p(t1) - p(t0) + int_t0^t1 (C(q, qd) qd + Q_grav(q) - Mdot(q, qd) qd + friction) dt = int_t0^t1 tau dt,

the integrand being ``Q_grav - C^T qd + friction`` (``Mdot = C + C^T``), the quantity a generalized-momentum
observer integrates (De Luca & Mattone, "Sensorless robot collision detection and hybrid force/motion
control", ICRA 2005). With the momentum regressor ``Y_p`` (``momentum_regressor``) and the torque regressor at
zero acceleration, each term is linear in ``pi``: ``Mdot(q, qd) qd = (d Y_p / dq . qd) pi`` is the derivative of
``Y_p`` along ``q`` in the direction ``qd`` with ``qd`` held, a Jacobian-vector product of a closed-form
quantity, so no acceleration enters. :func:`momentum_balance` forms these rows. They hold the torque model's
identifiable combinations by the argument above (every combination ``Y pi = 0`` along all motions drops out,
and the rows' derivative is ``Y pi``), with n equations per window, and the torque noise averaged over the
window instead of integrated into one work.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import numpy as np

from ..._errors import RequestError, ShapeError
from ...runtime._dynamics import Dynamics

ENERGY_QUANTITIES = ("kinetic_energy_regressor", "potential_energy_regressor", "friction_power_regressor")
"""What :func:`energy_balance` evaluates (``friction_power_regressor`` only for a robot with drives)."""

MOMENTUM_QUANTITIES = ("momentum_regressor", "regressor")
"""What :func:`momentum_balance` evaluates."""


class EnergyBalance(NamedTuple):
    """The linear system ``y pi = work`` of the energy balance, one equation per window, shaped for
    :func:`jaxskid.identify` (``identify(base.reduce(balance.y), balance.work)``).

    ``y``: ``(windows, 1, p)``, each window's change of ``y_K + y_U`` plus the integral of ``y_P``;
    ``work``: ``(windows, 1)``, the work ``int qd^T tau dt`` of the joint forces over the window;
    (:func:`momentum_balance`: ``y (windows, n, p)`` and the impulses ``int tau dt``, ``(windows, n)``);
    ``start``, ``stop``: ``(windows,)``, the indices of each window's first and last sample.
    """

    y: np.ndarray
    work: np.ndarray
    start: np.ndarray
    stop: np.ndarray


def _cumulative_trapezoid(t: np.ndarray, f: np.ndarray) -> np.ndarray:
    """``F[k] = int_t0^tk f dt`` by the trapezoid rule over the samples, ``F[0] = 0``; ``f`` is ``(N, ...)``."""
    dt = np.diff(t).reshape((-1,) + (1,) * (f.ndim - 1))
    steps = dt * (f[1:] + f[:-1]) / 2
    return np.concatenate([np.zeros_like(f[:1]), np.cumsum(steps, axis=0)])


def _check(dyn: Dynamics, t, q, qd, tau, window, caller="energy_balance", quantities=None) -> tuple[np.ndarray, ...]:
    quantities = ENERGY_QUANTITIES[: 3 if dyn.driven else 2] if quantities is None else quantities
    needed = [k for k in quantities if k not in dyn.quantities]
    if needed:
        raise RequestError(
            f"{caller} needs the quantities {', '.join(needed)}; lowered: {', '.join(dyn.quantities)}. "
            f"Lower them with jaxskid.lower(robot, [..., {', '.join(map(repr, needed))}])")
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.shape[0] < 2:
        raise ShapeError(f"{caller}: expected sample times t of shape (N,) with N >= 2, got {t.shape}")
    arrays = []
    for name, x in (("q", q), ("qd", qd), ("tau", tau)):
        x = np.asarray(x, dtype=float)
        if x.shape != (t.shape[0], dyn.n_dof):
            raise ShapeError(f"{caller}: expected {name} of shape ({t.shape[0]}, {dyn.n_dof}) "
                             f"(samples of t, joints), got {x.shape}")
        arrays.append(x)
    if not np.all(np.diff(t) > 0):
        raise ShapeError(f"{caller}: the sample times t must increase strictly")
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or not 2 <= window <= t.shape[0]:
        raise RequestError(f"{caller}: window: expected an integer number of samples in [2, {t.shape[0]}], "
                           f"got {window!r}")
    return (t, *arrays)


def energy_balance(dyn: Dynamics, t, q, qd, tau, params=None, *, window: int) -> EnergyBalance:
    """The energy-balance equations ``y pi = work`` of sampled motions, one per window of samples.

    Window k holds the ``window`` samples ``k (window - 1), ..., (k + 1)(window - 1)``: consecutive windows
    share their end sample, so the windows tile the samples and their rows sum to the balance of the whole
    record (samples after the last whole window are left out). Per window (module docstring):
    ``y = (y_K + y_U)(stop) - (y_K + y_U)(start) + int y_P dt`` and ``work = int qd^T tau dt``, both
    integrals by the trapezoid rule on the sample times (accurate to O(dt^2): the torques must be sampled
    with the motion, e.g. ``tau(t_k)`` of a smooth policy, not held over steps). The friction power's columns
    follow the dynamics' Coulomb shape, ``sign`` or ``tanh(qd / eps)`` under ``Options(friction_smoothing=eps)``.

    Args:
        dyn: lowered with ``kinetic_energy_regressor``, ``potential_energy_regressor`` and, for a robot with
            drives, ``friction_power_regressor`` (:data:`ENERGY_QUANTITIES`).
        t: ``(N,)`` sample times, strictly increasing (not necessarily evenly spaced).
        q, qd, tau: ``(N, n)`` joint positions, velocities and forces at those times.
        params: the (kinematic) parameter values the rows are evaluated at, as for any quantity.
        window: samples per window, at least 2 (2: one equation per sample interval).

    Returns:
        an :class:`EnergyBalance`: ``y (windows, 1, p)`` over the standard parameters (``p`` as the
        regressor's) and ``work (windows, 1)``. ``base = jaxskid.base_parameters(balance.y)`` and then
        ``jaxskid.identify(base.reduce(balance.y), balance.work)`` estimate the base parameters.

    Raises:
        RequestError: a quantity above was not lowered, or ``window`` is not an integer in ``[2, N]``.
        ShapeError: ``t``, ``q``, ``qd`` or ``tau`` of the wrong shape, or ``t`` not increasing.
    """
    t, q, qd, tau = _check(dyn, t, q, qd, tau, window)
    energy = np.asarray(dyn.kinetic_energy_regressor(q, qd, params)) + np.asarray(
        dyn.potential_energy_regressor(q, params))
    dissipated = np.zeros_like(energy)
    if dyn.driven:
        dissipated = _cumulative_trapezoid(t, np.asarray(dyn.friction_power_regressor(q, qd, params)))
    work = _cumulative_trapezoid(t, np.sum(qd * tau, axis=-1))
    start, stop = _windows(t.shape[0], window)
    y = energy[stop] - energy[start] + dissipated[stop] - dissipated[start]
    return EnergyBalance(y[:, None, :], (work[stop] - work[start])[:, None], start, stop)


def _windows(n_samples: int, window: int) -> tuple[np.ndarray, np.ndarray]:
    """The first and last sample of each window of ``window`` samples, consecutive windows sharing an end."""
    start = np.arange((n_samples - 1) // (window - 1)) * (window - 1)
    return start, start + window - 1


def momentum_balance(dyn: Dynamics, t, q, qd, tau, params=None, *, window: int) -> EnergyBalance:
    """The momentum-balance equations ``y pi = impulse`` of sampled motions, n per window of samples.

    Per window (module docstring): ``y = Y_p(stop) - Y_p(start) + int (Y(q, qd, 0) - dY_p/dq . qd) dt`` and
    ``impulse = int tau dt``, the integrals by the trapezoid rule; the windows as in :func:`energy_balance`.
    No accelerations enter: ``Y_p`` is ``momentum_regressor`` and ``dY_p/dq . qd`` its Jacobian-vector product.

    Args:
        dyn: lowered with ``momentum_regressor`` and ``regressor`` (:data:`MOMENTUM_QUANTITIES`).
        t: ``(N,)`` sample times, strictly increasing.
        q, qd, tau: ``(N, n)`` joint positions, velocities and forces at those times.
        params: the (kinematic) parameter values the rows are evaluated at.
        window: samples per window, at least 2.

    Returns:
        an :class:`EnergyBalance` whose ``y`` is ``(windows, n, p)`` and whose ``work`` holds the impulses
        ``(windows, n)``: ``jaxskid.identify(base.reduce(balance.y), balance.work)`` as for the energy balance.

    Raises:
        RequestError: a quantity above was not lowered, or ``window`` is not an integer in ``[2, N]``.
        ShapeError: ``t``, ``q``, ``qd`` or ``tau`` of the wrong shape, or ``t`` not increasing.
    """
    t, q, qd, tau = _check(dyn, t, q, qd, tau, window, "momentum_balance", MOMENTUM_QUANTITIES)
    momentum, transport = jax.jvp(lambda x: dyn.momentum_regressor(x, qd, params), (q,), (qd,))
    rest = np.asarray(dyn.regressor(q, qd, np.zeros_like(qd), params)) - np.asarray(transport)
    momentum, rest = np.asarray(momentum), _cumulative_trapezoid(t, rest)
    impulse = _cumulative_trapezoid(t, tau)
    start, stop = _windows(t.shape[0], window)
    y = momentum[stop] - momentum[start] + rest[stop] - rest[start]
    return EnergyBalance(y, impulse[stop] - impulse[start], start, stop)
