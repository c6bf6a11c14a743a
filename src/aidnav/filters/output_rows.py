"""The engine's per-sample output rows (state, biases, P's diagonal) in one block the caller allocates.

A whole-log run writes ~70 values per IMU sample (the walk's tight run: 20,455 × (10 + 24 + 33) doubles,
11 MB). Allocated inside the kernel (numba's allocator, glibc's malloc: fresh mmap'd memory), every 4 KiB
page of it is first touched by a page fault: 2,300 faults, ~20 % of the tight run's CPU time on the shared
machine (issue 40, session 15). Allocated by the caller as one numpy block, numpy advises the kernel to back
it with huge pages (from 4 MiB on, ``madvise(MADV_HUGEPAGE)``; the machine's THP mode is ``madvise``): the
same first touch in 2 MiB pages, a handful of faults. :func:`whole_run_rows` makes the block (C-contiguous
views, one per output), :func:`output_rows` (in the kernel) takes it where it fits the run and allocates as
before where it does not (a streamed chunk, another shape, none given: :data:`NO_ROWS`). The numbers
written are the same either way.
"""

from __future__ import annotations

import numpy as np

from aidnav.jit import njit

HUGE = 2 << 20  # bytes of a huge page (x86-64)
#: ``Output.rows`` of a run that allocates its outputs in the kernel (state, biases, P's diagonal)
NO_ROWS = (np.empty((0, 10)), np.empty((0, 1)), np.empty((0, 1)))


def whole_run_rows(n_out: int, nb: int, n: int) -> tuple:
    """The output rows of a whole-log run with ``n_out`` outputs, ``nb`` bias columns (``max(n_b, 1)``) and
    ``n`` states: views (n_out, 10), (n_out, nb), (n_out, n) of one block."""
    size = n_out * (10 + nb + n)
    raw = np.empty(size + HUGE // 8)  # one block: numpy advises huge pages for it (from 4 MiB on) …
    o = (-raw.ctypes.data % HUGE) // 8 if raw.ctypes.data % 8 == 0 else 0
    buf = raw[o:o + size]  # … and it starts on a huge page's boundary (the 2 MiB before it never touched)
    a, b = n_out * 10, n_out * (10 + nb)
    return buf[:a].reshape(n_out, 10), buf[a:b].reshape(n_out, nb), buf[b:].reshape(n_out, n)


@njit(cache=True)
def output_rows(rows, whole, n_out, nb, n):
    """(state, biases, P's diagonal) output arrays of a chunk: the caller's ``rows`` where the chunk is the
    whole log (``whole``) and their shapes are (n_out, 10), (n_out, nb), (n_out, n); else new arrays."""
    st, b, pd = rows
    if (whole and st.shape[0] == n_out and b.shape[0] == n_out and pd.shape[0] == n_out and st.shape[1] == 10
            and b.shape[1] == nb and pd.shape[1] == n):
        return st, b, pd
    return np.empty((n_out, 10)), np.empty((n_out, nb)), np.empty((n_out, n))
