"""The equations stage: the quantity catalogue, the :class:`Options` of the closed form, and
:func:`derive`, which turns a robot and a request into :class:`Equations` (named SymPy expressions over
one shared straight-line program, with their argument signature)."""

from ._catalogue import DEFAULT_QUANTITIES, QUANTITIES, QuantitySpec
from ._derive import Argument, Equations, Quantity, derive, resolve
from ._options import Options

__all__ = [
    "DEFAULT_QUANTITIES",
    "QUANTITIES",
    "Argument",
    "Equations",
    "Options",
    "Quantity",
    "QuantitySpec",
    "derive",
    "resolve",
]
