"""Jacobians and their time derivatives on the tape.

Column j of body i's body Jacobian is ``J_{i,j} = Ad(C_i^-1 C_j) X_j`` for the joints j that support i,
built down the tree as ``J_{i,j} = T_i J_{p,j}``; its time derivative follows from
``dT_i/dt = -qd_i ad(X_i) T_i`` as ``Jd_{i,j} = T_i Jd_{p,j} - qd_i ad(X_i) J_{i,j}`` (Müller & Kumar 2021,
sec. 2). The system Jacobian ``J = (I - A)^-1 X`` stacks the body Jacobians; a frame's Jacobian is its
body's, moved by the frame's offset, and the hybrid Jacobian ``J^h = blockdiag(R, R) J`` (Müller 2018).
A floating base (body ``-1``) has the six columns ``e_c`` of its screw matrix ``X = I_6`` (keys
:data:`~._derivation.BASE_COLUMNS`), constant in its own frame, so every body gets six base columns
``Ad(C_i^-1 C_b) e_c`` and the system Jacobian a block row for the base, ``(I_6, 0)``.
"""

from __future__ import annotations

import sympy as sp

from ..model import _lie as lie
from ..model import _spatial as sa
from ._derivation import BASE_COLUMNS, Derivation, memoized
from ._frames import frame_motion, frame_pose, hybridize, is_identity, to_frame
from ._kinematics import Vec, pose_rows, screw, to_child, zero6


@memoized
def jacobian_columns(d: Derivation, i: int) -> dict[int, Vec]:
    """Columns of body i's body Jacobian: joint j -> ``Ad(C_i^-1 C_j) X_j`` for j supporting i (and the
    floating base's six, keyed by :data:`BASE_COLUMNS`; body ``i = -1`` has those alone, ``e_c``)."""
    if i < 0:
        return {key: [sp.Integer(int(r == key[1])) for r in range(6)] for key in BASE_COLUMNS}
    parent = d.robot.joints[i].parent
    cols = {}
    if d.is_body(parent):
        for j, col in jacobian_columns(d, parent).items():
            cols[j] = to_child(d, i, col)
    cols[i] = screw(d, i)
    return cols


@memoized
def jacobian_dot_columns(d: Derivation, i: int) -> dict[int, Vec]:
    """Time derivative of :func:`jacobian_columns`: ``Jd_{i,j} = T_i Jd_{p,j} - qd_i ad(X_i) J_{i,j}`` (zero
    for the floating base's own columns)."""
    if i < 0:
        return {key: zero6() for key in BASE_COLUMNS}
    parent = d.robot.joints[i].parent
    x = screw(d, i)
    cols = {}
    if d.is_body(parent):
        cur = jacobian_columns(d, i)
        for j, col in jacobian_dot_columns(d, parent).items():
            moved = to_child(d, i, col)
            cols[j] = d.tape.vec(sa.add(moved, sa.scale(sa.ad_apply(x, cur[j]), -d.qd[i])))
    cols[i] = zero6()
    return cols


def system_jacobian(d: Derivation) -> list[Vec]:
    """The body-fixed system Jacobian, 6 n_b x nv: block row i is body i's body Jacobian (the moving bodies
    :attr:`~._derivation.Derivation.bodies`, the floating base first)."""
    return _stacked(d, jacobian_columns)


def system_jacobian_dot(d: Derivation) -> list[Vec]:
    """Time derivative of :func:`system_jacobian`, 6 n_b x nv."""
    return _stacked(d, jacobian_dot_columns)


def _stacked(d: Derivation, columns) -> list[Vec]:
    rows = []
    for i in d.bodies:
        cols = columns(d, i)
        full = [cols.get(j, zero6()) for j in d.columns]
        rows.extend([[c[r] for c in full] for r in range(6)])
    return rows


def body_jacobian(d: Derivation, name: str) -> list[Vec]:
    """Body Jacobian of a named frame, as nv columns (omega, v) in that frame's own coordinates."""
    f = d.robot.frame(name)
    cols = [zero6() for _ in range(d.nv)]
    if not d.is_body(f.body):
        return cols
    ro, po = pose_rows(lie.inverse(sp.Matrix(f.offset)))
    for j, col in jacobian_columns(d, f.body).items():
        cols[d.position(j)] = col if is_identity(f.offset) else d.tape.vec(sa.act_motion(ro, po, col))
    return cols


def hybrid_jacobian(d: Derivation, name: str) -> list[Vec]:
    """Hybrid Jacobian of a named frame (origin velocity, world axes), as nv columns."""
    cols = body_jacobian(d, name)
    r, _ = frame_pose(d, name)
    return [hybridize(d, r, c) for c in cols]


def body_jacobian_dot(d: Derivation, name: str) -> list[Vec]:
    """Time derivative of :func:`body_jacobian`, as nv columns."""
    body = d.robot.frame(name).body
    if not d.is_body(body):
        return [zero6() for _ in range(d.nv)]
    cols = jacobian_dot_columns(d, body)
    return [to_frame(d, name, cols[j]) if j in cols else zero6() for j in d.columns]


def hybrid_jacobian_dot(d: Derivation, name: str) -> list[Vec]:
    """``dJ^h/dt = blockdiag(R, R) (omega~ J + dJ/dt)`` of a named frame, as nv columns."""
    jd = body_jacobian_dot(d, name)
    j = body_jacobian(d, name)
    r = frame_pose(d, name)[0]
    w = frame_motion(d, name, 0)[:3]
    return [hybridize(d, r, sa.add(jd[c], [*sa.cross(w, j[c][:3]), *sa.cross(w, j[c][3:])])) for c in range(d.nv)]
