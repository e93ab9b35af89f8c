#define MAX_IN 8
#define MAX_NB 6
/* One call: the inputs, each one's step in entries along each batch axis (0: shared), the batch axes, the
   number of states and the result. The handler (cuda_handler.c) fills the same struct. */
typedef struct {
    const void *in[MAX_IN];
    long long stride[MAX_IN][MAX_NB];
    long long dims[MAX_NB];
    long long nb, batch;
    void *out;
} jaxskid_job;
