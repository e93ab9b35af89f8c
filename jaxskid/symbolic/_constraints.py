"""The constraints of a robot in closed form: their Jacobian ``A(q)``, drift ``Adot qd`` and residual ``phi(q)``.

Each constraint (:mod:`jaxskid.model._constraint`) holds frame a to frame b, or to a fixed anchor, along
world-aligned axes (rotations ``rx, ry, rz`` first, then translations ``x, y, z``). With the hybrid
quantities of the frames (:mod:`._frames`: world axes, at the frame's origin), its rows are

* ``A(q) = J^h_a(q) - J^h_b(q)``: the rows of the hybrid Jacobians (:func:`~._jacobians.hybrid_jacobian`), so
  the columns are those of every Jacobian: one per velocity coordinate;
* ``Adot(q, qd) qd = dV^h_a/dt - dV^h_b/dt`` at ``qdd = 0``: the hybrid accelerations
  (:func:`~._frames.hybrid_acceleration`) of the body accelerations with the velocity terms alone
  (``Terms.CORIOLIS``), the closed form of ``dJ^h/dt qd`` without its columns;
* ``phi(q)``: ``p_a - p_b`` along the translations and ``vee(E - E^T) / 2`` of ``E = R_a R_b^T`` about the
  rotations, whose time derivative is ``A qd`` (along rotations: where ``R_a = R_b``).

so that a motion that keeps ``phi = 0`` has ``A qd = 0`` and ``A qdd + Adot qd = 0``. Rows follow the
constraints' order and, within one, the order of :data:`~jaxskid.model._constraint.AXES`.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..model._constraint import AXES
from ._derivation import Derivation
from ._frames import frame_motion, frame_pose, hybrid_acceleration, to_frame
from ._jacobians import hybrid_jacobian
from ._kinematics import Terms, Vec, acceleration, pose_rows, zero6


def _axes(c) -> list[int]:
    return [AXES.index(a) for a in c.axes]


def constraint_jacobian(d: Derivation) -> list[list]:
    """``A(q)``: one row per constraint axis, one column per column of the frames' hybrid Jacobians."""
    rows = []
    for c in d.robot.constraints:
        a = hybrid_jacobian(d, c.frames[0])
        b = hybrid_jacobian(d, c.frames[1]) if c.frames[1] is not None else None
        for k in _axes(c):
            rows.append([col[k] - (b[j][k] if b is not None else 0) for j, col in enumerate(a)])
    return rows


def _drift(d: Derivation, name: str) -> Vec:
    """``dJ^h/dt qd`` of a named frame: its hybrid acceleration at ``qdd = 0``, without gravity."""
    body = d.robot.frame(name).body
    if not d.is_body(body):
        return zero6()
    r = frame_pose(d, name)[0]
    return hybrid_acceleration(d, r, frame_motion(d, name, 0), to_frame(d, name, acceleration(d, body, Terms.CORIOLIS)))


def constraint_drift(d: Derivation) -> list:
    """``Adot(q, qd) qd``: one entry per constraint axis."""
    out = []
    for c in d.robot.constraints:
        a = _drift(d, c.frames[0])
        b = _drift(d, c.frames[1]) if c.frames[1] is not None else zero6()
        out.extend(a[k] - b[k] for k in _axes(c))
    return out


def _rotation_residual(ra: Sequence[Sequence], rb: Sequence[Sequence], k: int):
    """Entry k of ``vee(E - E^T) / 2`` with ``E = R_a R_b^T``: ``(E_21 - E_12) / 2`` for k = 0, ..."""
    i, j = ((2, 1), (0, 2), (1, 0))[k]

    def e(r, s):
        return sum(ra[r][m] * rb[s][m] for m in range(3))

    return (e(i, j) - e(j, i)) / 2


def constraint_residual(d: Derivation) -> list:
    """``phi(q)``: one entry per constraint axis (module docstring)."""
    out = []
    for c in d.robot.constraints:
        ra, pa = frame_pose(d, c.frames[0])
        rb, pb = frame_pose(d, c.frames[1]) if c.frames[1] is not None else pose_rows(c.anchor)
        for k in _axes(c):
            out.append(d.tape(_rotation_residual(ra, rb, k)) if k < 3 else pa[k - 3] - pb[k - 3])
    return out
