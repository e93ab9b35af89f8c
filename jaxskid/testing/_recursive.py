"""Numeric recursive dynamics in JAX: the "recursive evaluation" that the closed form is measured against.

The closed form (:mod:`jaxskid.symbolic._kinematics`) runs the Newton-Euler and composite-rigid-body recursions once,
symbolically, and prints the result. This module runs the same recursions numerically, at every call, in
JAX: recursive Newton-Euler for ``tau``, ``C(q, qd) qd`` and ``Q_grav`` (Featherstone, "Rigid Body Dynamics
Algorithms", 2008, Alg. 5.1) and the composite-rigid-body algorithm for ``M`` (Alg. 6.2), in the body-fixed
representation of :mod:`jaxskid.model._robot` (Müller 2018, sec. 3). The loop over the tree is unrolled in Python
(the topology is static), so XLA sees straight-line code of 3x3 and 6x6 products.

It is a lowering of the model, as :mod:`jaxskid.codegen._jax` is: the robot's joint origins, screws, 6x6
inertias and gravity are lambdified to JAX functions of the parameter vector (the order of
``Robot.parameters``, the same vector the closed form takes), so both evaluations take the same inputs.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
import sympy as sp

from .._errors import RequestError, ShapeError
from ..model._robot import Robot, symbol

_SIGNATURES = {
    "mass_matrix": ("q",),
    "gravity_torques": ("q",),
    "coriolis_torques": ("q", "qd"),
    "inverse_dynamics": ("q", "qd", "qdd"),
}


@dataclass(frozen=True)
class _ModelFunction:
    """``p -> (origins (n, 4, 4), screws (n, 6), inertias (n, 6, 6), gravity (3,))`` from the robot's
    symbolic expressions.

    Entries that are polynomials in the parameters (inertias always, poses usually) are evaluated as
    ``coefficients @ monomials(p)``, a gather and a product instead of hundreds of scalar expressions that XLA
    compiles slowly when they are stacked into one array; the few others (e.g. ``sin`` of a parameter) are
    lambdified to JAX.
    """

    constant: np.ndarray  # (size,) every entry, with 0 where it depends on the parameters
    poly_index: np.ndarray  # (k,) flat positions of the polynomial entries
    coefficients: np.ndarray  # (k, n_monomials)
    exponents: np.ndarray  # (n_monomials, n_params) integer exponents
    other_index: np.ndarray  # flat positions of the other parameter-dependent entries
    other: Callable | None  # p_0, ..., p_m -> list of those entries
    n: int

    def __call__(self, p):
        dtype = p.dtype
        flat = jnp.asarray(self.constant, dtype=dtype)
        if self.poly_index.size:
            degree = int(self.exponents.max())
            powers = [jnp.ones_like(p)]
            for _ in range(degree):
                powers.append(powers[-1] * p)
            table = jnp.stack(powers)  # (degree + 1, n_params)
            cols = np.broadcast_to(np.arange(p.shape[0]), self.exponents.shape)
            monomials = jnp.prod(table[self.exponents, cols], axis=1)
            flat = flat.at[self.poly_index].set(jnp.asarray(self.coefficients, dtype=dtype) @ monomials)
        if self.other is not None:
            values = self.other(*(p[k] for k in range(p.shape[0])))
            flat = flat.at[self.other_index].set(jnp.stack([jnp.asarray(v, dtype=dtype) for v in values]))
        n = self.n
        cuts = np.cumsum([16 * n, 6 * n, 36 * n])
        o, s, m, g = jnp.split(flat, cuts)
        return o.reshape(n, 4, 4), s.reshape(n, 6), m.reshape(n, 6, 6), g


def _model_function(robot: Robot) -> _ModelFunction:
    exprs = []
    for j in robot.joints:
        exprs.extend(sp.sympify(e) for e in j.origin)
    for j in robot.joints:
        exprs.extend(sp.sympify(e) for e in j.screw)
    for j in robot.joints:
        exprs.extend(sp.sympify(e) for e in j.inertia)
    exprs.extend(sp.sympify(e) for e in robot.gravity)
    params = [symbol(p) for p in robot.parameters]
    constant = np.zeros(len(exprs))
    poly_index, polys, other_index, others = [], [], [], []
    for k, e in enumerate(exprs):
        if not e.free_symbols:
            constant[k] = float(e)
            continue
        try:
            poly = sp.Poly(e, *params)
        except sp.PolynomialError:
            poly = None
        if poly is not None and all(c.is_Number for c in poly.coeffs()):
            poly_index.append(k)
            polys.append(poly.terms())
        else:
            other_index.append(k)
            others.append(e)
    monomials: dict[tuple, int] = {}
    for terms in polys:
        for powers, _ in terms:
            monomials.setdefault(powers, len(monomials))
    coefficients = np.zeros((len(polys), len(monomials)))
    for r, terms in enumerate(polys):
        for powers, c in terms:
            coefficients[r, monomials[powers]] = float(c)
    exponents = np.array(list(monomials), dtype=int).reshape(len(monomials), len(params))
    other = sp.lambdify(params, others, modules="jax") if others else None
    return _ModelFunction(constant, np.asarray(poly_index, dtype=int), coefficients, exponents,
                          np.asarray(other_index, dtype=int), other, robot.n_dof)


# ---------------------------------------------------------------------------------------------- spatial algebra
# Small products are written as broadcast multiply + sum: XLA on CPU compiles each tiny ``dot`` separately
# (tens of milliseconds each), while elementwise code fuses.
def _mm(a, b):
    """``a @ b`` for small matrices."""
    return jnp.sum(a[:, :, None] * b[None, :, :], axis=1)


def _mv(a, x):
    """``a @ x`` for a small matrix and a vector."""
    return jnp.sum(a * x[None, :], axis=1)


def _dot(a, b):
    return jnp.sum(a * b)


def _cross(a, b):
    return jnp.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _skew(w):
    z = jnp.zeros((), w.dtype)
    return jnp.array([[z, -w[2], w[1]], [w[2], z, -w[0]], [-w[1], w[0], z]])


def _relative(origin, screw, qi, revolute: bool):
    """(R, p) of ``C = B exp(X q)`` (Lynch & Park 2017, eq. 3.88)."""
    w, v = screw[:3], screw[3:]
    if revolute:
        wx = _skew(w)
        s, c = jnp.sin(qi), jnp.cos(qi)
        re = jnp.eye(3, dtype=qi.dtype) + s * wx + (1 - c) * _mm(wx, wx)
        wv = _cross(w, v)
        pe = wv - _mv(re, wv) + w * (_dot(w, v) * qi)
    else:
        re = jnp.eye(3, dtype=qi.dtype)
        pe = v * qi
    rb, pb = origin[:3, :3], origin[:3, 3]
    return _mm(rb, re), _mv(rb, pe) + pb


def _to_child(r, p, twist):
    """``Ad(C^-1) V``: a twist in the parent's frame, in the child's frame."""
    w, v = twist[:3], twist[3:]
    return jnp.concatenate([_mv(r.T, w), _mv(r.T, v + _cross(w, p))])


def _to_parent(r, p, wrench):
    """``Ad(C^-1)^T F``: a wrench in the child's frame, in the parent's frame."""
    f = _mv(r, wrench[3:])
    return jnp.concatenate([_mv(r, wrench[:3]) + _cross(p, f), f])


def _ad(twist, x):
    """``ad(V) X = [V, X]`` for twists (omega, v)."""
    w, v = twist[:3], twist[3:]
    return jnp.concatenate([_cross(w, x[:3]), _cross(w, x[3:]) + _cross(v, x[:3])])


def _coad(twist, h):
    """``-ad(V)^T h`` for a momentum wrench h (moment, force)."""
    w, v = twist[:3], twist[3:]
    return jnp.concatenate([_cross(w, h[:3]) + _cross(v, h[3:]), _cross(w, h[3:])])


def _ad_inverse_matrix(r, p):
    """The 6x6 ``Ad(C^-1)`` of ``C = (R, p)``."""
    rt = r.T
    z = jnp.zeros((3, 3), r.dtype)
    return jnp.block([[rt, z], [-_mm(rt, _skew(p)), rt]])


# ---------------------------------------------------------------------------------------------- algorithms
@dataclass(frozen=True)
class RecursiveDynamics:
    """M, Q_grav, C qd and tau of one robot by numeric recursions in JAX; build it with
    :func:`recursive_dynamics`. Every function takes one state (``(n,)`` arrays) and the parameter vector
    ``p`` (``(len(parameters),)``); batch with ``jax.vmap``, as :meth:`jaxskid.Dynamics.raw`."""

    name: str
    parameters: tuple[str, ...]
    defaults: Mapping[str, float]
    parents: tuple[int, ...]
    revolute: tuple[bool, ...]
    model: _ModelFunction

    @property
    def n_dof(self) -> int:
        return len(self.parents)

    @property
    def quantities(self) -> tuple[str, ...]:
        return tuple(_SIGNATURES)

    def param_vector(self, params=None, dtype=None) -> jax.Array:
        """Parameters as a vector in the order of :attr:`parameters` (``None``: the defaults)."""
        if params is None:
            missing = [k for k in self.parameters if k not in self.defaults]
            if missing:
                raise RequestError(f"parameter(s) {', '.join(missing)} have no default value; pass params")
            params = self.defaults
        if isinstance(params, Mapping):
            vec = jnp.asarray(np.array([params[k] for k in self.parameters], dtype=np.float64))
        else:
            vec = jnp.asarray(params)
            if vec.shape != (len(self.parameters),):
                raise ShapeError(f"params: expected shape ({len(self.parameters)},), got {vec.shape}")
        return vec if dtype is None else vec.astype(dtype)

    def raw(self, name: str) -> Callable:
        """``f(*state, p)`` for one state, as :meth:`jaxskid.Dynamics.raw`."""
        if name not in _SIGNATURES:
            raise RequestError(f"unknown quantity {name!r}; the recursive evaluation has {', '.join(_SIGNATURES)}")
        return getattr(self, name)

    # -- the recursions
    def _kinematics(self, q, p):
        origins, screws, inertias, gravity = self.model(p)
        poses = [_relative(origins[i], screws[i], q[i], self.revolute[i]) for i in range(self.n_dof)]
        return poses, screws, inertias, gravity

    def _rnea(self, q, qd, qdd, p, *, gravity_on: bool):
        """Featherstone (2008) Alg. 5.1 in body-fixed coordinates; ``qd`` or ``qdd`` may be None (zero)."""
        poses, screws, inertias, gravity = self._kinematics(q, p)
        n = self.n_dof
        dtype = q.dtype
        zero6 = jnp.zeros(6, dtype)
        twists, accels, wrenches = [], [], []
        for i in range(n):
            r, pos = poses[i]
            x = screws[i]
            parent = self.parents[i]
            if parent >= 0:
                v = _to_child(r, pos, twists[parent])
                a = _to_child(r, pos, accels[parent])
            else:
                v = zero6
                base = jnp.concatenate([jnp.zeros(3, dtype), -gravity]) if gravity_on else zero6
                a = _to_child(r, pos, base)
            if qd is not None:
                v = v + x * qd[i]
                a = a + _ad(v, x) * qd[i]
            if qdd is not None:
                a = a + x * qdd[i]
            twists.append(v)
            accels.append(a)
            m = inertias[i]
            f = _mv(m, a)
            if qd is not None:
                f = f + _coad(v, _mv(m, v))
            wrenches.append(f)
        tau = [None] * n
        for i in reversed(range(n)):
            tau[i] = _dot(screws[i], wrenches[i])
            parent = self.parents[i]
            if parent >= 0:
                r, pos = poses[i]
                wrenches[parent] = wrenches[parent] + _to_parent(r, pos, wrenches[i])
        return jnp.stack(tau)

    def inverse_dynamics(self, q, qd, qdd, p):
        """tau = M(q) qdd + C(q, qd) qd + Q_grav(q), shape (n,)."""
        return self._rnea(q, qd, qdd, p, gravity_on=True)

    def gravity_torques(self, q, p):
        """Q_grav(q), shape (n,)."""
        return self._rnea(q, None, None, p, gravity_on=True)

    def coriolis_torques(self, q, qd, p):
        """C(q, qd) qd, shape (n,)."""
        return self._rnea(q, qd, None, p, gravity_on=False)

    def mass_matrix(self, q, p):
        """M(q) by the composite-rigid-body algorithm (Featherstone 2008, Alg. 6.2), shape (n, n)."""
        poses, screws, inertias, _ = self._kinematics(q, p)
        n = self.n_dof
        composite = [inertias[i] for i in range(n)]
        for i in reversed(range(n)):
            parent = self.parents[i]
            if parent >= 0:
                t = _ad_inverse_matrix(*poses[i])
                composite[parent] = composite[parent] + _mm(_mm(t.T, composite[i]), t)
        entries = {}
        for i in range(n):
            f = _mv(composite[i], screws[i])
            entries[i, i] = _dot(screws[i], f)
            j = i
            while self.parents[j] >= 0:
                f = _to_parent(*poses[j], f)
                j = self.parents[j]
                entries[i, j] = entries[j, i] = _dot(screws[j], f)
        zero = jnp.zeros((), q.dtype)
        return jnp.stack([jnp.stack([entries.get((r, c), zero) for c in range(n)]) for r in range(n)])


def recursive_dynamics(robot: Robot) -> RecursiveDynamics:
    """The numeric recursive evaluation of ``robot``'s M, Q_grav, C qd and tau in JAX."""
    return RecursiveDynamics(
        name=robot.name,
        parameters=robot.parameters,
        defaults=robot.default_params(),
        parents=robot.parents,
        revolute=tuple(t == "revolute" for t in robot.joint_types),
        model=_model_function(robot),
    )
