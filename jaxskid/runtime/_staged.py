"""The :class:`~jaxskid.Dynamics` of ``lower(..., checks="debug")``: quantities that check traced states too.

Each quantity function checks its state arguments for NaN and inf at the top level already
(:func:`~jaxskid.runtime._checks.check_finite`); here, inside a caller's ``jit``, ``grad`` or ``vmap`` as well,
by a test staged into the caller's program (:func:`~jaxskid.runtime._checks.stage_finite`), for as long as
``dyn.checks == "debug"``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

from ._checks import check_inputs
from ._dynamics import Dynamics
from ._jit import top_level


class CheckedDynamics(Dynamics):
    """:class:`~jaxskid.Dynamics` whose quantities check their traced states (module docstring); made by
    ``jaxskid.lower(..., checks="debug")``, with the arguments of :class:`~jaxskid.Dynamics`."""

    def _make(self, name: str) -> Callable:
        fn = super()._make(name)
        args = self.signature(name)[0]

        @functools.wraps(fn)
        def checked(*state, **kwargs):
            if self.checks == "debug" and not top_level(state):
                given = list(zip(args, state))
                params = kwargs.get("params", state[len(args)] if len(state) == len(args) + 1 else None)
                check_inputs("debug", name, [*given, ("params", params), ("wrench", kwargs.get("wrench"))],
                             self.parameters)
            return fn(*state, **kwargs)

        return checked
