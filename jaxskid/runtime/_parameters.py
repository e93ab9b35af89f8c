"""Parameters as arrays: the one conversion every runtime function and application uses.

The rule (defaults fill in, unknown names are errors, leading axes are a batch) is
:class:`jaxskid.model.ParameterLayout`'s; this module only builds arrays.

* :func:`param_array` gives the JAX array ``(..., n_params)``. A mapping that holds arrays or tracers
  (``jax.grad`` with respect to a dict, a batch of values per name) is stacked with ``jnp.stack`` so that
  it stays differentiable.
* :class:`HostParameters` packs concrete parameters on the host, as a float64 NumPy array, with the
  lookups of one model built once. A call packs a dict of plain numbers (the common case:
  ``robot.default_params()`` edited by hand) this way before it enters a jitted function: passed as a
  pytree, a dict of the G1's 290 parameters is flattened and transferred leaf by leaf at every call;
  packed, it is one array argument, as a vector is (``benchmarks/core.py --params-cost``).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import InputError, ShapeError
from ._batching import float_arrays
from ..model._parameters import ParameterLayout

_PLAIN = (float, int, np.floating, np.integer)


def _packed(values: list) -> np.ndarray | None:
    """``values`` as a float64 vector when every one is a plain number (checked once per distinct type),
    else ``None`` (they hold arrays or tracers)."""
    if all(issubclass(t, _PLAIN) for t in set(map(type, values))):
        return np.fromiter(values, np.float64, len(values))
    return None


def _check_vector(shape: tuple, layout: ParameterLayout, where: str) -> None:
    if len(shape) == 0 or shape[-1] != len(layout):
        raise ShapeError(
            f"{where}: expected a dict name -> value or an array of shape ({len(layout)},) or "
            f"(..., {len(layout)}), got shape {tuple(shape)}"
        )


@functools.lru_cache(maxsize=64)
def _defaults(layout: ParameterLayout) -> np.ndarray:
    """The default vector on the host (a JAX array made inside a trace would be a tracer: not cacheable)."""
    vector = np.asarray(layout.values(None), dtype=np.float64)
    vector.flags.writeable = False
    return vector


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
        return jnp.asarray(_defaults(layout), dtype=dtype)
    if isinstance(params, Mapping):
        values = layout.values(params, where)
        host = _packed(values)
        if host is not None:
            return jnp.asarray(host, dtype=dtype)
        if any(np.iscomplexobj(v) for v in values):  # a complex step in a parameter: keep it
            dtype = jnp.promote_types(dtype, jnp.complex64)
        arrays = [jnp.asarray(v, dtype) for v in values]
        return jnp.stack(jnp.broadcast_arrays(*arrays), axis=-1)
    if dtype is not None and np.iscomplexobj(params):
        dtype = jnp.promote_types(dtype, jnp.complex64)
    p = jnp.asarray(params) if dtype is None else jnp.asarray(params, dtype)
    if dtype is None and not jnp.issubdtype(p.dtype, jnp.inexact):
        p = p.astype(jnp.result_type(float))
    _check_vector(p.shape, layout, where)
    return p


def inexact_inputs(layout: ParameterLayout, states, params, where: str = "params"):
    """``(states, p, dtype)``: the state arrays and the parameters (:func:`param_array`) in one inexact dtype,
    complex where either is (complex-step derivatives)."""
    arrays, dtype = float_arrays(states)
    p = param_array(layout, params, dtype, where)
    if p.dtype != dtype:
        dtype = p.dtype
        arrays = [x.astype(dtype) for x in arrays]
    return arrays, p, dtype


def check_numeric(names, values, where: str = "params") -> None:
    """:class:`InputError` naming the first parameter whose value is not a number or a numeric array (a
    string, None, an object): JAX's own error would name a pytree path inside a jitted function."""
    for name, value in zip(names, values):
        if isinstance(value, (jax.Array, jax.core.Tracer, *_PLAIN)):
            continue
        kind = np.asarray(value).dtype.kind if not isinstance(value, (str, bytes)) and value is not None else "U"
        if kind not in "biufc":
            raise InputError(f"{where}: {name}: expected a number or a numeric array, got {value!r}")


class HostParameters:
    """One model's concrete parameters packed on the host: float64 NumPy arrays ``(..., n_params)``.

    The lookups (the names, the defaults to fill in) are built once. :meth:`pack` follows
    :class:`~jaxskid.model.ParameterLayout`'s rule and raises its errors. It keeps the last mapping it
    packed (a copy) with its vector: a call with an equal mapping, the common case of one dict passed in a
    loop, costs one dict comparison in C instead of a packing (``benchmarks/core.py --params-cost``), so
    that a dict costs about what a vector does. Equal
    means equal values: ``0.0`` and ``-0.0`` are one parameter value here.

    Attributes:
        layout: the model's parameter names and defaults.
        defaults: the default vector ``(n_params,)``, read-only; ``None`` if a parameter has no default.
    """

    def __init__(self, layout: ParameterLayout):
        self.layout = layout
        self._slots = dict.fromkeys(layout.names)
        self._fill = {k: layout.defaults[k] for k in layout.names if k in layout.defaults}
        self.defaults = None
        if layout.has_all_defaults:
            self.defaults = np.array(layout.values(None), dtype=np.float64)
            self.defaults.flags.writeable = False
        self._last: tuple[dict, np.ndarray | None] = ({}, None)
        self._device: tuple[np.ndarray | None, jax.Array | None] = (None, None)  # a vector and its device copy

    def pack(self, params=None, where: str = "params") -> np.ndarray | None:
        """``params`` as a float64 array ``(..., n_params)``, or ``None`` where they hold JAX values.

        ``None`` gives :attr:`defaults` (no copy); a mapping of plain numbers gives one read-only vector; a
        NumPy array or a sequence of numbers is checked and converted. A JAX array, a tracer or a mapping
        that holds them gives ``None``: convert those with :func:`param_array` (inside the jitted function,
        where they stay differentiable).
        """
        if params is None:
            if self.defaults is None:
                self.layout.values(None, where)  # raises, naming the parameters without a default
            return self.defaults
        if isinstance(params, Mapping):
            return self._pack_mapping(params, where)
        if isinstance(params, jax.Array):
            return None
        if np.iscomplexobj(params):
            return None  # complex steps: converted by param_array, inside the jitted function
        try:
            p = np.asarray(params, dtype=np.float64)
        except (TypeError, ValueError):
            return None  # e.g. a list of tracers: param_array stacks it
        _check_vector(p.shape, self.layout, where)
        return p

    def on_device(self, vector: np.ndarray) -> jax.Array:
        """A packed mapping's ``vector`` as a JAX array, the copy of the last one kept: passed to a jitted
        function, a host array costs a transfer per call, a device array does not. A new mapping packs to a
        new read-only vector (:meth:`pack`), so identity tells whether the copy is current. Inside a caller's
        trace the array is a constant of that trace and is not kept."""
        last, array = self._device
        if last is not vector:
            array = jnp.asarray(vector)
            if isinstance(array, jax.core.Tracer):
                return array
            self._device = (vector, array)
        return array

    def _pack_mapping(self, params: Mapping, where: str) -> np.ndarray | None:
        last, vector = self._last
        try:
            if params == last:  # equal plain numbers (arrays or tracers raise, or differ)
                return vector
        except (TypeError, ValueError):
            pass
        values = self._values(params, where)
        vector = _packed(values)
        if vector is not None:
            vector.flags.writeable = False
            self._last = (dict(params), vector)
        else:
            check_numeric(self.layout.names, values, where)
        return vector

    def _values(self, params: Mapping, where: str) -> list:
        names = self.layout.names
        if len(params) == len(names):  # every name given, unless one is unknown (then one is missing)
            try:
                return list(map(params.__getitem__, names))
            except KeyError:
                pass
        elif self.defaults is not None and params.keys() <= self._slots.keys():
            return list(map({**self._fill, **params}.__getitem__, names))
        return self.layout.values(params, where)  # the general case, with the rule's error messages
