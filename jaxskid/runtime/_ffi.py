"""The backward step of forward dynamics as one native kernel in XLA programs on CPU.

:func:`native_backward` wraps the library of :mod:`jaxskid.lowering._ffi` (built by the caller's
``build`` function, which :func:`jaxskid.lower` supplies) as a JAX function
``(q, qd, qdd, g, p) -> (lambda, -vjp)`` of one state: ``jax.ffi.ffi_call`` on CPU, the pure-JAX
function it replaces on every other platform (``lax.platform_dependent``), with that function's
derivatives (``jax.custom_jvp``), so gradients of gradients still work. It maps over batches with the
batch inside the kernel.

``JAXSKID_NATIVE=0`` in the environment turns it off; without a C compiler it is off, with one warning.
"""

from __future__ import annotations

import ctypes
import logging
import os
from collections.abc import Callable

import jax
import jax.numpy as jnp

log = logging.getLogger("jaxskid")

_TARGETS: dict[str, tuple[str, object]] = {}  # library path -> (registered target name, loaded library)
_WARNED: set[str] = set()


def enabled() -> bool:
    """Whether native kernels may be used (``JAXSKID_NATIVE`` is not ``0``/``false``/``off``)."""
    return os.environ.get("JAXSKID_NATIVE", "1").strip().lower() not in ("0", "false", "off", "no")


def _register(path: str) -> str:
    """Load the library at ``path`` and register its handler with XLA (once per process)."""
    if path not in _TARGETS:
        lib = ctypes.CDLL(path)
        name = f"jaxskid_fd_vjp_{len(_TARGETS)}"
        jax.ffi.register_ffi_target(name, jax.ffi.pycapsule(lib.jaxskid_fd_vjp), platform="cpu")
        _TARGETS[path] = (name, lib)
    return _TARGETS[path][0]


def library(build: Callable[[], str] | None, label: str) -> str | None:
    """The registered target of the library ``build()`` makes, or None (turned off, or the build failed:
    logged once per robot, and the pure-JAX kernels serve)."""
    if build is None or not enabled():
        return None
    try:
        return _register(str(build()))
    except Exception as exc:  # no compiler, a failed build, an unloadable library: fall back, say why once
        if label not in _WARNED:
            _WARNED.add(label)
            log.warning("jaxskid: native kernels for %s unavailable (%s); using the JAX kernels", label,
                        " ".join(str(exc).split())[:300])
        return None


def native_backward(target: str, n: int, n_out: int, fallback: Callable) -> Callable:
    """``f(q, qd, qdd, g, p) -> (lambda, -vjp)`` computed by the registered ``target`` on CPU and by
    ``fallback`` (the same function in JAX) elsewhere; ``n_out`` is the length of ``vjp``. On a machine
    whose devices are all CPUs the fallback is only traced for a gradient of a gradient."""

    def native(q, qd, a, g, p):
        dtype = jnp.result_type(q, qd, a, g, p)
        args = [jnp.asarray(x, dtype) for x in (q, qd, a, g, p)]
        out = jax.ffi.ffi_call(target, jax.ShapeDtypeStruct((n + n_out,), dtype), vmap_method="broadcast_all")(*args)
        return out[:n], out[n:]

    cpu_only = all(d.platform == "cpu" for d in jax.devices())

    @jax.custom_jvp
    def kernel(q, qd, a, g, p):
        if cpu_only:  # the JAX form is not traced where no other platform could run it
            return native(q, qd, a, g, p)
        return jax.lax.platform_dependent(q, qd, a, g, p, cpu=native, default=fallback)

    @kernel.defjvp
    def _derivative(primals, tangents):  # a gradient of a gradient differentiates the JAX form
        return jax.jvp(fallback, primals, tangents)

    return kernel
