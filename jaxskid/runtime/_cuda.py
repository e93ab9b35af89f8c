"""CUDA kernels in XLA programs on a GPU: the matrix-valued quantities as the generated kernels of
:mod:`jaxskid.lowering._cuda`, one state per thread, behind one XLA FFI handler.

:class:`CudaKernel` is the target :func:`jaxskid.runtime._ffi.native_call` calls on a GPU where on CPU it calls a
C kernel: the same arguments, batch broadcasting and ``out=``. Each kernel is compiled with NVRTC for the
device's architecture when a program first uses it with a dtype (float32 or float64), kept on disk, and
registered with the handler once per process.

``JAXSKID_CUDA=0`` turns it off (the JAX form runs); it is off where JAX's default backend is not a CUDA GPU.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import os
import threading

import jax
import jax.numpy as jnp
import numpy as np
from jax.extend.core import Primitive
from jax.interpreters import batching, mlir

from .._generated import NativeBuild, by_entry, constant_input
from ._whole import result_aval

TARGET = "jaxskid_cuda_quantity"
log = logging.getLogger("jaxskid")
_WARNED: set[str] = set()
_HANDLER: list = []
_LOCK = threading.Lock()


def enabled() -> bool:
    """Whether CUDA kernels may be used: ``JAXSKID_CUDA`` is not ``0``/``false``/``off``/``no``, and JAX's
    default backend is a CUDA GPU."""
    if os.environ.get("JAXSKID_CUDA", "1").strip().lower() in ("0", "false", "off", "no"):
        return False
    if jax.default_backend() != "gpu":
        return False
    version = str(getattr(jax.devices()[0].client, "platform_version", "")).lower()
    return "rocm" not in version and "hip" not in version


def _handler(build: NativeBuild) -> ctypes.CDLL:
    """The handler's library, built and registered with XLA for the CUDA platform once per process."""
    with _LOCK:
        if not _HANDLER:
            lib = ctypes.CDLL(str(build.cuda_handler()))
            lib.jaxskid_cuda_register.restype = ctypes.c_int64
            lib.jaxskid_cuda_register.argtypes = [ctypes.c_char_p, ctypes.c_int64, ctypes.c_int,
                                                  ctypes.POINTER(ctypes.c_int64), ctypes.POINTER(ctypes.c_int64),
                                                  ctypes.c_int64, ctypes.c_int64, ctypes.c_int, ctypes.c_int,
                                                  ctypes.c_int, ctypes.c_int]
            jax.ffi.register_ffi_target(TARGET, jax.ffi.pycapsule(lib.jaxskid_cuda_quantity), platform="CUDA")
            _HANDLER.append(lib)
        return _HANDLER[0]


def architecture() -> str:
    """The default device's real architecture, ``"sm_90"`` for compute capability 9.0."""
    capability = str(getattr(jax.devices()[0], "compute_capability", "9.0"))
    return "sm_" + capability.replace(".", "")


class CudaKernel:
    """The CUDA kernel of the quantity ``name`` of a native library (its sources, and the builds of its
    kernels and of the handler: :class:`jaxskid._generated.NativeBuild`)."""

    def __init__(self, build: NativeBuild, name: str):
        self.build, self.name = build, name
        self._ids: dict[tuple[str, bool], int] = {}

    def __repr__(self) -> str:
        return f"CudaKernel({self.build.sources.stem}.{self.name})"

    def call(self, dtype, shared: bool = False) -> tuple[str, dict]:
        """The FFI target and attributes of a call on ``dtype`` states (compiled and registered on the first);
        ``shared``: every state of the call has the same parameters, which the kernel then reads from constant
        memory (:meth:`shares` tells from the inputs' types)."""
        key = (np.dtype(dtype).name, bool(shared))
        if key not in self._ids:
            image, threads = self._image(*key)
            self._ids[key] = register(self.build, image, threads, *self._layout(key[1]), str(self))
        return TARGET, {"kernel": np.int64(self._ids[key])}

    def _shape(self) -> tuple:
        """``(sizes, cores, n_out, out_rank, zero_first)``: the entries per state of each input and the trailing
        axes holding them, the same of the result, and whether the handler zeroes the result first."""
        _, sizes, cores, n_out, out_rank = next(k for k in self.build.sources.kernels if k[0] == self.name)
        return sizes, cores, n_out, out_rank, bool(self.build.sources.vectors[self.name].zeros)

    def _parameters(self) -> tuple[int, int]:
        """``(input, size)``: which input holds the parameters (the last), and their number."""
        sizes = self._shape()[0]
        return len(sizes) - 1, sizes[-1]

    def out_rank(self) -> int:
        """The number of the result's trailing axes that hold one state's entries."""
        return self._shape()[3]

    def columns(self) -> bool:
        """Whether the kernel writes its result by entry (:func:`jaxskid._generated.by_entry`)."""
        return by_entry(self._shape()[2])

    def shares(self, avals) -> bool:
        """Whether a call on inputs of types ``avals``, as lowered (batch axes included), has one set of
        parameters for every state."""
        index, size = self._parameters()
        return int(np.prod(avals[index].shape, dtype=np.int64)) == size

    def _image(self, dtype: str, shared: bool) -> tuple[bytes, int]:
        return self.build.cuda_image(self.name, dtype, architecture(), shared)

    def _layout(self, shared: bool) -> tuple:
        """:meth:`_shape`, the input read into constant memory (-1: none) and :meth:`columns`, as
        :func:`register` takes them."""
        return (*self._shape(), constant_input(*self._parameters(), shared), self.columns())


def register(build: NativeBuild, image: bytes, threads: int, sizes, cores, n_out: int, out_rank: int,
             zero_first: bool, constant: int, columns: bool, label: str) -> int:
    """A compiled kernel registered with the handler (``c/cuda_handler.c``): its number, the attribute ``kernel``
    of its calls. ``constant``: the input the handler copies into the kernel's constant memory (-1: none);
    ``columns``: it writes its result by entry."""
    lib = _handler(build)
    sizes_c, cores_c = (ctypes.c_int64 * len(sizes))(*sizes), (ctypes.c_int64 * len(cores))(*cores)
    kid = lib.jaxskid_cuda_register(image, len(image), len(sizes), sizes_c, cores_c, n_out, out_rank, threads,
                                    int(zero_first), int(constant), int(columns))
    if kid < 0:
        raise RuntimeError(f"jaxskid: the CUDA kernel {label} could not be registered")
    return kid


def cuda_kernel(build: NativeBuild, name: str, label: str) -> CudaKernel | None:
    """The kernel of ``name``, or None where it has none (not a kernel of the library, or no vector form) or
    where the handler cannot be built or NVRTC is missing (logged once per ``label``, a robot's name: the JAX
    form serves)."""
    sources = build.sources
    if sources.vectors.get(name) is None or not any(k[0] == name for k in sources.kernels):
        return None
    try:
        _handler(build)
    except Exception as exc:  # no C compiler, no NVRTC, no FFI header
        if label not in _WARNED:
            _WARNED.add(label)
            log.warning("jaxskid: CUDA kernels for %s unavailable (%s); using the JAX form", label,
                        " ".join(str(exc).split())[:300])
        return None
    return CudaKernel(build, name)


# ---------------------------------------------------------------------------------------------- the call
def cuda_call(kernel: CudaKernel, shape: tuple, args, out=None):
    """``kernel`` on the arrays ``args`` (one dtype, float32 or float64), a result of ``shape``; ``out``, where
    given, the array its result is written into (XLA's ``input_output_aliases``). Under ``jax.vmap`` the batch
    goes into the call, and inputs that are not mapped get an axis of one (the handler shares them, as
    ``jax.ffi.ffi_call``'s ``"expand_dims"``). The kernel is chosen when the program is lowered, from its inputs'
    types with every batch axis in place: the parameters in constant memory where all states share them."""
    operands = [*args] if out is None else [*args, out]
    return _call_p.bind(*operands, kernel=kernel, shape=tuple(shape), aliased=out is not None)


_call_p = Primitive("jaxskid_cuda_call")


@functools.lru_cache(maxsize=256)
def _compiled(kernel: CudaKernel, shape: tuple, aliased: bool):
    return jax.jit(lambda *a: _call_p.bind(*a, kernel=kernel, shape=shape, aliased=aliased))


def _impl(*args, kernel, shape, aliased):  # a call outside any trace: compiled once per kernel and result shape
    return _compiled(kernel, shape, aliased)(*args)


def _abstract(*avals, kernel, shape, aliased):
    return result_aval(avals, shape, avals[0].dtype)


def _batch(args, dims, *, kernel, shape, aliased):
    size = next(a.shape[d] for a, d in zip(args, dims) if d is not None)
    moved = []
    for k, (a, d) in enumerate(zip(args, dims)):
        if d is not None:
            moved.append(jnp.moveaxis(a, d, 0))
        elif aliased and k == len(args) - 1:  # the result's memory: one per state
            moved.append(jnp.broadcast_to(a, (size, *a.shape)))
        else:
            moved.append(a[None])
    return _call_p.bind(*moved, kernel=kernel, shape=(size, *shape), aliased=aliased), 0


def _lower(ctx, *args, kernel, shape, aliased):
    n_in = len(args) - aliased
    name, attributes = kernel.call(ctx.avals_in[0].dtype, kernel.shares(ctx.avals_in[:n_in]))
    if kernel.columns():  # entries by state, transposed by XLA into a row per state; no memory to write into
        result = ctx.avals_out[0]
        nb = len(result.shape) - kernel.out_rank()
        entries = jax.ShapeDtypeStruct((int(np.prod(result.shape[nb:], dtype=np.int64)), *result.shape[:nb]),
                                       result.dtype)

        def by_entry(*inputs):
            flat = jax.ffi.ffi_call(name, entries)(*inputs, **attributes)
            return jnp.moveaxis(flat, 0, -1).reshape(result.shape)

        return mlir.lower_fun(by_entry, multiple_results=False)(ctx.replace(avals_in=ctx.avals_in[:n_in]),
                                                                *args[:n_in])
    rule = jax.ffi.ffi_lowering(name, operand_output_aliases={n_in: 0} if aliased else None)
    return rule(ctx, *args, **attributes)


_call_p.def_impl(_impl)
_call_p.def_abstract_eval(_abstract)
mlir.register_lowering(_call_p, _lower)
batching.primitive_batchers[_call_p] = _batch
