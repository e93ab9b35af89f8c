"""Compiled programs that outlive the process: JAX's persistent compilation cache in jaxskid's cache.

The generated modules are cached as text (:mod:`jaxskid.lowering._cache`), but XLA's compilation of a
rollout or of its gradient takes seconds to minutes and is lost with the process. JAX can keep the
compiled executables on disk, keyed by the program, the compiler options and the device; jaxskid turns
that on in ``cache_dir() / "xla"`` at the first :func:`jaxskid.lower`, unless:

* the environment variable ``JAXSKID_COMPILATION_CACHE`` is ``0`` (or ``false``, ``off``, ``no``);
* the user configured JAX's own cache (``jax_compilation_cache_dir`` or ``JAX_COMPILATION_CACHE_DIR``),
  which is then used as it is;
* the cache was turned off with :func:`compilation_cache` ``(None)``.

Like JAX's, the cache is trusted code: keep it in a directory only you can write to.
"""

from __future__ import annotations

import os
from pathlib import Path

import jax
from jax.experimental.compilation_cache import compilation_cache as _jax_cache

from ._cache import cache_dir

ENV = "JAXSKID_COMPILATION_CACHE"
_OFF = {"0", "false", "off", "no"}
MIN_COMPILE_SECONDS = 0.2
"""Programs that compile faster than this are not written (JAX's own default, 1 s, would leave out most of
the compilations of a first call: the quantity functions and the small conversions around them)."""

_state = {"decided": False}


def compilation_cache(path: str | os.PathLike | None | bool = True) -> Path | None:
    """Turn JAX's persistent compilation cache on in ``path``, or off.

    Args:
        path: a directory; ``True`` for ``jaxskid.cache_dir() / "xla"`` (the default, which
            :func:`jaxskid.lower` turns on by itself); ``None`` or ``False`` to turn it off for this process.

    Returns:
        The directory in use, or ``None`` when off. Programs compiled from then on are read from and
        written to it; a new process finds them there and skips XLA's compilation.
    """
    _state["decided"] = True
    _jax_cache.reset_cache()  # JAX opens its cache once; a new directory takes effect from here on
    if path is None or path is False:
        jax.config.update("jax_compilation_cache_dir", None)
        return None
    directory = Path(cache_dir() / "xla" if path is True else path)
    directory.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(directory))
    if jax.config.jax_persistent_cache_min_compile_time_secs > MIN_COMPILE_SECONDS:
        jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)
    return directory


def default_compilation_cache() -> Path | None:
    """The decision :func:`jaxskid.lower` makes once per process (see the module docstring): the cache in
    jaxskid's directory, or whatever the user chose. Returns the directory in use, or ``None``."""
    if _state["decided"]:
        configured = jax.config.jax_compilation_cache_dir
        return Path(configured) if configured else None
    _state["decided"] = True
    configured = jax.config.jax_compilation_cache_dir
    if configured:  # the user's own JAX cache
        return Path(configured)
    if os.environ.get(ENV, "1").strip().lower() in _OFF:
        return None
    try:
        return compilation_cache(True)
    except OSError:  # a read-only home: compile every time, as JAX does by default
        return None
