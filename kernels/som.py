"""OS-Map training kernel: local winner search and the anisotropic (matrix-exponential) update.

One kernel, specialised by the parameter record rather than copied: the same loop serves the
classic Kohonen SOM, the paper's OS-Map, and our extensions (coherent targets, range kernel,
periodic data components). Everything random (inputs, window positions) and the schedule values
are computed by the caller, so the kernel is a pure function of its arrays and is deterministic.

Map nodes live on a grid padded to three axes (a 2D map of shape (H, W) is (1, H, W)); node i has
grid coordinates (i // (g1*g2), (i // g2) % g1, i % g2). D is the map-space vector from the winner
to a node, in those padded coordinates.
"""

from collections import namedtuple

import numpy as np
from numba import njit

# The parameter record passed to `train_steps` (a namedtuple is a first-class Numba type).
#   grid      int64[3]        padded map shape
#   wrap      bool[3]         toroidal axes
#   window    int64[3]        winner-search window extent per axis (== grid: global search)
#   quad      float64[F,d,3,3] per frame and data component k: A_k = sum_j c_kj P_kj P_kj^T
#   extent    float64[F,3]    truncation half-width per axis for sigma = 1 (inf: whole axis)
#   separable bool            every A_k diagonal and one frame: use 1D tables
#   jac       float64[d,3]    coherent target x + jac @ D (zeros: the paper's target x)
#   periods   float64[d]      period of each data component (0: not periodic)
#   lo, hi    float64[d]      targets outside [lo, hi] are not applied to that node
#   range_a, range_b  float64 range kernel exp(-|t - m|^2 / 2 tau^2), tau = a*sigma + b (0: off)
#   cutoff    float64         neighbourhood weights below cutoff * alpha are skipped
KernelParams = namedtuple(
    "KernelParams",
    "grid wrap window quad extent separable jac periods lo hi range_a range_b cutoff",
)


@njit(cache=True, inline="always")
def _wrapped_diff(a, period):
    """a reduced to [-period/2, period/2) when period > 0."""
    if period > 0.0:
        return a - period * np.floor(a / period + 0.5)
    return a


@njit(cache=True)
def find_winner(weights, x, grid, wrap, origin, window, periods):
    """Index of the node nearest to x (squared Euclidean, periodic components wrapped) among the
    nodes of the window [origin, origin + window) (wrapping on wrapped axes). Ties: first node in
    scan order."""
    d = weights.shape[1]
    best = -1
    best_dist = np.inf
    for o0 in range(window[0]):
        a0 = origin[0] + o0
        if a0 >= grid[0]:
            a0 -= grid[0]
        for o1 in range(window[1]):
            a1 = origin[1] + o1
            if a1 >= grid[1]:
                a1 -= grid[1]
            base = (a0 * grid[1] + a1) * grid[2]
            for o2 in range(window[2]):
                a2 = origin[2] + o2
                if a2 >= grid[2]:
                    a2 -= grid[2]
                i = base + a2
                dist = 0.0
                for k in range(d):
                    diff = _wrapped_diff(x[k] - weights[i, k], periods[k])
                    dist += diff * diff
                    if dist >= best_dist:
                        break
                if dist < best_dist:
                    best_dist = dist
                    best = i
    return best


@njit(cache=True, inline="always")
def _axis_range(c, radius, g, wrap):
    """Offsets [lo, hi] of the update box along one axis around winner coordinate c."""
    if wrap:
        if 2 * radius + 1 >= g:
            lo = -(g // 2)
            return lo, lo + g - 1
        return -radius, radius
    return max(-radius, -c), min(radius, g - 1 - c)


@njit(cache=True)
def update_neighbourhood(weights, c, x, alpha, sigma, p, tables):
    """m_i += h_ci (target_i - m_i) for the nodes around winner c (one OS-Map step, eq. 1-4).

    h_ci is diagonal: component k uses exp(-D^T A_k D / (2 sigma^2)), times the optional range
    kernel. `tables` is scratch space of shape (d, 3, L) for the separable path.
    """
    grid = p.grid
    d = weights.shape[1]
    frame = c if p.quad.shape[0] > 1 else 0
    quad = p.quad[frame]
    c0 = c // (grid[1] * grid[2])
    c1 = (c // grid[2]) % grid[1]
    c2 = c % grid[2]
    coords = (c0, c1, c2)
    inv2s2 = 1.0 / (2.0 * sigma * sigma)

    lo = np.empty(3, np.int64)
    hi = np.empty(3, np.int64)
    for a in range(3):
        e = p.extent[frame, a] * sigma
        radius = grid[a] if not np.isfinite(e) or e >= grid[a] else np.int64(np.ceil(e))
        lo[a], hi[a] = _axis_range(coords[a], radius, grid[a], p.wrap[a])

    if p.separable:
        for k in range(d):
            for a in range(3):
                caa = quad[k, a, a]
                for off in range(lo[a], hi[a] + 1):
                    tables[k, a, off - lo[a]] = np.exp(-caa * off * off * inv2s2)

    use_range = p.range_a > 0.0 or p.range_b > 0.0
    tau = p.range_a * sigma + p.range_b
    inv2t2 = 1.0 / (2.0 * tau * tau) if use_range else 0.0
    floor_w = p.cutoff
    target = np.empty(d)
    h = np.empty(d)
    dvec = np.empty(3)

    for o0 in range(lo[0], hi[0] + 1):
        a0 = c0 + o0
        if a0 < 0:
            a0 += grid[0]
        elif a0 >= grid[0]:
            a0 -= grid[0]
        dvec[0] = o0
        for o1 in range(lo[1], hi[1] + 1):
            a1 = c1 + o1
            if a1 < 0:
                a1 += grid[1]
            elif a1 >= grid[1]:
                a1 -= grid[1]
            dvec[1] = o1
            base = (a0 * grid[1] + a1) * grid[2]
            for o2 in range(lo[2], hi[2] + 1):
                a2 = c2 + o2
                if a2 < 0:
                    a2 += grid[2]
                elif a2 >= grid[2]:
                    a2 -= grid[2]
                dvec[2] = o2
                i = base + a2

                inside = True
                for k in range(d):
                    t = x[k] + p.jac[k, 0] * o0 + p.jac[k, 1] * o1 + p.jac[k, 2] * o2
                    if t < p.lo[k] or t > p.hi[k]:
                        inside = False
                        break
                    target[k] = t
                if not inside:
                    continue

                hmax = 0.0
                for k in range(d):
                    if p.separable:
                        w = (tables[k, 0, o0 - lo[0]] * tables[k, 1, o1 - lo[1]]
                             * tables[k, 2, o2 - lo[2]])
                    else:
                        q = 0.0
                        for a in range(3):
                            for b in range(3):
                                q += dvec[a] * quad[k, a, b] * dvec[b]
                        w = np.exp(-q * inv2s2)
                    h[k] = w
                    hmax = max(hmax, w)
                if hmax < floor_w:
                    continue

                if use_range:
                    dist2 = 0.0
                    for k in range(d):
                        diff = _wrapped_diff(target[k] - weights[i, k], p.periods[k])
                        dist2 += diff * diff
                    r = np.exp(-dist2 * inv2t2)
                else:
                    r = 1.0

                for k in range(d):
                    diff = _wrapped_diff(target[k] - weights[i, k], p.periods[k])
                    m = weights[i, k] + alpha * h[k] * r * diff
                    if p.periods[k] > 0.0:
                        m -= p.periods[k] * np.floor(m / p.periods[k])
                    weights[i, k] = m


@njit(cache=True)
def train_steps(weights, inputs, origins, alphas, sigmas, p):
    """Run len(inputs) OS-Map steps in place: winner in the window at origins[t], then update.

    weights float32[N, d]; inputs float64[T, d]; origins int64[T, 3]; alphas, sigmas float64[T].
    Returns the winners (int64[T]) for diagnostics.
    """
    max_len = 2 * max(p.grid[0], p.grid[1], p.grid[2]) + 1
    tables = np.empty((weights.shape[1], 3, max_len))
    winners = np.empty(inputs.shape[0], np.int64)
    for t in range(inputs.shape[0]):
        x = inputs[t]
        c = find_winner(weights, x, p.grid, p.wrap, origins[t], p.window, p.periods)
        winners[t] = c
        update_neighbourhood(weights, c, x, alphas[t], sigmas[t], p, tables)
    return winners
