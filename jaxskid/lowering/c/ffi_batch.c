
/* Quantity kernels: VW states at once in vectors of doubles (GCC and Clang vector extensions). */
#define VW 4
typedef double V __attribute__((vector_size(8 * VW)));
#define VLIFT(e) ((V){0} + (e))
typedef long long VI __attribute__((vector_size(8 * VW)));

@TRIG_V@
static inline V Vsin(V x) { return Vtrig(x, 0); }
static inline V Vcos(V x) { return Vtrig(x, 1); }

typedef void (*kernel)(const V *const *in, V *out);
#define MAX_IN 8
#define MAX_RANK 16
#define CHUNK @CHUNK@

/* One call's batch, and a workspace per thread: the kernel's result, then each input's entries. */
typedef struct {
    int n_in, f64;
    const int64_t *size;
    int64_t n_out, n_nz, nb, batch, total;
    kernel fn;
    const int32_t *nz;
    const XLA_FFI_Buffer *in[MAX_IN];
    XLA_FFI_Buffer *res;
    int64_t stride[MAX_IN][MAX_RANK];  /* entries between consecutive indices along each batch axis */
    int shared[MAX_IN];  /* the same entries for every state (parameters, mostly): loaded once per workspace */
    V *buffers[MAX_THREADS];
} batch_job;

static V *workspace(const batch_job *j)
{
    V *buffer = NULL;
    if (posix_memalign((void **)&buffer, sizeof(V), (size_t)(j->total > 0 ? j->total : 1) * sizeof(V)) != 0)
        return NULL;
    V *xi = buffer + j->n_out;
    for (int i = 0; i < j->n_in; xi += j->size[i], i++)
        if (j->shared[i])
            for (int64_t k = 0; k < j->size[i]; k++) xi[k] = VLIFT(load(j->in[i], k));
    return buffer;
}

/* Chunk c of the batch: states [c CHUNK, (c + 1) CHUNK), in workspace `slot`. */
static void states(void *ctx, int64_t c, int slot)
{
    const batch_job *j = (const batch_job *)ctx;
    const int64_t from = c * CHUNK, to = from + CHUNK < j->batch ? from + CHUNK : j->batch;
    V *buffer = j->buffers[slot], *out = buffer;
    const V *x[MAX_IN];
    for (int i = 0, at = (int)j->n_out; i < j->n_in; at += (int)j->size[i], i++) x[i] = buffer + at;
    const int64_t n_out = j->n_out, bytes = j->f64 ? 8 : 4;
    for (int64_t b = from; b < to; b += VW) {
        for (int l = 0; l < VW; l++) {  /* a last partial group repeats its last state */
            int64_t s = b + l < to ? b + l : to - 1, off[MAX_IN] = {0};
            for (int64_t d = j->nb - 1; d >= 0; d--) {
                const int64_t k = s % j->res->dims[d];
                s /= j->res->dims[d];
                for (int i = 0; i < j->n_in; i++) off[i] += k * j->stride[i][d];
            }
            for (int i = 0; i < j->n_in; i++) {
                if (j->shared[i]) continue;
                V *xi = (V *)x[i];
                for (int64_t k = 0; k < j->size[i]; k++) xi[k][l] = load(j->in[i], off[i] + k);
            }
        }
        j->fn(x, out);
        const int m = to - b < VW ? (int)(to - b) : VW;
        if (j->nz) {  /* mostly zeros: zero the rows, then scatter the rest */
            memset((char *)j->res->data + b * n_out * bytes, 0, (size_t)m * (size_t)n_out * (size_t)bytes);
            for (int l = 0; l < m; l++) {
                if (j->f64) {
                    double *r = (double *)j->res->data + (b + l) * n_out;
                    for (int64_t k = 0; k < j->n_nz; k++) r[j->nz[k]] = out[j->nz[k]][l];
                } else {
                    float *r = (float *)j->res->data + (b + l) * n_out;
                    for (int64_t k = 0; k < j->n_nz; k++) r[j->nz[k]] = (float)out[j->nz[k]][l];
                }
            }
        } else if (j->f64) {
            double *r = (double *)j->res->data + b * n_out;
            for (int l = 0; l < m; l++)
                for (int64_t k = 0; k < n_out; k++) r[l * n_out + k] = out[k][l];
        } else {
            float *r = (float *)j->res->data + b * n_out;
            for (int l = 0; l < m; l++)
                for (int64_t k = 0; k < n_out; k++) r[l * n_out + k] = (float)out[k][l];
        }
    }
}

/* Run `fn` over a batch. The result's leading axes are the batch and its last `out_rank` axes one state's
   `n_out` entries; input i has `core[i]` trailing axes holding `size[i]` entries, and leading axes that
   broadcast against the result's batch axes (right-aligned; an axis of 1, or a missing one, is shared). */
static XLA_FFI_Error *run(XLA_FFI_CallFrame *call, int n_in, const int64_t *size, const int64_t *core,
                          int64_t n_out, int64_t out_rank, kernel fn, const int32_t *nz, int64_t n_nz)
{
    if (metadata(call) || call->stage != XLA_FFI_ExecutionStage_EXECUTE
        || (call->args.size != n_in && call->args.size != n_in + 1) || call->rets.size != 1 || n_in > MAX_IN)
        return NULL;
    batch_job j = {.n_in = n_in, .size = size, .n_out = n_out, .fn = fn, .nz = nz, .n_nz = n_nz};
    j.res = (XLA_FFI_Buffer *)call->rets.rets[0];
    j.nb = j.res->rank - out_rank, j.batch = 1, j.total = n_out, j.f64 = j.res->dtype == XLA_FFI_DataType_F64;
    if (j.nb < 0 || j.nb > MAX_RANK) return NULL;
    for (int64_t d = 0; d < j.nb; d++) j.batch *= j.res->dims[d];
    for (int i = 0; i < n_in; i++) {
        j.in[i] = (const XLA_FFI_Buffer *)call->args.args[i];
        const int64_t ib = j.in[i]->rank - core[i];
        int64_t step = size[i];
        j.shared[i] = 1;
        for (int64_t d = j.nb - 1; d >= 0; d--) {
            const int64_t id = d - (j.nb - ib);
            const int64_t extent = id >= 0 ? j.in[i]->dims[id] : 1;
            j.stride[i][d] = extent == 1 ? 0 : step;
            j.shared[i] &= extent == 1;
            step *= extent;
        }
        j.total += size[i];
    }
    const int64_t chunks = (j.batch + CHUNK - 1) / CHUNK;
    int threads = pool_threads(call, chunks);
    for (int t = 0; t < threads; t++)
        if ((j.buffers[t] = workspace(&j)) == NULL) threads = t;
    if (threads == 0) return NULL;
#ifdef MADV_HUGEPAGE
    {   /* a large result fills fresh pages: ask for 2 MB ones (512 times fewer page faults) */
        const uintptr_t start = (uintptr_t)j.res->data, end = start + (uintptr_t)(j.batch * n_out * (j.f64 ? 8 : 4));
        const uintptr_t lo = (start + (1u << 21) - 1) & ~(uintptr_t)((1u << 21) - 1), hi = end & ~(uintptr_t)((1u << 21) - 1);
        if (hi > lo) madvise((void *)lo, hi - lo, MADV_HUGEPAGE);
    }
#endif
    parallel_for(call, threads, chunks, states, &j);
    for (int t = 0; t < threads; t++) free(j.buffers[t]);
    return NULL;
}
