"""Laguerre (power) tessellations: every voxel's cell and its distance to the nearest wall
(osmap_cli.solid.structure.cells). Each block of voxels is searched among its own candidate
seeds, chosen by the caller; blocks are independent, so the result does not depend on the
thread count."""

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def power_cells(corners, block, step, grid, centres, weights, candidates, counts, size, wrap,
                owner, wall):
    """For every block b (corner corners[b], `block` voxels a side, cropped to `grid`) and
    every voxel centre x in it ((index + 0.5) * step): owner = the candidate seed of least
    power distance |x - c|^2 - w (candidates[b, :counts[b]]; ties to the lower index) and
    wall = the distance from x to the plane between it and the runner-up,
    (p2 - p1) / (2 |c2 - c1|); offsets wrap by `size` (z, y, x) when `wrap`."""
    for b in prange(corners.shape[0]):
        for i in range(block):
            z = corners[b, 0] + i
            if z >= grid[0]:
                continue
            for j in range(block):
                y = corners[b, 1] + j
                if y >= grid[1]:
                    continue
                for k in range(block):
                    x = corners[b, 2] + k
                    if x >= grid[2]:
                        continue
                    p0, p1, p2 = (z + 0.5) * step, (y + 0.5) * step, (x + 0.5) * step
                    best, second = np.inf, np.inf
                    i1, i2 = -1, -1
                    for t in range(counts[b]):
                        s = candidates[b, t]
                        dz, dy, dx = p0 - centres[s, 0], p1 - centres[s, 1], p2 - centres[s, 2]
                        if wrap:
                            dz -= size[0] * np.round(dz / size[0])
                            dy -= size[1] * np.round(dy / size[1])
                            dx -= size[2] * np.round(dx / size[2])
                        p = dz * dz + dy * dy + dx * dx - weights[s]
                        if p < best or (p == best and s < i1):
                            second, i2 = best, i1
                            best, i1 = p, s
                        elif p < second or (p == second and s < i2):
                            second, i2 = p, s
                    owner[z, y, x] = i1
                    if i2 < 0:
                        wall[z, y, x] = np.inf
                        continue
                    sz = centres[i2, 0] - centres[i1, 0]
                    sy = centres[i2, 1] - centres[i1, 1]
                    sx = centres[i2, 2] - centres[i1, 2]
                    if wrap:
                        sz -= size[0] * np.round(sz / size[0])
                        sy -= size[1] * np.round(sy / size[1])
                        sx -= size[2] * np.round(sx / size[2])
                    sep = np.sqrt(sz * sz + sy * sy + sx * sx)
                    wall[z, y, x] = (second - best) / max(2.0 * sep, 1e-9)
