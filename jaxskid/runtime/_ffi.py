"""Native kernels in XLA programs on CPU: the matrix-valued quantities and the backward step of forward
dynamics, from the library of :mod:`jaxskid.lowering._ffi` (a :class:`jaxskid._generated.NativeBuild`, which
:func:`jaxskid.lower` supplies).

:func:`native_quantity` and :func:`native_backward` wrap a handler as a JAX function of one state:
``jax.ffi.ffi_call`` on CPU, the pure-JAX function it replaces on every other platform
(``lax.platform_dependent``), with that function's derivatives (``jax.custom_jvp``), so ``jax.grad`` and
gradients of gradients still work. They map over batches with the batch inside the kernel.

``JAXSKID_NATIVE=0`` in the environment turns it off; without a C compiler it is off, with one warning; where
JAX's default backend is not the CPU, nothing is built.
"""

from __future__ import annotations

import ctypes
import logging
import os
from collections.abc import Callable

import jax
import jax.numpy as jnp

from .._generated import NativeBuild
from ._cuda import CudaKernel, cuda_call

log = logging.getLogger("jaxskid")

_LIBRARIES: dict[str, object] = {}  # library path -> the loaded library
_TARGETS: dict[tuple[str, str], str] = {}  # (library path, handler) -> its registered target name
_WARNED: set[str] = set()


def enabled() -> bool:
    """Whether native kernels may be used: ``JAXSKID_NATIVE`` is not ``0``/``false``/``off``, and JAX's
    default backend is the CPU. Where it is a GPU or TPU, programs run there and no C is built for them (a
    computation placed on the CPU by hand then runs the JAX form)."""
    if os.environ.get("JAXSKID_NATIVE", "1").strip().lower() in ("0", "false", "off", "no"):
        return False
    return jax.default_backend() == "cpu"


def target(path: str | None, handler: str) -> str | None:
    """The registered XLA target of the handler ``jaxskid_<handler>`` of the library at ``path`` (loaded and
    registered once per process), or None where the library does not export it."""
    if path is None:
        return None
    key = (path, handler)
    if key not in _TARGETS:
        lib = _LIBRARIES.get(path)
        if lib is None:
            lib = _LIBRARIES[path] = ctypes.CDLL(path)
        symbol = getattr(lib, f"jaxskid_{handler}", None)
        if symbol is None:
            return None
        name = f"jaxskid_{handler}_{len(_TARGETS)}"
        jax.ffi.register_ffi_target(name, jax.ffi.pycapsule(symbol), platform="cpu")
        _TARGETS[key] = name
    return _TARGETS[key]


def library(native: NativeBuild | None, label: str) -> str | None:
    """The path of the library ``native.build()`` makes, or None (none, or its build failed: logged once per
    robot, and the pure-JAX kernels serve). The caller has checked :func:`enabled`."""
    if native is None:
        return None
    try:
        path = str(native.build())
        ctypes.CDLL(path)  # a library that does not load is a failed build
        return path
    except Exception as exc:  # no compiler, a failed build, an unloadable library: fall back, say why once
        if label not in _WARNED:
            _WARNED.add(label)
            log.warning("jaxskid: native kernels for %s unavailable (%s); using the JAX kernels", label,
                        " ".join(str(exc).split())[:300])
        return None


def platform_kernel(native: Callable, fallback: Callable, platform: str = "cpu") -> Callable:
    """``native`` on ``platform`` (``"cpu"`` or ``"cuda"``) and ``fallback`` elsewhere, with the derivatives of
    ``fallback``. On a machine whose devices are all of that platform the fallback is only traced for a
    derivative."""
    only = all(d.platform == ("cpu" if platform == "cpu" else "gpu") for d in jax.devices())

    def evaluate(*args):
        if only:
            return native(*args)
        return jax.lax.platform_dependent(*args, **{platform: native}, default=fallback)

    kernel = jax.custom_jvp(evaluate)

    @kernel.defjvp
    def _derivative(primals, tangents):
        # the value from the kernel; the fallback's own value is unused, and XLA drops what only it needs
        return evaluate(*primals), jax.jvp(fallback, primals, tangents)[1]

    return kernel


def ffi_kernel(target: str | CudaKernel, shape, vmap_method: str = "broadcast_all") -> Callable:
    """``f(*arrays, out=None)``: the kernel ``target`` called through ``jax.ffi.ffi_call`` on float32 or float64
    arrays (cast to their common dtype), with no fallback (:func:`native_call` gives it one)."""

    def native(*args, out=None):
        dtype = jnp.result_type(*args)
        args = [jnp.asarray(x, dtype) for x in args]
        if not isinstance(target, str):
            return cuda_call(target, shape, args, None if out is None else out.astype(dtype))
        result = jax.ShapeDtypeStruct(tuple(shape), dtype)
        name, attributes = target, {}
        if out is None:
            return jax.ffi.ffi_call(name, result, vmap_method=vmap_method)(*args, **attributes)
        aliased = jax.ffi.ffi_call(name, result, vmap_method=vmap_method, input_output_aliases={len(args): 0})
        return aliased(*args, out.astype(dtype), **attributes)

    return native


def native_call(target: str | CudaKernel, shape, fallback: Callable, vmap_method: str = "broadcast_all") -> Callable:
    """``f(*arrays, out=None)`` of result shape ``shape``, computed by the registered ``target`` on CPU (or the
    :class:`~jaxskid.runtime._cuda.CudaKernel` ``target`` on a GPU) for
    float32 and float64 (in double), and by ``fallback`` (the same function in JAX) elsewhere, for other dtypes
    (complex steps) and for derivatives. Under ``jax.vmap`` the batch goes into the kernel; ``vmap_method`` is
    ``jax.ffi.ffi_call``'s (``"expand_dims"``: unbatched inputs, the parameters mostly, are not copied per
    state). ``out``, an array of the result's shape and dtype, is where the kernel writes (XLA's
    ``input_output_aliases``): in a program that donates it, the result takes its memory, and no fresh
    memory is filled; its entries are not read."""

    native = ffi_kernel(target, shape, vmap_method)

    def plain(*args):
        return fallback(*args[:-1])

    kernel = platform_kernel(lambda *args: native(*args[:-1], out=args[-1]), plain,
                             "cpu" if isinstance(target, str) else "cuda")

    def call(*args, out=None):
        if jnp.result_type(*args) not in (jnp.float32, jnp.float64):
            return fallback(*args)
        return kernel(*args, out)

    call.__name__ = getattr(fallback, "__name__", "quantity")
    return call


def native_quantity(target: str | CudaKernel, shape: tuple[int, ...], fallback: Callable) -> Callable:
    """``f(*state, p)``, a quantity of one state of shape ``shape`` (:func:`native_call`)."""
    return native_call(target, shape, fallback, vmap_method="expand_dims")


def native_backward(target: str, n: int, n_out: int, fallback: Callable) -> Callable:
    """``f(q, qd, qdd, g, p) -> (lambda, -vjp)`` (:func:`native_call`); ``fallback`` returns the same pair,
    ``n_out`` is the length of ``vjp``."""
    flat = native_call(target, (n + n_out,), lambda *args: jnp.concatenate(fallback(*args)))

    def backward(*args):
        out = flat(*args)
        return out[:n], out[n:]

    return backward
