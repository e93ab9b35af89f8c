"""What writing a batched result costs on this machine, before any arithmetic: the floor under a large
matrix-valued quantity.

    python benchmarks/memory_floor.py [--entries 8410] [--batch 4096] [--threads 2] [--repeats 10] [--markdown PATH]

A batch of the G1's regressors (29 x 290 = 8,410 doubles per state) is 275 MB. XLA gives each call's result
fresh memory, which the operating system maps and zeroes page by page on first write; Pinocchio's
``computeJointTorqueRegressor`` writes into the same matrix at every call. A small C program (built here with
the system compiler) writes such a batch, the work shared by ``--threads`` threads as the native kernels
share theirs, and prints the time per state:

- into fresh memory (allocated and freed at each repetition, as XLA's result buffers are), with and
  without 2 MB pages (which the kernels ask for), by ``memset`` and by streaming stores;
- into memory written before (reused), by ``memset``.

``--entries`` and ``--batch`` set the size (the defaults are the G1's regressor at the scaling benchmark's
batch). Medians of ``--repeats``.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import tempfile
from pathlib import Path

import doc_tables  # benchmarks/doc_tables.py, beside this script

SOURCE = r"""
#define _GNU_SOURCE
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

static char *buf;
static size_t bytes;
static int threads, stream;

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static void *fill(void *arg)
{
    const long k = (long)arg;
    const size_t share = (bytes / threads) & ~(size_t)63;
    char *p = buf + k * share;
    const size_t n = k == threads - 1 ? bytes - k * share : share;
#if defined(__SSE2__)
    if (stream) {
        const __m128i one = _mm_set1_epi8(1);
        for (size_t i = 0; i + 16 <= n; i += 16) _mm_stream_si128((__m128i *)(p + i), one);
        _mm_sfence();
        return NULL;
    }
#endif
    memset(p, 1, n);
    return NULL;
}

static int cmp(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* argv: bytes threads repeats fresh huge stream -> prints the median seconds of one batch */
int main(int argc, char **argv)
{
    if (argc != 7) return 2;
    bytes = strtoull(argv[1], NULL, 10), threads = atoi(argv[2]);
    const int repeats = atoi(argv[3]), fresh = atoi(argv[4]), huge = atoi(argv[5]);
    stream = atoi(argv[6]);
    double *t = malloc(sizeof(double) * repeats);
    if (!fresh) {
        buf = aligned_alloc(1 << 21, (bytes + (1 << 21) - 1) & ~(size_t)((1 << 21) - 1));
        memset(buf, 0, bytes);
    }
    for (int r = 0; r < repeats; r++) {
        const double start = now();
        if (fresh) {
            buf = aligned_alloc(1 << 21, (bytes + (1 << 21) - 1) & ~(size_t)((1 << 21) - 1));
#ifdef MADV_HUGEPAGE
            if (huge) madvise(buf, bytes & ~(size_t)((1 << 21) - 1), MADV_HUGEPAGE);
#endif
        }
        pthread_t th[64];
        for (long k = 0; k < threads; k++) pthread_create(&th[k], NULL, fill, (void *)k);
        for (int k = 0; k < threads; k++) pthread_join(th[k], NULL);
        if (fresh) free(buf);
        t[r] = now() - start;
    }
    qsort(t, repeats, sizeof(double), cmp);
    printf("%.9f\n", t[repeats / 2]);
    return 0;
}
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--entries", type=int, default=29 * 290, help="doubles per state")
    parser.add_argument("--batch", type=int, default=4096)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=10)
    doc_tables.add_option(parser)
    args = parser.parse_args()
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        raise SystemExit("memory_floor.py needs a C compiler (apt-get install gcc)")
    nbytes = args.entries * 8 * args.batch
    with tempfile.TemporaryDirectory() as tmp:
        exe = Path(tmp) / "floor"
        (Path(tmp) / "floor.c").write_text(SOURCE)
        subprocess.run([cc, "-O2", "-pthread", "-o", str(exe), str(Path(tmp) / "floor.c")], check=True)
        print(f"{args.batch} states x {args.entries} doubles = {nbytes / 1e6:.0f} MB a batch, "
              f"{args.threads} thread(s), medians of {args.repeats}")
        rows = []
        for fresh, huge, stream, label in [(1, 0, 0, "fresh, 4 KB pages"), (1, 1, 0, "fresh, 2 MB pages"),
                                           (1, 1, 1, "fresh, 2 MB pages"), (0, 0, 0, "reused")]:
            out = subprocess.run([str(exe), str(nbytes), str(args.threads), str(args.repeats), str(fresh),
                                  str(huge), str(stream)], check=True, capture_output=True, text=True).stdout
            per_state = float(out) / args.batch * 1e6
            rows.append([label, "streaming stores" if stream else "memset", f"{per_state:.2f} µs"])
    lines = doc_tables.table(["memory", "write", "per state"], rows)
    print("\n".join(lines))
    doc_tables.write(args.markdown, lines, f"{args.batch} states of {args.entries} doubles ({nbytes / 1e6:.0f} MB a "
                     f"batch), {args.threads} thread(s), medians of {args.repeats}.")


if __name__ == "__main__":
    main()
