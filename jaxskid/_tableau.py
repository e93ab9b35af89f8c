"""The Butcher tableau of the classical fourth-order Runge-Kutta method, written once.

:class:`jaxskid.RK4` (:mod:`jaxskid.apps.simulation._integrators`) steps with it, and the runtime's one-call RK4 steps
(:mod:`jaxskid.runtime._rk4`, and the native recursion :mod:`jaxskid.lowering._ffi_rk4` prints it into) run
the same stages backwards. Both sit below the applications, so the tableau lives here, at the bottom of the
layers.
"""

from __future__ import annotations

from typing import NamedTuple


class ExplicitTableau(NamedTuple):
    """An explicit Runge-Kutta method whose stage ``i`` reads only stage ``i - 1``: ``k_i = f(t + c_i h,
    y + c_i h k_{i-1})``, ``y_1 = y + h sum_i b_i k_i`` (so ``a_{i,i-1} = c_i`` and the rest of ``A`` is zero)."""

    c: tuple[float, ...]
    """The nodes."""
    b: tuple[float, ...]
    """The weights."""


RK4_TABLEAU = ExplicitTableau(c=(0.0, 0.5, 0.5, 1.0), b=(1 / 6, 1 / 3, 1 / 3, 1 / 6))
"""The classical RK4 (Hairer, Norsett & Wanner, "Solving Ordinary Differential Equations I", Table 1.2)."""
