
#define _POSIX_C_SOURCE 200112L
#define _DEFAULT_SOURCE
#include <math.h>
#include <stdint.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include "xla/ffi/api/c_api.h"
#include "@STEM@.@INCLUDE@"  /* the scalar C where a kernel calls it (one translation unit), else its macros */

#define N @STEM_UPPER@_NV  /* the velocity coordinates: n, or 6 + n with a floating base */
#define NQ @STEM_UPPER@_NQ /* the configuration: n, or 7 + n */
#define NP @STEM_UPPER@_N_PARAMS
#define NP1 (NP > 0 ? NP : 1)

static int64_t numel(const XLA_FFI_Buffer *b)
{
    int64_t n = 1;
    for (int64_t i = 0; i < b->rank; i++) n *= b->dims[i];
    return n;
}

static double load(const XLA_FFI_Buffer *b, int64_t i)
{
    return b->dtype == XLA_FFI_DataType_F64 ? ((const double *)b->data)[i] : ((const float *)b->data)[i];
}

static void store(XLA_FFI_Buffer *b, int64_t i, double x)
{
    if (b->dtype == XLA_FFI_DataType_F64) ((double *)b->data)[i] = x;
    else ((float *)b->data)[i] = (float)x;
}

@METADATA@