"""One lowered quantity as the runtime presents it: its call signature, its docstring (equation, shapes and
units) and the function :class:`jaxskid.Dynamics` exposes as an attribute named after it.

Each quantity function of a :class:`~jaxskid.Dynamics` is a plain function, made when the object is, with
the quantity's own signature (``inspect.signature(dyn.mass_matrix)`` is ``(q, params=None, *, out=None)``)
and a docstring ``help()`` shows; its program is compiled on the first call.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Sequence
from dataclasses import dataclass

_ARGUMENT_UNITS = {
    "q": "rad (revolute) or m (prismatic)",
    "qd": "rad/s or m/s",
    "qdd": "rad/s^2 or m/s^2",
    "q3d": "rad/s^3 or m/s^3",
    "q4d": "rad/s^4 or m/s^4",
    "tau": "N m (revolute) or N (prismatic)",
    "wrench": "per end-effector (moment in N m, force in N), in the end-effector's frame",
    "wrench_d": "the wrenches' first time derivative, per s",
    "wrench_dd": "the wrenches' second time derivative, per s^2",
    "cotangent": "a cotangent of the result (the result's units inverted)",
    "cotangent_matrix": "a cotangent of the result (the result's units inverted)",
    "cotangent_ee": "a cotangent of the result (the result's units inverted)",
    "cotangent_pose": "a cotangent of the result (the result's units inverted)",
    "cotangent_constraint": "a cotangent of the result (the result's units inverted)",
    "cotangent_rows": "a cotangent of the result (the result's units inverted)",
}

_TORQUE = "N m per revolute joint, N per prismatic joint"
_RESULT_UNITS = {
    "mass_matrix": "kg m^2 between revolute joints, kg m between a revolute and a prismatic one, kg between "
                   "prismatic ones",
    "coriolis_matrix": "the mass matrix's units per s",
    "coriolis_torques": _TORQUE,
    "gravity_torques": _TORQUE,
    "inverse_dynamics": _TORQUE,
    "external_torques": _TORQUE,
    "forward_dynamics": "rad/s^2 or m/s^2",
    "forward_kinematics": "positions in m",
    "ee_pose": "homogeneous poses, positions in m",
    "kinetic_energy": "J",
    "potential_energy": "J",
    "momentum": "kg m^2/s per revolute joint, kg m/s per prismatic joint",
    "center_of_mass": "m",
    "constraint_residual": "m (positions) or rad (orientations) on the constrained axes",
}


@dataclass(frozen=True)
class Quantity:
    """A lowered quantity: ``name(*args, params=None, *, out=None) -> shape`` (``wrench=`` too where it
    takes one), with the equation and description of :data:`jaxskid.QUANTITIES`. ``arg_shapes`` gives one
    state's shape of each argument."""

    name: str
    args: tuple[str, ...]
    shape: tuple[int, ...]
    equation: str
    doc: str
    arg_shapes: tuple[tuple[int, ...], ...]
    takes_wrench: bool = False
    floating_base: bool = False
    """Whether the robot floats: its base's position and quaternion, or twist, come first in the states."""

    @property
    def call(self) -> str:
        """The call as text, ``name(q, params=None, *, out=None)``."""
        return f"{self.name}{self.signature}"

    @property
    def signature(self) -> inspect.Signature:
        """The call signature: the state arguments, ``params`` (positional or by keyword), and by keyword
        only ``wrench`` (inverse dynamics) and ``out``."""
        P = inspect.Parameter
        params = [P(a, P.POSITIONAL_OR_KEYWORD) for a in self.args]
        params.append(P("params", P.POSITIONAL_OR_KEYWORD, default=None))
        if self.takes_wrench:
            params.append(P("wrench", P.KEYWORD_ONLY, default=None))
        params.append(P("out", P.KEYWORD_ONLY, default=None))
        return inspect.Signature(params)

    def help(self) -> str:
        """The docstring of the quantity's function: equation, arguments with shapes and units, result."""
        lines = [f"{self.equation}: {self.doc}", "", "Args:"]
        for a, shape in zip(self.args, self.arg_shapes):
            unit = _ARGUMENT_UNITS.get(a.rstrip("0123456789"), "")
            if self.floating_base and a in ("q", "qd"):
                unit += ("; the floating base's position in m and unit quaternion (x, y, z, w) first" if a == "q"
                         else "; the floating base's twist (omega in rad/s, v in m/s, base frame) first")
            lines.append(f"    {a}: {_shape(shape)}, or (..., {', '.join(map(str, shape))}) for a batch"
                         f"{'; ' + unit if unit else ''}.")
        lines.append("    params: None (the defaults), a dict name -> value, or a vector (..., n_params) in the "
                     "order of ``parameters``.")
        if self.takes_wrench:
            lines.append("    wrench: end-effector wrenches (n_ee, 6), whose joint torques J_e^T W_e are added; "
                         + _ARGUMENT_UNITS["wrench"] + ".")
        lines.append("    out: an earlier result of the same shape and dtype, whose memory the result takes (it is "
                     "donated: deleted after the call; use the returned array). Its entries are not read.")
        unit = _RESULT_UNITS.get(self.name)
        result = "a dict frame name -> (4, 4) pose" if self.name == "forward_kinematics" else _shape(self.shape)
        lines += ["", f"Returns: {result} per state{', in ' + unit if unit else ''}."]
        if not unit:
            lines.append("Units: SI (m, kg, s, rad), as the arguments'.")
        return "\n".join(lines)

    def function(self, call: Callable) -> Callable:
        """A function named after the quantity, with its signature and :meth:`help` as docstring, that
        forwards to ``call`` (which accepts every form the signature allows)."""

        def quantity(*args, **kwargs):
            if any(a in kwargs for a in self.args):  # state arguments by keyword: put in their places
                bound = self.signature.bind(*args, **kwargs).arguments
                args = tuple(bound[a] for a in self.args)
                kwargs = {k: v for k, v in bound.items() if k not in self.args}
            return call(*args, **kwargs)

        quantity.__name__ = quantity.__qualname__ = self.name
        quantity.__doc__ = self.help()
        quantity.__signature__ = self.signature
        quantity.quantity = self
        return quantity


def _shape(shape: Sequence[int]) -> str:
    return "a scalar" if not shape else f"({', '.join(map(str, shape))}{',' if len(shape) == 1 else ''})"
