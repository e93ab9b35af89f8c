"""Named frames (bodies, merged links, end-effectors): poses, twists, accelerations and loads.

A frame sits at a constant offset ``T_f`` on its body. Kinematic set (Müller, "Screw and Lie group theory
in multibody kinematics", Multibody Syst Dyn 43, 2018): *body* quantities are in the moving frame's own
coordinates; *hybrid* ones are at the frame's origin in world axes, ``V^h = (R omega^b, R v^b) =
(omega, dp/dt)``, and the hybrid acceleration is the time derivative of the hybrid twist,
``dV^h/dt = (domega/dt, d^2p/dt^2) = (R domega^b/dt, R (dv^b/dt + omega^b x v^b))`` (the classical
acceleration of the origin). The body acceleration ``dV^b/dt`` is Pinocchio's spatial acceleration in
``LOCAL``; Pinocchio's ``LOCAL_WORLD_ALIGNED`` spatial acceleration is ``(R domega^b/dt, R dv^b/dt)`` and
differs from ours by ``(0, omega x v)``. A frame on body ``-1`` is fixed to the world, or moves with the
floating base.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import sympy as sp

from ..model import _spatial as sa
from ._derivation import Derivation
from ._kinematics import Terms, Vec, absolute, acceleration, is_zero, pose_rows, twist, zero6


def is_identity(offset: sp.Matrix) -> bool:
    return sp.Matrix(offset) == sp.eye(4)


def frame_pose(d: Derivation, name: str) -> tuple[list[Vec], Vec]:
    """(R, p) of a named frame in the world frame."""
    f = d.robot.frame(name)
    ro, po = pose_rows(f.offset)
    if not d.is_body(f.body):
        return ro, po
    rb, pb = absolute(d, f.body)
    if is_identity(f.offset):
        return rb, pb
    return sa.compose(rb, pb, ro, po, d.tape.vec)


def to_frame(d: Derivation, name: str, v: Sequence) -> Vec:
    """A motion vector of the frame's body, in body coordinates -> the frame's: ``Ad(T_f^-1) v``."""
    offset = d.robot.frame(name).offset
    if is_zero(v) or is_identity(offset):
        return list(v)
    return d.tape.vec(sa.act_inv_motion(*pose_rows(offset), v))


def body_loads(d: Derivation, wrenches: Mapping[str, Sequence]) -> dict[int, Vec]:
    """Wrenches (moment, force) given in named frames, summed per body in body coordinates:
    ``sum_f Ad(T_f^-1)^T W_f`` (body ``-1``: the floating base). Frames fixed to the world carry no load."""
    out: dict[int, Vec] = {}
    for name, w in wrenches.items():
        f = d.robot.frame(name)
        if d.is_body(f.body):
            out[f.body] = sa.add(out.get(f.body, [0] * 6), sa.act_force(*pose_rows(f.offset), w))
    return out


def frame_motion(d: Derivation, name: str, k: int) -> Vec:
    """Body twist (k = 0) or body acceleration (k = 1) of a named frame, in its own coordinates."""
    body = d.robot.frame(name).body
    if not d.is_body(body):
        return zero6()
    return to_frame(d, name, twist(d, body) if k == 0 else acceleration(d, body, Terms.MOTION))


def hybridize(d: Derivation, r, v: Sequence) -> Vec:
    """Body-fixed 6-vector -> hybrid (frame origin, world axes): ``(R w, R v)``."""
    if is_zero(v):
        return zero6()
    return d.tape.vec([*sa.matvec(r, v[:3]), *sa.matvec(r, v[3:])])


def hybrid_acceleration(d: Derivation, r, v: Sequence, vd: Sequence) -> Vec:
    """``d/dt (R omega, R v) = (R domega, R (dv + omega x v))`` from body twist v and its derivative vd."""
    return hybridize(d, r, [*vd[:3], *sa.add(vd[3:], sa.cross(v[:3], v[3:]))])


def body_hybrid_twist(d: Derivation, i: int) -> Vec:
    """Hybrid twist ``(R_i omega_i, dp_i/dt)`` of body i."""
    return hybridize(d, absolute(d, i)[0], twist(d, i))


def body_hybrid_acceleration(d: Derivation, i: int) -> Vec:
    """Hybrid acceleration ``(domega_i/dt, d^2p_i/dt^2)`` of body i."""
    return hybrid_acceleration(d, absolute(d, i)[0], twist(d, i), acceleration(d, i, Terms.MOTION))


def frame_hybrid_twist(d: Derivation, name: str) -> Vec:
    """Hybrid twist ``(omega, dp/dt)`` of a named frame."""
    return hybridize(d, frame_pose(d, name)[0], frame_motion(d, name, 0))


def frame_hybrid_acceleration(d: Derivation, name: str) -> Vec:
    """Hybrid acceleration ``(domega/dt, d^2p/dt^2)`` of a named frame."""
    r = frame_pose(d, name)[0]
    return hybrid_acceleration(d, r, frame_motion(d, name, 0), frame_motion(d, name, 1))
