"""The parameter rule, in one place: how a user's ``params`` map onto a model's parameter vector.

Every function that takes ``params`` (the JAX quantities, the native library, rollouts, identification,
the standard parameters) reads them through a :class:`ParameterLayout`:

* ``None`` stands for the defaults (the description's ``assignments``, or a URDF's values);
* a mapping name -> value may be partial: a missing name takes its default; a name the model does not
  have is an error that names it and the closest valid names;
* a vector is in the order of :attr:`ParameterLayout.names`; leading axes are a batch.

The layout knows nothing of arrays; :func:`jaxskid.runtime.param_array` builds the JAX array from what
:meth:`ParameterLayout.values` returns.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from .._errors import RequestError, unknown_names


@dataclass(frozen=True)
class ParameterLayout:
    """The ordered parameter names of a model and the defaults of those that have one."""

    names: tuple[str, ...]
    defaults: Mapping[str, float] = field(default_factory=dict)
    _index: dict = field(default_factory=dict, init=False, compare=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "names", tuple(self.names))
        known = {k: float(v) for k, v in self.defaults.items() if v is not None and not math.isnan(float(v))}
        object.__setattr__(self, "defaults", known)
        self._index.update({k: i for i, k in enumerate(self.names)})

    def __len__(self) -> int:
        return len(self.names)

    def __hash__(self) -> int:
        return hash((self.names, tuple(sorted(self.defaults.items()))))

    @property
    def has_all_defaults(self) -> bool:
        return all(k in self.defaults for k in self.names)

    def index(self, name: str) -> int:
        """Position of ``name`` in the vector; an unknown name raises :class:`RequestError`."""
        if name not in self._index:
            self.check_names([name])
        return self._index[name]

    def check_names(self, given, where: str = "params") -> None:
        """Raise :class:`RequestError` for a name the model does not have, naming the closest valid ones."""
        unknown = [k for k in given if k not in self._index]
        if not unknown:
            return
        named, listed = unknown_names(unknown, self.names)
        raise RequestError(f"{where}: unknown parameter {named}; the parameters are {listed}")

    def missing_defaults(self, given: Mapping | None = None) -> list[str]:
        """Names that neither ``given`` nor the defaults provide."""
        given = given or {}
        return [k for k in self.names if k not in given and k not in self.defaults]

    def values(self, params: Mapping | None = None, where: str = "params") -> list:
        """One value per name, in order: ``params[name]`` where given, else the default.

        The values are whatever ``params`` holds (floats, arrays, tracers); nothing is converted here.
        """
        given = params or {}
        self.check_names(given, where)
        missing = self.missing_defaults(given)
        if missing:
            shown = ", ".join(missing[:8]) + (f", ... ({len(missing)} in all)" if len(missing) > 8 else "")
            raise RequestError(f"{where}: no value for {shown}: these parameters have no default; pass them")
        return [given[k] if k in given else self.defaults[k] for k in self.names]

    def as_dict(self, vector) -> dict:
        """``{name: vector[..., k]}``, the inverse of building a vector."""
        return {k: vector[..., i] for i, k in enumerate(self.names)}
