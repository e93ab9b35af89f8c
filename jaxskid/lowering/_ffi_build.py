"""Building the shared library of the native kernels (:mod:`._ffi`'s handlers around the generated C), once
per machine, keyed by a hash of everything that goes in; a build can start in a background thread
(:func:`ffi_library_soon`) so that the C compiler runs while the caller goes on."""

from __future__ import annotations

import concurrent.futures
import threading
from collections.abc import Mapping
from pathlib import Path

from ._ffi import FFI_CFLAGS, LANES, _vector_flags, glue_source, include_dir
from ._native import CFLAGS, BuildError, _compile, _compiler, _install, _key, _sources


def ffi_library(native: Mapping, root: Path) -> Path:
    """Build (once per machine: keyed by a hash of everything that goes in) the shared library of the
    handlers of :func:`glue_source` for ``native`` (``{"stem", "header", "source", "backward", "kernels"}``,
    the generated C of :func:`jaxskid.codegen._c.native_sources`), under ``root``; when
    :func:`ffi_library_soon` already started that build, wait for it.

    Raises:
        BuildError: no C compiler, no FFI header, or the build failed.
    """
    plan = _plan(native, root)
    with _LOCK:
        pending = _PENDING.get(plan[0])
    return pending.result() if pending is not None else _build(*plan)


def ffi_library_soon(native: Mapping, root: Path) -> None:
    """Start :func:`ffi_library` in a background thread and return at once: the compiler runs in its own
    process while the caller goes on (printing the JAX module). A build that cannot start is left to
    :func:`ffi_library`, which reports it."""
    try:
        plan = _plan(native, root)
    except BuildError:
        return
    with _LOCK:
        if plan[0].exists() or plan[0] in _PENDING:
            return
        global _POOL
        if _POOL is None:
            _POOL = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="jaxskid-cc")
        _PENDING[plan[0]] = _POOL.submit(_build, *plan)


_LOCK = threading.Lock()
_PENDING: dict[Path, concurrent.futures.Future] = {}  # builds started by ffi_library_soon, by library path
_POOL: concurrent.futures.ThreadPoolExecutor | None = None


def _plan(native: Mapping, root: Path) -> tuple:
    """``(library path, stem, header, source, glue, compiler command but its output)`` of :func:`ffi_library`."""
    stem = native["stem"]
    glue, lanes = glue_source(native)
    vectors = lanes or native.get("kernels")
    flags = (*CFLAGS, *FFI_CFLAGS, *((f"-DLANES={LANES}",) if lanes else ()), *(_vector_flags() if vectors else ()))
    inc = include_dir()
    if not (Path(inc) / "xla" / "ffi" / "api" / "c_api.h").exists():
        raise BuildError(f"jaxlib has no FFI header under {inc}")
    cc = _compiler()
    key = _key("ffi", cc, " ".join(flags), inc, native["header"], native["source"], glue)
    final = root / key[:24] / f"lib{stem}_ffi.so"
    return final, stem, native["header"], native["source"], glue, (*cc.split(), *flags, "-shared", "-I", inc)


def _build(final: Path, stem: str, header: str, source: str, glue: str, command: tuple) -> Path:
    if not final.exists():
        tmp = _sources(final.parent.parent, stem, header, source)
        (tmp / "glue.c").write_text(glue)
        out = tmp / final.name
        _compile([*command, "-I", str(tmp), "-o", str(out), str(tmp / "glue.c"), "-lm"], tmp)
        _install(tmp, out, final)
    return final
