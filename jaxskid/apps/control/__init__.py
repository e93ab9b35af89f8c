"""Joint-space control laws for rollouts (``_laws``): computed torque, PD plus gravity compensation and the
Slotine-Li adaptive controller, each a :class:`jaxskid.apps.simulation.Controller`."""

from ._laws import ComputedTorque, PDGravity, SlotineLi, mixed_regressor, reference_derivatives

__all__ = ["ComputedTorque", "PDGravity", "SlotineLi", "mixed_regressor", "reference_derivatives"]
