"""The fast single-call path: generated C, built into a library and called from Python.

A jitted JAX function costs tens of microseconds of dispatch per call; for one state at a time that is
most of the time. :func:`jaxskid.compile_native` prints the requested quantities as C (the ``"c"`` target
of :mod:`jaxskid.codegen`), builds them (:mod:`jaxskid.lowering._native`) and wraps them in a
:class:`NativeDynamics` whose methods take and return NumPy arrays::

    native = jaxskid.compile_native(robot, ["inverse_dynamics", "mass_matrix"])
    tau = native.inverse_dynamics(q, qd, qdd)           # numpy (n,), default parameters
    M = native.mass_matrix(q, params={"m1": 2.0})       # (n, n); missing names take their defaults

This module knows only NumPy and plain metadata (the same as a generated JAX module's ``METADATA``); it
never touches SymPy or the C source's origin.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Collection, Mapping
from pathlib import Path

import numpy as np

from .._errors import ShapeError
from ._base import QuantitySet, metadata_fields


# ---------------------------------------------------------------------------------------------- calling
# Per-call wrappers are generated as Python source so that each quantity's method does only what it must:
# a dtype and shape check per argument (conversion only when one fails), one output allocation and one C
# call. cffi's from_buffer views need no copy; it rejects non-contiguous arrays, which are then copied.
_CFFI_TEMPLATE = """
def {name}({args}, params=None):
    _p = {pvalue}
    try:
        if {fast}:
            _o = _empty({shape!r})
            _fn({views}, _p, _fb(_D, _o))
            return _o
    except (AttributeError, TypeError, ValueError):  # not a contiguous float64 array of the right shape
        pass
{converts}    _o = _empty({shape!r})
    _fn({views}, _p, _fb(_D, _o))
    return _o
"""

_CTYPES_TEMPLATE = """
def {name}({args}, params=None):
    _pv = {pvalue}
{checks}    with _lock:
{fills}        _fn({pointers}, _P if _pv is None else _pv.ctypes.data, _po)
        return _out.copy()
"""

_CHECK = "    if _shape({a}) != {shape!r}:\n        {a} = _arr({a}, {shape!r}, {what!r})\n"
_CONVERT = "    {a} = _arr({a}, {shape!r}, {what!r})\n"


def _arr(x, shape, what):
    try:
        a = np.ascontiguousarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"{what}: expected an array of numbers, got {type(x).__name__}") from exc
    if a.shape != shape:
        raise ShapeError(f"{what}: expected shape {shape}, got {a.shape}")
    return a


# ---------------------------------------------------------------------------------------------- metadata
# ---------------------------------------------------------------------------------------------- native
class NativeDynamics(QuantitySet):
    """Compiled quantities of one robot for single states. Build it with :func:`jaxskid.compile_native`.

    Each quantity is a method ``name(*state, params=None) -> numpy array`` for ONE state: every state
    argument has shape ``(n,)`` (``wrench``: ``(n_ee, 6)``); ``params`` is ``None`` for the defaults, a dict
    name -> value (missing names take their defaults) or a vector in the order of :attr:`parameters`.
    ``forward_kinematics`` returns a dict frame name -> 4x4 pose, as :class:`jaxskid.Dynamics` does. For
    batches use :func:`jaxskid.lower`.

    Args:
        metadata: the quantities' metadata, as a generated JAX module's ``METADATA``
            (:meth:`jaxskid.codegen.Layout.metadata`).
        functions: quantity name -> the C function ``f(const double *arg, ..., const double *p, double
            *out)``: a cffi function when ``ffi`` is given, else a ctypes function taking addresses; for
            the ``"capi"`` backend, the extension's method itself.
        ffi: cffi's ``FFI`` of the library, or None for ctypes and capi.
        backend: ``"capi"``, ``"cffi"`` or ``"ctypes"`` (default: cffi with ``ffi``, else ctypes).
        module: the capi extension module, which is given its converters here.
        path: the built library's file; source: its C source.
        catalogue: the names of every quantity jaxskid knows, so that asking for one that was not
            compiled says so.
    """

    _made = "compiled"
    _remedy = "jaxskid.compile_native(robot, [..., {name!r}])"

    def __init__(self, metadata: Mapping, functions: Mapping[str, Callable], *, ffi=None, path: Path | None = None,
                 source: str = "", catalogue: Collection[str] = (), backend: str | None = None, module=None):
        super().__init__(**metadata_fields(metadata), catalogue=catalogue)
        self._docs = {k: f"{m['equation']}: {m['doc']}" for k, m in metadata["quantities"].items()}
        self.backend = backend or ("ctypes" if ffi is None else "cffi")
        self.path = path
        self.source = source
        self._default_vector = np.array([self.defaults.get(k, np.nan) for k in self.parameters], dtype=np.float64)
        self._default_vector.flags.writeable = False
        if self.backend == "capi":
            # the extension's methods are complete: they convert what is not a float64 array through these
            module.configure(_arr, self.param_vector, self.layout.has_all_defaults)
        for name in self.quantities:
            args, shape = self.signature(name)
            if self.backend == "capi":
                fn = functions[name]  # a builtin with its own name and docstring
            else:
                fn = self._make(name, args, shape, functions[name], ffi)
                fn.__name__ = name
                fn.__doc__ = f"{name}({', '.join(args)}, params=None) -> {shape}\n\n{self._docs[name]}"
            if name == "forward_kinematics":
                fn = self._frames(fn)
            setattr(self, name, fn)

    def param_vector(self, params=None) -> np.ndarray:
        """Parameters as a contiguous float64 vector in the order of :attr:`parameters`: ``None`` for the
        defaults, a dict (missing names take their defaults; an unknown name is an error) or a vector."""
        packed = self._host.pack(params)  # the parameter rule; None for JAX values
        return _arr(params if packed is None else packed, (len(self.parameters),), "params")

    def _make(self, name: str, args: tuple[str, ...], shape: tuple[int, ...], function: Callable, ffi) -> Callable:
        """The method of one quantity, made from a template (see above)."""
        arg_shapes = {a: self._arg_shape(a) for a in args}
        # With every default known, params=None passes the prebuilt default vector without a call.
        has_defaults = self.layout.has_all_defaults
        ns = {"_f8": np.dtype(np.float64), "_arr": _arr, "_empty": np.empty, "_fn": function,
              "_pvec": self.param_vector}
        if ffi is not None:
            ns.update(_fb=ffi.from_buffer, _D="double[]", _P=ffi.from_buffer("double[]", self._default_vector))
            fast = [f"{a}.dtype is _f8" for a in args] + [f"{a}.shape == {arg_shapes[a]!r}" for a in args]
            text = _CFFI_TEMPLATE.format(
                name=name, args=", ".join(args), shape=tuple(shape), fast=" and ".join(fast),
                pvalue="_P if params is None else _fb(_D, _pvec(params))" if has_defaults else "_fb(_D, _pvec(params))",
                views=", ".join(f"_fb(_D, {a})" for a in args),
                converts="".join(_CONVERT.format(a=a, shape=arg_shapes[a], what=f"{name}: {a}") for a in args),
            )
        else:
            buffers = {a: np.zeros(arg_shapes[a]) for a in args}
            out = np.zeros(shape)
            ns.update({f"_b_{a}": buffers[a] for a in args})
            ns.update(_lock=threading.Lock(), _po=out.ctypes.data, _out=out, _P=self._default_vector.ctypes.data,
                      _shape=np.shape)
            text = _CTYPES_TEMPLATE.format(
                name=name, args=", ".join(args),
                checks="".join(_CHECK.format(a=a, shape=arg_shapes[a], what=f"{name}: {a}") for a in args),
                pvalue="None if params is None else _pvec(params)" if has_defaults else "_pvec(params)",
                fills="".join(f"        _b_{a}[...] = {a}\n" for a in args),
                pointers=", ".join(str(buffers[a].ctypes.data) for a in args),
            )
        exec(compile(text, f"<jaxskid native {name}>", "exec"), ns)  # noqa: S102 - our own template
        return ns[name]

    def _arg_shape(self, arg: str) -> tuple[int, ...]:
        return self.argument_shape(arg)

    def _frames(self, fn):
        frames = self.frame_names

        def forward_kinematics(q, params=None):
            poses = fn(q, params)
            return {f: poses[k] for k, f in enumerate(frames)}

        forward_kinematics.__name__ = fn.__name__
        forward_kinematics.__doc__ = fn.__doc__ + "\n\nReturns a dict frame name -> 4x4 pose."
        return forward_kinematics

    def __repr__(self) -> str:
        return (f"NativeDynamics({self.robot_name!r}, n_dof={self.n_dof}, quantities={list(self.quantities)}, "
                f"backend={self.backend!r})")
