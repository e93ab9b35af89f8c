"""Generated C as a kernel of XLA programs: the backward step of forward dynamics, built with a handler of
XLA's foreign function interface (the C API of ``xla/ffi/api/c_api.h``, shipped with jaxlib).

On CPU, XLA compiles a generated program of a few thousand scalar operations into a hundred or more small
kernels, each paying the runtime's dispatch; the backward pass of a rollout step ran 116 of them per RK4
stage against 9 for the forward pass, and the gradient cost 10-30 times the loss. The same arithmetic as
one C function is one kernel. :func:`ffi_library` builds

    jaxskid_fd_vjp(q, qd, qdd, g, p) -> [lambda, -vjp]     lambda = M(q)^-1 g,
                                                            vjp = lambda^T d ID(q, qd, qdd, p)/d(q, qd, p)

from the generated C of ``mass_matrix`` and ``inverse_dynamics_vjp`` and a hand-written L D L^T solve
(:func:`jaxskid.runtime._ldl.ldl_solve`, the same factorisation), compiled as one translation unit so that
both inline and share each joint's sine and cosine. The handler loops over a batch (the
leading axes of the output; an argument whose size is one state's is shared by all), and takes float32
or float64, computing in double. Nothing here knows SymPy: a build takes C text.
"""

from __future__ import annotations

import re
import subprocess
from collections.abc import Mapping
from pathlib import Path

from ._native import CFLAGS, BuildError, _compiler, _install, _key, _sources

FFI_CFLAGS = ("-fno-math-errno",)
"""Added to :data:`~jaxskid.lowering._native.CFLAGS`: ``sin`` and ``cos`` without ``errno`` are pure, so the
compiler computes each joint's once (the generated vector-Jacobian product repeats them)."""

TARGET = "jaxskid_fd_vjp"
"""The exported handler of a library built by :func:`ffi_library`."""

_GLUE = r"""
#include <math.h>
#include <stdint.h>
#include <stddef.h>
#include "xla/ffi/api/c_api.h"
#include "@STEM@.c"  /* one translation unit: M and the VJP inline here and share sin, cos */

#define N @STEM_UPPER@_N_DOF
#define NP @STEM_UPPER@_N_PARAMS
#define NV @STEM_UPPER@_INVERSE_DYNAMICS_VJP_SIZE
#define NO (N + NV)
#define NP1 (NP > 0 ? NP : 1)

#ifdef LANES /* W states at once in vectors (GCC and Clang vector extensions), the functions rewritten below */
#define W LANES
typedef double T __attribute__((vector_size(8 * LANES)));
#define LANE(x, l) ((x)[l])
#define LIFT(e) ((T){0} + (e))
static inline int same(T x) { for (int l = 1; l < W; l++) if (x[l] != x[0]) return 0; return 1; }
/* lane-wise sin and cos; a single state fills every lane, and costs one call */
static inline T vsin(T x) { T r; if (same(x)) return LIFT(sin(x[0])); for (int l = 0; l < W; l++) r[l] = sin(x[l]); return r; }
static inline T vcos(T x) { T r; if (same(x)) return LIFT(cos(x[0])); for (int l = 0; l < W; l++) r[l] = cos(x[l]); return r; }
static inline T positive_or_nan(T s) { for (int l = 0; l < W; l++) if (!(s[l] > 0)) s[l] = NAN; return s; }
@LANE_FUNCTIONS@
#define MASS @STEM@_mass_matrix_lanes
#define VJP @STEM@_inverse_dynamics_vjp_lanes
#else
#define W 1
typedef double T;
#define LANE(x, l) (x)
static inline T positive_or_nan(T s) { return s > 0 ? s : NAN; }
#define MASS @STEM@_mass_matrix
#define VJP @STEM@_inverse_dynamics_vjp
#endif

/* lambda = M^-1 g by M = L D L^T (Golub & Van Loan, Alg. 4.1.2; a pivot <= 0 gives nan), then the
   vector-Jacobian product of inverse dynamics at lambda, negated. out = [lambda (N), -vjp (NV)]. */
static void backward(const T *q, const T *qd, const T *a, const T *g, const T *p, T *out)
{
    T m[N * N], d[N], y[N];
    MASS(q, p, m);
    for (int j = 0; j < N; j++) {
        T s = m[j * N + j];
        for (int k = 0; k < j; k++) s -= m[j * N + k] * m[j * N + k] * d[k];
        d[j] = positive_or_nan(s);
        for (int i = j + 1; i < N; i++) {
            T t = m[i * N + j];
            for (int k = 0; k < j; k++) t -= m[i * N + k] * m[j * N + k] * d[k];
            m[i * N + j] = t / d[j];
        }
    }
    for (int i = 0; i < N; i++) {
        T s = g[i];
        for (int k = 0; k < i; k++) s -= m[i * N + k] * y[k];
        y[i] = s;
    }
    for (int i = N - 1; i >= 0; i--) {
        T s = y[i] / d[i];
        for (int k = i + 1; k < N; k++) s -= m[k * N + i] * out[k];
        out[i] = s;
    }
    VJP(q, qd, a, out, p, out + N);
    for (int i = N; i < NO; i++) out[i] = -out[i];
}

static int64_t numel(const XLA_FFI_Buffer *b)
{
    int64_t n = 1;
    for (int64_t i = 0; i < b->rank; i++) n *= b->dims[i];
    return n;
}

static double load(const XLA_FFI_Buffer *b, int64_t i)
{
    return b->dtype == XLA_FFI_DataType_F64 ? ((const double *)b->data)[i] : ((const float *)b->data)[i];
}

static void store(XLA_FFI_Buffer *b, int64_t i, double x)
{
    if (b->dtype == XLA_FFI_DataType_F64) ((double *)b->data)[i] = x;
    else ((float *)b->data)[i] = (float)x;
}

XLA_FFI_Error *jaxskid_fd_vjp(XLA_FFI_CallFrame *call)
{
    if (call->extension_start != NULL && call->extension_start->type == XLA_FFI_Extension_Metadata) {
        XLA_FFI_Metadata *meta = ((XLA_FFI_Metadata_Extension *)call->extension_start)->metadata;
        meta->api_version.major_version = XLA_FFI_API_MAJOR;
        meta->api_version.minor_version = XLA_FFI_API_MINOR;
        meta->traits = 0;
        return NULL;
    }
    if (call->stage != XLA_FFI_ExecutionStage_EXECUTE || call->args.size != 5 || call->rets.size != 1)
        return NULL;
    static const int64_t size[5] = {N, N, N, N, NP};
    const XLA_FFI_Buffer *in[5];
    int64_t stride[5];
    for (int i = 0; i < 5; i++) {
        in[i] = (const XLA_FFI_Buffer *)call->args.args[i];
        stride[i] = numel(in[i]) == size[i] ? 0 : size[i];  /* one state's size: shared by the batch */
    }
    XLA_FFI_Buffer *res = (XLA_FFI_Buffer *)call->rets.rets[0];
    const int64_t batch = numel(res) / NO;
    T q[N], qd[N], a[N], g[N], p[NP1], out[NO];
    T *w[5] = {q, qd, a, g, p};
    for (int64_t b = 0; b < batch; b += W) {
        for (int l = 0; l < W; l++) {  /* a last partial group repeats its last state */
            const int64_t s = b + l < batch ? b + l : batch - 1;
            for (int i = 0; i < 5; i++)
                for (int64_t k = 0; k < size[i]; k++) LANE(w[i][k], l) = load(in[i], s * stride[i] + k);
        }
        backward(q, qd, a, g, p, out);
        for (int l = 0; l < W && b + l < batch; l++)
            for (int k = 0; k < NO; k++) store(res, (b + l) * NO + k, LANE(out[k], l));
    }
    return NULL;
}
"""

LANES = 4
"""States computed at once by the kernel, in vectors of doubles (AVX2 registers where the machine has them)."""

_CALL = re.compile(r"\b([A-Za-z_]\w*)\s*\(")


def lane_functions(source: str, stem: str, names: tuple[str, ...]) -> str | None:
    """The generated C functions ``<stem>_<name>`` of ``source`` rewritten over vectors of ``LANES`` states
    (``<stem>_<name>_lanes``, type ``T``): every ``double`` becomes ``T``, ``sin``/``cos`` their lane-wise
    forms, a right-hand side that is a number is made a vector. None when a body calls any other function or has a
    conditional (the scalar kernel serves)."""
    out = []
    for name in names:
        fn = f"{stem}_{name}"
        m = re.search(rf"^void {fn}\((.*?)\)\n\{{\n(.*?)^\}}\n", source, re.M | re.S)
        if m is None:
            return None
        params, body = m.group(1), m.group(2)
        if "?" in body or set(_CALL.findall(body)) - {"sin", "cos"}:
            return None
        params = params.replace("const double *", "const T *").replace("double *out", "T *out")
        body = re.sub(r"\bconst double\b", "const T", body)
        body = re.sub(r"\b(sin|cos)\(", r"v\1(", body)
        body = re.sub(r"^(\s*[^=\n]+?) = (.+);$", _lift_constant, body, flags=re.M)
        out.append(f"static void {fn}_lanes({params})\n{{\n{body}}}\n")
    return "\n".join(out)


_NUMBER = re.compile(r"\b\d+\.?\d*(?:[eE][-+]?\d+)?\b|\.\d+(?:[eE][-+]?\d+)?")


def _lift_constant(m: re.Match) -> str:
    """An assignment whose right-hand side names no variable (a number: ``out[3] = 0.0;``) made a vector;
    the others already are (``0 + x`` is not folded in IEEE arithmetic, so nothing else is lifted)."""
    target, rhs = m.group(1), m.group(2)
    return f"{target} = {rhs};" if re.search(r"[A-Za-z_]", _NUMBER.sub("", rhs)) else f"{target} = LIFT({rhs});"


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


def ffi_library(native: Mapping[str, str], root: Path) -> Path:
    """Build (once per machine: keyed by a hash of everything that goes in) the shared library of the
    ``jaxskid_fd_vjp`` handler for ``native`` (``{"stem", "header", "source"}``: the generated C of
    ``mass_matrix`` and ``inverse_dynamics_vjp``, :func:`jaxskid.codegen._c.emit_c`), under ``root``.

    Raises:
        BuildError: no C compiler, no FFI header, or the build failed.
    """
    stem = native["stem"]
    lanes = lane_functions(native["source"], stem, ("mass_matrix", "inverse_dynamics_vjp"))
    glue = _GLUE.replace("@LANE_FUNCTIONS@", lanes or "").replace("@STEM_UPPER@", stem.upper())
    glue = glue.replace("@STEM@", stem)
    flags = (*CFLAGS, *FFI_CFLAGS, *((f"-DLANES={LANES}", *_vector_flags()) if lanes else ()))
    inc = include_dir()
    if not (Path(inc) / "xla" / "ffi" / "api" / "c_api.h").exists():
        raise BuildError(f"jaxlib has no FFI header under {inc}")
    cc = _compiler()
    key = _key("ffi", cc, " ".join(flags), inc, native["header"], native["source"], glue)
    final = root / key[:24] / f"lib{stem}_ffi.so"
    if not final.exists():
        tmp = _sources(root, stem, native["header"], native["source"])
        (tmp / "glue.c").write_text(glue)
        out = tmp / final.name
        cmd = [*cc.split(), *flags, "-shared", "-I", inc, "-I", str(tmp), "-o", str(out),
               str(tmp / "glue.c"), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise BuildError(f"{' '.join(cmd)} failed: {proc.stderr.strip()[-2000:]}")
        _install(tmp, out, final)
    return final
