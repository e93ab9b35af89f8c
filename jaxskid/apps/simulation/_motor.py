"""DC motors that drive the joints of a rollout: voltages in, currents as extra states, torques out.

A permanent-magnet DC motor on joint ``j`` through a gearbox of ratio ``r`` (motor angle ``r q_j``) obeys
(Spong, Hutchinson & Vidyasagar, "Robot Modeling and Control", 2006, sec. 6.1)

    L di/dt + R i + k_e w_m = V,      w_m = r qd_j,      tau_j = r k_t i,

with armature resistance ``R`` (ohm), inductance ``L`` (H), torque constant ``k_t`` (N m / A), back-EMF
constant ``k_e`` (V s / rad; equal to ``k_t`` in SI units for an ideal motor), the current ``i`` (A) and the
voltage ``V`` (V). The gearbox is ideal (no losses); for a prismatic joint ``r`` is in rad/m (a lead screw:
``2 pi / lead``) and ``tau_j`` a force. The motor only supplies the torque: the rotor's inertia reflected at
the joint (``r^2 J_rotor``) and the friction belong to the joint's :class:`~jaxskid.Drive` (armature, viscous,
Coulomb), which stay in the mechanical equations ``M qdd + C qd + Q_grav + tau_drive = tau``.

With ``L = None`` the electrical dynamics are taken as instantaneous (the quasi-static limit ``L -> 0``):
``i = (V - k_e r qd_j) / R``, no current state. Use it when the electrical time constant ``L / R`` is far
below the mechanical ones: an explicit integrator (:class:`~jaxskid.RK4`) needs ``dt`` below about
``2.8 L / R`` to stay stable on the current, or else an implicit diffrax solver (``diffrax.Kvaerno5``).

:meth:`DCMotors.drive` turns voltages (an array held over each step, or a function ``V(t, x)``) into the
controls of :func:`~jaxskid.rollout` and :func:`~jaxskid.vector_field`: a :class:`~jaxskid.Controller`
whose state ``z`` is the currents, so saving, batching, diffrax solvers and gradients work as for any
controller. :meth:`DCMotors.currents` reads the currents back from the :class:`~jaxskid.Trajectory`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ..._errors import RequestError, ShapeError
from ...runtime._jit import traced
from ._field import Controller, HeldInput
from ._rollout import Trajectory

_NAMES = ("R", "L", "k_t", "k_e", "ratio")


@jax.tree_util.register_pytree_node_class
class DCMotors:
    """DC motors on the joints (the model in :mod:`jaxskid.apps.simulation._motor`): one motor per joint of ``joints``.

    Args:
        R: armature resistance (ohm), ``> 0``.
        L: armature inductance (H), ``> 0``; ``None`` for the quasi-static model (no current states).
        k_t: torque constant (N m / A).
        k_e: back-EMF constant (V s / rad).
        ratio: gear ratio ``r``, motor speed over joint speed (``w_m = r qd``), non-zero.
        joints: indices (in the order of ``q``) of the joints with a motor; ``None``: every joint.

    Each of ``R, L, k_t, k_e, ratio`` is a scalar (shared) or an array with one value per motor. A joint
    without a motor takes its input as a torque. ``DCMotors`` is a JAX pytree whose leaves are the five
    parameters: build it inside a function to differentiate through a rollout with respect to them
    (``jax.grad``), or to ``jax.vmap`` over them. Numeric parameters are compared by value (two equal
    motors share one compiled rollout); values inside a trace are compiled into the caller's program.
    """

    def __init__(self, R, L, k_t, k_e, ratio=1.0, *, joints: Sequence[int] | None = None):
        values = {}
        for name, v in zip(_NAMES, (R, L, k_t, k_e, ratio)):
            values[name] = None if v is None and name == "L" else _parameter(name, v)
        self.joints = None if joints is None else _joint_indices(joints)
        sizes = {v.shape[0] for v in values.values() if v is not None and v.ndim == 1}
        if len(sizes) > 1 or (self.joints is not None and sizes - {len(self.joints)}):
            shapes = ", ".join(f"{k} {tuple(v.shape)}" for k, v in values.items() if v is not None)
            count = "one value per joint" if self.joints is None else f"{len(self.joints)} values (one per joint)"
            raise ShapeError(f"DCMotors: expected scalars or {count}, got {shapes}")
        self.R, self.L, self.k_t, self.k_e, self.ratio = (values[k] for k in _NAMES)

    # --------------------------------------------------------------------------------------- pytree
    def tree_flatten(self):
        return (self.R, self.L, self.k_t, self.k_e, self.ratio), self.joints

    @classmethod
    def tree_unflatten(cls, joints, leaves):
        out = object.__new__(cls)
        out.R, out.L, out.k_t, out.k_e, out.ratio = leaves
        out.joints = joints
        return out

    def __repr__(self):
        def show(v):
            return "None" if v is None else ("traced" if traced(v) else np.array2string(np.asarray(v)))
        where = "" if self.joints is None else f", joints={self.joints}"
        return "DCMotors(" + ", ".join(f"{k}={show(getattr(self, k))}" for k in _NAMES) + where + ")"

    # ----------------------------------------------------------------------------------------- model
    @property
    def quasi_static(self) -> bool:
        """Whether the currents follow the voltages at once (``L = None``): no current states."""
        return self.L is None

    def index(self, n: int) -> np.ndarray:
        """The indices of the joints with a motor, for a robot of ``n`` joints."""
        if self.joints is None:
            return np.arange(n)
        if max(self.joints) >= n:
            raise ShapeError(f"DCMotors: joints {self.joints}: the robot has {n} joint(s) (indices 0 to {n - 1})")
        return np.asarray(self.joints)

    def values(self, n: int, dtype) -> tuple:
        """``(R, L, k_t, k_e, ratio)`` as arrays ``(m,)`` for the ``m`` motors of a robot of ``n`` joints
        (``L`` is ``None`` for the quasi-static model)."""
        m = len(self.index(n))
        for name in _NAMES:
            v = getattr(self, name)
            if v is not None and v.ndim == 1 and v.shape[0] != m:
                raise ShapeError(f"DCMotors: {name}: expected {m} values (one per motor), got {v.shape[0]}")
        return tuple(None if v is None else jnp.broadcast_to(jnp.asarray(v, dtype), (m,))
                     for v in (getattr(self, k) for k in _NAMES))

    def derivatives(self, x, i, v):
        """``(tau_m, di/dt)``: the motors' joint torques ``r k_t i`` ``(m,)`` and, with an inductance, the
        currents' derivatives ``(V - R i - k_e r qd) / L`` (else ``()``, and ``i`` is ignored: the
        quasi-static currents ``(V - k_e r qd) / R`` are used), at state ``x = (q, qd)`` ``(2n,)`` and motor
        voltages ``v`` ``(m,)``."""
        n = x.shape[-1] // 2
        res, ind, kt, ke, r = self.values(n, x.dtype)
        emf = ke * r * x[n:][self.index(n)]
        if ind is None:
            return r * kt * (v - emf) / res, ()
        return r * kt * i, (v - res * i - emf) / ind

    # ------------------------------------------------------------------------------- rollout support
    def drive(self, voltage) -> Controller | HeldInput:
        """The controls of :func:`~jaxskid.rollout` (and :func:`~jaxskid.vector_field`) for the voltages
        ``voltage``: an array ``(steps, n)`` held over each step like array torques (``(..., steps, n)``: one
        sequence per rollout of a batch), or a function ``V(t, x) -> (n,)`` evaluated at every stage of the
        integrator. Entry ``j`` is the voltage of joint ``j``'s motor, or the torque of a joint without one.

        The currents start at zero. The :class:`~jaxskid.Trajectory`'s ``tau`` holds the joint torques
        applied (the motors' ``r k_t i``), ``z`` the currents (:meth:`currents`).
        """
        if callable(voltage):
            return _MotorController(self, voltage)
        inputs = voltage if traced(voltage) else np.asarray(voltage)
        if not traced(voltage) and not np.issubdtype(inputs.dtype, np.number):
            raise RequestError(f"DCMotors.drive: voltage: expected an array (steps, n) or a function V(t, x), "
                               f"got {type(voltage).__name__}")
        if inputs.ndim < 2:
            raise ShapeError(f"DCMotors.drive: voltage: expected shape (steps, n) (or (..., steps, n) for a batch), "
                             f"got {tuple(inputs.shape)}")
        return HeldInput(_MotorController(self, None), inputs)

    def currents(self, trajectory: Trajectory) -> jax.Array:
        """The motor currents of a rollout driven by :meth:`drive` ``(..., n_saved, m)``: its states ``z``.

        Quasi-static motors (``L = None``) have no current states: their currents ``tau_j / (r k_t)`` come
        from the torques applied at the start of each step, ``(..., n_saved - 1, m)`` (as ``trajectory.tau``).
        """
        if not isinstance(trajectory, Trajectory):
            raise RequestError(f"DCMotors.currents: expected a jaxskid.Trajectory, got {type(trajectory).__name__}")
        n = trajectory.tau.shape[-1]
        if not self.quasi_static:
            z = trajectory.z
            m = len(self.index(n))
            if not isinstance(z, jax.Array) or z.shape[-1:] != (m,):
                raise RequestError(f"DCMotors.currents: expected a trajectory of these motors' drive (states z "
                                   f"(..., n_saved, {m})), got z of shape {getattr(z, 'shape', ())}")
            return z
        _, _, kt, _, r = self.values(n, trajectory.tau.dtype)
        tau = trajectory.tau[..., self.index(n)]
        return tau / jnp.broadcast_to(r * kt, tau.shape)

    def _key(self):
        """A hashable value of the parameters, or ``None`` when one of them is traced."""
        leaves = [getattr(self, k) for k in _NAMES]
        if traced([v for v in leaves if v is not None]):
            return None
        return self.joints, tuple(None if v is None else (v.shape, np.asarray(v, np.float64).tobytes()) for v in leaves)


class _MotorController(Controller):
    """The motors as a controller: state ``z`` the currents ``(m,)`` (``()`` if quasi-static); the voltages
    from ``voltage(t, x)``, or the held input row ``u_k`` (:class:`~jaxskid.apps.simulation._field.HeldInput`)."""

    def __init__(self, motors: DCMotors, voltage: Callable | None):
        self.motors, self.voltage = motors, voltage

    def init(self, x0):
        if self.motors.quasi_static:
            return ()
        return jnp.zeros((len(self.motors.index(x0.shape[-1] // 2)),), x0.dtype)

    def __call__(self, t, x, z, u_k=None):
        n = x.shape[-1] // 2
        u = self.voltage(t, x) if u_k is None else u_k
        u = jnp.asarray(u, x.dtype)
        if u.shape != (n,):
            raise ShapeError(f"DCMotors: the voltages: expected shape ({n},) at a time t, got {u.shape}")
        index = self.motors.index(n)
        torque, di = self.motors.derivatives(x, z, u[index])
        return (torque if self.motors.joints is None else u.at[index].set(torque)), di

    def __eq__(self, other):
        if type(other) is not type(self) or other.voltage is not self.voltage:
            return False
        key = self.motors._key()
        return other.motors is self.motors or (key is not None and key == other.motors._key())

    def __hash__(self):
        key = self.motors._key()
        return hash((_MotorController, id(self.voltage), id(self.motors) if key is None else key))


def _parameter(name: str, value):
    """A motor parameter: a traced value as it is, else a float array of 0 or 1 axes, checked."""
    if traced(value):
        v = jnp.asarray(value)
    else:
        try:
            v = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise RequestError(f"DCMotors: {name}: expected a number or an array of numbers, got {value!r}") from None
        if not np.all(np.isfinite(v)):
            raise RequestError(f"DCMotors: {name}: expected finite values, got {v}")
        if name in ("R", "L") and not np.all(v > 0):
            raise RequestError(f"DCMotors: {name}: expected values > 0"
                               + (" (L=None for the quasi-static model)" if name == "L" else "") + f", got {v}")
        if name == "ratio" and not np.all(v != 0):
            raise RequestError(f"DCMotors: ratio: expected non-zero gear ratios, got {v}")
    if v.ndim > 1:
        raise ShapeError(f"DCMotors: {name}: expected a scalar or one value per motor, got shape {v.shape}")
    return v


def _joint_indices(joints) -> tuple[int, ...]:
    out = tuple(joints) if isinstance(joints, (list, tuple, range, np.ndarray)) else None
    if not out or not all(isinstance(j, (int, np.integer)) and not isinstance(j, bool) and j >= 0 for j in out) \
            or len(set(out)) != len(out):
        raise RequestError(f"DCMotors: joints: expected distinct joint indices >= 0 (in the order of q), "
                           f"got {joints!r}")
    return tuple(int(j) for j in out)
