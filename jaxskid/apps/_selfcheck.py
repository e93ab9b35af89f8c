"""A numeric self-check of lowered dynamics: independent routes through the same model must agree.

Each check compares two computations that share no derivation step, on random states:

* ``tau = M qdd + C qd + Q_grav``: recursive Newton-Euler against CRBA, Christoffel C and gravity (with
  drives, whose friction is unknown here, on the part of tau even in qd: ``(tau(qd) + tau(-qd)) / 2 -
  tau(0, 0) + Q_grav``, since ``fv qd + fc sign(qd)`` is odd and ``fo`` cancels with ``tau(0, 0)``);
* ``C(q, qd) qd`` from the Coriolis matrix against the Newton-Euler Coriolis forces;
* ``dM/dt - 2C`` is skew-symmetric, with ``dM/dt`` from ``jax.jvp`` of the mass matrix (for the
  Christoffel-consistent C only; ``Options(coriolis="skidy")`` gives a C without that property);
* M is symmetric positive definite;
* closed-form forward dynamics inverts Newton-Euler: ``FD(q, qd, tau(q, qd, qdd)) = qdd``;
* the Jacobian maps velocities like a finite difference of forward kinematics.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..runtime._dynamics import Dynamics


@dataclass(frozen=True)
class Check:
    name: str
    error: float
    tolerance: float

    @property
    def ok(self) -> bool:
        return bool(np.isfinite(self.error) and self.error <= self.tolerance)


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def self_check(dyn: Dynamics, params=None, *, n_states: int = 16, seed: int = 0) -> list[Check]:
    """Run every check that the lowered quantities allow; returns one :class:`Check` per test."""
    rng = np.random.default_rng(seed)
    n = dyn.n_dof
    dtype = jnp.zeros(()).dtype
    tol = 1e-9 if dtype == jnp.float64 else 1e-3
    q, qd, qdd = (jnp.asarray(rng.uniform(-np.pi, np.pi, size=(n_states, n)), dtype) for _ in range(3))
    have = set(dyn.quantities)
    out: list[Check] = []
    if "mass_matrix" in have:
        m = np.asarray(dyn.mass_matrix(q, params))
        out.append(Check("M symmetric", _rel(m, np.swapaxes(m, -1, -2)), tol))
        eig = np.linalg.eigvalsh(m).min(axis=-1)
        out.append(Check("M positive definite (-min eigenvalue)", float(max(0.0, -eig.min())), 0.0))
    if {"inverse_dynamics", "mass_matrix", "coriolis_matrix", "gravity_torques"} <= have:
        tau = dyn.inverse_dynamics(q, qd, qdd, params)
        m = dyn.mass_matrix(q, params)
        c = dyn.coriolis_matrix(q, qd, params)
        g = dyn.gravity_torques(q, params)
        rhs = jnp.einsum("bij,bj->bi", m, qdd) + jnp.einsum("bij,bj->bi", c, qd) + g
        if dyn.driven:
            rest = dyn.inverse_dynamics(q, 0 * qd, 0 * qdd, params)
            tau = (tau + dyn.inverse_dynamics(q, -qd, qdd, params)) / 2 - rest + g
        out.append(Check("RNEA tau = M qdd + C qd + Q_grav" + (" (even in qd)" if dyn.driven else ""), _rel(tau, rhs), tol))
    if {"coriolis_matrix", "coriolis_torques"} <= have:
        c = dyn.coriolis_matrix(q, qd, params)
        out.append(Check("C(q, qd) qd = Coriolis forces", _rel(jnp.einsum("bij,bj->bi", c, qd), dyn.coriolis_torques(q, qd, params)), tol))
    if {"mass_matrix", "coriolis_matrix"} <= have and dyn.coriolis == "christoffel":  # not Skidy's C
        def mdot(qi, qdi):
            return jax.jvp(lambda x: dyn.mass_matrix(x, params), (qi,), (qdi,))[1]

        md = jax.vmap(mdot)(q, qd)
        c = dyn.coriolis_matrix(q, qd, params)
        s = np.asarray(md - 2 * c)
        out.append(Check("dM/dt - 2C skew-symmetric", _rel(s, -np.swapaxes(s, -1, -2)), tol))
    if {"forward_dynamics", "inverse_dynamics"} <= have:
        tau = dyn.inverse_dynamics(q, qd, qdd, params)
        back = dyn.forward_dynamics(q, qd, tau, params)
        # round-off grows with cond(M), large for random states of robots with light distal links
        cond = float(np.max(np.linalg.cond(np.asarray(dyn.mass_matrix(q, params))))) if "mass_matrix" in have else 1e3
        out.append(Check("forward dynamics inverts tau", _rel(back, qdd), tol * max(1.0, cond)))
    if {"forward_kinematics", "hybrid_jacobian"} <= have and dyn.end_effectors:
        h = 1e-6 if dtype == jnp.float64 else 1e-2
        poses = dyn.forward_kinematics
        jh = dyn.hybrid_jacobian(q, params)
        k = dyn.frame_names.index(dyn.end_effectors[0])
        p1 = np.asarray(poses(q + h * qd, params)[dyn.frame_names[k]])[:, :3, 3]
        p0 = np.asarray(poses(q - h * qd, params)[dyn.frame_names[k]])[:, :3, 3]
        v_fd = (p1 - p0) / (2 * h)
        v = np.einsum("bij,bj->bi", np.asarray(jh[:, 0, 3:, :]), np.asarray(qd))
        out.append(Check("hybrid Jacobian vs finite-difference FK", _rel(v, v_fd), 1e-6 if dtype == jnp.float64 else 5e-2))
    return out
