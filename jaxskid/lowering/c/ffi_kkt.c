/* The backward step of constrained forward dynamics (jaxskid/lowering/_ffi_kkt.py), after the backward step of
   forward dynamics (ffi_backward.c: T, W, MASS, VJP, backward_call, load_lanes, store_lanes). KR is the number of
   constraint rows. */
#define KR (@STEM_UPPER@_CONSTRAINT_JACOBIAN_SIZE / N)
#define KO (NQ + 2 * N + NP)
#define AJAC @STEM@_constraint_jacobian_T
#define AJAC_VJP @STEM@_constraint_jacobian_vjp_T
#define DRIFT_VJP @STEM@_constraint_drift_vjp_T
#define PHI_VJP @STEM@_constraint_residual_vjp_T

/* x = L^-T D^-1 L^-1 b for the factor of ldl_factor (b and x may be the same array). */
static void ldl_solve_n(const T *f, const T *d, int n, const T *b, T *x)
{
    for (int i = 0; i < n; i++) {
        T s = b[i];
        for (int k = 0; k < i; k++) s -= f[i * n + k] * x[k];
        x[i] = s;
    }
    for (int i = n - 1; i >= 0; i--) {
        T s = x[i] / d[i];
        for (int k = i + 1; k < n; k++) s -= f[k * n + i] * x[k];
        x[i] = s;
    }
}

/* f = L D L^T of the symmetric n x n matrix f (its lower triangle, overwritten by L's; d gets D); a pivot <= 0
   gives nan. */
static void ldl_factor(T *f, T *d, int n)
{
    for (int j = 0; j < n; j++) {
        T s = f[j * n + j];
        for (int k = 0; k < j; k++) s -= f[j * n + k] * f[j * n + k] * d[k];
        d[j] = positive_or_nan(s);
        for (int i = j + 1; i < n; i++) {
            T t = f[i * n + j];
            for (int k = 0; k < j; k++) t -= f[i * n + k] * f[j * n + k] * d[k];
            f[i * n + j] = t / d[j];
        }
    }
}

/* One state. The KKT system K [qdd; lambda] = [tau - h; gamma], K = [[M, -A^T], [A, eps]], was solved forward;
   given the cotangent w of [qdd; lambda], K^T y = w is solved as M y1 - A^T u = w1, A y1 + eps u = -w2, y2 = -u
   (M y1 = w1 + A^T u, (A M^-1 A^T + eps) u = -w2 - A M^-1 w1). The cotangents are minus the pullback of
   y1^T R1 + y2^T R2 over the residuals R1 = ID(q, qd, qdd, p) - A^T lambda, R2 = A qdd + eps lambda + Adot qd +
   2 alpha A qd + beta^2 phi, and y1 for tau: out = [qbar (NQ), qdbar (N), taubar (N), pbar (NP)].
   c = (alpha, beta, eps). */
static void kkt_backward(const T *q, const T *qd, const T *a, const T *lam, const T *w, const T *c, const T *p,
                         T *out)
{
    T m[N * N], d[N], A[KR * N], y[KR * N], z[N], s[KR * KR], e[KR], u[KR], c1[N], bar[KR * N], o[KO];
    MASS(q, p, m);
    ldl_factor(m, d, N);
    AJAC(q, p, A);
    ldl_solve_n(m, d, N, w, z);  /* M^-1 w1 */
    for (int r = 0; r < KR; r++) ldl_solve_n(m, d, N, A + r * N, y + r * N);  /* M^-1 A^T */
    for (int r = 0; r < KR; r++) {
        T t = -w[N + r];
        for (int k = 0; k < N; k++) t -= A[r * N + k] * z[k];
        u[r] = t;
        for (int i = 0; i <= r; i++) {
            T v = i == r ? c[2] : TLIFT(0.0);
            for (int k = 0; k < N; k++) v += A[r * N + k] * y[i * N + k];
            s[r * KR + i] = s[i * KR + r] = v;
        }
    }
    ldl_factor(s, e, KR);
    ldl_solve_n(s, e, KR, u, u);
    T *qb = out, *qdb = out + NQ, *tb = out + NQ + N, *pb = out + NQ + 2 * N;
    for (int k = 0; k < N; k++) {
        T t = z[k];
        for (int r = 0; r < KR; r++) t += y[r * N + k] * u[r];
        tb[k] = t, c1[k] = -t;  /* y1 and R1's cotangent -y1; R2's is -y2 = u */
    }
    for (int k = 0; k < NQ + N; k++) out[k] = TLIFT(0.0);
    for (int k = 0; k < NP; k++) pb[k] = TLIFT(0.0);
    VJP(q, qd, a, c1, p, o);  /* [q, qd, p] (at fixed qdd) */
    for (int k = 0; k < NQ + N; k++) out[k] += o[k];
    for (int k = 0; k < NP; k++) pb[k] += o[NQ + N + k];
    for (int r = 0; r < KR; r++)
        for (int k = 0; k < N; k++) bar[r * N + k] = -lam[r] * c1[k] + u[r] * (a[k] + TLIFT(2.0) * c[0] * qd[k]);
    AJAC_VJP(q, bar, p, o);  /* [q, p] */
    for (int k = 0; k < NQ; k++) qb[k] += o[k];
    for (int k = 0; k < NP; k++) pb[k] += o[NQ + k];
    DRIFT_VJP(q, qd, u, p, o);  /* [q, qd, p] */
    for (int k = 0; k < NQ + N; k++) out[k] += o[k];
    for (int k = 0; k < NP; k++) pb[k] += o[NQ + N + k];
    for (int k = 0; k < N; k++)
        for (int r = 0; r < KR; r++) qdb[k] += TLIFT(2.0) * c[0] * A[r * N + k] * u[r];
    for (int r = 0; r < KR; r++) u[r] *= c[1] * c[1];
    PHI_VJP(q, u, p, o);  /* [q, p] */
    for (int k = 0; k < NQ; k++) qb[k] += o[k];
    for (int k = 0; k < NP; k++) pb[k] += o[NQ + k];
}

static const int64_t kkt_size[7] = {NQ, N, N, KR, N + KR, 3, NP};

static void kkt_chunk(void *ctx, int64_t c, int slot)
{
    (void)slot;
    const backward_job *j = (const backward_job *)ctx;
    const int64_t from = c * BACKWARD_CHUNK, to = from + BACKWARD_CHUNK < j->batch ? from + BACKWARD_CHUNK : j->batch;
    T q[NQ], qd[N], a[N], lam[KR], w[N + KR], k[3], p[NP1], out[KO];
    T *in[7] = {q, qd, a, lam, w, k, p};
    for (int64_t b = from; b < to; b += W) {
        load_lanes(j, 7, kkt_size, in, b, to);
        kkt_backward(q, qd, a, lam, w, k, p, out);
        store_lanes(j, out, KO, b, to);
    }
}

#if JAXSKID_PART == 0  /* the handlers: in the first part of a split build */
XLA_FFI_Error *jaxskid_kkt_vjp(XLA_FFI_CallFrame *call)
{
    return backward_call(call, 7, kkt_size, KO, kkt_chunk);
}
#endif
