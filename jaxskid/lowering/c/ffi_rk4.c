
#if NQ == N  /* a fixed base: dq/dt = qd */
#ifndef TLIFT
#define TLIFT(e) (e)
#endif
#define NR (3 * N + NP + 1)

@RK4_STEP@

/* The same under feedback: K the four stages' du/d(q, qd) (4 N 2N, row-major); out = [ybar_q, ybar_qd,
   lambda (4 N), pbar, hbar]. */
#define NF (6 * N + NP + 1)
static void rk4fb_backward(const T *q, const T *qd, const T *a, const T *kk, const T *p, T h, const T *gq,
                           const T *gqd, T *out)
{
    T *yq = out, *yqd = out + N, *lam = out + 2 * N, *pb = out + 6 * N, *hb = out + 6 * N + NP;
    T nq[N], nqd[N], kq[N], kqd[N], o[NO];
    for (int k = 0; k < N; k++) yq[k] = gq[k], yqd[k] = gqd[k], nq[k] = nqd[k] = TLIFT(0.0);
    for (int k = 0; k < NP; k++) pb[k] = TLIFT(0.0);
    *hb = TLIFT(0.0);
    for (int s = 3; s >= 0; s--) {
        const T wb = h * TLIFT(rk4_b[s]), wc = s < 3 ? h * TLIFT(rk4_c[s + 1]) : TLIFT(0.0);
        const T *ks = kk + s * N * 2 * N;
        for (int k = 0; k < N; k++) kq[k] = wb * gq[k] + wc * nq[k], kqd[k] = wb * gqd[k] + wc * nqd[k];
        backward(q + s * N, qd + s * N, a + s * N, kqd, p, o);
        for (int k = 0; k < N; k++) {
            T fq = o[N + k], fqd = kq[k] + o[2 * N + k];
            for (int r = 0; r < N; r++) fq += ks[r * 2 * N + k] * o[r], fqd += ks[r * 2 * N + N + k] * o[r];
            nq[k] = fq, nqd[k] = fqd;
        }
        *hb += TLIFT(rk4_b[s]) * (dot_n(gq, qd + s * N) + dot_n(gqd, a + s * N));
        if (s > 0) *hb += TLIFT(rk4_c[s]) * (dot_n(nq, qd + (s - 1) * N) + dot_n(nqd, a + (s - 1) * N));
        for (int k = 0; k < N; k++) yq[k] += nq[k], yqd[k] += nqd[k], lam[s * N + k] = o[k];
        for (int k = 0; k < NP; k++) pb[k] += o[3 * N + k];
    }
}

static const int64_t rk4_size[7] = {4 * N, 4 * N, 4 * N, NP, 1, N, N};

static const int64_t rk4fb_size[8] = {4 * N, 4 * N, 4 * N, 8 * N * N, NP, 1, N, N};

static void rk4fb_chunk(void *ctx, int64_t c, int slot)
{
    (void)slot;
    const backward_job *j = (const backward_job *)ctx;
    const int64_t from = c * BACKWARD_CHUNK, to = from + BACKWARD_CHUNK < j->batch ? from + BACKWARD_CHUNK : j->batch;
    T q[4 * N], qd[4 * N], a[4 * N], kk[8 * N * N], p[NP1], h[1], gq[N], gqd[N], out[NF];
    T *w[8] = {q, qd, a, kk, p, h, gq, gqd};
    for (int64_t b = from; b < to; b += W) {
        load_lanes(j, 8, rk4fb_size, w, b, to);
        rk4fb_backward(q, qd, a, kk, p, h[0], gq, gqd, out);
        store_lanes(j, out, NF, b, to);
    }
}

#if JAXSKID_PART == 0  /* the handlers: in the first part of a split build */
XLA_FFI_Error *jaxskid_rk4fb_vjp(XLA_FFI_CallFrame *call)
{
    return backward_call(call, 8, rk4fb_size, NF, rk4fb_chunk);
}
#endif

static void rk4_chunk(void *ctx, int64_t c, int slot)
{
    (void)slot;
    const backward_job *j = (const backward_job *)ctx;
    const int64_t from = c * BACKWARD_CHUNK, to = from + BACKWARD_CHUNK < j->batch ? from + BACKWARD_CHUNK : j->batch;
    T q[4 * N], qd[4 * N], a[4 * N], p[NP1], h[1], gq[N], gqd[N], out[NR];
    T *w[7] = {q, qd, a, p, h, gq, gqd};
    for (int64_t b = from; b < to; b += W) {
        load_lanes(j, 7, rk4_size, w, b, to);
        for (int k = 2 * N; k < NR; k++) out[k] = TLIFT(0.0);
        rk4_backward(q, qd, a, p, h[0], gq, gqd, out, out + N, out + 2 * N, out + 3 * N, out + 3 * N + NP, (T *)0);
        store_lanes(j, out, NR, b, to);
    }
}

#if JAXSKID_PART == 0  /* the handlers: in the first part of a split build */
XLA_FFI_Error *jaxskid_rk4_vjp(XLA_FFI_CallFrame *call)
{
    return backward_call(call, 7, rk4_size, NR, rk4_chunk);
}
#endif
#endif
