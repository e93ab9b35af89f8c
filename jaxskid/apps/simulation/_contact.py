"""Compliant ground contact for rollouts: feet that land, slide and stick on a plane.

:class:`GroundContact` is a :class:`~jaxskid.apps.simulation._field.Controller` that adds the generalized forces of
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

A frame may stand for a sphere of radius ``r`` around it (a round foot, a point of
:func:`jaxskid.collision_points`): its contact point is ``p - r e_z``, the lowest point of the sphere, moving at
``pd + omega x (-r e_z)``; the depth is ``height - p_z + r``, and the force acts there, so the wrench at the frame
adds the moment ``(-r e_z) x f``. With ``r = 0`` this is the point contact above.

The contact frames are :attr:`GroundContact.frames`, and its ``repr`` names them: a part of the robot with no
contact frame passes through the ground. :func:`jaxskid.rollout` warns when a floating base ends below the ground
with none of them on it (:func:`jaxskid.apps.simulation._health.warn_if_below_ground`); :func:`jaxskid.collision_points`
gives the points of a URDF's collision geometry, the base's included.

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

import math
from collections.abc import Mapping, Sequence

import jax.numpy as jnp
import numpy as np

from ..._errors import RequestError, unknown_names
from ...runtime._dynamics import Dynamics
from ...runtime._jit import traced
from ._field import Controller, as_controls


NEEDED = ("ee_pose", "ee_hybrid_twist", "external_torques")
"""The quantities :class:`GroundContact` evaluates."""


class GroundContact(Controller):
    """Point contacts of end-effector frames with the plane ``z = height`` (module docstring), added to the
    torques of ``inner``.

    Args:
        dyn: lowered with ``ee_pose``, ``ee_hybrid_twist`` and ``external_torques`` (:data:`NEEDED`).
        frames: the contact frames, end-effectors of ``dyn``: a sequence of names (points), a mapping name ->
            radius [m] (spheres of that radius around the frames: the ``radius`` of a
            :class:`~jaxskid.ContactPoints`), or ``None`` for every end-effector (points). Only these frames touch
            the ground.
        stiffness: ``k`` [N/m] of the normal spring.
        damping: ``c`` [N s/m] of the normal damper.
        friction: the Coulomb coefficient ``mu``.
        slip: ``s`` [m/s], the slip speed below which friction is viscous.
        height: the ground's height [m] in the world frame.
        inner: the controller whose torques the contact forces are added to: a :class:`Controller`, a policy
            ``tau(t, x)``, or ``None`` (no actuation).
        params: the parameters the kinematics is evaluated with (``None``: the defaults).

    Attributes:
        frames: the contact frames' names; radius: their radii ``(m,)``.
    """

    def __init__(self, dyn: Dynamics, frames: Sequence[str] | Mapping[str, float] | None = None, *, stiffness=5e3,
                 damping=50.0, friction=1.0, slip=5e-2, height=0.0, inner=None, params=None):
        missing = [k for k in NEEDED if k not in dyn.quantities]
        if missing:
            raise RequestError(f"GroundContact needs the quantities {', '.join(NEEDED)}; {', '.join(missing)} not "
                               f"lowered (lowered: {', '.join(dyn.quantities)})")
        frames, radius = _frames(dyn, frames)
        for name, value in (("stiffness", stiffness), ("damping", damping), ("friction", friction), ("slip", slip)):
            if traced(value):  # a value being differentiated: checked where it is concrete
                continue
            if not float(value) >= 0 or (name == "slip" and not float(value) > 0):
                raise RequestError(f"GroundContact: {name}: expected a {'positive' if name == 'slip' else 'non-negative'}"
                                   f" number, got {value!r}")
        self.dyn, self.frames, self.params = dyn, frames, params
        self.radius = radius
        self.k, self.c, self.mu, self.s, self.height = stiffness, damping, friction, slip, height
        self._rows = jnp.asarray([dyn.end_effectors.index(f) for f in frames])
        self._n_ee = len(dyn.end_effectors)
        self._pose, self._twist = dyn.raw("ee_pose"), dyn.raw("ee_hybrid_twist")
        self._generalized = dyn.raw("external_torques")
        self.inner = None if inner is None else as_controls(inner)[0]
        self._on_base: tuple[str, ...] | None = None

    def __repr__(self) -> str:
        shown = ", ".join(self.frames[:6]) + (f", ... ({len(self.frames)} in all)" if len(self.frames) > 6 else "")
        spheres = int(np.count_nonzero(self.radius))
        return (f"GroundContact({self.dyn.robot_name!r}, frames=[{shown}]"
                f"{f' ({spheres} with a radius)' if spheres else ''}, height={self.height!r}, "
                f"stiffness={self.k!r}, damping={self.c!r}, friction={self.mu!r})")

    def on_base(self) -> tuple[str, ...]:
        """The contact frames carried by a floating base (whose pose does not change with the joints), in the
        order of :attr:`frames`; ``()`` for a fixed base."""
        if self._on_base is None:
            self._on_base = () if not self.dyn.floating_base else _fixed_to_base(self)
        return self._on_base

    def init(self, x0):
        return () if self.inner is None else self.inner.init(x0)

    def forces(self, q, qd):
        """``(p, f, tau_c)``: the contact points ``(m, 3)`` (each frame's lowest point ``r`` below it), their
        forces ``(m, 3)`` (world axes) and the generalized force ``(nv,)`` at the state ``(q, qd)``."""
        p = self.dyn.param_vector(self.params, q.dtype)
        poses = self._pose(q, p).reshape(self._n_ee, 4, 4)[self._rows]
        radius = jnp.asarray(self.radius, q.dtype)
        points, rotations = poses[:, :3, 3].at[:, 2].add(-radius), poses[:, :3, :3]
        twist = self._twist(q, qd, p).reshape(self._n_ee, 6)[self._rows]
        lever = jnp.zeros_like(points).at[:, 2].set(-radius)  # from the frame to its contact point, world axes
        vel = twist[:, 3:] + jnp.cross(twist[:, :3], lever)
        depth = self.height - points[:, 2]
        normal = jnp.where(depth > 0, jnp.maximum(self.k * depth - self.c * vel[:, 2], 0.0), 0.0)
        tangential = vel[:, :2]
        speed = jnp.sqrt(jnp.sum(tangential**2, axis=-1) + self.s**2)
        f = jnp.concatenate([-(self.mu * normal / speed)[:, None] * tangential, normal[:, None]], axis=-1)
        # J^T f as external_torques of the wrenches (R^T (lever x f), R^T f) in the frames (linear in W)
        moment = jnp.einsum("eji,ej->ei", rotations, jnp.cross(lever, f))
        force = jnp.einsum("eji,ej->ei", rotations, f)
        wrench = jnp.zeros((self._n_ee, 6), f.dtype).at[self._rows].set(jnp.concatenate([moment, force], axis=-1))
        return points, f, self._generalized(q, wrench, p)

    def __call__(self, t, x, z):
        nq = (x.shape[-1] + 1) // 2
        q, qd = x[:nq], x[nq:]
        tau_c = self.forces(q, qd)[2]
        if self.inner is None:
            return tau_c, ()
        tau, zdot = self.inner(t, x, z)
        return tau + tau_c, zdot


def _frames(dyn: Dynamics, frames) -> tuple[tuple[str, ...], np.ndarray]:
    """The contact frames' names and radii, checked against ``dyn``'s end-effectors."""
    if isinstance(frames, Mapping):
        names, radius = tuple(frames), []
        for name, r in frames.items():
            try:
                r = float(r)
            except (TypeError, ValueError):
                r = float("nan")
            if not (math.isfinite(r) and r >= 0):
                raise RequestError(f"GroundContact: frames[{name!r}]: expected a radius >= 0 [m], got {frames[name]!r}")
            radius.append(r)
    else:
        names = tuple(dyn.end_effectors if frames is None else ([frames] if isinstance(frames, str) else frames))
        radius = [0.0] * len(names)
    unknown = [f for f in names if f not in dyn.end_effectors]
    if unknown or not names:
        named, listed = unknown_names(unknown, dyn.end_effectors)
        raise RequestError(f"GroundContact: frames: expected end-effectors of the robot ({listed}), got "
                           f"{named or 'none'}; load(..., end_effectors=...) places frames (collision_points gives "
                           f"a URDF's collision geometry as such frames)")
    return names, np.asarray(radius, float)


def _fixed_to_base(contact: GroundContact) -> tuple[str, ...]:
    """The contact frames whose pose stays the same when the joints move under a fixed floating base."""
    dyn = contact.dyn
    p = dyn.param_vector(contact.params)
    rest = np.zeros(dyn.nq)
    rest[6] = 1.0  # the identity quaternion (x, y, z, w)
    moved = rest.copy()
    moved[7:] = np.random.default_rng(0).uniform(-1.0, 1.0, dyn.nq - 7)
    poses = [np.asarray(contact._pose(jnp.asarray(q), p)).reshape(contact._n_ee, 4, 4)[np.asarray(contact._rows)]
             for q in (rest, moved)]
    fixed = np.abs(poses[0] - poses[1]).max(axis=(1, 2)) <= 1e-9
    return tuple(f for f, on in zip(contact.frames, fixed) if on)
