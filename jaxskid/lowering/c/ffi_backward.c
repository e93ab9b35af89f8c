
#define NV @STEM_UPPER@_INVERSE_DYNAMICS_VJP_SIZE
#define NO (N + NV)
#define BACKWARD_CHUNK @BACKWARD_CHUNK@

#ifdef LANES /* W states at once in vectors (GCC and Clang vector extensions), with the vector functions below */
#define W LANES
typedef double T __attribute__((vector_size(8 * LANES)));
#define LANE(x, l) ((x)[l])
#define TLIFT(e) ((T){0} + (e))
typedef long long TI __attribute__((vector_size(8 * LANES)));
@TRIG_T@
static inline T Tsin(T x) { return Ttrig(x, 0); }
static inline T Tcos(T x) { return Ttrig(x, 1); }
static inline T positive_or_nan(T s) { for (int l = 0; l < W; l++) if (!(s[l] > 0)) s[l] = NAN; return s; }
@LANE_FUNCTIONS@
#define MASS @STEM@_mass_matrix_T
#define VJP @STEM@_inverse_dynamics_vjp_T
#else
#define W 1
typedef double T;
#define LANE(x, l) (x)
static inline T positive_or_nan(T s) { return s > 0 ? s : NAN; }
#define MASS @STEM@_mass_matrix
#define VJP @STEM@_inverse_dynamics_vjp
#endif

@FD_BACKWARD@

/* One call of a backward handler: its inputs (at most 8) with their strides between states (0: one state's,
   shared by the batch), its result and the number of states. */
typedef struct {
    const XLA_FFI_Buffer *in[8];
    XLA_FFI_Buffer *res;
    int64_t stride[8], batch;
} backward_job;

/* Lane l of W states from b of the job's n_in inputs (one state's sizes `size`) into w (a last partial group
   repeats its last state), and the W results from out. */
static void load_lanes(const backward_job *j, int n_in, const int64_t *size, T *const *w, int64_t b, int64_t to)
{
    for (int l = 0; l < W; l++) {
        const int64_t s = b + l < to ? b + l : to - 1;
        for (int i = 0; i < n_in; i++)
            for (int64_t k = 0; k < size[i]; k++) LANE(w[i][k], l) = load(j->in[i], s * j->stride[i] + k);
    }
}

static void store_lanes(const backward_job *j, const T *out, int64_t n_out, int64_t b, int64_t to)
{
    for (int l = 0; l < W && b + l < to; l++)
        for (int k = 0; k < n_out; k++) store(j->res, (b + l) * n_out + k, LANE(out[k], l));
}

/* A backward handler: n_in inputs of one state's sizes `size`, one result of n_out entries per state, the
   batch in chunks of BACKWARD_CHUNK states that `chunk` computes on the pool. */
static XLA_FFI_Error *backward_call(XLA_FFI_CallFrame *call, int n_in, const int64_t *size, int64_t n_out,
                                    void (*chunk)(void *, int64_t, int))
{
    if (metadata(call) || call->stage != XLA_FFI_ExecutionStage_EXECUTE || call->args.size != n_in || call->rets.size != 1)
        return NULL;
    backward_job j;
    for (int i = 0; i < n_in; i++) {
        j.in[i] = (const XLA_FFI_Buffer *)call->args.args[i];
        j.stride[i] = numel(j.in[i]) == size[i] ? 0 : size[i];  /* one state's: shared by the batch */
    }
    j.res = (XLA_FFI_Buffer *)call->rets.rets[0];
    j.batch = numel(j.res) / n_out;
    const int64_t chunks = (j.batch + BACKWARD_CHUNK - 1) / BACKWARD_CHUNK;
    parallel_for(call, pool_threads(call, chunks), chunks, chunk, &j);
    return NULL;
}

static const int64_t backward_size[5] = {NQ, N, N, N, NP};

/* States [c BACKWARD_CHUNK, (c + 1) BACKWARD_CHUNK) of the batch. */
static void backward_chunk(void *ctx, int64_t c, int slot)
{
    (void)slot;
    const backward_job *j = (const backward_job *)ctx;
    const int64_t from = c * BACKWARD_CHUNK, to = from + BACKWARD_CHUNK < j->batch ? from + BACKWARD_CHUNK : j->batch;
    T q[NQ], qd[N], a[N], g[N], p[NP1], out[NO];
    T *w[5] = {q, qd, a, g, p};
    for (int64_t b = from; b < to; b += W) {
        load_lanes(j, 5, backward_size, w, b, to);
        backward(q, qd, a, g, p, out);
        store_lanes(j, out, NO, b, to);
    }
}

#if JAXSKID_PART == 0  /* the handlers: in the first part of a split build */
XLA_FFI_Error *jaxskid_fd_vjp(XLA_FFI_CallFrame *call)
{
    return backward_call(call, 5, backward_size, NO, backward_chunk);
}
#endif
