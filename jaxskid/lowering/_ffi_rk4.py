"""The backward pass of one classical Runge-Kutta step of a fixed-base robot under a held torque, as one native
handler (appended to the backward step's library by :func:`jaxskid.lowering._ffi.glue_source`).

For ``y = (q, qd)``, ``dy/dt = (qd, a(q, qd, tau, p))`` with ``tau`` held over the step, the step is
``y_1 = y``, ``y_i = y + c_i h k_(i-1)``, ``k_i = (qd_i, a_i)``, ``y+ = y + h sum_i b_i k_i`` (``c = 0, 1/2,
1/2, 1``, ``b = 1/6, 1/3, 1/3, 1/6``). Given the cotangent ``g`` of ``y+``, the stages are visited from the
last: ``kbar_i = h b_i g + c_(i+1) h ybar_(i+1)``, and the cotangent of stage i's input is ``ybar_i = J_i^T
kbar_i``, with ``J_i^T`` from the backward step of forward dynamics (``lambda = M^-1 kbar_i[qd]``, ``-lambda^T
d ID/d(q, qd, p)``): ``ybar_i = ((da/dq)^T kbar[qd], kbar[q] + (da/dqd)^T kbar[qd])``. The step's cotangents sum
them: ``ybar = g + sum_i ybar_i``, ``taubar = sum_i lambda_i``, ``pbar = sum_i (da/dp)^T kbar_i[qd]``, and
``hbar = sum_i b_i g . k_i + sum_(i>1) c_i ybar_i . k_(i-1)``.

``jaxskid_rk4_vjp(q, qd, a, p, h, gq, gqd) -> [ybar_q, ybar_qd, taubar, pbar, hbar]`` takes the four stages'
``q``, ``qd`` and accelerations as ``(4, n)`` each. In a rollout's gradient it replaces four calls of the
backward step and the loop over the stages around them (:mod:`jaxskid.runtime._rk4`).

Under feedback ``tau_i = u(t_i, q_i, qd_i)`` the stage's acceleration depends on its input through the torque
too: ``da_i/dy_i = dFD/dy + M^-1 K_i`` with the controller's Jacobian ``K_i = du/d(q, qd)`` ``(n, 2n)``, so
``ybar_i`` gains ``K_i^T lambda_i``. ``jaxskid_rk4fb_vjp(q, qd, a, K, p, h, gq, gqd) -> [ybar_q, ybar_qd,
lambda, pbar, hbar]`` takes the four stages' ``K`` ``(4, n, 2n)`` and returns each stage's ``lambda_i``
``(4, n)``, the cotangent of its torque, from which the caller takes the controller's own vector-Jacobian
product (its gains and parameters, and the stage times).
"""

from .._tableau import RK4_TABLEAU
from ._templates import fill, template

RK4_STEP = fill(template("rk4_backward.h"), RK4_B=", ".join(map(repr, RK4_TABLEAU.b)),
                RK4_C=", ".join(map(repr, RK4_TABLEAU.c)))
"""One state's RK4 backward step (``rk4_backward``, on ``backward``), shared by the CPU handlers and the GPU's
rollout kernels (:mod:`._cuda_rollout`)."""

RK4_BACKWARD = fill(template("ffi_rk4.c"), RK4_STEP=RK4_STEP)
"""The C of ``jaxskid_rk4_vjp`` and ``jaxskid_rk4fb_vjp``, after the backward step's (``backward``, ``NO``,
``load``, ``store``, ``parallel_for``), with the tableau of :data:`jaxskid._tableau.RK4_TABLEAU`."""

