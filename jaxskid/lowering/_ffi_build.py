"""Building the shared library of the native kernels (:mod:`._ffi`'s handlers around the generated C), once
per machine, keyed by a hash of everything that goes in; a build can start in a background thread
(:func:`ffi_library_soon`) so that the C compiler runs while the caller goes on. A long kernel, split into
pieces (:func:`._ffi._chunked`), compiles as several translation units at once, one per core
(:func:`split`)."""

from __future__ import annotations

import concurrent.futures
import functools
import os
import shutil
import subprocess
import threading
import tempfile
from dataclasses import dataclass
from pathlib import Path

from .._generated import NativeSource
from ._cuda import compile_kernel, handler_library, kernel_source, nvrtc, threads
from ._cuda_rollout import ROLLOUT_PTXAS, rollout_source
from ._ffi import FFI_CFLAGS, LANES, Piece, _vector_flags, glue_parts, include_dir
from ._native import CFLAGS, BuildError, _compile, _compiler, _install, _key, _sources
from ._templates import fill, template


@dataclass(frozen=True)
class NativeLibrary:
    """One native library of a lowering (:class:`jaxskid._generated.NativeBuild`): its generated C and the
    folder it is built in (None: a temporary folder, when the cache is off). :func:`jaxskid.lower` gives
    these to :class:`jaxskid.Dynamics`, which builds each when it first needs one of its kernels."""

    sources: NativeSource
    root: Path | None = None

    def build(self) -> Path:
        """The built library's path (:func:`ffi_library`)."""
        root = self.root if self.root is not None else Path(tempfile.mkdtemp(prefix="jaxskid-native-"))
        return ffi_library(self.sources, root)

    def cuda_image(self, name: str, dtype: str, arch: str, shared: bool = True) -> tuple[bytes, int]:
        """The CUDA kernel of ``name`` compiled for ``dtype`` and ``arch`` (:mod:`._cuda`), and its threads per
        block."""
        source = kernel_source(self.sources, name, dtype, shared)
        if source is None:
            raise BuildError(f"{name} has no CUDA kernel (no vector form)")
        return compile_kernel(source, arch, self._folder() / "cuda"), threads()

    def cuda_handler(self) -> Path:
        """The handler's library (:func:`._cuda.handler_library`).

        Raises:
            BuildError: no C compiler or XLA FFI header, or no NVRTC to compile the kernels with.
        """
        nvrtc()
        return handler_library(self._folder() / "cuda")

    def cuda_rollout_image(self, vectors, n: int, n_params: int, steps: int, dtype: str, arch: str,
                           part: str, shared: bool = True) -> tuple[bytes, int]:
        """A rollout kernel (:func:`._cuda_rollout.rollout_source`) compiled for ``dtype`` and ``arch``, and its
        threads per block."""
        source = rollout_source(vectors, self.sources.stem, n, n_params, steps, dtype, part, shared)
        return compile_kernel(source, arch, self._folder() / "cuda", ROLLOUT_PTXAS), threads()

    def _folder(self) -> Path:
        return self.root if self.root is not None else _temporary()


@functools.cache
def _temporary() -> Path:
    """This process's folder for the builds of a lowering without a cache."""
    return Path(tempfile.mkdtemp(prefix="jaxskid-native-"))


def ffi_library(native: NativeSource, root: Path) -> Path:
    """Build (once per machine: keyed by a hash of everything that goes in) the shared library of the
    handlers of :func:`glue_source` for ``native`` (the generated C of
    :func:`jaxskid.codegen._c.native_sources`), under ``root``; when
    :func:`ffi_library_soon` already started that build, wait for it.

    Raises:
        BuildError: no C compiler, no FFI header, or the build failed.
    """
    plan = _plan(native, root)
    with _LOCK:
        pending = _PENDING.get(plan[0])
    return pending.result() if pending is not None else _build(*plan)


def ffi_library_soon(native: NativeSource, root: Path, later: bool = False) -> None:
    """Start :func:`ffi_library` in a background thread and return at once: the compiler runs in its own
    process while the caller goes on (printing the JAX module). A build that cannot start is left to
    :func:`ffi_library`, which reports it. ``later``: the library serves only what is used later (the
    derivatives of forward dynamics), so the compiler runs at a low priority: on two cores its build
    slowed the first call of the G1's forward dynamics, which does not need it."""
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
        _PENDING[plan[0]] = _POOL.submit(_build, *plan, nice=_LATER if later else 0)


_LATER = 10
"""The niceness of a compiler building for :func:`ffi_library_soon` with ``later``."""

_LOCK = threading.Lock()
_PENDING: dict[Path, concurrent.futures.Future] = {}  # builds started by ffi_library_soon, by library path
_POOL: concurrent.futures.ThreadPoolExecutor | None = None


def _plan(native: NativeSource, root: Path) -> tuple:
    """``(library path, stem, header, source, glue, compiler command but its output)`` of :func:`ffi_library`."""
    stem = native.stem
    glue, lanes = glue_parts(native)
    vectors = lanes or native.kernels
    flags = (*CFLAGS, *FFI_CFLAGS, *((f"-DLANES={LANES}",) if lanes else ()), *(_vector_flags() if vectors else ()))
    inc = include_dir()
    if not (Path(inc) / "xla" / "ffi" / "api" / "c_api.h").exists():
        raise BuildError(f"jaxlib has no FFI header under {inc}")
    cc = _compiler()
    glue, parts = split(glue, _cores())
    key = _key("ffi", cc, " ".join(flags), inc, native.header, native.source, glue, str(parts))
    final = root / key[:24] / f"lib{stem}_ffi.so"
    return final, stem, native.header, native.source, glue, (*cc.split(), *flags, "-I", inc), parts


def _build(final: Path, stem: str, header: str, source: str, glue: str, command: tuple, parts: int,
           nice: int = 0) -> Path:
    if not final.exists():
        tmp = _sources(final.parent.parent, stem, header, source)
        (tmp / "glue.c").write_text(glue)
        out, glue_file = tmp / final.name, str(tmp / "glue.c")
        if parts == 1:
            _compile_all([[*command, "-shared", "-I", str(tmp), "-o", str(out), glue_file, "-lm"]], tmp, nice)
        else:
            objects = [str(tmp / f"part{k}.o") for k in range(parts)]
            _compile_all([[*command, f"-DJAXSKID_PART={k}", "-I", str(tmp), "-c", "-o", obj, glue_file]
                          for k, obj in enumerate(objects)], tmp, nice)
            _compile_all([[*command, "-shared", "-o", str(out), *objects, "-lm"]], tmp, nice)
        _install(tmp, out, final)
    return final


def _compile_all(commands: list[list[str]], tmp: Path, nice: int = 0) -> None:
    """Run the compiler commands at once, ``nice`` lower in priority; on a failure, as
    :func:`._native._compile` does."""
    runner = shutil.which("nice") if nice else None  # the compiler's own processes inherit its niceness
    prefix = [runner, "-n", str(nice)] if runner else []
    procs = [subprocess.Popen([*prefix, *cmd], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
             for cmd in commands]
    failed = [cmd for cmd, proc in zip(commands, procs) if proc.wait() != 0]
    if failed:
        _compile(failed[0], tmp)  # again, to raise BuildError with the compiler's output


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def split(glue: list[str | Piece], cores: int) -> tuple[str, int]:
    """``(glue, parts)``: the glue (:func:`._ffi.glue_parts`) as ``parts`` translation units, one per core (at
    most 4), each compiled with ``-DJAXSKID_PART=k``. The pieces of long kernels are dealt out to the parts by
    length; a part defines its own and declares the others. The handlers are part 0's (the templates guard
    them with ``#if JAXSKID_PART == 0``), and everything else a part does not call is static and dropped by the
    compiler. Without the macro the glue is one translation unit. Fewer than two pieces, or one core: one
    part. The build of the G1's Coriolis matrix (17 pieces) in one process was the critical path of its cold
    lowering: the Python side finished before it."""
    pieces = [p for p in glue if isinstance(p, Piece)]
    parts = min(cores, len(pieces), 4)
    if parts < 2:
        return "".join(p.text() if isinstance(p, Piece) else p for p in glue), 1
    load, owner = [0] * parts, {}
    for p in sorted(pieces, key=lambda p: -len(p.text())):
        k = load.index(min(load))
        owner[p.name] = k
        load[k] += len(p.text())

    def text(p: str | Piece) -> str:
        if not isinstance(p, Piece):
            return p
        return fill(template("piece.c"), OWNER=owner[p.name], NAME=p.name, PARAMS=p.params, BODY=p.body)

    return template("piece_prelude.h") + "".join(map(text, glue)), parts
