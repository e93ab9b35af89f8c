"""The backward step of constrained forward dynamics as one native handler (appended to the backward step's
library by :func:`jaxskid.lowering._ffi.glue_parts`).

Constrained forward dynamics solves the KKT system ``K [qdd; lambda] = [tau - h(q, qd); gamma]``, ``K = [[M,
-A^T], [A, eps]]`` (:mod:`jaxskid.runtime._constrained`). Its reverse-mode rule is the implicit function theorem on
the residuals ``R1 = ID(q, qd, qdd, p) - A^T lambda - tau`` and ``R2 = A qdd + eps lambda - gamma``: given the
cotangent ``w`` of ``[qdd; lambda]``, solve ``K^T y = w``; the cotangent of ``tau`` is ``y1`` and that of ``(q, qd,
p)`` minus the pullback of ``y1^T R1 + y2^T R2``.

``jaxskid_kkt_vjp(q, qd, qdd, lambda, w, (alpha, beta, eps), p) -> [qbar, qdbar, taubar, pbar]`` does both in one
call of one state, in C: ``M`` and ``A`` by their generated functions, the solve through ``M = L D L^T`` and the
Schur complement ``A M^-1 A^T + eps``, and the pullback from the generated pullbacks of inverse dynamics and of
the constraint Jacobian, drift and residual (:data:`jaxskid._generated.KKT_QUANTITIES`), with ``gamma = -Adot qd -
2 alpha A qd - beta^2 phi`` (Baumgarte's terms, :class:`jaxskid.Baumgarte`). In a rollout's gradient it
replaces the dozens of XLA kernels per stage of the same rule traced in JAX (the four-bar:
``benchmarks/gradients.py --scenes four_bar``).
"""

from ._templates import template

KKT_BACKWARD = template("ffi_kkt.c")
"""The C of ``jaxskid_kkt_vjp``, after the backward step's (``backward_call``, ``MASS``, ``VJP``, ``T``), with
``@STEM@`` and ``@STEM_UPPER@`` to fill."""
