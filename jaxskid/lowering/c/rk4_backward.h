/* The classical Runge-Kutta step's backward pass for one state (jaxskid/lowering/_ffi_rk4.py), on the backward
   step of forward dynamics (fd_backward.h); T, TLIFT, N, NP and NO come from the includer. RK4_TABLE declares the
   tableau (a device constant in a CUDA kernel). */
#ifndef RK4_TABLE
#define RK4_TABLE static const
#endif
RK4_TABLE double rk4_b[4] = {@RK4_B@}, rk4_c[4] = {@RK4_C@};

static T dot_n(const T *x, const T *y)
{
    T s = TLIFT(0.0);
    for (int k = 0; k < N; k++) s += x[k] * y[k];
    return s;
}

/* One state's step: q, qd, a the four stages' (4 N each), (gq, gqd) the cotangent of the step's result; yq, yqd
   the cotangent of its start (written), taubar, pbar and hbar added to tb, pb and *hb; with lam, each stage's
   lambda (the cotangent of its torque) written there (4 N). pb or lam null: not computed. */
static void rk4_backward(const T *q, const T *qd, const T *a, const T *p, T h, const T *gq, const T *gqd,
                         T *__restrict__ yq, T *__restrict__ yqd, T *__restrict__ tb, T *__restrict__ pb,
                         T *__restrict__ hb, T *__restrict__ lam)
{
    T nq[N], nqd[N], kq[N], kqd[N], o[NO];  /* nq, nqd: the cotangent of the next stage's input */
    for (int k = 0; k < N; k++) yq[k] = gq[k], yqd[k] = gqd[k], nq[k] = nqd[k] = TLIFT(0.0);
    for (int s = 3; s >= 0; s--) {
        const T wb = h * TLIFT(rk4_b[s]), wc = s < 3 ? h * TLIFT(rk4_c[s + 1]) : TLIFT(0.0);
        for (int k = 0; k < N; k++) kq[k] = wb * gq[k] + wc * nq[k], kqd[k] = wb * gqd[k] + wc * nqd[k];
        backward(q + s * N, qd + s * N, a + s * N, kqd, p, o);  /* o = [lambda, (da/d(q, qd, p))^T kqd] */
        for (int k = 0; k < N; k++) nq[k] = o[N + k], nqd[k] = kq[k] + o[2 * N + k];
        *hb += TLIFT(rk4_b[s]) * (dot_n(gq, qd + s * N) + dot_n(gqd, a + s * N));
        if (s > 0) *hb += TLIFT(rk4_c[s]) * (dot_n(nq, qd + (s - 1) * N) + dot_n(nqd, a + (s - 1) * N));
        for (int k = 0; k < N; k++) yq[k] += nq[k], yqd[k] += nqd[k], tb[k] += o[k];
        if (lam)
            for (int k = 0; k < N; k++) lam[s * N + k] = o[k];
        if (pb)
            for (int k = 0; k < NP; k++) pb[k] += o[3 * N + k];
    }
}
