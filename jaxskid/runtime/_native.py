"""The fast single-call path: the generated C, compiled on this machine and called from Python.

A jitted JAX function costs tens of microseconds of dispatch per call; for one state at a time that is
most of the time. :func:`compile_native` prints the requested quantities as C (the ``"c"`` target of
:mod:`jaxskid.codegen`), compiles them with the system C compiler and wraps them in a
:class:`NativeDynamics` whose methods take and return NumPy arrays::

    native = jaxskid.compile_native(robot, ["inverse_dynamics", "mass_matrix"])
    tau = native.inverse_dynamics(q, qd, qdd)           # numpy (n,), default parameters
    M = native.mass_matrix(q, params={"m1": 2.0, ...})  # (n, n)

Backends (one argument, ``backend``):

* ``"cffi"`` (the default when cffi is installed): cffi's API mode builds a CPython extension module
  around the C (needs the Python headers); arguments pass as ``ffi.from_buffer`` views, with no copy.
* ``"ctypes"``: a plain shared library (needs only a C compiler), called through ctypes with the
  argument types set once; inputs are copied into preallocated buffers under a lock.

The built library lives in ``<cache_dir>/native/<key>/``, keyed by a hash of the C source, the backend,
the compiler flags and the Python ABI, so it is built once per machine and reused.
"""

from __future__ import annotations

import ctypes
import hashlib
import importlib.util
import math
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import threading
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..equations._derive import Equations, derive, resolve
from .._errors import JaxskidError, RequestError, ShapeError
from ..lowering._jax import cache_dir as default_cache_dir
from ..model._robot import Robot
from ..codegen import Layout
from ..codegen._c import emit_c

CFLAGS = ("-O2", "-g0", "-std=c99", "-fPIC")
BACKENDS = ("cffi", "ctypes")


class BuildError(JaxskidError):
    """The generated C could not be compiled (no compiler, or the compiler failed)."""


def compile_native(
    model: Robot | Equations,
    quantities: Sequence[str] | str | None = None,
    *,
    backend: str | None = None,
    cache_dir: str | os.PathLike | None = None,
) -> "NativeDynamics":
    """Compile the requested quantities of ``model`` to native code for fast single calls.

    Args:
        model: a :class:`Robot` (its quantities are derived here) or already derived :class:`Equations`.
        quantities: names from :data:`jaxskid.QUANTITIES`; ``None`` for the defaults (for ``Equations``:
            every quantity they hold).
        backend: ``"cffi"`` or ``"ctypes"`` (see the module docstring); ``None`` picks cffi when it is
            installed.
        cache_dir: where built libraries are kept (default ``jaxskid.cache_dir() / "native"``).

    Raises:
        BuildError: no C compiler, or the build failed (the message ends with the compiler's output).
    """
    if backend is None:
        backend = "cffi" if importlib.util.find_spec("cffi") is not None else "ctypes"
    if backend not in BACKENDS:
        raise RequestError(f"unknown backend {backend!r}; expected one of {', '.join(BACKENDS)}")
    if isinstance(model, Equations):
        eqs = model
        names = tuple(eqs.quantities) if quantities is None else resolve(eqs.robot, quantities)
        missing = [n for n in names if n not in eqs.quantities]
        if missing:
            raise RequestError(f"{', '.join(missing)} not derived; derived: {', '.join(eqs.quantities)}")
    else:
        names = resolve(model, quantities)
        eqs = derive(model, names)
    layout = Layout(eqs, names)
    files = emit_c(layout)
    header, source = files[f"{layout.stem}.h"], files[f"{layout.stem}.c"]
    root = Path(cache_dir) if cache_dir is not None else default_cache_dir() / "native"
    build = _build_cffi if backend == "cffi" else _build_ctypes
    lib = build(layout, header, source, root)
    return NativeDynamics(layout, lib, backend, source)


# ---------------------------------------------------------------------------------------------- building
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


def _declarations(layout: Layout) -> str:
    s = layout.stem
    lines = []
    for k in layout.kernels:
        params = ", ".join([*(f"const double *{a}" for a in k.args), "const double *p", "double *out"])
        lines.append(f"void {s}_{k.name}({params});")
    return "\n".join(lines)


def _install(tmp: Path, built: Path, final: Path) -> None:
    final.parent.mkdir(parents=True, exist_ok=True)
    os.replace(built, final)  # atomic: concurrent builders of the same key each leave a whole file
    shutil.rmtree(tmp, ignore_errors=True)


def _build_ctypes(layout: Layout, header: str, source: str, root: Path):
    cc = _compiler()
    key = _key("ctypes", cc, " ".join(CFLAGS), header, source)
    final = root / key[:24] / f"lib{layout.stem}.so"
    if not final.exists():
        root.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(dir=root, prefix="build-"))
        (tmp / f"{layout.stem}.h").write_text(header)
        (tmp / f"{layout.stem}.c").write_text(source)
        out = tmp / final.name
        cmd = [*cc.split(), *CFLAGS, "-shared", "-o", str(out), str(tmp / f"{layout.stem}.c"), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            shutil.rmtree(tmp, ignore_errors=True)
            raise BuildError(f"{' '.join(cmd)} failed: {proc.stderr.strip()[-2000:]}")
        _install(tmp, out, final)
    lib = ctypes.CDLL(str(final))
    functions = {}
    for k in layout.kernels:
        fn = getattr(lib, f"{layout.stem}_{k.name}")
        fn.argtypes = [ctypes.c_void_p] * (len(k.args) + 2)
        fn.restype = None
        functions[k.name] = fn
    return _Library(final, functions, None, lib)


_LOADED: dict[str, object] = {}


def _build_cffi(layout: Layout, header: str, source: str, root: Path):
    import cffi

    cc = _compiler()
    abi = sysconfig.get_config_var("EXT_SUFFIX") or sys.implementation.cache_tag
    key = _key("cffi", cffi.__version__, cc, abi, " ".join(CFLAGS), header, source)
    modname = f"_jaxskid_{layout.stem}_{key[:16]}"
    final = root / key[:24] / f"{modname}{sysconfig.get_config_var('EXT_SUFFIX') or '.so'}"
    if modname in _LOADED:
        module = _LOADED[modname]
    else:
        if not final.exists():
            root.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(dir=root, prefix="build-"))
            (tmp / f"{layout.stem}.h").write_text(header)
            (tmp / f"{layout.stem}.c").write_text(source)
            ffi = cffi.FFI()
            ffi.cdef(_declarations(layout))
            ffi.set_source(modname, f'#include "{layout.stem}.h"', sources=[str(tmp / f"{layout.stem}.c")],
                           include_dirs=[str(tmp)], extra_compile_args=list(CFLAGS), libraries=["m"])
            try:
                built = Path(ffi.compile(tmpdir=str(tmp), verbose=False))
            except Exception as exc:  # distutils/setuptools raise their own CompileError classes
                shutil.rmtree(tmp, ignore_errors=True)
                raise BuildError(f"building the cffi extension {modname} failed: {exc}") from exc
            _install(tmp, built, final)
        spec = importlib.util.spec_from_file_location(modname, final)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _LOADED[modname] = module
    functions = {k.name: getattr(module.lib, f"{layout.stem}_{k.name}") for k in layout.kernels}
    return _Library(final, functions, module.ffi, module)


class _Library:
    def __init__(self, path: Path, functions: dict, ffi, handle):
        self.path = path
        self.functions = functions
        self.ffi = ffi
        self.handle = handle  # keeps the shared object loaded


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


class NativeDynamics:
    """Compiled quantities of one robot for single states. Build it with :func:`jaxskid.compile_native`.

    Each quantity is a method ``name(*state, params=None) -> numpy array`` for ONE state: every state
    argument has shape ``(n,)`` (``wrench``: ``(n_ee, 6)``); ``params`` is ``None`` for the defaults, a dict
    name -> value or a vector in the order of :attr:`parameters`. ``forward_kinematics`` returns a dict
    frame name -> 4x4 pose, as :class:`jaxskid.Dynamics` does. For batches use :func:`jaxskid.lower`.
    """

    def __init__(self, layout: Layout, library: _Library, backend: str, source: str):
        robot = layout.robot
        self.robot_name: str = robot.name
        self.joint_names: tuple[str, ...] = tuple(robot.joint_names)
        self.frame_names: tuple[str, ...] = tuple(robot.frame_names)
        self.end_effectors: tuple[str, ...] = tuple(robot.end_effectors)
        self.parameters: tuple[str, ...] = tuple(layout.parameters)
        self.defaults: dict[str, float] = {k: v for k, v in zip(self.parameters, layout.defaults) if not math.isnan(v)}
        self.n_dof: int = robot.n_dof
        self.backend = backend
        self.path: Path = library.path
        self.source = source
        self._library = library
        self._shapes = {k.name: ({a: layout.arg_shape(a) for a in k.args}, k.shape) for k in layout.kernels}
        self._default_vector = np.array(layout.defaults, dtype=np.float64)
        self._default_vector.flags.writeable = False
        for k in layout.kernels:
            fn = self._make(k.name, k.args, k.shape, library)
            fn.__name__ = k.name
            fn.__doc__ = (f"{k.name}({', '.join(k.args)}, params=None) -> {tuple(k.shape)}\n\n"
                          f"{k.equation}: {k.doc}")
            if k.name == "forward_kinematics":
                fn = self._frames(fn)
            setattr(self, k.name, fn)

    @property
    def quantities(self) -> tuple[str, ...]:
        return tuple(self._shapes)

    def signature(self, name: str) -> tuple[tuple[str, ...], tuple[int, ...]]:
        """(argument names, output shape) of a quantity."""
        args, shape = self._shapes[name]
        return tuple(args), tuple(shape)

    def default_params(self) -> dict[str, float]:
        return dict(self.defaults)

    def param_vector(self, params=None) -> np.ndarray:
        """Parameters as a contiguous float64 vector in the order of :attr:`parameters`."""
        if params is None:
            missing = [k for k in self.parameters if k not in self.defaults]
            if missing:
                raise RequestError(f"parameter(s) {', '.join(missing)} have no default value; pass params")
            return self._default_vector
        if isinstance(params, Mapping):
            missing = [k for k in self.parameters if k not in params]
            if missing:
                raise RequestError(f"params is missing {', '.join(missing)} (expected the names in .parameters)")
            return np.array([float(params[k]) for k in self.parameters], dtype=np.float64)
        return _arr(params, (len(self.parameters),), "params")

    def _make(self, name, args, shape, library):
        arg_shapes = {a: tuple(self._shapes[name][0][a]) for a in args}
        # With every default known, params=None passes the prebuilt default vector without a call.
        has_defaults = len(self.defaults) == len(self.parameters)
        ns = {"_f8": np.dtype(np.float64), "_arr": _arr, "_empty": np.empty, "_fn": library.functions[name],
              "_pvec": self.param_vector}
        if library.ffi is not None:
            ffi = library.ffi
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

    def _frames(self, fn):
        frames = self.frame_names

        def forward_kinematics(q, params=None):
            poses = fn(q, params)
            return {f: poses[k] for k, f in enumerate(frames)}

        forward_kinematics.__name__ = fn.__name__
        forward_kinematics.__doc__ = fn.__doc__ + "\n\nReturns a dict frame name -> 4x4 pose."
        return forward_kinematics

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        from ..equations._derive import QUANTITIES

        if name in QUANTITIES:
            raise RequestError(
                f"{name!r} was not compiled; compiled: {', '.join(self.quantities)}. "
                f"Ask for it with jaxskid.compile_native(robot, [..., {name!r}])"
            )
        raise AttributeError(f"'NativeDynamics' object has no attribute {name!r}")

    def __repr__(self) -> str:
        return (f"NativeDynamics({self.robot_name!r}, n_dof={self.n_dof}, quantities={list(self.quantities)}, "
                f"backend={self.backend!r})")
