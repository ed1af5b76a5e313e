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
