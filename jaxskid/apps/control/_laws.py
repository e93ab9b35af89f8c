"""Joint-space controllers for :func:`jaxskid.rollout`: computed torque, PD plus gravity compensation and
the Slotine-Li adaptive controller.

A reference is a function ``q_d(t)`` (shape ``(n,)``) that JAX can differentiate; its velocity and
acceleration are taken by forward-mode differentiation, so only positions are written. Gains are scalars or
vectors ``(n,)`` (diagonal gains); ``gamma`` of :class:`SlotineLi` is a scalar or one value per parameter.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from ..._errors import RequestError, ShapeError
from ...runtime._dynamics import Dynamics
from ..simulation import Controller


def reference_derivatives(reference: Callable, t) -> tuple[jax.Array, jax.Array, jax.Array]:
    """``(q_d, qd_d, qdd_d)``: a reference ``q_d(t)`` and its first two time derivatives at time ``t``.

    ``reference`` maps a scalar time to positions ``(n,)`` and must be differentiable by JAX; the
    derivatives are taken by nested forward-mode differentiation (``jax.jvp`` of ``jax.jvp``), exactly, with
    no finite differences. ``jax.vmap`` over ``t`` gives a whole trajectory: ``(T, n)`` each.
    """
    t = jnp.asarray(t)

    def position_velocity(s):
        return jax.jvp(reference, (s,), (jnp.ones_like(s),))

    (q, v), (_, a) = jax.jvp(position_velocity, (t,), (jnp.ones_like(t),))
    return q, v, a


def _as_reference(reference) -> Callable:
    if callable(reference):
        return reference
    setpoint = jnp.asarray(reference)
    return lambda t: setpoint + 0.0 * t


def _needs(dyn: Dynamics, names, who: str) -> None:
    missing = [k for k in names if k not in dyn.quantities]
    if missing:
        raise RequestError(f"{who} needs the quantities {', '.join(names)}; {', '.join(missing)} not lowered "
                           f"(lowered: {', '.join(dyn.quantities)})")


def _split(x):
    """``(q, qd)`` of a state ``x``: ``q`` is its first ``(len(x) + 1) // 2`` entries (``nq = nv + 1`` with a
    floating base, ``nq = nv`` without)."""
    n = (x.shape[-1] + 1) // 2
    return x[:n], x[n:]


TRACKING_ARGS = """
    Args:
        dyn: the lowered model the law computes with.
        reference: the desired joint positions, a function ``q_d(t) -> (n,)`` that JAX can differentiate twice
            (its velocity and acceleration are taken by forward mode), or a constant set-point ``(n,)``.
        kp, kd: position and velocity gains, scalars or one per joint ``(n,)``.
        params: the parameters of the law's model (``None``: the defaults); they may differ from the rollout's
            (the plant's), and may be traced (identification, adaptive control).
"""


class _Tracking(Controller):
    """A stateless tracking law with diagonal gains ``kp``, ``kd`` and the model's parameters ``params``
    (arguments: :data:`TRACKING_ARGS`)."""

    def __init__(self, dyn: Dynamics, reference, kp, kd, params=None):
        self.reference = _as_reference(reference)
        self.kp, self.kd = jnp.asarray(kp), jnp.asarray(kd)
        self.dyn, self.params = dyn, params

    def _errors(self, t, x):
        """``(q, qd, p, e, ed, qdd_d)``: the state, the parameter vector, the errors ``e = q_d - q`` and
        ``ed = qd_d - qd``, and the reference acceleration."""
        q, qd = _split(x)
        qr, vr, ar = reference_derivatives(self.reference, t)
        return q, qd, self.dyn.param_vector(self.params, x.dtype), qr - q, vr - qd, ar


class ComputedTorque(_Tracking):
    """Computed-torque (inverse-dynamics) control (Lynch & Park 2017, eq. 11.35):

        tau = M(q) (qdd_d + kd (qd_d - qd) + kp (q_d - q)) + C(q, qd) qd + Q_grav(q),

    one ``inverse_dynamics`` call. With the exact model the error ``e = q_d - q`` obeys
    ``edd + kd ed + kp e = 0``.
    """

    def __init__(self, dyn: Dynamics, reference, kp, kd, params=None):
        _needs(dyn, ("inverse_dynamics",), "ComputedTorque")
        super().__init__(dyn, reference, kp, kd, params)
        self.rnea = dyn.raw("inverse_dynamics")

    def __call__(self, t, x, z):
        q, qd, p, e, ed, ar = self._errors(t, x)
        return self.rnea(q, qd, ar + self.kd * ed + self.kp * e, p), ()


class PDGravity(_Tracking):
    """PD control with gravity compensation (Lynch & Park 2017, eq. 11.33; Takegaki & Arimoto 1981):

        tau = kp (q_d - q) + kd (qd_d - qd) + Q_grav(q).

    For a constant set-point ``q_d`` the closed loop converges to it from any state (Lyapunov function
    ``1/2 qd^T M qd + 1/2 kp |q_d - q|^2``).
    """

    def __init__(self, dyn: Dynamics, reference, kp, kd, params=None):
        super().__init__(dyn, reference, kp, kd, params)
        if "gravity_torques" in dyn.quantities:
            self.gravity = dyn.raw("gravity_torques")
        else:
            _needs(dyn, ("inverse_dynamics",), "PDGravity (without gravity_torques)")
            rnea = dyn.raw("inverse_dynamics")
            self.gravity = lambda q, p: rnea(q, jnp.zeros_like(q), jnp.zeros_like(q), p)

    def __call__(self, t, x, z):
        q, _, p, e, ed, _ = self._errors(t, x)
        return self.kp * e + self.kd * ed + self.gravity(q, p), ()


ComputedTorque.__doc__ += TRACKING_ARGS
PDGravity.__doc__ += TRACKING_ARGS


def mixed_regressor(dyn: Dynamics, q, qd, v, a, params=None) -> jax.Array:
    """``Y(q, qd, v, a)`` with ``M(q) a + C(q, qd) v + Q_grav(q) = Y(q, qd, v, a) pi`` (n, 10 n_bodies).

    ``C`` is the Christoffel Coriolis matrix, the one with ``dM/dt - 2C`` skew-symmetric that the
    Slotine-Li proof needs. Its symmetry ``C(q, x) y = C(q, y) x`` gives ``C(q, qd) v`` by polarisation of
    ``c(q, w) = C(q, w) w``: ``C(q, qd) v = (c(qd + v) - c(qd) - c(v)) / 2``, so the mixed regressor is a
    combination of five evaluations of the ordinary regressor ``Y(q, qd, qdd)``:

        Y(q, 0, a) + (Y(q, qd + v, 0) - Y(q, qd, 0) - Y(q, v, 0) + Y(q, 0, 0)) / 2.

    With drives, their columns (after the 10 per body) are those of ``Y(q, qd, a)``: the model is then
    ``... + Ia a + fv qd + fc sign(qd) + fo`` (n, 10 n_bodies + 4 n_driven).
    """
    _needs(dyn, ("regressor",), "mixed_regressor")
    p = dyn.param_vector(params, jnp.result_type(q, qd, v, a))
    return _mixed(dyn.raw("regressor"), q, qd, v, a, p)


def _mixed(reg, q, qd, v, a, p):
    zero = jnp.zeros_like(q)
    vel = jnp.stack([zero, qd + v, qd, v, zero])
    acc = jnp.stack([a, zero, zero, zero, zero])
    ys = jax.vmap(reg, in_axes=(None, 0, 0, None))(q, vel, acc, p)
    y = ys[0] + 0.5 * (ys[1] - ys[2] - ys[3] + ys[4])
    bodies = 10 * q.shape[-1]
    if y.shape[-1] > bodies:  # drives (Ia, fv, fc, fo): the columns (a, qd, sign(qd), 1) of Y(q, qd, a)
        y = y.at[..., bodies:].set(reg(q, qd, a, p)[..., bodies:])
    return y


class SlotineLi(Controller):
    """The Slotine-Li adaptive controller (Slotine & Li, "On the adaptive control of robot manipulators",
    IJRR 6(3), 1987; Lynch & Park 2017, sec. 11.4.3):

        e = q - q_d,   v = qd_d - lam e,   s = qd - v,
        tau = Y(q, qd, v, dv/dt) pi_hat - kd s,         d pi_hat / dt = -gamma Y^T s,

    with :func:`mixed_regressor` ``Y``. ``V = 1/2 s^T M s + 1/2 (pi_hat - pi)^T gamma^-1 (pi_hat - pi)``
    never increases (``dV/dt = -s^T kd s``), so ``s`` and the tracking error go to zero; the estimates
    converge to the true base parameters under persistent excitation.

    The controller's state ``z`` is ``pi_hat``. With ``base`` (a :class:`~jaxskid.BaseParameters`) the
    estimate is of the base parameters and the reduced regressor is used.

    Args:
        dyn: lowered with ``regressor``.
        reference: the desired joint positions, a function ``q_d(t) -> (n,)`` that JAX can differentiate twice
            (its velocity and acceleration are taken by forward mode), or a constant set-point ``(n,)``.
        estimate: the initial ``pi_hat``, ``(n_params,)`` (``(n_base,)`` with ``base``).
        lam: ``lam``, the gain of the position error in the reference velocity ``v``.
        kd: the gain of ``s`` in the torque.
        gamma: the adaptation gain (a scalar, or ``(n_params,)`` per parameter).
        base: a :class:`~jaxskid.BaseParameters` to estimate the base parameters; ``None``: all of them.
        params: the parameters of the regressor's constants (``None``: the defaults).
    """

    def __init__(self, dyn: Dynamics, reference, estimate, *, lam, kd, gamma, base=None, params=None):
        _needs(dyn, ("regressor",), "SlotineLi")
        self.reg = dyn.raw("regressor")
        self.reference = _as_reference(reference)
        self.estimate = jnp.asarray(estimate)
        width = base.n_base if base is not None else dyn.signature("regressor")[1][-1]
        if self.estimate.shape != (width,):
            raise ShapeError(f"SlotineLi: estimate: expected shape ({width},), got {self.estimate.shape}")
        self.lam, self.kd, self.gamma = jnp.asarray(lam), jnp.asarray(kd), jnp.asarray(gamma)
        self.base, self.dyn, self.params = base, dyn, params

    def init(self, x0):
        return self.estimate.astype(x0.dtype)

    def regressor(self, t, x):
        """``(Y, s)`` at time t and state x (Y reduced to the base parameters if ``base`` was given)."""
        q, qd = _split(x)
        qr, vr, ar = reference_derivatives(self.reference, t)
        e, ed = q - qr, qd - vr
        v = vr - self.lam * e
        a = ar - self.lam * ed
        y = _mixed(self.reg, q, qd, v, a, self.dyn.param_vector(self.params, x.dtype))
        if self.base is not None:
            y = self.base.reduce(y)
        return y, qd - v

    def __call__(self, t, x, z):
        y, s = self.regressor(t, x)
        tau = y @ z - self.kd * s
        return tau, -self.gamma * (s @ y)
