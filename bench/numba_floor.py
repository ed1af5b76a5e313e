"""The least any Numba program pays at start: Python, numpy and Numba imported, one cached
kernel (parallel, like osmap's) loaded and called once. bench_peer.py runs it against the peer
to show the part of osmap's wall time that no change inside osmap can remove.

    python bench/numba_floor.py
"""

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def add_one(values):
    out = np.empty_like(values)
    for i in prange(values.shape[0]):
        out[i] = values[i] + 1.0
    return out


if __name__ == "__main__":
    add_one(np.zeros(4))
