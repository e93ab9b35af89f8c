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

/* lambda = M^-1 g by M = L D L^T (Golub & Van Loan, Alg. 4.1.2; a pivot <= 0 gives nan), then the
   vector-Jacobian product of inverse dynamics at lambda, negated. out = [lambda (N), -vjp (NV)]. */
static void backward(const double *q, const double *qd, const double *a, const double *g, const double *p,
                     double *out)
{
    double m[N * N], d[N], y[N];
    @STEM@_mass_matrix(q, p, m);
    for (int j = 0; j < N; j++) {
        double s = m[j * N + j];
        for (int k = 0; k < j; k++) s -= m[j * N + k] * m[j * N + k] * d[k];
        d[j] = s > 0 ? s : NAN;
        for (int i = j + 1; i < N; i++) {
            double t = m[i * N + j];
            for (int k = 0; k < j; k++) t -= m[i * N + k] * m[j * N + k] * d[k];
            m[i * N + j] = t / d[j];
        }
    }
    for (int i = 0; i < N; i++) {
        double s = g[i];
        for (int k = 0; k < i; k++) s -= m[i * N + k] * y[k];
        y[i] = s;
    }
    for (int i = N - 1; i >= 0; i--) {
        double s = y[i] / d[i];
        for (int k = i + 1; k < N; k++) s -= m[k * N + i] * out[k];
        out[i] = s;
    }
    @STEM@_inverse_dynamics_vjp(q, qd, a, out, p, out + N);
    for (int i = N; i < NO; i++) out[i] = -out[i];
}

static int64_t numel(const XLA_FFI_Buffer *b)
{
    int64_t n = 1;
    for (int64_t i = 0; i < b->rank; i++) n *= b->dims[i];
    return n;
}

static void widen(const float *x, double *y, int64_t n) { for (int64_t i = 0; i < n; i++) y[i] = x[i]; }
static void narrow(const double *x, float *y, int64_t n) { for (int64_t i = 0; i < n; i++) y[i] = (float)x[i]; }

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
        stride[i] = numel(in[i]) == size[i] ? 0 : size[i];
    }
    XLA_FFI_Buffer *res = (XLA_FFI_Buffer *)call->rets.rets[0];
    const int64_t batch = numel(res) / NO;
    if (res->dtype == XLA_FFI_DataType_F64) {
        const double *x[5];
        for (int i = 0; i < 5; i++) x[i] = (const double *)in[i]->data;
        double *out = (double *)res->data;
        for (int64_t b = 0; b < batch; b++)
            backward(x[0] + b * stride[0], x[1] + b * stride[1], x[2] + b * stride[2], x[3] + b * stride[3],
                     x[4] + b * stride[4], out + b * NO);
    } else if (res->dtype == XLA_FFI_DataType_F32) {
        double q[N], qd[N], a[N], g[N], p[NP1], out[NO];
        double *w[5] = {q, qd, a, g, p};
        for (int64_t b = 0; b < batch; b++) {
            for (int i = 0; i < 5; i++) widen((const float *)in[i]->data + b * stride[i], w[i], size[i]);
            backward(q, qd, a, g, p, out);
            narrow(out, (float *)res->data + b * NO, NO);
        }
    }
    return NULL;
}
"""


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
    glue = _GLUE.replace("@STEM_UPPER@", stem.upper()).replace("@STEM@", stem)
    inc = include_dir()
    if not (Path(inc) / "xla" / "ffi" / "api" / "c_api.h").exists():
        raise BuildError(f"jaxlib has no FFI header under {inc}")
    cc = _compiler()
    key = _key("ffi", cc, " ".join((*CFLAGS, *FFI_CFLAGS)), inc, native["header"], native["source"], glue)
    final = root / key[:24] / f"lib{stem}_ffi.so"
    if not final.exists():
        tmp = _sources(root, stem, native["header"], native["source"])
        (tmp / "glue.c").write_text(glue)
        out = tmp / final.name
        cmd = [*cc.split(), *CFLAGS, *FFI_CFLAGS, "-shared", "-I", inc, "-I", str(tmp), "-o", str(out),
               str(tmp / "glue.c"), "-lm"]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            raise BuildError(f"{' '.join(cmd)} failed: {proc.stderr.strip()[-2000:]}")
        _install(tmp, out, final)
    return final
