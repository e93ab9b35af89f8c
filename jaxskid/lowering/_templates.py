"""The C the native libraries are built around, kept as ``.c`` and ``.h`` files in ``jaxskid/lowering/c/``
(package data): the XLA FFI handlers (:mod:`._ffi`, :mod:`._ffi_batch`, :mod:`._ffi_rk4`) and the CPython
extension module (:mod:`._extension`). A template marks what is filled in with ``@NAME@``."""

from __future__ import annotations

import functools
from importlib import resources


@functools.cache
def template(name: str) -> str:
    """The text of the file ``c/<name>`` shipped with jaxskid."""
    return resources.files(__package__).joinpath("c", name).read_text(encoding="utf-8")


def fill(text: str, **values) -> str:
    """``text`` with each ``@KEY@`` of ``values`` replaced by its value (as text); other placeholders stay."""
    for key, value in values.items():
        text = text.replace(f"@{key}@", str(value))
    return text

