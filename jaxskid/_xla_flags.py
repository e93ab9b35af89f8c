"""The switch to XLA's classic CPU emitters, set in ``XLA_FLAGS`` when jaxskid is imported, before JAX's
backends start. Imports nothing of JAX at import, so that ``import jaxskid`` stays light
(:func:`prefer_classic_emitters`; the per-program option is :func:`jaxskid.compiler_options`). Synchronous
dispatch on CPU (:func:`prefer_synchronous_cpu_dispatch`) is set when the runtime, which imports JAX, is. On
request (``JAXSKID_MALLOC=keep``), :func:`keep_freed_memory` makes glibc's allocator keep freed memory for the
next call's large buffers."""

from __future__ import annotations

import os
import sys

CLASSIC_EMITTERS_FLAG = "--xla_cpu_use_fusion_emitters=false"
LAST_WITH_CLASSIC_EMITTERS = (0, 10)  # jaxlib 0.11's XLA no longer knows the switch


def classic_emitters_switch() -> bool:
    """Whether this jaxlib's XLA has the switch to its classic CPU emitters. It is gone from jaxlib 0.11,
    whose XLA aborts the process at an unknown flag in ``XLA_FLAGS`` and refuses an unknown compiler
    option, so neither is given there."""
    try:
        import jaxlib.version

        release = tuple(int(part) for part in jaxlib.version.__version__.split(".")[:2])
    except (ImportError, AttributeError, ValueError):
        return False
    return release <= LAST_WITH_CLASSIC_EMITTERS


def prefer_classic_emitters() -> bool:
    """Make XLA's classic CPU emitters the process's default, so that a plain ``jax.jit`` of jaxskid's
    functions compiles as :func:`jaxskid.jit` does (otherwise a hand-written RK4 loop over the Panda's forward
    dynamics runs slower under ``jax.jit`` than under :func:`jaxskid.jit`; ``benchmarks/raw_loop.py``
    compares the two).

    Called when jaxskid is imported. It adds :data:`CLASSIC_EMITTERS_FLAG` to ``XLA_FLAGS`` only while
    JAX's backends have not started (XLA reads the variable once, when they do) and only if ``XLA_FLAGS``
    says nothing of the fusion emitters: ``XLA_FLAGS=--xla_cpu_use_fusion_emitters=true`` keeps XLA's
    default. Nothing is added where XLA has no such switch (:func:`classic_emitters_switch`). Returns
    whether the flag is in effect from this call.
    """
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_use_fusion_emitters" in flags or not classic_emitters_switch():
        return False
    if "jax" in sys.modules:  # JAX imported first: its backends may have started
        try:
            from jax._src import xla_bridge

            if xla_bridge.backends_are_initialized():
                return False  # too late for this process; jaxskid.jit still passes the option per program
        except (ImportError, AttributeError):
            return False
    os.environ["XLA_FLAGS"] = f"{flags} {CLASSIC_EMITTERS_FLAG}".strip()
    return True


SYNC_DISPATCH_VARIABLE = "JAXSKID_SYNC_DISPATCH"
"""Set to 1 to run JAX's CPU computations on the calling thread (:func:`prefer_synchronous_cpu_dispatch`)."""


def prefer_synchronous_cpu_dispatch() -> bool:
    """Make JAX's CPU client run each computation on the calling thread (``jax_cpu_enable_async_dispatch =
    False``), while JAX's backends have not started (the option is read once, when the CPU client is made).

    With asynchronous dispatch every call hands its computation to another thread and the caller then waits
    for it; on a machine whose cores other processes keep busy, each hand-over waits for the scheduler, and a
    loop of small calls that reads every result (:func:`jaxskid.design_excitation`'s optimiser) runs several
    times slower free to use every core than pinned to one (``benchmarks/threads.py`` measures both). A large
    batched rollout, though, runs several times slower on the calling thread (``examples/quadruped_drop.py``),
    so JAX's default stays: ``JAXSKID_SYNC_DISPATCH=1`` in the environment asks for this. Called when jaxskid's
    runtime is imported (it imports JAX); returns whether it set the option.
    """
    if os.environ.get(SYNC_DISPATCH_VARIABLE, "0") in ("", "0"):
        return False
    try:
        import jax
        from jax._src import xla_bridge

        if xla_bridge.backends_are_initialized():
            return False  # too late for this process: the CPU client exists
        jax.config.update("jax_cpu_enable_async_dispatch", False)
    except (ImportError, AttributeError, KeyError, ValueError):  # a JAX without the option
        return False
    return True


MALLOC_VARIABLE = "JAXSKID_MALLOC"
"""Set to ``keep`` to keep freed memory for the next allocation (:func:`keep_freed_memory`)."""

_M_TRIM_THRESHOLD, _M_MMAP_MAX, _M_ARENA_MAX = -1, -4, -8  # glibc's mallopt parameters (malloc.h)
KEPT_TOP = 1 << 30
"""Freed memory at the top of the heap returned to the system only beyond this (bytes)."""


def keep_freed_memory() -> bool:
    """With ``JAXSKID_MALLOC=keep`` on Linux with glibc: serve every allocation from one heap that keeps what is
    freed (``mallopt``: no ``mmap`` for large blocks, one arena, freed memory kept up to :data:`KEPT_TOP`).

    glibc gives a block of 32 MB or more its own ``mmap`` and returns it to the system when it is freed, so a
    program with such results or temporaries (XLA's buffers of a batch of 4,096 states: the G1 with hands'
    mass matrices are 60 MB) touches fresh pages on every call, and the page faults cost more than the
    arithmetic: a 60 MB elementwise kernel ran 6-9x faster with this. The price: the process keeps its peak
    memory, and its threads share one arena. Off by default: a library does not change how the process
    allocates unless asked. Called when jaxskid is imported, before JAX's threads allocate (arenas already
    made keep their own); returns whether the settings took.
    """
    if os.environ.get(MALLOC_VARIABLE, "") != "keep" or not sys.platform.startswith("linux"):
        return False
    import ctypes

    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):  # not glibc
        return False
    settings = ((_M_ARENA_MAX, 1), (_M_MMAP_MAX, 0), (_M_TRIM_THRESHOLD, KEPT_TOP))
    return all(mallopt(option, value) == 1 for option, value in settings)
