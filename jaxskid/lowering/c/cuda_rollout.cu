/* @STEM@: rollouts of @STEPS@ classical Runge-Kutta steps under torques held over each step, one rollout per
   thread (jaxskid/lowering/_cuda_rollout.py), printed inside cuda_kernel.cu as its `body`. Forward dynamics,
   the mass matrix and the pullback of inverse dynamics are the quantities' vector programs over doubles. */
#ifdef __CUDACC_RTC__
#define RK4_TABLE static __device__ const
#define NAN __longlong_as_double(0x7ff8000000000000LL)
#endif
typedef double T;
#define TLIFT(e) ((T)(e))

JAXSKID_FN double positive_or_nan(double s) { return s > 0 ? s : NAN; }
#define N @N@
#define NQ N
#define NP @NP@
#define NP1 (NP > 0 ? NP : 1)
#define NV @NV@
#define NO (N + NV)
#define NX (2 * N)
#define STEPS @STEPS@LL
#define MASS mass
#define VJP vjp

@PROGRAMS@
@FD_BACKWARD@
@RK4_STEP@
/* One step from (q, qd) under tau, in place (the sums of jaxskid.runtime._rk4._stages, in its order); stage s's
   q, qd and acceleration into qs, qds, as + s * stride (stride 0: one stage's buffers, reused). */
JAXSKID_FN void rk4_step(D *q, D *qd, const D *tau, const D *p, D h, D *qs, D *qds, D *as, int stride)
{
    D kq[N], kqd[N], sq[N], sqd[N];
    for (int k = 0; k < N; k++) kq[k] = kqd[k] = sq[k] = sqd[k] = 0.0;
    for (int s = 0; s < 4; s++) {
        D *qi = qs + s * stride, *qdi = qds + s * stride, *ai = as + s * stride;
        for (int k = 0; k < N; k++) qi[k] = q[k] + rk4_c[s] * h * kq[k], qdi[k] = qd[k] + rk4_c[s] * h * kqd[k];
        fd(qi, qdi, tau, p, ai);
        for (int k = 0; k < N; k++) {
            kq[k] = qdi[k], kqd[k] = ai[k];
            sq[k] = sq[k] + rk4_b[s] * qdi[k], sqd[k] = sqd[k] + rk4_b[s] * ai[k];
        }
    }
    for (int k = 0; k < N; k++) q[k] = q[k] + h * sq[k], qd[k] = qd[k] + h * sqd[k];
}

/* The parameters as doubles: the input itself, or a copy of a float32 input in `copy`. */
#if JAXSKID_IO_DOUBLE
#define PARAMETERS(pin, copy) const D *p = pin
#else
#define PARAMETERS(pin, copy) D copy[NP1]; for (int k = 0; k < NP; k++) copy[k] = pin[k]; const D *p = copy
#endif

#if JAXSKID_ROLLOUT_PART == 0
/* x0 (2 N), u (STEPS N), p, h (1) -> the states x_0 ... x_STEPS ((STEPS + 1) 2 N). */
static void body(const io_t *x0, const io_t *u, const io_t *pin, const io_t *hin, io_t *out)
{
    PARAMETERS(pin, copy);
    D q[N], qd[N], tau[N], qi[N], qdi[N], ai[N];
    const D h = hin[0];
    for (int k = 0; k < N; k++) q[k] = x0[k], qd[k] = x0[N + k], out[k] = (io_t)q[k], out[N + k] = (io_t)qd[k];
    for (long long s = 0; s < STEPS; s++) {
        for (int k = 0; k < N; k++) tau[k] = u[s * N + k];
        rk4_step(q, qd, tau, p, h, qi, qdi, ai, 0);
        for (int k = 0; k < N; k++) out[(s + 1) * NX + k] = (io_t)q[k], out[(s + 1) * NX + N + k] = (io_t)qd[k];
    }
}
#elif JAXSKID_ROLLOUT_PART == 1
/* The adjoint: the states x (the forward pass's result), u, p, h and the cotangent g of x -> [xbar_0 (2 N),
   ubar (STEPS N), hbar, lambda (STEPS 4 N)]: from the last step, each step's stages recomputed from its saved
   state, then its backward pass (rk4_backward), the cotangent of x_s being that pass's plus g's row s. Each
   stage's lambda is kept for the parameters' part, which needs no recursion (JAXSKID_ROLLOUT_PART 2). */
static void body(const io_t *x, const io_t *u, const io_t *pin, const io_t *hin, const io_t *g, io_t *out)
{
    io_t *ub = out + NX, *lout = out + NX + STEPS * N + 1;
    PARAMETERS(pin, copy);
    D q[N], qd[N], tau[N], qs[4 * N], qds[4 * N], as[4 * N], yq[N], yqd[N], zq[N], zqd[N], tb[N], lam[4 * N];
    const D h = hin[0];
    D hb = 0.0;
    for (int k = 0; k < N; k++) yq[k] = g[STEPS * NX + k], yqd[k] = g[STEPS * NX + N + k];
    for (long long s = STEPS - 1; s >= 0; s--) {
        for (int k = 0; k < N; k++) q[k] = x[s * NX + k], qd[k] = x[s * NX + N + k], tau[k] = u[s * N + k], tb[k] = 0.0;
        rk4_step(q, qd, tau, p, h, qs, qds, as, N);
        rk4_backward(qs, qds, as, p, h, yq, yqd, zq, zqd, tb, (D *)0, &hb, lam);
        for (int k = 0; k < N; k++) {
            ub[s * N + k] = (io_t)tb[k];
            yq[k] = zq[k] + g[s * NX + k], yqd[k] = zqd[k] + g[s * NX + N + k];
        }
        for (int k = 0; k < 4 * N; k++) lout[s * 4 * N + k] = (io_t)lam[k];
    }
    for (int k = 0; k < N; k++) out[k] = (io_t)yq[k], out[N + k] = (io_t)yqd[k];
    out[NX + STEPS * N] = (io_t)hb;
}
#else
/* The parameters' cotangent from the steps [j STRIDE, (j + 1) STRIDE) of one rollout: x, u and lambda (the
   adjoint's) of every step, p, h and j -> the sum over those steps and their stages of -(d ID/d p)^T lambda_i
   at the stage's state (NP). The rollouts' blocks of steps are threads of their own. */
static void body(const io_t *x, const io_t *u, const io_t *lin, const io_t *pin, const io_t *hin, const io_t *jin,
                 io_t *out)
{
    PARAMETERS(pin, copy);
    D pb[NP1], q[N], qd[N], tau[N], qs[4 * N], qds[4 * N], as[4 * N], lam[N], o[NV];
    const D h = hin[0];
    const long long first = (long long)jin[0] * @STRIDE@, last = first + @STRIDE@ < STEPS ? first + @STRIDE@ : STEPS;
    for (int k = 0; k < NP; k++) pb[k] = 0.0;
    for (long long s = first; s < last; s++) {
        for (int k = 0; k < N; k++) q[k] = x[s * NX + k], qd[k] = x[s * NX + N + k], tau[k] = u[s * N + k];
        rk4_step(q, qd, tau, p, h, qs, qds, as, N);
        for (int i = 0; i < 4; i++) {
            for (int k = 0; k < N; k++) lam[k] = lin[(s * 4 + i) * N + k];
            VJP(qs + i * N, qds + i * N, as + i * N, lam, p, o);
            for (int k = 0; k < NP; k++) pb[k] -= o[2 * N + k];
        }
    }
    for (int k = 0; k < NP; k++) out[k] = (io_t)pb[k];
}
#endif
