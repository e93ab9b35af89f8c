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

from ._templates import fill, template

CHUNK = 64
"""States per claim of a quantity handler's batch (a multiple of the kernels' four lanes). A batch of at most
one chunk runs on the calling thread alone."""

BACKWARD_CHUNK = 16
"""States per claim of the backward step's batch (a multiple of its four lanes): a rollout's gradient calls it
once per stage of every step, on batches of tens of states."""

POOL = template("ffi_pool.c")
"""A parallel loop over chunks on XLA's intra-op thread pool (``parallel_for``), for every handler."""

GENERIC = fill(template("ffi_batch.c"), CHUNK=CHUNK)
"""The quantity handlers' batch loop (``run``, after :data:`POOL`), with ``@TRIG_V@`` for the vector sine
and cosine."""

QUANTITY = template("ffi_quantity.c")
"""One quantity's handler around its vector kernel ``<stem>_<name>_V``."""




