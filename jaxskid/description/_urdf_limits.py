"""A URDF joint's numeric sub-elements, and its ``<limit>`` read into :class:`~jaxskid.JointLimits`.

``<limit lower upper velocity effort>`` (https://wiki.ros.org/urdf/XML/joint) becomes ``Joint.limits``: a
bound the file does not give is unknown and infinite (urdfdom reads a missing ``lower`` or ``upper`` as 0);
a ``continuous`` joint has no position limits (urdfdom ignores its ``lower`` and ``upper`` too), and a
joint without ``<limit>`` has ``limits=None``. The limits are metadata: no equation depends on them.
"""

from __future__ import annotations

import math

from ..model._joint import JointLimits

NUMERIC_JOINT_ATTRIBUTES = {  # read by yourdfpy as floats; jaxskid reads <limit> into Joint.limits
    "limit": ("lower", "upper", "effort", "velocity"),
    "dynamics": ("damping", "friction"),
    "calibration": ("rising", "falling"),
    "safety_controller": ("soft_lower_limit", "soft_upper_limit", "k_position", "k_velocity"),
}


def joint_limits(joint) -> JointLimits | None:
    """The :class:`JointLimits` of a yourdfpy joint (unchecked: :meth:`JointLimits.checked` validates them
    when the robot is built), ``None`` without ``<limit>`` and for a fixed joint."""
    limit = joint.limit
    if limit is None or joint.type == "fixed":
        return None

    def value(x, unknown: float) -> float:
        return unknown if x is None else float(x)

    bounded = joint.type != "continuous"
    return JointLimits(
        lower=value(limit.lower, -math.inf) if bounded else -math.inf,
        upper=value(limit.upper, math.inf) if bounded else math.inf,
        velocity=value(limit.velocity, math.inf),
        effort=value(limit.effort, math.inf),
    )
