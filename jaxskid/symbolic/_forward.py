"""Closed-form forward dynamics on the tape: ``qdd = M^-1 (tau - C qd - Q_grav)`` without a matrix solve.

The mass matrix from the composite-rigid-body algorithm and the bias from one Newton-Euler pass are
factored *symbolically* as ``M = L^T D L`` with the branch-induced sparsity of the tree (Featherstone,
"Efficient factorization of the joint-space inertia matrix for branched kinematic trees", IJRR 24(6),
2005, Alg. LTDL), then solved by substitution: about ``n d^2 / 2`` extra operations for depth ``d``.
Lowered like any quantity, the whole of forward dynamics becomes one fused kernel. Registered as the
quantity ``forward_dynamics``; :meth:`jaxskid.Dynamics.forward_dynamics` uses it when it was lowered and
otherwise solves with the lowered M and bias numerically (:func:`jaxskid._simulate.accelerations`).
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ..equations._derive import QuantitySpec, register
from ._kinematics import Kinematics


def forward_dynamics_outputs(kin: Kinematics, tau: Sequence[sp.Symbol]) -> list:
    """``qdd`` (n expressions on ``kin.tape``) for joint forces ``tau``, by the sparse ``L^T D L`` of M."""
    t = kin.tape
    n = kin.n
    lam = list(kin.robot.parents)
    m = kin.mass_matrix()
    bias = kin.rnea(velocity=True, accel=False, gravity=True)
    h = [[m[i, j] for j in range(n)] for i in range(n)]
    recip = [None] * n
    for k in reversed(range(n)):  # Featherstone 2005, Alg. LTDL: h becomes L (below the diagonal) and D
        recip[k] = t(1 / h[k][k])
        i = lam[k]
        while i != -1:
            a = t(h[k][i] * recip[k])
            j = i
            while j != -1:
                h[i][j] = t(h[i][j] - a * h[k][j])
                j = lam[j]
            h[k][i] = a
            i = lam[i]
    x = [t(tau[i] - bias[i]) for i in range(n)]
    for i in reversed(range(n)):  # L^T y = b
        j = lam[i]
        while j != -1:
            x[j] = t(x[j] - h[i][j] * x[i])
            j = lam[j]
    x = [t(x[i] * recip[i]) for i in range(n)]  # D z = y
    for i in range(n):  # L qdd = z
        j = lam[i]
        while j != -1:
            x[i] = t(x[i] - h[i][j] * x[j])
            j = lam[j]
    return x


register(QuantitySpec(
    "forward_dynamics", ("q", "qd", "tau"), lambda r: (r.n_dof,),
    lambda k: forward_dynamics_outputs(k, k.tau_symbols),
    "qdd = M(q)^-1 (tau - C(q, qd) qd - Q_grav(q))",
    "Forward dynamics in closed form: M = L^T D L factored symbolically with the tree's sparsity "
    "(Featherstone 2005), then solved by substitution. End-effector wrenches: pass tau - Q_ext.",
))
