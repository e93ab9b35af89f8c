"""Symbolic SE(3) helpers on SymPy matrices, used to describe robots.

Conventions (Müller 2018, "Screw and Lie group theory in multibody kinematics"; Lynch & Park 2017, ch. 3):

* a pose is a 4x4 homogeneous matrix ``C = [[R, p], [0, 1]]``;
* a twist or screw is a 6-vector ``(omega, v)``, angular part first;
* a wrench is a 6-vector ``(moment, force)``, dual to the twist;
* ``Ad(C) = [[R, 0], [p~ R, R]]`` maps twists from the frame of ``C`` to its reference frame;
* a 6x6 mass-inertia matrix in a body frame is ``[[I_o, m c~], [-m c~, m 1]]``, with ``I_o`` the rotational
  inertia about the frame's origin and ``c`` the centre of mass.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from .._errors import ModelError
from . import _spatial

AXES = ("rx", "ry", "rz", "x", "y", "z")
"""The directions of a constraint's rows (:mod:`jaxskid.model._constraint`), world-aligned: rotations about,
then translations along, the world axes, in the order of a twist's (omega, v)."""

Matrix = sp.ImmutableMatrix


def skew(v: Sequence) -> sp.Matrix:
    """3x3 cross-product matrix: ``skew(a) @ b == a x b``."""
    return sp.Matrix(_spatial.skew(v))


def unskew(m: sp.Matrix) -> list:
    return [m[2, 1], m[0, 2], m[1, 0]]


def pose(rotation=None, translation=None) -> Matrix:
    """4x4 pose from a 3x3 rotation (identity if None) and a 3-vector (zero if None)."""
    r = sp.eye(3) if rotation is None else sp.Matrix(rotation)
    t = sp.zeros(3, 1) if translation is None else sp.Matrix(list(translation))
    top = r.row_join(t)
    return Matrix(top.col_join(sp.Matrix([[0, 0, 0, 1]])))


def rotation_of(c: sp.Matrix) -> sp.Matrix:
    return sp.Matrix(c[:3, :3])


def translation_of(c: sp.Matrix) -> sp.Matrix:
    return sp.Matrix(c[:3, 3])


def rot_axis_angle(axis: Sequence, angle) -> sp.Matrix:
    """SO(3) exponential (Rodrigues): rotation by ``angle`` about the unit ``axis``."""
    w = skew(axis)
    angle = sp.sympify(angle)
    return sp.eye(3) + sp.sin(angle) * w + (1 - sp.cos(angle)) * (w * w)


def rot_rpy(roll, pitch, yaw) -> sp.Matrix:
    """URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll), fixed axes x, y, z."""
    return (
        rot_axis_angle((0, 0, 1), yaw) * rot_axis_angle((0, 1, 0), pitch) * rot_axis_angle((1, 0, 0), roll)
    )


def rot_quaternion(w, x, y, z) -> sp.Matrix:
    """Rotation of the unit quaternion ``w + x i + y j + z k``."""
    w, x, y, z = (sp.sympify(a) for a in (w, x, y, z))
    return sp.Matrix(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def pose_xyzrpy(x, y, z, roll, pitch, yaw) -> Matrix:
    return pose(rot_rpy(roll, pitch, yaw), (x, y, z))


def inverse(c: sp.Matrix) -> Matrix:
    r, p = rotation_of(c), translation_of(c)
    return pose(r.T, -r.T * p)


def adjoint(c: sp.Matrix) -> sp.Matrix:
    """Ad(C) = [[R, 0], [p~ R, R]] for twists in (omega, v) order."""
    r, p = rotation_of(c), translation_of(c)
    top = r.row_join(sp.zeros(3))
    bottom = (skew(p) * r).row_join(r)
    return top.col_join(bottom)


def ad(twist: Sequence) -> sp.Matrix:
    """ad(V) = [[w~, 0], [v~, w~]], the Lie bracket ``ad(V) X = [V, X]``."""
    w, v = list(twist[:3]), list(twist[3:])
    top = skew(w).row_join(sp.zeros(3))
    bottom = skew(v).row_join(skew(w))
    return top.col_join(bottom)


def screw_exp(screw: Sequence, angle) -> Matrix:
    """SE(3) exponential exp(X angle) of the screw ``X = (omega, v)`` (Lynch & Park eq. 3.88).

    ``omega`` is a unit vector or zero. For a pure rotation (omega . v = 0) the translation is
    ``(1 - R)(omega x v)``; the pitch term ``omega (omega . v) angle`` is kept in general.
    """
    w = sp.Matrix(list(screw[:3]))
    v = sp.Matrix(list(screw[3:]))
    angle = sp.sympify(angle)
    if all(sp.sympify(e) == 0 for e in w):
        return pose(None, v * angle)
    r = rot_axis_angle(w, angle)
    p = (sp.eye(3) - r) * w.cross(v) + w * (w.dot(v)) * angle
    return pose(r, p)


def screw(joint_type: str, axis: Sequence, point: Sequence | None = None) -> tuple:
    """Unit screw coordinates (omega, v) of a revolute or prismatic joint.

    revolute: axis through ``point``, ``v = point x axis`` (so ``v = -omega x point``);
    prismatic: ``(0, axis)``.
    """
    axis = [sp.sympify(a) for a in axis]
    if joint_type == "revolute":
        r = sp.Matrix([sp.sympify(a) for a in (point or (0, 0, 0))])
        v = r.cross(sp.Matrix(axis))
        return (*axis, *v)
    if joint_type == "prismatic":
        return (0, 0, 0, *axis)
    raise ValueError(f"unknown joint type {joint_type!r}")


def spatial_inertia(mass, com=(0, 0, 0), inertia=None, *, about: str = "com") -> Matrix:
    """6x6 mass-inertia matrix in a body frame.

    ``inertia`` is a 3x3 matrix, the six values (Ixx, Ixy, Ixz, Iyy, Iyz, Izz), or None for zero. With
    ``about="com"`` it is the inertia about the centre of mass in axes parallel to the body frame, and
    the parallel-axis theorem moves it to the body origin: ``I_o = I_c - m c~ c~``. With ``about="origin"``
    it is already about the body frame's origin.
    """
    m = sp.sympify(mass)
    c = [sp.sympify(x) for x in com]
    ic = inertia_matrix(inertia)
    cx = skew(c)
    io = ic - m * cx * cx if about == "com" else ic
    top = io.row_join(m * cx)
    bottom = (-m * cx).row_join(m * sp.eye(3))
    return Matrix(top.col_join(bottom))


def inertia_matrix(inertia) -> sp.Matrix:
    """A 3x3 rotational inertia from a 3x3 matrix (SymPy, NumPy or nested sequences), the six values (Ixx, Ixy,
    Ixz, Iyy, Iyz, Izz), or None (zero)."""
    if inertia is None:
        return sp.zeros(3)
    if hasattr(inertia, "shape") and not isinstance(inertia, sp.MatrixBase):  # a NumPy or JAX array
        inertia = [[sp.sympify(x) for x in row] for row in inertia] if len(inertia.shape) == 2 else list(inertia)
    if isinstance(inertia, (sp.MatrixBase,)) or (
        isinstance(inertia, Sequence) and len(inertia) == 3 and isinstance(inertia[0], Sequence)
    ):
        matrix = sp.Matrix(inertia)
        if matrix.shape == (3, 3):
            return matrix
    elif isinstance(inertia, Sequence) and len(inertia) == 6:
        ixx, ixy, ixz, iyy, iyz, izz = (sp.sympify(x) for x in inertia)
        return sp.Matrix([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    raise ModelError(f"expected a 3x3 inertia or its six values (Ixx, Ixy, Ixz, Iyy, Iyz, Izz), got {inertia!r}",
                     where="inertia")


def transform_inertia(m6: sp.Matrix, c: sp.Matrix) -> Matrix:
    """Mass-inertia of a body whose frame has pose ``c = (R, p)`` in a frame F, re-expressed in F.

    This is ``M_F = Ad(C^-1)^T M Ad(C^-1)`` (Lynch & Park 2017, eq. 8.42, in (omega, v) order), written
    with the standard parameters so that the result keeps the exact structure ``[[I_o, h~], [-h~, m 1]]``
    whatever the round-off in ``R``: ``m`` stays, the first moment becomes ``h_F = R h + m p``, and the
    rotational inertia about F's origin is ``I_F = R I_o R^T - (R h)~ p~ - p~ (R h)~ - m p~ p~`` (the
    parallel-axis theorem with ``c_F = R c + p``).
    """
    m6 = sp.Matrix(m6)
    r, p = rotation_of(c), translation_of(c)
    m = m6[5, 5]
    rh = r * sp.Matrix(unskew(m6[:3, 3:]))
    px, rhx = skew(p), skew(rh)
    i_f = r * m6[:3, :3] * r.T - rhx * px - px * rhx - m * px * px
    return inertia_from_parameters(m, *(rh + m * p), *_upper(i_f))


def _upper(i3: sp.Matrix) -> tuple:
    """(Ixx, Ixy, Iyy, Ixz, Iyz, Izz) of a 3x3 inertia, each off-diagonal entry averaged with its mirror."""
    def mean(a, b):
        return a if a == b else (a + b) / 2

    return (i3[0, 0], mean(i3[0, 1], i3[1, 0]), i3[1, 1], mean(i3[0, 2], i3[2, 0]), mean(i3[1, 2], i3[2, 1]),
            i3[2, 2])


def inertia_from_parameters(m, mcx, mcy, mcz, ixx, ixy, iyy, ixz, iyz, izz) -> Matrix:
    """The 6x6 mass-inertia ``[[I_o, (mc)~], [-(mc)~, m 1]]`` of the 10 standard parameters, in the order of
    :data:`STANDARD_PARAMETER_NAMES` (the inverse of :func:`standard_parameters`)."""
    io = sp.Matrix([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    mc = skew([mcx, mcy, mcz])
    return Matrix(io.row_join(mc).col_join((-mc).row_join(m * sp.eye(3))))


def standard_parameters(m6: sp.Matrix) -> tuple:
    """The 10 standard inertial parameters (m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz) of a 6x6
    mass-inertia matrix, inertia about the frame origin (Pinocchio's ``Inertia.toDynamicParameters``
    order)."""
    m6 = sp.Matrix(m6)
    m = m6[5, 5]
    mc = unskew(m6[:3, 3:])
    io = m6[:3, :3]
    return (m, *mc, io[0, 0], io[0, 1], io[1, 1], io[0, 2], io[1, 2], io[2, 2])


STANDARD_PARAMETER_NAMES = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")


def spatial_to_body(
    screws_world: Sequence[Sequence],
    poses_world: Sequence[sp.Matrix],
    parents: Sequence[int],
) -> tuple[list[tuple], list[sp.ImmutableMatrix]]:
    """Convert the spatial representation to the body-fixed one.

    Given each joint's screw ``Y_i`` in world coordinates and each body's reference pose ``A_i`` in the
    world at ``q = 0``, returns ``X_i = Ad(A_i^-1) Y_i`` and ``B_i = A_{p(i)}^-1 A_i`` (Müller 2018, eq. 25).
    """
    screws, origins = [], []
    for i, (y, a) in enumerate(zip(screws_world, poses_world)):
        a = sp.Matrix(a)
        x = adjoint(inverse(a)) * sp.Matrix(list(y))
        screws.append(tuple(sp.expand(e) for e in x))
        p = parents[i]
        b = a if p < 0 else inverse(poses_world[p]) * a
        origins.append(sp.ImmutableMatrix(b.applyfunc(sp.expand)))
    return screws, origins
