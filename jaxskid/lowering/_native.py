"""Building generated C into a library that Python calls directly: the compiler, the cffi and ctypes
builds, and the cache of built libraries. Nothing here knows SymPy or the equations: a build takes C text
and the names of the functions to export.

Backends (one argument, ``backend``):

* ``"cffi"`` (the default when cffi is installed): cffi's API mode builds a CPython extension module
  around the C (needs the Python headers); arguments pass as ``ffi.from_buffer`` views, with no copy.
* ``"ctypes"``: a plain shared library (needs only a C compiler), called through ctypes with the
  argument types set once.
* ``"capi"`` (the default where Python's and NumPy's headers are present): an extension module written for
  the quantities (:mod:`._extension`), whose methods check NumPy arrays in C and call the generated code
  with nothing in between; the fastest for single calls.

A built library lives in ``<root>/<key>/``, keyed by a hash of the C source, the backend, the compiler
and its flags and the Python ABI, so it is built once per machine and reused.
"""

from __future__ import annotations

import ctypes
import hashlib
import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from .._errors import JaxskidError, RequestError
from ._extension import Method, extension_source

CFLAGS = ("-O2", "-g0", "-std=c99", "-fPIC")
BACKENDS = ("capi", "cffi", "ctypes")


class BuildError(JaxskidError):
    """The generated C could not be compiled (no compiler, or the compiler failed)."""


@dataclass(frozen=True)
class Library:
    """A built library: its file, its functions by C name, and for cffi the ``ffi`` to pass buffers with
    (``None`` for ctypes, whose functions take addresses). ``handle`` keeps the library loaded."""

    path: Path
    functions: Mapping[str, Callable]
    ffi: object | None
    handle: object


def default_backend() -> str:
    """``"capi"`` where Python's headers are installed, else ``"cffi"`` when cffi is, else ``"ctypes"``."""
    if (Path(sysconfig.get_paths()["include"]) / "Python.h").exists():
        return "capi"
    return "cffi" if importlib.util.find_spec("cffi") is not None else "ctypes"


def build(name: str, header: str, source: str, functions: Mapping[str, int], backend: str, root: Path,
          methods: Sequence[Method] = ()) -> Library:
    """Compile ``<name>.c`` (``source``, which includes ``<name>.h``, ``header``) with the system compiler.

    Args:
        name: the file stem of the C files, an identifier.
        functions: the C functions to export, name -> number of arguments; each is
            ``void f(const double *, ..., double *out)`` (every argument a pointer to doubles, the last
            one the output).
        backend: ``"capi"``, ``"cffi"`` or ``"ctypes"`` (see the module docstring).
        root: the folder of built libraries.
        methods: for ``"capi"``, the extension's methods (one per function of ``functions``); the library's
            ``functions`` are then those methods, by C name, and ``handle`` the module.

    Raises:
        RequestError: an unknown backend.
        BuildError: no C compiler, or the build failed (the message ends with the compiler's output).
    """
    if backend not in BACKENDS:
        raise RequestError(f"unknown backend {backend!r}; expected one of {', '.join(BACKENDS)}")
    if backend == "capi":
        return _build_capi(name, header, source, methods, root)
    builder = _build_cffi if backend == "cffi" else _build_ctypes
    return builder(name, header, source, functions, root)


def _compiler() -> str:
    cc = os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc"
    exe = cc.split()[0]
    if shutil.which(exe) is None:
        raise BuildError(f"no C compiler found ({exe!r}); install gcc or clang, or set CC")
    return cc


def _key(*parts: str) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p.encode())
        h.update(b"\0")
    return h.hexdigest()


def _declarations(functions: Mapping[str, int]) -> str:
    """The prototypes of ``functions`` for cffi's ``cdef``."""
    return "\n".join(f"void {f}({', '.join(['const double *'] * (n - 1) + ['double *'])});"
                     for f, n in functions.items())


def _sources(root: Path, name: str, header: str, source: str) -> Path:
    """A fresh build folder under ``root`` holding the two C files."""
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=root, prefix="build-"))
    (tmp / f"{name}.h").write_text(header)
    (tmp / f"{name}.c").write_text(source)
    return tmp


def _compile(cmd: list[str], tmp: Path) -> None:
    """Run the compiler; on failure remove the build folder and raise with the compiler's output."""
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        shutil.rmtree(tmp, ignore_errors=True)
        raise BuildError(f"{' '.join(cmd)} failed: {proc.stderr.strip()[-2000:]}")


def _load_extension(modname: str, path: Path):
    """Import the extension module ``modname`` from ``path``."""
    spec = importlib.util.spec_from_file_location(modname, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _install(tmp: Path, built: Path, final: Path) -> None:
    final.parent.mkdir(parents=True, exist_ok=True)
    os.replace(built, final)  # atomic: concurrent builders of the same key each leave a whole file
    shutil.rmtree(tmp, ignore_errors=True)


def _build_ctypes(name: str, header: str, source: str, functions: Mapping[str, int], root: Path) -> Library:
    cc = _compiler()
    key = _key("ctypes", cc, " ".join(CFLAGS), header, source)
    final = root / key[:24] / f"lib{name}.so"
    if not final.exists():
        tmp = _sources(root, name, header, source)
        out = tmp / final.name
        _compile([*cc.split(), *CFLAGS, "-shared", "-o", str(out), str(tmp / f"{name}.c"), "-lm"], tmp)
        _install(tmp, out, final)
    lib = ctypes.CDLL(str(final))
    loaded = {}
    for f, n in functions.items():
        fn = getattr(lib, f)
        fn.argtypes = [ctypes.c_void_p] * n
        fn.restype = None
        loaded[f] = fn
    return Library(final, loaded, None, lib)


_LOADED: dict[str, object] = {}  # extension modules loaded in this process, by module name


def _build_cffi(name: str, header: str, source: str, functions: Mapping[str, int], root: Path) -> Library:
    import cffi

    cc = _compiler()
    abi = sysconfig.get_config_var("EXT_SUFFIX") or sys.implementation.cache_tag
    key = _key("cffi", cffi.__version__, cc, abi, " ".join(CFLAGS), header, source)
    modname = f"_jaxskid_{name}_{key[:16]}"
    final = root / key[:24] / f"{modname}{sysconfig.get_config_var('EXT_SUFFIX') or '.so'}"
    if modname not in _LOADED:
        if not final.exists():
            tmp = _sources(root, name, header, source)
            ffi = cffi.FFI()
            ffi.cdef(_declarations(functions))
            ffi.set_source(modname, f'#include "{name}.h"', sources=[str(tmp / f"{name}.c")],
                           include_dirs=[str(tmp)], extra_compile_args=list(CFLAGS), libraries=["m"])
            try:
                built = Path(ffi.compile(tmpdir=str(tmp), verbose=False))
            except Exception as exc:  # distutils/setuptools raise their own CompileError classes
                shutil.rmtree(tmp, ignore_errors=True)
                raise BuildError(f"building the cffi extension {modname} failed: {exc}") from exc
            _install(tmp, built, final)
        _LOADED[modname] = _load_extension(modname, final)
    module = _LOADED[modname]
    return Library(final, {f: getattr(module.lib, f) for f in functions}, module.ffi, module)


def _build_capi(name: str, header: str, source: str, methods: Sequence[Method], root: Path) -> Library:
    import numpy

    cc = _compiler()
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    includes = (sysconfig.get_paths()["include"], numpy.get_include())
    if not (Path(includes[0]) / "Python.h").exists():
        raise BuildError(f"the capi backend needs Python's headers (no Python.h in {includes[0]}); "
                         "use backend='cffi' or 'ctypes'")
    key = _key("capi", cc, suffix, numpy.__version__, " ".join(CFLAGS), *includes, header, source, repr(methods))
    modname = f"_jaxskid_{name}_{key[:16]}"
    final = root / key[:24] / f"{modname}{suffix}"
    if modname not in _LOADED:
        if not final.exists():
            tmp = _sources(root, name, header, source)
            (tmp / "module.c").write_text(extension_source(name, modname, methods))
            out = tmp / final.name
            _compile([*cc.split(), *CFLAGS, "-shared", *(f"-I{d}" for d in (*includes, tmp)), "-o", str(out),
                      str(tmp / "module.c"), str(tmp / f"{name}.c"), "-lm"], tmp)
            _install(tmp, out, final)
        _LOADED[modname] = _load_extension(modname, final)
    module = _LOADED[modname]
    return Library(final, {m.c_name: getattr(module, m.name) for m in methods}, None, module)
