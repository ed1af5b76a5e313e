"""The OS-Map's layout of the coarsest volume: three exemplar positions per voxel, one per slice
family, laid out so that each family's positions run coherently inside its slices.

The model vector is in R^6: one (row, col) pair per axis, each pair's kernel broad inside its
own slice plane and zero across it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_cli.engine import Orientation, OSMap, Schedule
from osmap_cli.solid.core import SolidLevel
from osmap_kernels.solid import PLANE

ACROSS = 1.0e4  # OS-Map kernel weight across a component's slice plane: no update there
NORMAL_DIM = (2, 1, 0)  # volume dim (z, y, x order) normal to axis x, y, z


@dataclass(frozen=True)
class Layout:
    """The OS-Map's training (SolidOptions som_*)."""

    steps_per_node: float  # training steps per coarsest voxel
    sigma_max: float  # initial neighbourhood radius, voxels
    anisotropy: float  # kernel weight across / along each component, inside its plane


def organise(level: SolidLevel, ex_of_axis, layout: Layout, *, tileable: bool,
             seed: int) -> np.ndarray:
    """int32 (3, Z, Y, X, 2): the OS-Map's layout of three positions per voxel of the level's
    volume, inside the level's valid bounds.

    Component (a, j) (axis a's exemplar row j=0 / column j=1) varies along volume dim
    PLANE[a, j], `anisotropy` times as steeply along the other in-plane dim, and not at all
    across the plane; its coherent target is x + (offset along PLANE[a, j]).
    """
    shape, lo, hi = level.shape, level.lo, level.hi
    weights = np.zeros((6, 3))
    jac = np.zeros((6, 3))
    bounds = np.zeros((6, 2))
    for a in range(3):
        e = ex_of_axis[a]
        for j in range(2):
            k = 2 * a + j
            weights[k, PLANE[a, j]] = 1.0
            weights[k, PLANE[a, 1 - j]] = layout.anisotropy
            weights[k, NORMAL_DIM[a]] = ACROSS
            jac[k, PLANE[a, j]] = 1.0
            bounds[k] = (lo[e, j], hi[e, j])
    extent = min(min(s) for s in level.ex_shapes)
    window = tuple(min(s, extent) for s in shape)
    som = OSMap(shape, 6, wrap=(tileable,) * 3, window=window,
                orientation=Orientation.axis_aligned(weights), target_jacobian=jac,
                range_kernel=(2.0, 1.0), bounds=bounds)
    rng = np.random.default_rng(seed)
    count = max(4096, 4 * som.size)
    data = np.empty((count, 6))
    for k in range(6):
        data[:, k] = rng.integers(bounds[k, 0], bounds[k, 1] + 1, count)
    som.init_random(data, seed=seed)
    steps = int(layout.steps_per_node * som.size)
    if steps:
        schedule = Schedule(alpha_max=0.5, alpha_min=0.05, sigma_max=layout.sigma_max,
                            sigma_min=0.3)
        som.train(data, steps, schedule=schedule, seed=seed + 1)
    grid = np.rint(som.grid_weights()).reshape(*shape, 3, 2)
    pos = np.moveaxis(grid, 3, 0)
    for a in range(3):
        e = ex_of_axis[a]
        for j in range(2):
            pos[a, ..., j] = np.clip(pos[a, ..., j], lo[e, j], hi[e, j])
    return np.ascontiguousarray(pos.astype(np.int32))
