"""Row bands: run a plain `@njit(nogil=True)` kernel over the rows of an output on a pool of
Python threads, instead of a `parallel=True` (parfors) kernel, which compiles several times
slower. A kernel run this way takes its row range (y0, y1) as its last two arguments and writes
only those rows, each from inputs it does not write: the result is the same bytes whatever the
thread count or the order the bands run in.

The thread count is Numba's: numba.get_num_threads() once Numba's threading layer is up (an
osmap_cli.cluster worker sets it per job), else NUMBA_NUM_THREADS (all cores by default). A
thread inside `on_this_thread()` runs its bands itself, as one band.
"""

from __future__ import annotations

import contextlib
import threading
from concurrent.futures import ThreadPoolExecutor

BANDS_PER_THREAD = 4  # more bands than threads: uneven rows still share out evenly

_pool = None
_pool_size = 0
_lock = threading.Lock()
_local = threading.local()


def thread_count() -> int:
    import numba
    from numba.np.ufunc import parallel

    if parallel._is_initialized:
        return max(1, numba.get_num_threads())
    return max(1, numba.config.NUMBA_NUM_THREADS)


def _executor(size: int) -> ThreadPoolExecutor:
    global _pool, _pool_size
    with _lock:
        if _pool is None or _pool_size < size:
            if _pool is not None:
                _pool.shutdown(wait=False)
            _pool = ThreadPoolExecutor(size, thread_name_prefix="osmap-band")
            _pool_size = size
        return _pool


def band_ranges(rows: int, threads: int) -> list[tuple[int, int]]:
    """[(y0, y1), ...]: `rows` rows cut into contiguous bands, about BANDS_PER_THREAD per
    thread (one band for one thread)."""
    count = 1 if threads <= 1 else min(rows, threads * BANDS_PER_THREAD)
    count = max(count, 1)
    edges = [rows * i // count for i in range(count + 1)]
    return [(a, b) for a, b in zip(edges, edges[1:]) if b > a]


def _always() -> bool:
    return True


@contextlib.contextmanager
def on_this_thread(while_=_always):
    """Within it, run_bands called on this thread runs the kernel over all rows itself (one
    band) whenever `while_()` is true at the call: for a helper thread's work beside a main
    thread that computes on one core, which would otherwise share that core with the band
    threads. The same bytes (see above)."""
    before = getattr(_local, "inline", None)
    _local.inline = while_
    try:
        yield
    finally:
        _local.inline = before


def run_bands(kernel, rows: int, *args) -> None:
    """kernel(*args, y0, y1) for every band of `rows` rows, on thread_count() threads (one
    band on the calling thread inside on_this_thread(), while its condition holds)."""
    inline = getattr(_local, "inline", None)
    threads = 1 if inline is not None and inline() else thread_count()
    bands = band_ranges(rows, threads)
    if len(bands) <= 1:
        for y0, y1 in bands:
            kernel(*args, y0, y1)
        return
    if not getattr(kernel, "signatures", True):
        # first call: compile or load it in this thread alone, not in every thread at once
        (y0, y1), bands = bands[0], bands[1:]
        kernel(*args, y0, y1)
    pool = _executor(threads)
    for future in [pool.submit(kernel, *args, y0, y1) for y0, y1 in bands]:
        future.result()
