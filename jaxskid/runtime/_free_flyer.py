"""The configuration space of a floating-base robot: integration and difference on SE(3) x R^n.

A floating-base configuration is ``q = (p, quat, q_j)``: the base position ``p`` in the world, its unit
quaternion ``quat = (x, y, z, w)`` and the joint positions (Pinocchio's layout). Its velocity is
``v = (omega, v_b, qd_j)``: the base twist in the base frame (angular first, as everywhere in jaxskid) and the
joint velocities. So ``nq = 7 + n`` and ``nv = 6 + n``; a fixed-base robot has ``q`` and ``v`` of one size and
the flat operations ``q + v dt``, ``q1 - q0``.

* :func:`integrate` ``(q, v, dt)``: the base moves along the one-parameter subgroup of its twist,
  ``g(dt) = g exp(dt V)`` (Lynch & Park, "Modern Robotics", 2017, eq. 3.88 for exp on SE(3)), the joints
  by ``q_j + dt qd_j``; this is Pinocchio's ``integrate`` for a ``JointModelFreeFlyer``.
* :func:`difference` ``(q0, q1)``: its inverse, ``V = log(g0^-1 g1)`` (Modern Robotics, Alg. 3.2 and
  eq. 3.92), ``q1_j - q0_j``; Pinocchio's ``difference``.
* :func:`configuration_rate` ``(q, v)``: ``dq/dt`` in the embedding, ``dp/dt = R v_b``,
  ``dquat/dt = quat * (omega, 0) / 2``, which a Runge-Kutta step integrates with the quaternion renormalised
  after the step (:func:`normalize`).

A quaternion that is not unit-norm is read as the rotation of its normalised value. Near zero angles the
series of ``sin`` and ``cos`` quotients are selected with a second ``where`` on safe arguments, so gradients
stay finite at ``omega = 0`` (``jaxlie/_so3.py`` does the same).
"""

from __future__ import annotations

import jax.numpy as jnp

_SMALL = 1e-4
"""Below this angle (rad) the quotients of sin and cos are taken from their Taylor series."""


# ---------------------------------------------------------------------------------------------- quaternions
def quaternion_multiply(a, b):
    """Hamilton product ``a b`` of quaternions stored ``(x, y, z, w)``, shape ``(..., 4)``."""
    av, aw = a[..., :3], a[..., 3:]
    bv, bw = b[..., :3], b[..., 3:]
    vec = aw * bv + bw * av + jnp.cross(av, bv)
    w = aw * bw - jnp.sum(av * bv, axis=-1, keepdims=True)
    return jnp.concatenate([vec, w], axis=-1)


def quaternion_conjugate(a):
    return jnp.concatenate([-a[..., :3], a[..., 3:]], axis=-1)


def rotate(quat, x):
    """``R(quat) x`` for a unit quaternion ``(x, y, z, w)`` and a 3-vector."""
    u, w = quat[..., :3], quat[..., 3:]
    t = 2.0 * jnp.cross(u, x)
    return x + w * t + jnp.cross(u, t)


def _taylor_select(theta2, exact, series):
    """``exact(theta2)`` away from zero, ``series(theta2)`` near it, with finite gradients at zero."""
    small = theta2 < _SMALL**2
    safe = jnp.where(small, 1.0, theta2)
    return jnp.where(small, series(theta2), exact(safe))


def _exp_so3_quaternion(omega):
    """The unit quaternion of ``exp(omega^)``: ``(sin(t/2) omega/t, cos(t/2))`` with ``t = |omega|``."""
    t2 = jnp.sum(omega * omega, axis=-1, keepdims=True)
    half_sinc = _taylor_select(t2, lambda s: jnp.sin(jnp.sqrt(s) / 2) / jnp.sqrt(s),
                               lambda s: 0.5 - s / 48 + s * s / 3840)
    cos_half = _taylor_select(t2, lambda s: jnp.cos(jnp.sqrt(s) / 2), lambda s: 1 - s / 8 + s * s / 384)
    return jnp.concatenate([half_sinc * omega, cos_half], axis=-1)


def _left_jacobian_apply(omega, v, sign: float = 1.0):
    """``V(omega) v = v + sign (1 - cos t)/t^2 omega x v + (t - sin t)/t^3 omega x (omega x v)``
    (Modern Robotics, eq. 3.88 / the G(theta) of Prop. 3.25); ``sign=-1`` gives ``V(-omega) v``."""
    t2 = jnp.sum(omega * omega, axis=-1, keepdims=True)
    a = _taylor_select(t2, lambda s: (1 - jnp.cos(jnp.sqrt(s))) / s, lambda s: 0.5 - s / 24 + s * s / 720)
    b = _taylor_select(t2, lambda s: (jnp.sqrt(s) - jnp.sin(jnp.sqrt(s))) / (s * jnp.sqrt(s)),
                       lambda s: 1 / 6 - s / 120 + s * s / 5040)
    wxv = jnp.cross(omega, v)
    return v + sign * a * wxv + b * jnp.cross(omega, wxv)


def _left_jacobian_inverse_apply(omega, v):
    """``V(omega)^-1 v = v - omega x v / 2 + (1/t^2 - (1 + cos t)/(2 t sin t)) omega x (omega x v)``
    (Modern Robotics, Alg. 3.2)."""
    t2 = jnp.sum(omega * omega, axis=-1, keepdims=True)

    def exact(s):
        t = jnp.sqrt(s)
        return 1 / s - (1 + jnp.cos(t)) / (2 * t * jnp.sin(t))

    c = _taylor_select(t2, exact, lambda s: 1 / 12 + s / 720 + s * s / 30240)
    wxv = jnp.cross(omega, v)
    return v - wxv / 2 + c * jnp.cross(omega, wxv)


def _log_quaternion(quat):
    """``omega`` with ``exp(omega^) = R(quat)``, ``|omega| <= pi`` (the quaternion's sign is chosen with
    ``w >= 0``)."""
    quat = jnp.where(quat[..., 3:] < 0, -quat, quat)
    u, w = quat[..., :3], quat[..., 3]
    s2 = jnp.sum(u * u, axis=-1)
    small = s2 < _SMALL**2
    s = jnp.sqrt(jnp.where(small, 1.0, s2))
    # omega = 2 atan2(s, w) u / s; near s = 0 the factor is 2/w (1 - s^2 / (3 w^2))
    factor = jnp.where(small, 2 / w * (1 - s2 / (3 * w * w)), 2 * jnp.arctan2(s, w) / s)
    return factor[..., None] * u


# ---------------------------------------------------------------------------------------------- SE(3) x R^n
def normalize(q, floating: bool):
    """``q`` with its base quaternion scaled to unit norm (``q`` itself for a fixed base)."""
    if not floating:
        return q
    quat = q[..., 3:7]
    quat = quat / jnp.linalg.norm(quat, axis=-1, keepdims=True)
    return jnp.concatenate([q[..., :3], quat, q[..., 7:]], axis=-1)


def integrate(q, v, dt, floating: bool):
    """The configuration reached from ``q`` (shape ``(..., nq)``) moving at the constant velocity ``v``
    (``(..., nv)``) for ``dt``: ``g exp(dt V)`` for the base, ``q_j + dt qd_j`` for the joints."""
    if not floating:
        return q + dt * v
    dv = dt * v
    p, quat = q[..., :3], normalize(q, True)[..., 3:7]
    omega, vb = dv[..., :3], dv[..., 3:6]
    p1 = p + rotate(quat, _left_jacobian_apply(omega, vb))
    quat1 = quaternion_multiply(quat, _exp_so3_quaternion(omega))
    return jnp.concatenate([p1, quat1, q[..., 7:] + dv[..., 6:]], axis=-1)


def difference(q0, q1, floating: bool):
    """The velocity ``v`` (``(..., nv)``) with ``integrate(q0, v, 1) = q1``: ``log(g0^-1 g1)`` for the base
    (as (omega, v)), ``q1_j - q0_j`` for the joints."""
    if not floating:
        return q1 - q0
    a, b = normalize(q0, True), normalize(q1, True)
    inv = quaternion_conjugate(a[..., 3:7])
    rel = quaternion_multiply(inv, b[..., 3:7])
    p_rel = rotate(inv, b[..., :3] - a[..., :3])
    omega = _log_quaternion(rel)
    vb = _left_jacobian_inverse_apply(omega, p_rel)
    return jnp.concatenate([omega, vb, q1[..., 7:] - q0[..., 7:]], axis=-1)


def configuration_rate(q, v, floating: bool):
    """``dq/dt`` (``(..., nq)``) of a configuration moving at velocity ``v``: ``R v_b`` for the position,
    ``quat (omega, 0) / 2`` for the quaternion, ``qd_j`` for the joints (``v`` itself for a fixed base)."""
    if not floating:
        return v
    quat = q[..., 3:7]
    omega = jnp.concatenate([v[..., :3], jnp.zeros_like(v[..., :1])], axis=-1)
    dquat = quaternion_multiply(quat, omega) / 2
    return jnp.concatenate([rotate(quat, v[..., 3:6]), dquat, v[..., 6:]], axis=-1)
