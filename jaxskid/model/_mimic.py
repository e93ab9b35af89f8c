"""Mimic joints: a joint that follows another, ``q_m = multiplier * q_j + offset`` (URDF's ``<mimic>``).

A robot with mimic joints keeps every joint and body (:attr:`Robot.joints`), but only the independent
joints are coordinates: ``q``, ``qd``, ``qdd`` and ``tau`` have :attr:`Robot.n_dof` entries, one per
independent joint in the order of the bodies (:attr:`Robot.joint_names`). The coupling is the constant
affine map ``q_bodies = G q + b``, with ``G[i, k] = 1`` when body ``i``'s joint is coordinate ``k``,
``G[i, k] = a`` when it mimics coordinate ``k``'s joint with multiplier ``a`` (offset ``b_i``), and 0
otherwise; so ``qd_bodies = G qd`` and ``qdd_bodies = G qdd``. The equations of motion in the independent
coordinates are the full ones projected (virtual work, as Pinocchio's ``JointModelMimic``):
``M = G^T M_bodies G``, ``C = G^T C_bodies G``, ``Q_grav = G^T Q_grav_bodies``, ``tau = G^T tau_bodies``,
``J = J_bodies G``, and the regressor is ``G^T Y_bodies`` (:mod:`jaxskid.equations._mimic`).

Rules, checked when the robot is created (:func:`resolve`):

* the followed joint is a moving joint of the robot, other than the mimic joint itself; a fixed joint
  neither mimics nor is mimicked;
* a chain (a joint that mimics a mimic joint) is composed into one coupling to the independent joint at
  its end, ``a = a_1 a_2``, ``b = a_1 b_2 + b_1`` (Pinocchio refuses chains); a loop is an error;
* the two joints may be of different types (a revolute joint following a prismatic one, as URDF and
  Pinocchio allow): the multiplier then carries the units (rad/m or m/rad);
* multiplier and offset are numbers (expressions of numbers such as ``pi/2`` too), not parameters;
* locking a joint locks its mimic joints at ``a v + b`` (:func:`follow_locks`); a mimic joint is locked only
  with the joint it follows, at that value;
* a drive on a mimic joint acts through the coupling: its force ``Ia qdd_m + fv qd_m + fc sign(qd_m) + fo``
  at ``qd_m = a qd_j`` is projected by ``G^T`` (``a^2 Ia`` on the diagonal of ``M``, ``a`` times the rest).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import sympy as sp

from .._errors import ModelError
from ._validate import describe_value, differ, to_expr


@dataclass(frozen=True)
class Mimic:
    """The coupling of a mimic joint to the joint it follows: ``q = multiplier * q_joint + offset``."""

    joint: str
    multiplier: sp.Expr | float = 1
    offset: sp.Expr | float = 0

    @classmethod
    def of(cls, value, where: str) -> "Mimic | None":
        """A :class:`Mimic` from ``None``, a :class:`Mimic`, a tuple ``(joint, multiplier[, offset])`` or a
        joint name, with numeric multiplier and offset (:class:`ModelError` at ``where`` otherwise)."""
        if value is None:
            return None
        if isinstance(value, str):
            value = (value,)
        elif isinstance(value, Mimic):
            value = (value.joint, value.multiplier, value.offset)
        if not isinstance(value, (tuple, list)) or not 1 <= len(value) <= 3:
            raise ModelError(f"expected a Mimic, a joint name or (joint, multiplier, offset), got {describe_value(value)}",
                             where=where)
        joint, multiplier, offset = (*value, *(None, 1, 0)[len(value):])
        if not isinstance(joint, str) or not joint:
            raise ModelError(f"expected the name of a joint, got {describe_value(joint)}", where=f"{where}.joint")
        return cls(joint, _number(multiplier, f"{where}.multiplier"), _number(offset, f"{where}.offset"))


def _number(value, where: str) -> sp.Expr:
    expr = to_expr(value, where=where)
    if expr.free_symbols:
        names = ", ".join(sorted(s.name for s in expr.free_symbols))
        raise ModelError(f"expected a number, got {str(value)!r}, which depends on {names}", where=where)
    return expr


def resolve(mimics: Mapping[str, Mimic], kinds: Mapping[str, str],
            where: Callable[[str], str]) -> dict[str, Mimic]:
    """Every mimic joint's coupling composed down to the independent joint at the end of its chain.

    Args:
        mimics: mimic joint name -> its :class:`Mimic`, as given.
        kinds: joint name -> type (``revolute``, ``prismatic``, ``fixed``) for every joint.
        where: mimic joint name -> the key path of its mimic entry, for errors.
    """
    out = {}
    for name, m in mimics.items():
        if kinds.get(name) == "fixed":
            raise ModelError(f"expected a moving joint to mimic another, got fixed joint {name!r}", where=where(name))
        chain, a, b, at = [name], m.multiplier, m.offset, name
        target = m.joint
        while True:
            if target not in kinds:
                raise ModelError(f"expected the name of a joint, got {target!r}; joints are "
                                 f"{', '.join(kinds)}", where=f"{where(at)}.joint")
            if kinds[target] == "fixed":
                raise ModelError(f"expected a moving joint, got fixed joint {target!r}", where=f"{where(at)}.joint")
            if target in chain:
                loop = " -> ".join([*chain[chain.index(target):], target])
                raise ModelError(f"expected mimic joints that end at an independent joint, got the loop {loop}",
                                 where=f"{where(name)}.joint")
            if target not in mimics:
                break
            chain.append(target)
            nxt = mimics[target]
            a, b, at, target = a * nxt.multiplier, a * nxt.offset + b, target, nxt.joint
        out[name] = Mimic(target, a, b)
    return out


def follow_locks(mimics: Mapping[str, Mimic], values: Mapping, where: str = "lock") -> dict:
    """``values`` (joint name -> position) with every mimic joint of a locked joint added at ``a v + b``.

    ``mimics`` are resolved (:func:`resolve`). A mimic joint locked without the joint it follows, or at
    another value than ``a v + b``, is a :class:`ModelError` at ``where.<name>``.
    """
    out = dict(values)
    for name, m in mimics.items():
        if m.joint in values:
            value = m.multiplier * sp.sympify(values[m.joint]) + m.offset
            if name in values and differ(values[name], value):
                raise ModelError(f"joint {name!r} mimics {m.joint!r} (q = {m.multiplier} * q_{m.joint} + {m.offset}): "
                                 f"expected {value}, got {values[name]}", where=f"{where}.{name}")
            out[name] = value
        elif name in values:
            raise ModelError(f"joint {name!r} mimics {m.joint!r}: lock {m.joint!r} instead (its mimic joints follow)",
                             where=f"{where}.{name}")
    return out
