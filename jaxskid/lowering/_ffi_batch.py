"""The handlers' batches on XLA's intra-op thread pool, and the batch loop of the quantity handlers of
:mod:`._ffi`.

XLA on CPU spreads a large elementwise program over its intra-op thread pool; a handler is one call on one
thread unless it hands work to that pool itself (``XLA_FFI_ThreadPool_Schedule`` of the FFI's C API).
``parallel_for`` (:data:`POOL`) splits a batch into chunks, schedules one helper task per further thread of
the pool, and works through the chunks beside them, each thread taking the next unclaimed chunk (an atomic
counter). It returns when every chunk is done and waits for no task that has not started: the pool may run
its tasks late, on the calling thread, or on one thread only (the API promises nothing else), so a task
that starts after the work is gone finds no chunk left, and the last holder of the shared counters frees
them. The quantity handlers (:data:`GENERIC`) take chunks of :data:`CHUNK` states, the backward step of
forward dynamics chunks of :data:`BACKWARD_CHUNK`.
"""

from __future__ import annotations

CHUNK = 64
"""States per claim of a quantity handler's batch (a multiple of the kernels' four lanes). A batch of at most
one chunk runs on the calling thread alone."""

BACKWARD_CHUNK = 16
"""States per claim of the backward step's batch (a multiple of its four lanes): a rollout's gradient calls it
once per stage of every step, on batches of tens of states."""

POOL = r"""
#include <sched.h>
#include <stdatomic.h>
#define MAX_THREADS 64

/* The counters of one parallel loop, shared by the calling thread and the pool's tasks; the last holder
   frees them. Everything else (the batch, the workspaces) is the caller's: a task touches it only for a
   chunk it claimed, and the caller returns only when every claimed chunk is done. */
typedef struct {
    atomic_llong next, done, slot;  /* the next chunk to claim; chunks finished; the next free workspace */
    atomic_int holders;
    int64_t chunks;
    void (*chunk)(void *ctx, int64_t c, int slot);
    void *ctx;
} pool_job;

/* Compute chunk c, then claim and compute chunks until none is left, with workspace `slot`. */
static void pool_work(pool_job *j, int64_t c, int slot)
{
    for (; c < j->chunks; c = atomic_fetch_add(&j->next, 1)) {
        j->chunk(j->ctx, c, slot);
        atomic_fetch_add(&j->done, 1);
    }
}

static void pool_release(pool_job *j)
{
    if (atomic_fetch_sub(&j->holders, 1) == 1) free(j);
}

static void pool_task(void *data)
{
    pool_job *j = (pool_job *)data;
    const int64_t c = atomic_fetch_add(&j->next, 1);
    if (c < j->chunks) pool_work(j, c, (int)atomic_fetch_add(&j->slot, 1));
    pool_release(j);
}

static void destroy(XLA_FFI_CallFrame *call, XLA_FFI_Error *err)
{
    XLA_FFI_Error_Destroy_Args args = {XLA_FFI_Error_Destroy_Args_STRUCT_SIZE, NULL, err};
    call->api->XLA_FFI_Error_Destroy(&args);
}

/* The threads of XLA's intra-op pool, at most `limit` (1 where the runtime offers none). */
static int pool_threads(XLA_FFI_CallFrame *call, int64_t limit)
{
    const XLA_FFI_Api *api = call->api;
    if (limit <= 1 || api == NULL || api->struct_size < XLA_FFI_STRUCT_SIZE(XLA_FFI_Api, XLA_FFI_ThreadPool_NumThreads)
        || api->XLA_FFI_ThreadPool_NumThreads == NULL || api->XLA_FFI_ThreadPool_Schedule == NULL)
        return 1;
    int64_t n = 1;
    XLA_FFI_ThreadPool_NumThreads_Args args = {XLA_FFI_ThreadPool_NumThreads_Args_STRUCT_SIZE, NULL, call->ctx, &n};
    XLA_FFI_Error *err = api->XLA_FFI_ThreadPool_NumThreads(&args);
    if (err != NULL) {
        destroy(call, err);
        return 1;
    }
    n = n < limit ? n : limit;
    return n < 1 ? 1 : n > MAX_THREADS ? MAX_THREADS : (int)n;
}

/* chunk(ctx, c, slot) for every c in [0, chunks), on the calling thread and `threads` - 1 tasks of the pool
   (slot: which of `threads` workspaces the running thread owns). Returns when every chunk is done. */
static void parallel_for(XLA_FFI_CallFrame *call, int threads, int64_t chunks,
                         void (*chunk)(void *, int64_t, int), void *ctx)
{
    pool_job *j = threads > 1 && chunks > 1 ? (pool_job *)calloc(1, sizeof(pool_job)) : NULL;
    if (j == NULL) {
        for (int64_t c = 0; c < chunks; c++) chunk(ctx, c, 0);
        return;
    }
    j->chunks = chunks, j->chunk = chunk, j->ctx = ctx;
    atomic_init(&j->next, 1);  /* chunk 0 is the caller's */
    atomic_init(&j->done, 0);
    atomic_init(&j->slot, 1);
    atomic_init(&j->holders, threads);
    for (int h = 1; h < threads; h++) {
        XLA_FFI_ThreadPool_Schedule_Args args = {XLA_FFI_ThreadPool_Schedule_Args_STRUCT_SIZE, NULL, call->ctx,
                                                 pool_task, j};
        XLA_FFI_Error *err = call->api->XLA_FFI_ThreadPool_Schedule(&args);
        if (err != NULL) {
            destroy(call, err);
            pool_release(j);
        }
    }
    pool_work(j, 0, 0);
    while (atomic_load(&j->done) < chunks) sched_yield();  /* chunks other threads claimed */
    pool_release(j);
}
"""
"""A parallel loop over chunks on XLA's intra-op thread pool (``parallel_for``), for every handler."""


GENERIC = r"""
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
""".replace("@CHUNK@", str(CHUNK))
"""The quantity handlers' batch loop (``run``, after :data:`POOL`), with ``@TRIG_V@`` for the vector sine
and cosine."""

QUANTITY = r"""
static void call_@NAME@(const V *const *x, V *out) { @STEM@_@NAME@_V(@ARGS@, out); }
static const int64_t size_@NAME@[] = {@SIZES@}, core_@NAME@[] = {@CORES@};
@NONZERO@
XLA_FFI_Error *jaxskid_@NAME@(XLA_FFI_CallFrame *call)
{
    return run(call, @N_IN@, size_@NAME@, core_@NAME@, @N_OUT@, @OUT_RANK@, call_@NAME@, @NZ@, @N_NZ@);
}
"""
"""One quantity's handler around its vector kernel ``<stem>_<name>_V``."""
