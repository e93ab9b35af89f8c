"""A generated JAX module, executed, read into its typed form (:class:`jaxskid._generated.GeneratedModule`).

This is the one place that knows the names a module of :mod:`jaxskid.codegen._jax` defines: ``METADATA``,
each quantity's function ``<name>`` and program ``_<name>``, and ``NATIVE_C``, the generated C of its native
libraries (:func:`jaxskid.codegen._c.native_block`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from .._generated import GeneratedModule, GeneratedQuantity, NativeSource


def generated_module(namespace: Mapping, source: str, path: Path | None = None) -> GeneratedModule:
    """The :class:`GeneratedModule` of an executed module's ``namespace`` and its ``source`` text."""
    meta = namespace["METADATA"]
    quantities = {
        name: GeneratedQuantity(name, tuple(m["args"]), tuple(m["shape"]), m["equation"], m["doc"],
                                function=namespace[name], program=namespace[f"_{name}"])
        for name, m in meta["quantities"].items()
    }
    native = tuple(NativeSource.from_dict(d) for d in namespace.get("NATIVE_C", ()))
    return GeneratedModule(meta, quantities, native, source, path)
