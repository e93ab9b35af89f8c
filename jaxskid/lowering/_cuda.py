"""Generated CUDA for a GPU: the matrix-valued quantities as kernels of one state per thread, compiled at run
time with NVRTC, and the XLA FFI handler that launches them.

On a GPU, XLA compiles a generated JAX program of tens of thousands of scalar operations slowly (minutes for
the G1's Coriolis matrix) and runs a matrix's assembly as select chains. The program the CPU kernels are
printed from (:class:`jaxskid._generated.VectorKernel`) is straight-line arithmetic; printed once more over
doubles, it is a CUDA kernel in which each thread computes one state and writes its entries of the result:

* :func:`kernel_source` writes that kernel (the template ``c/cuda_kernel.cu``); the same text compiles as
  C on the host (:func:`host_library`), which is how the tests check its arithmetic where no GPU is;
* :func:`compile_kernel` compiles it with NVRTC (``libnvrtc``, from the ``nvidia-cuda-nvrtc`` wheel that
  JAX's CUDA plugin brings, or a CUDA toolkit) to a cubin for the device's architecture, or to PTX, and
  keeps the result on disk, keyed by the source, the options and NVRTC's version;
* :func:`handler_library` builds the one handler all kernels share (``c/cuda_handler.c``): it reads the
  kernel's number from the call's attributes, loads the module on the call's device once and launches it
  on XLA's stream, with the CUDA driver API opened at run time (nothing links against CUDA at build time).

Inputs and results are float32 or float64 (one kernel per type, compiled when first used); the arithmetic
is in double.
"""

from __future__ import annotations

import ctypes
import glob
import hashlib
import os
import sys
import threading
from pathlib import Path

import numpy as np

from .._generated import NativeSource, VectorKernel, by_entry, constant_input
from ._ffi import Piece, _chunked
from ._native import CFLAGS, BuildError, _compile, _compiler, _install, _key, _sources
from ._templates import fill, template

THREADS = 64
"""Threads per block (``JAXSKID_CUDA_THREADS`` sets another). One state per thread leaves few threads per
multiprocessor at the batches users run (16,384 states on an H200's 132 multiprocessors: 124 each), so small
blocks spread them over every multiprocessor: the G1's M and C ran faster in blocks of 64 than of 128, and
slowest in blocks of 256, which left half the multiprocessors idle (``benchmarks/gpu.py``'s ``variants``)."""


def threads() -> int:
    """Threads per block: ``JAXSKID_CUDA_THREADS`` or :data:`THREADS`."""
    return int(os.environ.get("JAXSKID_CUDA_THREADS") or THREADS)


LONG = 4096
"""A kernel of more statements is split into device functions of :data:`CHUNK` statements (not inlined), which
pass the values that cross a boundary through a per-thread workspace: ptxas's register allocation, like GCC's,
takes time superlinear in a function's length (:func:`jaxskid.lowering._ffi._chunked`, as for the CPU). On an
H200 the G1's Coriolis matrix (6,900 statements) built several times faster in pieces of 512 and ran faster
than as one function or in pieces of 2,048; its mass matrix (2,150) ran faster as one function
(``benchmarks/gpu.py``'s ``variants``). ``JAXSKID_CUDA_LONG`` sets another length."""

CHUNK = 512
"""Statements per piece of a long kernel (``JAXSKID_CUDA_CHUNK`` sets another)."""

TRIG = "fused"
"""How a kernel computes sine and cosine: ``"fused"``, multiply-adds without a branch (``c/cuda_trig.h``), or
``"library"``, CUDA's ``sin`` and ``cos`` (``JAXSKID_CUDA_TRIG`` sets the other for the quantity kernels; the
rollout kernels always use ``"fused"``). The library's functions branch to a slow reduction for large angles,
which keeps a thread's calls from interleaving; on an H200 the G1's tau ran 1.7x and its Coriolis matrix 1.4x
faster with the multiply-adds, its mass matrix about as fast (``benchmarks/gpu.py``'s ``variants``)."""

_IO = {"float32": "float", "float64": "double"}


def trig_source(kind: str | None = None) -> str:
    """The definitions of ``Dsin`` and ``Dcos`` in a kernel: ``kind`` (:data:`TRIG`'s choices), by default
    ``JAXSKID_CUDA_TRIG`` or :data:`TRIG`."""
    kind = kind or os.environ.get("JAXSKID_CUDA_TRIG") or TRIG
    if kind == "library":
        return "#define Dsin(x) sin(x)\n#define Dcos(x) cos(x)"
    if kind == "fused":
        return template("cuda_trig.h").rstrip("\n")
    raise ValueError(f"JAXSKID_CUDA_TRIG: expected 'library' or 'fused', got {kind!r}")


def split_sizes() -> tuple[int, int]:
    """``(long, chunk)``: :data:`LONG` and :data:`CHUNK`, or ``JAXSKID_CUDA_LONG`` and ``JAXSKID_CUDA_CHUNK``."""
    return tuple(int(os.environ.get(f"JAXSKID_CUDA_{k}") or d) for k, d in (("LONG", LONG), ("CHUNK", CHUNK)))


CONSTANT = "jaxskid_p"
"""The array in a kernel's constant memory that holds the parameters when every state shares them."""

ORDER = "thread"
"""The order of a kernel's statements: ``"thread"`` (:func:`thread_order`, with ``__restrict__`` pointers) or
``"program"``, the program's own (``JAXSKID_CUDA_ORDER`` sets the other)."""


def ordered(kernel: VectorKernel) -> tuple[VectorKernel, bool]:
    """``kernel`` in the order ``JAXSKID_CUDA_ORDER`` or :data:`ORDER` names, and whether its pointers are
    ``__restrict__`` (as :func:`jaxskid.lowering._ffi._chunked` takes it)."""
    kind = os.environ.get("JAXSKID_CUDA_ORDER") or ORDER
    if kind not in ("thread", "program"):
        raise ValueError(f"JAXSKID_CUDA_ORDER: expected 'thread' or 'program', got {kind!r}")
    return (thread_order(kernel), True) if kind == "thread" else (kernel, False)


def thread_order(kernel: VectorKernel) -> VectorKernel:
    """``kernel`` with its statements in an order for one GPU thread: each input read just before the first
    statement that needs it, each output written just after the last value it reads. The program's own order
    reads every input first and writes every result last, which keeps them all live at once: in it the floating
    G1's M spills 3.4 KB per thread to local memory (ptxas ``-v``), in this order 0.5 KB."""
    statements = kernel.statements
    pending = {s.name: s for s in statements if s.kind == "input"}
    position = {s.name: k for k, s in enumerate(statements) if s.kind == "define"}
    after: dict[int, list] = {}
    for s in statements:
        if s.kind == "output":
            after.setdefault(max((position[v] for v in s.reads if v in position), default=-1), []).append(s)
    order: list = []

    def emit(s) -> None:
        order.extend(pending.pop(v) for v in s.reads if v in pending)
        order.append(s)

    for s in after.get(-1, []):
        emit(s)
    for k, s in enumerate(statements):
        if s.kind in ("input", "output"):
            continue
        emit(s)
        for out in after.get(k, []):
            emit(out)
    return kernel._replace(statements=tuple(order + list(pending.values())))


def constant_parameters(kernel: VectorKernel) -> VectorKernel:
    """``kernel`` reading its parameters (its last argument) from :data:`CONSTANT`, in constant memory: a value
    every thread of a warp reads there is an operand of the instruction that uses it, and takes no register."""
    prefix = f"{kernel.args[-1]}["
    return kernel._replace(statements=tuple(
        s._replace(value=CONSTANT + s.value[len(prefix) - 1:]) if s.kind == "input" and s.value.startswith(prefix)
        else s for s in kernel.statements))


def constants(n_params: int | None) -> str:
    """The declaration of :data:`CONSTANT` for ``n_params`` parameters (none for None): constant memory on the
    device, an exported array on the host (which :func:`run_on_host` fills)."""
    if n_params is None:
        return ""
    size = max(n_params, 1)
    return (f"#ifdef __CUDACC_RTC__\n__constant__ io_t {CONSTANT}[{size}];\n#else\nio_t {CONSTANT}[{size}];\n"
            "#endif")


def kernel_source(native: NativeSource, name: str, io: str = "float64", shared: bool = True) -> str | None:
    """The CUDA source of the quantity ``name`` of ``native`` for inputs and result of dtype ``io``
    (``"float32"`` or ``"float64"``), exporting ``jaxskid_kernel(jaxskid_job)``; None where the quantity has
    no kernel (no vector form); a result of many entries by entry (:func:`jaxskid._generated.by_entry`), which
    the caller transposes. ``shared``: every state of a call has the same parameters, which the kernel
    reads from constant memory (the handler copies them there before it runs), where they fit
    (:func:`jaxskid._generated.constant_input`); otherwise from the parameters' input."""
    kernel = native.vectors.get(name)
    entry = next((k for k in native.kernels if k[0] == name), None)
    if kernel is None or entry is None:
        return None
    _, sizes, _, n_out, _ = entry
    constant = sizes[-1] if constant_input(len(sizes) - 1, sizes[-1], shared) >= 0 else None
    kernel, restrict = ordered(kernel if constant is None else constant_parameters(kernel))
    long, chunk = split_sizes()
    columns = by_entry(n_out)
    functions = _chunked("body", kernel, "D", set(kernel.zeros), io="io_t", long=long, chunk_size=chunk, huge=None,
                         restrict=restrict, stride=columns)
    call = ", ".join(f"(const io_t *)j->in[{i}] + off[{i}]" for i in range(len(sizes)))
    out = "(io_t *)j->out + s, j->batch" if columns else f"(io_t *)j->out + s * {n_out}LL"
    return "".join([f"#define JAXSKID_IO {_IO[io]}\n",
                    fill(template("cuda_kernel.cu"), JOB=template("cuda_job.h"), TRIG=trig_source(), STEM=native.stem,
                         NAME=name, CONSTANTS=constants(constant),
                         FUNCTIONS="".join(f.text() if isinstance(f, Piece) else f for f in functions),
                         N_IN=len(sizes), CALL=call, OUT=out, THREADS=threads())])


# ---------------------------------------------------------------------------------------------- NVRTC
class NvrtcError(BuildError):
    """NVRTC is missing or failed to compile a kernel."""


_NVRTC: list = []
_NVRTC_LOCK = threading.Lock()


def _nvrtc_candidates() -> list[str]:
    """Where ``libnvrtc`` may be: ``JAXSKID_NVRTC``, the ``nvidia`` wheels (CUDA 13's ``nvidia/cu13/lib``,
    CUDA 12's ``nvidia/cuda_nvrtc/lib``), a CUDA toolkit, then the loader's own search."""
    found = [os.environ["JAXSKID_NVRTC"]] if os.environ.get("JAXSKID_NVRTC") else []
    roots = [Path(p) for p in sys.path if p] + [Path("/usr/local/cuda/lib64")]
    for root in roots:
        for pattern in ("nvidia/cu*/lib/libnvrtc.so*", "nvidia/cuda_nvrtc/lib/libnvrtc.so*", "libnvrtc.so*"):
            found += sorted(p for p in glob.glob(str(root / pattern)) if "builtins" not in p and ".alt." not in p)
    return found + ["libnvrtc.so.13", "libnvrtc.so.12", "libnvrtc.so"]


def nvrtc() -> ctypes.CDLL:
    """The NVRTC library, loaded once.

    Raises:
        NvrtcError: none found (install ``nvidia-cuda-nvrtc``, or set ``JAXSKID_NVRTC`` to its path).
    """
    with _NVRTC_LOCK:
        if not _NVRTC:
            for path in _nvrtc_candidates():
                try:
                    lib = ctypes.CDLL(path)
                except OSError:
                    continue
                lib.nvrtcGetErrorString.restype = ctypes.c_char_p
                _NVRTC.append(lib)
                break
            else:
                raise NvrtcError("no NVRTC library found (libnvrtc.so); install the nvidia-cuda-nvrtc wheel "
                                 "(JAX's CUDA plugin brings it) or set JAXSKID_NVRTC to its path")
        return _NVRTC[0]


def nvrtc_version() -> str:
    major, minor = ctypes.c_int(), ctypes.c_int()
    nvrtc().nvrtcVersion(ctypes.byref(major), ctypes.byref(minor))
    return f"{major.value}.{minor.value}"


def _check(lib, status: int, what: str, log: str = "") -> None:
    if status != 0:
        raise NvrtcError(f"NVRTC {what} failed: {lib.nvrtcGetErrorString(status).decode()}"
                         + (f"\n{log[-3000:]}" if log else ""))


def compile_kernel(source: str, arch: str = "sm_90", root: Path | None = None, level: str = "1") -> bytes:
    """The compiled ``source``: a cubin for a real architecture (``"sm_90"``), or PTX for a virtual one
    (``"compute_90"``: what the tests check where no GPU is), read from ``root`` when this source, target and
    NVRTC were compiled before. ``level`` is ptxas's optimisation level, unless ``JAXSKID_PTXAS_O`` sets another
    (1 for the quantities: on an H200 neither level ran the G1's M and C faster in both of two runs, and ``-O1``
    built the Coriolis matrix in less time; ``benchmarks/gpu.py``'s ``variants``).

    Raises:
        NvrtcError: no NVRTC, or the compiler rejected the source (the message ends with its log).
    """
    level = os.environ.get("JAXSKID_PTXAS_O") or level
    options = [f"--gpu-architecture={arch}", "--std=c++17", "-default-device", "-Xptxas", f"-O{level}"]
    key = hashlib.sha256("\0".join([source, *options, nvrtc_version()]).encode()).hexdigest()[:32]
    cubin = arch.startswith("sm_")
    path = root / f"{key}.{'cubin' if cubin else 'ptx'}" if root is not None else None
    if path is not None and path.exists():
        return path.read_bytes()
    image = _nvrtc_compile(source, options)
    if path is not None:
        root.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_bytes(image)
        os.replace(tmp, path)
    return image


def _nvrtc_compile(source: str, options: list[str]) -> bytes:
    lib = nvrtc()
    prog = ctypes.c_void_p()
    _check(lib, lib.nvrtcCreateProgram(ctypes.byref(prog), source.encode(), b"jaxskid.cu", 0, None, None), "setup")
    try:
        opts = (ctypes.c_char_p * len(options))(*(o.encode() for o in options))
        status = lib.nvrtcCompileProgram(prog, len(options), opts)
        size = ctypes.c_size_t()
        lib.nvrtcGetProgramLogSize(prog, ctypes.byref(size))
        log = ctypes.create_string_buffer(size.value)
        lib.nvrtcGetProgramLog(prog, log)
        _check(lib, status, "compilation", log.value.decode(errors="replace"))
        cubin = options[0].startswith("--gpu-architecture=sm_")
        get_size, get = (lib.nvrtcGetCUBINSize, lib.nvrtcGetCUBIN) if cubin else (lib.nvrtcGetPTXSize, lib.nvrtcGetPTX)
        _check(lib, get_size(prog, ctypes.byref(size)), "output size")
        image = ctypes.create_string_buffer(size.value)
        _check(lib, get(prog, image), "output")
        return image.raw
    finally:
        lib.nvrtcDestroyProgram(ctypes.byref(prog))


# ---------------------------------------------------------------------------------------------- builds
def _shared_library(name: str, source: str, root: Path, flags: tuple[str, ...] = (), libs: tuple[str, ...] = ()) -> Path:
    """``source`` built as the shared library ``lib<name>.so`` under ``root`` (keyed by everything that goes
    in; built once per machine)."""
    cc = _compiler()
    key = _key("cuda", cc, " ".join(CFLAGS), *flags, *libs, source)
    final = root / key[:24] / f"lib{name}.so"
    if not final.exists():
        tmp = _sources(root, name, "", source)
        out = tmp / final.name
        _compile([*cc.split(), *CFLAGS, *flags, "-shared", "-o", str(out), str(tmp / f"{name}.c"), *libs], tmp)
        _install(tmp, out, final)
    return final


def handler_library(root: Path) -> Path:
    """The shared library of the handler ``jaxskid_cuda_quantity`` and of ``jaxskid_cuda_register``, built
    with the system C compiler once per machine under ``root``.

    Raises:
        BuildError: no C compiler, no XLA FFI header, or the build failed.
    """
    from ._ffi import include_dir

    return _shared_library("jaxskid_cuda", fill(template("cuda_handler.c"), JOB=template("cuda_job.h"),
                                                METADATA=template("ffi_metadata.h")), root, (f"-I{include_dir()}",),
                           ("-ldl", "-lpthread"))


def host_library(source: str, root: Path) -> ctypes.CDLL:
    """A kernel's source built as C for the host: ``jaxskid_host(const jaxskid_job *)`` loops over the states,
    with the same arithmetic and indexing as the GPU's threads (at ``-O0``: a check, built fast)."""
    return ctypes.CDLL(str(_shared_library("jaxskid_cuda_host", source, root, ("-O0", "-fno-math-errno"), ("-lm",))))


class HostJob(ctypes.Structure):
    """``jaxskid_job`` of ``c/cuda_kernel.cu`` and ``c/cuda_handler.c``."""

    _fields_ = [("inputs", ctypes.c_void_p * 8), ("stride", (ctypes.c_longlong * 6) * 8),
                ("dims", ctypes.c_longlong * 6), ("nb", ctypes.c_longlong), ("batch", ctypes.c_longlong),
                ("out", ctypes.c_void_p)]


def run_on_host(lib: ctypes.CDLL, inputs, cores, out, out_rank: int, constant: int = -1,
                columns: bool = False) -> None:
    """Run a :func:`host_library` kernel on contiguous NumPy arrays as the handler runs it on a GPU: ``out``'s
    leading axes (all but its last ``out_rank``) are the batch, input i's last ``cores[i]`` axes hold one
    state's entries and its leading axes broadcast against the batch (right-aligned; an axis of 1, or a missing
    one, is shared). ``constant``: the input copied into the kernel's :data:`CONSTANT` first, as the handler
    copies it into constant memory (-1: none). ``columns``: the kernel writes by entry (``out``'s shape as for
    rows: it is written through a buffer of the entries by state, then transposed). Zeroes ``out``, then
    writes it."""
    if constant >= 0:
        values = np.ascontiguousarray(inputs[constant]).ravel()
        ctypes.memmove(ctypes.addressof(ctypes.c_char.in_dll(lib, CONSTANT)), values.ctypes.data, values.nbytes)
    job, nb = HostJob(), out.ndim - out_rank
    batch = out.shape[:nb]
    buffer = np.zeros((int(np.prod(out.shape[nb:], dtype=np.int64)), *batch), out.dtype) if columns else out
    buffer[...] = 0
    for d in range(nb):
        job.dims[d] = batch[d]
    for i, (x, core) in enumerate(zip(inputs, cores)):
        job.inputs[i] = x.ctypes.data
        lead, step = x.shape[:x.ndim - core], int(np.prod(x.shape[x.ndim - core:], dtype=np.int64))
        for d in range(nb - 1, -1, -1):
            k = d - (nb - len(lead))
            extent = lead[k] if k >= 0 else 1
            job.stride[i][d] = 0 if extent == 1 else step
            step *= extent
    job.nb, job.batch, job.out = nb, int(np.prod(batch, dtype=np.int64)), buffer.ctypes.data
    lib.jaxskid_host(ctypes.byref(job))
    if columns:
        out[...] = np.moveaxis(buffer, 0, -1).reshape(out.shape)
