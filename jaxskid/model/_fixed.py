"""Fixed joints: locking a moving joint at a position, and welding fixed joints into their parent body.

Both work on lists of :class:`~jaxskid.Joint` and :class:`~jaxskid.Frame` (body-fixed representation, see
:mod:`jaxskid.model._robot`), before or after a :class:`~jaxskid.Robot` exists: :meth:`Robot.create` and
:meth:`Robot.lock` use them, and so does the URDF reader, which welds numeric inertias before it writes
the merged bodies' standard parameters.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import sympy as sp

from . import _lie as lie
from ._joint import Frame


def lock_joint(joint, value):
    """``joint`` fixed at position ``value``: type ``"fixed"``, origin ``B exp(X value)``, no screw, no
    drive and no mimic coupling (Müller 2018, eq. 9: the relative pose ``C_{p,i}(q_i) = B_i exp(X_i q_i)`` at
    ``q_i = value``)."""
    origin = sp.ImmutableMatrix(joint.origin * lie.screw_exp(joint.screw, value))
    return replace(joint, type="fixed", origin=origin, screw=(0,) * 6, drive=None, mimic=None)


def merge_fixed(joints: Sequence, frames: Sequence, base_inertia=None) -> tuple[list, list, sp.ImmutableMatrix | None]:
    """Weld every fixed joint's body to its parent; returns the moving joints, the frames and the base inertia.

    A fixed body's mass-inertia is moved into its parent's frame and added to the parent's
    (:func:`jaxskid.model._lie.transform_inertia`); its children and frames are re-attached to the parent,
    and the body itself stays reachable as a frame named after its link, appended after the given frames.
    Joints are in the order of ``q`` (parents first), so a fixed chain collapses from the root outwards.
    A body welded to the root (parent ``-1``) adds its inertia to ``base_inertia``, the floating base's
    (``None``: a fixed base, which drops it).
    """
    joints, frames = list(joints), list(frames)
    alive = [True] * len(joints)
    for i, j in enumerate(joints):
        if j.type != "fixed":
            continue
        alive[i] = False
        t, p = j.origin, j.parent  # pose of body i in its parent's frame
        if any(e != 0 for e in j.inertia) and (p >= 0 or base_inertia is not None):
            merged = (joints[p].inertia if p >= 0 else base_inertia) + lie.transform_inertia(j.inertia, t)
            merged = sp.ImmutableMatrix(merged.applyfunc(_tidy))
            if p >= 0:
                joints[p] = replace(joints[p], inertia=merged)
            else:
                base_inertia = merged
        for k in range(i + 1, len(joints)):
            if joints[k].parent == i:
                joints[k] = replace(joints[k], parent=p, origin=_moved(t, joints[k].origin))
        frames = [replace(f, body=p, offset=_moved(t, f.offset)) if f.body == i else f for f in frames]
        frames.append(Frame(j.link, p, t))
    new_index = {-1: -1}
    for i in range(len(joints)):
        if alive[i]:
            new_index[i] = len(new_index) - 1
    kept = [replace(j, parent=new_index[j.parent]) for i, j in enumerate(joints) if alive[i]]
    return kept, [replace(f, body=new_index[f.body]) for f in frames], base_inertia


def _moved(t, pose) -> sp.ImmutableMatrix:
    return sp.ImmutableMatrix((t * pose).applyfunc(_tidy))


def _tidy(e):
    """Drop float round-off next to exact zeros, produced by merging numeric poses and inertias."""
    e = sp.sympify(e)
    if e.is_Float and abs(float(e)) < 1e-15:
        return sp.Integer(0)
    return e
