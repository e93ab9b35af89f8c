
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
