"""End-effector wrenches of a description: Skidy's convention, jaxskid's, and the conversion between them.

Skidy (``src/skidy/kinematics_generator.py``, ``_closed_form_inv_dyn_body_fixed``) writes ``WEE[i]`` into the
rows of body ``ee_parent[i]`` of the stacked body wrenches ``W_ext`` and adds ``Q_ext = J^T W_ext`` to
``M q2d + C qd + Q_grav``, with ``J`` the body-fixed system Jacobian. So each wrench ``W_p = (n_p, f_p)``
acts at the origin of the end-effector's parent body, in that body's frame: ``Q_ext = J_p^T W_p``, with
``J_p`` the parent's body Jacobian (its twist ``(omega, v)`` in its own frame). jaxskid's ``wrench``
argument, ``(n_ee, 6)`` with rows in the order of ``Robot.end_effectors``, acts at the origin of the
end-effector frame, in that frame: ``Q_ext = sum_e J_e^T W_e``. Both add ``Q_ext`` to the joint forces, so
in both ``W`` is the wrench the robot exerts on its surroundings.

The conversion. With ``C = (R, p)`` the end-effector's pose in its parent's frame (the ``ee`` entry),
``J_e = Ad(C^-1) J_p``, so ``J_e^T W_e = J_p^T Ad(C^-1)^T W_e``, and the two agree when
``W_e = Ad(C)^T W_p = (R^T (n_p - p x f_p), R^T f_p)``: the moment is taken about the end-effector's
origin, and both parts are turned into its axes (the change of frame of a wrench, Lynch & Park, "Modern
Robotics", 2017, sec. 3.4: ``F_b = Ad(T_ab)^T F_a``). ``C`` is constant, so the time derivatives ``WDEE``
and ``W2DEE`` convert the same way.

Where two end-effectors share a parent body, Skidy keeps only the last one's wrench (it assigns the rows
of ``W_ext``, it does not add them); jaxskid adds both.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import sympy as sp

from ..model import _lie as lie

Wrenches = tuple[tuple[sp.Expr, ...], ...]
"""One 6-vector ``(moment, force)`` per end-effector."""


@dataclass(frozen=True)
class DescriptionExtras:
    """What a description gives beyond the :class:`Robot`: symbol names and end-effector wrenches.

    ``q``, ``qd``, ``q2d``, ``q3d``, ``q4d``: the names of the joint positions and their time derivatives (n
    each; Skidy's defaults ``d<q>``, ``dd<q>``.. when absent). ``end_effectors``: the end-effector names.

    ``wrench``, ``wrench_d``, ``wrench_2d``: ``WEE``, ``WDEE``, ``W2DEE`` in jaxskid's convention, one
    6-vector ``(moment, force)`` per end-effector in the order of ``end_effectors``, acting at the
    end-effector frame's origin in that frame: the values to pass as the ``wrench`` arguments
    (``inverse_dynamics(..., wrench=)``, ``external_torques``), which then give Skidy's ``J_p^T W``.

    ``wrench_skidy``, ``wrench_d_skidy``, ``wrench_2d_skidy``: the same as written in the file, in Skidy's
    convention: at the origin of the end-effector's parent body, in that body's frame. Zeros when absent;
    see :func:`end_effector_wrench` for the conversion.
    """

    q: tuple[str, ...]
    qd: tuple[str, ...]
    q2d: tuple[str, ...]
    q3d: tuple[str, ...]
    q4d: tuple[str, ...]
    end_effectors: tuple[str, ...]
    wrench: Wrenches
    wrench_d: Wrenches
    wrench_2d: Wrenches
    wrench_skidy: Wrenches
    wrench_d_skidy: Wrenches
    wrench_2d_skidy: Wrenches


def end_effector_wrench(wrench: Sequence, offset: sp.Matrix) -> tuple[sp.Expr, ...]:
    """Skidy's wrench ``W_p = (n_p, f_p)``, at the origin of an end-effector's parent body in that body's
    frame, as jaxskid's wrench at the end-effector frame, whose pose in the parent's frame is ``offset``
    (4x4): ``W_e = Ad(C)^T W_p = (R^T (n_p - p x f_p), R^T f_p)``, so that ``J_e^T W_e = J_p^T W_p``."""
    return tuple(lie.adjoint(offset).T * sp.Matrix(list(wrench)))


def end_effector_wrenches(wrenches: Wrenches, offsets: Sequence[sp.Matrix]) -> Wrenches:
    """:func:`end_effector_wrench` for each end-effector; ``offsets`` in the order of ``wrenches``."""
    return tuple(end_effector_wrench(w, c) for w, c in zip(wrenches, offsets, strict=True))
