"""Quantities lowered when first used: the pullbacks of a lowering that builds no native kernel.

A pullback (``<name>_vjp``, :mod:`jaxskid.runtime._pullback`) serves reverse mode only, and costs more to derive
and print than its quantity (the G1's Coriolis matrix: 1.5 s to derive and 0.8 s to print alone, 5.0 s and
2.1 s with its pullback). Where native kernels are built, :func:`jaxskid.lower` derives the pullbacks with the
quantities, so that the compiler works on their kernels in the background; where none is (``JAXSKID_NATIVE=0``,
no CUDA kernels on a GPU, a TPU), it leaves them to a second module, derived, printed and cached when a gradient
first needs one. Their signatures are known beforehand (the catalogue gives them), so a :class:`Dynamics`
lists them among its quantities and its functions reach them as if they had been lowered with the rest.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Mapping, Sequence

from .._generated import GeneratedModule


class Deferred:
    """The quantities of a module made when one of them is first asked for.

    Args:
        quantities: their metadata by name, as a generated module's ``METADATA["quantities"]`` has it
            (``args``, ``shape``, ``equation``, ``doc``).
        parameters: the order of ``p`` the module must take (that of the module lowered with it).
        load: makes the module (derives, prints and caches it, or reads it from the cache); called once.
    """

    def __init__(self, quantities: Mapping[str, dict], parameters: Sequence[str],
                 load: Callable[[], GeneratedModule]):
        self.quantities: dict[str, dict] = dict(quantities)
        self._parameters = list(parameters)
        self._load = load
        self._lock = threading.Lock()
        self._module: GeneratedModule | None = None

    def module(self) -> GeneratedModule:
        """The module, made on the first call (one thread makes it; the others wait for it)."""
        with self._lock:
            if self._module is None:
                module = self._load()
                made = module.metadata["quantities"]
                wrong = [k for k, m in self.quantities.items() if made.get(k) != m]
                if wrong or list(module.metadata["parameters"]) != self._parameters:
                    raise RuntimeError(f"the module of the deferred quantities {', '.join(self.quantities)} does not "
                                       "give them the signatures and parameter order announced; clear jaxskid's "
                                       "cache (jaxskid.cache_dir())")
                self._module = module
        return self._module


class OnDemand(dict):
    """A dict by quantity name whose entries for the deferred quantities ``names`` are made by ``fill()`` when one
    is first read (``in`` stays False until then, as for a quantity that was not lowered)."""

    def __init__(self, items: Mapping, fill: Callable[[], None], names: Iterable[str]):
        super().__init__(items)
        self._fill = fill
        self._names = frozenset(names)

    def __missing__(self, key):
        if key in self._names:
            self._fill()
            if dict.__contains__(self, key):
                return dict.__getitem__(self, key)
        raise KeyError(key)
