"""Fixed-step integrators for :func:`jaxskid.rollout`: semi-implicit Euler and the classical RK4.

An integrator takes one step of ``dy/dt = f(t, y)`` with ``y = (q, qd, z)`` (positions, velocities and a
controller's state) through ``step(f, t, y, dt) -> (y1, aux)``, where ``f(t, y) -> (dy/dt, aux)`` and the
returned ``aux`` (the applied torque) is that of the first evaluation, at ``(t, y)``. Any diffrax solver
serves too (:mod:`jaxskid.apps.simulation._diffrax`); why these two are kept is said at each, with measured figures.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import jax
import jax.numpy as jnp

from ..._errors import RequestError
from ..._tableau import RK4_TABLEAU, ExplicitTableau


@dataclass(frozen=True)
class SemiImplicitEuler:
    """Semi-implicit Euler: ``qd' = qd + dt qdd(q, qd)``, ``q' = q + dt qd'``. Order 1.

    The velocity is updated first and the position with the new velocity; other states (a controller's)
    take an explicit Euler step. It is symplectic when the mass matrix is constant (Hairer, Lubich & Wanner,
    "Geometric Numerical Integration", 2006, sec. VI.3), not for a configuration-dependent M. diffrax's
    ``SemiImplicitEuler`` takes two terms, ``dq/dt = f(p)`` and ``dp/dt = g(q)``, which ``qdd(q, qd)`` is not;
    a step costs what diffrax's explicit ``Euler`` step costs, within the noise
    (``benchmarks/tradeoff_rollouts.py``).
    """

    order = 1

    def step(self, f: Callable, t, y, dt):
        (_, qdd, zdot), aux = f(t, y)
        q, qd, z = y
        qd1 = qd + dt * qdd
        z1 = jax.tree.map(lambda a, b: a + dt * b, z, zdot)
        rate = getattr(f, "rate", None)  # dq/dt at a velocity: a floating base's (jaxskid.apps.simulation._field)
        return (q + dt * (qd1 if rate is None else rate(q, qd1)), qd1, z1), aux


@dataclass(frozen=True)
class RK4:
    """The classical fourth-order Runge-Kutta method (Hairer, Norsett & Wanner, "Solving Ordinary
    Differential Equations I", Table 1.2). Order 4.

    The four stages run as a ``lax.scan`` over one evaluation of ``f``, so the dynamics are traced and
    compiled once. Kept beside diffrax because it is faster per evaluation of the dynamics than the same
    tableau as a diffrax solver in ``diffeqsolve`` with ``jaxskid.vector_field``
    (``benchmarks/tradeoff_rollouts.py`` times both on the Panda and the 12-DOF quadruped).
    """

    order = 4
    tableau: ClassVar[ExplicitTableau] = RK4_TABLEAU
    """The nodes and weights; the runtime's one-call steps (:mod:`jaxskid.runtime._rk4`) serve this tableau."""

    def step(self, f: Callable, t, y, dt):
        def axpy(a, dy, base):
            return jax.tree.map(lambda u, v: u + a * v, base, dy)

        def stage(carry, cb):
            k, acc = carry
            c, b = cb
            ki, aux = f(t + c * dt, axpy(c * dt, k, y))
            return (ki, axpy(b, ki, acc)), aux

        zero = jax.tree.map(jnp.zeros_like, y)
        dtype = jnp.result_type(dt)
        cb = (jnp.asarray(self.tableau.c, dtype), jnp.asarray(self.tableau.b, dtype))
        (_, incr), aux = jax.lax.scan(stage, (zero, zero), cb)
        return axpy(dt, incr, y), jax.tree.map(lambda a: a[0], aux)


def classical_rk4(integrator) -> bool:
    """Whether ``integrator`` takes :class:`RK4`'s own step on the classical tableau: the runtime's one-call
    steps (:mod:`jaxskid.runtime._rk4`), which run that tableau's stages, then serve it."""
    return isinstance(integrator, RK4) and type(integrator).step is RK4.step and integrator.tableau == RK4_TABLEAU


def fixed_step(integrator):
    """``integrator``, checked to be a fixed-step integrator of this module's kind (any object with
    ``step(f, t, y, dt)``)."""
    if not callable(getattr(integrator, "step", None)):
        raise RequestError(f"rollout: integrator: expected RK4(), SemiImplicitEuler() or a diffrax solver, "
                           f"got {integrator!r}")
    return integrator
