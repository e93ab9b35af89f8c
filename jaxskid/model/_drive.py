"""The drive of a joint: armature, viscous and Coulomb friction and a torque offset.

A drive adds to joint ``j``'s generalized force (Pinocchio's ``model.armature`` for ``Ia``; the friction
model of Khalil & Dombre, "Modeling, Identification and Control of Robots", 2002, sec. 12.3)

    tau_drive_j = Ia_j qdd_j + fv_j qd_j + fc_j sign(qd_j) + fo_j,

so that ``M`` becomes ``M + diag(Ia)`` and the bias gains ``fv qd + fc sign(qd) + fo``. ``Ia`` is the rotor
inertia reflected at the joint (``gear_ratio^2 * rotor_inertia``), kg m^2 (kg for a prismatic joint);
``fv`` N m s, ``fc`` and ``fo`` N m (N s and N for a prismatic joint). The four values are expressions
like every other part of the model; :meth:`Drive.symbolic` gives the drive whose four values are
parameters ``{joint}_Ia, {joint}_fv, {joint}_fc, {joint}_fo``, linear in the equations of motion (the
regressor's last columns, :mod:`jaxskid.symbolic._regressor`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, fields

import sympy as sp

from ._validate import symbol, to_expr

DRIVE_PARAMETER_NAMES = ("Ia", "fv", "fc", "fo")
"""The suffixes of a drive's parameters, in the order of :class:`Drive`'s fields and of the regressor."""


@dataclass(frozen=True)
class Drive:
    """A joint's drive (see the module docstring): numbers, parameter names or expressions.

    Args:
        armature: ``Ia``, the rotor inertia reflected at the joint [kg m^2; kg for a prismatic joint].
        viscous: ``fv``, the viscous friction coefficient [N m s; N s].
        coulomb: ``fc``, the Coulomb friction torque [N m; N].
        offset: ``fo``, a constant torque offset [N m; N].
    """

    armature: sp.Expr = sp.Integer(0)
    viscous: sp.Expr = sp.Integer(0)
    coulomb: sp.Expr = sp.Integer(0)
    offset: sp.Expr = sp.Integer(0)

    @classmethod
    def symbolic(cls, joint: str) -> "Drive":
        """The drive whose values are the parameters :func:`drive_parameter_names` of ``joint``."""
        return cls(*(symbol(n) for n in drive_parameter_names(joint)))

    def values(self) -> tuple[sp.Expr, ...]:
        """``(Ia, fv, fc, fo)``."""
        return tuple(getattr(self, f.name) for f in fields(self))

    def normalized(self, where: str) -> "Drive":
        """The same drive with every value read by :func:`~jaxskid.model._validate.to_expr`."""
        return Drive(*(to_expr(getattr(self, f.name), where=f"{where}.{f.name}") for f in fields(self)))

    def mapped(self, fn) -> "Drive":
        """``fn`` applied to every value."""
        return Drive(*(fn(sp.sympify(v)) for v in self.values()))


def drive_parameter_names(joint: str) -> tuple[str, ...]:
    """``{joint}_Ia, {joint}_fv, {joint}_fc, {joint}_fo``, with ``joint`` made a valid identifier."""
    prefix = re.sub(r"[^0-9A-Za-z_]", "_", joint)
    prefix = f"_{prefix}" if prefix[:1].isdigit() else prefix
    return tuple(f"{prefix}_{p}" for p in DRIVE_PARAMETER_NAMES)
