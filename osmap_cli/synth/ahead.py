"""The exemplar's side of each pyramid level (its appearance features and k-NN table) computed
on a helper thread, ahead of the refinement that uses it.

Both depend on the exemplar's level and its valid box alone, not on the output, so every level's
is submitted at the start, coarsest first: they are computed while the main thread trains the
OS-Map (the coarsest level), then refines and aligns the coarser levels. The training and the
alignment run on one core; the helper takes the other: while the OS-Map trains, its k-NN
kernel's row bands run on the helper itself (osmap_kernels.bands.on_this_thread), one core each,
and the finer levels' tables are mostly computed then, when that core would otherwise wait;
afterwards its bands share the band threads with the refinement's. The same values whichever
thread computes them (the k-NN kernel's row bands write disjoint rows; the features' BLAS is
single-threaded), so the same bytes; with one thread (`NUMBA_NUM_THREADS=1`, a cluster worker's
share) everything is computed in turn, on the caller's thread, when it is taken.

Right after the coarsest level's, the helper also loads the kernels that the refinement and the
render call (`load_kernels`), from Numba's cache, while the main thread trains the OS-Map: else
the main thread loads each at its first call (about 0.05 s of a 256x256 run's wall time).

    ahead = LevelsAhead(opts)
    ahead.submit(level, image, lo, hi)       # every level, coarsest first
    ahead.load_kernels()                     # after the coarsest (threaded only)
    ahead.trained()                          # once the coarsest level's OS-Map is trained
    feat, knn = ahead.take(level)            # when its refinement starts
    ahead.close()                            # in a finally: drops what was not taken
"""

from __future__ import annotations

import threading
from concurrent.futures import Future, ThreadPoolExecutor

from osmap_cli.synth.options import SynthOptions
from osmap_cli.synth.refine import knn_candidates
from osmap_cli.texture.features import appearance_features
from osmap_kernels.bands import on_this_thread, thread_count


def level_inputs(image, lo, hi, opts: SynthOptions):
    """(features, k-NN table) of one exemplar level, as refine() takes them."""
    feat = appearance_features([image], opts.feature_dims)[0]
    return feat, knn_candidates(feat, lo, hi, opts)


def _on_helper(image, lo, hi, opts: SynthOptions, training):
    """level_inputs on the helper thread; while `training()` (the main thread trains the
    OS-Map on one core) its k-NN bands run on the helper itself, so that the two take a core
    each, and afterwards on the band threads, beside the refinement's."""
    with on_this_thread(training):
        return level_inputs(image, lo, hi, opts)


def load_kernels() -> None:
    """Load the refinement's and the render's kernels (a tiny run with a real run's argument
    types: osmap_cli.synth.warm). Only a head start: whatever goes wrong here goes wrong again,
    and is reported, where the run calls them."""
    import numpy as np

    from osmap_cli.synth.render import render
    from osmap_cli.synth.warm import compile_group

    try:
        compile_group("refine")
        pos = np.full((8, 8, 2), 4.0, np.float32)
        render(np.zeros((16, 16, 3), np.float32), pos, None, False, 2)
    except Exception:  # noqa: BLE001, S110 - see the docstring
        pass


def _same_threads(threads: int) -> None:
    """The helper's row bands on as many threads as its caller's: Numba's thread count is per
    thread once its threading layer is up (a cluster job sets it, osmap_cli.cluster)."""
    from numba.np.ufunc import parallel

    if parallel._is_initialized:
        import numba

        numba.set_num_threads(threads)


class Meanwhile:
    """fn(*args) on a thread of its own, started now (inline at result() with one thread):
    for work the main thread needs later than it can start it, such as the exemplar's lattice,
    which the coarsest level's OS-Map does not use. result() returns or raises what fn did."""

    def __init__(self, fn, *args):
        self._fn, self._args = fn, args
        self._outcome = None
        self._thread = None
        if thread_count() > 1:
            self._thread = threading.Thread(target=self._run, name="osmap-meanwhile",
                                            daemon=True)
            self._thread.start()

    def _run(self):
        try:
            self._outcome = (True, self._fn(*self._args))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller by result()
            self._outcome = (False, exc)

    def result(self):
        if self._thread is not None:
            self._thread.join()
        elif self._outcome is None:
            self._run()
        done, value = self._outcome
        if not done:
            raise value
        return value


class LevelsAhead:
    """Features and k-NN tables of levels submitted in the order they are needed (see the module
    docstring)."""

    def __init__(self, opts: SynthOptions):
        self._opts = opts
        self._pending: dict[int, Future | tuple] = {}
        self._training = threading.Event()  # set until the coarsest level's OS-Map is trained
        self._training.set()
        threads = thread_count()
        self._pool = (ThreadPoolExecutor(1, thread_name_prefix="osmap-ahead",
                                         initializer=_same_threads, initargs=(threads,))
                      if threads > 1 else None)

    def submit(self, level: int, image, lo, hi) -> None:
        if self._pool is None:
            self._pending[level] = (image, lo, hi)
        else:
            self._pending[level] = self._pool.submit(_on_helper, image, lo, hi, self._opts,
                                                     self._training.is_set)

    def load_kernels(self) -> None:
        if self._pool is not None:
            self._pool.submit(load_kernels)

    def trained(self) -> None:
        """The main thread has trained the OS-Map: the helper's bands go back to the band
        threads."""
        self._training.clear()

    def take(self, level: int):
        """(feat, knn) of a submitted level."""
        work = self._pending.pop(level)
        if isinstance(work, Future):
            return work.result()
        return level_inputs(*work, self._opts)

    def close(self) -> None:
        self._pending.clear()
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
