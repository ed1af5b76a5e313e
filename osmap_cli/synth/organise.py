"""Organise: an OS-Map lays out exemplar positions over the coarsest output grid.

Each step draws an exemplar position x, finds the winner among the nodes of a random window about
the exemplar's extent (the paper's local winner search, which sets the scale), and pulls the
neighbours toward the coherent target x + J (i - c) with the per-component anisotropic kernel
times a range kernel. The result is a position field made of coherent, varied copies: the
layout that the refinement stage then polishes.
"""

from __future__ import annotations

import math

import numpy as np

from osmap_cli.engine import Orientation, OSMap, Schedule
from osmap_cli.synth.options import SynthOptions


def exemplar_positions(lo, hi) -> np.ndarray:
    """Every integer (row, col) position in the box [lo, hi], as float64 (n, 2)."""
    rows = np.arange(math.ceil(lo[0]), math.floor(hi[0]) + 1)
    cols = np.arange(math.ceil(lo[1]), math.floor(hi[1]) + 1)
    grid = np.stack(np.meshgrid(rows, cols, indexing="ij"), -1)
    return grid.reshape(-1, 2).astype(np.float64)


def search_window(exemplar_shape, out_shape, jac: np.ndarray, window_scale: float):
    """Winner-search window, in output pixels: the exemplar's extent seen through J."""
    magnification = 1.0 / math.sqrt(abs(np.linalg.det(jac)))
    return tuple(int(min(o, max(1, round(window_scale * e * magnification))))
                 for e, o in zip(exemplar_shape, out_shape))


def component_orientation(jac: np.ndarray, anisotropy: float) -> Orientation:
    """Each exemplar coordinate's neighbourhood is narrow along its own gradient across the
    output (row k of J) and `anisotropy` times as steep across it."""
    theta = np.arctan2(jac[:, 1], jac[:, 0])
    return Orientation.angles(theta, [[1.0, anisotropy], [1.0, anisotropy]])


def organise(exemplar_shape, out_shape, jac, lo, hi, opts: SynthOptions, *, wrap: bool,
             seed: int, allowed=None) -> np.ndarray:
    """float32 (H, W, 2) position field over the output grid `out_shape`; `allowed` (bool
    (h, w), optional): train on those exemplar positions only (an atlas of several)."""
    data = exemplar_positions(lo, hi)
    if allowed is not None:
        data = data[allowed[data[:, 0].astype(int), data[:, 1].astype(int)]]
    som = OSMap(out_shape, 2, wrap=(wrap, wrap),
                window=search_window(exemplar_shape, out_shape, jac, opts.window_scale),
                orientation=component_orientation(jac, opts.som_anisotropy),
                target_jacobian=jac,
                range_kernel=(opts.som_range, 1.0) if opts.som_range > 0 else None,
                bounds=np.stack([lo, hi], 1))
    som.init_random(data, seed=seed)
    steps = int(opts.som_steps_per_node * som.size)
    schedule = Schedule(alpha_max=opts.som_alpha_max, alpha_min=opts.som_alpha_min,
                        sigma_max=opts.som_sigma_max, sigma_min=opts.som_sigma_min)
    if steps:
        som.train(data, steps, schedule=schedule, seed=seed + 1)
    return som.grid_weights().astype(np.float32)
