"""`--method paper`: the OS-Map exactly as published, one node per output pixel.

The model vector of each node is an exemplar position; inputs are exemplar positions drawn
uniformly; the winner is searched in a random window of the exemplar's extent (scale); the
update uses the paper's per-component anisotropic kernel (row varies along the output's rows,
column along its columns) and schedule. No coherent targets, no range kernel, no refinement:
expect the mirror folds and warps the paper's formulation produces.
"""

from __future__ import annotations

import numpy as np

from osmap_cli.engine import Orientation, OSMap, Schedule
from osmap_cli.synth.options import SynthOptions
from osmap_cli.synth.organise import exemplar_positions, search_window

PAPER_STEPS_PER_NODE = 10
PAPER_SCHEDULE = Schedule(alpha_max=0.5, alpha_min=0.01, sigma_max=4.0, sigma_min=0.5)


def synthesize_paper(exemplar_shape, opts: SynthOptions, progress=None) -> np.ndarray:
    """float32 (H, W, 2) position field learned by the published OS-Map."""
    out_shape = (opts.height, opts.width)
    jac = opts.jacobian()
    lo = np.zeros(2)
    hi = np.array(exemplar_shape, np.float64) - 1
    data = exemplar_positions(lo, hi)
    theta = np.arctan2(jac[:, 1], jac[:, 0])
    a = opts.som_anisotropy
    som = OSMap(out_shape, 2, wrap=(opts.tileable, opts.tileable),
                window=search_window(exemplar_shape, out_shape, jac, opts.window_scale),
                orientation=Orientation.angles(theta, [[1.0, a], [1.0, a]]))
    som.init_random(data, seed=opts.seed)
    steps = PAPER_STEPS_PER_NODE * som.size

    class _Fraction:
        def update(self, n):
            if progress is not None:
                progress(n / steps)

    som.train(data, steps, schedule=PAPER_SCHEDULE, seed=opts.seed + 1, progress=_Fraction())
    return som.grid_weights().astype(np.float32)
