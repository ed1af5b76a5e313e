"""The synthesis' helper thread (osmap_cli.synth.ahead): the same tables as computed in turn, on
no more threads than its caller's."""

import os
import subprocess
import sys

import numpy as np

from osmap_cli.synth.ahead import LevelsAhead, level_inputs
from osmap_cli.synth.options import SynthOptions


def test_tables_computed_ahead_are_the_ones_computed_in_turn():
    opts = SynthOptions(width=32, height=32).validated()
    rng = np.random.default_rng(3)
    images = [rng.random((24, 24, 3), dtype=np.float32), rng.random((12, 12, 3), dtype=np.float32)]
    boxes = [(np.array([2.0, 2.0]), np.array([21.0, 21.0])),
             (np.array([2.0, 2.0]), np.array([9.0, 9.0]))]
    ahead = LevelsAhead(opts)
    try:
        for level in (1, 0):
            ahead.submit(level, images[level], *boxes[level])
        ahead.load_kernels()
        for level in (1, 0):
            feat, knn = ahead.take(level)
            want_feat, want_knn = level_inputs(images[level], *boxes[level], opts)
            assert feat.tobytes() == want_feat.tobytes()
            assert knn.tobytes() == want_knn.tobytes() and knn.dtype == want_knn.dtype
    finally:
        ahead.close()


def test_the_helper_uses_its_callers_thread_count():
    code = """
import numba
from numba.np.ufunc import parallel
parallel._launch_threads()
numba.set_num_threads(2)  # as a cluster job does
from osmap_cli.synth.ahead import LevelsAhead
from osmap_cli.synth.options import SynthOptions
from osmap_kernels.bands import thread_count
one = LevelsAhead(SynthOptions())
print(thread_count(), one._pool.submit(thread_count).result())
one.close()
numba.set_num_threads(1)
print(LevelsAhead(SynthOptions())._pool is None)  # one thread: everything in turn, no helper
"""
    env = dict(os.environ, NUMBA_NUM_THREADS="3")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["2", "2", "True"]


def test_bands_on_this_thread_run_as_one_band_with_the_same_result():
    import threading

    from osmap_kernels.bands import on_this_thread, run_bands

    calls = []

    def kernel(out, y0, y1):
        calls.append((threading.get_ident(), y0, y1))
        out[y0:y1] = np.arange(y0, y1)

    spread, inline = np.zeros(40), np.zeros(40)
    run_bands(kernel, 40, spread)
    banded = len(calls)
    calls.clear()
    with on_this_thread():
        run_bands(kernel, 40, inline)
    assert calls == [(threading.get_ident(), 0, 40)]
    assert inline.tobytes() == spread.tobytes() == np.arange(40.0).tobytes()
    run_bands(kernel, 40, inline)  # outside it, bands again (as many as before)
    assert len(calls) == 1 + banded
    training = [True]
    with on_this_thread(lambda: training[0]):  # only while its condition holds
        run_bands(kernel, 40, inline)
        assert len(calls) == 2 + banded
        training[0] = False
        run_bands(kernel, 40, inline)
    assert len(calls) == 2 + 2 * banded


def test_work_done_meanwhile_gives_its_result_or_raises_its_error():
    from osmap_cli.synth.ahead import Meanwhile

    assert Meanwhile(sum, [1, 2, 3]).result() == 6
    failing = Meanwhile(int, "not a number")
    for _ in range(2):  # the same error each time it is asked for
        try:
            failing.result()
        except ValueError as exc:
            assert "not a number" in str(exc)
        else:
            raise AssertionError("no error")


def test_a_lattice_found_meanwhile_is_the_one_found_first():
    """The automatic lattice, found while the OS-Map trains, gives the bytes of a run that
    found it before (the lattice given by hand, as found)."""
    from osmap_cli.synth.lattice import find_lattice
    from osmap_cli.synth.pipeline import synthesize

    y, x = np.mgrid[0:48, 0:48]
    rng = np.random.default_rng(5)
    tile = rng.random((8, 6, 3)).astype(np.float32)
    exemplar = tile[y % 8, x % 6] + 0.05 * rng.random((48, 48, 3)).astype(np.float32)
    found = find_lattice(exemplar)
    assert found is not None
    opts = SynthOptions(width=40, height=40, seed=2)
    auto = synthesize(exemplar, opts)
    assert auto.lattice is not None and auto.lattice.vectors == found.vectors
    from osmap_cli.synth import pipeline

    given = pipeline._lattice
    try:  # the lattice resolved up front, as a lattice given by hand is
        pipeline_opts = opts.replace(lattice="off")
        pipeline._lattice = lambda *args: found
        first = synthesize(exemplar, pipeline_opts)
    finally:
        pipeline._lattice = given
    assert first.pixels.tobytes() == auto.pixels.tobytes()
    assert first.positions.tobytes() == auto.positions.tobytes()
