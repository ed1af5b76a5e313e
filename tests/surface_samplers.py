"""Independent point samplers for the surface tests and the fold-rate benchmark.

They deliberately do not use `osmap_cli.surface.shapes`: the roll is sampled by rejection on its
arc-length density sqrt(1 + t^2) (shapes.py inverts the arc length by Newton's method), the torus
by rejection on (R + r cos theta). Variants that users' scans have:
- `density`: a function of the two surface parameters (each scaled to [0, 1)) giving a relative
  density in (0, 1]; `ramp4` varies it 4x across the surface;
- `noise`: Gaussian noise with a standard deviation of this fraction of the bounding-box
  diagonal of the clean points.
"""

from __future__ import annotations

import numpy as np

ROLL_T0 = 1.5 * np.pi


def ramp4(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Relative density from 1/4 (a = 0) to 1 (a = 1): a 4x variation along the first
    parameter (the roll's arc, the torus's big circle)."""
    return (1.0 + 3.0 * a) / 4.0


def wave4(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Periodic 4x variation along the first parameter: 1/4 .. 1 (for closed surfaces)."""
    return (1.0 + 3.0 * (0.5 + 0.5 * np.cos(2.0 * np.pi * a))) / 4.0


def _finish(out: np.ndarray, n: int, rng, noise: float) -> np.ndarray:
    out = out[:n]
    if noise > 0:
        diag = float(np.linalg.norm(out.max(0) - out.min(0)))
        out = out + rng.normal(0.0, noise * diag, out.shape)
    return out


def roll_points(n: int, rng, turns: float = 1.0, height: float = 14.0, density=None,
                noise: float = 0.0) -> np.ndarray:
    """x = t cos t, y = t sin t, t in [1.5 pi, 1.5 pi + 2 pi turns], z in [0, height]; uniform
    by area (times `density`) by rejection."""
    t1 = ROLL_T0 + 2.0 * np.pi * turns
    top = np.sqrt(1.0 + t1 * t1)
    parts, have = [], 0
    while have < n:
        t = rng.uniform(ROLL_T0, t1, 2 * n)
        z = rng.uniform(0.0, height, 2 * n)
        w = np.sqrt(1.0 + t * t) / top
        if density is not None:
            w = w * density((t - ROLL_T0) / (t1 - ROLL_T0), z / height)
        keep = rng.uniform(0.0, 1.0, 2 * n) < w
        t, z = t[keep], z[keep]
        parts.append(np.stack([t * np.cos(t), t * np.sin(t), z], 1))
        have += len(t)
    return _finish(np.concatenate(parts), n, rng, noise)


def torus_points(n: int, rng, major: float = 2.0, minor: float = 0.7, density=None,
                 noise: float = 0.0) -> np.ndarray:
    """Torus about z; uniform by area (times `density` of (phi, theta) / 2 pi) by rejection."""
    parts, have = [], 0
    while have < n:
        theta = rng.uniform(0.0, 2.0 * np.pi, 2 * n)
        phi = rng.uniform(0.0, 2.0 * np.pi, 2 * n)
        w = (major + minor * np.cos(theta)) / (major + minor)
        if density is not None:
            w = w * density(phi / (2.0 * np.pi), theta / (2.0 * np.pi))
        keep = rng.uniform(0.0, 1.0, 2 * n) < w
        theta, phi = theta[keep], phi[keep]
        rho = major + minor * np.cos(theta)
        parts.append(np.stack([rho * np.cos(phi), rho * np.sin(phi), minor * np.sin(theta)], 1))
        have += len(theta)
    return _finish(np.concatenate(parts), n, rng, noise)


# The flags docs/surface.md gives for point files of these shapes.
ROLL_FLAGS = ["--vary", "x=u,y=u,z=v"]
TORUS_FLAGS = ["--wrap", "uv", "--frame", "cylindrical", "--axis", "z", "--vary",
               "rho=v,z=v,phi=u"]

# name: (shape, sampler keyword arguments, CLI flags); the torus variants vary the density
# periodically so that there is no seam in it.
VARIANTS = {
    "roll": ("roll", {"turns": 1.0}, ROLL_FLAGS),
    "roll-1.5": ("roll", {"turns": 1.5}, ROLL_FLAGS),
    "torus": ("torus", {}, TORUS_FLAGS),
    "roll-noisy": ("roll", {"turns": 1.0, "noise": 0.01}, ROLL_FLAGS),
    "roll-nonuniform": ("roll", {"turns": 1.0, "density": ramp4}, ROLL_FLAGS),
    "torus-noisy": ("torus", {"noise": 0.01}, TORUS_FLAGS),
    "torus-nonuniform": ("torus", {"density": wave4}, TORUS_FLAGS),
}


def sample_variant(name: str, n: int, seed: int) -> np.ndarray:
    shape, kwargs, _ = VARIANTS[name]
    rng = np.random.default_rng([17, seed])
    fn = roll_points if shape == "roll" else torus_points
    return fn(n, rng, **kwargs)
