"""Compliant ground contact for rollouts: feet that land, slide and stick on a plane.

:class:`GroundContact` is a :class:`~jaxskid.apps._field.Controller` that adds the generalized forces of
point contacts between chosen end-effector frames and the ground plane ``z = height`` to those of another
controller (or of none). For a contact point at world position ``p`` with world velocity ``pd = J_v(q) qd``
(the linear rows of its hybrid Jacobian) and penetration ``d = height - p_z``:

* normal force, a spring-damper that only pushes: ``f_n = max(0, k d - c pd_z)`` while ``d > 0``, else 0
  (the damping may not pull the foot down: Hunt & Crossley, "Coefficient of restitution interpreted as damping
  in vibroimpact", J. Appl. Mech. 42, 1975, discuss the pull of a linear damper at separation);
* friction, Coulomb's law regularised over the slip speed ``s``: ``f_t = -mu f_n pd_t / sqrt(|pd_t|^2 + s^2)``
  (``pd_t`` the tangential velocity): full Coulomb friction when sliding much faster than ``s``, viscous below;
* the generalized force ``tau_c = sum_e J_v,e^T f_e``, with ``f_e = (f_t, f_n)`` in world axes: the quantity
  ``external_torques`` of the wrenches ``(0, R_e^T f_e)`` in the feet's frames.

It is smooth enough for ``jax.grad`` almost everywhere and needs no event detection, so a batch of rollouts
with feet touching down at different times stays one ``vmap`` of a fixed-step loop.

The law is stiff, and an explicit step must resolve it: the normal spring's ``sqrt(k / m_foot)`` and, above all,
the friction's slope ``mu f_n / s`` over the effective mass of a foot. On the 2.5 kg solo12 (RK4 at 0.5 ms,
``k = 5e3`` N/m, ``c = 50`` N s/m) a slip speed ``s = 1e-2`` m/s left the feet chattering with 20 % of the weight
missing from the mean normal force, while the default ``s = 5e-2`` settles in 3 s to the weight within 1e-6 and
joint speeds of 6e-5 rad/s; a smaller ``s`` (less creep under tangential load) needs a proportionally smaller
step. The bilateral, exact
alternative for feet that never lift is :func:`jaxskid.constrained_forward_dynamics` with point contacts.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax.numpy as jnp

from .._errors import RequestError
from ..runtime._dynamics import Dynamics
from ..runtime._jit import traced
from ._field import Controller, as_controls


NEEDED = ("ee_pose", "ee_hybrid_twist", "external_torques")
"""The quantities :class:`GroundContact` evaluates."""


class GroundContact(Controller):
    """Point contacts of end-effector frames with the plane ``z = height`` (module docstring), added to the
    torques of ``inner``.

    Args:
        dyn: lowered with ``ee_pose``, ``ee_hybrid_twist`` and ``external_torques`` (:data:`NEEDED`).
        frames: the contact frames, end-effectors of ``dyn`` (default: every end-effector).
        stiffness: ``k`` [N/m]; damping: ``c`` [N s/m]; friction: ``mu``; slip: ``s`` [m/s].
        height: the ground's height [m] in the world frame.
        inner: the controller whose torques the contact forces are added to: a :class:`Controller`, a policy
            ``tau(t, x)``, or ``None`` (no actuation).
        params: the parameters the kinematics is evaluated with (``None``: the defaults).
    """

    def __init__(self, dyn: Dynamics, frames: Sequence[str] | None = None, *, stiffness=5e3, damping=50.0,
                 friction=1.0, slip=5e-2, height=0.0, inner=None, params=None):
        missing = [k for k in NEEDED if k not in dyn.quantities]
        if missing:
            raise RequestError(f"GroundContact needs the quantities {', '.join(NEEDED)}; {', '.join(missing)} not "
                               f"lowered (lowered: {', '.join(dyn.quantities)})")
        frames = tuple(dyn.end_effectors if frames is None else frames)
        unknown = [f for f in frames if f not in dyn.end_effectors]
        if unknown or not frames:
            raise RequestError(f"GroundContact: frames: expected end-effectors of the robot "
                               f"({', '.join(dyn.end_effectors) or 'none'}), got {', '.join(unknown) or 'none'}")
        for name, value in (("stiffness", stiffness), ("damping", damping), ("friction", friction), ("slip", slip)):
            if traced(value):  # a value being differentiated: checked where it is concrete
                continue
            if not float(value) >= 0 or (name == "slip" and not float(value) > 0):
                raise RequestError(f"GroundContact: {name}: expected a {'positive' if name == 'slip' else 'non-negative'}"
                                   f" number, got {value!r}")
        self.dyn, self.frames, self.params = dyn, frames, params
        self.k, self.c, self.mu, self.s, self.height = stiffness, damping, friction, slip, height
        self._rows = jnp.asarray([dyn.end_effectors.index(f) for f in frames])
        self._n_ee = len(dyn.end_effectors)
        self._pose, self._twist = dyn.raw("ee_pose"), dyn.raw("ee_hybrid_twist")
        self._generalized = dyn.raw("external_torques")
        self.inner = None if inner is None else as_controls(inner)[0]

    def init(self, x0):
        return () if self.inner is None else self.inner.init(x0)

    def forces(self, q, qd):
        """``(p, f, tau_c)``: the contact points ``(m, 3)``, their forces ``(m, 3)`` (world axes) and the
        generalized force ``(nv,)`` at the state ``(q, qd)``."""
        p = self.dyn.param_vector(self.params, q.dtype)
        poses = self._pose(q, p).reshape(self._n_ee, 4, 4)[self._rows]
        points, rotations = poses[:, :3, 3], poses[:, :3, :3]
        vel = self._twist(q, qd, p).reshape(self._n_ee, 6)[self._rows, 3:]
        depth = self.height - points[:, 2]
        normal = jnp.where(depth > 0, jnp.maximum(self.k * depth - self.c * vel[:, 2], 0.0), 0.0)
        tangential = vel[:, :2]
        speed = jnp.sqrt(jnp.sum(tangential**2, axis=-1) + self.s**2)
        f = jnp.concatenate([-(self.mu * normal / speed)[:, None] * tangential, normal[:, None]], axis=-1)
        # J_v^T f as external_torques of the wrenches (0, R_e^T f) in the feet's own frames (linear in W)
        local = jnp.einsum("eji,ej->ei", rotations, f)
        wrench = jnp.zeros((self._n_ee, 6), f.dtype).at[self._rows, 3:].set(local)
        return points, f, self._generalized(q, wrench, p)

    def __call__(self, t, x, z):
        nq = (x.shape[-1] + 1) // 2
        q, qd = x[:nq], x[nq:]
        tau_c = self.forces(q, qd)[2]
        if self.inner is None:
            return tau_c, ()
        tau, zdot = self.inner(t, x, z)
        return tau + tau_c, zdot
