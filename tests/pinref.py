"""Reference computations with Pinocchio for jaxskid's tests.

``to_pinocchio`` rebuilds a jaxskid Robot (with numeric parameter values) as a Pinocchio model, using only
Pinocchio's own joint models and spatial algebra; the dynamics are then computed by Pinocchio's algorithms
(rnea, crba, computeCoriolisMatrix, computeGeneralizedGravity), independently of jaxskid's derivation.

Conventions: Pinocchio orders twists (v, omega) and jaxskid (omega, v); a revolute joint's axis passes
through the Pinocchio joint frame's origin, so a jaxskid screw with an offset (v != 0) gets a joint frame
placed on its axis, and the body is placed relative to it.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import sympy as sp

from jaxskid import Robot, symbol


def numeric(robot: Robot, params: dict[str, float]):
    sub = {symbol(k): v for k, v in params.items()}

    def num(m):
        return np.array(sp.Matrix(m).xreplace(sub).evalf(), dtype=float)

    return num


def _translation(r):
    return pin.SE3(np.eye(3), np.asarray(r, dtype=float).reshape(3))


def _se3(m4):
    return pin.SE3(np.array(m4[:3, :3], dtype=float), np.array(m4[:3, 3], dtype=float))


def inertia_to_pin(m6: np.ndarray) -> pin.Inertia:
    """jaxskid 6x6 (omega, v) mass-inertia about the frame origin -> pin.Inertia."""
    m = m6[5, 5]
    if m <= 0:
        return pin.Inertia.Zero()
    mcx = m6[:3, 3:]
    c = np.array([mcx[2, 1], mcx[0, 2], mcx[1, 0]]) / m
    cx = pin.skew(c)
    ic = m6[:3, :3] + m * cx @ cx
    return pin.Inertia(m, c, ic)


def to_pinocchio(robot: Robot, params: dict[str, float]):
    """(model, frame names) with one Pinocchio joint per jaxskid joint, in the same order; a floating base is a
    ``JointModelFreeFlyer`` first, carrying the base inertia (Pinocchio's q, v layouts then: see
    :func:`velocity_to_pin`)."""
    num = numeric(robot, params)
    model = pin.Model()
    g = num(sp.Matrix(robot.gravity)).reshape(3)
    model.gravity = pin.Motion(g, np.zeros(3))
    root = 0
    if robot.floating_base:
        root = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "root_joint")
        model.appendBodyToJoint(root, inertia_to_pin(num(robot.base_inertia)), pin.SE3.Identity())
    joint_ids = []
    shift = []  # translation from the Pinocchio joint frame to the jaxskid body frame
    for i, j in enumerate(robot.joints):
        x = num(sp.Matrix(j.screw)).reshape(6)
        w, v = x[:3], x[3:]
        if j.type == "revolute":
            r = np.cross(w, v)  # closest point of the axis to the body origin
            jm = pin.JointModelRevoluteUnaligned(w / np.linalg.norm(w))
        else:
            r = np.zeros(3)
            jm = pin.JointModelPrismaticUnaligned(v / np.linalg.norm(v))
        b = _se3(num(j.origin))
        parent_id = root if j.parent < 0 else joint_ids[j.parent]
        parent_shift = np.zeros(3) if j.parent < 0 else shift[j.parent]
        placement = _translation(-parent_shift) * b * _translation(r)
        jid = model.addJoint(parent_id, jm, placement, j.name)
        body_in_joint = _translation(-r)
        model.appendBodyToJoint(jid, inertia_to_pin(num(j.inertia)).se3Action(body_in_joint), pin.SE3.Identity())
        joint_ids.append(jid)
        shift.append(r)
    names = []
    for name in robot.frame_names:
        f = robot.frame(name)
        off = _se3(num(f.offset))
        if f.body < 0:
            model.addFrame(pin.Frame(name, root, 0, off, pin.FrameType.OP_FRAME))
        else:
            model.addFrame(
                pin.Frame(name, joint_ids[f.body], 0, _translation(-shift[f.body]) * off, pin.FrameType.OP_FRAME)
            )
        names.append(name)
    return model, names


def velocity_to_pin(x: np.ndarray, floating: bool, axis: int = -1) -> np.ndarray:
    """A velocity-space array in jaxskid's order (a floating base's (omega, v) first) in Pinocchio's ((v, omega)
    first) along ``axis``; unchanged for a fixed base. Its own inverse."""
    if not floating:
        return x
    idx = np.r_[3:6, 0:3, 6:x.shape[axis]]
    return np.take(x, idx, axis=axis)


def to_omega_v(m6_pin: np.ndarray) -> np.ndarray:
    """Pinocchio (v, omega) 6x6 -> jaxskid (omega, v)."""
    p = np.block([[np.zeros((3, 3)), np.eye(3)], [np.eye(3), np.zeros((3, 3))]])
    return p @ m6_pin @ p


def motion_to_omega_v(m) -> np.ndarray:
    return np.concatenate([m.angular, m.linear])


def jac_to_omega_v(j: np.ndarray) -> np.ndarray:
    return np.vstack([j[3:], j[:3]])
