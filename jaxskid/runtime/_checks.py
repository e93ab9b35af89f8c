"""The checks a top-level call makes on its inputs before anything runs.

* :func:`check_finite`: NaN or inf in a state argument raises :class:`~jaxskid.InputError` naming the
  argument, the first bad index and its value (a NaN ``q`` would otherwise give a partly NaN ``M`` and a
  rollout NaN to its end).
* :class:`InertiaCheck`: a parameter vector that gives a body a negative mass, no mass with a first moment
  ``m c``, or a rotational inertia about its centre of mass that is not positive semi-definite (``I_C = I_O + h~ h~ / m``, with ``h = m c``),
  raises :class:`~jaxskid.InputError` naming the parameters of the body: the mass matrix is then not
  positive definite and forward dynamics meaningless. A body whose standard parameters equal the
  defaults' is not checked again (they were checked at load, :mod:`jaxskid.model._inertia_check`). The
  triangle inequality of the principal moments is not asked for here: identified parameters often break
  it and still reproduce the torques they were fitted to, and planar models give the moment about their
  axis only.

Only concrete values are checked by default: inside a caller's ``jit``, ``grad`` or ``vmap`` the inputs are
tracers, and the checks are skipped. ``jaxskid.lower(..., checks=False)`` skips them at the top level too.

``jaxskid.lower(..., checks="debug")`` checks traced states as well (:func:`check_inputs`): each call stages,
into the caller's program, a test of its state arguments for NaN and inf, and a host callback
(``jax.debug.callback``) that raises :class:`~jaxskid.InputError` with the same message as at the top level. The
compiled program then fails with ``jax.errors.JaxRuntimeError``, whose message ends with that
``InputError``'s (``mass_matrix: q[3, 2] is nan: ...``). Under ``vmap`` the batch's first bad index is named,
batch axes included, from one callback per call (:func:`jax.custom_batching.custom_vmap`: JAX would otherwise
unroll the callback over the batch); ``grad`` and ``jvp`` check the primal values. The test costs a reduction
over the states and a host call per evaluation: a debugging aid, off by default.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_batching import custom_vmap

from .._errors import InputError, RequestError, ShapeError
from ._jit import top_level

CHECKS = (True, False, "debug")
"""The values of ``lower(..., checks=...)``: top-level calls only, none, or traced calls too."""


def _concrete(value):
    """``value`` as a NumPy array, or None where it is traced (or not numeric: other checks name that)."""
    if value is None or isinstance(value, jax.core.Tracer):
        return None
    try:
        array = np.asarray(value)
    except (TypeError, ValueError, jax.errors.ConcretizationTypeError):
        return None
    return array if array.dtype.kind in "fc" else None


@functools.lru_cache(maxsize=1)
def _cpu_only() -> bool:
    return all(d.platform == "cpu" for d in jax.devices())


def _finite_sum(value) -> bool | None:
    """Whether ``sum |x|^2`` over ``value`` is finite (then every entry is; NaN and inf propagate, and only a
    sum that overflows from finite entries needs the entry-wise look), None where ``value`` is traced or not
    a floating array. One dot product: a third of ``isfinite(x).all()``'s cost on a state, a half on a
    batch; an array on an accelerator is reduced there, not copied to the host."""
    if value is None or isinstance(value, jax.core.Tracer):
        return None
    if isinstance(value, jax.Array) and not _cpu_only():
        return math.isfinite(float(jnp.real(jnp.vdot(value, value)))) if value.dtype.kind in "fc" else None
    array = _concrete(value)
    return None if array is None else math.isfinite(np.vdot(array, array).real)


def _not_numeric(value) -> bool:
    """Whether a concrete argument is no array of numbers (a string, None, an object): JAX's own error would name
    a function inside jaxskid. JAX arrays and tracers are numeric."""
    if isinstance(value, (jax.Array, jax.core.Tracer)):
        return False
    try:
        return np.asarray(value).dtype.kind not in "biufc"
    except (TypeError, ValueError):  # ragged nested lists
        return True


def check_finite(where: str, named: Iterable[tuple[str, object]]) -> None:
    """Raise :class:`InputError` for the first argument ``(name, value)`` that is not an array of numbers or
    holds NaN or inf."""
    for name, value in named:
        if _not_numeric(value):
            shown = repr(value) if len(repr(value)) <= 60 else f"a {type(value).__name__}"
            raise InputError(f"{where}: {name}: expected an array of numbers, got {shown}")
        if _finite_sum(value) is not False:
            continue
        array = _concrete(value)
        finite = np.isfinite(array)
        if finite.all():  # the sum overflowed: every entry is finite
            continue
        index = np.unravel_index(int(np.argmin(finite.ravel())), array.shape)
        shown = f"{name}[{', '.join(map(str, index))}]" if array.ndim else name
        raise InputError(f"{where}: {shown} is {array[index]}: expected finite values (no NaN or inf)")


def checks_mode(checks) -> bool | str:
    """``checks`` checked to be one of :data:`CHECKS`."""
    if checks is None or not any(checks is c or (isinstance(checks, str) and checks == c) for c in CHECKS):
        raise RequestError(f"checks: expected True (check calls from Python), False or 'debug' (check inside "
                           f"jit, grad and vmap too), got {checks!r}")
    return checks


def check_inputs(checks, where: str, named: Iterable[tuple[str, object]], names: Sequence[str] = ()) -> None:
    """The checks of ``lower(..., checks=...)`` on a call's state arguments ``(name, value)``: at the top level
    :func:`check_finite`; inside a caller's trace, with ``checks="debug"``, :func:`stage_finite` (module
    docstring); else nothing. ``names``: the names of a ``params`` argument's last axis (for its message)."""
    if not checks:
        return
    named = [(name, value) for name, value in named if value is not None]
    if top_level(tuple(value for _, value in named)):
        check_finite(where, named)
    elif checks == "debug":
        stage_finite(where, named, names)


def stage_finite(where: str, named: Iterable[tuple[str, object]], names: Sequence[str] = ()) -> None:
    """:func:`check_finite` for traced values: concrete ones are checked now, traced ones in the program being
    traced (module docstring). ``names``: the names of the entries of the last axis of an argument called
    ``params``, named in its message."""
    concrete = [(name, value) for name, value in named if not isinstance(value, jax.core.Tracer)]
    check_finite(where, concrete)
    for name, value in named:
        if isinstance(value, jax.core.Tracer) and jnp.issubdtype(value.dtype, jnp.inexact):
            _staged_check(where, name, tuple(names) if name == "params" else ())(jax.lax.stop_gradient(value))


@functools.lru_cache(maxsize=256)
def _staged_check(where: str, name: str, names: tuple[str, ...]) -> Callable:
    """``check(x)``: stages the test of ``x`` for NaN and inf and the callback that raises; batched by one test
    of the whole batch (its first bad index named with the batch axes)."""

    def host(bad, first, value, *, shape):
        if bool(bad):
            index = np.unravel_index(int(first), shape)
            shown = f"{name}[{', '.join(map(str, index))}]" if shape else name
            named = f" ({names[index[-1]]})" if names and shape and shape[-1] == len(names) else ""
            raise InputError(f"{where}: {shown}{named} is {value}: expected finite values (no NaN or inf)")

    @custom_vmap
    def check(x):
        flat = jnp.ravel(x)
        bad = ~jnp.isfinite(flat)
        first = jnp.argmax(bad)
        jax.debug.callback(functools.partial(host, shape=tuple(x.shape)), bad.any(), first, flat[first])
        return jnp.zeros((), bool)

    @check.def_vmap
    def _batched(axis_size, in_batched, x):  # the batch axis is in front: one test of the whole batch
        del axis_size, in_batched
        return check(x), False

    return check


class InertiaCheck:
    """The physical check of parameter vectors (module docstring).

    Args:
        names: the parameter names, the order of the vector.
        standard: ``f(p) -> pi``, the standard parameters ``(..., n_bodies, 10)`` (``m, mcx, mcy, mcz, Ixx,
            Ixy, Iyy, Ixz, Iyz, Izz`` per body) of a vector ``p`` ``(..., n_params)``; built on first use.
        bodies: the body names, in the order of ``pi``.
        involved: per body, ``(mass, all)``: the parameter names its mass and its whole inertia depend on
            (for the messages).
        defaults: the default vector, or None.
    """

    def __init__(self, names: Sequence[str], standard: Callable, bodies: Sequence[str],
                 involved: Sequence[Sequence[str]], defaults: np.ndarray | None):
        self.names, self.standard, self.bodies, self.involved = tuple(names), standard, tuple(bodies), involved
        self.defaults = defaults
        self.reference = None if defaults is None else standard(defaults)

    def check(self, p: np.ndarray, where: str = "params") -> None:
        pi = self.standard(p)
        m = pi[..., 0]
        if (m < 0).any():
            k = int(np.argmax((m < 0).reshape(-1, m.shape[-1]).any(axis=0)))
            raise InputError(f"{where}: {self._named(k, 0, p)} gives body {self.bodies[k]!r} the mass "
                             f"{float(np.min(m[..., k])):g}: expected a mass >= 0")
        changed = np.ones(m.shape[-1], bool) if self.reference is None else \
            (np.abs(pi - self.reference) > 1e-12 * (1 + np.abs(self.reference))).reshape(-1, *pi.shape[-2:]).any(axis=(0, 2))
        if not changed.any():
            return
        h_norm = np.abs(pi[..., 1:4]).max(axis=-1)
        hollow = (m == 0) & (h_norm > 0) & changed  # no mass, yet a first moment m c: no body has it
        if hollow.any():
            k = int(np.argmax(hollow.reshape(-1, m.shape[-1]).any(axis=0)))
            raise InputError(f"{where}: {self._named(k, 1, p)} give body {self.bodies[k]!r} the mass 0 with a first "
                             f"moment of mass (m c) of size {float(np.max(h_norm[..., k])):g}: expected a mass > 0, or "
                             f"mcx = mcy = mcz = 0 for a massless body")
        sub = pi[..., changed, :]
        mass, h, about_origin = sub[..., 0], sub[..., 1:4], _rotational(sub[..., 4:])
        hx = _skew(h)
        safe = np.where(mass > 0, mass, 1.0)[..., None, None]
        about_com = about_origin + np.where(mass[..., None, None] > 0, hx @ hx / safe, 0.0)
        low = np.linalg.eigvalsh(0.5 * (about_com + np.swapaxes(about_com, -1, -2)))[..., 0]
        scale = np.abs(about_origin).max(axis=(-1, -2))
        bad = (low < -1e-9 * np.maximum(scale, 1e-300)).reshape(-1, low.shape[-1]).any(axis=0)
        if bad.any():
            k = int(np.flatnonzero(changed)[int(np.argmax(bad))])
            raise InputError(
                f"{where}: body {self.bodies[k]!r}: {self._named(k, 1, p)} give a rotational inertia about the centre "
                f"of mass with the eigenvalue {float(np.min(low[..., int(np.argmax(bad))])):.6g}: expected a "
                f"positive semi-definite inertia")

    def _named(self, k: int, which: int, p: np.ndarray) -> str:
        """The parameters body ``k``'s mass (``which = 0``) or inertia (1) depends on, those given other values
        than their defaults first."""
        names = self.involved[k][which]
        if self.defaults is not None:
            index = {name: i for i, name in enumerate(self.names)}
            values = np.reshape(p, (-1, len(self.names)))
            changed = [x for x in names if np.any(values[:, index[x]] != self.defaults[index[x]])]
            names = changed + [x for x in names if x not in changed]
        shown = ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")
        return shown or "constants"


def _skew(v: np.ndarray) -> np.ndarray:
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    zero = np.zeros_like(x)
    return np.stack([np.stack([zero, -z, y], -1), np.stack([z, zero, -x], -1), np.stack([-y, x, zero], -1)], -2)


def _rotational(six: np.ndarray) -> np.ndarray:
    """``(Ixx, Ixy, Iyy, Ixz, Iyz, Izz)`` as symmetric 3x3 matrices."""
    xx, xy, yy, xz, yz, zz = (six[..., k] for k in range(6))
    return np.stack([np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1)], -2)


def check_not_a_wrench(name: str, params, call: str, n_ee: int, n_params: int) -> None:
    """A 4th positional argument of the shape of the wrenches of ``n_ee`` end-effectors, where a parameter vector
    is expected: the wrench goes by keyword, and the error says so (rather than that the parameters have a wrong
    shape)."""
    shape = getattr(params, "shape", None)
    if shape is None and not isinstance(params, Mapping):
        shape = np.shape(params) if isinstance(params, (list, tuple)) else None
    if shape is not None and len(shape) >= 2 and tuple(shape[-2:]) == (n_ee, 6) and shape[-1] != n_params:
        raise ShapeError(f"{name}: params has the shape of the end-effector wrenches {tuple(shape)}; pass "
                         f"a wrench by keyword: {call}")
