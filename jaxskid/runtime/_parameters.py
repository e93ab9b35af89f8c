"""Parameters as a JAX array: the one conversion every runtime function and application uses.

The rule (defaults fill in, unknown names are errors, leading axes are a batch) is
:class:`jaxskid.model.ParameterLayout`'s; this module only builds the array. A mapping of plain numbers
(the common case: ``robot.default_params()`` edited by hand) is packed on the host in one NumPy call
and sent to the device once, so a dict costs about what a vector does; a mapping that holds arrays or
tracers (``jax.grad`` with respect to a dict, a batch of values per name) is stacked with ``jnp.stack``
so that it stays differentiable.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ShapeError
from ..model._parameters import ParameterLayout

_PLAIN = (float, int, np.floating, np.integer)


@functools.lru_cache(maxsize=64)
def _defaults(layout: ParameterLayout, dtype) -> jax.Array:
    return jnp.asarray(np.asarray(layout.values(None), dtype=np.float64), dtype=dtype)


def param_array(layout: ParameterLayout, params=None, dtype=None, where: str = "params") -> jax.Array:
    """``params`` as an array of shape ``(..., len(layout))``.

    Args:
        layout: the model's parameter names and defaults.
        params: ``None`` (the defaults), a mapping name -> value (missing names take their defaults; a
            value may carry leading batch axes, which broadcast against each other), or an array whose
            last axis is the parameter vector and whose leading axes are a batch.
        dtype: the result's dtype (default: float64 when x64 is enabled, else float32, for mappings; the
            array's own floating dtype for arrays).
        where: the argument's name, for error messages.
    """
    if dtype is None:
        dtype = jnp.result_type(float) if params is None or isinstance(params, Mapping) else None
    if params is None:
        return _defaults(layout, jnp.dtype(dtype))
    if isinstance(params, Mapping):
        values = layout.values(params, where)
        if all(isinstance(v, _PLAIN) for v in values):
            return jnp.asarray(np.asarray(values, dtype=np.float64), dtype=dtype)
        if not values:
            return jnp.zeros((0,), dtype)
        arrays = [jnp.asarray(v, dtype) for v in values]
        return jnp.stack(jnp.broadcast_arrays(*arrays), axis=-1)
    p = jnp.asarray(params) if dtype is None else jnp.asarray(params, dtype)
    if dtype is None and not jnp.issubdtype(p.dtype, jnp.floating):
        p = p.astype(jnp.result_type(float))
    if p.ndim == 0 or p.shape[-1] != len(layout):
        raise ShapeError(
            f"{where}: expected a dict name -> value or an array of shape ({len(layout)},) or "
            f"(..., {len(layout)}), got shape {tuple(p.shape)}"
        )
    return p
