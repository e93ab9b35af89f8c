"""The runtime: the lowered quantities as jit/vmap/grad-ready JAX functions (:class:`Dynamics`), the
compiled C for single calls (:class:`NativeDynamics`), both on one base (:class:`QuantitySet`) with one
parameter rule (:func:`param_array`), :func:`jit` with the compiler options the generated programs need,
and the forward-dynamics solve. No SymPy here: everything comes from generated modules' metadata."""

from ._base import QuantitySet
from ._dynamics import Dynamics
from ._forward import forward_dynamics, mass_matrix_condition
from ._jit import compiler_options, jit
from ._ldl import ldl_solve
from ._native import NativeDynamics
from ._parameters import HostParameters, param_array
