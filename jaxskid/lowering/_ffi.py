"""Generated C as kernels of XLA programs: the matrix-valued quantities and the backward step of forward
dynamics, built with handlers of XLA's foreign function interface (the C API of ``xla/ffi/api/c_api.h``,
shipped with jaxlib).

On CPU, XLA compiles a generated program of thousands of scalar operations into many small kernels, or,
for a result of n^2 or n * 10 n entries, into select chains whose work grows with the number of entries
(the G1's regressor, 29 x 290, far slower than its arithmetic; ``benchmarks/scaling.py`` with
``JAXSKID_NATIVE=0``). The same arithmetic as one C function is one kernel.
:func:`glue_source` writes, for the generated C of :func:`jaxskid.codegen._c.native_sources`:

* ``jaxskid_<quantity>(*state, p) -> out`` per matrix-valued quantity, four states at a time in vectors
  of doubles (GCC/Clang vector extensions; AVX2 where the CPU has it), with sine and cosine as vector
  polynomials; a batch's leading axes broadcast (an input shared by all states is read once);
* ``jaxskid_fd_vjp(q, qd, qdd, g, p) -> [lambda, -vjp]``, lambda = M(q)^-1 g and
  vjp = lambda^T d ID(q, qd, qdd, p)/d(q, qd, p), from ``mass_matrix``, ``inverse_dynamics_vjp`` and an
  L D L^T solve (:func:`jaxskid.runtime._ldl.ldl_solve`, the same factorisation);
* ``jaxskid_rk4_vjp``, the backward pass of a Runge-Kutta step built on it (:mod:`._ffi_rk4`);
* ``jaxskid_kkt_vjp``, the backward step of constrained forward dynamics, where the library has the
  constraint quantities' pullbacks (:mod:`._ffi_kkt`).

The handlers' C is in the templates of ``jaxskid/lowering/c/`` (:mod:`._templates`); the kernels over
vectors of states come printed from the program representation, as statements
(:class:`jaxskid._generated.VectorKernel`). Long functions are split into pieces (:func:`_chunked`): GCC's
register allocation is quadratic in a function's length. Handlers take float32 or float64 and compute in
double. Nothing here knows SymPy: a build takes the C of a :class:`jaxskid._generated.NativeSource`.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

from .._generated import GPU_ONLY, KKT_QUANTITIES, NativeSource, Statement, VectorKernel
from ._ffi_batch import BACKWARD_CHUNK, GENERIC, POOL, QUANTITY
from ._ffi_kkt import KKT_BACKWARD
from ._ffi_rk4 import RK4_BACKWARD
from ._templates import fill, template

FFI_CFLAGS = ("-fno-math-errno",)
"""Added to :data:`~jaxskid.lowering._native.CFLAGS`: ``sin`` and ``cos`` without ``errno`` are pure, so the
compiler computes each joint's once (the generated vector-Jacobian product repeats them)."""

TARGET = "jaxskid_fd_vjp"
"""The exported handler of a library built by :func:`jaxskid.lowering._ffi_build.ffi_library`."""

_PRELUDE = fill(template("ffi_prelude.c"), METADATA=template("ffi_metadata.h"))
"""What every library's handlers share: the includes, the sizes of the generated C, reading and writing
float32 or float64 buffers, and the handlers' answer to XLA's metadata query."""

_TRIG = template("ffi_trig.h")
"""Lane-wise sine, cosine and sign of a vector type ``@V@`` (with ``@V@LIFT`` and the integer vector ``@V@I``): the
quantity kernels' (``V``) and the backward step's (``T``; with libm per lane it spent about a third of its
time in ``sin`` and ``cos``)."""

_BACKWARD = fill(template("ffi_backward.c"), FD_BACKWARD=template("fd_backward.h"), TRIG_T=fill(_TRIG, V="T"),
                 BACKWARD_CHUNK=BACKWARD_CHUNK)
"""The backward step of forward dynamics, ``jaxskid_fd_vjp``, with ``@LANE_FUNCTIONS@`` for the vector forms
of the mass matrix and the inverse dynamics' vector-Jacobian product."""

_GENERIC = fill(GENERIC, TRIG_V=fill(_TRIG, V="V"))





LANES = 4
"""States computed at once by the kernel, in vectors of doubles (AVX2 registers where the machine has them)."""

def lane_functions(native: NativeSource, names: tuple[str, ...], vec: str = "T",
                   drop_zeros: bool = False) -> list[str | Piece] | None:
    """The functions ``<stem>_<name>_<vec>`` of the quantities ``names`` over vectors of ``LANES`` states, of
    the vector type ``vec`` (their :class:`~jaxskid._generated.VectorKernel`, printed from the generated
    program by :func:`jaxskid.codegen._c.vector_kernel`, split by :func:`_chunked`). ``drop_zeros``: the
    assignments of the outputs that are always zero are left out (:func:`_scattered`). The C, as text and
    the :class:`Piece` objects of long kernels; None when one of them has no vector form (the scalar kernel
    or the JAX function serves)."""
    out: list[str | Piece] = []
    for k, name in enumerate(names):
        kernel = native.vectors.get(name)
        if kernel is None:
            return None
        out += ["\n"] * (k > 0)
        out += _chunked(f"{native.stem}_{name}_{vec}", kernel, vec, set(kernel.zeros) if drop_zeros else set())
    return out


class Piece(NamedTuple):
    """A piece of a long kernel (:func:`_chunked`), ``static __attribute__((noinline)) void name(params)``
    with its ``body`` (braces included); a split build (:func:`jaxskid.lowering._ffi_build.split`) defines it
    in one translation unit and declares it in the others."""

    name: str
    params: str
    body: str

    def text(self) -> str:
        return f"static __attribute__((noinline)) void {self.name}({self.params})\n{self.body}"


def _line(s: Statement, vec: str, stride: bool = False) -> str:
    """One statement of a vector kernel as C; ``stride``: output ``k`` is ``out[k * ostride]``."""
    if s.kind == "unused":
        return f"    (void){s.name};"
    if s.kind == "output":
        return f"    out[{s.name}{'LL * ostride' if stride else ''}] = {fill(s.value, V=vec)};"
    return f"    const {vec} {s.name} = {fill(s.value, V=vec)};"


CHUNK = 256
"""Statements per function of a long generated body (:func:`_chunked`)."""

LONG = 1024
"""Bodies up to this many statements stay one function (split, the Panda's regressor ran slower)."""

HUGE = 5000
"""Bodies of more statements are compiled at GCC's ``-Og`` (``c/og_begin.h``; the rest of the library at ``-O2``).
GCC takes about half as long on them, and they run as fast (the G1's Coriolis matrix, 6,900 statements, and its
regressor, 11,000, measured with both libraries in one process, alternated), which shortens the cold lowering of
such a quantity. Shorter bodies run slower at ``-Og`` (the G1's and the Panda's mass matrices), and their build is
short anyway."""


def _chunked(name: str, kernel: VectorKernel, vec: str, zeros: set[int] = frozenset(), io: str | None = None,
             long: int | None = None, chunk_size: int | None = None, huge: int | None = HUGE,
             restrict: bool = False, stride: bool = False) -> list[str | Piece]:
    """The function ``name`` of ``kernel``, split into functions of ``chunk_size`` statements (:data:`CHUNK`)
    that pass the values later pieces read through a workspace, where it has more than ``long``; the outputs
    ``zeros`` are not assigned. GCC's register allocator takes time quadratic in a function's length (the G1's
    Coriolis matrix, 4,300 statements: 2.7 minutes at ``-O1``); pieces of a few hundred statements compile in
    linear time, and only the values that cross a boundary go to memory. ``io``: the type the inputs and the
    output point to (``vec`` where None); ``huge``: the length from which GCC builds the pieces at ``-Og``
    (None: never). Left out, ``long`` and ``chunk_size`` are :data:`LONG` and :data:`CHUNK` as they are when
    called. ``restrict``: the pointers are ``__restrict__`` (none aliases another), and a piece reads each value
    of an earlier piece just before its first statement that needs it, not at its top (a GPU thread's registers:
    :func:`jaxskid.lowering._cuda.thread_order`). ``stride``: the function takes ``ostride`` after ``out`` and
    writes output ``k`` to ``out[k * ostride]`` (a GPU kernel's results by entry:
    :func:`jaxskid.lowering._cuda.kernel_source`)."""
    long, chunk_size = LONG if long is None else long, CHUNK if chunk_size is None else chunk_size
    ptr, star = io or vec, " *__restrict__ " if restrict else " *"
    params = ", ".join([*(f"const {ptr}{star}{a}" for a in kernel.args), f"{ptr}{star}out",
                        *(["const long long ostride"] if stride else [])])
    statements = kernel.statements
    kept = [s.kind != "output" or int(s.name) not in zeros for s in statements]
    if len(statements) <= long:
        body = "".join(_line(s, vec, stride) + "\n" for s, keep in zip(statements, kept) if keep)
        return [f"static void {name}({params})\n{{\n{body}}}\n"]
    defined: dict[str, int] = {}  # variable -> the chunk defining it
    inputs: dict[str, str] = {}  # variable -> its definition, for the reads of an input entry (read again)
    for k, s in enumerate(statements):
        if s.kind in ("input", "define"):
            defined[s.name] = k // chunk_size
            if s.kind == "input":
                inputs[s.name] = _line(s, vec)
    slots: dict[str, int] = {}
    for k, s in enumerate(statements):
        for v in s.reads:
            if defined[v] < k // chunk_size and v not in slots and v not in inputs:
                slots[v] = len(slots)
    args = ", ".join([*kernel.args, "out", *(["ostride"] if stride else [])])
    pieces, calls = [], []
    for c in range(0, len(statements), chunk_size):
        chunk = range(c, min(c + chunk_size, len(statements)))
        # inputs (no slot) by name: an order that a set's (which varies with each process's string hashes) would
        # give makes a new source, and a new build, in every process
        needed = sorted({v for k in chunk for v in statements[k].reads if defined[v] < c // chunk_size},
                        key=lambda v: (slots.get(v, -1), v))
        reads = {v: inputs[v] if v in inputs else f"    const {vec} {v} = w[{slots[v]}];" for v in needed}
        text = [] if restrict else list(reads.values())
        for k in chunk:
            s = statements[k]
            if restrict:
                text += [reads.pop(v) for v in s.reads if v in reads]
            if kept[k]:
                text.append(_line(s, vec, stride))
            if s.kind == "define" and s.name in slots:
                text.append(f"    w[{slots[s.name]}] = {s.name};")
        piece = f"{name}_{c // chunk_size}"
        pieces.append(Piece(piece, f"{params}, {vec} *w", "{\n" + "\n".join(text) + "\n}\n"))
        calls.append(f"    {piece}({args}, w);")
    workspace = f"    {vec} w[{max(len(slots), 1)}];"
    if huge is not None and len(statements) > huge:
        pieces = [template("og_begin.h").rstrip("\n"), *pieces, template("og_end.h").rstrip("\n")]
    out: list[str | Piece] = []
    for k, piece in enumerate(pieces):
        out += ["\n"] * (k > 0) + [piece]
    return out + [f"\nstatic void {name}({params})\n{{\n{workspace}\n" + "\n".join(calls) + "\n}\n"]


def _vector_flags() -> tuple[str, ...]:
    """``-mavx2`` where this machine's CPU has AVX2 (the library is built for the machine it runs on, and
    the flags are part of its key), otherwise none."""
    try:
        return ("-mavx2",) if " avx2" in Path("/proc/cpuinfo").read_text() else ()
    except OSError:
        return ()


def include_dir() -> str:
    """The folder holding ``xla/ffi/api/c_api.h`` (shipped with jaxlib)."""
    import jax.ffi

    return jax.ffi.include_dir()


def _scattered(kernel: VectorKernel) -> bool:
    """Whether at least :data:`SCATTER` of a kernel's outputs are zero for every state: the handler then zeroes
    each result row and writes only the others (and the kernel does not assign the zeros)."""
    n_out = sum(s.kind == "output" for s in kernel.statements)
    return len(kernel.zeros) >= SCATTER * n_out


def _nonzero(kernel: VectorKernel, name: str) -> tuple[str, str, str]:
    """The C of the indices of a scattered kernel's other entries, ``(declaration, pointer, count)``, or
    ``("", "NULL", "0")`` for a kernel that writes every entry."""
    if not _scattered(kernel):
        return "", "NULL", "0"
    n_out = sum(s.kind == "output" for s in kernel.statements)
    keep = [k for k in range(n_out) if k not in set(kernel.zeros)]
    values = ", ".join(map(str, keep)) or "0"
    return f"static const int32_t nz_{name}[] = {{{values}}};", f"nz_{name}", str(len(keep))


SCATTER = 0.75
"""The share of structurally zero entries above which a handler zeroes its result and writes only the nonzero
entries. The G1's regressor (84 % zeros) runs and builds faster that way; its Coriolis matrix (69 % zeros)
ran slower that way than with one sequential copy of every entry (``benchmarks/scaling.py --robots g1``)."""


def _state_part(kernel: VectorKernel, n_out: int) -> VectorKernel:
    """``kernel`` computing only its first ``n_out`` outputs, with the statements they read."""
    live: set[str] = set()
    kept: list[Statement] = []
    for s in reversed(kernel.statements):
        if s.kind == "unused" or (s.kind == "output" and int(s.name) < n_out) or s.name in live and s.kind != "output":
            kept.append(s)
            live.update(s.reads)
    read = {s.value.split("[")[0] for s in kept if s.kind == "input"}
    kept += [Statement("unused", a, "", ()) for a in kernel.args if a not in read and
             not any(s.kind == "unused" and s.name == a for s in kept)]
    return VectorKernel(kernel.args, tuple(reversed(kept)), tuple(z for z in kernel.zeros if z < n_out))


def _with_state_parts(native: NativeSource):
    """``(name, sizes, cores, n_out, out_rank, vector kernel)`` of each of the library's kernels, and after each
    pullback (``<name>_vjp``) its kernel without the parameters' part, ``<name>_vjp_state``: reverse mode asks
    for that one where the parameters are not differentiated (a controller's Jacobian with respect to the
    state; :class:`jaxskid.runtime._pullback.Rule`)."""
    for name, sizes, cores, n_out, out_rank in native.kernels:
        kernel = native.vectors.get(name)
        yield name, sizes, cores, n_out, out_rank, kernel
        if name in native.state_parts and kernel is not None:
            yield f"{name}_state", sizes, cores, n_out - sizes[-1], out_rank, _state_part(kernel, n_out - sizes[-1])


def glue_source(native: NativeSource) -> tuple[str, bool]:
    """The C of a library's handlers as one translation unit (see :func:`glue_parts`) and whether the
    backward kernel computes in vectors."""
    parts, lanes = glue_parts(native)
    return "".join(p.text() if isinstance(p, Piece) else p for p in parts), lanes


def glue_parts(native: NativeSource) -> tuple[list[str | Piece], bool]:
    """The C of a library's handlers (it includes the generated ``<stem>.c``), as text and the
    :class:`Piece` objects of long kernels, and whether the backward kernel computes in vectors: the
    backward step when ``native.backward`` (with the constrained one when ``native.kkt``), and a handler ``jaxskid_<name>`` per entry of ``native.kernels``
    whose C has a vector form (the others are left out; the JAX function serves them)."""
    stem = native.stem
    parts: list[str | Piece] = [_PRELUDE, POOL]
    lanes = None
    if native.backward:
        lanes = lane_functions(native, ("mass_matrix", "inverse_dynamics_vjp"))
        before, _, after = _BACKWARD.partition("@LANE_FUNCTIONS@")
        parts += [before, *(lanes or ()), after, RK4_BACKWARD]
        kkt = lane_functions(native, KKT_QUANTITIES[2:]) if lanes and native.kkt else None
        if kkt:
            parts += ["\n", *kkt, KKT_BACKWARD]
    quantities: list[str | Piece] = []
    for name, sizes, cores, n_out, out_rank, kernel in _with_state_parts(native):
        if kernel is None or name in GPU_ONLY:
            continue
        zeros = set(kernel.zeros) if _scattered(kernel) else set()
        quantities += _chunked(f"{native.stem}_{name}_V", kernel, "V", zeros)
        args = ", ".join(f"x[{i}]" for i in range(len(sizes)))
        nonzero, nz, n_nz = _nonzero(kernel, name)
        quantities.append(fill(QUANTITY, NONZERO=nonzero, NZ=nz, N_NZ=n_nz, NAME=name, ARGS=args,
                               SIZES=", ".join(map(str, sizes)), CORES=", ".join(map(str, cores)),
                               N_IN=len(sizes), N_OUT=n_out, OUT_RANK=out_rank))
    if quantities:
        parts += [_GENERIC, *quantities]
    scalar = native.backward and lanes is None
    names = dict(INCLUDE="c" if scalar else "h", STEM_UPPER=stem.upper(), STEM=stem)
    return [p if isinstance(p, Piece) else fill(p, **names) for p in parts], lanes is not None
