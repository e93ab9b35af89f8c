"""Numeric recursive dynamics in JAX: the "recursive evaluation" that the closed form is measured against.

The closed form (:mod:`jaxskid.symbolic`) runs the Newton-Euler and composite-rigid-body recursions once,
symbolically, and prints the result. This module runs the same recursions numerically, at every call, in
JAX: recursive Newton-Euler for ``tau``, ``C(q, qd) qd`` and ``Q_grav`` (Featherstone, "Rigid Body Dynamics
Algorithms", 2008, Alg. 5.1) and the composite-rigid-body algorithm for ``M`` (Alg. 6.2), in the body-fixed
representation of :mod:`jaxskid.model._robot` (Müller 2018, sec. 3), with the spatial algebra of
:mod:`jaxskid.model._spatial` applied to JAX scalars. The loop over the tree is unrolled in Python (the
topology is static), so XLA sees straight-line scalar code, which it fuses.

It is a lowering of the model, as :mod:`jaxskid.codegen._jax` is: the robot's joint origins, screws, 6x6
inertias and gravity are lambdified to JAX functions of the parameter vector (the order of
``Robot.parameters``, the same vector the closed form takes), so both evaluations take the same inputs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
import sympy as sp

from .._errors import RequestError
from ..model import _spatial as sa
from ..model._parameters import ParameterLayout
from ..model._robot import Robot, symbol
from ..runtime._parameters import param_array

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


# ---------------------------------------------------------------------------------------------- model as scalars
def _rows(a, n_rows: int, n_cols: int) -> list[list]:
    """A small array as rows of JAX scalars, the form :mod:`jaxskid.model._spatial` works on."""
    return [[a[r, c] for c in range(n_cols)] for r in range(n_rows)]


def _vector(a, n: int) -> list:
    return [a[k] for k in range(n)]


# ---------------------------------------------------------------------------------------------- algorithms
@dataclass(frozen=True)
class RecursiveDynamics:
    """M, Q_grav, C qd and tau of one robot by numeric recursions in JAX; build it with
    :func:`recursive_dynamics`. Every function takes one state (``(n,)`` arrays) and the parameter vector
    ``p`` (``(len(parameters),)``); batch with ``jax.vmap``, as :meth:`jaxskid.Dynamics.raw`."""

    name: str
    layout: ParameterLayout
    parents: tuple[int, ...]
    revolute: tuple[bool, ...]
    model: _ModelFunction

    @property
    def parameters(self) -> tuple[str, ...]:
        return self.layout.names

    @property
    def n_dof(self) -> int:
        return len(self.parents)

    @property
    def quantities(self) -> tuple[str, ...]:
        return tuple(_SIGNATURES)

    def param_vector(self, params=None, dtype=None) -> jax.Array:
        """Parameters as an array whose last axis is in the order of :attr:`parameters`: ``None`` for the
        defaults, a dict name -> value (missing names take their defaults) or an array
        (:func:`jaxskid.runtime._parameters.param_array`)."""
        return param_array(self.layout, params, dtype)

    def raw(self, name: str) -> Callable:
        """``f(*state, p)`` for one state, as :meth:`jaxskid.Dynamics.raw`."""
        if name not in _SIGNATURES:
            raise RequestError(f"unknown quantity {name!r}; the recursive evaluation has {', '.join(_SIGNATURES)}")
        return getattr(self, name)

    # -- the recursions
    def _kinematics(self, q, p):
        """Relative poses ``(R, p)`` of ``C = B exp(X q)``, screws, inertias ``(m, h, I)`` and gravity, as
        JAX scalars."""
        origins, screws, inertias, gravity = self.model(p)
        poses, xs, ms = [], [], []
        for i in range(self.n_dof):
            x = _vector(screws[i], 6)
            sin_cos = (jnp.sin(q[i]), jnp.cos(q[i])) if self.revolute[i] else None
            r, pos = sa.screw_exp(x[:3], x[3:], q[i], sin_cos)
            o = origins[i]
            poses.append(sa.compose(_rows(o, 3, 3), [o[k, 3] for k in range(3)], r, pos))
            xs.append(x)
            ms.append(sa.inertia_parts(_rows(inertias[i], 6, 6)))
        return poses, xs, ms, _vector(gravity, 3)

    def _rnea(self, q, qd, qdd, p, *, gravity_on: bool):
        """Featherstone (2008) Alg. 5.1 in body-fixed coordinates; ``qd`` or ``qdd`` may be None (zero)."""
        poses, screws, inertias, gravity = self._kinematics(q, p)
        n = self.n_dof
        zero6 = [0.0] * 6
        twists, accels, wrenches = [], [], []
        for i in range(n):
            x = screws[i]
            parent = self.parents[i]
            if parent >= 0:
                v = sa.act_inv_motion(*poses[i], twists[parent])
                a = sa.act_inv_motion(*poses[i], accels[parent])
            else:
                v = zero6
                a = sa.act_inv_motion(*poses[i], [0.0, 0.0, 0.0, *(-g for g in gravity)]) if gravity_on else zero6
            if qd is not None:
                v = sa.add(v, sa.scale(x, qd[i]))
                a = sa.add(a, sa.scale(sa.ad_apply(v, x), qd[i]))
            if qdd is not None:
                a = sa.add(a, sa.scale(x, qdd[i]))
            twists.append(v)
            accels.append(a)
            f = sa.apply_inertia_parts(inertias[i], a)
            if qd is not None:
                f = sa.add(f, sa.coad_apply(v, sa.apply_inertia_parts(inertias[i], v)))
            wrenches.append(f)
        tau = [None] * n
        for i in reversed(range(n)):
            tau[i] = sa.dot(screws[i], wrenches[i])
            parent = self.parents[i]
            if parent >= 0:
                wrenches[parent] = sa.add(wrenches[parent], sa.act_force(*poses[i], wrenches[i]))
        return jnp.stack([jnp.asarray(t, q.dtype) for t in tau])

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
        composite = list(inertias)  # children have larger indices than their parents
        for i in reversed(range(n)):
            parent = self.parents[i]
            if parent >= 0:
                composite[parent] = sa.add_inertia_parts(composite[parent], *poses[i], composite[i])
        entries = {}
        for i in range(n):
            f = sa.apply_inertia_parts(composite[i], screws[i])
            entries[i, i] = sa.dot(screws[i], f)
            j = i
            while self.parents[j] >= 0:
                f = sa.act_force(*poses[j], f)
                j = self.parents[j]
                entries[i, j] = entries[j, i] = sa.dot(screws[j], f)
        zero = jnp.zeros((), q.dtype)
        return jnp.stack([jnp.stack([jnp.asarray(entries.get((r, c), zero), q.dtype) for c in range(n)])
                          for r in range(n)])


def recursive_dynamics(robot: Robot) -> RecursiveDynamics:
    """The numeric recursive evaluation of ``robot``'s M, Q_grav, C qd and tau in JAX (a fixed base, no mimic
    joints)."""
    if robot.floating_base:
        raise RequestError(f"the recursive evaluation has a fixed base; robot {robot.name!r} floats")
    if robot.mimic_joints:
        raise RequestError(f"the recursive evaluation has no mimic joints; robot {robot.name!r} has "
                           f"{', '.join(robot.mimic_joints)}")
    return RecursiveDynamics(
        name=robot.name,
        layout=ParameterLayout(robot.parameters, robot.default_params()),
        parents=robot.parents,
        revolute=tuple(t == "revolute" for t in robot.joint_types),
        model=_model_function(robot),
    )
