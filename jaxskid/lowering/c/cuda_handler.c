/* The XLA FFI handler of jaxskid's CUDA kernels (jaxskid/lowering/_cuda.py): one handler for every kernel. A
   kernel is registered once per process with its compiled image (cubin or PTX) and sizes, and a call names it
   by the attribute `kernel`. The CUDA driver API is opened at run time, so the library builds anywhere. */
#define _POSIX_C_SOURCE 200809L
#define _DEFAULT_SOURCE
#include <dlfcn.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "xla/ffi/api/c_api.h"

typedef int CUresult;
typedef void *CUmodule, *CUfunction, *CUcontext, *CUstream;
typedef unsigned long long CUdeviceptr;

static struct {
    CUresult (*module_load)(CUmodule *, const void *);
    CUresult (*get_function)(CUfunction *, CUmodule, const char *);
    CUresult (*launch)(CUfunction, unsigned, unsigned, unsigned, unsigned, unsigned, unsigned, unsigned, CUstream,
                       void **, void **);
    CUresult (*stream_context)(CUstream, CUcontext *);
    CUresult (*push)(CUcontext);
    CUresult (*pop)(CUcontext *);
    CUresult (*error_string)(CUresult, const char **);
    CUresult (*memset)(void *, unsigned char, size_t, CUstream);
    CUresult (*get_global)(CUdeviceptr *, size_t *, CUmodule, const char *);
    CUresult (*copy)(CUdeviceptr, CUdeviceptr, size_t, CUstream);
} cu;

@JOB@
#define MAX_KERNELS 4096
#define MAX_CONTEXTS 16

typedef struct {
    char *image;
    int n_in, threads, zero_first, constant, columns;
    int64_t size[MAX_IN], core[MAX_IN], n_out, out_rank;
    CUcontext context[MAX_CONTEXTS];
    CUfunction function[MAX_CONTEXTS];
    CUdeviceptr parameters[MAX_CONTEXTS];  /* the module's jaxskid_p in each context (constant >= 0) */
    size_t parameter_bytes[MAX_CONTEXTS];
} entry;

static entry table[MAX_KERNELS];
static int64_t n_kernels;
static pthread_mutex_t lock = PTHREAD_MUTEX_INITIALIZER;

/* Open the driver API; 0 on success. */
static int open_driver(void)
{
    static int state = 0;  /* 0: not tried, 1: open, -1: failed */
    pthread_mutex_lock(&lock);
    if (state == 0) {
        void *h = dlopen("libcuda.so.1", RTLD_NOW | RTLD_GLOBAL);
        state = -1;
        if (h != NULL) {
            *(void **)&cu.module_load = dlsym(h, "cuModuleLoadData");
            *(void **)&cu.get_function = dlsym(h, "cuModuleGetFunction");
            *(void **)&cu.launch = dlsym(h, "cuLaunchKernel");
            *(void **)&cu.stream_context = dlsym(h, "cuStreamGetCtx");
            *(void **)&cu.push = dlsym(h, "cuCtxPushCurrent_v2");
            *(void **)&cu.pop = dlsym(h, "cuCtxPopCurrent_v2");
            *(void **)&cu.error_string = dlsym(h, "cuGetErrorString");
            *(void **)&cu.memset = dlsym(h, "cuMemsetD8Async");
            *(void **)&cu.get_global = dlsym(h, "cuModuleGetGlobal_v2");
            *(void **)&cu.copy = dlsym(h, "cuMemcpyDtoDAsync_v2");
            if (cu.module_load && cu.get_function && cu.launch && cu.stream_context && cu.push && cu.pop && cu.memset
                && cu.get_global && cu.copy)
                state = 1;
        }
    }
    pthread_mutex_unlock(&lock);
    return state == 1 ? 0 : -1;
}

/* Register a kernel: its image (`length` bytes, kept), the entries per state of each input and the trailing
   axes holding them, the result's entries per state and its trailing axes, its threads per block, whether
   the result is zeroed before it runs (it does not write the entries that are always zero), and the input
   copied into the module's constant memory (`jaxskid_p`) before each launch, shared by every state (-1: none),
   and whether it writes its result by entry (columns: the result's first axis is the entries, the batch
   axes follow). Returns its number, or -1. */
int64_t jaxskid_cuda_register(const char *image, int64_t length, int n_in, const int64_t *size, const int64_t *core,
                              int64_t n_out, int64_t out_rank, int threads, int zero_first, int constant,
                              int columns)
{
    if (n_in > MAX_IN || n_in < 1 || constant >= n_in) return -1;
    char *copy = malloc((size_t)length + 1);
    if (copy == NULL) return -1;
    memcpy(copy, image, (size_t)length);
    copy[length] = 0;  /* PTX is read as a string */
    pthread_mutex_lock(&lock);
    int64_t id = n_kernels < MAX_KERNELS ? n_kernels++ : -1;
    if (id >= 0) {
        entry *e = &table[id];
        e->image = copy, e->n_in = n_in, e->n_out = n_out, e->out_rank = out_rank, e->threads = threads;
        e->zero_first = zero_first, e->constant = constant, e->columns = columns;
        for (int i = 0; i < n_in; i++) e->size[i] = size[i], e->core[i] = core[i];
    }
    pthread_mutex_unlock(&lock);
    if (id < 0) free(copy);
    return id;
}

static XLA_FFI_Error *fail(const XLA_FFI_Api *api, const char *what, CUresult status)
{
    static __thread char message[512];
    const char *reason = NULL;
    if (status != 0 && cu.error_string != NULL) cu.error_string(status, &reason);
    snprintf(message, sizeof message, "jaxskid CUDA kernel: %s%s%s", what, reason ? ": " : "", reason ? reason : "");
    XLA_FFI_Error_Create_Args args = {XLA_FFI_Error_Create_Args_STRUCT_SIZE, NULL, message, XLA_FFI_Error_Code_INTERNAL};
    return api->XLA_FFI_Error_Create(&args);
}

/* The kernel's function in `context`, its module loaded there on the first call, and where its constant
   parameters are (`parameters`, `bytes`; untouched where it has none). */
static CUresult function_in(entry *e, CUcontext context, CUfunction *fn, CUdeviceptr *parameters, size_t *bytes)
{
    CUresult status = 0;
    pthread_mutex_lock(&lock);
    int slot = 0;
    while (slot < MAX_CONTEXTS && e->context[slot] != NULL && e->context[slot] != context) slot++;
    if (slot == MAX_CONTEXTS) status = 1;  /* CUDA_ERROR_INVALID_VALUE */
    else if (e->context[slot] != context) {
        CUmodule module;
        CUfunction loaded;
        status = cu.module_load(&module, e->image);
        if (status == 0) status = cu.get_function(&loaded, module, "jaxskid_kernel");
        if (status == 0 && e->constant >= 0)
            status = cu.get_global(&e->parameters[slot], &e->parameter_bytes[slot], module, "jaxskid_p");
        if (status == 0) e->context[slot] = context, e->function[slot] = loaded;
    }
    if (status == 0) *fn = e->function[slot], *parameters = e->parameters[slot], *bytes = e->parameter_bytes[slot];
    pthread_mutex_unlock(&lock);
    return status;
}

static int64_t kernel_attribute(const XLA_FFI_CallFrame *call)
{
    for (int64_t k = 0; k < call->attrs.size; k++) {
        const XLA_FFI_ByteSpan *name = call->attrs.names[k];
        if (call->attrs.types[k] != XLA_FFI_AttrType_SCALAR || name->len != 6 || memcmp(name->ptr, "kernel", 6) != 0)
            continue;
        const XLA_FFI_Scalar *s = (const XLA_FFI_Scalar *)call->attrs.attrs[k];
        if (s->dtype == XLA_FFI_DataType_S64) return *(const int64_t *)s->value;
        if (s->dtype == XLA_FFI_DataType_S32) return *(const int32_t *)s->value;
    }
    return -1;
}

/* The job of one call: the result's leading axes are the batch (by entry: the axes after its first); input
   i's leading axes broadcast against them (right-aligned; an axis of 1, or a missing one, is shared: step 0). */
static int job_of(const XLA_FFI_CallFrame *call, const entry *e, jaxskid_job *j)
{
    XLA_FFI_Buffer *res = (XLA_FFI_Buffer *)call->rets.rets[0];
    const int64_t first = e->columns ? 1 : 0;
    memset(j, 0, sizeof *j);
    j->nb = e->columns ? res->rank - 1 : res->rank - e->out_rank, j->batch = 1, j->out = res->data;
    if (j->nb < 0 || j->nb > MAX_NB) return -1;
    for (int64_t d = 0; d < j->nb; d++) j->dims[d] = res->dims[first + d], j->batch *= res->dims[first + d];
    for (int i = 0; i < e->n_in; i++) {
        const XLA_FFI_Buffer *b = (const XLA_FFI_Buffer *)call->args.args[i];
        if (b->dtype != res->dtype) return -1;
        const int64_t ib = b->rank - e->core[i];
        int64_t step = e->size[i];
        j->in[i] = b->data;
        for (int64_t d = j->nb - 1; d >= 0; d--) {
            const int64_t id = d - (j->nb - ib);
            const int64_t extent = id >= 0 ? b->dims[id] : 1;
            j->stride[i][d] = extent == 1 ? 0 : step;
            step *= extent;
        }
    }
    return 0;
}

@METADATA@
XLA_FFI_Error *jaxskid_cuda_quantity(XLA_FFI_CallFrame *call)
{
    if (metadata(call) || call->stage != XLA_FFI_ExecutionStage_EXECUTE) return NULL;
    const XLA_FFI_Api *api = call->api;
    const int64_t id = kernel_attribute(call);
    if (id < 0 || id >= n_kernels) return fail(api, "no such kernel (the attribute `kernel`)", 0);
    entry *e = &table[id];
    if ((call->args.size != e->n_in && call->args.size != e->n_in + 1) || call->rets.size != 1)
        return fail(api, "wrong number of arguments or results", 0);
    jaxskid_job j;
    if (job_of(call, e, &j) != 0) return fail(api, "unexpected shapes or dtypes", 0);
    if (j.batch == 0) return NULL;
    if (open_driver() != 0) return fail(api, "the CUDA driver (libcuda.so.1) could not be opened", 0);
    XLA_FFI_Stream_Get_Args sa = {XLA_FFI_Stream_Get_Args_STRUCT_SIZE, NULL, call->ctx, NULL};
    XLA_FFI_Error *error = api->XLA_FFI_Stream_Get(&sa);
    if (error != NULL) return error;
    CUstream stream = (CUstream)sa.stream;
    CUcontext context = NULL, previous;
    CUresult status = cu.stream_context(stream, &context);
    if (status != 0) return fail(api, "the stream's context", status);
    if ((status = cu.push(context)) != 0) return fail(api, "making the stream's context current", status);
    CUfunction fn = NULL;
    CUdeviceptr parameters = 0;
    size_t parameter_bytes = 0;
    status = function_in(e, context, &fn, &parameters, &parameter_bytes);
    if (status == 0 && e->constant >= 0) {
        /* The parameters, shared by every state, into constant memory on the same stream: the launch that reads
           them follows, and a later call's copy waits for it (XLA's calls of a program share one stream). */
        const XLA_FFI_Buffer *b = (const XLA_FFI_Buffer *)call->args.args[e->constant];
        const size_t bytes = (size_t)e->size[e->constant] * (b->dtype == XLA_FFI_DataType_F64 ? 8 : 4);
        for (int64_t d = 0; d < j.nb; d++)
            if (j.stride[e->constant][d] != 0) {
                cu.pop(&previous);
                return fail(api, "the parameters differ between states, and this kernel reads one set", 0);
            }
        status = bytes <= parameter_bytes ? cu.copy(parameters, (CUdeviceptr)b->data, bytes, stream) : 1;
    }
    if (status == 0 && e->zero_first) {
        const size_t bytes = (size_t)j.batch * (size_t)e->n_out
                             * (((XLA_FFI_Buffer *)call->rets.rets[0])->dtype == XLA_FFI_DataType_F64 ? 8 : 4);
        status = cu.memset(j.out, 0, bytes, stream);
    }
    if (status == 0) {
        const long long blocks = (j.batch + e->threads - 1) / e->threads;
        void *params[] = {&j};
        status = cu.launch(fn, (unsigned)blocks, 1, 1, (unsigned)e->threads, 1, 1, 0, stream, params, NULL);
    }
    cu.pop(&previous);
    return status == 0 ? NULL : fail(api, "loading or launching the kernel", status);
}
