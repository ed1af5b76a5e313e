"""The least any Numba program pays at start: Python, numpy and Numba imported, one cached
kernel loaded and called once (a plain `@njit(nogil=True)` kernel, the kind `osmap synth` runs),
then an exit without the interpreter's teardown, as the `osmap` command ends. bench_peer.py runs
it against the peer to show the part of osmap's wall time that no change inside osmap can
remove.

    python bench/numba_floor.py
"""

import os

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def add_one(values):
    out = np.empty_like(values)
    for i in range(values.shape[0]):
        out[i] = values[i] + 1.0
    return out


if __name__ == "__main__":
    add_one(np.zeros(4))
    os._exit(0)
